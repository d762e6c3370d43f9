"""Loaders of real sources on small fixtures (hand-computed values) and ``comems4build data build``."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.core.scenario import ScenarioError, ScenarioWarning, load_scenario_csv
from comems4build_ros.core.scenario import loaders as ld

FIX = __import__("pathlib").Path(__file__).resolve().parent / "fixtures"
T0 = pd.Timestamp("2022-12-01 00:00", tz="UTC")



def test_j_per_cm2_to_w_m2():
    # 6 J/cm2 in 10 min = 60000 J/m2 / 600 s = 100 W/m2
    assert ld.j_per_cm2_10min_to_w_m2(6.0) == pytest.approx(100.0)
    assert ld.j_per_cm2_10min_to_w_m2(1.2) == pytest.approx(20.0)


def test_awattar_hourly():
    s = ld.read_awattar_json(FIX / "awattar_3h.json")
    assert list(s.index) == [T0, T0 + pd.Timedelta(hours=1), T0 + pd.Timedelta(hours=2)]
    assert list(s) == [250.5, 230.0, -4.2]


def test_awattar_quarter_hours_averaged():
    s = ld.read_awattar_json(FIX / "awattar_15min.json")
    assert len(s) == 1 and s.iloc[0] == pytest.approx((100 + 120 + 80 + 60) / 4)


def _awattar(tmp_path, data):
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"object": "list", "data": data}))
    return path


def _entry(h, price=100.0, unit="Eur/MWh"):
    start = int(T0.timestamp() * 1000) + h * ld.MS_PER_HOUR
    return {"start_timestamp": start, "end_timestamp": start + ld.MS_PER_HOUR, "marketprice": price, "unit": unit}


@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        ([_entry(0), _entry(1, unit="Eur/kWh")], "data[1], field 'unit'"),
        ([_entry(0), _entry(2)], "data[1], field 'start_timestamp': gap"),
        ([_entry(0), _entry(0)], "data[1], field 'start_timestamp': overlapping"),
        ([_entry(0), {"start_timestamp": 1}], "data[1]: field 'end_timestamp' missing"),
        ([_entry(0, price=None)], "data[0], field 'marketprice'"),
        ([], "'data' is empty"),
    ],
)
def test_awattar_bad_input(tmp_path, data, fragment):
    path = _awattar(tmp_path, data)
    with pytest.raises(ScenarioError) as exc:
        ld.read_awattar_json(path)
    assert str(path) in str(exc.value) and fragment in str(exc.value)


def test_awattar_invalid_json(tmp_path):
    path = tmp_path / "p.json"
    path.write_text('{"data": [\n  {"start_timestamp": 1,\n')
    with pytest.raises(ScenarioError, match=r"line 3: invalid JSON"):
        ld.read_awattar_json(path)


def test_dwd_10min_temperature():
    t = ld.read_dwd_temperature(FIX / "dwd_10min_tt_4177.txt")
    assert t.index[0] == T0
    assert t.iloc[0] == pytest.approx((1.0 + 1.2 + 1.4 + 1.6 + 1.8 + 2.0) / 6)  # 1.5
    assert t.iloc[1] == pytest.approx((2.0 + 2.2 + 2.4 + 2.6 + 2.8) / 5)  # one -999 -> 5 values, 2.4
    assert math.isnan(t.iloc[2])  # only 3 valid values < MIN_VALID_10MIN


def test_dwd_hourly_temperature():
    t = ld.read_dwd_temperature(FIX / "dwd_hourly_tt_4177.txt")
    assert list(t.index) == [T0 + pd.Timedelta(hours=h) for h in range(3)]
    assert t.iloc[0] == 3.5 and math.isnan(t.iloc[1]) and t.iloc[2] == 4.1


def test_dwd_10min_solar():
    s = ld.read_dwd_solar(FIX / "dwd_10min_solar_4177.txt")
    # stamps 00:10..01:00 form hour 00 (sums over the 10 min ending at the stamp)
    assert s.index[0] == T0
    assert s["ghi_w_m2"].iloc[0] == pytest.approx(100.0)  # 6 J/cm2 each
    assert s["dhi_w_m2"].iloc[0] == pytest.approx(50.0)  # 3 J/cm2 each
    # hour 01: 0, 6, 12, 18, 24, 30 J/cm2 -> 0..500 W/m2 -> mean 250
    assert s["ghi_w_m2"].iloc[1] == pytest.approx(250.0)
    assert s["dhi_w_m2"].iloc[1] == pytest.approx(100.0)
    assert s["ghi_w_m2"].iloc[2] == pytest.approx(20.0) and math.isnan(s["dhi_w_m2"].iloc[2])


@pytest.mark.parametrize(
    ("mutate", "fragment"),
    [
        (lambda lines: [lines[0].replace("TT_10", "TX_10")] + lines[1:], "line 1 (header): neither 'TT_10'"),
        (lambda lines: lines[:3] + [lines[3].replace(";eor", ";")] + lines[4:], "line 4, column 'eor'"),
        (lambda lines: lines[:2] + [lines[2].replace("202212010010", "2022120100x0")] + lines[3:],
         "line 3, column 'MESS_DATUM'"),
        (lambda lines: lines[:5] + [lines[5].replace("   1.8", "  warm")] + lines[6:], "line 6, column 'TT_10'"),
        (lambda lines: lines[:4] + [lines[4].replace(";eor", ";1;eor")] + lines[5:], "line 5: 10 fields"),
        (lambda lines: lines[:4] + [lines[3]] + lines[5:], "duplicate time"),
    ],
)
def test_dwd_bad_input(tmp_path, mutate, fragment):
    lines = (FIX / "dwd_10min_tt_4177.txt").read_text().splitlines()
    path = tmp_path / "tt.txt"
    path.write_text("\n".join(mutate(lines)) + "\n")
    with pytest.raises(ScenarioError) as exc:
        ld.read_dwd_temperature(path)
    assert str(path) in str(exc.value) and fragment in str(exc.value), str(exc.value)


def _dhwcalc(tmp_path, values, header=False):
    path = tmp_path / "dhw.txt"
    path.write_text(("Water_LperH\n" if header else "") + "\n".join(f"{v:g}" for v in values) + "\n")
    return path


def test_dhwcalc_hourly_and_15min(tmp_path):
    hourly = np.zeros(8760)
    hourly[7] = 60.0  # Jan 1 07:00 local standard time
    s = ld.read_dhwcalc(_dhwcalc(tmp_path, hourly, header=True), 2022, "Europe/Berlin")
    assert len(s) == 8760 and s.index[0] == pd.Timestamp("2021-12-31 23:00", tz="UTC")
    assert s.iloc[7] == 60.0 and s.sum() == 60.0
    quarter = np.zeros(35040)
    quarter[28:32] = [40.0, 80.0, 0.0, 120.0]  # 07:00-08:00 in 15-min steps, l/h each
    s = ld.read_dhwcalc(_dhwcalc(tmp_path, quarter), 2022, "Europe/Berlin")
    assert len(s) == 8760 and s.iloc[7] == pytest.approx(60.0)  # mean flow of the hour


def test_dhwcalc_bad_input(tmp_path):
    with pytest.raises(ScenarioError, match="100 rows"):
        ld.read_dhwcalc(_dhwcalc(tmp_path, np.zeros(100)), 2022, "Europe/Berlin")
    values = [0.0] * 8760
    values[4] = -1.0
    with pytest.raises(ScenarioError, match="line 5, column 1"):
        ld.read_dhwcalc(_dhwcalc(tmp_path, values), 2022, "Europe/Berlin")


def test_repeat_year_profile_maps_by_position():
    profile = pd.Series(np.arange(8760, dtype=float), index=pd.date_range("2021-12-31 23:00", periods=8760,
                                                                         freq="h", tz="UTC"))
    idx = pd.DatetimeIndex([pd.Timestamp("2023-01-01 00:00", tz="Europe/Berlin").tz_convert("UTC"),
                            pd.Timestamp("2022-12-01 10:00", tz="Europe/Berlin").tz_convert("UTC")])
    out = ld.repeat_year_profile(profile, idx, "Europe/Berlin")
    assert list(out) == [0.0, (334 * 24 + 10)]  # Dec 1 = day 335


def test_load_csv_kw_15min():
    s = ld.read_load_csv(FIX / "load_15min.csv")
    assert list(s.index) == [T0 + pd.Timedelta(hours=h) for h in range(3)]
    assert list(s.round(9)) == [400.0, 2000.0, 300.0]  # kW means * 1000


def test_load_csv_bad_input(tmp_path):
    path = tmp_path / "l.csv"
    path.write_text("time,p_w\n2022-12-01T00:00:00+01:00,100\n2022-12-01T02:00:00+01:00,100\n"
                    "2022-12-01T03:00:00+01:00,100\n")
    with pytest.raises(ScenarioError, match="line 4, column 'time': irregular"):
        ld.read_load_csv(path)
    path.write_text("time,power\n2022-12-01T00:00:00+01:00,100\n")
    with pytest.raises(ScenarioError, match="unit unknown"):
        ld.read_load_csv(path)
    path.write_text("time,p_w\n2022-12-01T00:00:00+01:00,-5\n")
    with pytest.raises(ScenarioError, match=r"line 2, column 'p_w' \(read as W\): value -5 outside the plausible"):
        ld.read_load_csv(path)


def test_build_from_fixtures(tmp_path, params):
    frame, provenance = ld.build_scenario_frame(
        params,
        ("prices", ld.read_awattar_json(FIX / "awattar_3h.json")),
        ("tt", ld.read_dwd_temperature(FIX / "dwd_10min_tt_4177.txt")),
        ("sd", ld.read_dwd_solar(FIX / "dwd_10min_solar_4177.txt")),
        load=("load", ld.read_load_csv(FIX / "load_15min.csv")),
    )
    # common span: temperature and diffuse radiation end at hour 01 (hour 02 missing)
    assert list(frame.index) == [T0, T0 + pd.Timedelta(hours=1)]
    np.testing.assert_allclose(frame["t_amb_c"], [1.5, 2.4])
    np.testing.assert_allclose(frame["ghi_w_m2"], [100.0, 250.0])
    np.testing.assert_allclose(frame["dhi_w_m2"], [50.0, 100.0])
    np.testing.assert_allclose(frame["spot_eur_per_mwh"], [250.5, 230.0])
    np.testing.assert_allclose(frame["p_load_w"], [400.0, 2000.0])
    assert provenance["dhw_l_per_h"].startswith("default generator")
    assert provenance["p_load_w"] == "load"


def test_build_fills_short_gap_and_rejects_long(params):
    idx = pd.date_range(T0, periods=8, freq="h")
    prices = pd.Series(100.0, index=idx)
    solar = pd.DataFrame({"ghi_w_m2": 0.0, "dhi_w_m2": 0.0}, index=idx)
    temp = pd.Series([1.0, 2.0, np.nan, np.nan, 5.0, 6.0, 7.0, 8.0], index=idx)
    with pytest.warns(ScenarioWarning, match="t_amb_c"):
        frame, _ = ld.build_scenario_frame(params, ("p", prices), ("tt.txt", temp), ("s", solar))
    np.testing.assert_allclose(frame["t_amb_c"].iloc[2:4], [3.0, 4.0])
    temp[1:5] = np.nan
    with pytest.raises(ScenarioError, match=r"tt.txt: time 2022-12-01T02:00:00\+01:00 to .* 4 missing"):
        ld.build_scenario_frame(params, ("p", prices), ("tt.txt", temp), ("s", solar))


def test_data_build_command_writes_a_readable_csv(tmp_path, params, capsys):
    out = tmp_path / "built.csv"
    code = main([
        "data", "build",
        "--prices", str(FIX / "awattar_3h.json"),
        "--temperature", str(FIX / "dwd_10min_tt_4177.txt"),
        "--solar", str(FIX / "dwd_10min_solar_4177.txt"),
        "--load", str(FIX / "load_15min.csv"),
        "--out", str(out),
    ])
    assert code == 0
    printed = capsys.readouterr().out
    assert "dhw_l_per_h" in printed and "default generator" in printed
    assert out.read_text().splitlines()[1].startswith("2022-12-01T01:00:00+01:00,1.5,100,50,250.5,400,")
    s = load_scenario_csv(out, params)
    assert s.n_steps == 2 and s.t_amb_c[1] == pytest.approx(2.4)


def test_data_build_missing_file_exit_2(tmp_path, capsys):
    code = main(["data", "build", "--prices", str(tmp_path / "none.json"), "--temperature", "x", "--solar", "y",
                 "--out", str(tmp_path / "o.csv")])
    assert code == 2 and "none.json" in capsys.readouterr().err
