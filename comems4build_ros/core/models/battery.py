"""Battery energy storage system (BESS), ``eq:batt_soc`` .. ``eq:s_summ``.

    SOC[k] = SOC[k-1] + (eta_ch * P_ch[k] * t_s - P_d[k] / eta_d * t_s) / E_B,max      (eq:batt_soc)
    SOC_min <= SOC[k] <= SOC_max                                                         (eq:SOC_const)
    s_c * P_c,min <= P_c <= s_c * P_c,max,  s_ch + s_d <= 1                              (eq:bat_ch_dis_const)

One signed set-point ``p_bess_w`` (> 0 charging, < 0 discharging) maps to exactly one of
P_ch and P_d, so the battery never charges and discharges in the same step
(``eq:s_summ``). Self-discharge is neglected as in the paper.
"""

from __future__ import annotations

from comems4build_ros.core.config import W_PER_KW, BatteryParams

#: A request that exceeds what the SOC bounds allow by no more than this [W] is cut without
#: counting as a clip: an EMS that asks for exactly the room left (charging to SOC_max)
#: computes it with a rounding that differs from the plant's in the last bits, and which way
#: those bits fall depends on the CPU's floating-point kernels.
SOC_CLIP_TOL_W = 1e-6


class Battery:
    """The battery's parameters as plain attributes, for the plant step.

    It has the fields of :class:`~comems4build_ros.core.config.BatteryParams` with the same
    values; :func:`split_power` and :func:`step` take either (reading a plain attribute costs
    a third of reading a field of the validated parameters, which the step does a dozen
    times).

    Parameters
    ----------
    b : BatteryParams
        The battery's parameters: ``e_max_kwh`` [kWh], ``p_ch_max_w``, ``p_d_max_w``,
        ``p_ch_min_w``, ``p_d_min_w`` [W], ``eta_ch``, ``eta_d``, ``soc_min``, ``soc_max`` [-].
    """

    __slots__ = ("e_max_kwh", "p_ch_max_w", "p_d_max_w", "p_ch_min_w", "p_d_min_w", "eta_ch", "eta_d", "soc_min",
                 "soc_max")

    def __init__(self, b: BatteryParams) -> None:
        for name in self.__slots__:
            setattr(self, name, getattr(b, name))


def power_limits_w(soc: float, b: BatteryParams, dt_h: float) -> tuple[float, float]:
    """Return the largest charging and discharging power the SOC bounds and power limits allow.

    Parameters
    ----------
    soc : float
        SOC[k-1] [-].
    b : BatteryParams
        The battery's parameters (``e_max_kwh`` [kWh], ratings [W], efficiencies and SOC bounds [-]).
    dt_h : float
        Step t_s [h].

    Returns
    -------
    p_ch_max_w, p_d_max_w : float
        Upper limits of P_ch and P_d in this step [W] (``eq:SOC_const`` and
        ``eq:bat_ch_dis_const`` together).
    """
    e_wh = b.e_max_kwh * W_PER_KW
    room_ch = max(0.0, (b.soc_max - soc) * e_wh / (b.eta_ch * dt_h))
    room_d = max(0.0, (soc - b.soc_min) * e_wh * b.eta_d / dt_h)
    return min(b.p_ch_max_w, room_ch), min(b.p_d_max_w, room_d)


def split_power(p_bess_w: float, soc: float, b: BatteryParams | Battery,
                dt_h: float) -> tuple[float, float, bool, bool]:
    """Clip a signed set-point to what the battery can do in one step.

    A request beyond the power rating is cut to it (``power_clipped``); a request the
    SOC bounds cannot take is cut to the SOC limit (``soc_clipped`` when the cut exceeds
    :data:`SOC_CLIP_TOL_W`); a non-zero result below the minimum power P_c,min is set to
    zero (flagged as power or SOC clip by the reason). ``p_bess_w`` must be finite.

    Parameters
    ----------
    p_bess_w : float
        Requested power [W], > 0 charging, < 0 discharging.
    soc : float
        SOC[k-1] [-].
    b : BatteryParams or Battery
        The battery's parameters.
    dt_h : float
        Step t_s [h].

    Returns
    -------
    p_ch_w, p_d_w : float
        Feasible charging and discharging power [W] (at most one non-zero; ``eq:bat_ch_dis_const``,
        ``eq:s_summ``).
    power_clipped, soc_clipped : bool
        The request was cut by the power limits or by the SOC bounds (``eq:SOC_const``).
    """
    p_ch, p_d, _, power_clipped, soc_clipped = step(p_bess_w, soc, b, dt_h)
    return p_ch, p_d, power_clipped, soc_clipped


def step(p_bess_w: float, soc: float, b: BatteryParams | Battery,
         dt_h: float) -> tuple[float, float, float, bool, bool]:
    """Advance the battery by one step for a signed set-point (``eq:batt_soc`` with the limits of :func:`split_power`).

    Parameters
    ----------
    p_bess_w : float
        Requested power [W], > 0 charging, < 0 discharging (finite).
    soc : float
        SOC[k-1] [-].
    b : BatteryParams or Battery
        The battery's parameters.
    dt_h : float
        Step t_s [h].

    Returns
    -------
    p_ch_w, p_d_w : float
        Charging and discharging power of the step [W] (as :func:`split_power`).
    soc_new : float
        SOC[k] [-] (``eq:batt_soc``, held within ``eq:SOC_const``).
    power_clipped, soc_clipped : bool
        The request was cut by the power limits or by the SOC bounds.
    """
    power_clipped = False
    soc_clipped = False
    p_ch = p_d = 0.0
    if p_bess_w > 0.0 or p_bess_w < 0.0:  # (0 and NaN: idle)
        if p_bess_w > 0.0:
            p_rated, p_min, eta = b.p_ch_max_w, b.p_ch_min_w, b.eta_ch
            room = (b.soc_max - soc) * b.e_max_kwh * W_PER_KW / (eta * dt_h)
        else:
            p_rated, p_min, eta = b.p_d_max_w, b.p_d_min_w, b.eta_d
            room = (soc - b.soc_min) * b.e_max_kwh * W_PER_KW * eta / dt_h
        p = abs(p_bess_w)
        if p > p_rated:
            p = p_rated
            power_clipped = True
        if p < p_min:
            p = 0.0
            power_clipped = True
        if p > room:
            cut = room if room > 0.0 and room >= p_min else 0.0
            soc_clipped = p - cut > SOC_CLIP_TOL_W
            p = cut
        if p_bess_w > 0.0:
            p_ch = p
        else:
            p_d = p
    soc_new = soc + (b.eta_ch * p_ch - p_d / b.eta_d) * dt_h / (b.e_max_kwh * W_PER_KW)
    if soc_new > b.soc_max:
        soc_new = b.soc_max
    elif soc_new < b.soc_min:
        soc_new = b.soc_min
    return p_ch, p_d, soc_new, power_clipped, soc_clipped
