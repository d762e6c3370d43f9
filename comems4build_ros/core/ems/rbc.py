"""Rule-based controller (``--ems rbc``, paper ``sec:RBC``).

The RBC follows the ComEMS4Build workflow with crisp rules and the "basic" inputs of
``tab:level_of_information`` (no comfort bounds ahead, no radiation, no H2 allowance):

1. Heating: the thermal states chi_SH ``eq:s_sh`` (with T_air,min[k] only, no
   look-ahead) and chi_DHW ``eq:s_dhw`` drive two hysteresis switches on the same [0, 1]
   scale. Room heating switches on when T_air reaches T_air,min (chi_SH = 0) and off at
   T_air,max (chi_SH = 1); tank heating on below ``dhw_on_chi`` and off above
   ``dhw_off_chi``. When both want heat, DHW goes first. The HP runs at ``hp_mod_on``.
2. dP = P_PV - P_el,HP - P_el,load, P_el,HP estimated as eta_HP * P_el,max(t_ref).
3. FC at P_el,FC = zeta * P_el,FC,max when dP < 0 and the EDF price ``eq:EDF_prices``
   is in the upper quartile and the store is above the RBC's own lower limit
   ``loh_reserve`` (the RBC does not know how much H2 it may use per day, so it reaches
   that limit early).
4. Battery: in the lowest EDF quartile it charges at full power (the grid buys the load
   and the charge); otherwise it takes the residual dP_new = dP + P_el,FC: charging with
   surplus, discharging to cover demand, within its power and SOC limits.

A year-round plant (``docs/seasonal.md``; not in the paper) adds, each only where installed:
cooling at the upper bound (on when T_air reaches T_air,max, off at ``cool_off_chi`` of the
mirrored thermal state, at ``hp_mod_on``; DHW first), and the electrolyser on the surplus
left after the battery (P_EL = that surplus up to P_EL,max, off below P_EL,min or with the
store at LOH_max).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.features import chi_cool, chi_dhw, chi_sh, edf_price, hp_p_el_ref_w
from comems4build_ros.core.ems.settings import RBCSettings, load_settings
from comems4build_ros.core.models.battery import power_limits_w
from comems4build_ros.core.models.cooling import p_el_max_cool_w
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.types import HP_COOL, HP_DHW, HP_OFF, HP_SH, Action


def loh_floor(params: PlantParams, options: Mapping[str, Any] | None = None) -> float:
    """Lowest H2 level the RBC runs its FC at: the plant's LOH_min or the RBC's own ``loh_reserve``.

    Reports count the RBC's store as empty when it reaches this level (``sec:results``:
    the RBC "has depleted the H2 storage to the LOH_min").

    Parameters
    ----------
    params : PlantParams
        Plant parameters (``hydrogen.loh_min`` [-]).
    options : Mapping[str, Any], optional
        The RBC's options (:class:`~comems4build_ros.core.ems.settings.RBCSettings`).

    Returns
    -------
    float
        The level [-] (fraction of the store's capacity).
    """
    return max(params.hydrogen.loh_min, load_settings(RBCSettings, options).loh_reserve)


class RuleBasedController:
    """The paper's RBC (``sec:RBC``).

    Parameters
    ----------
    params : PlantParams
        Plant parameters (device sizes, tank volumes).
    options : Mapping[str, Any], optional
        Overrides of ``config/rbc.yaml`` section ``rbc``
        (:class:`~comems4build_ros.core.ems.settings.RBCSettings`).
    """

    name = "rbc"
    info_level = "basic"
    settings_class = RBCSettings

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None) -> None:
        self.params = params
        self.settings = load_settings(RBCSettings, options)
        if params.heat_pump.mod_min > self.settings.hp_mod_on:
            raise ConfigError(f"rbc option hp_mod_on={self.settings.hp_mod_on} is below the HP's minimal modulation")
        self._p_hp_ref_w = hp_p_el_ref_w(params.heat_pump, self.settings.p_el_ref_t_amb_c)
        self._p_fc_w = params.fuel_cell.zeta * params.fuel_cell.p_max_w
        self._cooling = bool(params.cooling.enabled)
        self._p_cool_ref_w = float(p_el_max_cool_w(self.settings.p_el_ref_cool_t_amb_c, params.cooling))
        table = ElectrolyserTable(params.electrolyser)
        self._el = table.n > 0
        self._p_el_min_w, self._p_el_max_w = table.p_min_w, table.p_max_w
        self.step_info: dict[str, float] = {}
        self.reset()

    def reset(self) -> None:
        """Both heating switches (and the cooling switch) off."""
        self._sh_on = False
        self._dhw_on = False
        self._cool_on = False
        self.step_info = {}

    def act(self, obs: Observation) -> Action:
        """Decide the step by the rules of ``sec:RBC`` (``fig:flc_rbc_flowchart`` right).

        Parameters
        ----------
        obs : Observation
            The step's inputs (basic level, ``tab:level_of_information``).

        Returns
        -------
        Action
            The set-points; the features go to :attr:`step_info`.
        """
        o, p = self.settings, self.params
        c_sh = chi_sh(obs.t_air_c, obs.t_min_c, obs.t_max_c)
        c_dhw = chi_dhw(obs.v_dhw_l, p.dhw.v_min_l, p.dhw.v_max_l)
        if c_sh <= o.sh_on_chi:
            self._sh_on = True
        elif c_sh >= o.sh_off_chi:
            self._sh_on = False
        if c_dhw <= o.dhw_on_chi:
            self._dhw_on = True
        elif c_dhw >= o.dhw_off_chi:
            self._dhw_on = False
        if self._dhw_on:
            mode, eta = HP_DHW, o.hp_mod_on
        elif self._sh_on:
            mode, eta = HP_SH, o.hp_mod_on
        else:
            mode, eta = HP_OFF, 0.0
        p_hp_ref = self._p_hp_ref_w
        if self._cooling:
            c_cool = chi_cool(obs.t_air_c, obs.t_min_c, obs.t_max_c)
            if c_cool <= 0.0:
                self._cool_on = True
            elif c_cool >= o.cool_off_chi:
                self._cool_on = False
            if self._cool_on and mode == HP_OFF:
                mode, eta, p_hp_ref = HP_COOL, o.hp_mod_on, self._p_cool_ref_w
        dp_w = obs.p_pv_w - eta * p_hp_ref - obs.p_load_w
        edf = edf_price(obs.price_buy_eur_per_kwh, obs.prices_buy_24h)
        p_fc = 0.0
        if dp_w < 0.0 and edf > o.edf_upper_quartile and obs.loh > max(o.loh_reserve, p.hydrogen.loh_min):
            p_fc = self._p_fc_w
        dp_new_w = dp_w + p_fc
        b = p.battery
        if edf <= o.edf_lower_quartile:
            p_bess = b.p_ch_max_w
        elif dp_new_w > 0.0:
            p_bess = min(dp_new_w, b.p_ch_max_w)
        else:
            p_bess = -min(-dp_new_w, b.p_d_max_w)
        room_ch, room_d = power_limits_w(obs.soc, b, p.simulation.time_step_h)
        p_bess = min(p_bess, room_ch) if p_bess > 0 else max(p_bess, -room_d)
        self.step_info = {"chi_sh": c_sh, "chi_dhw": c_dhw, "edf": edf, "dp_w": dp_w, "dp_new_w": dp_new_w}
        p_el = 0.0
        if self._el:
            surplus = dp_new_w - max(p_bess, 0.0)
            if surplus >= self._p_el_min_w and obs.loh < p.hydrogen.loh_max:
                p_el = min(surplus, self._p_el_max_w)
            self.step_info["p_el_w"] = p_el
        return Action(hp_mod=eta, hp_mode=mode, p_fc_w=p_fc, p_bess_w=p_bess, p_el_w=p_el)
