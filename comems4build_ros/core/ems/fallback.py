"""Safe fallback action, used when no controller command is available.

Used by the MPC when a solve yields no solution and by ``plant_sim`` when the EMS node
is silent past its timeout or sends an invalid command: heat the hot-water tank when it
nears V_min, else heat the rooms when they near T_air,min, battery and fuel cell idle,
the grid covers the load (``eq:power_balance``).
"""

from __future__ import annotations

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action

#: Fraction of the usable tank range kept as a reserve above V_min [-]: one hour of a
#: heavy draw (~40 l/h, DHWCalc peak) is about 15 % of the 260 l usable range.
DHW_RESERVE_FRACTION = 0.25
#: Margin above T_air,min below which the fallback heats the rooms [K].
T_AIR_MARGIN_K = 0.5


def safe_action(t_air_c: float, v_dhw_l: float, t_min_c: float, params: PlantParams) -> Action:
    """Decide a conservative action from the measured temperature and tank volume.

    Parameters
    ----------
    t_air_c : float
        Indoor air temperature at the start of the step [degC].
    v_dhw_l : float
        Usable hot-water volume [l].
    t_min_c : float
        Lower comfort bound of the step (``eq:T_min``) [degC].
    params : PlantParams
        Plant parameters (the tank's usable volume V_DHW,min .. V_DHW,max [l]).

    Returns
    -------
    Action
        Full-power DHW heating if the tank is within the reserve above V_min, else
        full-power space heating if the room is within ``T_AIR_MARGIN_K`` of T_min,
        else everything off; fuel cell and battery always idle.
    """
    dhw = params.dhw
    reserve_l = dhw.v_min_l + DHW_RESERVE_FRACTION * (dhw.v_max_l - dhw.v_min_l)
    if not v_dhw_l > reserve_l:  # also true for NaN: heat rather than risk running dry
        return Action(hp_mod=1.0, hp_mode=HP_DHW)
    if not t_air_c > t_min_c + T_AIR_MARGIN_K:
        return Action(hp_mod=1.0, hp_mode=HP_SH)
    return Action(hp_mod=0.0, hp_mode=HP_OFF)
