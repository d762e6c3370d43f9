"""Reproducing the paper: the 12-week default runs on every seed against the paper's statements and findings.

The module fixture makes the default 12-week runs of the three EMS on the study's five seeds
once (in two processes, through the same code as ``comems4build reproduce --no-study``); the
tests read its ``reproduce.json``.
"""

from __future__ import annotations

import html as html_lib
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from comems4build_ros.app.commands.reproduce import reproduce
from comems4build_ros.core.config import ConfigError, load_plant_params
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario import default_scenario
from comems4build_ros.report import findings as fd
from comems4build_ros.report import reproduce as rp
from comems4build_ros.report.figures import CAPTIONS, FIGURES
from comems4build_ros.report.reproduce_doc import unexplained
from comems4build_ros.report.runs import read_run
from comems4build_ros.study import reproduce as sr

ROOT = Path(__file__).resolve().parents[1]
#: The command line as the installed ``comems4build`` runs it (main() maps errors to exit 2).
CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main(sys.argv[1:]))"]
CALIBRATION_DOC = ROOT / "docs" / "calibration.md"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    res = reproduce(out, with_study=False, jobs=2)
    return out, json.loads(res.json.read_text(encoding="utf-8"))


def test_five_seeds_the_default_first(base):
    report = base[1]
    study = sr.load_study()
    assert report["seeds"] == list(study.seeds) and len(report["seeds"]) >= 5
    assert sr.check_defaults(study) == []  # the first seed is the default scenario's


#: Findings this reproduction does not reproduce, each explained with measured figures in
#: docs/calibration.md ("Findings that do not hold"). Strict: a finding that starts to hold
#: fails the test, so that the list and the document are updated.
NOT_REPRODUCED = {
    "no_dhw_cover_at_75": ("the MPC spends the H2 it saved in the cheap weeks 4-7 in week 8, where its FC heat "
                           "covers the DHW demand at 75 % and its heat pump makes no hot water"),
    "dhw_demand_met": "three morning draws of 209-269 l/h exceed what the RBC's tank holds at that hour",
}


@pytest.mark.parametrize("key", [
    pytest.param(f.key, marks=pytest.mark.xfail(strict=True, reason=NOT_REPRODUCED[f.key]))
    if f.key in NOT_REPRODUCED else f.key for f in fd.FINDINGS])
def test_every_finding_holds_on_at_least_four_of_five_seeds(base, key):
    report = base[1]
    need = report["targets"]["findings_seeds"]
    finding = next(f for f in report["base"]["findings"] if f["key"] == key)
    assert finding["held"] >= need, f"{finding['claim']}: held on {finding['held']} seeds; {finding['evidence']}"


def test_findings_not_reproduced_are_explained():
    """Each finding listed in NOT_REPRODUCED has its explanation in docs/calibration.md."""
    text = CALIBRATION_DOC.read_text(encoding="utf-8")
    section = text.split("## Findings that do not hold", 1)[1].split("\n## ", 1)[0]
    assert {f.key for f in fd.FINDINGS} >= set(NOT_REPRODUCED)
    for key in NOT_REPRODUCED:
        assert f"`{key}`" in section, key


def test_fuel_cell_operation_as_the_paper_runs_it(base):
    """ComEMS4Build: -10..+25 % toggles vs MPC (paper +6.09 %); the RBC runs fewer FC hours than
    the MPC (paper -7.59 %). Medians over the seeds."""
    fc = base[1]["base"]["fc"]
    assert -10.0 <= fc["fuzzy_toggles"]["median"] <= 25.0
    assert fc["rbc_hours"]["median"] < 0.0


@pytest.mark.xfail(strict=True, reason="the robust defaults run ComEMS4Build's FC +83 % of the MPC's hours, over the "
                                       "band (docs/calibration.md 'Calibration against robustness')")
def test_fuel_cell_hours_within_the_band(base):
    """ComEMS4Build: +20..+80 % working hours vs MPC (paper +48.44 %), median over the seeds."""
    assert 20.0 <= base[1]["base"]["fc"]["fuzzy_hours"]["median"] <= 80.0


