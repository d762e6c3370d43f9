"""The embedded default scenario: the paper's winter from the shipped measured data."""

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core import scenario as sc
from comems4build_ros.core.scenario import measured as ms
from comems4build_ros.core.scenario.loaders import read_dwd_temperature

HOURS = 12 * 168



@pytest.fixture(scope="module")
def default(params):
    return sc.default_scenario(params)


@pytest.fixture(scope="module")
def settings():
    return sc.load_measured_settings()


def test_shape_and_time(default):
    assert default.name == "default"
    assert default.n_steps == HOURS and len(default.time) == HOURS + 24
    assert default.time[0] == pd.Timestamp("2022-12-01 00:00", tz="Europe/Berlin")
    assert default.time[-1] == pd.Timestamp("2023-02-23 23:00", tz="Europe/Berlin")
    for name in sc.SERIES:
        assert np.isfinite(getattr(default, name)).all(), name


def test_prices_are_the_measured_ones(default, settings):
    raw = ms.read_entsoe_prices(ms.data_dir() / settings.prices_file, settings.prices_column)
    # first value: 2022-12-01 00:00 local = 2022-11-30 23:00 UTC, 292.06 EUR/MWh in the file
    assert default.spot_eur_per_mwh[0] == 292.06
    np.testing.assert_array_equal(default.spot_eur_per_mwh, raw.to_numpy()[: len(default.time)])
    # ENTSO-E DE-LU, first 12 weeks: mean 170 EUR/MWh, min -5, 43 negative hours in Dec-Feb
    assert default.spot_eur_per_mwh[:HOURS].mean() == pytest.approx(170.02, abs=0.01)


def test_tariff_is_affine_in_spot(params, default):
    g = params.grid
    np.testing.assert_allclose(
        default.price_buy_eur_per_kwh, g.buy_offset_eur_per_kwh + g.buy_spot_factor * default.spot_eur_per_mwh / 1000
    )
    assert (default.price_sell_eur_per_kwh == 0.0794).all()


def test_temperature_measured_then_filled_and_flagged(default, settings):
    raw = read_dwd_temperature(ms.data_dir() / settings.temperature.file)
    utc = default.time.tz_convert("UTC")
    fill = default.meta["t_amb_filled"]
    assert fill["method"] == settings.temperature.fill
    first_filled = pd.Timestamp("2023-02-15 00:00", tz="UTC")
    assert pd.Timestamp(fill["from"]) == first_filled
    measured = utc < first_filled
    np.testing.assert_array_equal(default.t_amb_c[measured], raw.reindex(utc[measured]).to_numpy())
    # filled: 2023-02-15 00:00 to 2023-02-23 22:00 UTC
    assert ms.filled_mask(default.time, default.meta).sum() == (~measured).sum() == 8 * 24 + 23
    # DWD Rheinstetten 2022-12-01..2023-02-14: minimum -12.2 degC, mean 4.2 degC
    assert default.t_amb_c[measured].min() == -12.2


@pytest.mark.parametrize("method", ["repeat", "synthetic"])
def test_fill_methods_by_hand(method):
    t = np.r_[np.arange(48.0), [np.nan] * 30]
    synthetic = np.arange(78.0) * 2 if method == "synthetic" else None
    out = ms.fill_temperature(t, 48, method, 1, 0, synthetic=synthetic)
    if method == "repeat":
        # the last measured day (24..47) repeated in order, no seam offset (seam_h = 0)
        np.testing.assert_array_equal(out[48:72], np.arange(24.0, 48.0))
        np.testing.assert_array_equal(out[72:78], np.arange(24.0, 30.0))
    else:
        # generated values shifted by mean(measured last day) - mean(generated last day) = 35.5 - 71
        np.testing.assert_allclose(out[48:], np.arange(48.0, 78.0) * 2 + (35.5 - 71.0))
    np.testing.assert_array_equal(out[:48], np.arange(48.0))


