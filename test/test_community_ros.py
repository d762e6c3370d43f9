"""A community over ROS 2 (``launch --community``): the coordinator node and every house's node set.

- three houses and the coordinator on one host, and on one network-namespace host each, give
  the in-process community run bit for bit: every house's timeseries and KPIs (also its bag
  evaluated alone), the hub's timeseries, the community's KPIs;
- in simulated time a killed house node fails the run, naming it;
- on a wall clock the community goes on without a house that left, its account frozen, the
  hub's balance closed, the gap marked;
- the plan, the contract's community topics and the signed hub messages, without processes.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import signal
from array import array
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from launch_probe import netns_available
from waits import BUDGET_S

from comems4build_ros.core.community.hubrun import (
    HUB_TIMESERIES_COLUMNS,
    NO_FLOWS,
    NO_REQUEST,
    HouseMeter,
    HubRun,
    initial_accounts,
)
from comems4build_ros.core.community.loop import simulate_community
from comems4build_ros.core.community.plant import CommunityPlant
from comems4build_ros.core.community.spec import CommunitySpec, HouseSpec, build_community, load_community
from comems4build_ros.core.types import Action
from comems4build_ros.run.plan import LaunchOptions
from comems4build_ros.run.plans import plan_any
from comems4build_ros.run.supervisor import processes_with_env
from comems4build_ros.wire.contract import load_contract
from comems4build_ros.wire.tokens import authentic, secret_key, sign

THREE = """community:
  name: three
  houses:
    - {name: h1, reason: "the paper's house"}
    - {name: h2, reason: "a 2-person household with an east roof and a smaller house", load_scale: 0.71,
       load_seed: 1101, dhw_scale: 0.5, dhw_shift_days: 7, pv_n_modules: 24, pv_azimuth_deg: 90, building_scale: 0.85}
    - {name: h3, reason: "a 3-person household with a west roof and a larger share", load_scale: 0.91,
       load_seed: 1102, pv_azimuth_deg: 270, building_scale: 1.1, h2_weight: 2}
"""
#: Summary entries that are the run's facts, not its figures (wall time, bag facts, labels).
NOT_FIGURES = ("wall_s", "ems_s", "bag_duration_s", "lost_messages", "coordinator_s", "community_file",
               "coordinator_s_per_decision_mean", "coordinator_s_per_decision_max", "scenario_extended",
               "over_ros", "houses_left", "clock", "coordinator_stats")
#: The hub's columns of wall-clock time per call.
TIMING_COLUMNS = ("coord_allot_s", "coord_dispatch_s")


def _file(tmp_path: Path) -> Path:
    path = tmp_path / "three.yaml"
    path.write_text(THREE, encoding="utf-8")
    return path


def _reference(path: Path, scenario: str, weeks: int, steps: int, start: str | None, ems: str,
               coordinator: str = "rule"):
    community = build_community(load_community(path), scenario, weeks=weeks, steps=steps, start=start)
    return simulate_community(community, coordinator, ems)


def _equal(a: pd.Series, b: pd.Series) -> bool:
    if a.name == "time":
        return list(map(str, a)) == list(map(str, b))
    return np.array_equal(a.to_numpy(float), b.to_numpy(float), equal_nan=True)


def _same_figures(a: dict, b: dict, where: str) -> None:
    for key in set(a) - set(NOT_FIGURES):
        va, vb = a[key], b.get(key)
        same = va == vb or (isinstance(va, float) and isinstance(vb, float) and math.isnan(va) and math.isnan(vb))
        assert same, f"{where}: {key}: {va!r} (in-process) != {vb!r} (over ROS)"


def _same_as_in_process(out: Path, bag: Path, ref, tmp_path: Path) -> None:
    """The run directory of a community launch equals the in-process run: every column of every
    house's timeseries, every KPI, the hub's timeseries and the community's KPIs."""
    from comems4build_ros.bags.community import evaluate_community_bags
    from comems4build_ros.bags.evaluation import evaluate_bag

    got = evaluate_community_bags(bag, tmp_path / "again")
    for name, house in ref.houses.items():
        ts = got.houses[name].timeseries
        assert list(ts.columns) == list(house.timeseries.columns), name
        for col in house.timeseries.columns:
            assert _equal(house.timeseries[col], ts[col]), f"house {name}: column {col}"
        _same_figures(house.summary, got.houses[name].summary, f"house {name}")
        assert got.houses[name].summary["lost_messages"] == {}, name
        alone = evaluate_bag(bag / name, tmp_path / "alone" / name)  # comems4build evaluate of the house's bag
        _same_figures({k: v for k, v in house.summary.items() if k not in ("house", "community", "scenario")},
                      next(iter(alone.values())), f"house {name} evaluated alone")
    for col in ref.hub.columns:
        if col not in TIMING_COLUMNS:
            assert _equal(ref.hub[col], got.hub[col]), f"hub: column {col}"
    _same_figures(ref.summary, got.summary, "community")
    written = json.loads((out / "community.json").read_text(encoding="utf-8"))
    _same_figures(ref.summary, written, "community.json")
    assert written["houses_left"] == {}