def test_cost_ratios_within_twenty_percent_of_the_papers(base):
    report = base[1]
    assert report["paper_ratios"]["rbc/fuzzy"] == pytest.approx(43.10 / 25.02)
    for key, value in report["base"]["ratios"].items():
        p = report["paper_ratios"][key]
        v = value["median"]
        assert p * 0.8 <= v <= p * 1.2, f"{key}: {v:.2f} outside {0.8 * p:.2f}..{1.2 * p:.2f}"


def test_at_least_35_stated_figures_with_a_seed_median_error(base):
    figures = base[1]["base"]["figures"]
    errs = [f["rel_error"] for f in figures if f["rel_error"] is not None]
    assert len(errs) >= 35
    assert base[1]["base"]["median_rel_error"] == pytest.approx(float(np.median(errs)))


def test_every_figure_off_by_more_than_40_percent_is_explained(base):
    """docs/calibration.md names each such figure (``<ems>/<statement>``) in its explanation section."""
    assert unexplained(base[1], CALIBRATION_DOC.read_text(encoding="utf-8")) == []


def test_figures_as_before_the_year_round_plant(base):
    """The reproduction gives the figures main's code gave without the electrolyser, cooling and the year
    scenario: the stated figures, findings and ratios on every seed, the H2 figures and the paper's windows
    of ``reproduce --no-study`` (test/fixtures/winter_reference/README.md says how they were made)."""
    ref = json.loads((ROOT / "test" / "fixtures" / "winter_reference" / "reproduce_base.json").read_text(
        encoding="utf-8"))
    for key in ("scenario", "weeks", "seeds", "base", "h2", "windows"):
        assert base[1][key] == ref[key], key


def test_h2_figures_reported(base):
    rows = {r["ems"]: r for r in base[1]["h2"]}
    for e in sr.EMS:
        r = rows[e]
        assert 0 <= r["fc_kwh_week_min"] <= r["fc_kwh_week_max"] <= r["h2_kwh_week_max"]
        assert r["h2_left_value_eur"] == pytest.approx(r["loh_end_pct"] / 100 * 1800 * r["price_buy_mean_eur_per_kwh"])
    # the default tariff's mean over the twelve weeks is the paper's 0.384 EUR/kWh
    assert rows["fuzzy"]["price_buy_mean_eur_per_kwh"] == pytest.approx(0.384, abs=0.001)


def test_documents_and_the_papers_figures_written(base):
    out, report = base
    md = (out / "reproduce.md").read_text(encoding="utf-8")
    html = html_lib.unescape((out / "reproduce.html").read_text(encoding="utf-8"))
    for text in (md, html):
        assert "Every stated figure of the paper beside ours" in text and "The paper's findings" in text
    assert f"{100 * report['base']['median_rel_error']:.1f} %" in md
    assert set(report["figures"]) == set(FIGURES)
    for key, rel in report["figures"].items():
        png = out / rel
        for suffix in (".png", ".pdf", ".svg"):
            assert png.with_suffix(suffix).is_file(), png.with_suffix(suffix)
        assert CAPTIONS[key].split(".")[0] in md  # captioned with the paper's label
    # the paper's windows: fig:performance_comparison from 2022-12-03, the high-PV window two months on
    assert report["windows"]["performance_comparison"][0].startswith("2022-12-03T00:00")
    assert report["windows"]["high_pv"][0] >= "2023-01-31"


@pytest.mark.parametrize("ems", ["fuzzy", "rbc", "mpc"])
def test_two_week_run_is_the_start_of_the_twelve_week_run(base, ems):
    """The H2 allowance follows the season (eq:deltaLOH over 12 weeks), not --weeks."""
    params = load_plant_params()
    short = simulate(ems, default_scenario(params, weeks=2), params).timeseries
    full = pd.read_csv(base[0] / "runs" / f"base_{ems}_s{base[1]['seeds'][0]}" / "timeseries.csv")
    full = full.iloc[: len(short)]
    cols = [c for c in short.columns if c != "time" and not c.endswith("_s")]  # timings differ
    np.testing.assert_array_equal(short[cols].to_numpy(dtype=float), full[cols].to_numpy(dtype=float))


