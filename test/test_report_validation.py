"""The validation evaluated and written: the checks of every case, the shares per subset, the documents.

The module fixture runs ``comems4build validate`` for half a week on one calibration case and
two validation cases, with the fuzzy EMS and the RBC only (the MPC's checks are then
reported as not run); the tests read what it wrote.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.report import findings as fd
from comems4build_ros.report import validation as rv
from comems4build_ros.report import validation_doc as vd

CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main(sys.argv[1:]))"]
CASES = "paper-s57,hamburg-2017-18,household-102"


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("validate") / "v"
    assert main(["validate", "--out", str(out), "--weeks", "0.5", "--cases", CASES, "--ems", "fuzzy,rbc",
                 "--study", "rbc_h2_reserve,discomfort_sample", "--jobs", "2", "--no-progress"]) == 0
    return out


@pytest.mark.parametrize("weeks, per_12, allowed", [(12, 2, 2), (6, 2, 1), (1, 2, 0), (24, 2, 4), (12, 0, 0),
                                                     (3, 2, 0), (12, 3, 3)])
def test_weeks_with_discomfort_allowed_in_proportion(weeks, per_12, allowed):
    assert fd.allowed_discomfort_weeks(weeks, per_12) == allowed


def test_daily_spread_is_the_median_of_each_local_days_max_minus_min():
    time = pd.date_range("2022-12-01 00:00", periods=72, freq="h", tz="Europe/Berlin").tz_convert("UTC")
    price = [0.1] * 24 + [0.1, 0.5] * 12 + [0.2, 0.3] * 12
    ts = pd.DataFrame({"time": time, "price_buy_eur_per_kwh": price})
    assert rv.daily_spread_eur_per_kwh(ts, "Europe/Berlin") == pytest.approx(0.1)  # days: 0, 0.4, 0.1


def test_subset_shares_from_hand_made_cases():
    def case(comfort, order, loh):
        return {"criteria": {"comfort": comfort, "cost_order": order, "h2_left": True, "fc_longer_lower": None,
                             "rbc_sells_most": False, "net_cost_order": True},
                "findings": {"a": "held", "b": "n/a"}, "ratios": {"rbc/fuzzy": 1.5, "mpc/fuzzy": 0.5},
                "loh_end": {"fuzzy": loh}, "discomfort_weeks": {"fuzzy": 1}, "fc_hours": {"fuzzy": 10.0},
                "fc_load_w": {"fuzzy": 900.0}, "cost": {"fuzzy": 20.0}}

    s = rv.subset_summary([case(True, True, 0.1), case(True, False, 0.3), case(False, True, 0.2)], 0.9)
    assert s["criteria"]["comfort"] == {"held": 2, "cases": 3, "share": pytest.approx(2 / 3), "met": False}
    assert s["criteria"]["h2_left"]["met"] is True
    assert s["criteria"]["fc_longer_lower"] == {"held": 0, "cases": 0, "share": None, "met": None}
    assert s["criteria"]["net_cost_order"]["held"] == 3
    assert s["findings"] == {"a": {"held": 3, "cases": 3}, "b": {"held": 0, "cases": 0}}
    assert s["loh_end"]["fuzzy"] == {"median": 0.2, "low": 0.1, "high": 0.3, "n": 3}


def test_every_case_checked_and_the_missing_ems_reported_as_not_run(out):
    rep = json.loads((out / "validation.json").read_text(encoding="utf-8"))
    assert [c["id"] for c in rep["cases"]] == CASES.split(",")
    assert list(rep["subsets"]) == ["calibration", "development", "held-out"]
    for c in rep["cases"]:
        assert c["criteria"]["cost_order"] is None and c["criteria"]["fc_longer_lower"] is None
        assert c["criteria"]["net_cost_order"] is None
        assert c["criteria"]["comfort"] == (c["discomfort_weeks"]["fuzzy"] <= c["allowed_weeks"])
        assert c["criteria"]["rbc_sells_most"] is None  # "the most of all EMS": needs the MPC too
        lo, hi = rep["criteria"]["h2_left"]
        even = c["h2_even"]["fuzzy"] <= rep["criteria"]["h2_even_max"] and c["h2_even"]["fuzzy"] < c["h2_even"]["rbc"]
        assert c["criteria"]["h2_left"] == (lo <= c["loh_end"]["fuzzy"] <= hi and even)
        for key, findings in rv.CRITERIA_FINDINGS.items():  # each check is made of its findings
            status = [c["findings"][k] for k in findings]
            assert c["criteria"][key] == (None if "n/a" in status else all(v == "held" for v in status))
        assert c["findings"]["mpc_cheapest"] == "n/a" and c["weeks"] == 1  # half a week: one partial week row
        summary = json.loads((out / "runs" / f"{c['id']}__fuzzy" / "summary.json").read_text(encoding="utf-8"))
        assert c["cost"]["fuzzy"] == summary["cost_eur_week_median"]
    assert rep["calibration_fit"] is None  # no MPC, half a week: not the reproduction's figures


def test_readings_on_every_case(out):
    rep = json.loads((out / "validation.json").read_text(encoding="utf-8"))
    names = [(r["ambiguity"], r["reading"], r["default"]) for r in rep["study"]]
    assert ("rbc_h2_reserve", "none", False) in names and ("discomfort_sample", "end", True) in names
    assert (out / "runs" / "hamburg-2017-18__rbc_h2_reserve__none__rbc" / "summary.json").is_file()
    assert not (out / "runs" / "hamburg-2017-18__discomfort_sample__start__rbc").exists()  # evaluation only
    default = next(r for r in rep["study"] if r["reading"] == "end")
    assert default["subsets"]["held-out"]["criteria"] == rep["subsets"]["held-out"]["criteria"]


def test_documents_and_figure_written(out):
    md = (out / "validation.md").read_text(encoding="utf-8")
    for text in ("## The checks on every case", "## Every case", "hamburg-2017-18", "## Radiation of the cases",
                 "## Every reading: calibration and validation", "figures/validation_cases.png"):
        assert text in md
    assert (out / "validation.html").read_text(encoding="utf-8").count("<table") >= 5
    for name in ("validation_cases", "validation_prices"):
        for fmt in ("png", "pdf", "svg"):
            assert (out / "figures" / f"{name}.{fmt}").is_file()


def test_mpc_break_even_by_hand():
    """0.350 EUR/h (10908 EUR / 35000 h + 0.038 EUR/h, tab:degradation_HESS, per operating hour) at
    zeta * P_FC,max = 0.8 * 2441.6 W = 1.953 kW: 0.179 EUR/kWh."""
    from comems4build_ros.core.config import load_plant_params

    assert rv.mpc_fc_break_even_eur_per_kwh(load_plant_params()) == pytest.approx(
        (10908 / 35000 + 0.038) / (0.8 * 2.4416), rel=1e-9)


def test_update_doc_between_the_markers(out, tmp_path):
    rep = json.loads((out / "validation.json").read_text(encoding="utf-8"))
    doc = tmp_path / "validation.md"
    doc.write_text(f"# Validation\n\nprose\n\n{vd.DOC_BEGIN}\nold\n{vd.DOC_END}\n\nafter\n", encoding="utf-8")
    vd.update_doc(doc, rep, out)
    text = doc.read_text(encoding="utf-8")
    assert text.startswith("# Validation\n\nprose\n\n") and text.endswith(f"{vd.DOC_END}\n\nafter\n")
    assert "\nold\n" not in text and "### The checks on every case" in text
    assert (tmp_path / vd.DOC_FIGURES / "validation_cases.png").is_file()
    bad = tmp_path / "nomarkers.md"
    bad.write_text("nothing\n", encoding="utf-8")
    with pytest.raises(ValueError, match="markers"):
        vd.update_doc(bad, rep)


def test_from_runs_gives_the_same_figures(out, tmp_path):
    again = tmp_path / "again"
    assert main(["validate", "--out", str(again), "--weeks", "0.5", "--cases", CASES, "--ems", "fuzzy,rbc",
                 "--study", "rbc_h2_reserve,discomfort_sample", "--from-runs", str(out), "--no-figures"]) == 0
    a = json.loads((out / "validation.json").read_text(encoding="utf-8"))
    b = json.loads((again / "validation.json").read_text(encoding="utf-8"))
    assert a["cases"] == b["cases"] and a["subsets"] == b["subsets"] and b["runs_from"] == str(out)


def test_choose_and_judge_steps_read_only_their_own_cases(out, tmp_path):
    """The choosing step reads the calibration and development cases only and writes its choice with the
    runs it read; the judging step reads the held-out cases and records the defaults it judged."""
    from comems4build_ros.study.identity import defaults_identity

    common = ["--weeks", "0.5", "--ems", "fuzzy,rbc", "--study", "rbc_h2_reserve,discomfort_sample",
              "--from-runs", str(out), "--no-figures"]
    choose, judge = tmp_path / "choose", tmp_path / "judge"
    assert main(["validate", "--out", str(choose), "--choose", "--cases", "paper-s57,hamburg-2017-18", *common]) == 0
    rep = json.loads((choose / "validation.json").read_text(encoding="utf-8"))
    assert [c["id"] for c in rep["cases"]] == ["paper-s57", "hamburg-2017-18"] and "judged" not in rep
    choice = json.loads((choose / "choice.json").read_text(encoding="utf-8"))
    assert choice["cases"] == ["paper-s57", "hamburg-2017-18"]
    assert set(choice["ambiguities"]) == {"rbc_h2_reserve", "discomfort_sample"}
    for a in choice["ambiguities"].values():
        assert a["decided_by"] == "paper" and a["chosen"] == a["shipped"] and a["agrees"]
        for r in a["readings"]:
            assert r["runs"] and not any(n.startswith("household-102") for n in r["runs"])
    assert choice["defaults"]["runs"]["code_sha256"] == defaults_identity()["code_sha256"]
    assert main(["validate", "--out", str(judge), "--judge", "--choice", str(choose / "choice.json"),
                 "--cases", "household-102", *common]) == 0
    rep = json.loads((judge / "validation.json").read_text(encoding="utf-8"))
    assert [c["id"] for c in rep["cases"]] == ["household-102"] and "choice" not in rep
    assert not (judge / "choice.json").exists()
    judged = rep["judged"]
    assert judged["cases"] == ["household-102"]
    assert judged["defaults"]["parameters_sha256"] == defaults_identity()["parameters_sha256"]
    assert judged["choice"]["same_defaults"] is True and judged["choice"]["differ"] == {}
    assert "What the held-out cases judged" in (judge / "validation.md").read_text(encoding="utf-8")


def _reading(name, default, dev_met, cal_met, findings, table):
    crit = {k: {"held": 1, "cases": 1, "share": 1.0, "met": True} for k in rv.CRITERIA}

    def subset(met):
        return {"cases": 4, "criteria": {k: {**v, "met": i < met} for i, (k, v) in enumerate(crit.items())}}

    return {"ambiguity": "fc_rules", "reading": name, "default": default,
            "subsets": {"calibration": subset(cal_met), "development": subset(dev_met), "held-out": subset(0)},
            "calibration_fit": {"median_rel_error": 0.1, "table_rel_error": table, "findings_held": findings,
                                "findings_total": 33, "fc": {}}}


@pytest.mark.parametrize("rows, chosen", [
    ([("battery_supports", True, 4, 5, 30, 0.08), ("battery_first", False, 5, 4, 20, 0.20)], "battery_first"),
    ([("battery_supports", True, 4, 5, 30, 0.08), ("battery_first", False, 4, 5, 31, 0.20)], "battery_first"),
    ([("battery_supports", True, 4, 5, 30, 0.08), ("battery_first", False, 4, 5, 30, 0.09)], "battery_supports"),
    ([("battery_supports", True, 3, 5, 30, 0.08), ("start_at_average", False, 3, 4, 33, 0.01)], "battery_supports"),
])
def test_choice_rule_in_its_order_and_blind_to_held_out(rows, chosen):
    """Development checks first, then calibration checks, findings, the table's error; the held-out
    subset (here: no check met) never enters."""
    from comems4build_ros.study import validate as sv

    p = sv.plan(["fc_rules"], weeks=1, cases=["paper-s57", "hamburg-2015-16"], step="choose")
    report = {"study": [_reading(*r) for r in rows], "defaults": {"runs": None, "evaluated": None}}
    c = rv.choose_defaults(p, report, 0.9)["ambiguities"]["fc_rules"]
    assert c["decided_by"] == "figures" and c["chosen"] == chosen and c["agrees"] == (chosen == "battery_supports")


@pytest.mark.parametrize("args, message", [
    (["--cases", "atlantis"], "--cases: no case atlantis"),
    (["--ems", "thermostat"], "--ems: thermostat"),
    (["--study", "tariff_offset"], "change the plant or the scenario's data"),
    (["--weeks", "13"], "outside the allowed range"),
    (["--cases", "paper-s57,paper-s57"], "given twice"),
    (["--from-runs", "/nonexistent"], "no runs/ directory"),
    (["--choose", "--cases", "household-102"], "never while choosing"),
    (["--judge", "--cases", "paper-s57,muenchen-2015-16"], "not read by the judge step"),
    (["--choose", "--judge"], "not allowed with"),
    (["--choice", "choice.json"], "--judge"),
    (["--judge", "--update-doc", "validation.md"], "needs both steps"),
])
def test_bad_options_exit_2_naming_them(tmp_path, args, message):
    res = subprocess.run([*CLI, "validate", "--out", str(tmp_path / "o"), *args], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert res.returncode == 2 and message in res.stderr and "Traceback" not in res.stderr
