"""Scenario CSV: round trip, windows and every bad-input case (file, line and column named)."""

import warnings

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.scenario import (
    ScenarioError,
    ScenarioWarning,
    default_scenario,
    load_scenario_csv,
    write_scenario_csv,
)

HOURS = 48



def rows(n: int = HOURS) -> pd.DataFrame:
    """A hand-made valid scenario table: values are simple functions of the row number."""
    time = pd.date_range("2022-12-01 00:00", periods=n, freq="h", tz="Europe/Berlin")
    i = np.arange(n, dtype=float) % 24  # daily pattern
    return pd.DataFrame(
        {
            "time": [t.isoformat() for t in time],
            "t_amb_c": 2.0 + 0.5 * i,
            "ghi_w_m2": 10.0 * i,
            "dhi_w_m2": 5.0 * i,
            "spot_eur_per_mwh": 100.0 + np.arange(n, dtype=float),
            "p_load_w": 400.0 + 10.0 * i,
            "dhw_l_per_h": 8.0,
            "comment": "ignored",
        }
    )


def write(tmp_path, df: pd.DataFrame, name: str = "s.csv"):
    path = tmp_path / name
    df.to_csv(path, index=False)
    return path


def test_round_trip_default(tmp_path, params):
    s = default_scenario(params)
    path = write_scenario_csv(s, tmp_path / "default.csv")
    r = load_scenario_csv(path, params)
    assert r.n_steps == s.n_steps and len(r.time) == len(s.time)
    assert (r.time == s.time).all()
    for name in ("t_amb_c", "ghi_w_m2", "dhi_w_m2", "spot_eur_per_mwh", "p_load_w", "dhw_l_per_h",
                 "price_buy_eur_per_kwh", "price_sell_eur_per_kwh", "t_min_c", "t_max_c"):
        np.testing.assert_allclose(getattr(r, name), getattr(s, name), rtol=1e-9, atol=1e-9, err_msg=name)


def test_hand_made_values_and_tariff(tmp_path, params):
    r = load_scenario_csv(write(tmp_path, rows()), params)
    assert r.n_steps == HOURS  # shorter than a week: all rows run
    assert r.time[0] == pd.Timestamp("2022-12-01 00:00", tz="Europe/Berlin")
    assert r.spot_eur_per_mwh[3] == 103.0
    # buy = a + b * spot / 1000 (plant.yaml grid): 103 EUR/MWh -> a + b * 0.103
    g = params.grid
    assert r.price_buy_eur_per_kwh[3] == pytest.approx(g.buy_offset_eur_per_kwh + g.buy_spot_factor * 0.103)
    assert r.t_min_c[7] == 21.0 and r.t_min_c[10] == 18.0  # Thursday 07:00 home, 10:00 away


def test_buy_price_column_overrides_tariff(tmp_path, params):
    df = rows()
    df["price_buy_eur_per_kwh"] = 0.40
    r = load_scenario_csv(write(tmp_path, df), params)
    assert (r.price_buy_eur_per_kwh == 0.40).all()


def test_utc_times_are_converted_to_site_time(tmp_path, params):
    df = rows()
    df["time"] = [pd.Timestamp(t).tz_convert("UTC").isoformat() for t in df["time"]]
    r = load_scenario_csv(write(tmp_path, df), params)
    assert r.time[0] == pd.Timestamp("2022-12-01 00:00", tz="Europe/Berlin")
    assert r.time[0].utcoffset() == pd.Timedelta(hours=1)


def test_weeks_and_start_window(tmp_path, params):
    df = rows(2 * 168 + 30)
    path = write(tmp_path, df)
    r = load_scenario_csv(path, params)
    assert r.n_steps == 336 and len(r.time) == 336 + 24  # whole weeks, rest is look-ahead
    r = load_scenario_csv(path, params, start="2022-12-02T00:00", weeks=1)
    assert r.n_steps == 168 and r.time[0] == pd.Timestamp("2022-12-02", tz="Europe/Berlin")
    assert r.spot_eur_per_mwh[0] == 124.0
    with pytest.raises(ScenarioError, match="3 week"):
        load_scenario_csv(path, params, weeks=3)
    with pytest.raises(ScenarioError, match="not an hour of the data"):
        load_scenario_csv(path, params, start="2023-05-01")


def expect_error(tmp_path, params, df, *fragments):
    path = write(tmp_path, df)
    with pytest.raises(ScenarioError) as exc:
        load_scenario_csv(path, params)
    msg = str(exc.value)
    assert str(path) in msg
    said = msg.replace(str(path), "")  # the test's own folder name must not answer for the message
    for fragment in fragments:
        assert fragment in said, msg
    return msg


