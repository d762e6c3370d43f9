"""The EnergyPlus house in co-simulation: IDF checks, EPW, heat balance, and refusals before a run."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.models import house_idf as house
from comems4build_ros.core.models.building_energyplus import IDFError, check_idf, polygon_area_m2
from comems4build_ros.core.models.epw import (
    EPWError,
    Weather,
    check_epw_covers,
    dew_point_c,
    epw_hours,
    write_epw,
)
from comems4build_ros.core.scenario import resolve_scenario

pytest.importorskip("pyenergyplus")


def test_shipped_idf_is_what_the_generator_writes():
    assert house.shipped_idf().read_text(encoding="utf-8") == house.idf_text()


def test_shipped_house_offers_the_cosimulation_interface():
    spec = check_idf(house.shipped_idf())
    assert spec.zones == list(house.ZONES)
    assert spec.floors == list(house.FLOORS)
    assert spec.timesteps_per_hour == 4
    assert sum(spec.floor_areas_m2) == pytest.approx(house.HouseSpec().heated_floor_m2, rel=1e-6)


def test_heat_loss_coefficient_by_the_typology_method_is_within_25_percent_of_the_4r3c(params):
    h = house.heat_loss_coefficient()
    b = params.building
    h_rc = 1 / b.r_air_amb_k_per_w + 1 / (b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w)
    assert abs(h["h_w_per_k"] / h_rc - 1) <= 0.25
    assert h["h_tr_w_per_k"] == pytest.approx(87.0, rel=0.05)  # TABULA DE.N.SFH.09.Gen.ReEx.001.003


def test_polygon_area():
    assert polygon_area_m2([0, 0, 0, 2, 0, 0, 2, 3, 0, 0, 3, 0]) == pytest.approx(6.0)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("Version,\n  25.2;", "Version,\n  9.6;"), "object Version: field Version Identifier"),
        (lambda t: t.replace(house.HEAT_SCHEDULE, "Other Schedule"), "object Schedule:Constant: field Name"),
        (lambda t: t.replace("Timestep,\n  4;", "Timestep,\n  2;"), "object Timestep: field Number of Timesteps"),
        (lambda t: t.replace("ElectricEquipment,", "OtherEquipment,"), "object ElectricEquipment"),
        (lambda t: t.replace("HalfFlowPower", "ZeroFlowPower", 1),
         "object ZoneHVAC:LowTemperatureRadiant:Electric 'GF Floor Heating': field Temperature Control Type"),
    ],
)
def test_check_idf_names_the_file_and_the_object(tmp_path, edit, message):
    bad = tmp_path / "house.idf"
    bad.write_text(edit(house.idf_text()))
    with pytest.raises(IDFError, match=message) as exc:
        check_idf(bad)
    assert str(bad) in str(exc.value)


def test_epw_roundtrip_and_coverage(params, tmp_path):
    time = pd.date_range("2022-12-01", periods=48, freq="h", tz=params.site.timezone)
    w = Weather(time, np.linspace(-5, 5, 48), np.where(time.hour.isin(range(9, 16)), 200.0, 0.0),
                np.where(time.hour.isin(range(9, 16)), 100.0, 0.0))
    path = write_epw(tmp_path / "w.epw", w, params.site)
    hours = epw_hours(path)
    assert len(hours) == 48 and hours[0] == pd.Timestamp("2022-12-01 00:00")
    rows = path.read_text().splitlines()[8:]
    fields = rows[0].split(",")
    assert len(fields) == 35 and float(fields[6]) == -5.0 and float(fields[14]) == 0.0  # no DNI at midnight
    check_epw_covers(path, pd.Timestamp("2022-12-01"), 48)
    with pytest.raises(EPWError, match="field date: the weather file does not cover the run"):
        check_epw_covers(path, pd.Timestamp("2022-12-01"), 49)


def test_dew_point_magnus():
    assert dew_point_c(20.0, 100.0) == pytest.approx(20.0)
    assert dew_point_c(20.0, 50.0) == pytest.approx(9.26, abs=0.05)


@pytest.fixture(scope="module")
def week_run(params):
    """One week of ComEMS4Build on the EnergyPlus house."""
    scenario = resolve_scenario("default", params, weeks=1)
    return simulate("fuzzy", scenario, params, building="energyplus")


def test_every_steps_heat_equals_what_energyplus_received(week_run):
    ts = week_run.timeseries
    q_plant = ts["q_hp_sh_w"] - ts["q_cool_w"]
    assert (q_plant > 0).sum() > 10  # the heat pump heated in the week
    rel = np.abs(q_plant - ts["building_q_floor_received_w"]) / np.maximum(np.abs(q_plant), 1.0)
    assert rel.max() <= 1e-6
    assert week_run.summary["building_heat_balance_max_rel"] <= 1e-6
    assert np.allclose(ts["building_gains_w"], ts["p_load_w"])


def test_heat_goes_into_the_screed_and_cooling_through_the_floor_face(params):
    """Heat through the radiant systems (internal source in the screed), cooling through the source terms."""
    from comems4build_ros.core.loop import exogenous_series
    from comems4build_ros.core.models.building_energyplus import EnergyPlusBuilding, weather_of

    scenario = resolve_scenario("default", params, hours=12)
    exo = exogenous_series(scenario, params)
    spec = check_idf(house.shipped_idf())
    assert [r.name for r in spec.radiant] == list(house.RADIANT)
    b = EnergyPlusBuilding(None, weather_of(scenario.time, scenario.t_amb_c, scenario.ghi_w_m2, scenario.dhi_w_m2),
                           params.site, scenario.n_steps, 21.0)
    try:
        x = b.initial_temperatures(21.0, 4.0)
        for k, q in enumerate([4500.0, 4500.0, 0.0, 700.0, -1500.0, -1500.0, 0.0, 3000.0, 3000.0, 3000.0, 0.0, 0.0]):
            x = b.step(x, q, exo[k])
            assert b.last.q_floor_received_w == pytest.approx(q, rel=1e-6, abs=1e-6)
        assert x[0] > 15.0
    finally:
        b.close()


def test_energyplus_house_is_a_house(week_run):
    ts = week_run.timeseries
    assert week_run.summary["building"] == "energyplus"
    assert 15.0 < ts["t_air_c"].min() and ts["t_air_c"].max() < 28.0
    assert ts["t_air_c"].diff().abs().max() < 3.0  # no jumps between hours


def test_rc_runs_have_no_building_columns(params):
    run = simulate("rbc", resolve_scenario("default", params, hours=24), params)
    assert not [c for c in run.timeseries.columns if c.startswith("building_")]
    assert "building" not in run.summary


def test_cli_refuses_broken_idf_and_short_epw_with_exit_2(params, tmp_path, capsys):
    bad = tmp_path / "broken.idf"
    bad.write_text(house.idf_text().replace(house.HEAT_SCHEDULE, "Typo"))
    out = tmp_path / "run"
    assert main(["simulate", "--ems", "fuzzy", "--building", f"energyplus:{bad}", "--out", str(out)]) == 2
    assert f"{bad}: object Schedule:Constant: field Name" in capsys.readouterr().err
    time = pd.date_range("2022-12-01", periods=24, freq="h", tz=params.site.timezone)
    short = write_epw(tmp_path / "short.epw", Weather(time, np.zeros(24), np.zeros(24), np.zeros(24)), params.site)
    assert main(["simulate", "--ems", "fuzzy", "--building", "energyplus", "--epw", str(short), "--weeks", "1",
                 "--out", str(out)]) == 2
    assert "short.epw: field date: the weather file does not cover the run" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("command", [
    ["simulate", "--ems", "fuzzy"], ["compare"], ["sweep", "--ems", "rbc", "--param", "battery.e_max_kwh=5"],
    ["size", "--ems", "rbc"], ["reproduce", "--only", "x"], ["launch", "--ems", "fuzzy", "--steps", "2"], ["identify"],
])
def test_every_command_that_runs_a_plant_takes_building_and_refuses_a_broken_idf(command, tmp_path, capsys):
    bad = tmp_path / "broken.idf"
    bad.write_text("Version, 9.6;\n")
    out = tmp_path / "out.yaml" if command[0] == "identify" else tmp_path / "out"
    assert main([*command, "--building", f"energyplus:{bad}", "--out", str(out)]) == 2
    assert f"{bad}: object Version: field Version Identifier" in capsys.readouterr().err
    assert not out.exists()
