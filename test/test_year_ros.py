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

from comems4build_ros.config import load_plant_params, scenario_config_files
from comems4build_ros.ros.launcher import launch
from comems4build_ros.ros.plan import LaunchOptions
from comems4build_ros.scenario.run import load_scenario
from comems4build_ros.sim import simulate

pytestmark = pytest.mark.ros
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")
START = "2022-07-18T06:00:00"
STEPS = 36


@pytest.mark.parametrize("ems", ["fuzzy", "mpc"])
def test_year_window_over_ros_equals_in_process(ems: str, tmp_path: Path) -> None:
    out = tmp_path / "run"
    launch(LaunchOptions(ems=ems, out=out, scenario="year", start=START, steps=STEPS, timeout_s=240))
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
