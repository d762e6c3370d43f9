"""Every finding and every validation check fails when another EMS's behaviour stands where the paper says they differ.

The module fixture makes the real 12-week runs of ComEMS4Build and the RBC on the paper's
winter (in process, as ``comems4build simulate``). Each check is then fed the other EMS's run
in the place of the EMS its claim is about (ComEMS4Build's run as the RBC's and the other way
round; the RBC's or ComEMS4Build's run as the MPC's, for the claims about the MPC) and must
not hold. Where both runs stand in their own places the claims about ComEMS4Build and the RBC
must hold, so the failure comes from the swap, not from a check that cannot pass.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate, write_run
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.report import findings as fd
from comems4build_ros.report import validation as rv
from comems4build_ros.report.reproduce import at_efficiency
from comems4build_ros.report.runs import RunData, RunSpec, read_run

BASE_ETA, HEAT_ETA = 0.75, 0.90


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, RunData]:
    params = load_plant_params()
    out = tmp_path_factory.mktemp("winter")
    made = {}
    for ems in ("fuzzy", "rbc"):
        write_run(simulate(ems, resolve_scenario("default", params), params), out / ems)
        made[ems] = read_run(out / ems, RunSpec(name=ems, ems=ems, eta_sys=BASE_ETA))
    return made


def _ctx(slots: dict[str, RunData], variants: dict[tuple[str, float], RunData] | None = None) -> fd.Context:
    base = {(e, BASE_ETA): r for e, r in slots.items()}
    heat = {(e, HEAT_ETA): at_efficiency(r, HEAT_ETA) for e, r in slots.items()}
    return fd.Context(runs=dict(slots), variants=variants if variants is not None else {**base, **heat},
                      params=load_plant_params(), base_eta=BASE_ETA)


def _verdict(key: str, ctx: fd.Context) -> fd.Verdict:
    f = next(f for f in fd.FINDINGS if f.key == key)
    return f.evaluate(fd.paper_context(ctx))


def _swap(r: dict[str, RunData]) -> dict[str, RunData]:
    """The RBC's run as ComEMS4Build's and ComEMS4Build's as the RBC's."""
    return {"fuzzy": r["rbc"], "rbc": r["fuzzy"]}


def _rbc_as_mpc(r: dict[str, RunData]) -> dict[str, RunData]:
    """The RBC's run in the MPC's place, beside both real runs."""
    return {"mpc": r["rbc"], "fuzzy": r["fuzzy"], "rbc": r["rbc"]}


def _fuzzy_as_mpc(r: dict[str, RunData]) -> dict[str, RunData]:
    """ComEMS4Build's run in the MPC's place, beside both real runs."""
    return {"mpc": r["fuzzy"], "fuzzy": r["fuzzy"], "rbc": r["rbc"]}


def _rbc_as_fuzzy_beside_fuzzy_as_mpc(r: dict[str, RunData]) -> dict[str, RunData]:
    """The RBC's run as ComEMS4Build's; ComEMS4Build's run (which the paper puts near the MPC's) as the MPC's."""
    return {"mpc": r["fuzzy"], "fuzzy": r["rbc"], "rbc": r["rbc"]}


def _fuzzy_as_rbc_beside_rbc_as_mpc(r: dict[str, RunData]) -> dict[str, RunData]:
    """ComEMS4Build's run as the RBC's; the RBC's as the MPC's."""
    return {"mpc": r["rbc"], "fuzzy": r["rbc"], "rbc": r["fuzzy"]}


Feed = Callable[[dict[str, RunData]], dict[str, RunData]]

