"""Numbers of one horizon problem, built from an MPC observation only.

:class:`PlantConstants` holds what the MPC knows from the plant parameters (its
"forecasting models", ``tab:level_of_information``): the discretised 4R3C building, the
DHW tank, battery, FC and H2 store constants, the lifecycle costs. :func:`build_horizon`
combines them with one :class:`~comems4build_ros.core.ems.base.Observation` of level "mpc"
into a :class:`HorizonData`: the initial states of step ``k - 1`` and the 24-step
forecast from step ``k``. Nothing else enters the optimisation, so the controllers can
only use what the plant published (a test perturbs the scenario beyond the horizon).

The MILP (:mod:`.milp`) and the QP (:mod:`.qp`) are both built from these numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from comems4build_ros.core.config import W_PER_KW, PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.mpc.costs import LifecycleCosts, lifecycle_costs
from comems4build_ros.core.models import building, dhw, heat_pump


@dataclass(frozen=True)
class PlantConstants:
    """Constants of the MPC's linear plant model (from :class:`PlantParams`).

    Attributes
    ----------
    n : int
        Horizon steps [-].
    dt_h : float
        Step [h].
    ad, bd : numpy.ndarray
        Building model ZOH matrices (``eq:state_update_bldgs``): x = [T_air, T_w_in, T_w_out]
        [degC], u = [Q_h,SH [W], T_amb [degC], q_s [W/m2]].
    l_per_wh : float
        DHW volume change per Wh of heat at T_DHW [l/Wh] (``eq:DHW_model``).
    q_dhw_loss_w : float
        Standing loss of the tank [W].
    v_min_l, v_max_l : float
        Usable volume bounds [l].
    soc_min, soc_max : float
        Battery SOC bounds [-].
    soc_per_wh_ch, soc_per_wh_d : float
        SOC change per Wh charged (eta_ch / E) and per Wh discharged (1 / (eta_d E)) [1/Wh]
        (``eq:batt_soc``).
    p_ch_max_w, p_d_max_w, p_ch_min_w, p_d_min_w : float
        Battery power range [W].
    loh_per_wh_fc : float
        LOH drop per Wh of FC electricity at constant eta_el_mpc [1/Wh] (``eq:LOH``).
    loh_init, loh_lower, loh_upper : float
        Initial H2 level and the store's bounds [-].
    k_fc_heat : float
        Recovered heat per W of FC electricity, (eta_sys - eta_el_mpc) / eta_el_mpc [-]
        (``eq:FC_sys_efficiency``).
    p_fc_min_w, p_fc_max_w : float
        FC power range, max = zeta * P_max [W].
    hp_mod_min : float
        Smallest non-zero heat pump modulation [-].
    t_supply_sh_c, t_supply_dhw_c : float
        Supply temperatures of the two circuits [degC] (their COPs).
    costs : LifecycleCosts
        Lifecycle costs (``eq:batt_andFC_operation_degradation``).
    params : PlantParams
        The plant parameters they come from.
    el, cooling : bool
        Year-round plant: an electrolyser / cooling is installed (not in the paper).
    p_el_min_w, p_el_max_w : float
        Electrolyser intake range [W] (0 without one).
    loh_per_wh_el : float
        LOH gain per Wh of electrolyser intake at its rated efficiency, compression
        included [1/Wh].
    q_cool_max_w : float
        Cooling capacity [W] (0 without cooling).
    """

    n: int
    dt_h: float
    ad: np.ndarray
    bd: np.ndarray
    l_per_wh: float
    q_dhw_loss_w: float
    v_min_l: float
    v_max_l: float
    soc_min: float
    soc_max: float
    soc_per_wh_ch: float
    soc_per_wh_d: float
    p_ch_max_w: float
    p_d_max_w: float
    p_ch_min_w: float
    p_d_min_w: float
    loh_per_wh_fc: float
    loh_init: float
    loh_lower: float
    loh_upper: float
    k_fc_heat: float
    p_fc_min_w: float
    p_fc_max_w: float
    hp_mod_min: float
    t_supply_sh_c: float
    t_supply_dhw_c: float
    costs: LifecycleCosts
    params: PlantParams
    #: year-round plant: electrolyser (P_EL range [W], LOH gain per Wh of intake at its rated
    #: efficiency, compression included [1/Wh]) and cooling (capacity [W]); 0 where not installed
    el: bool = False
    p_el_min_w: float = 0.0
    p_el_max_w: float = 0.0
    loh_per_wh_el: float = 0.0
    cooling: bool = False
    q_cool_max_w: float = 0.0

    @property
    def year_round(self) -> bool:
        """An electrolyser or cooling is installed: the MILP gets their variables."""
        return self.el or self.cooling

    @classmethod
    def from_params(cls, params: PlantParams, fc_lifecycle_eta: str = "eta_el_mpc") -> PlantConstants:
        """Derive the constants from the plant parameters.

        Parameters
        ----------
        params : PlantParams
            The plant parameters (the MPC's forecasting models, ``tab:level_of_information``).
        fc_lifecycle_eta : {"eta_el_mpc", "eta_sys", "one"}
            Efficiency dividing the FC's lifecycle cost (:func:`.costs.lifecycle_costs`).

        Returns
        -------
        PlantConstants
            The constants.
        """
        sim, b, fc, h2, hp, tank = (params.simulation, params.battery, params.fuel_cell, params.hydrogen,
                                    params.heat_pump, params.dhw)
        dt_h = sim.time_step_h
        ad, bd = building.discretize(params.building, dt_h)
        w_per_l_per_h = float(dhw.heat_w_from_l_per_h(1.0, tank))  # [W] carried by 1 l/h
        e_b_wh = b.e_max_kwh * W_PER_KW
        return cls(
            n=int(round(sim.horizon_h / dt_h)),
            dt_h=dt_h,
            ad=np.asarray(ad, dtype=float),
            bd=np.asarray(bd, dtype=float),
            l_per_wh=1.0 / w_per_l_per_h,
            q_dhw_loss_w=tank.q_loss_w,
            v_min_l=tank.v_min_l,
            v_max_l=tank.v_max_l,
            soc_min=b.soc_min,
            soc_max=b.soc_max,
            soc_per_wh_ch=b.eta_ch / e_b_wh,
            soc_per_wh_d=1.0 / (b.eta_d * e_b_wh),
            p_ch_max_w=b.p_ch_max_w,
            p_d_max_w=b.p_d_max_w,
            p_ch_min_w=b.p_ch_min_w,
            p_d_min_w=b.p_d_min_w,
            loh_per_wh_fc=1.0 / (fc.eta_el_mpc * h2.e_max_kwh * W_PER_KW),
            loh_init=sim.loh_init,
            loh_lower=h2.loh_min,
            loh_upper=h2.loh_max,
            k_fc_heat=max(fc.eta_sys - fc.eta_el_mpc, 0.0) / fc.eta_el_mpc,
            p_fc_min_w=fc.p_min_w,
            p_fc_max_w=fc.zeta * fc.p_max_w,
            hp_mod_min=hp.mod_min,
            t_supply_sh_c=hp.t_supply_sh_c,
            t_supply_dhw_c=hp.t_supply_dhw_c,
            costs=lifecycle_costs(params, fc_lifecycle_eta),
            params=params,
            **_year_constants(params),
        )


@dataclass(frozen=True)
class HorizonData:
    """One horizon problem (arrays of length ``n``, index 0 = step k).

    Attributes
    ----------
    x0 : numpy.ndarray
        Building model state at the end of step k-1 (T_air, T_w_in, T_w_out) [degC].
    soc0, loh0 : float
        Battery and H2 levels [-].
    v0_l : float
        Usable DHW volume [l].
    fc_on_prev : bool
        FC on in step k-1 (``eq:on_off_logic``).
    t_amb_c : numpy.ndarray
        Ambient temperature forecast [degC].
    ghi_w_m2 : numpy.ndarray
        Global horizontal irradiance forecast [W/m2].
    p_pv_w, p_load_w : numpy.ndarray
        PV and appliance forecasts [W].
    q_dhw_dem_w : numpy.ndarray
        DHW demand as heat [W].
    t_min_c, t_max_c : numpy.ndarray
        Comfort bounds [degC].
    price_buy_eur_per_kwh : numpy.ndarray
        Buy tariff [EUR/kWh].
    price_sell_eur_per_kwh : float
        Sell tariff [EUR/kWh].
    cop_sh, cop_dhw : numpy.ndarray
        COP at the two supply temperatures and the forecast T_amb [-].
    p_hp_max_w : numpy.ndarray
        P_el,HP,max at the forecast T_amb [W].
    loh_min : numpy.ndarray
        Lower LOH bound per step (``eq:LOHmin_MPC``) [-].
    el_on_prev : bool
        Year-round plant: electrolyser on in step k-1.
    eer, p_cool_max_w : numpy.ndarray or None
        Year-round plant: EER [-] and cooling intake limit [W] at the forecast T_amb.
    loh_season : numpy.ndarray or None
        Year-round plant: the soft seasonal LOH target per step [-].
    """

    x0: np.ndarray
    soc0: float
    loh0: float
    v0_l: float
    fc_on_prev: bool
    t_amb_c: np.ndarray
    ghi_w_m2: np.ndarray
    p_pv_w: np.ndarray
    p_load_w: np.ndarray
    q_dhw_dem_w: np.ndarray
    t_min_c: np.ndarray
    t_max_c: np.ndarray
    price_buy_eur_per_kwh: np.ndarray
    price_sell_eur_per_kwh: float
    cop_sh: np.ndarray
    cop_dhw: np.ndarray
    p_hp_max_w: np.ndarray
    loh_min: np.ndarray
    #: year-round plant: EL on in step k-1, EER and cooling intake limit at forecast T_amb,
    #: the soft seasonal LOH target per step (None where not installed)
    el_on_prev: bool = False
    eer: np.ndarray | None = None
    p_cool_max_w: np.ndarray | None = None
    loh_season: np.ndarray | None = None

    @property
    def n(self) -> int:
        """Horizon steps."""
        return len(self.t_amb_c)


def _year_constants(params: PlantParams) -> dict:
    """Electrolyser and cooling constants of :class:`PlantConstants` (empty for the paper's plant)."""
    from comems4build_ros.core.models.electrolyser import ElectrolyserTable

    out: dict = {}
    table = ElectrolyserTable(params.electrolyser)
    if table.n:
        out.update(el=True, p_el_min_w=table.p_min_w, p_el_max_w=table.p_max_w,
                   loh_per_wh_el=table.efficiency(1.0) / (params.hydrogen.e_max_kwh * W_PER_KW))
    if params.cooling.enabled:
        out.update(cooling=True, q_cool_max_w=params.cooling.q_cool_max_w)
    return out


def season_schedules(
    days_to_season: float, season_days_left: float, loh_season_start: float | None, const: PlantConstants,
    target: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Compute the hard lower LOH bound and the soft seasonal LOH target per horizon step (year-round plant).

    Inside the heating season: the bound falls linearly from ``loh_season_start`` (the LOH
    when the season began) to ``simulation.loh_season_end`` at its end, the bound of the
    current day over the whole horizon (the paper's ``day`` reading); no target. Outside it:
    the store's own LOH_min as bound, and a target rising linearly from ``loh_season_end``
    at the end of the last season to ``target`` at the start of the next (over the days
    between two seasons). Not in the paper (its winter has no electrolyser).

    Parameters
    ----------
    days_to_season : float
        Days from step k to the next heating season [d] (0 inside it).
    season_days_left : float
        Days left in the heating season [d] (0 outside it).
    loh_season_start : float or None
        LOH when the current season began [-] (None outside a season).
    const : PlantConstants
        The plant's constants (``simulation.loh_season_end``, the season's dates).
    target : float
        LOH the target rises to by the next season [-] (``loh_season_target``).

    Returns
    -------
    bound : numpy.ndarray
        Lower bound per step [-] (``eq:LOHmin_MPC`` over the heating season).
    target : numpy.ndarray
        Soft target per step [-] (0 inside the season).
    """
    sim = const.params.simulation
    end = sim.loh_season_end
    n = const.n
    if season_days_left > 0.0 and loh_season_start is not None:
        season_len = _season_length_days(sim)
        day_no = np.floor(season_len - season_days_left) + 1.0
        bound = loh_season_start - max(loh_season_start - end, 0.0) * day_no / season_len
        return np.full(n, max(bound, const.loh_lower)), np.zeros(n)
    gap = 365.0 - _season_length_days(sim)
    ahead = days_to_season - np.arange(n) * const.dt_h / 24.0
    share = np.clip(1.0 - ahead / gap, 0.0, 1.0)
    return np.full(n, const.loh_lower), end + (target - end) * share


def _season_length_days(sim) -> float:
    """Days of the heating season (``heating_season_start`` .. ``_end``, a non-leap year)."""
    import datetime as _dt

    sm, sd = (int(x) for x in sim.heating_season_start.split("-"))
    em, ed = (int(x) for x in sim.heating_season_end.split("-"))
    start = _dt.date(2001, sm, sd)
    end = _dt.date(2001 if (em, ed) > (sm, sd) else 2002, em, ed)
    return float((end - start).days)


def loh_min_schedule(
    day_index: int, hour_of_day: int, dloh_per_day: float, const: PlantConstants, mode: str
) -> np.ndarray:
    """Compute the lower LOH bound of each horizon step, ``eq:deltaLOH`` / ``eq:LOHmin_MPC``.

    ``LOH_min = LOH_init - dLOH * (number of the day)`` with the day counted from 1
    (LOH_init = LOH_max in the paper). Mode ``day`` (the paper's): the bound of the
    current day holds over the whole horizon; ``step``: each step gets the bound of the
    day it falls in. Never below the store's own ``loh_min``.

    Parameters
    ----------
    day_index : int
        Day of step k since the start of the period [d].
    hour_of_day : int
        Hour of step k [h].
    dloh_per_day : float
        Allowance of ``eq:deltaLOH`` [fraction of the store per day].
    const : PlantConstants
        The plant's constants.
    mode : {"day", "step"}
        The reading (above).

    Returns
    -------
    numpy.ndarray
        The bound per step [-].

    Raises
    ------
    ValueError
        For an unknown mode.
    """
    steps = np.arange(const.n)
    if mode == "day":
        day_no = np.full(const.n, day_index + 1)
    elif mode == "step":
        day_no = day_index + 1 + ((hour_of_day + steps * const.dt_h) // 24).astype(int)
    else:
        raise ValueError(f"loh_min_mode: unknown value '{mode}' (day, step)")
    return np.maximum(const.loh_init - dloh_per_day * day_no, const.loh_lower)


def build_horizon(obs: Observation, const: PlantConstants, loh_min_mode: str = "day") -> HorizonData:
    """Build the horizon numbers from an observation of level "mpc" and the plant constants.

    Parameters
    ----------
    obs : Observation
        The step's inputs (MPC level: states of step k-1 and 24-step forecasts).
    const : PlantConstants
        The plant's constants.
    loh_min_mode : {"day", "step"}
        The reading of ``eq:LOHmin_MPC`` (:func:`loh_min_schedule`).

    Returns
    -------
    HorizonData
        The horizon problem's numbers.

    Raises
    ------
    ValueError
        For a forecast of another length than the horizon or holding NaN or inf.
    """
    fc = obs.forecast
    n = const.n

    def series(key: str) -> np.ndarray:
        arr = np.asarray(fc[key], dtype=float)
        if arr.shape != (n,):
            raise ValueError(f"MPC observation: forecast '{key}' has {arr.size} values, expected {n}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"MPC observation: forecast '{key}' holds NaN or inf")
        return arr

    t_amb = series("t_amb_c")
    hp = const.params.heat_pump
    dhw_l = series("dhw_l_per_h")
    return HorizonData(
        x0=np.array([obs.t_air_c, obs.t_wall_in_c, obs.t_wall_out_c], dtype=float),
        soc0=float(obs.soc),
        loh0=float(obs.loh),
        v0_l=float(obs.v_dhw_l),
        fc_on_prev=bool(obs.fc_on_prev),
        t_amb_c=t_amb,
        ghi_w_m2=series("ghi_w_m2"),
        p_pv_w=series("p_pv_w"),
        p_load_w=series("p_load_w"),
        q_dhw_dem_w=np.asarray(dhw.heat_w_from_l_per_h(dhw_l, const.params.dhw), dtype=float),
        t_min_c=series("t_min_c"),
        t_max_c=series("t_max_c"),
        price_buy_eur_per_kwh=series("price_buy_eur_per_kwh"),
        price_sell_eur_per_kwh=float(obs.price_sell_eur_per_kwh),
        cop_sh=np.asarray(heat_pump.cop(t_amb, const.t_supply_sh_c, hp), dtype=float),
        cop_dhw=np.asarray(heat_pump.cop(t_amb, const.t_supply_dhw_c, hp), dtype=float),
        p_hp_max_w=np.asarray(heat_pump.p_el_max_w(t_amb, hp), dtype=float),
        loh_min=loh_min_schedule(int(obs.day_index), int(obs.hour_of_day), float(obs.dloh_per_day), const,
                                 loh_min_mode),
        **(_year_horizon(obs, t_amb, const) if const.year_round else {}),
    )


def _year_horizon(obs: Observation, t_amb: np.ndarray, const: PlantConstants) -> dict:
    """Add the year-round plant's horizon numbers (the seasonal schedules are set by the controller)."""
    from comems4build_ros.core.models.cooling import eer

    out: dict = {"el_on_prev": bool(obs.el_on_prev)}
    if const.cooling:
        e = np.asarray(eer(t_amb, const.params.cooling), dtype=float)
        out.update(eer=e, p_cool_max_w=const.q_cool_max_w / e)
    return out



# ---------------------------------------------------------------------- the same numbers on every CPU
#: Significant bits the MPC keeps of its horizon's forecasts, prices, bounds and coefficients
#: (relative step 2**-22, 2.4e-7) and of its measured temperatures, LOH and tank volume (2**-28,
#: 3.7e-9). The MIP search stops at the first plan within the gap, so which plan that is
#: depends on the last bits of these numbers; those differ between CPUs: the modelled PV and
#: load series and some plant models (the FC's polarisation curve) go through numpy's
#: transcendental functions, whose code paths numpy chooses by the CPU (glibc's on AVX2, its
#: own on AVX-512, a few ulp apart; up to 1e-10 relative after pvlib's transposition near
#: sunrise), and the plant's states then differ by an ulp. Rounded, numbers that differ in
#: their last bits become the same number, so every CPU solves the same problem and gets the
#: same plan. Both steps are far below what a forecast or a measurement knows. The SOC is
#: passed as it is: it follows from the commands by arithmetic alone (``eq:batt_soc``), so it
#: is the same on every CPU when the plans are, and rounded it made a plan that fills or
#: empties the battery ask the plant for up to 8e-5 W more than the room (a clip each time).
#: docs/mpc.md ("Reproducible plans") gives the measurements and the odds of a number on a
#: step's middle.
FORECAST_BITS = 22
STATE_BITS = 28
#: Fields of :class:`HorizonData` that are measured states rounded to :data:`STATE_BITS`.
STATE_FIELDS = ("x0", "loh0", "v0_l")
#: Fields passed as they are (see above).
EXACT_FIELDS = ("soc0",)


def round_bits(x: np.ndarray | float, bits: int) -> np.ndarray:
    """``x`` rounded to ``bits`` significant bits (round half to even); zeros and infinities kept.

    Parameters
    ----------
    x : numbers [any unit]
    bits : significant bits kept [-] (53 keeps every float as it is)

    Returns
    -------
    numpy.ndarray
        The rounded numbers, computed by exact binary operations only (``frexp``, ``ldexp``,
        ``rint``), so the same on every CPU. A number so large that rounding up would leave
        the float range is kept as it is.
    """
    x = np.asarray(x, dtype=float)
    mantissa, exponent = np.frexp(x)  # x = mantissa * 2**exponent, 0.5 <= |mantissa| < 1
    with np.errstate(over="ignore"):
        rounded = np.ldexp(np.rint(np.ldexp(mantissa, bits)), exponent - bits)
    return np.where(np.isfinite(rounded), rounded, x)


def same_on_every_cpu(h: HorizonData) -> HorizonData:
    """Round the numbers of a horizon so that every CPU solves the same problem.

    Parameters
    ----------
    h : HorizonData
        The horizon as built from the observation.

    Returns
    -------
    HorizonData
        ``h`` with its measured states (:data:`STATE_FIELDS`) rounded to :data:`STATE_BITS`
        significant bits, the SOC as it is, every other number to :data:`FORECAST_BITS`.
    """
    import dataclasses

    out: dict = {}
    for f in dataclasses.fields(h):
        if f.name in EXACT_FIELDS:
            continue
        value = getattr(h, f.name)
        bits = STATE_BITS if f.name in STATE_FIELDS else FORECAST_BITS
        if isinstance(value, np.ndarray):
            out[f.name] = round_bits(value, bits)
        elif isinstance(value, float):
            out[f.name] = float(round_bits(value, bits))
    return dataclasses.replace(h, **out)
