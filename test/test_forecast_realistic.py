"""``--forecast realistic``: prices as published, correlated weather errors, misplaced days.

The price mask is checked as a property over start times (any hour, across the DST
changes), publication times and issuing steps; the weather errors against the moments their
AR(1) models imply on long seeded samples; the misplaced days against their configured rate;
and the forecasts as a pure function of the scenario and the absolute time, which is what
lets the ROS feed node (it builds the same ObservationBuilder) hand the MPC the in-process
forecasts.
"""

from __future__ import annotations

from datetime import datetime

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.ems.base import FORECAST_KEYS, PRICE_WINDOW
from comems4build_ros.core.forecast import (
    RealisticForecast,
    RealisticParams,
    miss_days,
    published_until,
    t_amb_error_moments,
)
from comems4build_ros.core.loop import ForecastModel, load_forecast_settings

TZ = "Europe/Berlin"


def bounded(n: int) -> settings:
    """Reproducible, bounded property tests."""
    return settings(max_examples=n, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def realistic(**changes) -> RealisticParams:
    """The shipped ``realistic`` settings with ``changes``."""
    return load_forecast_settings(mode="realistic").realistic.model_copy(update=changes)


def make_series(n: int, rng: np.random.Generator | None = None) -> dict[str, list[float]]:
    """Series of ``n`` steps; every price unique (its step index), so a forecast price names its source."""
    rng = rng or np.random.default_rng(0)
    hour = np.arange(n) % 24
    sun = np.clip(np.sin((hour - 6) / 12 * np.pi), 0, None)
    clear = rng.uniform(0.1, 1.0, n // 24 + 1).repeat(24)[:n]
    ghi = 400.0 * sun * clear
    return {
        "t_amb_c": (5 + 3 * np.sin(hour / 24 * 2 * np.pi)).tolist(),
        "ghi_w_m2": ghi.tolist(),
        "p_pv_w": (8.0 * ghi).tolist(),
        "p_load_w": (300 + 10 * hour).tolist(),
        "dhw_l_per_h": (hour % 5).astype(float).tolist(),
        "t_min_c": [20.0] * n,
        "t_max_c": [24.0] * n,
        "price_buy_eur_per_kwh": np.arange(n, dtype=float).tolist(),
    }


def make_model(start: str | pd.Timestamp, days: int, params: RealisticParams | None = None, seed: int = 7,
               tz: str = TZ) -> tuple[RealisticForecast, dict[str, list[float]]]:
    """Hourly steps from ``start`` (local time of ``tz``, or an aware time converted to it)."""
    t0 = pd.Timestamp(start)
    t0 = t0.tz_convert(tz) if t0.tzinfo is not None else t0.tz_localize(tz)
    times = pd.date_range(t0, periods=days * 24, freq="h")
    series = make_series(len(times) + PRICE_WINDOW)
    return RealisticForecast(series, params or realistic(), seed, times, 24, PRICE_WINDOW), series


# --- prices as published -------------------------------------------------------------------------------

def test_before_publication_the_next_day_is_forecast_and_from_1300_it_is_known() -> None:
    model, series = make_model("2022-12-05 00:00", 14)  # a Monday
    true = np.asarray(series["price_buy_eur_per_kwh"])
    k = 24 * 2 + 12  # Wednesday 12:00, before the 12:55 publication
    w = np.asarray(model.window(k)["price_buy_eur_per_kwh"])
    assert (w[:12] == true[k : k + 12]).all()  # Wednesday 12:00-23:00: published on Tuesday
    # Thursday 00:00-11:00 not yet published: naive forecast = Wednesday's same hour
    assert (w[12:] == true[k + 12 - 24 : k + 24 - 24]).all()
    assert not (w[12:] == true[k + 12 : k + 24]).any()
    k13 = k + 1  # Wednesday 13:00: Thursday's prices are out
    assert (np.asarray(model.window(k13)["price_buy_eur_per_kwh"]) == true[k13 : k13 + 24]).all()


def test_naive_forecast_takes_last_week_for_saturday_to_monday() -> None:
    model, series = make_model("2022-12-05 00:00", 21)  # Monday 2022-12-05
    true = np.asarray(series["price_buy_eur_per_kwh"])
    for day, weekly in ((12, True), (13, True), (14, True), (8, False), (11, False)):  # Sat, Sun, Mon; Tue, Fri
        k = 24 * (day - 1) + 6  # the day before at 06:00: the target day's 00:00-05:00 are forecast
        w = np.asarray(model.window(k)["price_buy_eur_per_kwh"])
        target = np.arange(24 * day, 24 * day + 6)
        src = target - (7 * 24 if weekly else 24)
        assert (w[18:] == true[src]).all(), day


@bounded(60)
@given(start=st.datetimes(min_value=pd.Timestamp("2015-01-01").to_pydatetime(),
                          max_value=pd.Timestamp("2030-12-31").to_pydatetime()),
       hh=st.integers(0, 23), mm=st.integers(0, 59), k=st.integers(0, 24 * 9 - 1),
       tz=st.sampled_from(["Europe/Berlin", "UTC", "America/New_York"]),
       method=st.sampled_from(["naive", "previous_day", "previous_week"]))
@example(start=datetime(2023, 3, 25, 11), hh=12, mm=55, k=14, tz="Europe/Berlin", method="naive")  # spring DST
@example(start=datetime(2022, 10, 29, 11), hh=12, mm=55, k=14, tz="Europe/Berlin", method="naive")  # autumn DST
@example(start=datetime(2022, 10, 29, 11), hh=0, mm=0, k=37, tz="UTC", method="previous_week")
def test_no_price_after_the_cutoff_is_the_true_one_unless_published(start, hh, mm, k, tz, method) -> None:
    """Any start (any hour, also in the days of the DST changes), publication time, market zone and step."""
    start = pd.Timestamp(start).floor("h").tz_localize("UTC")  # an instant: no local time is skipped or doubled
    params = realistic(price_publication_time=f"{hh:02d}:{mm:02d}", price_market_timezone=tz,
                       price_forecast=method)
    model, series = make_model(start, 10, params, tz="Europe/Berlin")
    true = np.asarray(series["price_buy_eur_per_kwh"])
    w = np.asarray(model.window(k)["price_buy_eur_per_kwh"])
    known = int(model.known_until[k])
    # what the market's clock says is published at the step's start
    wall = model.times.tz_convert(tz).tz_localize(None)
    t = wall[k]
    pub = t.normalize() + pd.Timedelta(hours=hh, minutes=mm)
    end = t.normalize() + pd.Timedelta(days=2 if t >= pub else 1)
    assert known > k
    assert (wall[k:known] < end).all() and (known >= len(wall) or wall[known] >= end)
    for i, value in enumerate(w):
        if k + i < known:
            assert value == true[k + i]
        else:  # a forecast made of published prices only (values are step indices)
            assert value != true[k + i] and int(value) < known


@pytest.mark.parametrize("day", ["2023-03-26", "2022-10-30"])
def test_published_until_at_the_clock_change(day: str) -> None:
    """Days of 23 and 25 hours in Berlin: the next day's prices still come at 12:55 wall time."""
    times = pd.date_range(pd.Timestamp(day, tz=TZ) - pd.Timedelta(days=1), periods=96, freq="h")
    known = published_until(times, "12:55", TZ)
    wall = list(times.tz_localize(None))
    d = pd.Timestamp(day)
    k12, k13 = wall.index(d + pd.Timedelta(hours=12)), wall.index(d + pd.Timedelta(hours=13))
    assert wall[known[k12]] == d + pd.Timedelta(days=1)
    assert wall[known[k13]] == d + pd.Timedelta(days=2)


# --- weather errors ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("phi,s1,s,m1", [(0.93, 1.2, 0.6, 0.15), (0.5, 0.3, 1.0, 0.0), (0.0, 2.0, 0.8, -0.5)])
def test_temperature_error_matches_its_ar1(phi: float, s1: float, s: float, m1: float) -> None:
    params = realistic(t_amb_phi=phi, t_amb_sd_lead1_k=s1, t_amb_sd_innovation_k=s, t_amb_mean_lead1_k=m1)
    model, _ = make_model("2022-12-01 00:00", 200, params)
    err = np.array([model.t_amb_error(k) for k in range(4000)])
    mean, sd = t_amb_error_moments(params, PRICE_WINDOW)
    assert (err[:, 0] == 0).all()  # lead 0 is measured
    rmse = np.sqrt(np.mean(err**2, axis=0))
    expect = np.sqrt(mean**2 + sd**2)
    assert rmse[1:] == pytest.approx(expect[1:], rel=0.06)
    for lead in (1, 12, 22):  # lag-1 correlation over lead hours: phi * sd_l / sd_(l+1)
        r = np.corrcoef(err[:, lead], err[:, lead + 1])[0, 1]
        assert r == pytest.approx(phi * sd[lead] / sd[lead + 1], abs=0.05)


@pytest.mark.parametrize("sd,phi", [(0.14, 0.63), (0.3, 0.9), (0.05, 0.0)])
def test_irradiance_error_matches_its_ar1(sd: float, phi: float) -> None:
    model, _ = make_model("2022-12-01 00:00", 200, realistic(ghi_sd_rel=sd, ghi_phi=phi))
    err = np.array([model.ghi_error(k) for k in range(4000)])
    assert (err[:, 0] == 0).all()
    assert np.std(err[:, 1:], axis=0) == pytest.approx(np.full(PRICE_WINDOW - 1, sd), rel=0.07)
    r = np.corrcoef(err[:, 1:-1].ravel(), err[:, 2:].ravel())[0, 1]
    assert r == pytest.approx(phi, abs=0.04)


def test_the_night_stays_dark_and_pv_follows_irradiance() -> None:
    model, series = make_model("2022-12-01 00:00", 30, realistic(ghi_sd_rel=0.5))
    ghi, pv = np.asarray(series["ghi_w_m2"]), np.asarray(series["p_pv_w"])
    for k in range(0, 30 * 24 - 24, 7):
        w = model.window(k)
        f_ghi, f_pv = np.asarray(w["ghi_w_m2"]), np.asarray(w["p_pv_w"])
        night = ghi[k : k + 24] == 0
        assert (f_ghi[night] == 0).all() and (f_ghi >= 0).all()
        assert f_ghi[0] == ghi[k] and f_pv[0] == pv[k]
        assert f_pv == pytest.approx(8.0 * f_ghi)  # one factor for both, on the same (true or other) day


@pytest.mark.parametrize("p,window", [(0.1, 7), (0.5, 1), (0.02, 30)])
def test_misplaced_days_happen_at_the_configured_rate(p: float, window: int) -> None:
    params = realistic(ghi_miss_probability=p, ghi_miss_window_days=window)
    days = list(range(730_000, 736_000))
    missed = miss_days(days, params, seed=11)
    n = len(days)
    assert abs(len(missed) - p * n) < 4 * np.sqrt(n * p * (1 - p))
    assert all(1 <= abs(o - d) <= window for d, o in missed.items())
    # a day's miss does not depend on which other days the run holds (away from the edges)
    part = miss_days(days[1000:2000], params, seed=11)
    inner = range(days[1000] + window, days[2000] - window)
    assert {d: o for d, o in part.items() if d in inner} == {d: o for d, o in missed.items() if d in inner}


def test_a_missed_day_is_forecast_with_the_other_days_sun() -> None:
    model, series = make_model("2022-12-01 00:00", 60, realistic(ghi_miss_probability=0.5, ghi_sd_rel=0.0))
    ghi = np.asarray(series["ghi_w_m2"])
    assert model.missed
    first = model.day_of_step[0]
    for d, other in model.missed.items():
        i = d - first
        if not 1 <= i < 59:
            continue
        k = 24 * i - 1  # 23:00 the day before: leads 1..23 are the missed day's 00:00-22:00
        f = np.asarray(model.window(k)["ghi_w_m2"])[1:]
        assert f == pytest.approx(ghi[24 * (other - first) : 24 * (other - first) + 23])


# --- reproducible, the same in-process and over ROS ---------------------------------------------------------

def test_forecasts_depend_on_the_absolute_time_only() -> None:
    """Neither the call order, nor the instance, nor the run's start or length change a forecast."""
    a, sa = make_model("2022-12-01 00:00", 40)
    b, _ = make_model("2022-12-01 00:00", 40)
    ks = [500, 3, 250, 3]
    assert [a.window(k) for k in ks] == [b.window(k) for k in reversed(ks)][::-1]
    c, sc = make_model("2022-12-03 00:00", 30)  # starts two days later (same scenario values shifted)
    shift = 48
    sc_shifted = {key: sa[key][shift : shift + len(sc[key])] for key in sa}
    c = RealisticForecast(sc_shifted, realistic(), 7, c.times, 24, PRICE_WINDOW)
    for k in (200, 333, 480):
        wa, wc = a.window(k + shift), c.window(k)
        for key in ("t_amb_c", "ghi_w_m2", "p_pv_w", "price_buy_eur_per_kwh"):
            assert wa[key] == wc[key], key


def test_forecast_model_dispatches_and_needs_times() -> None:
    fs = load_forecast_settings(mode="realistic")
    series = make_series(24 * 5)
    with pytest.raises(ValueError, match="realistic.*times"):
        ForecastModel(series, fs, 24)
    times = pd.date_range(pd.Timestamp("2022-12-01", tz=TZ), periods=24 * 4, freq="h")
    fm = ForecastModel(series, fs, 24, times)
    w = fm.window(30)
    assert set(w) == set(FORECAST_KEYS) and all(len(v) == PRICE_WINDOW for v in w.values())
    assert w["t_min_c"] == tuple(series["t_min_c"][30:54])


@pytest.mark.parametrize("field,value,match", [
    ("price_publication_time", "13:60", "price_publication_time"),
    ("price_forecast", "oracle", "price_forecast"),
    ("ghi_miss_probability", 1.5, "ghi_miss_probability"),
    ("t_amb_phi", 1.0, "t_amb_phi"),
])
def test_bad_settings_are_named(field: str, value, match: str) -> None:
    raw = load_forecast_settings(mode="realistic").realistic.model_dump()
    raw[field] = value
    with pytest.raises(ConfigError, match=f"forecast.yaml.*{match}"):
        load_forecast_settings(mode="realistic", realistic=raw)


@pytest.mark.parametrize("zone", ["Mars/Olympus", "Europe/Karlsruhe", "../etc/passwd"])
def test_unknown_market_timezone_is_named(zone: str) -> None:
    raw = load_forecast_settings(mode="realistic").realistic.model_dump()
    raw["price_market_timezone"] = zone
    with pytest.raises(ConfigError, match="forecast.yaml.*price_market_timezone"):
        load_forecast_settings(mode="realistic", realistic=raw)


def test_shipped_settings_give_their_documented_skill_on_the_paper_winter() -> None:
    """config/forecast.yaml: the GHI forecast's skill against day-ahead persistence is 0.5 on the
    paper's winter (Perez et al. 2013), the temperature RMSE what its AR(1) implies."""
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import ObservationBuilder, exogenous_series
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_plant_params()
    scenario = resolve_scenario("default", params)
    fs = load_forecast_settings(mode="realistic")
    builder = ObservationBuilder(scenario, params, "mpc", exogenous_series(scenario, params), fs)
    stats = builder.forecast_errors(scenario.n_steps)
    assert stats["ghi_skill_vs_persistence"] == pytest.approx(0.5, abs=0.02)
    mean, sd = t_amb_error_moments(fs.realistic, PRICE_WINDOW)
    assert stats["t_amb_rmse_k_lead_last"] == pytest.approx(float(np.hypot(mean[-1], sd[-1])), rel=0.1)
    assert 0.1 < stats["price_unpublished_share"] < 0.2  # at most 11-12 of 23 leads, before 13:00 only