#: finding -> how the other EMS's behaviour is fed to it (every registered finding is here).
FED: dict[str, Feed] = {
    "fuzzy_discomfort_free": _swap,
    "rbc_largest_discomfort": _swap,
    "fuzzy_cheaper_than_rbc": _swap,
    "fuzzy_buys_less_than_rbc": _swap,
    "mpc_cheapest": _rbc_as_mpc,
    "mpc_no_discomfort": _rbc_as_mpc,
    "rbc_hysteresis": _swap,
    "mpc_at_lower_bound": _fuzzy_as_mpc,
    "fuzzy_stores_heat": _swap,
    "rbc_sells_more_than_fuzzy": _swap,
    "rbc_sells_most": _fuzzy_as_rbc_beside_rbc_as_mpc,
    "mpc_sells_least": _rbc_as_mpc,
    "rbc_charges_more": _swap,
    "fuzzy_bess_like_mpc": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "rbc_empties_early": _swap,
    "fuzzy_h2_left": _swap,
    "fuzzy_most_h2_left": _swap,
    "fuzzy_h2_even": _swap,
    "mpc_h2_at_high_prices": _fuzzy_as_mpc,
    "mpc_h2_not_emptied_early": _rbc_as_mpc,
    "fuzzy_fc_longer_than_rbc": _swap,
    "fuzzy_fc_lower_load": _swap,
    "fuzzy_fc_higher_eta": _swap,
    "rbc_fc_full_power": _swap,
    "fuzzy_fc_longer_than_mpc": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "fuzzy_fc_lower_load_than_mpc": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "fuzzy_fc_more_than_mpc": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "rbc_fc_less_than_mpc": _fuzzy_as_rbc_beside_rbc_as_mpc,
    "fuzzy_least_heat_recovered": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "some_dhw_cover_at_90": _swap,
    "dhw_tank_kept_high": _fuzzy_as_mpc,
}
#: Findings about every EMS at once, each fed a run that breaks it (see their tests below).
NOT_ABOUT_ONE_EMS = {"no_dhw_cover_at_75", "dhw_demand_met"}
#: Findings that hold on the real runs of ComEMS4Build and the RBC in their own places (the rest
#: need the MPC, or do not hold on the paper's winter: the RBC leaves some DHW demand unmet).
HOLD_ON_BOTH = ("fuzzy_discomfort_free", "rbc_largest_discomfort", "fuzzy_cheaper_than_rbc",
                "fuzzy_buys_less_than_rbc", "rbc_hysteresis", "fuzzy_stores_heat", "rbc_sells_more_than_fuzzy",
                "rbc_charges_more", "rbc_empties_early", "fuzzy_h2_left", "fuzzy_most_h2_left", "fuzzy_h2_even",
                "fuzzy_fc_longer_than_rbc", "fuzzy_fc_lower_load", "fuzzy_fc_higher_eta", "rbc_fc_full_power",
                "no_dhw_cover_at_75", "some_dhw_cover_at_90")


def test_every_finding_is_fed_another_ems():
    assert set(FED) | NOT_ABOUT_ONE_EMS == {f.key for f in fd.FINDINGS}


@pytest.mark.parametrize("key", sorted(FED))
def test_the_other_ems_fails(runs, key):
    v = _verdict(key, _ctx(FED[key](runs)))
    assert v.status == fd.NOT_HELD, f"{key} holds for another EMS's behaviour: {v.evidence}"


#: More feeds of the checks about the MPC: the RBC's run in its place too.
MORE_FED = [("mpc_h2_at_high_prices", _rbc_as_mpc), ("mpc_at_lower_bound", _rbc_as_mpc),
            ("mpc_cheapest", _fuzzy_as_mpc), ("mpc_sells_least", _fuzzy_as_mpc),
            ("dhw_tank_kept_high", _rbc_as_mpc)]


@pytest.mark.parametrize("key, feed", MORE_FED, ids=[k for k, _ in MORE_FED])
def test_the_rule_based_ems_fail_the_mpc_claims(runs, key, feed):
    v = _verdict(key, _ctx(feed(runs)))
    assert v.status == fd.NOT_HELD, f"{key} holds for another EMS's behaviour: {v.evidence}"


@pytest.mark.parametrize("key", HOLD_ON_BOTH)
def test_holds_with_each_ems_in_its_place(runs, key):
    v = _verdict(key, _ctx(dict(runs)))
    assert v.status == fd.HELD, f"{key}: {v.evidence}"


def test_no_dhw_cover_fails_for_the_heat_of_a_90_percent_system(runs):
    """The RBC's dispatch evaluated at 90 % covers some weeks (sec:heat_recovery); fed as the 75 % runs it fails."""
    ninety = at_efficiency(runs["rbc"], HEAT_ETA)
    ctx = _ctx(dict(runs), {("fuzzy", BASE_ETA): runs["fuzzy"], ("rbc", BASE_ETA): ninety})
    assert fd.covered_weeks(ninety)
    assert _verdict("no_dhw_cover_at_75", ctx).status == fd.NOT_HELD


