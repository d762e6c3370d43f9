"""``comems4build size``: a 3 x 3 grid of PV and H2-store sizes for the RBC and ComEMS4Build over an
8-week window of the year scenario that holds the start of the heating season (2022-10-27 ..
2022-12-22: the full year's 18 runs take about half a minute on two loaded cores, the window a
few seconds; docs/sizing.md gives the full year's table), its table, Pareto front, figure and
report checked against the runs' own summaries; the cost arithmetic; bad options refused with
exit 2 before anything runs.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import pytest
from test_bad_input import param_file, run_cli

from comems4build_ros.core.economics import crf, cycle_closes, load_costs
from comems4build_ros.report.sizing import pareto_figure, pareto_mask
from comems4build_ros.report.style import layout_problems

WINDOW = ["--start", "2022-10-27", "--weeks", "8"]
GRID = ["--pv-kwp", "4,7,9.6", "--h2-kwh", "600,1200,1800"]


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The study's output directory and its standard output."""
    import subprocess
    import sys

    out = tmp_path_factory.mktemp("size") / "study"
    proc = subprocess.run([sys.executable, "-m", "comems4build_ros.app.cli", "size", "--ems", "rbc,fuzzy", *GRID,
                           *WINDOW, "--jobs", "2", "--no-progress", "--out", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout


def test_size_writes_table_figure_report_and_names_the_closing_sizes(study: tuple[Path, str]) -> None:
    out, stdout = study
    for name in ("size.csv", "size.md", "size.json", "report.md", "report.html", "figures/pareto.png",
                 "figures/pareto.pdf", "figures/pareto.svg"):
        assert (out / name).is_file(), name
    df = pd.read_csv(out / "size.csv")
    assert len(df) == 18 and sorted(set(df["ems"])) == ["fuzzy", "rbc"]
    assert sorted(set(df["pv_kwp"])) == [3.842, 7.043, 9.604]  # whole modules of 0.320 kWp
    assert sorted(set(df["h2_kwh"])) == [600.0, 1200.0, 1800.0]
    costs = load_costs()
    for r in df.itertuples():
        summary = json.loads((out / r.run / "summary.json").read_text(encoding="utf-8"))
        assert summary["weeks"] == 8 and summary["ems"] == r.ems
        assert summary["loh_init"] == pytest.approx(0.10)
        # the seasonal cycle, as defined, from the run's own summary
        filled = summary["loh_heating_season_start"] > summary["loh_init"] + 1e-6
        closes = (filled and summary["loh_end"] >= summary["loh_init"] - 1e-6 and summary["h2_empty_at"] is None
                  and summary["heating_season_discomfort_weeks"] == 0)
        assert summary["heating_season_weeks"] == 3
        assert bool(r.closes) == closes, r.run
        # annual figures: the 8 weeks scaled to 52
        assert r.energy_eur_a == pytest.approx(summary["cost_net_eur"] * 52 / 8)
        assert r.fc_hours_a == pytest.approx(summary["fc_working_hours"] * 52 / 8)
        assert r.total_eur_a == pytest.approx(r.energy_eur_a + r.annuity_eur_a + r.om_eur_a)
        assert r.self_sufficiency == pytest.approx(summary["self_sufficiency"])
        invest = (r.pv_kwp * 1250.0 + r.battery_kwh * 138.46 + r.el_modules * 12000.0 + r.fc_kw * 5454.0
                  + r.h2_kwh * 18.0)
        assert r.invest_eur == pytest.approx(invest)
        cycles = summary["bess_charged_kwh_total"] / (r.battery_kwh * 0.8) * 52 / 8
        assert r.life_battery_a == pytest.approx(min(15.0, 6000.0 / cycles))
        fc_life = min(20.0, 35000.0 / r.fc_hours_a) if r.fc_hours_a > 0 else 20.0
        el_life = min(20.0, 35000.0 / r.el_hours_a) if r.el_hours_a > 0 else 20.0
        annuity = (r.pv_kwp * 1250.0 * crf(0.03, 25) + r.battery_kwh * 138.46 * crf(0.03, r.life_battery_a)
                   + r.el_modules * 12000.0 * crf(0.03, el_life) + r.fc_kw * 5454.0 * crf(0.03, fc_life)
                   + r.h2_kwh * 18.0 * crf(0.03, 25))
        assert r.annuity_eur_a == pytest.approx(annuity)
        assert costs.interest_rate == 0.03
    # the Pareto front per EMS: no point of the front is dominated, every other point is
    for ems, sub in df.groupby("ems"):
        pts = list(zip(sub["total_eur_a"], sub["self_sufficiency"]))
        for (c, g), front in zip(pts, sub["pareto"]):
            dominated = any(c2 <= c and g2 >= g and (c2 < c or g2 > g) for c2, g2 in pts)
            assert bool(front) == (not dominated), ems
        assert sub["pareto"].any()
    # what the command says: per EMS the closing points, by name
    for ems, sub in df.groupby("ems"):
        names = sorted(Path(r).name for r in sub.loc[sub["closes"], "run"])
        line = next(x for x in stdout.splitlines() if x.startswith(f"{ems}: "))
        assert f"{len(names)} of 9 size points close the seasonal cycle" in line
        assert all(n in line for n in names)
    report = (out / "report.md").read_text(encoding="utf-8")
    assert "## Smallest sizes that close the cycle" in report and "## Pareto front" in report
    assert "figures/pareto.png" in report
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "data:image/png;base64," in html
    assert layout_problems(pareto_figure(df)) == []


def test_a_size_point_runs_the_same_year_as_simulate(study: tuple[Path, str], tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The point of the year plant's own sizes (9.6 kWp, 1800 kWh) is the plain year run."""
    out, _ = study
    code, _, err = run_cli(["simulate", "--ems", "fuzzy", "--scenario", "year", *WINDOW, "--no-progress",
                            "--out", tmp_path / "sim"], capsys)
    assert code == 0, err
    plain = json.loads((tmp_path / "sim" / "summary.json").read_text(encoding="utf-8"))
    sized = json.loads((out / "runs" / "fuzzy__pv9.604_bat6.5_el1_fc2_h21800" / "summary.json").read_text())
    for key in ("cost_net_eur", "loh_end", "self_sufficiency", "fc_working_hours", "h2_produced_kwh"):
        assert sized[key] == plain[key], key


def test_cost_arithmetic() -> None:
    assert crf(0.0, 20) == pytest.approx(0.05)
    assert crf(0.03, 20) == pytest.approx(0.03 * 1.03**20 / (1.03**20 - 1))
    assert math.isclose(crf(0.03, 1), 1.03)
    assert pareto_mask([1, 2, 3, 2], [0.1, 0.5, 0.4, 0.5]) == [True, True, False, True]
    base = {"heating_season_weeks": 12, "loh_init": 0.1, "loh_heating_season_start": 0.8, "loh_end": 0.12,
            "h2_empty_at": None, "heating_season_discomfort_weeks": 0}
    assert cycle_closes(base) == (True, "closes")
    assert cycle_closes({**base, "loh_end": 0.05})[0] is False
    assert cycle_closes({**base, "loh_heating_season_start": 0.1})[0] is False  # never filled: no seasonal cycle
    assert cycle_closes({**base, "h2_empty_at": "2023-02-01T00:00:00+01:00"})[0] is False
    assert cycle_closes({**base, "heating_season_discomfort_weeks": 2})[0] is False
    assert cycle_closes({**base, "heating_season_weeks": 0})[0] is None
    assert cycle_closes({**base, "loh_heating_season_start": None})[0] is True  # a run starting inside the season


@pytest.mark.parametrize(("argv", "named"), [
    (["--pv-kwp", "5,x"], "--pv-kwp '5,x': 'x' is not a number"),
    (["--pv-kwp", "0.1"], "--pv-kwp 0.1: less than half a module"),
    (["--h2-kwh", "0"], "--h2-kwh '0': '0' must be > 0"),
    (["--battery-kwh", "5,5"], "--battery-kwh '5,5': 5 is given twice"),
    (["--el-modules", "1.5"], "--el-modules '1.5': '1.5' is not an integer >= 0"),
    (["--fc-kw", "nan"], "--fc-kw 'nan': 'nan' is not a finite number"),
    (["--sample", "4"], "--sample needs at least one size option with two different values"),
    (["--sample", "0", "--pv-kwp", "4,8"], "argument --sample: 0 is outside the allowed range"),
    (["--set", "pv.n_modules=3"], "--set pv.n_modules: a sized parameter"),
    (["--costs", "/nonexistent/costs.yaml"], "--costs /nonexistent/costs.yaml: no such file"),
    (["--ems", "nope"], "--ems nope"),
    (["--weeks", "-1"], "argument --weeks"),
    (["--start", "2022-03-27T02:30"], "--start"),
    (["--weeks", "60"], "--start/--weeks: scenario 'year': the run (60 week(s))"),
    (["--jobs", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--jobs and --scheduler exclude each other"),
])
def test_bad_options_are_refused_before_any_run(argv: list[str], named: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    window = [] if "--weeks" in argv else WINDOW
    base = ["size", *window] if "--ems" in argv else ["size", "--ems", "rbc", *window]
    code, _, err = run_cli([*base, *argv, "--out", out], capsys)
    assert code == 2, err
    assert named in err, err
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(("text", "named"), [
    ("costs:\n  pv:\n    invest_eur_per_kwp: -5", "costs.pv.invest_eur_per_kwp = -5 must be >= 0"),
    ("costs:\n  pv:\n    colour: 1", "unknown key costs.pv.colour"),
    ("costs:\n  interest_rate: 1.5", "costs.interest_rate 1.5 must be below 1"),
    ("costs:\n  fuel_cell:\n    life_h: 0", "costs.fuel_cell.life_h = 0 must be > 0"),
    ("costs:\n  battery:\n    n_cycles: lots", "costs.battery.n_cycles = 'lots' is not a finite number"),
])
def test_bad_cost_files_are_named(text: str, named: str, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = param_file(tmp_path / "costs.yaml", text)
    out = tmp_path / "out"
    code, _, err = run_cli(["size", "--ems", "rbc", *WINDOW, "--costs", path, "--out", out], capsys)
    assert code == 2, err
    assert str(path) in err and named in err, err
    assert not out.exists()