def test_repeat_fill_closes_the_seam():
    t = np.r_[np.zeros(24), np.full(24, 5.0), [np.nan] * 48]
    t[47] = 8.0  # last measured value
    out = ms.fill_temperature(t, 48, "repeat", 1, 24)
    # first filled hour: repeats t[24] = 5, plus the seam offset (8 - t[23] = 8) * 24/25
    assert out[48] == pytest.approx(5.0 + 8.0 * 24 / 25)
    assert out[48 + 24] == 5.0  # offset gone after 24 h


def test_synthetic_fill_differs_only_in_the_filled_hours(params, default):
    other = sc.default_scenario(params, fill="synthetic")
    mask = ms.filled_mask(default.time, default.meta)
    np.testing.assert_array_equal(other.t_amb_c[~mask], default.t_amb_c[~mask])
    assert not np.allclose(other.t_amb_c[mask], default.t_amb_c[mask])
    assert other.meta["t_amb_filled"]["method"] == "synthetic"


def test_dhwcalc_weekday_alignment():
    # The shipped DHWcalc year starts on a Monday. 2022-12-01 (Thursday, day 335) takes file
    # day 333 (a Thursday in the file); 2023-01-01 (Sunday, day 1) takes file day 7, 2023-01-02 (Monday) file day 1.
    days = pd.DatetimeIndex(["2022-12-01", "2022-12-31", "2023-01-01", "2023-01-02"])
    np.testing.assert_array_equal(ms.dhwcalc_day_of_year(days, 0), [333, 363, 7, 1])
    file_weekday = (ms.dhwcalc_day_of_year(days, 0) - 1) % 7
    np.testing.assert_array_equal(file_weekday, days.day_of_week)


def test_dhw_weekend_pattern_on_weekends(params, default):
    """Weekend draws (DHWcalc: 120 % of weekdays) fall on Saturdays and Sundays."""
    n = HOURS
    local = default.time[:n]
    daily = pd.Series(default.dhw_l_per_h[:n]).groupby(np.asarray(local.normalize().tz_localize(None))).sum()
    weekend = daily.index.day_of_week >= 5
    assert daily[weekend].mean() > 1.1 * daily[~weekend].mean()
    assert 180 < daily.mean() < 220  # 200 l/day file mean


def test_radiation_and_load_are_seeded(params, default):
    again = sc.default_scenario(params)
    np.testing.assert_array_equal(again.ghi_w_m2, default.ghi_w_m2)
    other = sc.default_scenario(params, seed=1)
    assert not np.allclose(other.ghi_w_m2, default.ghi_w_m2)
    assert not np.allclose(other.p_load_w, default.p_load_w)
    np.testing.assert_array_equal(other.spot_eur_per_mwh, default.spot_eur_per_mwh)
    np.testing.assert_array_equal(other.t_amb_c, default.t_amb_c)


def test_rank_matching_keeps_values_and_follows_the_key():
    values = np.array([0.1, 0.5, 0.3])
    key = np.array([10.0, 1.0, 5.0])
    np.testing.assert_array_equal(ms.rank_matched(values, key), [0.5, 0.1, 0.3])


def test_short_run_is_the_start_of_the_full_one(params, default):
    short = sc.default_scenario(params, weeks=2)
    n = len(short.time)
    for name in sc.SERIES:
        np.testing.assert_array_equal(getattr(short, name), getattr(default, name)[:n])


def test_longer_than_the_data_is_refused(params):
    # prices cover 2160 h from the start: 12.71 weeks with the 24 h look-ahead
    with pytest.raises(sc.ScenarioError, match="measured data cover 2160 hours"):
        sc.default_scenario(params, weeks=13)


def test_resolve_default_and_synthetic(params, default):
    assert sc.resolve_scenario("default", params, weeks=1).name == "default"
    assert sc.resolve_scenario("synthetic", params, weeks=1).name == "synthetic"
    w = sc.resolve_scenario("default", params, start="2022-12-10", weeks=2)
    k = 9 * 24
    np.testing.assert_array_equal(w.spot_eur_per_mwh, default.spot_eur_per_mwh[k : k + 360])