@pytest.mark.ros
def test_three_houses_and_the_coordinator_equal_in_process_bit_for_bit(tmp_path: Path) -> None:
    """ComEMS4Build in every house, three May days of the year with the hub's electrolysers running."""
    from comems4build_ros.run.launcher import launch

    path = _file(tmp_path)
    out = tmp_path / "run"
    res = launch(LaunchOptions(ems="fuzzy", out=out, scenario="year", start="2022-05-01", weeks=1, steps=36,
                               community=str(path), timeout_s=BUDGET_S))
    ref = _reference(path, "year", 1, 36, "2022-05-01", "fuzzy")
    assert ref.summary["h2_produced_kwh"] > 0.0  # the hub's electrolysers ran
    _same_as_in_process(out, res.bag, ref, tmp_path)
    assert res.community is not None and res.community["houses"] == 3
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []


@pytest.mark.ros
def test_the_fuzzy_coordinator_over_ros_equals_in_process(tmp_path: Path) -> None:
    """FLC_hub (it reads the day-ahead prices and the season of the view) with the RBC in every house."""
    from comems4build_ros.run.launcher import launch

    path = _file(tmp_path)
    out = tmp_path / "run"
    res = launch(LaunchOptions(ems="rbc", out=out, scenario="year", start="2022-05-01", weeks=1, steps=30,
                               community=str(path), coordinator="fuzzy", timeout_s=BUDGET_S))
    ref = _reference(path, "year", 1, 30, "2022-05-01", "rbc", "fuzzy")
    assert ref.summary["coordinator"] == "fuzzy" and ref.hub["p_el_w"].sum() > 0.0  # FLC_hub ran the hub
    _same_as_in_process(out, res.bag, ref, tmp_path)


@pytest.mark.ros
def test_one_network_namespace_host_per_house_equals_in_process(tmp_path: Path) -> None:
    """Each house on a host of its own and the coordinator on another, joined by a bridge, DDS over UDP."""
    import subprocess

    from comems4build_ros.run.launcher import launch

    reason = netns_available()
    if reason:
        pytest.skip(f"network namespaces unavailable: {reason}")
    path = _file(tmp_path)
    out = tmp_path / "run"
    res = launch(LaunchOptions(ems="rbc", out=out, weeks=1, steps=18, community=str(path), network="netns",
                               timeout_s=BUDGET_S))
    _same_as_in_process(out, res.bag, _reference(path, "default", 1, 18, None, "rbc"), tmp_path)
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert f"c4b{res.domain_id}h" not in listed and f"c4b{res.domain_id}b" not in listed  # torn down


def _kill_when(out: Path, house: str, recorded: int):
    """A progress callback that SIGKILLs the plant_sim of ``house`` once ``recorded`` steps (of every
    house) are recorded; the pid it killed in the list it returns."""
    killed: list[int] = []

    def on_progress(r: int, _n: int) -> None:
        if killed or r < recorded:
            return
        for pid in processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")):
            try:
                argv = Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")
            except OSError:
                continue
            if any(Path(a).name == "plant_sim" for a in argv[:3]) and f"__ns:=/{house}" in argv:
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return

    return on_progress, killed


