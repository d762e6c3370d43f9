"""The paper's statements measured on hand-made runs (comems4build_ros/report/paper.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.kpi import heat_recovered_at
from comems4build_ros.report import paper as pp
from comems4build_ros.report.runs import RunData, RunSpec

HOURS = 168


def _run(ems: str, weekly: dict, summary: dict | None = None, ts: dict | None = None, weeks: int = 12) -> RunData:
    time = pd.date_range("2022-12-01 00:00", periods=HOURS * weeks, freq="h", tz="Europe/Berlin").tz_convert("UTC")
    frame = pd.DataFrame({"time": time, "price_buy_eur_per_kwh": 0.3, "ghi_w_m2": 0.0, "loh": 0.5,
                          "p_buy_w": 0.0, "fc_on": False, "p_h2_w": 0.0, "eta_fc_el": 0.0})
    for k, v in (ts or {}).items():
        frame[k] = v
    w = pd.DataFrame({"week": np.arange(1, weeks + 1), "hours": float(HOURS), **weekly})
    return RunData(RunSpec(ems, ems, 0.75), Path("."), dict(summary or {}), w, frame)


def _evidence(runs: dict[str, RunData], variants: dict | None = None) -> pp.Evidence:
    return pp.Evidence(runs=runs, params=load_plant_params(), base_eta=0.75, variants=variants or {})


def _statement(key: str, measure: dict, paper: dict, error_on: str = "value") -> pp.Statement:
    return pp.Statement(key, key, "-", "sec:results", "quote", measure, paper, error_on=error_on)


def _measure(st: pp.Statement, ev: pp.Evidence, ems: str) -> float | list[int] | None:
    run = ev.run(ems, st.eta)
    return None if run is None else pp.MEASURES[st.measure["of"]](ev, ems, run, st.measure)


def test_weeks_are_numbered_from_the_start_and_ranked_by_the_mpcs_cost() -> None:
    cost_mpc = np.arange(12, dtype=float)
    cost_mpc[[2, 7]] = [100.0, 90.0]  # weeks 3 and 8 are the MPC's costliest
    mpc = _run("mpc", {"cost_eur": cost_mpc, "buy_kwh": np.arange(12.0)})
    fuzzy = _run("fuzzy", {"cost_eur": 10.0 * np.arange(1, 13), "buy_kwh": np.zeros(12)})
    ev = _evidence({"mpc": mpc, "fuzzy": fuzzy})
    first = _statement("w1", {"of": "mpc_ranked_week", "column": "cost_eur", "rank": 1}, {"fuzzy": 1.0})
    second = _statement("w2", {"of": "mpc_ranked_week", "column": "cost_eur", "rank": 2}, {"fuzzy": 1.0})
    assert _measure(first, ev, "fuzzy") == 30.0  # the fuzzy EMS's cost in week 3
    assert _measure(second, ev, "fuzzy") == 80.0  # ... and in week 8
    week3 = _statement("b3", {"of": "week", "column": "buy_kwh", "week": 3}, {"mpc": 1.0})
    assert _measure(week3, ev, "mpc") == 2.0


def test_ranked_weeks_and_weeks_without_discomfort() -> None:
    disc = np.zeros(12)
    disc[[4, 9]] = [0.7, 2.1]
    fuzzy = _run("fuzzy", {"discomfort_kh": disc})
    ev = _evidence({"fuzzy": fuzzy})
    assert _measure(_statement("a", {"of": "ranked_week", "column": "discomfort_kh", "rank": 1}, {"fuzzy": 1.0}),
                    ev, "fuzzy") == 2.1
    assert _measure(_statement("b", {"of": "ranked_week", "column": "discomfort_kh", "rank": 2}, {"fuzzy": 1.0}),
                    ev, "fuzzy") == 0.7
    assert _measure(_statement("c", {"of": "weeks_without", "column": "discomfort_kh"}, {"fuzzy": 1.0}),
                    ev, "fuzzy") == 10.0


def test_relative_error_of_a_percentage_is_taken_on_the_ratio() -> None:
    assert pp.relative_error(60.0, 48.44, "ratio") == pytest.approx(abs(1.6 - 1.4844) / 1.4844)
    assert pp.relative_error(6.25, -3.48, "ratio") == pytest.approx(abs(1.0625 - 0.9652) / 0.9652)
    assert pp.relative_error(27.0, 25.0) == pytest.approx(0.08)


def test_pct_vs_mpc_and_differences() -> None:
    mpc = _run("mpc", {}, {"fc_working_hours": 400.0, "cost_eur_week_median": 13.0})
    fuzzy = _run("fuzzy", {}, {"fc_working_hours": 600.0, "cost_eur_week_median": 25.0})
    ev = _evidence({"mpc": mpc, "fuzzy": fuzzy})
    pct = _statement("h", {"of": "pct_vs_mpc", "key": "fc_working_hours"}, {"fuzzy": 48.44}, "ratio")
    assert _measure(pct, ev, "fuzzy") == pytest.approx(50.0)
    diff = _statement("d", {"of": "minus_mpc", "key": "cost_eur_week_median"}, {"fuzzy": 12.06})
    assert _measure(diff, ev, "fuzzy") == pytest.approx(12.0)


def test_heat_at_another_efficiency_and_covered_weeks() -> None:
    """eq:FC_sys_efficiency at 90 %: the same H2 power gives (0.9 - eta_el) of heat."""
    on = np.zeros(HOURS * 12, dtype=bool)
    on[:10] = True  # ten hours in week 1
    ts = {"fc_on": on, "p_h2_w": np.where(on, 2000.0, 0.0), "eta_fc_el": np.where(on, 0.5, 0.0)}
    heat = heat_recovered_at(_run("rbc", {}, ts=ts).timeseries, 0.9)
    assert heat.sum() == pytest.approx(10 * 2000.0 * 0.4 / 1000.0)
    run = _run("rbc", {"heat_recovered_kwh": [10.0, 5.0] + [1.0] * 10, "dhw_demand_kwh": [8.0, 6.0] + [2.0] * 10})
    assert pp.covered_weeks(run) == [1]


def test_the_h2_stores_empty_days_and_share() -> None:
    loh = np.full(HOURS * 12, 0.5)
    loh[-24 * 16:] = 0.1  # at the RBC's own floor for the last 16 days
    rbc = _run("rbc", {}, {"rbc_loh_floor": 0.1}, {"loh": loh})
    ev = _evidence({"rbc": rbc})
    days = _measure(_statement("d", {"of": "h2_empty_days"}, {"rbc": 16.0}), ev, "rbc")
    assert days == pytest.approx(16.0 - 1 / 24)  # from the first step at the floor to the last step
    share = _measure(_statement("s", {"of": "h2_empty_share"}, {"rbc": 19.0}), ev, "rbc")
    assert share == pytest.approx(100 * days / 84)


def test_compare_kinds_and_aggregate_over_seeds() -> None:
    st = _statement("x", {"of": "summary", "key": "k"}, {"mpc": 0.0, "fuzzy": 10.0, "rbc": {"below": 30}})
    zero, value, bound = (pp.compare(st, e, v, 0.005) for e, v in (("mpc", 0.001), ("fuzzy", 12.0), ("rbc", 31.0)))
    assert (zero.kind, zero.held) == ("zero", True)
    assert value.rel_error == pytest.approx(0.2) and value.held is None
    assert (bound.kind, bound.held) == ("bound", False)
    weeks = _statement("w", {"of": "covered_weeks"}, {"rbc": [4, 6]})
    assert pp.compare(weeks, "rbc", [6, 4], 0.0).held
    # over three seeds: the median of the values and of the errors, and how often a bound held
    per_seed = [[pp.compare(st, "fuzzy", v, 0.0), pp.compare(st, "rbc", b, 0.0)]
                for v, b in ((9.0, 20.0), (12.0, 35.0), (20.0, 25.0))]
    agg = pp.aggregate(per_seed)
    assert (agg[0].ours, agg[0].low, agg[0].high) == (12.0, 9.0, 20.0)
    assert agg[0].rel_error == pytest.approx(0.2)  # errors 0.1, 0.2, 1.0
    assert (agg[1].held, agg[1].runs) == (2, 3)


def test_evaluate_statements_on_the_shipped_file_says_what_was_not_run() -> None:
    """A comparison without the MPC has no MPC figures and no figures relative to it."""
    weekly = {c: np.ones(12) for c in ("cost_eur", "buy_kwh", "discomfort_kh", "fc_kwh", "heat_recovered_kwh",
                                       "dhw_demand_kwh")}
    summary = {k: 1.0 for k in ("cost_eur_week_median", "reimbursement_eur_week_median", "discomfort_kh_week_median",
                                "bess_charged_kwh_week_median", "fc_working_hours", "fc_toggles", "fc_mean_load_w",
                                "loh_end", "h2_left_value_eur", "buy_kwh_week_median", "sell_kwh_week_median")}
    ev = _evidence({"fuzzy": _run("fuzzy", weekly, summary), "rbc": _run("rbc", weekly, summary)})
    figs = {(f.key, f.ems): f for f in pp.evaluate_statements(ev)}
    assert figs[("cost", "mpc")].ours is None and figs[("cost", "fuzzy")].ours == 1.0
    assert figs[("fc_hours_vs_mpc", "fuzzy")].ours is None
    assert figs[("heat_week_5_eta90", "mpc")].ours is None
