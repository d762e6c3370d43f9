"""Key performance indicators of a run (``sec:evaluation_metrics``).

One function per KPI, each with a fixed short key and its unit in the docstring; the
weekly table and the run summary are built from them. Input is the per-step timeseries
(``timeseries.csv`` of a run, or the same table rebuilt from a ROS bag), so the in-process
path, the ROS path and the bag evaluation share this code and give identical figures.

Conventions: row ``k`` holds the action and flows of step ``k`` (mean powers over the
step [W]) and the state at the end of the step; the comfort bounds of row ``k`` are those
of step ``k`` (``eq:discomfort`` compares ``T_air[k]`` with ``T_air,min[k]``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import W_PER_KW

#: Hours per evaluation week.
HOURS_PER_WEEK = 168.0
#: A week counts as "with discomfort" above this many Kelvin-hours (measurement
#: resolution; a 0.01 K violation over one hour). [K*h]
DISCOMFORT_TOL_KH = 0.01
#: The H2 store counts as empty within this fraction of LOH_min. [-]
LOH_EMPTY_TOL = 1e-6
#: A step counts as one with unmet hot-water demand above this heat flow: 1e-3 W over a
#: 1-h step is the KPIs' energy resolution of 1e-6 kWh. [W]
DHW_UNMET_TOL_W = 1e-3
#: When within a step the air temperature is compared with the comfort band
#: (``eq:discomfort`` samples ``T_air[k]`` without saying where in step ``k``):
#: ``end`` = the state at the end of the step (the plant's ``T_air[k]``), ``start`` = the
#: state at its start (``T_air[k-1]``, what the EMS saw), ``mean`` = the mean of both.
DISCOMFORT_SAMPLES = ("end", "start", "mean")

#: Resolution at which every KPI is reported, by unit: values are rounded to it, so a
#: magnitude below it is 0 (a 1-week MPC run sums 1.6e-14 K*h of float noise as
#: discomfort; reported, that is 0). Stated in every summary as ``kpi_resolution``.
KPI_RESOLUTION: dict[str, float] = {
    "K*h": 1e-6,  # discomfort
    "h": 1e-6,  # hours (outside the band, FC working hours)
    "EUR": 1e-6,  # costs and reimbursements
    "kWh": 1e-6,  # energies
    "W": 1e-6,  # mean powers
    "-": 1e-9,  # fractions (LOH, efficiency)
}
#: Key tokens -> unit of :data:`KPI_RESOLUTION`, tried in order (``h2_kwh_week_min`` -> kWh).
_UNIT_TOKENS = (("kh", "K*h"), ("kwh", "kWh"), ("eur", "EUR"), ("w", "W"), ("hours", "h"), ("h", "h"),
                ("loh", "-"), ("eta", "-"))
#: Checks of the numerics that are reported unrounded (their size is the point).
UNROUNDED_KEYS = ("max_balance_residual_w",)

#: Timeseries columns the KPIs read.
REQUIRED_COLUMNS = (
    "time",
    "t_air_c",
    "t_min_c",
    "t_max_c",
    "p_buy_w",
    "p_sell_w",
    "price_buy_eur_per_kwh",
    "price_sell_eur_per_kwh",
    "p_ch_w",
    "p_dis_w",
    "p_fc_w",
    "p_h2_w",
    "eta_fc_el",
    "q_fc_rec_w",
    "q_fc_dump_w",
    "q_dhw_demand_w",
    "q_dhw_loss_w",
    "q_dhw_unmet_w",
    "p_hp_el_w",
    "q_hp_sh_w",
    "q_hp_dhw_w",
    "p_pv_w",
    "p_load_w",
    "fc_on",
    "fc_start",
    "loh",
    "balance_residual_w",
    "clipped",
)


def _energy_kwh(power_w: np.ndarray, dt_h: float) -> float:
    """``t_s * sum(P)`` in kWh for mean powers [W] over steps of ``dt_h`` hours."""
    return float(np.sum(power_w) * dt_h / W_PER_KW)


def discomfort_kh(t_air_c: np.ndarray, t_min_c: np.ndarray, t_max_c: np.ndarray, dt_h: float) -> float:
    """Thermal discomfort ``eq:discomfort``: band violation integrated over time.

    ``d = t_s * sum_k (max(T_min[k] - T[k], 0) + max(T[k] - T_max[k], 0))``.

    Parameters
    ----------
    t_air_c : numpy.ndarray
        Air temperature compared with the band, per step [degC].
    t_min_c, t_max_c : numpy.ndarray
        Comfort bounds T_air,min and T_air,max of each step (``eq:T_min``) [degC].
    dt_h : float
        Step t_s [h].

    Returns
    -------
    float
        Discomfort [K*h].
    """
    below = np.clip(t_min_c - t_air_c, 0.0, None)
    above = np.clip(t_air_c - t_max_c, 0.0, None)
    return float(np.sum(below + above) * dt_h)


def discomfort_hours(t_air_c: np.ndarray, t_min_c: np.ndarray, t_max_c: np.ndarray, dt_h: float) -> float:
    """Time outside the comfort band (CityLearn's share of time, as hours).

    Parameters
    ----------
    t_air_c, t_min_c, t_max_c : numpy.ndarray
        Air temperature and its bounds per step, as for :func:`discomfort_kh` [degC].
    dt_h : float
        Length of a step [h].

    Returns
    -------
    float
        Hours with the temperature below T_min or above T_max [h].
    """
    return float(np.count_nonzero((t_air_c < t_min_c) | (t_air_c > t_max_c)) * dt_h)


def cost_eur(price_eur_per_kwh: np.ndarray, power_w: np.ndarray, dt_h: float) -> float:
    """Energy cost or reimbursement ``eq:costs``: ``t_s * sum(p[k] * P[k])``.

    Parameters
    ----------
    price_eur_per_kwh : numpy.ndarray
        Price p_buy or p_sell of each step [EUR/kWh].
    power_w : numpy.ndarray
        Mean power P_buy or P_sell of each step [W].
    dt_h : float
        Step t_s [h].

    Returns
    -------
    float
        Cost or reimbursement [EUR].
    """
    return float(np.sum(price_eur_per_kwh * power_w) * dt_h / W_PER_KW)


def fc_working_hours(fc_on: np.ndarray, dt_h: float) -> float:
    """Fuel-cell working hours ``eq:working_hours``: ``t_s * sum(s_FC[k])``.

    Parameters
    ----------
    fc_on : numpy.ndarray
        s_FC of each step (non-zero: on).
    dt_h : float
        Step t_s [h].

    Returns
    -------
    float
        Working hours [h].
    """
    return float(np.count_nonzero(fc_on) * dt_h)


def fc_toggles(fc_start: np.ndarray) -> int:
    """Fuel-cell start-ups ``eq:on_off_switching``: ``sum(s_FC,on[k])``.

    Parameters
    ----------
    fc_start : numpy.ndarray
        s_FC,on of each step (non-zero: started, ``eq:on_off_logic``).

    Returns
    -------
    int
        Number of start-ups [-].
    """
    return int(np.count_nonzero(fc_start))


def comfort_sample_c(ts: pd.DataFrame, sample: str = "end", t_air_init_c: float | None = None) -> np.ndarray:
    """Return the air temperature compared with the comfort band in each step.

    ``eq:discomfort`` does not say where within step k it reads T_air[k]; the readings are
    :data:`DISCOMFORT_SAMPLES`.

    Parameters
    ----------
    ts : pandas.DataFrame
        Per-step timeseries; ``t_air_c`` is the state at the end of each step [degC].
    sample : str, optional
        ``end`` (default), ``start`` or ``mean``.
    t_air_init_c : float, optional
        Air temperature before the first step, for ``start`` and ``mean`` [degC]; default:
        the first end-of-step value.

    Returns
    -------
    numpy.ndarray
        One temperature per step [degC].

    Raises
    ------
    ValueError
        For an unknown ``sample``.
    """
    end = ts["t_air_c"].to_numpy(dtype=float)
    if sample == "end":
        return end
    if sample not in DISCOMFORT_SAMPLES:
        raise ValueError(f"unknown discomfort sample '{sample}' (known: {', '.join(DISCOMFORT_SAMPLES)})")
    first = end[0] if t_air_init_c is None else float(t_air_init_c)
    start = np.concatenate(([first], end[:-1])) if len(end) else end
    return start if sample == "start" else 0.5 * (start + end)


def _week_kpis(ts: pd.DataFrame, dt_h: float, t_comfort: np.ndarray | None = None) -> dict[str, float]:
    """All per-period KPIs of the rows ``ts`` (one week or any slice).

    ``t_comfort`` is the air temperature compared with the comfort band per row
    (:func:`comfort_sample_c`; default: the end-of-step ``t_air_c``).
    """
    col = {name: ts[name].to_numpy(dtype=float) for name in REQUIRED_COLUMNS if name != "time"}
    e = lambda name: _energy_kwh(col[name], dt_h)  # noqa: E731
    on = col["fc_on"] > 0.5
    t_c = col["t_air_c"] if t_comfort is None else t_comfort
    return {
        "hours": float(len(ts) * dt_h),
        "discomfort_kh": discomfort_kh(t_c, col["t_min_c"], col["t_max_c"], dt_h),
        "discomfort_h": discomfort_hours(t_c, col["t_min_c"], col["t_max_c"], dt_h),
        "cost_eur": cost_eur(col["price_buy_eur_per_kwh"], col["p_buy_w"], dt_h),
        "reimbursement_eur": cost_eur(col["price_sell_eur_per_kwh"], col["p_sell_w"], dt_h),
        "buy_kwh": e("p_buy_w"),
        "sell_kwh": e("p_sell_w"),
        "bess_charged_kwh": e("p_ch_w"),
        "bess_discharged_kwh": e("p_dis_w"),
        "fc_kwh": e("p_fc_w"),
        "h2_kwh": e("p_h2_w"),
        # eq:heat_recovery: all recoverable FC heat; the part the tank could use as well
        "heat_recovered_kwh": _energy_kwh(col["q_fc_rec_w"] + col["q_fc_dump_w"], dt_h),
        "heat_recovered_used_kwh": e("q_fc_rec_w"),
        "dhw_demand_kwh": _energy_kwh(col["q_dhw_demand_w"] + col["q_dhw_loss_w"], dt_h),
        "dhw_unmet_kwh": e("q_dhw_unmet_w"),
        "hp_el_kwh": e("p_hp_el_w"),
        "sh_heat_kwh": e("q_hp_sh_w"),
        "hp_dhw_heat_kwh": e("q_hp_dhw_w"),
        "pv_kwh": e("p_pv_w"),
        "load_kwh": e("p_load_w"),
        "fc_working_hours": fc_working_hours(on, dt_h),
        "fc_toggles": float(fc_toggles(col["fc_start"] > 0.5)),
        "fc_mean_load_w": float(np.mean(col["p_fc_w"][on])) if on.any() else 0.0,
        "clipped_steps": float(np.count_nonzero(col["clipped"])),
    }


#: Run totals of :func:`run_totals` (``summary.json`` keys) -> key of :func:`_week_kpis`.
RUN_TOTALS = {
    "cost_eur_total": "cost_eur",
    "reimbursement_eur_total": "reimbursement_eur",
    "discomfort_kh_total": "discomfort_kh",
    "buy_kwh_total": "buy_kwh",
    "sell_kwh_total": "sell_kwh",
}


def run_totals(ts: pd.DataFrame, dt_h: float, t_comfort: np.ndarray | None = None) -> dict[str, float]:
    """Return the run totals of the rows so far, as :func:`summarize` gives them at the end.

    The same arithmetic, each value at its :data:`KPI_RESOLUTION`.

    Parameters
    ----------
    ts : pandas.DataFrame
        Per-step timeseries with at least :data:`REQUIRED_COLUMNS`.
    dt_h : float
        Step t_s [h].
    t_comfort : numpy.ndarray, optional
        Air temperature compared with the band per step (:func:`comfort_sample_c`) [degC];
        default: the end-of-step ``t_air_c``.

    Returns
    -------
    dict of str to float
        The keys of :data:`RUN_TOTALS`: grid purchase cost ``cost_eur_total`` (gross,
        ``eq:costs``' purchase term) and feed-in reimbursement ``reimbursement_eur_total``
        [EUR], discomfort ``discomfort_kh_total`` (``eq:discomfort``) [K*h], grid import
        ``buy_kwh_total`` and export ``sell_kwh_total`` [kWh].
    """
    total = _week_kpis(ts, dt_h, t_comfort)
    return {key: at_resolution(key, total[name]) for key, name in RUN_TOTALS.items()}


def kpi_unit(key: str) -> str | None:
    """Return the unit of a KPI key, read from the tokens of its name.

    Parameters
    ----------
    key : str
        KPI key, e.g. ``h2_kwh_week_min``.

    Returns
    -------
    str or None
        A key of :data:`KPI_RESOLUTION` (``kWh``), or None for counts and text.
    """
    tokens = key.split("_")
    for token, unit in _UNIT_TOKENS:
        if token in tokens:
            return unit
    return None


def at_resolution(key: str, value: Any) -> Any:
    """Round a KPI value to the resolution of its unit (:data:`KPI_RESOLUTION`).

    Parameters
    ----------
    key : str
        KPI key; its unit comes from :func:`kpi_unit`.
    value : object
        The value.

    Returns
    -------
    object
        ``value`` rounded (as float, -0.0 as 0.0); booleans, ints, text, None, non-finite
        values and :data:`UNROUNDED_KEYS` unchanged.
    """
    unit = kpi_unit(key)
    if unit is None or key in UNROUNDED_KEYS or isinstance(value, bool | int | str) or value is None:
        return value
    value = float(value)
    if not np.isfinite(value):
        return value
    decimals = int(round(-np.log10(KPI_RESOLUTION[unit])))
    return round(value, decimals) + 0.0  # + 0.0 turns -0.0 into 0.0


def weekly_kpis(
    ts: pd.DataFrame, dt_h: float = 1.0, discomfort_sample: str = "end", t_air_init_c: float | None = None
) -> pd.DataFrame:
    """One row of KPIs per week of the run; a last partial week gets its own row, marked.

    Parameters
    ----------
    ts : pandas.DataFrame
        Per-step timeseries with at least :data:`REQUIRED_COLUMNS`.
    dt_h : float, optional
        Step t_s [h].
    discomfort_sample : str, optional
        Where in a step the air temperature is compared (:func:`comfort_sample_c`).
    t_air_init_c : float, optional
        Air temperature before the first step [degC] (:func:`comfort_sample_c`).

    Returns
    -------
    pandas.DataFrame
        Columns ``week`` (1-based), ``start`` (ISO time of the week's first step),
        ``full_week`` (False for a last week shorter than 168 h, which the weekly medians
        leave out) and the keys of the per-period KPIs (units in the names: kh = K*h, eur,
        kwh, h, w), each at its :data:`KPI_RESOLUTION`.

    Raises
    ------
    ValueError
        If ``ts`` lacks a column of :data:`REQUIRED_COLUMNS`.
    """
    missing = [c for c in REQUIRED_COLUMNS if c not in ts.columns]
    if missing:
        raise ValueError(f"timeseries lacks column(s): {', '.join(missing)}")
    steps_per_week = int(round(HOURS_PER_WEEK / dt_h))
    t_comfort = comfort_sample_c(ts, discomfort_sample, t_air_init_c)
    rows = []
    for w, start in enumerate(range(0, len(ts), steps_per_week)):
        part = ts.iloc[start : start + steps_per_week]
        t_part = t_comfort[start : start + steps_per_week]
        kpis = {k: at_resolution(k, v) for k, v in _week_kpis(part, dt_h, t_part).items()}
        rows.append({"week": w + 1, "start": str(part["time"].iloc[0]), "full_week": len(part) == steps_per_week,
                     **kpis})
    return pd.DataFrame(rows)


def median_weeks(weekly: pd.DataFrame) -> pd.DataFrame:
    """Select the weeks the weekly medians and extremes are taken over: the full weeks.

    A run shorter than one week has no full week; then its one partial week is used
    (and :func:`summarize` says so in ``week_medians_over``).

    Parameters
    ----------
    weekly : pandas.DataFrame
        Output of :func:`weekly_kpis`.

    Returns
    -------
    pandas.DataFrame
        The rows with ``full_week``, or all rows if there is none.
    """
    if "full_week" not in weekly:
        return weekly
    full = weekly[weekly["full_week"].astype(bool)]
    return full if len(full) else weekly


def h2_empty_at(ts: pd.DataFrame, loh_min: float, dt_h: float = 1.0) -> str | None:
    """Return when the H2 store first reached LOH_min (within :data:`LOH_EMPTY_TOL`).

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries with ``time`` (step start) and ``loh`` (end of step) [-].
    loh_min : float
        Lower bound of the store [-].
    dt_h : float, optional
        Step t_s [h].

    Returns
    -------
    str or None
        ISO time of the end of that step, or None if the store never reached it.
    """
    loh = ts["loh"].to_numpy(dtype=float)
    hit = np.flatnonzero(loh <= loh_min + LOH_EMPTY_TOL)
    if hit.size == 0:
        return None
    start = pd.Timestamp(ts["time"].iloc[int(hit[0])])
    return (start + pd.Timedelta(hours=dt_h)).isoformat()


def dhw_unmet_steps(ts: pd.DataFrame) -> tuple[int, str | None]:
    """Count the steps whose hot-water draw and standing loss the tank could not serve.

    A step counts when ``q_dhw_unmet_w`` is above :data:`DHW_UNMET_TOL_W`: the tank sat at
    V_DHW,min (``sec:dhw``).

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries with ``time`` and ``q_dhw_unmet_w`` [W].

    Returns
    -------
    tuple of (int, str or None)
        Number of such steps, and the ISO start time of the first (None if there is none).
    """
    hit = np.flatnonzero(ts["q_dhw_unmet_w"].to_numpy(dtype=float) > DHW_UNMET_TOL_W)
    if hit.size == 0:
        return 0, None
    return int(hit.size), pd.Timestamp(ts["time"].iloc[int(hit[0])]).isoformat()


def heat_recovered_at(ts: pd.DataFrame, eta_sys: float, dt_h: float = 1.0) -> pd.Series:
    """Return the FC heat of each step at system efficiency ``eta_sys`` for the run's own dispatch.

    ``eq:FC_sys_efficiency``: ``Q_hr = n_FC * LHV * (eta_sys - eta_el)``, i.e. the step's H2
    power ``p_h2_w`` (LHV) times ``eta_sys - eta_el`` while the FC is on. The paper evaluates
    the heat recovery "if the overall FC system efficiency could achieve 90 %"
    (``sec:heat_recovery``); this is that evaluation without simulating the run again.

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries with ``p_h2_w`` [W], ``eta_fc_el`` [-] and ``fc_on``.
    eta_sys : float
        Fuel-cell system efficiency eta_sys,FC [-].
    dt_h : float, optional
        Step t_s [h].

    Returns
    -------
    pandas.Series
        Recoverable heat of each step, 0 while the fuel cell is off [kWh].
    """
    on = ts["fc_on"].astype(bool).to_numpy()
    q_w = ts["p_h2_w"].to_numpy(dtype=float) * np.maximum(eta_sys - ts["eta_fc_el"].to_numpy(dtype=float), 0.0)
    return pd.Series(np.where(on, q_w, 0.0) * dt_h / W_PER_KW, index=ts.index)


def h2_left_value_eur(loh_end: float, loh_min: float, e_h2_max_kwh: float, price_eur_per_kwh: float) -> float:
    """Value of the usable H2 left at the end (``sec:results``).

    ``(LOH_end - LOH_min) * E_H2,max * p_buy,avg``: the paper values the H2 its EMS leave in
    the store at the run's mean buy price (68.68 / 97.75 / 36.04 EUR for RBC /
    ComEMS4Build / MPC).

    Parameters
    ----------
    loh_end, loh_min : float
        H2 level at the end and its lower bound [-].
    e_h2_max_kwh : float
        LHV energy of the full store E_H2,max [kWh].
    price_eur_per_kwh : float
        Mean buy price of the run p_buy,avg [EUR/kWh].

    Returns
    -------
    float
        Value of the H2 above LOH_min, 0 if none is left [EUR].
    """
    return max(loh_end - loh_min, 0.0) * e_h2_max_kwh * price_eur_per_kwh


# Long on purpose: one line per KPI of the run summary (sec:evaluation_metrics and the
# project's additions), in the order of summary.json, so that each key has one visible home.
def summarize(
    ts: pd.DataFrame,
    weekly: pd.DataFrame,
    loh_min: float,
    dt_h: float = 1.0,
    extra: Mapping[str, Any] | None = None,
    e_h2_max_kwh: float | None = None,
    t_comfort: np.ndarray | None = None,
) -> dict[str, Any]:
    """Summarise a run (``summary.json``): weekly medians, extremes and run totals.

    Medians, minima, maxima and the spread over weeks are taken over the full weeks
    (:func:`median_weeks`); ``weeks`` counts every row of ``weekly`` (a last partial week
    included), ``full_weeks`` and ``partial_week_h`` say which. ``fallback_steps`` counts
    the steps on a safe fallback action, whether the plant applied it (no valid command in
    time, column ``fallback``) or the EMS did (no solution, column ``ems_fallback``);
    ``ems_fallback_steps`` the latter alone. ``dhw_unmet_steps`` and ``dhw_unmet_first``
    say in how many steps, and from when, the tank could not serve the hot-water demand
    (:func:`dhw_unmet_steps`). KPIs are rounded to :data:`KPI_RESOLUTION`.

    Parameters
    ----------
    ts : pandas.DataFrame
        Per-step timeseries with at least :data:`REQUIRED_COLUMNS` (optional columns
        ``fallback``, ``ems_fallback``, ``ems_slack_used``).
    weekly : pandas.DataFrame
        Output of :func:`weekly_kpis`.
    loh_min : float
        Lower bound of the H2 store [-].
    dt_h : float, optional
        Step t_s [h].
    extra : mapping, optional
        Entries added as they are (e.g. ``ems``, ``scenario``, ``wall_s``).
    e_h2_max_kwh : float, optional
        LHV energy of the full H2 store [kWh]; with it the summary values the H2 left
        (:func:`h2_left_value_eur`) and gives the cost net of that value.
    t_comfort : numpy.ndarray, optional
        Air temperature compared with the comfort band per step (:func:`comfort_sample_c`;
        default: end of step), as for ``weekly`` [degC].

    Returns
    -------
    dict
        The summary keys (units in the names: ``_eur`` [EUR], ``_kwh`` [kWh], ``_kh``
        [K*h], ``_w`` [W], ``_h``/``hours`` [h], LOH and efficiencies [-]), each at its
        :data:`KPI_RESOLUTION`, with ``kpi_resolution`` and ``extra``.
    """
    on = ts["fc_on"].to_numpy(dtype=float) > 0.5
    eta = ts["eta_fc_el"].to_numpy(dtype=float)
    plant_fb = ts["fallback"].astype(float).to_numpy() > 0.5 if "fallback" in ts else np.zeros(len(ts), bool)
    ems_fb = ts["ems_fallback"].astype(float).to_numpy() > 0.5 if "ems_fallback" in ts else np.zeros(len(ts), bool)
    slack = int((ts["ems_slack_used"].astype(float) > 0.5).sum()) if "ems_slack_used" in ts else 0
    unmet_steps, unmet_first = dhw_unmet_steps(ts)
    total = _week_kpis(ts, dt_h, t_comfort)
    price_mean = float(np.mean(ts["price_buy_eur_per_kwh"].to_numpy(dtype=float)))
    loh_end = float(ts["loh"].iloc[-1])
    weeks = median_weeks(weekly)
    full = int(weekly["full_week"].astype(bool).sum()) if "full_week" in weekly else len(weekly)
    partial_h = float(weekly["hours"].iloc[-1]) if full < len(weekly) else 0.0
    med = weeks.median(numeric_only=True)
    summary: dict[str, Any] = {
        "weeks": int(len(weekly)),
        "full_weeks": full,
        "partial_week_h": partial_h,
        "week_medians_over": (f"{full} full week(s)" if full else
                              f"the partial week ({partial_h:g} h; the run is shorter than a week)"),
        "steps": int(len(ts)),
        "cost_eur_week_median": float(med["cost_eur"]),
        "reimbursement_eur_week_median": float(med["reimbursement_eur"]),
        "discomfort_kh_week_median": float(med["discomfort_kh"]),
        "discomfort_weeks_nonzero": int((weekly["discomfort_kh"] > DISCOMFORT_TOL_KH).sum()),
        "buy_kwh_week_median": float(med["buy_kwh"]),
        "sell_kwh_week_median": float(med["sell_kwh"]),
        "bess_charged_kwh_week_median": float(med["bess_charged_kwh"]),
        # weekly H2 use as LHV energy drawn from the store and as the FC's electrical output
        # (the paper's "H2 consumption" ranges fit the electrical output), over the full weeks
        "h2_kwh_week_min": float(weeks["h2_kwh"].min()),
        "h2_kwh_week_max": float(weeks["h2_kwh"].max()),
        "h2_kwh_week_std": float(weeks["h2_kwh"].std(ddof=0)),
        "fc_kwh_week_min": float(weeks["fc_kwh"].min()),
        "fc_kwh_week_max": float(weeks["fc_kwh"].max()),
        "fc_working_hours": total["fc_working_hours"],
        "fc_toggles": int(total["fc_toggles"]),
        "fc_mean_load_w": total["fc_mean_load_w"],
        "fc_mean_eta_el": float(np.mean(eta[on])) if on.any() else 0.0,
        "loh_end": loh_end,
        "h2_empty_at": h2_empty_at(ts, loh_min, dt_h),
        "dhw_unmet_kwh": total["dhw_unmet_kwh"],
        "dhw_unmet_steps": unmet_steps,
        "dhw_unmet_first": unmet_first,
        "max_balance_residual_w": float(np.max(np.abs(ts["balance_residual_w"].to_numpy(dtype=float)))),
        "clipped_actions": int(total["clipped_steps"]),
        "fallback_steps": int(np.count_nonzero(plant_fb | ems_fb)),
        "ems_fallback_steps": int(np.count_nonzero(ems_fb)),
        "slack_steps": slack,
        "cost_eur_total": total["cost_eur"],
        "reimbursement_eur_total": total["reimbursement_eur"],
        "discomfort_kh_total": total["discomfort_kh"],
        "buy_kwh_total": total["buy_kwh"],
        "sell_kwh_total": total["sell_kwh"],
        "bess_charged_kwh_total": total["bess_charged_kwh"],
        "h2_kwh_total": total["h2_kwh"],
        "heat_recovered_kwh_total": total["heat_recovered_kwh"],
        "dhw_demand_kwh_total": total["dhw_demand_kwh"],
        "fc_kwh_total": total["fc_kwh"],
        "price_buy_mean_eur_per_kwh": price_mean,
        "price_paid_mean_eur_per_kwh": total["cost_eur"] / total["buy_kwh"] if total["buy_kwh"] > 0 else None,
    }
    if e_h2_max_kwh is not None:
        value = h2_left_value_eur(loh_end, loh_min, e_h2_max_kwh, price_mean)
        summary["h2_left_kwh"] = max(loh_end - loh_min, 0.0) * e_h2_max_kwh
        summary["h2_left_value_eur"] = value
        summary["cost_net_eur_total"] = total["cost_eur"] - total["reimbursement_eur"] - value
    summary = {k: at_resolution(k, v) for k, v in summary.items()}
    summary["kpi_resolution"] = dict(KPI_RESOLUTION)
    if extra:
        summary.update(extra)
    return summary


# ----------------------------------------------------------------------------- year
#: HP circuits of the ``hp_mode`` column (``comems4build_ros.core.types``) in the monthly table.
_HP_COLUMNS = (("hp_heating_kwh", 1), ("hp_dhw_kwh", 2), ("hp_cooling_kwh", 3))


def _sum_kwh(ts: pd.DataFrame, column: str, dt_h: float, mask: np.ndarray | None = None) -> float:
    """Return the energy [kWh] of a power column [W], over the steps of ``mask`` if given."""
    values = ts[column].to_numpy(dtype=float)
    if mask is not None:
        values = values[mask]
    return _energy_kwh(values, dt_h)


def energy_balance_rel_error(ts: pd.DataFrame) -> float:
    """Relative error of the run's energy balance (``eq:power_balance`` summed over the run).

    Supply: PV, grid purchase, FC, battery discharge; demand: sale, appliances, HP, battery
    charge, electrolyser. Throughput: the supply's sum.

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries with the power columns of both sides [W].

    Returns
    -------
    float
        ``|supply - demand| / supply``, 0 without supply [-].
    """
    col = {c: ts[c].to_numpy(dtype=float) for c in ("p_pv_w", "p_buy_w", "p_fc_w", "p_dis_w", "p_sell_w",
                                                     "p_load_w", "p_hp_el_w", "p_ch_w", "p_el_w")}
    supply = float(np.sum(col["p_pv_w"] + col["p_buy_w"] + col["p_fc_w"] + col["p_dis_w"]))
    demand = float(np.sum(col["p_sell_w"] + col["p_load_w"] + col["p_hp_el_w"] + col["p_ch_w"] + col["p_el_w"]))
    return abs(supply - demand) / supply if supply > 0 else 0.0


def monthly_table(ts: pd.DataFrame, dt_h: float = 1.0, t_comfort: np.ndarray | None = None) -> pd.DataFrame:
    """Tabulate energy and comfort per calendar month (local time) of a run.

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries of a year-round run (with ``hp_mode``, ``p_el_w``, ``p_h2_el_w``).
    dt_h : float, optional
        Step t_s [h].
    t_comfort : numpy.ndarray, optional
        Air temperature compared with the bounds per step [degC]; default: end of step.

    Returns
    -------
    pandas.DataFrame
        One row per month: ``month`` (``YYYY-MM``), ``hours`` [h]; bought, sold, PV,
        appliances, EL input, H2 produced (LHV), FC output, HP electricity for heating,
        hot water and cooling [kWh]; ``discomfort_kh`` (both bounds) and
        ``overheating_kh`` (above the upper bound) [K*h]; ``cost_eur`` net of the
        reimbursement [EUR]; ``loh_end`` at the end of the month [-].
    """
    month = ts["time"].astype(str).str[:7].to_numpy()
    t = ts["t_air_c"].to_numpy(dtype=float) if t_comfort is None else np.asarray(t_comfort, dtype=float)
    rows = []
    for m in pd.unique(month):
        sel = month == m
        part = ts[sel]
        mode = part["hp_mode"].to_numpy(dtype=float)
        tc = t[sel]
        row: dict[str, Any] = {"month": m, "hours": float(sel.sum() * dt_h)}
        for key, col in (("bought_kwh", "p_buy_w"), ("sold_kwh", "p_sell_w"), ("pv_kwh", "p_pv_w"),
                         ("load_kwh", "p_load_w"), ("el_input_kwh", "p_el_w"), ("h2_produced_kwh", "p_h2_el_w"),
                         ("fc_output_kwh", "p_fc_w")):
            row[key] = _sum_kwh(part, col, dt_h)
        for key, code in _HP_COLUMNS:
            row[key] = _sum_kwh(part, "p_hp_el_w", dt_h, mode == code)
        row["discomfort_kh"] = discomfort_kh(tc, part["t_min_c"].to_numpy(float), part["t_max_c"].to_numpy(float), dt_h)
        row["overheating_kh"] = float(np.sum(np.clip(tc - part["t_max_c"].to_numpy(float), 0.0, None)) * dt_h)
        row["cost_eur"] = (
            cost_eur(part["price_buy_eur_per_kwh"].to_numpy(float), part["p_buy_w"].to_numpy(float), dt_h)
            - cost_eur(part["price_sell_eur_per_kwh"].to_numpy(float), part["p_sell_w"].to_numpy(float), dt_h))
        row["loh_end"] = float(part["loh"].iloc[-1])
        rows.append({k: at_resolution(k, v) for k, v in row.items()})
    return pd.DataFrame(rows)


def in_heating_season(times: pd.Series, tz: Any, season_start: str, season_end: str) -> np.ndarray:
    """Tell whether each time lies in the heating season.

    Parameters
    ----------
    times : pandas.Series
        ISO times (with their offsets).
    tz : datetime.tzinfo or None
        The local time zone the ``MM-DD`` bounds are read in; None: UTC.
    season_start, season_end : str
        Heating season as local ``MM-DD`` dates, end exclusive (``simulation.heating_season_*``);
        a start after the end wraps over the new year.

    Returns
    -------
    numpy.ndarray
        True for each time inside the season.
    """
    utc = pd.to_datetime(times.astype(str), utc=True)
    local = utc.dt.tz_convert(tz) if tz is not None else utc
    mmdd = local.dt.strftime("%m-%d").to_numpy()
    if season_start < season_end:
        return (mmdd >= season_start) & (mmdd < season_end)
    return (mmdd >= season_start) | (mmdd < season_end)


def loh_heating_season_start(ts: pd.DataFrame, season_start: str, season_end: str) -> float | None:
    """Return the LOH when the run's first heating season starts.

    Parameters
    ----------
    ts : pandas.DataFrame
        The run's timeseries (``time``, ``loh``).
    season_start, season_end : str
        Heating season as local ``MM-DD`` dates, end exclusive (``simulation.heating_season_*``).

    Returns
    -------
    float or None
        The end state of the step before the season's first step [-]; None when the run
        starts inside the season or never reaches it.
    """
    tz = pd.Timestamp(str(ts["time"].iloc[0])).tzinfo
    in_season = in_heating_season(ts["time"], tz, season_start, season_end)
    first = np.flatnonzero(in_season & ~np.concatenate(([True], in_season[:-1])))
    return float(ts["loh"].iloc[first[0] - 1]) if len(first) and first[0] > 0 else None


def year_kpis(
    ts: pd.DataFrame, weekly: pd.DataFrame, dt_h: float, season_start: str, season_end: str,
    t_comfort: np.ndarray | None = None,
) -> dict[str, Any]:
    """Compute the KPIs of a year-round run with an electrolyser and cooling.

    Parameters
    ----------
    ts : pandas.DataFrame
        The run's timeseries.
    weekly : pandas.DataFrame
        Its weekly table (:func:`weekly_kpis`).
    dt_h : float
        Step t_s [h].
    season_start, season_end : str
        Heating season as local ``MM-DD`` dates, end exclusive
        (``simulation.heating_season_*``).
    t_comfort : numpy.ndarray, optional
        Air temperature compared with the bounds per step [degC]; default: end of step.

    Returns
    -------
    dict
        ``h2_produced_kwh`` (LHV) [kWh], ``el_input_kwh`` (standby and compression
        included) [kWh], ``el_working_hours`` [h], ``el_starts`` [-], ``el_mean_eta`` (H2
        over the intake while producing) [-], ``h2_round_trip`` (FC electrical output over
        EL electrical input) [-], ``loh_heating_season_start`` (LOH when the first heating
        season of the run starts, or None) [-], ``self_sufficiency``
        (1 - bought / (appliances + HP + EL)) [-], ``overheating_kh`` [K*h],
        ``hp_cooling_kwh`` [kWh], ``cost_net_eur`` (bought - sold) [EUR],
        ``heating_season_weeks`` and ``heating_season_discomfort_weeks`` (full weeks starting
        in the season; those above :data:`DISCOMFORT_TOL_KH`), ``energy_balance_rel_error``
        [-].
    """
    on = ts["el_on"].to_numpy(dtype=float) > 0.5
    h2 = _sum_kwh(ts, "p_h2_el_w", dt_h)
    el_in = _sum_kwh(ts, "p_el_w", dt_h)
    el_on_in = _sum_kwh(ts, "p_el_w", dt_h, on)
    fc_out = _sum_kwh(ts, "p_fc_w", dt_h)
    consumption = _sum_kwh(ts, "p_load_w", dt_h) + _sum_kwh(ts, "p_hp_el_w", dt_h) + el_in
    bought = _sum_kwh(ts, "p_buy_w", dt_h)
    t = ts["t_air_c"].to_numpy(dtype=float) if t_comfort is None else np.asarray(t_comfort, dtype=float)
    tz = pd.Timestamp(str(ts["time"].iloc[0])).tzinfo
    loh_start = loh_heating_season_start(ts, season_start, season_end)
    wk_season = in_heating_season(weekly["start"], tz, season_start, season_end)
    full = weekly["full_week"].astype(bool).to_numpy() if "full_week" in weekly else np.ones(len(weekly), bool)
    wk_season &= full
    mode = ts["hp_mode"].to_numpy(dtype=float)
    out = {
        "h2_produced_kwh": h2,
        "el_input_kwh": el_in,
        "el_working_hours": float(np.count_nonzero(on) * dt_h),
        "el_starts": int(np.count_nonzero(ts["el_start"].to_numpy(dtype=float) > 0.5)),
        "el_mean_eta": h2 / el_on_in if el_on_in > 0 else 0.0,
        "h2_round_trip": fc_out / el_in if el_in > 0 else 0.0,
        "loh_heating_season_start": loh_start,
        "self_sufficiency": 1.0 - bought / consumption if consumption > 0 else 0.0,
        "overheating_kh": float(np.sum(np.clip(t - ts["t_max_c"].to_numpy(float), 0.0, None)) * dt_h),
        "hp_cooling_kwh": _sum_kwh(ts, "p_hp_el_w", dt_h, mode == 3),
        "cost_net_eur": (cost_eur(ts["price_buy_eur_per_kwh"].to_numpy(float), ts["p_buy_w"].to_numpy(float), dt_h)
                         - cost_eur(ts["price_sell_eur_per_kwh"].to_numpy(float), ts["p_sell_w"].to_numpy(float),
                                    dt_h)),
        "heating_season_weeks": int(np.count_nonzero(wk_season)),
        "heating_season_discomfort_weeks": int(np.count_nonzero(
            wk_season & (weekly["discomfort_kh"].to_numpy(float) > DISCOMFORT_TOL_KH))),
    }
    out = {k: (at_resolution(k, v) if v is not None else None) for k, v in out.items()}
    out["energy_balance_rel_error"] = energy_balance_rel_error(ts)
    return out
