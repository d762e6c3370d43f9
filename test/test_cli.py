"""Command line: the simulate path end to end and exit code 2 for invalid input."""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from collections.abc import Iterator
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


#: reST markup that argparse would print as is: inline literals and Sphinx roles.
REST_MARKUP = re.compile(r"``|:[a-z]+:`|^\.\. [a-z]+::", re.MULTILINE)
#: Libraries no ``--help`` may import (the parser is built without them).
HEAVY = ("numpy", "pandas", "matplotlib", "rclpy", "pulp", "highspy", "scipy", "dask", "pvlib", "skfuzzy")


def _helps(parser: argparse.ArgumentParser, name: str = "comems4build") -> Iterator[tuple[str, str]]:
    """``(command, help text)`` of ``parser`` and of every subcommand under it."""
    yield name, parser.format_help()
    for action in parser._actions:  # noqa: SLF001 (argparse keeps the subparsers here)
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for sub, p in action.choices.items():
                yield from _helps(p, f"{name} {sub}")


def test_help_is_plain_text() -> None:
    """``comems4build --help`` and every ``COMMAND --help`` print no reST markup (argparse shows it raw)."""
    from comems4build_ros.app.cli import COMMANDS, build_parser

    helps = dict(_helps(build_parser()))
    assert {f"comems4build {c}" for c in COMMANDS} <= set(helps)
    assert len(helps) > len(COMMANDS) + 2  # bench and data have their own subcommands
    found = [f"{name}: {m.group(0)!r}" for name, text in helps.items() for m in REST_MARKUP.finditer(text)]
    assert found == []
    for bad in ("``comems4build``", ":mod:`x`", ":class:`~a.B`", ".. note::"):
        assert REST_MARKUP.search(bad), bad


def _modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter has imported after running ``code`` (from the repository root)."""
    probe = f"import sys\n{code}\nprint('\\n'.join(sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], cwd=Path(__file__).resolve().parents[1],
                         capture_output=True, text=True, check=True).stdout
    return set(out.split())


def test_top_level_help_imports_no_command_module() -> None:
    """``comems4build --help`` lists every command from cli.COMMANDS alone: no command module, no core."""
    mods = _modules_after("import contextlib, io\nfrom comems4build_ros.app.cli import main\n"
                          "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
                          "    main(['--help'])")
    assert "comems4build_ros.app.cli" in mods
    assert not [m for m in mods if m.startswith(("comems4build_ros.app.commands.", "comems4build_ros.core"))]
    assert not [m for m in mods if m.split(".")[0] in HEAVY]


def test_every_parser_is_built_without_numerical_or_ros_libraries() -> None:
    """Building every command's options (what ``COMMAND --help`` does) imports none of :data:`HEAVY`."""
    mods = _modules_after("from comems4build_ros.app.cli import build_parser\nbuild_parser().format_help()")
    assert "comems4build_ros.app.commands.simulate" in mods and "comems4build_ros.app.bench.mpc" in mods
    assert sorted({m.split(".")[0] for m in mods} & set(HEAVY)) == []


def test_only_the_chosen_command_is_built(capsys: pytest.CaptureFixture[str]) -> None:
    """The chosen command has its options; the others are listed by name and help; an unknown one is refused."""
    from comems4build_ros.app.cli import build_parser, chosen_command

    assert chosen_command(["simulate", "--help"]) == ["simulate"]
    assert chosen_command(["--help", "simulate"]) == [] and chosen_command([]) == []
    assert chosen_command(["simulat"]) == []
    helps = dict(_helps(build_parser(chosen_command(["evaluate", "BAG"]))))
    assert "--no-timeseries" in helps["comems4build evaluate"]
    assert "--ems" not in helps["comems4build simulate"] and "simulate" in helps["comems4build"]
    with pytest.raises(SystemExit) as exc:
        main(["simulat", "--ems", "rbc"])
    assert exc.value.code == 2 and "invalid choice: 'simulat'" in capsys.readouterr().err
