"""``comems4build compare --community``: the coordinators side by side, its report and its refusals."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.core.community.coordinator import coordinator_names
from comems4build_ros.report import community as rc
from comems4build_ros.report.style import layout_problems

TWO = """community:
  name: two
  houses:
    - {name: a, reason: "the paper's house"}
    - {name: b, reason: "a 2-person neighbour with an east roof", load_scale: 0.71, load_seed: 5, dhw_scale: 0.5,
       pv_azimuth_deg: 90}
"""


def _file(tmp_path: Path, text: str = TWO) -> Path:
    path = tmp_path / "two.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_compare_community_runs_every_coordinator_and_writes_the_report(tmp_path: Path, capsys) -> None:
    out = tmp_path / "c"
    assert main(["compare", "--community", str(_file(tmp_path)), "--scenario", "year", "--start", "2022-05-02",
                 "--weeks", "0.25", "--ems", "rbc", "--no-progress", "--out", str(out)]) == 0
    manifest = json.loads((out / rc.MANIFEST).read_text(encoding="utf-8"))
    assert manifest["coordinators"] == list(coordinator_names()) and manifest["ems"] == "rbc"
    summary = json.loads((out / "runs" / "rule" / "community.json").read_text(encoding="utf-8"))
    assert summary["houses"] == 2 and summary["steps"] == 42 and summary["h2_produced_kwh"] > 0.0
    assert (out / "runs" / "rule" / "houses" / "b" / "timeseries.csv").is_file()
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "Energy sharing, EnWG § 42c" in text and "Rule-based" in text and "peak import" in text
    assert {p.stem for p in (out / "figures").glob("*.png")} == {"hub_loh", "household_cost", "house_costs",
                                                                 "connection_exchange"}
    manifest_bytes = (out / rc.MANIFEST).read_bytes()
    assert main(["compare", "--from-runs", str(out)]) == 0  # the report again from the runs, nothing run
    assert (out / rc.MANIFEST).read_bytes() == manifest_bytes
    assert "report: built in" in capsys.readouterr().out
    _, runs = rc.read_community_comparison(out)
    rules = runs["rule"].summary["rule_sets"]
    for fig in (rc.hub_loh_figure(runs, "Europe/Berlin"), rc.household_cost_figure(runs, rules),
                rc.house_costs_figure(runs, rules), rc.connection_exchange_figure(runs)):
        fig.canvas.draw()
        assert layout_problems(fig) == []
        plt.close(fig)


@pytest.mark.parametrize("argv, message", [
    (["--coordinator", "nosuch"], "unknown coordinator 'nosuch'"),
    (["--coordinator", "rule,rule"], "'rule' given twice"),
    (["--coordinator-option", "rule.h2_splt=need"], "h2_splt"),
    (["--coordinator-option", "h2_split=need"], "NAME.KEY=VALUE"),
    (["--coordinator", "rule", "--coordinator-option", "central.x=1"],
     "'central' is not among the compared coordinators"),
    (["--coordinator-option", "distributed.rho_eur_per_kw2=0"], "rho_eur_per_kw2"),
    (["--ems", "rbc,fuzzy"], "the one EMS of every house"),
    (["--via", "ros"], "runs in-process"),
    (["--fc-efficiency", "0.9"], "--fc-efficiency"),
    (["--building", "energyplus"], "4R3C"),
    (["--set", "battery.e_max_kwh=-1"], "battery.e_max_kwh"),
])
def test_bad_community_options_exit_2_naming_the_option(tmp_path: Path, capsys, argv, message) -> None:
    out = tmp_path / "c"
    assert main(["compare", "--community", str(_file(tmp_path)), "--weeks", "0.25", *argv, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "runs").exists()


def test_a_bad_community_file_exits_2_naming_file_and_field(tmp_path: Path, capsys) -> None:
    path = _file(tmp_path, TWO.replace("load_scale: 0.71", "load_scale: -1"))
    assert main(["compare", "--community", str(path), "--weeks", "0.25", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "two.yaml" in err and "houses.1.load_scale" in err


def test_coordinator_options_need_a_community(tmp_path: Path, capsys) -> None:
    assert main(["compare", "--coordinator", "rule", "--weeks", "1", "--out", str(tmp_path / "c")]) == 2
    assert "apply with --community" in capsys.readouterr().err
