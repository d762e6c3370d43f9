"""The installed console scripts, run as a user would (outside the repo, no PYTHONPATH).

`comems4build launch` (separate node processes over DDS, MCAP bag, evaluation from the
bag) must give the same summary as `comems4build simulate` for the same EMS and scenario.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from waits import BUDGET_S

BIN = Path(sys.executable).parent
WALL_KEYS = {"wall_s", "ems_s", "bag_duration_s", "lost_messages"}


def _env(tmp: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["ROS_LOG_DIR"] = str(tmp / "roslog")
    return env


@pytest.mark.ros
def test_installed_launch_equals_installed_simulate(tmp_path: Path) -> None:
    exe = BIN / "comems4build"
    if not exe.exists():
        pytest.skip("console script not installed (run tools/setup.sh)")
    env = _env(tmp_path)
    run = dict(cwd=tmp_path, env=env, capture_output=True, text=True, timeout=BUDGET_S)
    sim = subprocess.run([str(exe), "simulate", "--ems", "rbc", "--weeks", "1", "--out", "sim", "--no-progress"], **run)
    assert sim.returncode == 0, sim.stderr[-2000:]
    ros = subprocess.run([str(exe), "launch", "--ems", "rbc", "--weeks", "1", "--out", "ros", "--no-progress"], **run)
    assert ros.returncode == 0, (ros.stdout[-2000:], ros.stderr[-2000:])
    a = json.loads((tmp_path / "sim" / "summary.json").read_text())
    b = json.loads((tmp_path / "ros" / "summary.json").read_text())
    assert (tmp_path / "ros" / "bag" / "metadata.yaml").is_file()
    diff = {k: (a.get(k), b.get(k)) for k in (set(a) | set(b)) - WALL_KEYS if a.get(k) != b.get(k)}
    assert not diff, diff
