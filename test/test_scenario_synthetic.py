"""The synthetic scenario generator: shape, determinism, tariff, comfort and calibration to the reference statistics."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core import scenario as sc
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.scenario import stats as st
from comems4build_ros.core.scenario.generator import dynamisation_factor, opendhw_offday_mass_ratio

DOCS = Path(__file__).resolve().parents[1] / "docs" / "scenario.md"



@pytest.fixture(scope="module")
def default(params):
    """The synthetic scenario with the configured seed (named after the fixture of the measured tests)."""
    return sc.synthetic_scenario(params)


@pytest.fixture(scope="module")
def stats(params, default):
    settings = sc.load_scenario_settings()
    return st.scenario_stats(default, sc.is_off_day(default.time, params.comfort), settings.load.dynamisation_coef)


def test_shape_and_time(default):
    assert default.n_steps == 12 * 168
    assert len(default.time) == 12 * 168 + 24
    assert default.time[0] == pd.Timestamp("2022-12-01 00:00", tz="Europe/Berlin")
    assert str(default.time.tz) == "Europe/Berlin"
    assert (np.diff(default.time.as_unit("s").asi8) == 3600).all()
    for name in sc.SERIES:
        assert np.isfinite(getattr(default, name)).all(), name


def test_tariff_and_comfort(params, default):
    g = params.grid
    expected_buy = g.buy_offset_eur_per_kwh + g.buy_spot_factor * default.spot_eur_per_mwh / 1000.0
    np.testing.assert_allclose(default.price_buy_eur_per_kwh, expected_buy)
    assert (default.price_sell_eur_per_kwh == 0.0794).all()
    t_min, t_max = sc.comfort_bounds(default.time, params.comfort)
    np.testing.assert_array_equal(default.t_min_c, t_min)
    np.testing.assert_array_equal(default.t_max_c, t_max)


def test_physical_ranges(default):
    assert (default.ghi_w_m2 >= 0).all() and (default.dhi_w_m2 >= 0).all()
    assert (default.dhi_w_m2 <= default.ghi_w_m2 + 1e-9).all()
    night = (default.time.hour < 6) | (default.time.hour >= 18)  # winter: no sun before 07 or after 17
    assert (default.ghi_w_m2[night] == 0).all()
    assert default.ghi_w_m2.max() < 600  # winter noon clear-sky at 49 N stays well below 600 W/m2
    assert (default.p_load_w > 0).all() and (default.dhw_l_per_h >= 0).all()


def test_deterministic_same_seed(params, default):
    sc._CACHE.clear()
    again = sc.synthetic_scenario(params)
    for name in sc.SERIES:
        np.testing.assert_array_equal(getattr(again, name), getattr(default, name))


def test_other_seed_differs_and_cache_returns_copies(params, default):
    other = sc.synthetic_scenario(params, weeks=2, seed=1)
    assert other.n_steps == 336 and len(other.time) == 360
    assert not np.allclose(other.spot_eur_per_mwh[:336], default.spot_eur_per_mwh[:336])
    first = sc.synthetic_scenario(params, weeks=2, seed=1)
    first.t_amb_c[:] = 99.0
    assert sc.synthetic_scenario(params, weeks=2, seed=1).t_amb_c[0] != 99.0


def test_resolve_default_window(params, default):
    w = sc.resolve_scenario("synthetic", params, start="2022-12-10", weeks=2)
    assert w.time[0] == pd.Timestamp("2022-12-10", tz="Europe/Berlin")
    assert w.n_steps == 336 and len(w.time) == 360
    k = 9 * 24
    np.testing.assert_array_equal(w.spot_eur_per_mwh, default.spot_eur_per_mwh[k : k + 360])
    with pytest.raises(sc.ScenarioError, match="only"):
        sc.resolve_scenario("synthetic", params, start="2023-02-01", weeks=4)


def test_resolve_missing_file(params):
    with pytest.raises(sc.ScenarioError, match="no such file"):
        sc.resolve_scenario("/nonexistent/scenario.csv", params)


# Acceptance bands around the reference figures (tol of each statistic in stats.STATS).
BANDED = [s for s in st.STATS if s.tol is not None]


@pytest.mark.parametrize("stat", BANDED, ids=[s.key for s in BANDED])
def test_statistics_within_reference_bands(stats, stat):
    assert abs(stats[stat.key] - stat.ref) <= stat.tol, f"{stat.label}: {stats[stat.key]:.3g} vs {stat.ref}"


def test_qualitative_facts(stats):
    assert stats["spot_workday"] > stats["spot_offday"]
    assert stats["spot_dec"] > stats["spot_feb"] and stats["spot_dec"] > stats["spot_jan"]
    assert stats["t_cold_spell_max"] < 0.0  # DWD: daily means below 0 in the cold spell
    assert stats["t_new_year_max"] > 10.0  # mild around New Year
    assert 6 <= stats["load_morning_peak_h"] <= 9 and 17 <= stats["load_evening_peak_h"] <= 21
    assert stats["diffuse_share"] > 0.5  # overcast winter


def test_dynamisation_factor_hand_values():
    coef = sc.load_scenario_settings().load.dynamisation_coef
    # F(1) = 1.24 + 2.1e-3 - 7.02e-5 + 3.2e-7 - 3.916e-10
    assert dynamisation_factor(np.array([1]), coef)[0] == pytest.approx(1.2420301196084, rel=1e-12)


def test_opendhw_weekend_factor_correction():
    # OpenDHW's own off-day base profile has 2.545 / 2.09 the mass of the workday profile (SFH, 1 h)
    assert opendhw_offday_mass_ratio(3600) == pytest.approx(2.545 / 2.09, rel=1e-9)


def test_docs_table_matches_the_scenarios(params, stats):
    text = DOCS.read_text(encoding="utf-8")
    m = re.search(r"<!-- stats:begin -->\n(.*?)\n<!-- stats:end -->", text, re.S)
    assert m, f"{DOCS.name} lacks the stats markers"
    assert m.group(1).strip() == st.markdown_table(st.default_stats(params), stats).strip()


def test_fractional_weeks(params):
    two_days = sc.synthetic_scenario(params, weeks=2 / 7)
    assert two_days.n_steps == 48 and len(two_days.time) == 72
    with pytest.raises(sc.ScenarioError, match="whole number"):
        sc.synthetic_scenario(params, weeks=0.3)  # 50.4 h
    w = sc.resolve_scenario("synthetic", params, start="2022-12-05T06:00", weeks=0.5)
    assert w.n_steps == 84 and w.time[0].hour == 6


def test_short_synthetic_run_is_the_start_of_the_full_scenario() -> None:
    """--weeks cuts the synthetic scenario; it does not generate a different one."""
    params = load_plant_params()
    full = sc.synthetic_scenario(params, weeks=12)
    short = sc.synthetic_scenario(params, weeks=1)
    assert short.n_steps == 168
    n = len(short.time)
    assert (short.time == full.time[:n]).all()
    for name in sc.SERIES:
        np.testing.assert_array_equal(getattr(short, name), getattr(full, name)[:n])