@pytest.mark.ros
def test_a_killed_house_node_fails_a_simulated_time_run_naming_it(tmp_path: Path) -> None:
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.supervisor import LaunchError

    out = tmp_path / "run"
    on_progress, killed = _kill_when(out, "h2", 6)
    with pytest.raises(LaunchError) as err:
        launch(LaunchOptions(ems="rbc", out=out, weeks=4, community=str(_file(tmp_path)), layout="node",
                             timeout_s=BUDGET_S, on_progress=on_progress))
    assert killed
    assert "h2/plant_sim" in err.value.cause and "code -9" in err.value.cause
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []


@pytest.mark.ros
def test_on_a_wall_clock_the_community_goes_on_without_a_house_that_left(tmp_path: Path,
                                                                         capfd: pytest.CaptureFixture[str]) -> None:
    """wall:1200 (3 s steps): h2's plant is killed after a few steps; the others run to the end, h2's
    account stays frozen, the hub's balance closes, the gap is in community.json and hub.csv."""
    from comems4build_ros.run.launcher import launch

    out = tmp_path / "run"
    steps = 8
    on_progress, killed = _kill_when(out, "h2", 7)
    res = launch(LaunchOptions(ems="rbc", out=out, weeks=1, steps=steps, community=str(_file(tmp_path)),
                               layout="node", clock="wall:1200", timeout_s=BUDGET_S, on_progress=on_progress))
    assert killed
    assert "its house(s) /h2 left the run; the community goes on without them" in capfd.readouterr().err
    summary = res.community
    assert summary is not None and summary["steps"] == steps
    left = summary["houses_left"]
    assert list(left) == ["h2"] and 2 <= left["h2"]["left_at_step"] < steps
    hub = pd.read_csv(out / "hub.csv")
    k = left["h2"]["left_at_step"]
    assert (hub["houses_present"][:k] == 3).all() and (hub["houses_present"][k:] == 2).all()
    assert summary["h2_balance_max_rel"] < 1e-9
    h2 = pd.read_csv(out / "houses" / "h2" / "timeseries.csv")
    assert len(h2) == left["h2"]["steps_recorded"] <= k
    for name in ("h1", "h3"):
        assert len(pd.read_csv(out / "houses" / name / "timeseries.csv")) == steps
    # h2's account frozen from the step it left: the accounts' total moves only by the others' draws and credits
    share = res.community["hub_e_max_kwh"] / 4.0  # h2's weight 1 of 4
    h2_account = hub["accounts_kwh"].to_numpy() - _others(out, ("h1", "h3"), res.community["hub_e_max_kwh"])
    assert np.allclose(h2_account[k:], h2_account[k], atol=1e-9 * share)
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []


def _others(out: Path, names: tuple[str, ...], e_max_kwh: float) -> np.ndarray:
    """The accounts of the houses ``names`` per step [kWh] (their LOH times their shares: h1 1/4, h3 2/4)."""
    weights = {"h1": 1.0, "h3": 2.0}
    return sum(pd.read_csv(out / "houses" / n / "timeseries.csv")["loh"].to_numpy() * e_max_kwh * weights[n] / 4.0
               for n in names)


