"""Nodes composed the ROS 2 way: remapped names, a shadow EMS beside the house's own, another naming scheme.

Two user launch files (``test/fixtures/launch/``) started with the real ``ros2 launch``:
one runs a shadow RBC beside the fuzzy EMS that controls the house, its commands remapped
away from the plant and recorded by a second recorder; the other renames every topic
into another scheme and runs every node on simulated time (a launch-wide
``SetParameter``). The contract holds in both (it checks roles, types and QoS, not the
names remapping gives), and both runs equal their in-process counterparts bit for bit.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from ros2_tools import run_ros2
from waits import BUDGET_S

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate

pytestmark = pytest.mark.ros

LAUNCH_FILES = Path(__file__).resolve().parent / "fixtures" / "launch"
CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")
STEPS = 30


def _scenario(steps: int):
    from comems4build_ros.core.scenario.run import load_scenario

    params = load_plant_params()
    return params, load_scenario("default", params, None, 1, None, steps)


def reference(ems: str, steps: int) -> dict:
    params, scenario = _scenario(steps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate(ems, scenario, params).summary


def shadow_decisions(main: str, shadow: str, steps: int) -> list[list[float]]:
    """What ``shadow`` decides at each step of a run controlled by ``main`` (in-process): the
    shadow sees the same states, its own information level, and nothing it decides is applied."""
    from comems4build_ros.core.ems import make_controller
    from comems4build_ros.core.loop import ObservationBuilder, exogenous_series, load_forecast_settings
    from comems4build_ros.core.plant import Plant
    from comems4build_ros.core.types import ACTION_FIELDS

    params, scenario = _scenario(steps)
    ctrl, shade = make_controller(main, params), make_controller(shadow, params)
    ctrl.reset()
    shade.reset()
    plant = Plant(params)
    exo = exogenous_series(scenario, params)
    forecast = load_forecast_settings()
    build = ObservationBuilder(scenario, params, ctrl.info_level, exo, forecast)
    build_shadow = ObservationBuilder(scenario, params, shade.info_level, exo, forecast)
    state = plant.initial_state()
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(steps):
            decided = shade.act(build_shadow.build(k, state))
            out.append([float(k), *(float(getattr(decided, f)) for f in ACTION_FIELDS)])
            state, _flows = plant.step(state, ctrl.act(build.build(k, state)), exo[k])
    return out


def evaluate(bag: Path, out: Path) -> dict:
    res = subprocess.run([*CLI, "evaluate", str(bag), "--out", str(out)], capture_output=True, text=True,
                         timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr
    return json.loads((out / "summary.json").read_text())


def same_kpis(got: dict, want: dict) -> None:
    for k in sorted(set(want) - set(TIMING_KEYS)):
        a, b = got[k], want[k]
        assert (isinstance(a, float) and math.isnan(a) and math.isnan(b)) or a == b, k


def test_a_shadow_ems_beside_the_house_ems(ros2, domain_id, tmp_path) -> None:
    """The fuzzy EMS controls the house (its run equals the in-process one, no foreign
    command reached the plant); the shadow RBC, remapped, decided every step as the RBC
    decides on those very states, and its bag holds each decision."""
    from rosbags.highlevel import AnyReader

    out = tmp_path / "run"
    res = run_ros2(ros2, ["launch", str(LAUNCH_FILES / "shadow_ems.launch.py"), f"out:={out}", f"steps:={STEPS}"],
                   domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-4000:]
    assert "[shadow_ems]" in res.stdout and "recording" in res.stdout
    summary = evaluate(out / "bag", tmp_path / "eval")
    assert summary["steps"] == STEPS and summary["lost_messages"] == {}
    assert "ros_faults" not in summary  # no foreign or rejected command
    same_kpis(summary, reference("fuzzy", STEPS))
    with AnyReader([out / "shadow_bag"]) as reader:
        conns = {c.topic: c for c in reader.connections}
        commands = [list(reader.deserialize(raw, c.msgtype).data)
                    for c, _t, raw in reader.messages(connections=[conns["/shadow/ems/command"]])]
        infos = [json.loads(reader.deserialize(raw, c.msgtype).data)
                 for c, _t, raw in reader.messages(connections=[conns["/shadow/ems/info"]])]
    by_step = {int(c[0]): c[:-1] for c in commands}  # the last element is the run token
    # The shadow's first decision can be missing from its bag (once in three full suite runs):
    # its writer had matched the shadow recorder's reader (the gate) but that reader had not yet
    # matched the writer, and a volatile DDS reader drops what a writer sent before it matched
    # it (docs/limitations.md). Every later decision is there, as the RBC decides it.
    assert sorted(by_step) in (list(range(STEPS)), list(range(1, STEPS))), sorted(by_step)
    assert {i["ems"] for i in infos} == {"rbc"}
    want = shadow_decisions("fuzzy", "rbc", STEPS)
    assert [by_step[k] for k in sorted(by_step)] == [want[k] for k in sorted(by_step)]


def test_every_topic_renamed_into_another_scheme_on_simulated_time(ros2, domain_id, tmp_path) -> None:
    """Every topic of plant, feed, EMS and recorder renamed (``/bus/state_t_air_c`` ...) and every
    node on simulated time: the run equals the in-process RBC run, the recorder names what it
    read where, and its bag holds the contract's names."""
    bag = tmp_path / "bag"
    res = run_ros2(ros2, ["launch", str(LAUNCH_FILES / "renamed_topics.launch.py"), f"out:={bag}",
                          f"steps:={STEPS}"], domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-4000:]
    assert "/state/t_air_c -> /bus/state_t_air_c" in res.stdout and "/ems/command -> /bus/ems_command" in res.stdout
    assert re.search(r"\[sim 2022-1[12]-\d\dT\d\d:00:00Z\]", res.stdout)  # 2022-12-01 00:00 CET = 23:00Z
    summary = evaluate(bag, tmp_path / "eval")
    assert summary["steps"] == STEPS and summary["lost_messages"] == {}
    same_kpis(summary, reference("rbc", STEPS))
