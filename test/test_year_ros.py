"""A year-round run over ROS 2 (real nodes, DDS, MCAP) equals the in-process run exactly.

A shortened window of the year scenario (a summer day and a half: the electrolyser and the
cooling work) through ``launch``; every summary key, the year's KPIs included, must equal the
in-process run of the same window; the recorded flows carry the electrolyser and cooling.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import pytest
from waits import BUDGET_S, wait_exit

from comems4build_ros.core.config import load_plant_params, scenario_config_files
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario.run import load_scenario
from comems4build_ros.run.launcher import launch
from comems4build_ros.run.plan import LaunchOptions

pytestmark = pytest.mark.ros
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")
START = "2022-07-18T06:00:00"
STEPS = 36


@pytest.mark.parametrize("ems", ["fuzzy", "mpc"])
def test_year_window_over_ros_equals_in_process(ems: str, tmp_path: Path) -> None:
    out = tmp_path / "run"
    # the plant waits for every command (the budget as its step time-out): this compares runs, a
    # fallback on a slow MPC step of a loaded machine would be the machine's
    launch(LaunchOptions(ems=ems, out=out, scenario="year", start=START, steps=STEPS, timeout_s=BUDGET_S,
                         plant_node_params={"step_timeout_s": BUDGET_S}))
    ros = json.loads((out / "summary.json").read_text())
    params = load_plant_params(scenario_config_files("year"))
    scenario = load_scenario("year", params, START, None, None, STEPS)
    ref = simulate(ems, scenario, params).summary
    keys = set(ref) - set(TIMING_KEYS)
    assert keys == set(ros) - set(TIMING_KEYS)
    for k in sorted(keys):
        a, b = ros[k], ref[k]
        if isinstance(b, float) and math.isnan(b):
            assert isinstance(a, float) and math.isnan(a), k
        else:
            assert a == b, k
    assert ros["h2_produced_kwh"] > 0.0 and ros["scenario"] == "year"
    ts = pd.read_csv(out / "timeseries.csv")
    assert ts["p_el_w"].max() > 0.0 and "q_cool_w" in ts and "cmd_p_el_w" in ts
    assert (out / "monthly.csv").exists()


def test_year_inputs_replayed_drive_the_rbc(tmp_path: Path) -> None:
    """The recorded feed of a year window (feed/season included) drives plant_sim and the RBC over ROS:
    the evaluated bag equals the in-process RBC run of that window."""
    from comems4build_ros.bags.evaluation import evaluate_bag
    from comems4build_ros.run.plan import node_command, ros_args
    from comems4build_ros.run.supervisor import ProcessGroup, acquire_domain_id, child_env

    rec_run = launch(LaunchOptions(ems="fuzzy", out=tmp_path / "rec", scenario="year", start=START, steps=STEPS,
                                   timeout_s=BUDGET_S))
    files = scenario_config_files("year")
    bag = tmp_path / "rbc_bag"

    def wait(child) -> int:
        try:
            return wait_exit(child.proc, f"{child.name} to exit")
        except AssertionError as exc:
            raise AssertionError(f"{exc}\n{child.tail()}") from None

    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = group.start("recorder", "recorder", [*node_command("recorder"), *ros_args("", {"bag_path": str(bag)})])
        # the replay and the EMS as the launcher starts the feed and the EMS: their first message
        # waits until their writers matched the recorder's readers (else the first steps can miss)
        group.start("rbc_ems", "ems", [*node_command("ems", "rbc"), *ros_args(
            "", {"config_files": files, "wait_for_recorder": True})])
        group.start("replay", "replay", [*node_command("replay"), str(rec_run.bag), "--inputs-only",
                                         *ros_args("", {"wait_for_recorder": True})])
        plant = group.start("plant_sim", "plant", [*node_command("plant_sim"), *ros_args(
            "", {"wait_for_recorder": True, "config_files": files})])
        assert wait(plant) == 0, plant.tail()
        assert wait(rec) == 0, rec.tail()
    params = load_plant_params(files)
    summary = evaluate_bag(bag, tmp_path / "eval", params=params)["/"]
    ref = simulate("rbc", load_scenario("year", params, START, None, None, STEPS), params).summary
    for key in set(ref) - {"wall_s", "ems_s", "scenario"}:
        assert summary[key] == ref[key], key
    assert summary["h2_produced_kwh"] > 0.0 and summary["lost_messages"] == {}


def test_year_cli_launch_and_evaluate_across_the_heating_season_start(tmp_path: Path) -> None:
    """``comems4build launch --scenario year`` and ``comems4build evaluate`` of its bag (plant parameters from
    the bag's run_info.json, no --config) over the night the heating season starts (2022-12-01): the summary,
    weekly and monthly tables equal the in-process run's; the bag carries state/el_on and feed/season."""
    import subprocess
    import sys

    from rosbags.highlevel import AnyReader

    from comems4build_ros.core.loop import write_run

    cli = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
    start, steps = "2022-11-30T18:00:00", 12
    out = tmp_path / "run"
    proc = subprocess.run([*cli, "launch", "--ems", "fuzzy", "--scenario", "year", "--start", start, "--steps",
                           str(steps), "--out", str(out), "--no-progress"],
                          capture_output=True, text=True, timeout=BUDGET_S)
    assert proc.returncode == 0, proc.stderr
    ev = tmp_path / "eval"
    proc = subprocess.run([*cli, "evaluate", str(out / "bag"), "--out", str(ev)], capture_output=True, text=True,
                          timeout=BUDGET_S)
    assert proc.returncode == 0, proc.stderr
    params = load_plant_params(scenario_config_files("year"))
    ref = simulate("fuzzy", load_scenario("year", params, start, None, None, steps), params)
    write_run(ref, tmp_path / "ref", timeseries=False)
    for run_dir in (out, ev):
        got = json.loads((run_dir / "summary.json").read_text())
        for k in sorted(set(ref.summary) - set(TIMING_KEYS)):
            b = ref.summary[k]
            assert (isinstance(got[k], float) and math.isnan(got[k])) if isinstance(b, float) and math.isnan(b) \
                else got[k] == b, (run_dir.name, k)
        for name in ("weekly.csv", "monthly.csv"):
            assert (run_dir / name).read_text() == (tmp_path / "ref" / name).read_text(), (run_dir.name, name)
    monthly = pd.read_csv(ev / "monthly.csv")
    assert list(monthly["month"]) == ["2022-11", "2022-12"]
    assert ref.summary["loh_heating_season_start"] is not None
    with AnyReader([out / "bag"]) as reader:
        conns = {c.topic: c for c in reader.connections}
        season = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages([conns["/feed/season"]])]
        el_steps = [int(reader.deserialize(raw, c.msgtype).data[0])
                    for c, _, raw in reader.messages([conns["/state/el_on"]])]
        n_fc = sum(1 for _ in reader.messages([conns["/state/fc_on"]]))
    assert sorted(set(el_steps)) == list(range(steps)) and len(el_steps) == n_fc  # published as state/fc_on
    by_step = {int(m[0]): list(m[1:]) for m in season}  # the feed may send a step again (lockstep resend)
    assert sorted(by_step) == list(range(steps))
    assert all(list(m[1:]) == by_step[int(m[0])] for m in season)
    # days to the heating season fall to 0 at 2022-12-01 00:00 (step 6), the days left then count down from 90
    assert [by_step[5], by_step[6]] == [[pytest.approx(1 / 24), 0.0], [0.0, pytest.approx(90.0)]]


