"""The year-round scenario (``--scenario year``) and its plant, KPIs and the EMS over it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.config import load_plant_params, scenario_config_files
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.core.scenario.comfort import heating_season_days


@pytest.fixture(scope="module")
def params():
    return load_plant_params(scenario_config_files("year"))


def test_year_plant_file_comes_first_and_once() -> None:
    files = scenario_config_files("year", ["mine.yaml"])
    assert files[0].endswith("year.yaml") and files[1] == "mine.yaml"
    assert scenario_config_files("year", files) == files
    assert scenario_config_files("default", ["mine.yaml"]) == ["mine.yaml"]
    p = load_plant_params(scenario_config_files("year"), {"electrolyser.n_modules": 2})
    assert p.electrolyser.n_modules == 2 and p.simulation.loh_init == pytest.approx(0.10)


def test_year_scenario_window_and_data(params) -> None:
    sc = resolve_scenario("year", params)
    assert sc.n_steps == 52 * 168
    assert sc.time[0].isoformat() == "2022-03-01T00:00:00+01:00"
    assert len(sc.time) == 8760  # the run and its 24 h look-ahead: every hour of the data
    assert sc.meta["t_amb_filled"]["from"] == "2023-02-15T01:00:00+01:00"  # record ends 2023-02-14 23 UTC
    assert sc.meta["t_amb_filled"]["hours"] == 8760 - 8425
    prices = pd.read_csv(
        __import__("comems4build_ros.core.scenario.measured", fromlist=["data_dir"]).data_dir()
        / "DE_LU_day_ahead_EURperMWh_2022-03-01_2023-02-28_hourly.csv")
    assert np.array_equal(sc.spot_eur_per_mwh, prices["price_EUR_per_MWh"].to_numpy(float))
    # summer bound in the cooling season, the paper's in winter
    t_max = pd.Series(sc.t_max_c, index=sc.time)
    assert t_max["2022-07-01"].eq(26.0).all() and t_max["2022-12-01"].eq(24.0).all()
    # a window inside the year
    sub = resolve_scenario("year", params, start="2022-07-04T00:00:00", weeks=1)
    assert sub.n_steps == 168 and sub.time[0].isoformat() == "2022-07-04T00:00:00+02:00"


def test_heating_season_days() -> None:
    t = pd.DatetimeIndex(["2022-11-30T12:00", "2022-12-01T00:00", "2023-02-28T23:00", "2023-03-01T00:00"],
                         tz="Europe/Berlin")
    to_start, left = heating_season_days(t, "12-01", "03-01")
    assert to_start.tolist() == pytest.approx([0.5, 0.0, 0.0, 275.0])
    assert left.tolist() == pytest.approx([0.0, 90.0, 1 / 24, 0.0])


@pytest.mark.parametrize("ems", ["fuzzy", "rbc"])
def test_summer_week_electrolyses_and_cools(ems: str, params) -> None:
    sc = resolve_scenario("year", params, start="2022-07-18T00:00:00", weeks=1)
    r = simulate(ems, sc, params)
    s = r.summary
    assert s["h2_produced_kwh"] > 10.0 and s["el_working_hours"] > 5
    assert r.timeseries["q_cool_w"].max() > 0.0
    assert s["energy_balance_rel_error"] < 1e-6
    assert 0.5 < s["el_mean_eta"] < 0.63
    assert r.monthly is not None and list(r.monthly["month"]) == ["2022-07"]
    # LOH bookkeeping: the store gains the H2 produced less the FC's draw
    ts = r.timeseries
    gain = (ts["p_h2_el_w"].sum() - ts["p_h2_w"].sum()) / (params.hydrogen.e_max_kwh * 1000.0)
    assert ts["loh"].iloc[-1] - params.simulation.loh_init == pytest.approx(gain, abs=1e-9)


def test_fuzzy_year_closes_the_balance_and_the_seasonal_cycle(params) -> None:
    """ComEMS4Build over the year from LOH_init: the energy balance closes to 1e-6 of the throughput, the
    store holds at least half on 2022-12-01 and ends with at least LOH_init, and at most 2 of the 12 winter
    weeks have discomfort (docs/seasonal.md, results)."""
    r = simulate("fuzzy", resolve_scenario("year", params), params)
    s = r.summary
    assert s["energy_balance_rel_error"] < 1e-6
    assert s["heating_season_weeks"] == 12
    assert len(r.monthly) == 12
    assert s["loh_heating_season_start"] >= 0.5
    assert s["loh_end"] >= params.simulation.loh_init
    assert s["heating_season_discomfort_weeks"] <= 2


def test_rbc_year_closes_the_balance(params) -> None:
    s = simulate("rbc", resolve_scenario("year", params), params).summary
    assert s["energy_balance_rel_error"] < 1e-6
    assert s["h2_produced_kwh"] > 0.0 and s["loh_heating_season_start"] is not None


def test_compare_year_writes_the_year_report(tmp_path) -> None:
    from comems4build_ros.app.cli import main

    out = tmp_path / "cmp"
    rc = main(["compare", "--scenario", "year", "--ems", "rbc,fuzzy", "--start", "2022-11-21T00:00:00",
               "--weeks", "2", "--out", str(out), "--no-progress"])
    assert rc == 0
    md = (out / "report.md").read_text(encoding="utf-8")
    for key in ("loh_year", "monthly_energy", "sankey_rbc", "sankey_fuzzy"):
        assert (out / "figures" / f"{key}.png").is_file() and (out / "figures" / f"{key}.svg").is_file()
        assert f"figures/{key}" in md
    assert "Monthly tables" in md and "2022-12" in md and "H2 produced" in md
    assert (out / "runs" / "fuzzy" / "monthly.csv").is_file()
    assert not (out / "runs" / "fuzzy_eta90").exists()  # the year compares at the plant's FC efficiency


def test_sankey_flows_balance(params) -> None:
    from comems4build_ros.report.year import sankey_flows

    r = simulate("rbc", resolve_scenario("year", params, start="2022-06-06T00:00:00", weeks=1), params)
    flows = sankey_flows(r.summary, r.monthly, r.timeseries)
    total_in = sum(v for _, v in flows if v > 0)
    assert abs(sum(v for _, v in flows)) < 1e-6 * total_in


def test_sweep_over_the_year_tabulates_the_sizing_figures(tmp_path) -> None:
    from comems4build_ros.app.cli import main

    out = tmp_path / "sweep"
    rc = main(["sweep", "--param", "electrolyser.n_modules=1,2", "--ems", "rbc", "--scenario", "year",
               "--start", "2022-07-04T00:00:00", "--weeks", "1", "--out", str(out), "--no-progress"])
    assert rc == 0
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["electrolyser.n_modules"]) == [1, 2]
    assert {"h2_produced_kwh", "self_sufficiency", "loh_heating_season_start"} <= set(df.columns)
    assert (df["h2_produced_kwh"] > 0).all()
