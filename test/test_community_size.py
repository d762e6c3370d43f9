"""``comems4build size --community``: isolated houses against one shared H2 hub, per household and rule set.

A community of two houses over half a week of May of the year scenario (the electrolysers
run), two hub stores with two modules and the isolated houses at their shares: the tables,
figure and report are written and rebuilt from the runs; every figure of the tables is
checked against the runs' own summaries (the per-household split adds up to the community's
total, the isolated houses' energy is their own meter's); the hub's cost split and the
hub's seasonal cycle as property tests; bad inputs refused with exit 2 before any run.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_bad_input import param_file, run_cli

from comems4build_ros.core.community.sharing import load_sharing_rules
from comems4build_ros.core.community.spec import load_community, resized
from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.economics import WEEKS_PER_YEAR, annual_costs, crf, load_costs
from comems4build_ros.report import community_sizing as rcs
from comems4build_ros.report.style import layout_problems
from comems4build_ros.study.community_sizing import (
    HubSize,
    community_cycle,
    household_costs,
    hub_annual_costs,
    shares_kwh,
)

TWO = """community:
  name: two
  houses:
    - {name: a, reason: "the paper's house"}
    - {name: b, reason: "a 2-person neighbour with an east roof", load_scale: 0.71, load_seed: 5, dhw_scale: 0.5,
       pv_azimuth_deg: 90, pv_n_modules: 20, h2_weight: 0.5}