def test_bench_year_prints_the_figures_and_the_ros_run_equals_in_process(tmp_path: Path) -> None:
    """``comems4build bench year`` on a short window of the year: the in-process lines with their targets and
    seasonal figures, and the composed ROS run whose summary equals the in-process one."""
    import subprocess
    import sys

    cli = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
    proc = subprocess.run([*cli, "bench", "year", "--ems", "rbc,fuzzy", "--weeks", "0.25", "--ros",
                           "--ros-ems", "fuzzy", "--out", str(tmp_path / "bench")],
                          capture_output=True, text=True, timeout=BUDGET_S)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("year scenario, 0.25 weeks from 2022-03-01; load average")
    for ems in ("rbc", "fuzzy"):
        line = next(x for x in lines if x.startswith(f"{ems:6s} in-process: scenario"))
        assert "target < 3 s" in line
    assert sum("LOH 2022-12-01 None, end" in x and "H2 made" in x for x in lines) == 2  # March: no season yet
    ros = next(x for x in lines if x.startswith("fuzzy  over ROS, composed (one container)"))
    assert "summary equals in-process: yes" in ros and "load average" in ros
    assert (tmp_path / "bench" / "ros_fuzzy" / "bag").is_dir()
    assert (tmp_path / "bench" / "fuzzy" / "summary.json").is_file()