def test_study_file_defaults_match_config():
    study = sr.load_study()
    assert sr.check_defaults(study) == []
    keys = {a.key for a in study.ambiguities}
    assert {"fc_lifecycle_cost", "h2_carry_over", "fc_cap_to_demand", "hp_zero", "battery_grid_charging",
            "rbc_thresholds", "discomfort_sample", "building_envelope", "appliance_load",
            "heat_recovery_eta"} <= keys


def _study_file(tmp_path: Path, edit) -> Path:
    data = yaml.safe_load((ROOT / "config" / "reproduce.yaml").read_text(encoding="utf-8"))
    edit(data["/**"]["ros__parameters"]["reproduce"])
    path = tmp_path / "reproduce.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_a_drifted_default_is_refused(tmp_path):
    def drift(s):
        a = next(a for a in s["ambiguities"] if a["key"] == "tariff_offset")
        a["default"] = "a110"

    study = sr.load_study(_study_file(tmp_path, drift))
    problems = sr.check_defaults(study)
    assert problems and "grid.buy_offset_eur_per_kwh" in problems[0]
    def swap(s):  # the default scenario's seed second; as many seeds as findings_seeds asks for
        s["seeds"] = [1, 57, *(n for n in s["seeds"] if n not in (1, 57))]

    other_first = sr.load_study(_study_file(tmp_path, swap))
    assert any(p.startswith("seeds: the first seed 1") for p in sr.check_defaults(other_first))


