"""Command line: the simulate path end to end and exit code 2 for invalid input."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from comems4build_ros.app.cli import main


def test_unknown_ems_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--ems", "oracle", "--out", str(tmp_path)]) == 2
    assert "unknown EMS 'oracle'" in capsys.readouterr().err


def test_unreadable_config_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--ems", "thermostat", "--config", str(tmp_path / "x.yaml"), "--out", str(tmp_path)]) == 2
    assert "x.yaml" in capsys.readouterr().err


def test_invalid_parameter_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["simulate", "--ems", "thermostat", "--set", "battery.soc_min=2", "--out", str(tmp_path)]) == 2
    assert "battery.soc_min" in capsys.readouterr().err


def test_missing_scenario_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.csv"
    assert main(["simulate", "--ems", "thermostat", "--scenario", str(missing), "--out", str(tmp_path)]) == 2
    assert "nope.csv" in capsys.readouterr().err


def test_invalid_option_exits_2(tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "--ems", "thermostat", "--weeks", "many", "--out", str(tmp_path)])
    assert exc.value.code == 2


def test_simulate_thermostat_12_weeks_writes_three_files(tmp_path: Path) -> None:
    """Done-when of the plant issue: 12 weekly rows and a closed power balance."""
    assert main(["simulate", "--ems", "thermostat", "--out", str(tmp_path), "--no-progress"]) == 0
    ts = pd.read_csv(tmp_path / "timeseries.csv")
    weekly = pd.read_csv(tmp_path / "weekly.csv")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert len(ts) == 12 * 168
    assert len(weekly) == 12
    assert summary["weeks"] == 12 and summary["steps"] == 2016
    assert summary["max_balance_residual_w"] < 1e-6
    for key in ("cost_eur_week_median", "reimbursement_eur_week_median", "discomfort_kh_week_median",
                "discomfort_weeks_nonzero", "buy_kwh_week_median", "sell_kwh_week_median",
                "bess_charged_kwh_week_median", "h2_kwh_week_min", "h2_kwh_week_max", "fc_working_hours",
                "fc_toggles", "loh_end", "h2_empty_at", "dhw_unmet_kwh", "clipped_actions", "wall_s"):
        assert key in summary
    # the thermostat never runs the fuel cell or the battery
    assert summary["fc_working_hours"] == 0 and summary["loh_end"] == 1.0
    assert summary["bess_charged_kwh_week_median"] == 0.0
    # and buys what the house needs: weekly cost equals the sum of price x bought energy
    cost = (ts["price_buy_eur_per_kwh"] * ts["p_buy_w"]).sum() / 1000.0
    assert weekly["cost_eur"].sum() == pytest.approx(cost)


def test_readme_command_table_is_generated_from_the_parsers() -> None:
    """Every option of every subcommand is in the README (regenerate: python -m comems4build_ros.app.commands.table
    --update-doc README.md)."""
    from comems4build_ros.app.commands.table import BEGIN, END, command_table, rows

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    block = readme.split(BEGIN, 1)[1].split(END, 1)[0].strip()
    assert block == command_table()
    for name, options, _ in rows():
        line = next(line for line in block.splitlines() if line.startswith(f"| `comems4build {name}` |"))
        for opt in options:
            for flag in opt.strip("[]").split(" | "):
                assert flag.split()[0] in line, f"{name}: {flag}"