# ----------------------------------------------------------------- without processes
def test_the_plan_of_a_community(tmp_path: Path) -> None:
    path = _file(tmp_path)
    plan = plan_any(LaunchOptions(ems="fuzzy", out=tmp_path / "o", weeks=1, steps=5, community=str(path),
                                  coordinator="rule", coordinator_options=["h2_split=need"]), 7)
    assert [h.namespace for h in plan.houses] == ["/h1", "/h2", "/h3"]
    coordinator = [n for _p, n in plan.nodes("coordinator")]
    assert len(coordinator) == 1 and coordinator[0].namespace == "/"
    assert coordinator[0].params["coordinator_options"] == ["h2_split=need"]
    assert len(coordinator[0].params["hub_token_files"]) == 3
    plants = [n for _p, n in plan.nodes("plant")]
    assert all(n.params["hub"] and n.params["hub_token_file"].endswith(f"{n.namespace[1:]}.hub.token") for n in plants)
    feeds = [n for _p, n in plan.nodes("feed")]
    assert sorted(n.params["community_house"] for n in feeds) == ["h1", "h2", "h3"]
    recorders = [n for _p, n in plan.nodes("recorder")]
    assert sum(n.params.get("follows") == "coordinator" for n in recorders) == 1
    assert len(plan.secrets) == 6 and len({t for _f, t in plan.secrets}) == 6  # a run and a hub secret per house
    assert not any(p.may_leave for p in plan.processes)
    wall = plan_any(LaunchOptions(ems="rbc", out=tmp_path / "o", weeks=1, community=str(path), clock="wall:60",
                                  network="netns"), 7)
    assert {p.side for p in wall.processes} == {"coordinator", "house_h1", "house_h2", "house_h3"}
    assert all(p.may_leave == (p.side != "coordinator") for p in wall.processes)
    assert all(len({n.namespace for n in p.nodes}) == 1 for p in wall.processes)


@pytest.mark.parametrize("change, words", [
    ({"houses": 2}, "no --houses"),
    ({"layout": "role"}, "layout node or house"),
    ({"plant": "mqtt"}, "plant 'sim'"),
    ({"coordinator": "nonesuch"}, "unknown coordinator 'nonesuch'"),
    ({"coordinator": "central"}, "coordinator 'central' reads every house's MPC-level observation"),
    ({"coordinator": "distributed"}, r"does not receive over ROS 2; over ROS 2 run a coordinator of information "
                                     r"level hub \(rule, fuzzy\)"),
])
def test_a_community_plan_refuses_what_it_cannot_run(tmp_path: Path, change: dict, words: str) -> None:
    opts = dataclasses.replace(LaunchOptions(ems="rbc", out=tmp_path / "o", community=str(_file(tmp_path))), **change)
    with pytest.raises(ValueError, match=words):
        plan_any(opts, 7)


@pytest.mark.parametrize("argv, words", [
    (["--coordinator", "central"], "--coordinator central: coordinator 'central' reads every house's MPC-level"),
    (["--coordinator", "distributed"], "run a coordinator of information level hub (rule, fuzzy)"),
    (["--coordinator", "nonesuch"], "--coordinator nonesuch: unknown coordinator 'nonesuch'"),
    (["--coordinator", "fuzzy", "--coordinator-option", "rules=no_such_rules.yaml"], "no_such_rules.yaml"),
])
def test_launch_community_refuses_a_coordinator_it_cannot_run_before_starting(tmp_path: Path, capsys, argv: list,
                                                                             words: str) -> None:
    from comems4build_ros.app.cli import main

    out = tmp_path / "run"
    assert main(["launch", "--community", str(_file(tmp_path)), "--ems", "rbc", "--weeks", "1", "--steps", "4", *argv,
                 "--out", str(out)]) == 2
    assert words in capsys.readouterr().err
    assert not (out / "bag").exists()


def test_a_house_named_like_the_coordinator_s_bag_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(THREE.replace("name: h2,", "name: coordinator,"), encoding="utf-8")
    with pytest.raises(ValueError, match="may not be called 'coordinator'"):
        plan_any(LaunchOptions(ems="rbc", out=tmp_path / "o", community=str(path)), 7)


def test_the_contract_s_community_topics_match_the_hub_s_records() -> None:
    contract = load_contract()
    record = contract.topic("hub/record").field_names()
    assert record[:3] == ("step", "n_steps", "time_unix_s")
    assert list(record[3:]) == [c for c in HUB_TIMESERIES_COLUMNS if c not in ("time", "step")]
    report = contract.topic("hub/report").field_names()
    assert list(report) == ["step", "loh", *(f.name for f in dataclasses.fields(HouseMeter)), "p_el_w", "token"]
    assert contract.topic("feed/h2_allowance").publishers == ("feed", "coordinator")
    assert {t.name for t in contract.in_scope("community_house")} == {"hub/allotment", "hub/report", "hub/settlement"}


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=1, max_size=14),
       st.integers(1, 2**53 - 1), st.integers(1, 2**53 - 1), st.integers(0, 13))
