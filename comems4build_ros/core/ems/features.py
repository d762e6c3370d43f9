"""Input features shared by ComEMS4Build and the RBC (``sec:FLC``, ``sec:RBC``).

- :func:`chi_sh` thermal state of space heating, ``eq:s_sh``
- :func:`chi_dhw` thermal state of the hot-water tank, ``eq:s_dhw``
- :func:`edf_price` empirical distribution function of the day-ahead prices, ``eq:EDF_prices``
- :class:`DailyH2Allowance` bookkeeping of the daily permissible H2 use, ``eq:deltaLOH``
- :func:`update_modulation` the HP modulation update of ``sec:appendix`` (interpreted)
- :func:`hp_p_el_ref_w` the HP electrical power estimate the EMS uses for dP

All functions are plain scalar Python (one control step at a time, microseconds each).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from comems4build_ros.core.config import HeatPumpParams


def chi_cool(t_air_c: float, t_min_c: float, t_max_c: float) -> float:
    """Compute the thermal state towards the upper bound for cooling: ``eq:s_sh`` mirrored.

    ``chi_cool = sqrt((T_air,max[k] - T_air[k-1]) / (T_air,max[k] - T_air,min[k]))``, clipped to
    [0, 1] before the root: 0 at or above the upper bound (no reserve), 1 at the lower bound.
    A year-round plant's feature (not in the paper).

    Parameters
    ----------
    t_air_c : float
        Indoor air temperature of the previous step T_air[k-1] [degC].
    t_min_c, t_max_c : float
        Comfort bounds T_air,min[k] and T_air,max[k] [degC].

    Returns
    -------
    float
        chi_cool [-], in [0, 1]; with coinciding bounds 0 at or above them, else 1.
    """
    span = float(t_max_c) - float(t_min_c)
    if span <= 0.0:
        return 0.0 if t_air_c >= t_max_c else 1.0
    return math.sqrt(min(1.0, max(0.0, (float(t_max_c) - float(t_air_c)) / span)))


def chi_sh(t_air_c: float, t_min_c: float | Sequence[float], t_max_c: float) -> float:
    """Compute the thermal state of space heating ``eq:s_sh``.

    ``chi_SH = sqrt((T_air[k-1] - T_low) / (T_air,max[k] - T_low))`` with
    ``T_low = max(T_air,min[k], T_air,min[k+5])``.

    Parameters
    ----------
    t_air_c : float
        Indoor air temperature of the previous step T_air[k-1] [degC].
    t_min_c : float or Sequence[float]
        Lower comfort bound(s) [degC]: a scalar T_air,min[k] (RBC: no look-ahead,
        ``sec:RBC``) or the bounds k .. k+5 of the fuzzy EMS; their maximum is used, so
        a home period starting anywhere within the next five hours triggers pre-heating
        (the paper calls T_air,min[k+5] "the minimal temperature bound in the next five
        hours").
    t_max_c : float
        Upper comfort bound T_air,max[k] [degC].

    Returns
    -------
    float
        chi_SH [-], in [0, 1].

    Notes
    -----
    The ratio is clipped to [0, 1] before the square root: below the lower bound the
    state is 0 (no reserve), above the upper bound 1. If the bounds coincide the state
    is 0 below and 1 at or above them.
    """
    t_low = float(max(t_min_c)) if isinstance(t_min_c, Sequence | np.ndarray) else float(t_min_c)
    span = t_max_c - t_low
    if span <= 0.0:
        return 0.0 if t_air_c < t_low else 1.0
    ratio = (t_air_c - t_low) / span
    return math.sqrt(min(1.0, max(0.0, ratio)))


def chi_dhw(v_dhw_l: float, v_min_l: float, v_max_l: float) -> float:
    """Compute the thermal state of the hot-water tank ``eq:s_dhw``.

    ``chi_DHW = ((V_DHW[k-1] - V_min) / (V_max - V_min))^2``, the fill ratio clipped to [0, 1].

    Parameters
    ----------
    v_dhw_l : float
        Usable hot-water volume of the previous step V_DHW[k-1] [l].
    v_min_l, v_max_l : float
        Usable volume bounds V_DHW,min and V_DHW,max [l].

    Returns
    -------
    float
        chi_DHW [-], in [0, 1].
    """
    ratio = (v_dhw_l - v_min_l) / (v_max_l - v_min_l)
    ratio = min(1.0, max(0.0, ratio))
    return ratio * ratio


def edf_price(price_now: float, prices_24h: Sequence[float]) -> float:
    """Compute the empirical distribution function of the day-ahead prices ``eq:EDF_prices``.

    ``p_hat[k] = (1/H) * sum_i I(X_i <= p_buy[k])`` over the H = 24 day-ahead prices.

    Parameters
    ----------
    price_now : float
        Current buy price p_buy[k] [EUR/kWh].
    prices_24h : Sequence[float]
        Day-ahead buy prices of steps k .. k+23 [EUR/kWh] (the observation's
        ``prices_buy_24h``). The paper sums over i = k+1 .. k+H; the observation holds the
        24 prices known at step k, which start at k, so the window here is k .. k+H-1 and
        always counts the current price itself.

    Returns
    -------
    float
        p_hat[k] [-], in [1/H, 1]; 1 means the current price is the day's highest.

    Raises
    ------
    ValueError
        Without any day-ahead price.
    """
    n = len(prices_24h)
    if n == 0:
        raise ValueError("edf_price needs at least one day-ahead price")
    return sum(1 for p in prices_24h if p <= price_now) / n


class DailyH2Allowance:
    """Daily permissible H2 use of ComEMS4Build (``eq:deltaLOH``, ``sec:FLC``).

    The EMS observes ``dloh_per_day`` = ``24 h * LOH_init / N`` (fraction of the store per
    day, N = steps of the whole period). The paper: "This value is updated daily, as
    ComEMS4Build may not use the entire permissible amount unless necessary." Two readings:

    ``fixed``
        every day gets ``dloh_per_day``; unused H2 is not carried over.
    ``rolling``
        ``eq:deltaLOH`` is re-evaluated every day with the current level as LOH_init and
        the remaining period as N: ``(LOH[k-1] - LOH_min) / days_left`` with
        ``days_left = LOH_init / dloh_per_day - day_index`` (the period length follows from
        the observed dLOH and the configured initial level), so H2 left unused on earlier
        days is spread over the remaining ones.

    The use so far today is the drop of the observed LOH since the day's first step.
    :meth:`update` returns the remaining share of today's allowance in [0, 1], the FLC_FC
    input "dLOH" (``fig:FLC_3D``: dLOH[k-1] = 80 %).

    Parameters
    ----------
    mode : {"fixed", "rolling"}
        The reading of ``eq:deltaLOH`` (above).
    loh_init : float
        Initial H2 level of the period [-] (``simulation.loh_init``).
    loh_min : float
        Lower bound of the store [-] (``hydrogen.loh_min``).

    Attributes
    ----------
    today, remaining : float
        Today's allowance and what is left of it [fraction of the store].
    share : float
        ``remaining / today`` [-], in [0, 1].
    """

    MODES = ("fixed", "rolling")

    def __init__(self, mode: str = "fixed", loh_init: float = 1.0, loh_min: float = 0.0) -> None:
        if mode not in self.MODES:
            raise ValueError(f"unknown H2 allowance mode '{mode}' (known: {', '.join(self.MODES)})")
        self.mode = mode
        self.loh_init = loh_init
        self.loh_min = loh_min
        self.reset()

    def reset(self) -> None:
        """Forget the current day."""
        self._day: int | None = None
        self._loh_day_start = 0.0
        self.today = 0.0  # today's allowance [fraction of the store]
        self.remaining = 0.0  # [fraction of the store]
        self.share = 0.0  # [-]

    def update(self, day_index: int, loh: float, dloh_per_day: float) -> float:
        """Book the observed LOH of the previous step; return the remaining share of today.

        Parameters
        ----------
        day_index : int
            Index of the current step's day since the start of the period [d].
        loh : float
            H2 level at the end of the previous step LOH[k-1] [-].
        dloh_per_day : float
            Allowance of ``eq:deltaLOH`` [fraction of the store per day].

        Returns
        -------
        float
            The remaining share of today's allowance [-], in [0, 1] (FLC_FC's input dLOH).
        """
        if day_index != self._day:
            self._day = day_index
            self._loh_day_start = loh
            if self.mode == "rolling" and dloh_per_day > 0:
                days_left = max(1.0, self.loh_init / dloh_per_day - day_index)
                self.today = max(0.0, loh - self.loh_min) / days_left
            else:
                self.today = dloh_per_day
        used = max(0.0, self._loh_day_start - loh)
        self.remaining = max(0.0, self.today - used)
        self.share = self.remaining / self.today if self.today > 0 else 0.0
        return self.share


def update_modulation(eta_prev: float, alpha_hp: float, mod_min: float) -> float:
    """Update the HP modulation with FLC_flex's output (``sec:appendix``, interpreted).

    The paper writes ``eta_HP[k] = alpha_HP * eta_HP[k-1]`` and calls alpha_HP "the
    increment or decrement of the HP modulation factor from the previous timestep". As
    written, zero is a fixed point (an HP that is off could never start) and the output
    terms "big negative" .. "big positive" of alpha_HP would give negative modulations.
    We read alpha_HP in [-1, 1] as the increment it is described as::

        eta_raw = clip(eta_HP[k-1] + alpha_HP, 0, 1)
        eta_HP[k] = 0        if eta_raw <  mod_min / 2
                    mod_min  if mod_min / 2 <= eta_raw < mod_min
                    eta_raw  otherwise

    so "zero" holds the modulation, positive terms raise it (from 0 as well) and negative
    ones lower it, and the result always lies in {0} U [mod_min, 1] (``sec:hp``).

    Parameters
    ----------
    eta_prev : float
        Modulation of the previous step eta_HP[k-1] [-].
    alpha_hp : float
        FLC_flex output alpha_HP [-], in [-1, 1].
    mod_min : float
        Smallest non-zero modulation [-] (0.2 in the paper, ``sec:hp``).

    Returns
    -------
    float
        eta_HP[k] [-], in {0} U [mod_min, 1].
    """
    return _snap_modulation(eta_prev + alpha_hp, mod_min)


def modulation_level(alpha_hp: float, mod_min: float) -> float:
    """Read the FLC_flex output alpha_HP as the modulation level itself (the other reading).

    ``eta_HP[k] = Q(clip(alpha_HP, 0, 1))`` with the snapping of :func:`update_modulation`:
    "zero" and every negative term switch the HP off, so the rules whose output is "Z"
    mean "saving mode" as the paper says of its rule 2 (``tab:FLCflex_rules``), and the
    previous modulation plays no role.

    Parameters
    ----------
    alpha_hp : float
        FLC_flex output alpha_HP [-], in [-1, 1].
    mod_min : float
        Smallest non-zero modulation [-].

    Returns
    -------
    float
        eta_HP[k] [-], in {0} U [mod_min, 1].
    """
    return _snap_modulation(alpha_hp, mod_min)


def _snap_modulation(eta_raw: float, mod_min: float) -> float:
    """``eta_raw`` clipped to [0, 1] and snapped to {0} U [mod_min, 1] (nearest of 0 and mod_min below it)."""
    eta = min(1.0, max(0.0, eta_raw))
    if eta < mod_min:
        return mod_min if eta >= 0.5 * mod_min else 0.0
    return eta


def hp_p_el_ref_w(hp: HeatPumpParams, t_ref_c: float) -> float:
    """Look up the HP's rated electrical power P_el,max at a fixed reference temperature.

    Neither the RBC nor ComEMS4Build observes the ambient temperature
    (``tab:level_of_information``), so their estimate of the HP's electrical power in
    ``dP = P_PV - P_el,HP - P_el,load`` is ``eta_HP * P_el,max(t_ref_c)``: a constant
    taken from the device data (``heat_pump.p_el_max_*`` of the plant file) at a
    configured rating temperature, not a measurement.

    Parameters
    ----------
    hp : HeatPumpParams
        The heat pump's parameters (its P_el,max(T_amb) table [degC] -> [W]).
    t_ref_c : float
        Reference ambient temperature [degC] (EN 14511 rating point A2: 2 degC).

    Returns
    -------
    float
        P_el,max(t_ref_c) [W], interpolated linearly in the table.
    """
    return float(np.interp(t_ref_c, hp.p_el_max_t_amb_c, hp.p_el_max_w))
