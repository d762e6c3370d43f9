"""``comems4build compare`` options: efficiencies, run names, bad input (exit 2, nothing run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.app.commands.compare import parse_etas, run_name


def test_parse_etas() -> None:
    assert parse_etas("0.75,0.90") == [0.75, 0.9]
    assert parse_etas("0.9") == [0.9]


def test_run_names() -> None:
    assert run_name("rbc", 0.75, 0.75) == "rbc"
    assert run_name("rbc", 0.90, 0.75) == "rbc_eta90"
    assert run_name("mpc", 0.75, 0.90) == "mpc_eta75"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--fc-efficiency", "0.75,abc"], "'abc' is not a number"),
        (["--fc-efficiency", "1.5"], "outside (0, 1]"),
        (["--fc-efficiency", "0.75,0.75"], "given twice"),
        (["--ems", "rbc,nosuch"], "unknown EMS 'nosuch'"),
        (["--set", "battery.e_max_kwh=-1"], "battery.e_max_kwh"),
        (["--config", "/nonexistent.yaml"], "/nonexistent.yaml: no such file"),
    ],
)
def test_bad_input_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str) -> None:
    out = tmp_path / "c"
    assert main(["compare", *argv, "--weeks", "1", "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_out_required(capsys: pytest.CaptureFixture) -> None:
    assert main(["compare", "--weeks", "1"]) == 2
    assert "--out is required" in capsys.readouterr().err


@pytest.mark.ros
def test_via_ros_equals_inprocess(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """One RBC week through the node set: bag recorded, KPIs read from it equal the in-process run."""
    import json

    monkeypatch.setenv("ROS_LOG_DIR", str(tmp_path / "roslog"))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    common = ["--ems", "rbc", "--weeks", "1", "--fc-efficiency", "0.75"]
    assert main(["compare", *common, "--via", "ros", "--out", str(tmp_path / "ros")]) == 0
    assert main(["compare", *common, "--out", str(tmp_path / "ip")]) == 0
    run = tmp_path / "ros" / "runs" / "rbc"
    assert any((run / "bag").glob("*.mcap"))
    assert (run / "timeseries.csv").stat().st_size > 0
    ros = json.loads((run / "summary.json").read_text())
    ip = json.loads((tmp_path / "ip" / "runs" / "rbc" / "summary.json").read_text())
    for key in ("cost_eur_week_median", "buy_kwh_week_median", "sell_kwh_week_median", "discomfort_kh_week_median",
                "fc_working_hours", "fc_toggles", "loh_end", "h2_kwh_total"):
        assert ros[key] == pytest.approx(ip[key], rel=1e-9, abs=1e-9), key
    assert json.loads((tmp_path / "ros" / "compare.json").read_text())["via"] == "ros"
    assert "runs ros" in (tmp_path / "ros" / "report.md").read_text()