@pytest.mark.parametrize("edit, message", [
    (lambda s: s["ambiguities"][0].update(default="nope"), "default 'nope' is not one of its readings"),
    (lambda s: s["ambiguities"][0].update(ems=["thermostat"]), "'ems' must list some of"),
    (lambda s: s["ambiguities"][0].update(readings=s["ambiguities"][0]["readings"][:1]), "at least two readings"),
    (lambda s: s["ambiguities"][0]["readings"][0].update(colour="red"), "unknown entries colour"),
    (lambda s: s["ambiguities"][0]["readings"][0].update(heat="later"), "'heat' must be one of"),
    (lambda s: s.pop("weeks"), "missing 'weeks'"),
    (lambda s: s.update(seeds=[1, 1]), "'seeds' must list distinct integers"),
    (lambda s: s["targets"].update(fuzzy_fc_hours_pct=[80, 20]), "'fuzzy_fc_hours_pct' must be [low, high]"),
    (lambda s: s["targets"].update(findings_seeds=9), "'findings_seeds' must lie in 1..5"),
])
def test_bad_study_files_are_named(tmp_path, edit, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        sr.load_study(_study_file(tmp_path, edit))


def test_plan_reuses_base_runs_and_makes_no_run_for_kpi_only_readings():
    study = sr.load_study()
    tasks, cases = sr.plan(study)
    seeds = study.seeds
    assert {f"base_{e}_s{s}" for e in sr.EMS for s in seeds} <= set(tasks)
    kpi = next(a for a in study.ambiguities if a.kpi_only)
    assert not any(name.startswith(kpi.key) for name in tasks)
    for case in cases:
        if case.ambiguity == "h2_carry_over" and case.reading != next(
                a.default for a in study.ambiguities if a.key == "h2_carry_over"):
            assert case.runs[seeds[0]]["mpc"] == f"base_mpc_s{seeds[0]}"
            assert case.runs[seeds[0]]["fuzzy"] == f"h2_carry_over__{case.reading}__fuzzy_s{seeds[0]}"
    heat = next(a for a in study.ambiguities if any(r.heat for r in a.readings))
    rerun = len(sr.EMS) * len(seeds) if heat.default != "rerun" else 0
    expected = len(sr.EMS) * len(seeds) + rerun + len(seeds) * sum(
        len(a.ems) * (len(a.readings) - 1) for a in study.ambiguities if not a.kpi_only and a is not heat)
    assert len(tasks) == expected


def test_cli_study_on_one_week(tmp_path):
    """The command end to end on a short run and one seed: an evaluation-only ambiguity and one with runs."""
    out = tmp_path / "rep"
    proc = subprocess.run(
        [*CLI, "reproduce", "--out", str(out), "--weeks", "1", "--seeds", "57", "--no-figures",
         "--only", "discomfort_sample,h2_carry_over"],
        capture_output=True, text=True, timeout=900,
    )
    assert proc.returncode == 0, proc.stderr
    assert "findings held" in proc.stdout and "ComEMS4Build's FC vs MPC" in proc.stdout
    report = json.loads((out / "reproduce.json").read_text(encoding="utf-8"))
    assert report["runs_made"] == 4  # 3 base runs + the fuzzy run of the other h2_carry_over reading
    cases = {(r["ambiguity"], r["reading"]) for r in report["study"]}
    readings = {a.key: [r.name for r in a.readings] for a in sr.load_study().ambiguities}
    assert cases == {("discomfort_sample", n) for n in readings["discomfort_sample"]} | {
        ("h2_carry_over", n) for n in readings["h2_carry_over"]}
    start = next(r for r in report["study"] if r["reading"] == "start")
    end = next(r for r in report["study"] if r["reading"] == "end")
    assert start["values"] == end["values"]  # same runs, only the discomfort changes
    md = (out / "reproduce.md").read_text(encoding="utf-8")
    assert "Interpretation study" in md and "(default)" in md
    # an evaluation-only reading keeps what the controller reported (the RBC's own H2 limit)
    rbc = read_run(out / "runs" / "base_rbc_s57")
    rbc.summary["rbc_loh_floor"] = 0.1
    again = rp.reevaluate(rbc, load_plant_params(overrides={"comfort.discomfort_sample": "start"}))
    assert again.summary["rbc_loh_floor"] == 0.1
    # the same study evaluated again from its run directories, without simulating
    out2 = tmp_path / "again"
    proc = subprocess.run([*CLI, "reproduce", "--from-runs", str(out), "--out", str(out2), "--seeds", "57",
                           "--no-figures", "--only", "discomfort_sample,h2_carry_over"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "evaluated again" in proc.stdout and not (out2 / "runs").exists()
    report2 = json.loads((out2 / "reproduce.json").read_text(encoding="utf-8"))
    assert report2["study"] == report["study"] and report2["base"] == report["base"]
    assert report2["runs_made"] == 4 and report2["runs_from"] == str(out)
    # a study that needs a run the directory does not hold is refused, naming it
    proc = subprocess.run([*CLI, "reproduce", "--from-runs", str(out), "--out", str(tmp_path / "r3"),
                           "--seeds", "57", "--only", "hp_zero"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "hp_zero__level__fuzzy_s57" in proc.stderr


@pytest.mark.parametrize("args, message", [
    (["--weeks", "13"], "--weeks"),
    (["--jobs", "0"], "--jobs"),
    (["--only", "nope"], "no ambiguity nope"),
    (["--seeds", "1,x"], "--seeds"),
    (["--seeds", "1,1"], "--seeds"),
])
def test_cli_bad_options_exit_2(tmp_path, args, message):
    proc = subprocess.run([*CLI, "reproduce", "--out", str(tmp_path / "r"), *args],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and message in proc.stderr


def test_usage_error_exits_2_when_run_as_a_module(tmp_path):
    """``python -m comems4build_ros.app.cli``: a usage error raised by a command is an exit 2 with its message."""
    proc = subprocess.run([sys.executable, "-m", "comems4build_ros.app.cli", "reproduce", "--out", str(tmp_path / "r"),
                           "--from-json", "a.json", "--from-runs", "b"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "exclude each other" in proc.stderr and "Traceback" not in proc.stderr
