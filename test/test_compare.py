"""``comems4build compare`` options: efficiencies, run names, bad input (exit 2, nothing run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from comems4build_ros.cli import main
from comems4build_ros.commands.compare import parse_etas, run_name
from comems4build_ros.report.runner import override_file


def test_parse_etas() -> None:
    assert parse_etas("0.75,0.90") == [0.75, 0.9]
    assert parse_etas("0.9") == [0.9]


def test_run_names() -> None:
    assert run_name("rbc", 0.75, 0.75) == "rbc"
    assert run_name("rbc", 0.90, 0.75) == "rbc_eta90"
    assert run_name("mpc", 0.75, 0.90) == "mpc_eta75"


def test_override_file_is_a_ros_parameter_file(tmp_path: Path) -> None:
    from comems4build_ros.config import load_plant_params

    path = override_file({"fuel_cell.eta_sys": 0.9, "battery.e_max_kwh": 10.0}, tmp_path / "o.yaml")
    params = load_plant_params([path])
    assert params.fuel_cell.eta_sys == 0.9
    assert params.battery.e_max_kwh == 10.0


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