def test_a_hub_message_is_authentic_under_its_house_s_secret_only(values, secret, other, at) -> None:
    """Signed (sign) messages: authentic under their key, not under another, not with one value changed."""
    key = secret_key(secret)
    msg = sign(key, array("d", values))
    assert authentic(key, msg)
    if other != secret:
        assert not authentic(secret_key(other), msg)
    changed = list(msg)
    i = at % len(values)
    changed[i] = changed[i] + 1.0 if abs(changed[i]) < 1e15 else changed[i] / 2.0
    if changed[i] != msg[i]:
        assert not authentic(key, changed)
    assert authentic(None, msg)  # without a secret (nodes started by hand) nothing is checked


@settings(max_examples=8, deadline=None)
@given(st.integers(2, 5), st.data())
def test_an_absent_house_keeps_its_account_frozen_and_the_balance_closed(n: int, data) -> None:
    """Over random communities of the year's spring (fuel cells and electrolysers run): a house absent
    from a random step on (a wall-clock run it left) gets no transfer, draw or credit and its account
    stays as it was; the store stays the accounts plus the pool, every step, to 1e-6 of the throughput."""
    from comems4build_ros.core.community.coordinator import Request
    from comems4build_ros.core.loop import exogenous_series

    houses = [HouseSpec(name=f"h{i}", reason="random neighbour", load_scale=data.draw(st.floats(0.4, 1.5)),
                        pv_n_modules=data.draw(st.integers(10, 40)), h2_weight=data.draw(st.floats(0.5, 2.0)))
              for i in range(n)]
    hours = 36
    community = build_community(CommunitySpec(name="random", houses=houses), "year", start="2022-04-25", hours=hours,
                                overrides={"simulation.loh_init": data.draw(st.sampled_from([0.3, 0.9]))})
    gone, since = data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, hours - 1))
    plant = CommunityPlant(community)
    run = HubRun(community, "rule", {"h2_split": data.draw(st.sampled_from(["equal", "need"])), "need_days": 1})
    states = plant.initial_states()
    run.start(states)
    exos = [exogenous_series(h.scenario, h.plant_params) for h in community.houses]
    col = {c: HUB_TIMESERIES_COLUMNS.index(c) for c in ("p_h2_el_w", "p_h2_fc_w", "h2_residual_wh", "houses_present")}
    throughput, frozen = run.hub.e_wh, None
    for k in range(hours):
        present = [i != gone or k < since for i in range(n)]
        run.allot(k, states, present)
        if k == since:
            frozen = states[gone].loh
        actions = [Action(p_fc_w=2000.0 if e[k].p_load_w > e[k].p_pv_w else 0.0,
                          p_el_w=max(0.0, e[k].p_pv_w - e[k].p_load_w)) for e in exos]
        new, flows = plant.houses_step(states, actions, [e[k] for e in exos])
        if not present[gone]:  # the house is gone: what its plant did reaches the hub no more
            new[gone] = states[gone]
        run.settle(k, new, [f if p else NO_FLOWS for f, p in zip(flows, present)],
                   [Request(a.p_el_w, 0.0, 0.0) if p else NO_REQUEST for a, p in zip(actions, present)], present)
        states = new
        row = run.rows[-1]
        if frozen is not None:
            assert states[gone].loh == frozen
        throughput += row[col["p_h2_el_w"]] + row[col["p_h2_fc_w"]]
        assert abs(row[col["h2_residual_wh"]]) <= 1e-6 * throughput
        assert row[col["houses_present"]] == sum(present)
    assert initial_accounts(community)[gone].loh == community.houses[gone].plant_params.simulation.loh_init