"""
WINDOW = ["--start", "2022-05-02", "--weeks", "0.5"]
RULES = ("none", "enwg_42c", "one_connection", "at_local")


def _file(folder: Path, text: str = TWO) -> Path:
    path = folder / "two.yaml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The study's output directory and its standard output."""
    import subprocess
    import sys

    folder = tmp_path_factory.mktemp("size_community")
    out = folder / "study"
    proc = subprocess.run([sys.executable, "-m", "comems4build_ros.app.cli", "size", "--community",
                           str(_file(folder)), "--ems", "rbc", *WINDOW, "--hub-kwh", "1800,3600", "--hub-modules", "2",
                           "--jobs", "2", "--no-progress", "--out", str(out)],
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout


def test_size_community_writes_its_tables_figure_and_report(study: tuple[Path, str]) -> None:
    out, stdout = study
    for name in ("households.csv", "points.csv", rcs.MANIFEST, "report.md", "report.html",
                 "figures/household_cost.png", "figures/household_cost.pdf", "figures/household_cost.svg"):
        assert (out / name).is_file(), name
    households = pd.read_csv(out / "households.csv")
    points = pd.read_csv(out / "points.csv")
    # 2 hub sizes and 2 isolated store sizes, 4 rule sets, 2 households
    assert len(households) == 2 * 2 * 4 * 2 and len(points) == 2 * 2 * 4
    assert set(households["rule"]) == set(RULES) and set(households["arm"]) == {"hub", "isolated"}
    # the isolated houses' stores are their nominal shares of each hub store (weights 1 and 0.5)
    iso = households[(households["arm"] == "isolated") & (households["rule"] == "none")]
    assert sorted(zip(iso["hub_kwh"], iso["house"], iso["h2_kwh"])) == [
        (1800.0, "a", 1200.0), (1800.0, "b", 600.0), (3600.0, "a", 2400.0), (3600.0, "b", 1200.0)]
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "Energy sharing, EnWG § 42c" in text and "nominal share" in text and "The answer" in text
    for label in ("No sharing", "Energy sharing, EnWG § 42c", "One connection point (what-if)"):
        assert any(line.startswith(label) for line in stdout.splitlines()), label
    assert "not tested" in stdout  # half a week of May holds no heating-season week


def test_the_household_split_adds_up_to_the_community(study: tuple[Path, str]) -> None:
    out, _ = study
    households = pd.read_csv(out / "households.csv")
    meta = json.loads((out / rcs.MANIFEST).read_text(encoding="utf-8"))
    costs = load_costs()
    scale = WEEKS_PER_YEAR / 0.5
    for hub in meta["hub_sizes"]:
        run = out / "runs" / hub["run"]
        summary = json.loads((run / "community.json").read_text(encoding="utf-8"))
        # the hub's annuity and O&M computed here from the cost figures, independently of the study
        el_inv = hub["modules"] * costs["electrolyser"]["invest_eur_per_module"]
        store_inv = hub["store_kwh"] * costs["hydrogen"]["invest_eur_per_kwh"]
        el_h = summary["el_module_hours"] / hub["modules"] * scale
        el_life = min(costs["electrolyser"]["life_a"], costs["electrolyser"]["life_h"] / el_h) if el_h else \
            costs["electrolyser"]["life_a"]
        capital = (el_inv * crf(costs.interest_rate, el_life) + store_inv * crf(costs.interest_rate,
                                                                                costs["hydrogen"]["life_a"])
                   + el_inv * costs["electrolyser"]["om_share_per_a"] + store_inv * costs["hydrogen"]["om_share_per_a"])
        for rule in RULES:
            sub = households[(households["arm"] == "hub") & (households["hub_kwh"] == hub["store_kwh"])
                             & (households["rule"] == rule)]
            assert len(sub) == 2
            assert (sub["hub_annuity_eur_a"] + sub["hub_om_eur_a"]).sum() == pytest.approx(capital, rel=1e-9)
            # by nominal share: house a owns 2/3 of the hub, b 1/3
            a, b = (sub[sub["house"] == h].iloc[0] for h in ("a", "b"))
            assert a["hub_annuity_eur_a"] == pytest.approx(2 * b["hub_annuity_eur_a"], rel=1e-9)
            # community.json holds the costs to 1e-6 EUR (core.kpi.at_resolution), scaled to the year
            assert sub["energy_eur_a"].sum() == pytest.approx(summary[f"cost_eur_{rule}"] * scale, abs=1e-6 * scale)
            own = sub["annuity_eur_a"] + sub["om_eur_a"]
            assert sub["total_eur_a"].sum() == pytest.approx(
                summary[f"cost_eur_{rule}"] * scale + capital + own.sum(), abs=1e-6 * scale)
            point = pd.read_csv(out / "points.csv")
            row = point[(point["arm"] == "hub") & (point["hub_kwh"] == hub["store_kwh"]) & (point["rule"] == rule)]
            assert row["total_eur_a"].iloc[0] == pytest.approx(sub["total_eur_a"].sum(), rel=1e-12)
            assert row["total_eur_a_per_household"].iloc[0] == pytest.approx(sub["total_eur_a"].mean(), rel=1e-12)


def test_an_isolated_house_pays_its_own_meter_without_sharing(study: tuple[Path, str]) -> None:
    """Under the rule set that shares nothing, an isolated household's energy is its own run's
    net cost (its electrolyser behind its meter), and its self-sufficiency its own."""
    out, _ = study
    households = pd.read_csv(out / "households.csv")
    iso = households[(households["arm"] == "isolated") & (households["rule"] == "none")]
    for r in iso.itertuples():
        run = json.loads((out / r.run / "community.json").read_text(encoding="utf-8"))
        scale = WEEKS_PER_YEAR / 0.5
        assert r.energy_eur_a == pytest.approx(run["cost_cp_eur"] * scale, abs=1e-6 * scale)
        assert r.self_sufficiency == pytest.approx(run["self_sufficiency"], abs=1e-6)
        assert r.el_modules == 1 and r.hub_annuity_eur_a == 0.0
    # sharing among isolated neighbours never makes a household's energy dearer than its own meter's
    shared = households[(households["arm"] == "isolated") & (households["rule"] == "one_connection")]
    alone = iso.set_index(["hub_kwh", "house"])["energy_eur_a"]
    for r in shared.itertuples():
        assert r.energy_eur_a <= alone[(r.hub_kwh, r.house)] + 1e-9


def test_from_runs_rebuilds_the_same_tables(study: tuple[Path, str], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    out, _ = study
    code, stdout, err = run_cli(["size", "--from-runs", out, "--out", tmp_path / "again"], capsys)
    assert code == 0, err
    for name in ("households.csv", "points.csv"):
        assert (tmp_path / "again" / name).read_bytes() == (out / name).read_bytes(), name
    assert "EnWG § 42c" in stdout
    points = pd.read_csv(out / "points.csv")
    labels = {name: r.label for name, r in load_sharing_rules().rule_sets.items()}
    fig = rcs.cost_figure(points, labels)
    fig.canvas.draw()
    assert layout_problems(fig) == []
    plt.close(fig)


@settings(max_examples=60, deadline=None)
@given(weights=st.lists(st.floats(0.1, 10.0), min_size=1, max_size=12),
       store=st.floats(10.0, 50_000.0), modules=st.integers(1, 40), hours=st.floats(0.0, 8760.0 * 40),
       weeks=st.floats(0.5, 52.0))
def test_the_hub_split_adds_up_for_any_weights(weights: list[float], store: float, modules: int, hours: float,
                                               weeks: float) -> None:
    costs = load_costs()
    size = HubSize(store, modules)
    hub = hub_annual_costs(size, hours, weeks, costs)
    names = {f"h{i}": w for i, w in enumerate(weights)}
    shares = shares_kwh(store, names)
    assert sum(shares.values()) == pytest.approx(store, rel=1e-12)
    summary = {"weeks": weeks, "fc_working_hours": 0.0, "fc_toggles": 0.0, "bess_charged_kwh_total": 0.0}
    sizes = {"pv_kwp": 0.0, "battery_kwh": 0.0, "fc_kw": 0.0, "el_modules": 0, "h2_kwh": 0.0}
    parts = [household_costs(sizes, summary, 0.0, costs, 0.0, weeks, 0.0, hub, shares[n] / store) for n in names]
    assert sum(p["hub_annuity_eur_a"] + p["hub_om_eur_a"] for p in parts) == pytest.approx(
        hub["annuity_eur_a"] + hub["om_eur_a"], rel=1e-9)
    assert sum(p["invest_eur"] for p in parts) == pytest.approx(hub["invest_eur"], rel=1e-9)
    # the hub is the size study's electrolyser and store: its annual cost as annual_costs gives them
    direct = annual_costs({**sizes, "el_modules": modules, "h2_kwh": store},
                          {**summary, "cost_net_eur": 0.0, "el_working_hours": hours / modules}, costs, 0.0)
    assert hub["total_eur_a"] == pytest.approx(direct["total_eur_a"], rel=1e-12)


def _house(**kw: object) -> dict[str, object]:
    return {"heating_season_weeks": 12, "h2_empty_at": None, "heating_season_discomfort_weeks": 0, **kw}


HUB = {"hub_loh_init": 0.1, "hub_loh_end": 0.12, "hub_loh_heating_season_start": 0.7}


@pytest.mark.parametrize(("hub", "houses", "closes", "named"), [
    (HUB, {"a": _house(), "b": _house()}, True, "closes"),
    ({**HUB, "hub_loh_end": 0.09}, {"a": _house()}, False, "LOH at the end 0.090 < at the start 0.100"),
    ({**HUB, "hub_loh_heating_season_start": 0.1}, {"a": _house()}, False, "the summer did not fill"),
    (HUB, {"a": _house(), "b": _house(h2_empty_at="2023-02-03T18:00:00+01:00")}, False, "b's account at 2023-02-03"),
    (HUB, {"a": _house(heating_season_discomfort_weeks=1), "b": _house(heating_season_discomfort_weeks=2)}, False,
     "3 heating-season week(s) with discomfort"),
    (HUB, {"a": _house(heating_season_weeks=0)}, None, "no full heating-season week"),
])
def test_the_hub_closes_the_cycle_by_the_criterion_of_size(hub: dict, houses: dict, closes: bool | None,
                                                           named: str) -> None:
    verdict, why = community_cycle(hub, houses)
    assert verdict is closes and named in why


def test_resized_names_the_bad_field_and_an_unknown_house(tmp_path: Path) -> None:
    spec = load_community(_file(tmp_path))
    alone = resized(spec, {"store_kwh": 1200.0, "electrolyser_modules": None}, "b")
    assert [h.name for h in alone.houses] == ["b"] and alone.hub.store_kwh == 1200.0
    assert resized(spec, {"electrolyser_modules": 3}).hub.electrolyser_modules == 3
    with pytest.raises(ConfigError, match="no house 'c'"):
        resized(spec, {}, "c")
    with pytest.raises(ConfigError, match="hub.store_kwh"):
        resized(spec, {"store_kwh": -1.0})
    with pytest.raises(ConfigError, match="hub.colour"):
        resized(spec, {"colour": 1})


@pytest.mark.parametrize(("argv", "named"), [
    (["--hub-kwh", "0"], "--hub-kwh '0': '0' must be > 0"),
    (["--hub-kwh", "900,x"], "--hub-kwh '900,x': 'x' is not a number"),
    (["--hub-kwh", "900,900"], "--hub-kwh '900,900': 900 is given twice"),
    (["--hub-modules", "0"], "a hub needs at least one module"),
    (["--hub-modules", "1.5"], "--hub-modules '1.5': '1.5' is not an integer >= 0"),
    (["--pv-kwp", "5"], "--pv-kwp sizes one house"),
    (["--sample", "3"], "--sample draws one house's sizes"),
    (["--coordinator", "nosuch"], "unknown coordinator 'nosuch'"),
    (["--coordinator", "rule,rule"], "'rule' given twice"),
    (["--coordinator-option", "rule.h2_splt=need"], "h2_splt"),
    (["--ems", "rbc,fuzzy"], "the one EMS of every house"),
    (["--set", "hydrogen.e_max_kwh=5"], "--set hydrogen.e_max_kwh: the H2 systems are sized by the study"),
    (["--set", "electrolyser.n_modules=2"], "--set electrolyser.n_modules"),
    (["--building", "energyplus"], "4R3C"),
    (["--weeks", "60"], "--start/--weeks"),
    (["--costs", "/nonexistent/costs.yaml"], "--costs /nonexistent/costs.yaml: no such file"),
])
def test_bad_community_options_exit_2_before_any_run(argv: list[str], named: str, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    window = [] if "--weeks" in argv else WINDOW
    code, _, err = run_cli(["size", "--community", _file(tmp_path), *window, *argv, "--out", out], capsys)
    assert code == 2, err
    assert named in err, err
    assert "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(("argv", "named"), [
    (["--ems", "rbc", "--hub-kwh", "900"], "--hub-kwh applies with --community"),
    (["--ems", "rbc", "--coordinator", "rule"], "--coordinator applies with --community"),
    (["--ems", "rbc", "--coordinator-option", "rule.h2_split=need"], "--coordinator-option applies with --community"),
    ([], "--ems is required"),
])
def test_community_options_without_community_are_refused(argv: list[str], named: str, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["size", *WINDOW, *argv, "--out", tmp_path / "out"], capsys)
    assert code == 2 and named in err, err


def test_bad_community_file_and_runs_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = _file(tmp_path, TWO.replace("h2_weight: 0.5", "h2_weight: -1"))
    code, _, err = run_cli(["size", "--community", bad, *WINDOW, "--out", tmp_path / "out"], capsys)
    assert code == 2 and "two.yaml" in err and "houses.1.h2_weight" in err, err
    empty = tmp_path / "empty"
    empty.mkdir()
    code, _, err = run_cli(["size", "--from-runs", empty], capsys)
    assert code == 2 and rcs.MANIFEST in err, err
    code, _, err = run_cli(["size", "--from-runs", empty, "--resume"], capsys)
    assert code == 2 and "--from-runs makes none" in err, err
    costs = param_file(tmp_path / "costs.yaml", "costs:\n  hydrogen:\n    invest_eur_per_kwh: -1")
    code, _, err = run_cli(["size", "--community", _file(tmp_path), *WINDOW, "--costs", costs, "--out",
                            tmp_path / "out"], capsys)
    assert code == 2 and "costs.hydrogen.invest_eur_per_kwh = -1 must be >= 0" in err, err
