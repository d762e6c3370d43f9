"""``cosim-study`` end to end on a short window: folders, reports, the document's table and findings."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.study import identify as ident

pytest.importorskip("pyenergyplus")


@pytest.fixture(scope="module")
def study(params, tmp_path_factory) -> Path:
    """A day of the study with an identified file fitted to a known model (the house's own fit takes minutes)."""
    root = tmp_path_factory.mktemp("cosim")
    b = params.building.model_copy(update={"f_gains_air": 0.5})
    report = {"building": "energyplus", "train": {"start": ident.TRAIN_START, "weeks": 3.0},
              "excitation": {"q_excite_w": ident.Q_EXCITE_W}, "fit": {"fit_rmse_k": 0.1},
              "identified": {n: float(getattr(b, n)) for n in ident.REPORTED},
              "heat_loss_coefficient_w_per_k": ident.heat_loss_coefficient(b),
              "validation": {"start": ident.VALID_START, "rmse_k": 0.1, "max_abs_k": 0.3, "predictions": 121},
              "evaluation_weeks_thermostat": {"rmse_k": 0.2, "max_abs_k": 1.0, "predictions": 10}}
    ident.write_parameter_file(root / "identified.yaml", b, report)
    ident.write_report(root / "identified.json", report)
    out = root / "study"
    assert main(["cosim-study", "--out", str(out), "--identified", str(root / "identified.yaml"), "--weeks", "0.25",
                 "--jobs", "2", "--no-progress", "--doc", str(root / "cosimulation.md")]) == 0
    return out


def test_study_writes_a_compare_folder_per_building(study):
    for building in ("rc", "energyplus"):
        for ems in ("rbc", "fuzzy", "mpc", "thermostat"):
            assert (study / building / "runs" / ems / "summary.json").is_file()
        assert (study / building / "report.md").is_file()
        assert list((study / building / "figures").glob("*.png"))
    ep = json.loads((study / "energyplus" / "runs" / "mpc" / "summary.json").read_text())
    assert ep["building"] == "energyplus" and ep["building_heat_balance_max_rel"] <= 1e-6
    rc = json.loads((study / "rc" / "runs" / "mpc" / "summary.json").read_text())
    assert "building" not in rc


def test_document_sets_the_paper_beside_both_buildings(study):
    doc = (study / "cosimulation.md").read_text()
    assert doc == (study.parent / "cosimulation.md").read_text()
    assert "| electricity cost, weekly median | EUR/week | MPC | 12.96 |" in doc
    assert "**comfort: ComEMS4Build without discomfort in 10 of 12 weeks**" in doc
    for heading in ("## The house", "## The MPC's model, identified", "## The paper's findings on both buildings",
                    "## What changes on the detailed house, and why"):
        assert heading in doc
    assert "../shared" not in doc
