"""ComEMS4Build: the hierarchical fuzzy EMS (``--ems fuzzy``, paper ``sec:FLC``).

One step (``fig:flc_rbc_flowchart`` left, ``sec:appendix``):

1. Features: chi_SH ``eq:s_sh`` (with the lower bounds 5 h ahead), chi_DHW ``eq:s_dhw``,
   EDF price ``eq:EDF_prices``, remaining share of today's H2 allowance ``eq:deltaLOH``.
2. FLC_flex(min(chi_SH, chi_DHW), LOH, SOC, EDF, q_s) -> alpha_HP; the modulation follows
   :func:`~comems4build_ros.core.ems.features.update_modulation` (eta_HP[k-1] + alpha_HP,
   snapped to {0} U [0.2, 1]). Circuit: DHW priority (paper ``sec:results``: both
   ComEMS4Build and RBC "give priority to the DHW over an SH ... keep the storage filled
   mostly at more than 50 %"): the HP serves the tank when chi_DHW <= chi_SH or chi_DHW is
   below ``dhw_priority_chi`` (tank less than half full), else the room.
3. dP = P_PV - P_el,HP - P_el,load with P_el,HP estimated as eta_HP * P_el,max(t_ref)
   (the EMS does not see T_amb; :func:`~comems4build_ros.core.ems.features.hp_p_el_ref_w`).
4. Only if dP < 0: FLC_FC(dP / 10 kW, dLOH share, SOC, EDF, s_on/off[k-1]) -> alpha_FC,
   P_el,FC = alpha_FC * P_el,FC,max * zeta, capped at the demand, 0 below P_min.
5. FLC_B(dP_new / 10 kW, SOC, EDF) with dP_new = dP + P_el,FC -> alpha_B in [-1, 1];
   alpha_B > 0 charges alpha_B * P_ch,max, alpha_B <= 0 discharges alpha_B * dP_new; the
   grid covers the rest (the plant's power balance).

A year-round plant (``docs/seasonal.md``; not in the paper) adds, each only where installed:

- cooling (``cooling.enabled``): FLC_flex drives cooling as it drives heating, with the
  thermal state towards the upper bound chi_cool (:func:`~comems4build_ros.core.ems.features.chi_cool`)
  in place of chi_SH, when chi_cool is below ``hp.cool_below_chi`` and the tank does not
  take the HP (DHW priority);
- the electrolyser (``electrolyser.n_modules > 0``): only if dP > 0,
  FLC_EL(dP / 10 kW, SOC, LOH, EDF, days to the heating season) -> alpha_EL,
  P_EL = alpha_EL * P_EL,max capped at dP, 0 below P_EL,min; dP_new = dP + P_el,FC - P_EL;
  and the daily H2 budget ``eq:deltaLOH`` spread over the heating season: on its first step
  the budget becomes (LOH - ``simulation.loh_season_end``) / days of the season, outside the
  season it is 0 (the FC saves the store for the winter); it is booked as a fixed daily
  budget whatever ``fc.h2_allowance`` says.

The membership functions and rule bases are the data files ``config/fuzzy/flex.yaml``,
``fc.yaml`` and ``battery.yaml``; the options choose other files or override entries.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.features import (
    DailyH2Allowance,
    chi_cool,
    chi_dhw,
    chi_sh,
    edf_price,
    hp_p_el_ref_w,
    modulation_level,
    update_modulation,
)
from comems4build_ros.core.ems.fuzzy.engine import FuzzySystem, flc_system
from comems4build_ros.core.ems.settings import FuzzySettings, load_settings
from comems4build_ros.core.models.battery import power_limits_w
from comems4build_ros.core.types import HP_COOL, HP_DHW, HP_OFF, HP_SH, Action

#: Controllers only a year-round plant with an electrolyser builds (the paper's plant has none).
EL_FLCS = ("el",)


def fuzzy_systems(settings: FuzzySettings, params: PlantParams) -> dict[str, FuzzySystem]:
    """Build the fuzzy controllers of ``settings`` for the plant ``params``.

    Parameters
    ----------
    settings : FuzzySettings
        The rule files' sections, checked (:func:`~comems4build_ros.core.ems.settings.load_settings`).
    params : PlantParams
        Plant parameters (device sizes for the membership peaks); FLC_EL only for a plant
        with an electrolyser (``electrolyser.n_modules > 0``).

    Returns
    -------
    dict[str, FuzzySystem]
        ``flex``, ``fc``, ``battery`` (and ``el``) -> the controller.
    """
    out = {}
    for key, where in FuzzySettings.FILES.items():
        if key in EL_FLCS and params.electrolyser.n_modules == 0:
            continue
        section = getattr(settings, key)
        out[key] = flc_system(str(where.section), section.model_dump(), params, getattr(settings, f"{key}_file"))
    return out


def load_flcs(params: PlantParams, options: Mapping[str, Any] | None = None) -> dict[str, tuple[FuzzySystem, dict]]:
    """Build the fuzzy controllers from their rule files and ``options``.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (device sizes for the membership peaks).
    options : Mapping[str, Any], optional
        The fuzzy EMS's options (:class:`~comems4build_ros.core.ems.settings.FuzzySettings`):
        ``<flc>_file`` chooses a rule file, ``<flc>.<key>`` overrides a value of its section
        (``"fc.fc.cap_to_demand"``, as from ``--ems-option``).

    Returns
    -------
    dict[str, tuple[FuzzySystem, dict]]
        ``flex``, ``fc``, ``battery`` (and ``el``) -> the controller and its section.
    """
    settings = load_settings(FuzzySettings, options)
    return {key: (system, getattr(settings, key).model_dump())
            for key, system in fuzzy_systems(settings, params).items()}


class FuzzyEMS:
    """ComEMS4Build: FLC_flex -> FLC_FC (only when dP < 0) -> FLC_B (``sec:FLC``).

    Parameters
    ----------
    params : PlantParams
        Plant parameters (device sizes, tank volumes, the H2 store's bounds).
    options : Mapping[str, Any], optional
        The fuzzy EMS's options (:class:`~comems4build_ros.core.ems.settings.FuzzySettings`;
        may be empty: the shipped rule files are read).

    Attributes
    ----------
    settings : FuzzySettings
        The rule files' sections and the post-processing options, checked.
    step_info : dict[str, float]
        Features and controller outputs of the last step (recorded as ``ems_*``).
    """

    name = "fuzzy"
    info_level = "fuzzy"
    settings_class = FuzzySettings

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None) -> None:
        self.settings = s = load_settings(FuzzySettings, options)
        flcs = fuzzy_systems(s, params)
        self.flex, self.fc, self.battery = flcs["flex"], flcs["fc"], flcs["battery"]
        self.params = params
        self._mod_min = params.heat_pump.mod_min
        hp = s.flex.hp
        self._p_hp_ref_w = hp_p_el_ref_w(params.heat_pump, hp.p_el_ref_t_amb_c)
        self._dhw_prio = hp.dhw_priority_chi
        self._hp_level = hp.update == "level"
        self._cap_fc = s.fc.fc.cap_to_demand
        self._stop_fc = s.fc.fc.stop_when_allowance_used
        self._absorb = s.battery.battery.absorb_surplus
        self._scale_fc = self.fc.load_scale_w
        self._scale_b = self.battery.load_scale_w
        fc = params.fuel_cell
        self._p_fc_max_w = fc.zeta * fc.p_max_w
        self._p_fc_min_w = fc.p_min_w
        self._dt_h = params.simulation.time_step_h
        allowance = s.fc.fc.h2_allowance
        # A plant with an electrolyser spreads its budget over the heating season once, at the
        # season's start (season_dloh, docs/seasonal.md): eq:deltaLOH's period is not the run there,
        # so its daily budget is booked as given ("fixed").
        if params.electrolyser.n_modules > 0:
            allowance = "fixed"
        self._allowance = DailyH2Allowance(allowance, params.simulation.loh_init, params.hydrogen.loh_min)
        self.step_info: dict[str, float] = {}
        # year-round plant: cooling and the electrolyser, each only where installed
        self._cooling = bool(params.cooling.enabled)
        self._cool_chi = hp.cool_below_chi
        from comems4build_ros.core.models.cooling import p_el_max_cool_w
        from comems4build_ros.core.models.electrolyser import ElectrolyserTable

        self._p_cool_ref_w = float(p_el_max_cool_w(hp.p_el_ref_cool_t_amb_c, params.cooling))
        self.el: FuzzySystem | None = flcs.get("el")
        if self.el is not None:
            self._cap_el = s.el.el.cap_to_surplus
            self._scale_el = self.el.load_scale_w
            table = ElectrolyserTable(params.electrolyser)
            self._p_el_max_w, self._p_el_min_w = table.p_max_w, table.p_min_w
        self._season_loh0: float | None = None
        self._season_dloh = 0.0

    def reset(self) -> None:
        """Forget the day's H2 bookkeeping."""
        self._allowance.reset()
        self.step_info = {}
        self._season_loh0 = None
        self._season_dloh = 0.0

    # ------------------------------------------------------------------ stages
    def heating(self, obs: Observation, edf: float) -> tuple[float, int, float, float, float]:
        """Decide the heat pump's heating with FLC_flex (``tab:FLCflex_rules``) and the DHW priority.

        Parameters
        ----------
        obs : Observation
            The step's inputs (fuzzy level, ``tab:level_of_information``).
        edf : float
            EDF of the day-ahead prices ``eq:EDF_prices`` [-].

        Returns
        -------
        eta : float
            Modulation eta_HP[k] [-], in {0} U [mod_min, 1].
        mode : int
            ``HP_OFF``, ``HP_SH`` or ``HP_DHW`` (the circuit).
        alpha : float
            FLC_flex output alpha_HP [-].
        chi_sh, chi_dhw : float
            Thermal states ``eq:s_sh`` (bounds 5 h ahead) and ``eq:s_dhw`` [-].
        """
        dhw = self.params.dhw
        c_sh = chi_sh(obs.t_air_c, obs.t_min_5h_c, obs.t_max_c)
        c_dhw = chi_dhw(obs.v_dhw_l, dhw.v_min_l, dhw.v_max_l)
        alpha = self.flex(min(c_sh, c_dhw), obs.loh, obs.soc, edf, obs.ghi_w_m2)
        if self._hp_level:
            eta = modulation_level(alpha, self._mod_min)
        else:
            eta = update_modulation(obs.hp_mod_prev, alpha, self._mod_min)
        if eta <= 0.0:
            return 0.0, HP_OFF, alpha, c_sh, c_dhw
        mode = HP_DHW if (c_dhw <= c_sh or c_dhw < self._dhw_prio) else HP_SH
        return eta, mode, alpha, c_sh, c_dhw

    def cooling(self, obs: Observation, edf: float, eta: float, mode: int) -> tuple[float, int, float, float]:
        """Decide cooling with FLC_flex on the mirrored thermal state (year-round plant; not in the paper).

        Parameters
        ----------
        obs : Observation
            The step's inputs.
        edf : float
            EDF of the day-ahead prices ``eq:EDF_prices`` [-].
        eta, mode : float, int
            The heating decision of :meth:`heating`: kept when the room does not need
            cooling or the tank takes the heat pump (DHW priority).

        Returns
        -------
        eta : float
            Modulation [-].
        mode : int
            ``HP_COOL``, or the heating decision's mode.
        alpha : float
            FLC_flex output for cooling [-] (0 when not evaluated).
        chi_cool : float
            Thermal state towards the upper bound [-] (:func:`~..features.chi_cool`).
        """
        c_cool = chi_cool(obs.t_air_c, obs.t_min_c, obs.t_max_c)
        if mode == HP_DHW or c_cool >= self._cool_chi:
            return eta, mode, 0.0, c_cool
        alpha = self.flex(c_cool, obs.loh, obs.soc, edf, obs.ghi_w_m2)
        prev = obs.hp_mod_prev
        eta_c = modulation_level(alpha, self._mod_min) if self._hp_level else \
            update_modulation(prev, alpha, self._mod_min)
        if eta_c <= 0.0:
            return eta, mode, alpha, c_cool
        return eta_c, HP_COOL, alpha, c_cool

    def season_dloh(self, obs: Observation) -> float:
        """Compute the daily H2 budget of a plant with an electrolyser: ``eq:deltaLOH`` over the heating season.

        On the season's first step the budget becomes (LOH - ``simulation.loh_season_end``)
        / days left in the season; outside the season it is 0 (not in the paper).

        Parameters
        ----------
        obs : Observation
            The step's inputs (``heating_season_days_left`` [d], ``loh`` [-]).

        Returns
        -------
        float
            The budget [fraction of the store per day].
        """
        left = obs.heating_season_days_left
        if left <= 0.0:
            self._season_loh0 = None
            self._season_dloh = 0.0
        elif self._season_loh0 is None:
            self._season_loh0 = obs.loh
            self._season_dloh = max(0.0, obs.loh - self.params.simulation.loh_season_end) / left
        return self._season_dloh

    def electrolyser(self, obs: Observation, dp_w: float, edf: float) -> tuple[float, float]:
        """Decide the electrolyser's power with FLC_EL (year-round plant; not in the paper).

        Parameters
        ----------
        obs : Observation
            The step's inputs.
        dp_w : float
            dP = P_PV - P_el,HP - P_el,load [W] (> 0: surplus).
        edf : float
            EDF of the day-ahead prices ``eq:EDF_prices`` [-].

        Returns
        -------
        p_el : float
            Electrolyser intake P_EL [W]; 0 without surplus, with a full store or below P_EL,min.
        alpha : float
            FLC_EL output alpha_EL [-].
        """
        if self.el is None or dp_w <= 0.0 or obs.loh >= self.params.hydrogen.loh_max:
            return 0.0, 0.0
        alpha = self.el(dp_w / self._scale_el, obs.soc, obs.loh, edf, obs.days_to_heating_season)
        p_el = alpha * self._p_el_max_w
        if self._cap_el:
            p_el = min(p_el, dp_w)
        if p_el < self._p_el_min_w:
            p_el = 0.0
        return p_el, alpha

    def fuel_cell(self, obs: Observation, dp_w: float, share: float, edf: float) -> tuple[float, float]:
        """Decide the fuel cell's power with FLC_FC (``tab:FLCfc_rules``, ``sec:appendix``).

        Parameters
        ----------
        obs : Observation
            The step's inputs.
        dp_w : float
            dP = P_PV - P_el,HP - P_el,load [W] (< 0: demand).
        share : float
            Remaining share of today's H2 allowance ``eq:deltaLOH`` [-].
        edf : float
            EDF of the day-ahead prices ``eq:EDF_prices`` [-].

        Returns
        -------
        p_fc : float
            P_el,FC = alpha_FC * zeta * P_FC,max [W]; 0 without demand, below P_FC,min, with
            the day's allowance used up or the store at LOH_min.
        alpha : float
            FLC_FC output alpha_FC [-].
        """
        if dp_w >= 0.0 or (self._stop_fc and share <= 0.0) or obs.loh <= self.params.hydrogen.loh_min:
            return 0.0, 0.0
        alpha = self.fc(dp_w / self._scale_fc, share, obs.soc, edf, 1.0 if obs.fc_on_prev else 0.0)
        p_fc = alpha * self._p_fc_max_w
        if self._cap_fc:
            p_fc = min(p_fc, max(-dp_w, self._p_fc_min_w))
        if p_fc < self._p_fc_min_w:
            p_fc = 0.0
        return p_fc, alpha

    def battery_power(self, soc: float, dp_new_w: float, edf: float) -> tuple[float, float]:
        """Decide the battery's power with FLC_B (``tab:FLCb_rules``, ``sec:appendix``).

        Parameters
        ----------
        soc : float
            Battery state of charge SOC[k-1] [-].
        dp_new_w : float
            dP_new = dP + P_el,FC - P_EL [W].
        edf : float
            EDF of the day-ahead prices ``eq:EDF_prices`` [-].

        Returns
        -------
        p_bess : float
            Battery power [W], > 0 charging: alpha_B * P_ch,max, or alpha_B * dP_new when
            discharging, within the SOC room (``eq:batt_soc``) and 0 below the minimum powers.
        alpha : float
            FLC_B output alpha_B [-], in [-1, 1].
        """
        b = self.params.battery
        alpha = self.battery(dp_new_w / self._scale_b, soc, edf)
        if alpha > 0.0:
            p = alpha * b.p_ch_max_w
            if self._absorb and dp_new_w > 0.0:
                p = max(p, min(dp_new_w, b.p_ch_max_w))
        elif dp_new_w < 0.0:
            p = alpha * min(-dp_new_w, b.p_d_max_w)  # P_d = alpha_B * dP_new (both < 0)
        else:
            p = 0.0
        room_ch, room_d = power_limits_w(soc, b, self._dt_h)
        p = min(p, room_ch) if p > 0 else max(p, -room_d)
        if 0.0 < p < b.p_ch_min_w or -b.p_d_min_w < p < 0.0:
            p = 0.0
        return p, alpha

    def act(self, obs: Observation) -> Action:
        """Decide the step by the hierarchy of ``sec:FLC`` (``fig:flc_rbc_flowchart``).

        Parameters
        ----------
        obs : Observation
            The step's inputs (fuzzy level, ``tab:level_of_information``).

        Returns
        -------
        Action
            The set-points; the features and controller outputs go to :attr:`step_info`.
        """
        edf = edf_price(obs.price_buy_eur_per_kwh, obs.prices_buy_24h)
        eta, mode, alpha_hp, c_sh, c_dhw = self.heating(obs, edf)
        year: dict[str, float] = {}
        if self._cooling:
            eta, mode, alpha_cool, c_cool = self.cooling(obs, edf, eta, mode)
            year.update(chi_cool=c_cool, alpha_cool=alpha_cool)
        p_hp_ref = self._p_cool_ref_w if mode == HP_COOL else self._p_hp_ref_w
        dp_w = obs.p_pv_w - eta * p_hp_ref - obs.p_load_w
        dloh = obs.dloh_per_day if self.el is None else self.season_dloh(obs)
        share = self._allowance.update(obs.day_index, obs.loh, dloh)
        p_fc, alpha_fc = self.fuel_cell(obs, dp_w, share, edf)
        p_el = 0.0
        if self.el is not None:
            p_el, alpha_el = self.electrolyser(obs, dp_w, edf)
            year.update(alpha_el=alpha_el, p_el_w=p_el, dloh_season=dloh)
        dp_new_w = dp_w + p_fc - p_el
        p_bess, alpha_b = self.battery_power(obs.soc, dp_new_w, edf)
        self.step_info = {
            "chi_sh": c_sh,
            "chi_dhw": c_dhw,
            "edf": edf,
            "dloh_share": share,
            "alpha_hp": alpha_hp,
            "alpha_fc": alpha_fc,
            "alpha_b": alpha_b,
            "dp_w": dp_w,
            "dp_new_w": dp_new_w,
            **year,
        }
        return Action(hp_mod=eta, hp_mode=mode, p_fc_w=p_fc, p_bess_w=p_bess, p_el_w=p_el)
