"""``comems4build bench ros`` end to end on a short run (the figures themselves are the benchmark's)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from waits import BUDGET_S

pytestmark = pytest.mark.ros

CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main(sys.argv[1:]))"]


def test_bench_ros_runs_both_layouts_and_reports_no_loss(tmp_path: Path) -> None:
    out = subprocess.run([*CLI, "bench", "ros", "--weeks", "0.1", "--houses", "1,2", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=BUDGET_S)
    assert out.returncode == 0, out.stderr
    text = out.stdout
    # the one-house run in both layouts equals the in-process run and lost nothing
    assert text.count("summaries equal (timing aside): yes; messages lost by the recorder: 0") == 2, text
    assert "over ROS, one process per node:" in text and "over ROS, 1 container process(es):" in text
    rows = [r for r in (line.split() for line in text.splitlines())
            if len(r) >= 11 and r[0].isdigit() and r[1] in ("node", "house", "role")]
    table = {(r[0], r[1]): r for r in rows}
    assert set(table) == {("1", "node"), ("1", "house"), ("2", "house")}, text
    assert all(r[10] == "0" and r[8] == "0" for r in table.values())  # lost, fallback
    assert table[("1", "node")][2] == "4" and table[("1", "house")][2] == "1"  # processes
    assert table[("2", "house")][2] == str(min(2, os.cpu_count() or 1))
    # the runs of each layout (the output layer's owner record aside)
    runs = sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))
    assert runs == ["fuzzy_0.1w_house", "fuzzy_0.1w_node", "fuzzy_0.1w_x2"]