def _set(col: str, index, value):
    """A change of rows(): ``col`` at ``index`` set to ``value`` (a function of the frame, or a value)."""
    def change(df: pd.DataFrame) -> pd.DataFrame:
        df = df.astype({col: object}) if isinstance(value, str) and col != "time" else df
        df.loc[index, col] = value(df) if callable(value) else value
        return df
    return change


#: (case, change of rows(), fragments the error names): every refusal names the file too.
BAD_CSV = [
    ("missing_column", lambda df: df.drop(columns="dhi_w_m2"), ("line 1", "dhi_w_m2")),
    # the row after the gap (originally row 12) is the 11th data row -> line 12
    ("gap_in_time", lambda df: df.drop(index=[10, 11]).reset_index(drop=True),
     ("line 12", "column 'time'", "gap", "2 rows missing")),
    ("duplicate_time", _set("time", 5, lambda df: df.loc[4, "time"]), ("line 7", "duplicate")),
    ("time_backwards", _set("time", 5, lambda df: df.loc[3, "time"]), ("line 7", "backwards")),
    ("time_without_offset", _set("time", 3, "2022-12-01T03:00:00"), ("line 5", "column 'time'", "UTC offset")),
    ("not_a_number", _set("t_amb_c", 9, "warm"), ("line 11", "column 't_amb_c'", "not a number")),
    ("long_nan_run", _set("spot_eur_per_mwh", slice(10, 13), np.nan),
     ("line 12 to line 15", "spot_eur_per_mwh", "4 missing values")),
    ("missing_first_row", _set("ghi_w_m2", 0, -999), ("line 2", "ghi_w_m2", "start or end")),
    ("spot_in_eur_per_kwh", _set("spot_eur_per_mwh", slice(None), lambda df: df["spot_eur_per_mwh"] / 1000.0),
     ("spot_eur_per_mwh", "EUR/kWh")),
    ("buy_price_in_eur_per_mwh", _set("price_buy_eur_per_kwh", slice(None), 390.0),
     ("line 2", "price_buy_eur_per_kwh", "outside")),
    ("temperature_in_kelvin", _set("t_amb_c", slice(None), lambda df: df["t_amb_c"] + 273.15),
     ("line 2", "t_amb_c", "Kelvin")),
    ("load_in_kw", _set("p_load_w", slice(None), lambda df: df["p_load_w"] / 1000.0), ("p_load_w", "kW")),
    ("negative_draw", _set("dhw_l_per_h", 4, -3.0), ("line 6", "dhw_l_per_h")),
    ("diffuse_above_global", _set("dhi_w_m2", 8, lambda df: df.loc[8, "ghi_w_m2"] + 50.0),
     ("line 10", "dhi_w_m2", "exceeds")),
]


@pytest.mark.parametrize(("change", "fragments"), [c[1:] for c in BAD_CSV], ids=[c[0] for c in BAD_CSV])
def test_bad_csv_is_refused_naming_file_line_and_column(tmp_path, params, change, fragments):
    expect_error(tmp_path, params, change(rows()), *fragments)


def test_short_nan_run_is_filled_with_warning(tmp_path, params):
    df = rows().astype({"t_amb_c": object})
    df.loc[[10, 11], "t_amb_c"] = ["NaN", ""]
    path = write(tmp_path, df)
    with pytest.warns(ScenarioWarning, match=r"column 't_amb_c'.*line 12 to line 13"):
        r = load_scenario_csv(path, params)
    # neighbours: row 9 -> 6.5, row 12 -> 8.0; linear: 7.0, 7.5 (= the original values)
    assert r.t_amb_c[10] == pytest.approx(7.0) and r.t_amb_c[11] == pytest.approx(7.5)


def test_minus_999_is_missing(tmp_path, params):
    df = rows()
    df.loc[20, "p_load_w"] = -999
    with pytest.warns(ScenarioWarning, match="line 22"):
        r = load_scenario_csv(write(tmp_path, df), params)
    assert r.p_load_w[20] == pytest.approx(600.0)  # (590 + 610) / 2


def test_small_negative_irradiance_clipped_with_warning(tmp_path, params):
    df = rows()
    df.loc[0, ["ghi_w_m2", "dhi_w_m2"]] = [-2.0, -1.0]
    with pytest.warns(ScenarioWarning, match="set to 0"):
        r = load_scenario_csv(write(tmp_path, df), params)
    assert r.ghi_w_m2[0] == 0.0 and r.dhi_w_m2[0] == 0.0


def test_clean_file_gives_no_warning(tmp_path, params):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_scenario_csv(write(tmp_path, rows()), params)


def test_cli_exit_code_2_on_bad_csv(tmp_path, capsys):
    from comems4build_ros.app.cli import main

    df = rows().drop(columns="p_load_w")
    path = write(tmp_path, df)
    code = main(["simulate", "--ems", "thermostat", "--scenario", str(path), "--out", str(tmp_path / "run")])
    assert code == 2
    assert "p_load_w" in capsys.readouterr().err
