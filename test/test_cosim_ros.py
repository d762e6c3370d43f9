"""The EnergyPlus house over ROS 2 (plant_sim runs it) equals the in-process run exactly."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from waits import BUDGET_S

from comems4build_ros.app.ros2_launch import ARGUMENTS
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario.run import load_scenario
from comems4build_ros.run.launcher import launch
from comems4build_ros.run.plan import LaunchOptions

pytestmark = pytest.mark.ros
pytest.importorskip("pyenergyplus")
STEPS = 48


def test_energyplus_house_over_ros_equals_in_process(tmp_path: Path) -> None:
    out = tmp_path / "run"
    launch(LaunchOptions(ems="fuzzy", out=out, steps=STEPS, timeout_s=BUDGET_S, building="energyplus"))
    params = load_plant_params()
    ref = simulate("fuzzy", load_scenario("default", params, None, None, None, STEPS), params, building="energyplus")
    ros = pd.read_csv(out / "timeseries.csv")
    mine = ref.timeseries
    cols = [c for c in mine.columns if c in ros.columns and c != "time"]
    assert "t_air_c" in cols and "q_hp_sh_w" in cols
    for c in cols:
        assert ros[c].equals(mine[c].astype(ros[c].dtype)), c
    assert (mine["q_hp_sh_w"] > 0).any()


def test_launch_file_takes_the_building():
    assert ARGUMENTS["building"][0] == "rc" and ARGUMENTS["building"][2] == "--building"


def test_launch_refuses_a_broken_idf_before_starting(tmp_path: Path, capsys) -> None:
    from comems4build_ros.app.cli import main

    bad = tmp_path / "bad.idf"
    bad.write_text("Version, 9.6;\n")
    assert main(["launch", "--ems", "fuzzy", "--building", f"energyplus:{bad}", "--steps", "2",
                 "--out", str(tmp_path / "run")]) == 2
    assert "field Version Identifier" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
