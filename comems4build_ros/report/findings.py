"""The paper's qualitative findings, each checked by a small function over the runs.

Sources: the paper's ``sec:results`` (its parts on the time series comparison, the
occupant-oriented metrics, the HESS utilization and the grid utilization),
``sec:heat_recovery`` and ``sec:discussion``; each finding names the part it is stated in,
and numbers quoted in a claim are the paper's. Every function computes its verdict from the
run summaries, weekly tables and timeseries; nothing is hard-coded. A finding whose EMS
were not run is reported as ``n/a``.

Thresholds used by the checks (named constants below): a week "without discomfort" has
at most :data:`~comems4build_ros.core.kpi.DISCOMFORT_TOL_KH`; H2 "left" means more than
:data:`H2_LEFT_TOL` of the store above LOH_min; "full permissible power" is at least
:data:`FULL_POWER_SHARE` of ``zeta * P_FC,max``; the hysteresis band is
:data:`HYSTERESIS_BAND_K` inside each comfort bound.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.kpi import DISCOMFORT_TOL_KH, HOURS_PER_WEEK
from comems4build_ros.report.paper import H2_EMPTY_TOL, h2_empty_days_before_end, h2_floor
from comems4build_ros.report.runs import RunData

#: "H2 left" at the end: LOH above LOH_min by more than this fraction of the store [-]
#: (the same threshold as "empty", ``paper.H2_EMPTY_TOL``).
H2_LEFT_TOL = H2_EMPTY_TOL
#: RBC "empties the store early": LOH_min reached at least this many days before the end [d].
EARLY_EMPTY_DAYS = 7.0
#: "Full permissible power": mean FC load at least this share of zeta * P_FC,max [-].
FULL_POWER_SHARE = 0.95
#: Hysteresis zones: within this distance of T_air,min / T_air,max [K].
HYSTERESIS_BAND_K = 0.5
#: "Keeps the tank above half": share of V_max [-].
DHW_HALF = 0.5
#: Unmet DHW energy counted as "demand met" [kWh].
DHW_UNMET_TOL_KWH = 0.01
#: Price quartile used for "low" and "high" prices [-].
QUARTILE = 0.25

#: The paper's three schedulers; findings compare these only (baselines such as the
#: thermostat appear in the tables and figures but not in the findings).
PAPER_EMS = ("mpc", "fuzzy", "rbc")

HELD = "held"
NOT_HELD = "not held"
NA = "n/a"


@dataclass
class Context:
    """Everything the checks read.

    Attributes
    ----------
    runs : EMS name -> run at the base FC system efficiency
    variants : (EMS name, eta_sys) -> run, every efficiency including the base
    params : plant parameters of the base runs
    base_eta : FC system efficiency of the base runs [-]
    """

    runs: dict[str, RunData]
    variants: dict[tuple[str, float], RunData]
    params: PlantParams
    base_eta: float

    def s(self, ems: str, key: str) -> float:
        """Summary value ``key`` of the base run of ``ems``."""
        return float(self.runs[ems].summary[key])


@dataclass
class Verdict:
    """Outcome of one check: held / not held / n/a and the figures behind it."""

    status: str
    evidence: str


@dataclass
class Finding:
    """A qualitative finding with its source and check."""

    key: str
    source: str
    claim: str
    needs: tuple[str, ...]
    check: Callable[[Context], Verdict] = field(repr=False)

    def evaluate(self, ctx: Context) -> Verdict:
        """Run the check, or ``n/a`` when an EMS it needs was not run."""
        missing = [e for e in self.needs if e not in ctx.runs]
        if missing:
            return Verdict(NA, f"no run of {', '.join(missing)}")
        return self.check(ctx)


FINDINGS: list[Finding] = []


def finding(key: str, source: str, claim: str, needs: tuple[str, ...]) -> Callable:
    """Register a check function as a :class:`Finding`."""

    def register(fn: Callable[[Context], Verdict]) -> Callable[[Context], Verdict]:
        FINDINGS.append(Finding(key, source, claim, needs, fn))
        return fn

    return register


def _v(ok: bool, evidence: str) -> Verdict:
    return Verdict(HELD if ok else NOT_HELD, evidence)


def _f(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}"


def _listing(ctx: Context, key: str, unit: str, digits: int = 2) -> str:
    return ", ".join(f"{e} {_f(ctx.s(e, key), digits)}" for e in ctx.runs) + f" {unit}"


def _complete_weeks(run: RunData) -> pd.DataFrame:
    w = run.weekly
    return w[w["hours"] >= HOURS_PER_WEEK - 1e-9] if "hours" in w else w


def _ordered(ctx: Context, key: str) -> dict[str, tuple[float, float]]:
    """Per EMS (weekly median, run total) of a weekly KPI; totals break ties of medians."""
    return {e: (float(r.weekly[key].median()), float(r.weekly[key].sum())) for e, r in ctx.runs.items()}


def _med_tot(vals: dict[str, tuple[float, float]], unit: str) -> str:
    return ", ".join(f"{e} median {_f(m)} (total {_f(t, 1)}) {unit}" for e, (m, t) in vals.items())


# ---------------------------------------------------------------- occupants (comfort, cost)


@finding("fuzzy_discomfort_free", "paper sec:results (occupant-oriented metrics), sec:discussion",
         "ComEMS4Build: no discomfort in at "
         "least 10 of 12 weeks (scaled to the run length)", ("fuzzy",))
def _fuzzy_discomfort_free(ctx: Context) -> Verdict:
    w = ctx.runs["fuzzy"].weekly
    free = int((w["discomfort_kh"] <= DISCOMFORT_TOL_KH).sum())
    need = math.ceil(10.0 / 12.0 * len(w))
    bad = [f"week {int(r.week)}: {_f(r.discomfort_kh)} Kh" for r in w.itertuples()
           if r.discomfort_kh > DISCOMFORT_TOL_KH]
    return _v(free >= need, f"fuzzy: {free} of {len(w)} weeks without discomfort (need {need})"
              + (f"; {', '.join(bad)}" if bad else ""))


@finding("rbc_largest_discomfort", "paper sec:results (occupant-oriented metrics)", "RBC has the largest median weekly "
         "discomfort (larger than ComEMS4Build's)", ("rbc", "fuzzy"))
def _rbc_largest_discomfort(ctx: Context) -> Verdict:
    m = {e: ctx.s(e, "discomfort_kh_week_median") for e in ctx.runs}
    ok = m["rbc"] > m["fuzzy"] and all(m["rbc"] >= v for v in m.values())
    return _v(ok, "median " + _listing(ctx, "discomfort_kh_week_median", "Kh/week"))


@finding("fuzzy_cheaper_than_rbc", "paper sec:results (occupant-oriented metrics)",
         "weekly cost median lower for ComEMS4Build "
         "than for RBC", ("rbc", "fuzzy"))
def _fuzzy_cheaper(ctx: Context) -> Verdict:
    ok = ctx.s("fuzzy", "cost_eur_week_median") < ctx.s("rbc", "cost_eur_week_median")
    return _v(ok, "median " + _listing(ctx, "cost_eur_week_median", "EUR/week"))


@finding("fuzzy_buys_less_than_rbc", "paper sec:results (grid utilization)", "purchased energy median lower for "
         "ComEMS4Build than for RBC", ("rbc", "fuzzy"))
def _fuzzy_buys_less(ctx: Context) -> Verdict:
    ok = ctx.s("fuzzy", "buy_kwh_week_median") < ctx.s("rbc", "buy_kwh_week_median")
    return _v(ok, "median " + _listing(ctx, "buy_kwh_week_median", "kWh/week"))


@finding("mpc_cheapest", "paper sec:results (occupant-oriented metrics)",
         "MPC has the lowest weekly cost median", ("mpc",))
def _mpc_cheapest(ctx: Context) -> Verdict:
    m = {e: ctx.s(e, "cost_eur_week_median") for e in ctx.runs}
    ok = all(m["mpc"] < v for e, v in m.items() if e != "mpc") and len(m) > 1
    return _v(ok, "median " + _listing(ctx, "cost_eur_week_median", "EUR/week"))


@finding("mpc_no_discomfort", "paper sec:results (occupant-oriented metrics)",
         "MPC: zero discomfort in every week (or a "
         "comfort slack reported in every step with discomfort)", ("mpc",))
def _mpc_no_discomfort(ctx: Context) -> Verdict:
    run = ctx.runs["mpc"]
    ts = run.timeseries
    dev = np.clip(ts["t_min_c"] - ts["t_air_c"], 0, None) + np.clip(ts["t_air_c"] - ts["t_max_c"], 0, None)
    steps = dev > DISCOMFORT_TOL_KH
    weeks = int(run.summary["discomfort_weeks_nonzero"])
    slack = ts["ems_slack_used"].astype(float) > 0.5 if "ems_slack_used" in ts else pd.Series(False, index=ts.index)
    uncovered = int((steps & ~slack).sum())
    ok = weeks == 0 or uncovered == 0
    return _v(ok, f"mpc: {weeks} of {len(run.weekly)} weeks with discomfort, {int(steps.sum())} steps outside the "
              f"band, {int(slack.sum())} steps with slack reported, {uncovered} outside the band without slack")


@finding("rbc_hysteresis", "paper sec:results (time series comparison), sec:discussion",
         "RBC heats as a hysteresis between T_air,min and "
         "T_air,max (more full swings per week than the other EMS)", ("rbc",))
def _rbc_hysteresis(ctx: Context) -> Verdict:
    swings = {e: hysteresis_swings_per_week(r.timeseries) for e, r in ctx.runs.items()}
    others = [v for e, v in swings.items() if e != "rbc"]
    ok = swings["rbc"] >= 1.0 and all(swings["rbc"] > v for v in others)
    return _v(ok, "swings from within " + _f(HYSTERESIS_BAND_K, 1) + " K of T_min to within the same of T_max, per "
              "week: " + ", ".join(f"{e} {_f(v)}" for e, v in swings.items()))


def hysteresis_swings_per_week(ts: pd.DataFrame) -> float:
    """Upward swings of T_air from the lower zone to the upper zone per week [1/week].

    The lower zone is ``T_air <= T_air,min + band``, the upper zone ``T_air >= T_air,max -
    band`` (:data:`HYSTERESIS_BAND_K`); a swing is counted each time the upper zone is
    reached after the lower zone was last visited.
    """
    t = ts["t_air_c"].to_numpy(float)
    low = t <= ts["t_min_c"].to_numpy(float) + HYSTERESIS_BAND_K
    high = t >= ts["t_max_c"].to_numpy(float) - HYSTERESIS_BAND_K
    count, armed = 0, False
    for lo, hi in zip(low, high):
        if lo:
            armed = True
        elif hi and armed:
            count += 1
            armed = False
    return count / (len(t) / HOURS_PER_WEEK)


@finding("mpc_at_lower_bound", "paper sec:results (time series comparison)",
         "MPC keeps T_air closest to T_air,min (smallest mean "
         "excess over the lower bound)", ("mpc",))
def _mpc_at_lower_bound(ctx: Context) -> Verdict:
    ex = {e: float((r.timeseries["t_air_c"] - r.timeseries["t_min_c"]).mean()) for e, r in ctx.runs.items()}
    ok = len(ex) > 1 and all(ex["mpc"] < v for e, v in ex.items() if e != "mpc")
    return _v(ok, "mean T_air - T_air,min: " + ", ".join(f"{e} {_f(v)} K" for e, v in ex.items()))


def favourable_hours(ts: pd.DataFrame, tz: str) -> np.ndarray:
    """Hours with a low price (lowest quartile of the local day) or PV above the appliance load."""
    local = ts["time"].dt.tz_convert(tz)
    price = ts["price_buy_eur_per_kwh"]
    q = price.groupby(local.dt.date.to_numpy()).transform(lambda p: p.quantile(QUARTILE))
    return ((price <= q) | (ts["p_pv_w"] > ts["p_load_w"])).to_numpy()


def heat_shift_ratio(ts: pd.DataFrame, tz: str) -> float:
    """Mean SH heat in favourable hours over the mean in the other hours [-] (nan without SH)."""
    fav = favourable_hours(ts, tz)
    sh = ts["q_hp_sh_w"].to_numpy(float)
    rest = sh[~fav].mean() if (~fav).any() else float("nan")
    return float(sh[fav].mean() / rest) if rest and rest > 0 else float("nan")


@finding("fuzzy_stores_heat", "paper sec:results (time series comparison), sec:discussion",
         "ComEMS4Build stores heat in the building mass "
         "when prices are low or PV is high (more SH heat in those hours than in the others, more so than RBC)",
         ("fuzzy", "rbc"))
def _fuzzy_stores_heat(ctx: Context) -> Verdict:
    tz = ctx.params.site.timezone
    r = {e: heat_shift_ratio(run.timeseries, tz) for e, run in ctx.runs.items()}
    ok = r["fuzzy"] > 1.0 and r["fuzzy"] > r["rbc"]
    return _v(ok, "mean SH heat in low-price (day's lowest quartile) or PV-surplus hours / other hours: "
              + ", ".join(f"{e} {_f(v)}" for e, v in r.items()))


# ---------------------------------------------------------------- grid and BESS


def _sells(vals: dict[str, tuple[float, float]], a: str, b: str) -> bool:
    """``a`` sells more than ``b``: larger median, ties broken by the run total."""
    return vals[a] > vals[b]


@finding("rbc_sells_more_than_fuzzy", "paper sec:results (grid utilization)", "RBC sells more energy than ComEMS4Build "
         "(weekly median; equal medians compared by total)", ("rbc", "fuzzy"))
def _rbc_sells_more(ctx: Context) -> Verdict:
    vals = _ordered(ctx, "sell_kwh")
    return _v(_sells(vals, "rbc", "fuzzy"), _med_tot(vals, "kWh"))


@finding("rbc_sells_most", "paper sec:discussion", "RBC sells the most energy of all EMS", ("rbc",))
def _rbc_sells_most(ctx: Context) -> Verdict:
    vals = _ordered(ctx, "sell_kwh")
    ok = len(vals) > 1 and all(_sells(vals, "rbc", e) for e in vals if e != "rbc")
    return _v(ok, _med_tot(vals, "kWh"))


@finding("mpc_sells_least", "paper sec:results (grid utilization)", "MPC sells the least energy", ("mpc",))
def _mpc_sells_least(ctx: Context) -> Verdict:
    vals = _ordered(ctx, "sell_kwh")
    ok = len(vals) > 1 and all(_sells(vals, e, "mpc") for e in vals if e != "mpc")
    return _v(ok, _med_tot(vals, "kWh"))


@finding("rbc_charges_more", "paper sec:results (HESS utilization)", "RBC charges the battery more than ComEMS4Build",
         ("rbc", "fuzzy"))
def _rbc_charges_more(ctx: Context) -> Verdict:
    ok = ctx.s("rbc", "bess_charged_kwh_week_median") > ctx.s("fuzzy", "bess_charged_kwh_week_median")
    return _v(ok, "median " + _listing(ctx, "bess_charged_kwh_week_median", "kWh/week"))


@finding("fuzzy_bess_like_mpc", "paper sec:results (HESS utilization)", "ComEMS4Build's weekly BESS charging is "
         "closer to the MPC's than to the RBC's", ("fuzzy", "mpc", "rbc"))
def _fuzzy_bess_like_mpc(ctx: Context) -> Verdict:
    m = {e: ctx.s(e, "bess_charged_kwh_week_median") for e in ctx.runs}
    ok = abs(m["fuzzy"] - m["mpc"]) < abs(m["fuzzy"] - m["rbc"])
    return _v(ok, "median " + _listing(ctx, "bess_charged_kwh_week_median", "kWh/week"))


# ---------------------------------------------------------------- hydrogen


@finding("rbc_empties_early", "paper sec:results (time series comparison), sec:heat_recovery",
         "RBC reaches LOH_min at least a week before the "
         "end", ("rbc",))
def _rbc_empties_early(ctx: Context) -> Verdict:
    days = h2_empty_days_before_end(ctx.runs["rbc"], h2_floor("rbc", ctx.params.hydrogen.loh_min))
    ok = days is not None and days >= EARLY_EMPTY_DAYS
    return _v(ok, f"rbc: {_empty_text(ctx, 'rbc', days)}")


def _empty_text(ctx: Context, ems: str, days: float | None) -> str:
    tol = _f(100 * H2_EMPTY_TOL, 0)
    txt = "never" if days is None else f"{_f(days, 1)} days before the end"
    exact = ctx.runs[ems].summary.get("h2_empty_at")
    return (f"LOH within {tol} % of LOH_min {txt}; LOH at the end {_f(100 * ctx.s(ems, 'loh_end'), 2)} %; "
            f"exactly LOH_min reached at {exact or 'never'}")


@finding("fuzzy_h2_left", "paper sec:results (HESS utilization)", "ComEMS4Build ends with H2 left", ("fuzzy",))
def _fuzzy_h2_left(ctx: Context) -> Verdict:
    loh_min = ctx.params.hydrogen.loh_min
    end = ctx.s("fuzzy", "loh_end")
    return _v(end > loh_min + H2_LEFT_TOL, "LOH at the end: " + ", ".join(
        f"{e} {_f(100 * ctx.s(e, 'loh_end'), 1)} %" for e in ctx.runs) + f" (LOH_min {_f(100 * loh_min, 1)} %)")


@finding("fuzzy_most_h2_left", "paper sec:results (HESS utilization)", "ComEMS4Build ends with the most H2 left",
         ("fuzzy",))
def _fuzzy_most_h2_left(ctx: Context) -> Verdict:
    end = {e: ctx.s(e, "loh_end") for e in ctx.runs}
    ok = len(end) > 1 and all(end["fuzzy"] > v for e, v in end.items() if e != "fuzzy")
    return _v(ok, "LOH at the end: " + ", ".join(f"{e} {_f(100 * v, 1)} %" for e, v in end.items()))


@finding("fuzzy_h2_even", "paper sec:results (HESS utilization)", "ComEMS4Build spends H2 nearly evenly: the smallest "
         "spread (max - min) of weekly H2 use of all EMS", ("fuzzy",))
def _fuzzy_h2_even(ctx: Context) -> Verdict:
    spread = {}
    if len(_complete_weeks(ctx.runs["fuzzy"])) < 2:
        return Verdict(NA, "fewer than 2 complete weeks: no spread between weeks")
    for e, r in ctx.runs.items():
        w = _complete_weeks(r)["h2_kwh"]
        spread[e] = (float(w.max() - w.min()), float(w.min()), float(w.max()))
    ok = len(spread) > 1 and all(spread["fuzzy"][0] < v[0] for e, v in spread.items() if e != "fuzzy")
    return _v(ok, "weekly H2 use (complete weeks) spread: " + ", ".join(
        f"{e} {_f(s)} kWh ({_f(lo)}..{_f(hi)})" for e, (s, lo, hi) in spread.items()))


def h2_price_response(ts: pd.DataFrame) -> tuple[float, float]:
    """Mean H2 power [W] in hours with a buy price in the top and in the bottom quartile of the run."""
    price = ts["price_buy_eur_per_kwh"]
    h2 = ts["p_h2_w"]
    hi = h2[price >= price.quantile(1 - QUARTILE)].mean()
    lo = h2[price <= price.quantile(QUARTILE)].mean()
    return float(hi), float(lo)


@finding("mpc_h2_at_high_prices", "paper sec:results (HESS utilization)",
         "MPC spends H2 more when (absolute) prices are high than "
         "when they are low", ("mpc",))
def _mpc_h2_high_prices(ctx: Context) -> Verdict:
    resp = {e: h2_price_response(r.timeseries) for e, r in ctx.runs.items()}
    hi, lo = resp["mpc"]
    return _v(hi > lo, "mean H2 use in top / bottom price quartile hours of the run: " + ", ".join(
        f"{e} {_f(h, 0)} / {_f(low, 0)} W" for e, (h, low) in resp.items()))


@finding("mpc_h2_not_emptied_early", "paper sec:results (HESS utilization), eq:LOHmin_MPC",
         "MPC does not empty the H2 store before the last day",
         ("mpc",))
def _mpc_h2_kept(ctx: Context) -> Verdict:
    days = h2_empty_days_before_end(ctx.runs["mpc"], ctx.params.hydrogen.loh_min)
    ok = days is None or days <= 1.0
    return _v(ok, f"mpc: {_empty_text(ctx, 'mpc', days)}")


# ---------------------------------------------------------------- fuel cell


@finding("fuzzy_fc_longer_than_rbc", "paper sec:results (HESS utilization)",
         "ComEMS4Build runs the FC more hours than RBC",
         ("fuzzy", "rbc"))
def _fuzzy_fc_longer(ctx: Context) -> Verdict:
    return _v(ctx.s("fuzzy", "fc_working_hours") > ctx.s("rbc", "fc_working_hours"),
              "FC working hours: " + _listing(ctx, "fc_working_hours", "h", 0))


@finding("fuzzy_fc_lower_load", "paper sec:results (HESS utilization), sec:heat_recovery",
         "ComEMS4Build runs the FC at a lower mean load than "
         "RBC", ("fuzzy", "rbc"))
def _fuzzy_fc_lower_load(ctx: Context) -> Verdict:
    return _v(ctx.s("fuzzy", "fc_mean_load_w") < ctx.s("rbc", "fc_mean_load_w"),
              "mean FC load when on: " + _listing(ctx, "fc_mean_load_w", "W", 0))


@finding("fuzzy_fc_higher_eta", "paper sec:results (HESS utilization), eq:efficiency_FC",
         "ComEMS4Build runs the FC at a higher mean "
         "electrical efficiency than RBC", ("fuzzy", "rbc"))
def _fuzzy_fc_higher_eta(ctx: Context) -> Verdict:
    return _v(ctx.s("fuzzy", "fc_mean_eta_el") > ctx.s("rbc", "fc_mean_eta_el"),
              "mean FC electrical efficiency when on: " + ", ".join(
                  f"{e} {_f(100 * ctx.s(e, 'fc_mean_eta_el'), 1)} %" for e in ctx.runs))


@finding("rbc_fc_full_power", "paper sec:RBC, sec:results (HESS utilization)",
         "RBC runs the FC at its full permissible power "
         "zeta * P_FC,max", ("rbc",))
def _rbc_full_power(ctx: Context) -> Verdict:
    fc = ctx.params.fuel_cell
    full = fc.zeta * fc.p_max_w
    load = ctx.s("rbc", "fc_mean_load_w")
    return _v(load >= FULL_POWER_SHARE * full, f"rbc mean FC load {_f(load, 0)} W = "
              f"{_f(100 * load / full, 1)} % of zeta * P_FC,max = {_f(full, 0)} W")


@finding("fuzzy_fc_more_than_mpc", "paper sec:results (HESS utilization)", "ComEMS4Build has more FC working "
         "hours and toggles than MPC (paper: +48.44 %, +6.09 %)", ("fuzzy", "mpc"))
def _fuzzy_vs_mpc(ctx: Context) -> Verdict:
    h = ctx.s("fuzzy", "fc_working_hours") > ctx.s("mpc", "fc_working_hours")
    t = ctx.s("fuzzy", "fc_toggles") > ctx.s("mpc", "fc_toggles")
    return _v(h and t, "working hours: " + _listing(ctx, "fc_working_hours", "h", 0) + "; toggles: "
              + _listing(ctx, "fc_toggles", "", 0))


@finding("rbc_fc_less_than_mpc", "paper sec:results (HESS utilization)", "RBC has fewer FC working hours and "
         "toggles than MPC (paper: -7.59 %, -3.48 %)", ("rbc", "mpc"))
def _rbc_vs_mpc(ctx: Context) -> Verdict:
    h = ctx.s("rbc", "fc_working_hours") < ctx.s("mpc", "fc_working_hours")
    t = ctx.s("rbc", "fc_toggles") < ctx.s("mpc", "fc_toggles")
    return _v(h and t, "working hours: " + _listing(ctx, "fc_working_hours", "h", 0) + "; toggles: "
              + _listing(ctx, "fc_toggles", "", 0))


@finding("fuzzy_least_heat_recovered", "paper sec:heat_recovery", "ComEMS4Build recovers the least FC "
         "heat (weekly median)", ("fuzzy",))
def _fuzzy_least_heat(ctx: Context) -> Verdict:
    m = {e: float(r.weekly["heat_recovered_kwh"].median()) for e, r in ctx.runs.items()}
    ok = len(m) > 1 and all(m["fuzzy"] < v for e, v in m.items() if e != "fuzzy")
    return _v(ok, "median heat recovered: " + ", ".join(f"{e} {_f(v)} kWh/week" for e, v in m.items()))


# ---------------------------------------------------------------- DHW and heat recovery


def covered_weeks(run: RunData) -> list[int]:
    """Weeks whose recovered FC heat reaches the DHW demand including losses."""
    w = run.weekly
    return [int(r.week) for r in w.itertuples() if r.heat_recovered_kwh >= r.dhw_demand_kwh]


@finding("no_dhw_cover_at_75", "paper sec:heat_recovery", "at 75 % FC system efficiency no EMS covers a "
         "whole week's DHW demand with FC heat", ())
def _no_cover_75(ctx: Context) -> Verdict:
    return _dhw_cover(ctx, 0.75, lambda cov: all(not v for v in cov.values()))


@finding("some_dhw_cover_at_90", "paper sec:heat_recovery", "at 90 % FC system efficiency some EMS (RBC and MPC in "
         "the paper) cover the DHW demand with FC heat in some weeks", ())
def _cover_90(ctx: Context) -> Verdict:
    return _dhw_cover(ctx, 0.90, lambda cov: any(cov.values()))


def _dhw_cover(ctx: Context, eta_sys: float, holds: Callable[[dict[str, list[int]]], bool]) -> Verdict:
    """``holds(weeks covered per EMS)`` over the runs at FC system efficiency ``eta_sys`` [-]."""
    runs = {e: r for (e, eta), r in ctx.variants.items() if abs(eta - eta_sys) < 1e-9}
    if not runs:
        return Verdict(NA, f"no runs at eta_sys = {eta_sys:.2f}")
    cov = {e: covered_weeks(r) for e, r in runs.items()}
    return _v(holds(cov), f"weeks covered at {eta_sys * 100:.0f} %: "
              + "; ".join(f"{e} {v or 'none'}" for e, v in cov.items()))


def share_above_half(run: RunData, v_max_l: float) -> float:
    """Share of steps with the usable DHW volume above half of V_max [-]."""
    return float((run.timeseries["v_dhw_l"] > DHW_HALF * v_max_l).mean())


@finding("dhw_tank_kept_high", "paper sec:results (time series comparison, occupant-oriented metrics)",
         "ComEMS4Build and RBC keep the DHW tank above 50 % most of "
         "the time; MPC keeps it lower", ("fuzzy", "rbc", "mpc"))
def _dhw_tank(ctx: Context) -> Verdict:
    v_max = ctx.params.dhw.v_max_l
    sh = {e: share_above_half(r, v_max) for e, r in ctx.runs.items()}
    ok = sh["fuzzy"] > DHW_HALF and sh["rbc"] > DHW_HALF and sh["mpc"] < min(sh["fuzzy"], sh["rbc"])
    return _v(ok, "share of hours with V_DHW above 50 %: " + ", ".join(f"{e} {_f(100 * v, 1)} %"
                                                                     for e, v in sh.items()))


@finding("dhw_demand_met", "paper sec:results (occupant-oriented metrics)",
         "every EMS meets the DHW demand in every step", ())
def _dhw_met(ctx: Context) -> Verdict:
    if not ctx.runs:
        return Verdict(NA, "no runs")
    unmet = {e: ctx.s(e, "dhw_unmet_kwh") for e in ctx.runs}
    return _v(all(v <= DHW_UNMET_TOL_KWH for v in unmet.values()),
              "unmet DHW energy: " + ", ".join(f"{e} {_f(v)} kWh" for e, v in unmet.items()))


def paper_context(ctx: Context) -> Context:
    """``ctx`` restricted to the paper's EMS (:data:`PAPER_EMS`)."""
    return Context(
        runs={e: r for e, r in ctx.runs.items() if e in PAPER_EMS},
        variants={k: r for k, r in ctx.variants.items() if k[0] in PAPER_EMS},
        params=ctx.params,
        base_eta=ctx.base_eta,
    )


def evaluate_findings(ctx: Context) -> list[tuple[Finding, Verdict]]:
    """Every registered finding with its verdict, over the paper's EMS in ``ctx``."""
    pctx = paper_context(ctx)
    return [(f, f.evaluate(pctx)) for f in FINDINGS]
