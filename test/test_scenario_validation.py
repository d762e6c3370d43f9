"""The validation set's scenarios: station data, radiation from sunshine duration, the cases and their frames."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.config import ConfigError, config_dir, load_plant_params
from comems4build_ros.core.scenario import ScenarioError, default_scenario, is_embedded, resolve_scenario
from comems4build_ros.core.scenario import validation as va

SETTINGS = va.load_validation_settings()


# --------------------------------------------------------------------------- radiation


def test_angstrom_prescott_at_noon_on_the_equator_at_the_equinox():
    """Hand values: E0 = 1367 (1 + 0.033 cos(2 pi 80 / 365)) = 1376.8 W/m2 (Duffie and Beckman eq. 1.4.1b),
    sun 1.8 deg from the zenith at 12:00 UTC (equation of time -7.5 min), so R_a = 1376 W/m2 within 1 %;
    FAO-56: a cloudless hour passes 0.75 R_a, an overcast one 0.25 R_a; Erbs: diffuse fraction 0.1831 at
    kt = 0.75 and 0.9735 at kt = 0.25."""
    start = pd.DatetimeIndex(["2016-03-20 11:30", "2016-03-20 11:30", "2016-03-20 11:30"], tz="UTC")
    ghi, dhi = va.ghi_from_sunshine(start, np.array([1.0, 0.5, 0.0]), 0.0, 0.0, 0.0)
    r_a = 1367.0 * (1 + 0.033 * math.cos(2 * math.pi * 80 / 365)) * math.cos(math.radians(1.84))
    assert ghi == pytest.approx([0.75 * r_a, 0.50 * r_a, 0.25 * r_a], rel=0.01)
    assert dhi[0] / ghi[0] == pytest.approx(0.1831, abs=0.002)
    assert dhi[2] / ghi[2] == pytest.approx(0.9735, abs=0.002)


def test_clear_sky_variant_scales_the_ineichen_ghi():
    """model="ineichen": (a_s + b_s n/N) / (a_s + b_s) times pvlib's Ineichen clear-sky GHI, so a
    cloudless hour is the clear sky itself and an overcast one a third of it."""
    import pvlib

    start = pd.DatetimeIndex(["2016-01-10 10:30"] * 2, tz="UTC")
    ghi, _ = va.ghi_from_sunshine(start, np.array([1.0, 0.0]), 48.35, 11.81, 453.0, model="ineichen")
    clear = pvlib.location.Location(48.35, 11.81, altitude=453.0).get_clearsky(
        start + pd.Timedelta(minutes=30), model="ineichen")["ghi"].to_numpy()
    assert ghi == pytest.approx([clear[0], clear[0] / 3])
    with pytest.raises(ValueError, match="unknown sunshine model 'nope'"):
        va.ghi_from_sunshine(start, np.array([1.0, 0.0]), 48.35, 11.81, 453.0, model="nope")


def test_no_radiation_at_night_and_diffuse_never_above_global():
    start = pd.date_range("2016-01-10 00:00", periods=48, freq="h", tz="UTC")
    sf = np.tile(np.linspace(0, 1, 24), 2)
    ghi, dhi = va.ghi_from_sunshine(start, sf, 48.35, 11.81, 453.0)
    night = (start.hour < 6) | (start.hour >= 17)  # Munich in January: sunrise ~7:00, sunset ~15:45 UTC
    assert np.all(ghi[night] == 0.0) and np.all(dhi[night] == 0.0)
    assert np.all(dhi <= ghi + 1e-12) and np.all(dhi >= 0.0)
    assert ghi[(start.hour >= 9) & (start.hour <= 13)].min() > 0.0


def test_coefficients_named_in_the_config_are_fao56s():
    assert (SETTINGS.radiation.a_s, SETTINGS.radiation.b_s) == (0.25, 0.50)


@pytest.mark.parametrize("bad", [np.array([1.2]), np.array([-0.1]), np.array([np.nan])])
def test_sunshine_fraction_outside_0_1_is_refused(bad):
    with pytest.raises(ValueError, match="sunshine fraction"):
        va.ghi_from_sunshine(pd.DatetimeIndex(["2016-01-10 11:00"], tz="UTC"), bad, 48.0, 11.0, 0.0)


def test_daylight_gaps_interpolated_and_night_zero():
    idx = pd.date_range("2016-01-10 00:00", periods=8, freq="h", tz="UTC")
    minutes = pd.Series([np.nan, 0.0, 30.0, np.nan, np.nan, 60.0, 12.0, np.nan], index=idx)
    r_a = np.array([0.0, 10.0, 100.0, 200.0, 200.0, 100.0, 10.0, 0.0])
    sf = va.sunshine_fraction(minutes, r_a, 2, "file")
    assert sf == pytest.approx([0.0, 0.0, 0.5, 2 / 3, 5 / 6, 1.0, 0.2, 0.0])
    with pytest.raises(ScenarioError, match=r"file: no sunshine duration for more than 1 daylight hours from "
                                            r"2016-01-10T03:00:00\+00:00"):
        va.sunshine_fraction(minutes, r_a, 1, "file")


# --------------------------------------------------------------------------- station files


def _station(tmp_path, rows):
    path = tmp_path / "station.csv"
    path.write_text("MESS_DATUM;TT_TU;RF_TU;SD_SO\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_station_file_sunshine_belongs_to_the_hour_it_ends(tmp_path):
    path = _station(tmp_path, ["2016010100;1.0;90.0;", "2016010101;2.0;90.0;0", "2016010102;-999;90.0;30"])
    f = va.read_station_hourly(path)
    assert list(f.index.strftime("%Y-%m-%d %H")) == ["2015-12-31 23", "2016-01-01 00", "2016-01-01 01",
                                                     "2016-01-01 02"]
    assert f["t_amb_c"].iloc[1:3].tolist() == [1.0, 2.0] and math.isnan(f["t_amb_c"].iloc[3])
    assert math.isnan(f["sunshine_min"].iloc[0])       # stamp 00 ended the hour 23..00, empty (night)
    assert f["sunshine_min"].iloc[1:3].tolist() == [0.0, 30.0]


@pytest.mark.parametrize("rows, message", [
    (["2016010100;x;90.0;"], r"line 2, column 'TT_TU': 'x' is not a number"),
    (["2016010100;1.0;90.0;", "2016010101;1.0;90.0;61"], r"line 3, column 'SD_SO': 61 min is outside 0..60"),
    (["2016010100;70.0;90.0;"], r"line 2, column 'TT_TU': value 70 outside the plausible range -60..60 degC"),
    (["20160101;1.0;90.0;"], r"line 2, column 'MESS_DATUM': '20160101' is not yyyymmddHH"),
    (["2016010100;1.0;90.0"], r"line 2: 3 fields, header has 4"),
])
def test_bad_station_rows_are_named(tmp_path, rows, message):
    with pytest.raises(ScenarioError, match=message):
        va.read_station_hourly(_station(tmp_path, rows))


def test_price_file_may_jump_between_winters_but_not_back(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("utc_start,price\n2016-01-01T00:00:00Z,1\n2016-01-01T01:00:00Z,2\n2017-01-01T00:00:00Z,3\n",
                    encoding="utf-8")
    assert va.read_price_winters(path, "price").tolist() == [1.0, 2.0, 3.0]
    path.write_text("utc_start,price\n2016-01-01T01:00:00Z,1\n2016-01-01T00:00:00Z,2\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match="line 3, column 'utc_start': not after the previous row"):
        va.read_price_winters(path, "price")


# --------------------------------------------------------------------------- cases


def test_the_set_and_its_split():
    cases = va.validation_cases(SETTINGS)
    assert len(cases) == 24
    winters = [c for c in cases if c.kind == va.WEATHER]
    assert len(winters) == 16 and {c.station for c in winters} == {"muenchen", "hamburg"}
    assert 2021 not in {c.winter for c in winters}  # its prices are held back
    assert sum(c.subset == va.DEVELOPMENT for c in cases) == 12
    assert {c.winter for c in winters if c.subset == va.DEVELOPMENT} == {2015, 2017, 2019, 2022}
    assert va.case_of("validation/muenchen-2016-17", SETTINGS).subset == va.HELD_OUT
    assert va.case_of("household-108", SETTINGS).annual_kwh == 4500.0
    assert va.case_of("muenchen-2015-16", SETTINGS).plant_overrides(SETTINGS) == {
        "site.latitude_deg": 48.3477, "site.longitude_deg": 11.8134, "site.altitude_m": 453.0,
        "comfort.holidays_subdivision": "BY"}
    with pytest.raises(ScenarioError, match="no such validation case.*household-101"):
        va.case_of("validation/nowhere-2015-16", SETTINGS)
    assert is_embedded("validation/household-101") and is_embedded("default") and not is_embedded("x.csv")


def test_a_winter_case_needs_the_plant_at_its_station():
    with pytest.raises(ScenarioError, match=r"validation/hamburg-2016-17.*site.latitude_deg.*DWD station 1975 "
                                            r"Hamburg-Fuhlsbüttel.*--set site.latitude_deg=53.6332"):
        resolve_scenario("validation/hamburg-2016-17", load_plant_params())


def test_a_winter_case_from_its_files():
    case = va.case_of("muenchen-2016-17", SETTINGS)
    params = load_plant_params(overrides=case.plant_overrides(SETTINGS))
    sc = resolve_scenario(case.scenario, params)
    assert sc.n_steps == 12 * 168 and len(sc.time) == 12 * 168 + 24
    assert sc.time[0].isoformat() == "2016-12-01T00:00:00+01:00"
    prices = pd.read_csv(va._data_path(SETTINGS.prices_file))
    row = prices.index[prices["utc_start"] == "2016-11-30T23:00:00Z"][0]
    assert sc.spot_eur_per_mwh[:3].tolist() == prices["price_EUR_per_MWh"].iloc[row:row + 3].tolist()
    wx = va.read_station_hourly(va._data_path(SETTINGS.stations["muenchen"].file))
    assert sc.t_amb_c[0] == wx.loc[pd.Timestamp("2016-11-30 23:00", tz="UTC"), "t_amb_c"]
    assert np.all(sc.ghi_w_m2 >= sc.dhi_w_m2) and sc.ghi_w_m2.max() < 700.0
    assert 0.5 < sc.ghi_w_m2[:sc.n_steps].mean() * 24 / 1000 < 2.0  # kWh/m2/d of a Bavarian winter
    assert sc.meta["kind"] == "winter" and "Angstrom-Prescott" in sc.meta["ghi_w_m2"]
    assert sc.dhw_l_per_h[:sc.n_steps].mean() * 24 == pytest.approx(200.0, rel=0.05)
    with pytest.raises(ScenarioError, match="fixes its own seeds"):
        resolve_scenario(case.scenario, params, seed=3)
    with pytest.raises(ScenarioError, match="takes no scenario settings"):
        resolve_scenario(case.scenario, params, settings_overrides={"scenario.load.annual_kwh": 4000})


def test_a_household_case_is_the_papers_winter_with_another_household():
    params = load_plant_params()
    sc = resolve_scenario("validation/household-104", params)
    ref = default_scenario(params)
    assert np.array_equal(sc.spot_eur_per_mwh, ref.spot_eur_per_mwh)
    assert np.array_equal(sc.t_amb_c, ref.t_amb_c)
    assert not np.array_equal(sc.p_load_w, ref.p_load_w) and not np.array_equal(sc.dhw_l_per_h, ref.dhw_l_per_h)
    seeded = default_scenario(params, seed=104)
    assert np.array_equal(sc.ghi_w_m2, seeded.ghi_w_m2)  # radiation of the seed
    # the appliance cycles keep their energy per run, the rest scales with the annual energy
    assert sc.p_load_w[:sc.n_steps].sum() / seeded.p_load_w[:sc.n_steps].sum() == pytest.approx(4210 / 4300, rel=0.01)
    assert 150 < sc.dhw_l_per_h[:sc.n_steps].mean() * 24 < 260


def test_a_shorter_run_is_the_start_of_the_full_one():
    case = va.case_of("hamburg-2019-20", SETTINGS)
    params = load_plant_params(overrides=case.plant_overrides(SETTINGS))
    full = resolve_scenario(case.scenario, params)
    short = resolve_scenario(case.scenario, params, weeks=2)
    assert short.n_steps == 336 and np.array_equal(short.ghi_w_m2, full.ghi_w_m2[:336 + 24])


def test_bad_validation_file_is_named(tmp_path):
    text = (config_dir() / va.VALIDATION_FILE).read_text(encoding="utf-8")
    path = tmp_path / "v.yaml"
    path.write_text(text.replace("b_s: 0.50", "b_s: 0.90"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"v.yaml: parameter 'radiation': .*a_s \+ b_s = 1.15"):
        va.load_validation_settings(path)
    path.write_text(text.replace("households: [101, 103, 105, 107]", "households: [101, 199]"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"development.households \[199\] are not among the household seeds"):
        va.load_validation_settings(path)
    path.write_text(text.replace("tariff: household", "tariff: flat"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"v.yaml: parameter 'tariff': Input should be 'paper' or 'household'"):
        va.load_validation_settings(path)


def test_radiation_statistics_by_local_month():
    idx = pd.date_range("2016-12-31 22:00", periods=4, freq="h", tz="UTC")  # 23:00, 00:00, 01:00, 02:00 local
    frame = pd.DataFrame({"ghi_w_m2": [100.0, 200.0, 300.0, 1000.0], "dhi_w_m2": [50.0, 100.0, 150.0, 0.0]},
                         index=idx)
    stats = va.radiation_statistics(frame, "Europe/Berlin", 3)
    assert stats["ghi_kwh_m2_day_m12"] == pytest.approx(100.0 * 24 / 1000)
    assert stats["ghi_kwh_m2_day_m01"] == pytest.approx(250.0 * 24 / 1000)
    assert stats["diffuse_share"] == pytest.approx(0.5)