def test_dhw_demand_met_fails_for_a_run_with_unmet_demand(runs):
    """ComEMS4Build's run meets every draw; the RBC's leaves some unmet on the paper's winter."""
    assert _verdict("dhw_demand_met", _ctx({"fuzzy": runs["fuzzy"]})).status == fd.HELD
    assert runs["rbc"].summary["dhw_unmet_kwh"] > fd.DHW_UNMET_TOL_KWH
    assert _verdict("dhw_demand_met", _ctx({"fuzzy": runs["fuzzy"], "rbc": runs["rbc"]})).status == fd.NOT_HELD


def test_h2_left_band_fails_the_rbc_reserve_and_the_mpc_of_the_paper():
    """The paper's end levels (sec:results): RBC 9.94 %, MPC 5.21 % fail; ComEMS4Build's 14.14 % holds."""
    assert fd.h2_left_near_paper(0.1414)
    assert not fd.h2_left_near_paper(0.0994) and not fd.h2_left_near_paper(0.0521)
    assert not fd.h2_left_near_paper(1.0)  # an EMS that never uses its H2


def _loh_run(loh: list[float], ems: str = "fuzzy") -> RunData:
    ts = pd.DataFrame({"loh": loh, "time": pd.date_range("2022-12-01", periods=len(loh), freq="h", tz="UTC")})
    return RunData(RunSpec(name=ems, ems=ems, eta_sys=BASE_ETA), Path("."), {}, pd.DataFrame(), ts)


@pytest.mark.parametrize("days_early", [10, 16, 25])
def test_evenness_fails_a_store_emptied_days_before_the_end(days_early):
    """The RBC's pattern: linear use to its 10 % reserve, then flat for ``days_early`` of 84 days."""
    n = 84 * 24
    k = n - days_early * 24
    loh = [1.0 - 0.9 * (i + 1) / k if i < k else 0.1 for i in range(n)]
    tol = fd.h2_even_tolerance(load_plant_params())
    assert fd.h2_chord_deviation(_loh_run(loh), 1.0) > tol


def test_evenness_fails_h2_kept_through_cheap_weeks_and_spent_late():
    """The MPC's pattern of sec:results: H2 reserved in the cheap weeks (December 20 to January 6),
    spent after; the straight line is more than a week of the allowance away."""
    n = 84 * 24
    kept = range(19 * 24, 37 * 24)
    use = [0.0 if i in kept else 1.0 for i in range(n)]
    total = sum(use)
    loh, level = [], 1.0
    for u in use:
        level -= 0.95 * u / total
        loh.append(level)
    assert fd.h2_chord_deviation(_loh_run(loh), 1.0) > fd.h2_even_tolerance(load_plant_params())


def test_evenness_holds_for_linear_use():
    n = 84 * 24
    loh = [1.0 - 0.86 * (i + 1) / n for i in range(n)]
    assert fd.h2_chord_deviation(_loh_run(loh), 1.0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("a, b, less", [(1.0, 1.04, False), (1.0, 1.06, True), (-1.0, -0.9, True), (0.0, 0.0, False),
                                        (25.02, 43.10, True), (43.10, 25.02, False)])
def test_an_order_needs_the_margin(a, b, less):
    assert fd.less(a, b) is less


# ---------------------------------------------------------------- the validation's checks


def _case(slots: dict[str, RunData]) -> dict:
    return rv.case_metrics(slots, load_plant_params(), HEAT_ETA, BASE_ETA)


#: check -> how the other EMS's behaviour is fed to it (every check is here).
CHECKS_FED: dict[str, Feed] = {
    "comfort": _swap,
    "cost_order": _fuzzy_as_rbc_beside_rbc_as_mpc,
    "h2_left": _swap,
    "fc_longer_lower": _rbc_as_fuzzy_beside_fuzzy_as_mpc,
    "rbc_sells_most": _fuzzy_as_rbc_beside_rbc_as_mpc,
}


def test_every_check_is_fed_another_ems():
    assert set(CHECKS_FED) == set(rv.CRITERIA) == set(rv.CRITERIA_FINDINGS)


@pytest.mark.parametrize("key", sorted(CHECKS_FED))
def test_each_check_fails_for_the_other_ems(runs, key):
    m = _case(CHECKS_FED[key](runs))
    assert m["criteria"][key] is False, (key, {k: m["findings"][k] for k in rv.CRITERIA_FINDINGS[key]})


def test_checks_of_comfort_and_h2_hold_with_each_ems_in_its_place(runs):
    m = _case(dict(runs))
    assert m["criteria"]["comfort"] is True and m["criteria"]["h2_left"] is True
    assert m["criteria"]["cost_order"] is None  # no MPC run: not judged
