"""The on-disk cache of results of heavy libraries (pvlib, SciPy's expm, holidays): a hit is
bit-identical to the library, keys cover the inputs and parameters, a damaged file or an
unwritable directory never changes a result, and a process that builds a scenario (or a plant)
with a warm cache does not import pvlib (or SciPy, or holidays' calendars) at all."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core import result_cache
from comems4build_ros.core.models import pv
from comems4build_ros.core.scenario import generator
from comems4build_ros.core.scenario.settings import load_scenario_settings


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    d = tmp_path / "cache"
    monkeypatch.setenv(result_cache.CACHE_ENV, str(d))
    return d



def _week() -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray]:
    time = pd.date_range("2022-12-05", periods=168, freq="h", tz="Europe/Berlin")
    rng = np.random.default_rng(7)
    clear = np.clip(800.0 * np.sin(np.pi * ((time.hour.to_numpy() - 8) / 8.0)), 0.0, None)
    ghi = clear * rng.uniform(0.1, 1.0, len(time))
    return time, ghi, ghi * rng.uniform(0.3, 1.0, len(time))


def _pvlib_poa(time: pd.DatetimeIndex, ghi: np.ndarray, dhi: np.ndarray, params) -> np.ndarray:
    mid = time + pd.Timedelta(minutes=pv.MID_STEP_MINUTES)
    return pv._poa_from_horizontal_quiet(mid, ghi, dhi, params.pv, params.site)


def _files(d: Path) -> list[Path]:
    return sorted(d.glob("pvlib-*.npz")) if d.is_dir() else []


def test_poa_miss_then_hit_bit_identical_to_pvlib(cache: Path, params, monkeypatch: pytest.MonkeyPatch) -> None:
    time, ghi, dhi = _week()
    expected = _pvlib_poa(time, ghi, dhi, params)
    first = pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site)
    assert len(_files(cache)) == 1
    np.testing.assert_array_equal(first, expected)

    def no_pvlib(*_args, **_kwargs):
        raise AssertionError("pvlib called on a cache hit")

    monkeypatch.setattr(pv, "_poa_from_horizontal_quiet", no_pvlib)
    second = pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site)
    assert second.tobytes() == expected.tobytes()
    # another tilt, another irradiance value: a different key, so pvlib is called
    with pytest.raises(AssertionError, match="pvlib called"):
        pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv.model_copy(update={"tilt_deg": 10.0}), params.site)
    dhi2 = dhi.copy()
    dhi2[12] *= 0.5
    with pytest.raises(AssertionError, match="pvlib called"):
        pv.poa_irradiance_w_m2(time, ghi, dhi2, params.pv, params.site)


def test_damaged_file_is_computed_again(cache: Path, params) -> None:
    time, ghi, dhi = _week()
    expected = pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site)
    (path,) = _files(cache)
    path.write_bytes(path.read_bytes()[:100])  # cut short, as by a full disk
    again = pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site)
    np.testing.assert_array_equal(again, expected)
    assert result_cache.load("pvlib-poa", result_cache.key_of("x", {}, []), (168,)) is None
    # written anew: the next call reads a whole file
    with np.load(path) as data:
        np.testing.assert_array_equal(data["a0"], expected)


def test_off_and_unwritable_directory_change_nothing(tmp_path: Path, params, monkeypatch: pytest.MonkeyPatch) -> None:
    time, ghi, dhi = _week()
    expected = _pvlib_poa(time, ghi, dhi, params)
    monkeypatch.setenv(result_cache.CACHE_ENV, "off")
    assert result_cache.cache_dir() is None
    np.testing.assert_array_equal(pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site), expected)
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    monkeypatch.setenv(result_cache.CACHE_ENV, str(blocker / "cache"))
    np.testing.assert_array_equal(pv.poa_irradiance_w_m2(time, ghi, dhi, params.pv, params.site), expected)
    assert not result_cache.store("pvlib-poa", "0" * 64, [expected])


def test_default_directory_follows_xdg(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(result_cache.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert result_cache.cache_dir() == tmp_path / "comems4build_ros"


def test_modelled_radiation_hit_bit_identical(cache: Path, params, monkeypatch: pytest.MonkeyPatch) -> None:
    settings = load_scenario_settings()
    time = pd.date_range("2022-12-01", periods=24 * 14, freq="h", tz=params.site.timezone)
    local = time.normalize().tz_localize(None)
    day = (local - local[0]).days.to_numpy()
    kc = np.full(int(day.max()) + 1, 0.5)

    def radiation() -> tuple[np.ndarray, np.ndarray]:
        rng = generator._streams(11)["solar"]
        return generator._solar(rng, time, day, kc, settings, params.site)

    ghi, dhi = radiation()
    assert ghi.max() > 100.0 and len(_files(cache)) == 1
    rng = generator._streams(11)["solar"]  # the same draws, straight from pvlib
    kc_h = np.clip(kc[day] * (1.0 + generator._ar1(rng, len(time), settings.solar.hourly_phi,
                                                    settings.solar.hourly_sigma
                                                    * np.sqrt(1 - settings.solar.hourly_phi**2))),
                   0.02, settings.solar.kc_max)
    ref = generator._solar_pvlib(time + pd.Timedelta(minutes=30), kc_h, settings.solar.clearsky_model, params.site)
    np.testing.assert_array_equal(ghi, ref[0])
    np.testing.assert_array_equal(dhi, ref[1])
    monkeypatch.setattr(generator, "_solar_pvlib", lambda *a: (_ for _ in ()).throw(AssertionError("pvlib")))
    hit = radiation()
    assert hit[0].tobytes() == ghi.tobytes() and hit[1].tobytes() == dhi.tobytes()


def _cold_then_warm(code: str, cache: Path) -> tuple[list[str], list[str]]:
    """Words printed by ``code`` run twice in fresh processes with the cache directory ``cache``."""
    env = {**os.environ, result_cache.CACHE_ENV: str(cache)}
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
            for _ in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    return runs[0].stdout.split(), runs[1].stdout.split()


def test_warm_cache_scenario_without_pvlib(cache: Path) -> None:
    """A second process house the default scenario (as a feed node does) never imports pvlib."""
    code = ("import sys, warnings; warnings.simplefilter('ignore');"
            "from comems4build_ros.core.config import load_plant_params;"
            "from comems4build_ros.core.scenario.run import load_scenario;"
            "from comems4build_ros.core.loop import exogenous_series;"
            "p = load_plant_params(); s = load_scenario('default', p, None, 2, None, None);"
            "x = exogenous_series(s, p);"
            "print('pvlib' in sys.modules, repr(sum(e.p_pv_w for e in x)))")
    cold, warm = _cold_then_warm(code, cache)
    assert cold[0] == "True" and warm[0] == "False"
    assert cold[1] == warm[1] and float(cold[1]) > 0.0  # the same PV energy


def test_building_discretisation_hit_bit_identical_to_scipy(cache: Path, params,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """eq:state_update_bldgs: Ad and Bd from the cache equal SciPy's expm (rounded to
    building.EXPM_DIGITS significant digits) bit for bit."""
    from scipy.linalg import expm

    from comems4build_ros.core.models import building

    ad, bd = building.discretize(params.building, 1.0)
    a, bm = building.continuous(params.building)
    aug = np.zeros((6, 6))
    aug[:3, :3], aug[:3, 3:] = a, bm
    phi = expm(aug * 3600.0)
    np.testing.assert_allclose(phi[:3], np.hstack([ad, bd]), rtol=1e-11, atol=0.0)
    phi = np.vectorize(lambda v: float(f"{v:.{building.EXPM_DIGITS - 1}e}"))(phi)
    assert ad.tobytes() == phi[:3, :3].tobytes() and bd.tobytes() == phi[:3, 3:].tobytes()
    assert len(sorted(cache.glob("expm-*.npz"))) == 1
    monkeypatch.setattr(building, "_expm", lambda m: (_ for _ in ()).throw(AssertionError("expm")))
    hit = building.discretize(params.building, 1.0)
    assert hit[0].tobytes() == ad.tobytes() and hit[1].tobytes() == bd.tobytes()
    with pytest.raises(AssertionError, match="expm"):  # another time step: another key
        building.discretize(params.building, 0.5)


def test_holiday_calendar_found_once_is_remembered_and_an_unknown_one_always_refused(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from comems4build_ros.core import config

    config.check_holiday_calendar("DE", "BW")
    assert len(sorted(cache.glob("holidays-*.npz"))) == 1
    monkeypatch.setattr(config, "_check_holiday_calendar", lambda *a: (_ for _ in ()).throw(AssertionError("asked")))
    config.check_holiday_calendar("DE", "BW")  # remembered: the library is not asked
    with pytest.raises(AssertionError, match="asked"):
        config.check_holiday_calendar("DE", "BY")
    monkeypatch.undo()
    monkeypatch.setenv(result_cache.CACHE_ENV, str(cache))
    for _ in range(2):  # a refusal is never stored
        with pytest.raises(ValueError, match="holidays_subdivision 'ZZ' is not a subdivision of DE"):
            config.check_holiday_calendar("DE", "ZZ")
    assert len(sorted(cache.glob("holidays-*.npz"))) == 1


def test_warm_cache_plant_without_scipy_and_holiday_calendars(cache: Path) -> None:
    """A second process checking the plant parameters and house the plant (as plant_sim
    does) imports neither SciPy's linalg nor holidays' calendars."""
    code = ("import sys; from comems4build_ros.core.config import load_plant_params;"
            "from comems4build_ros.core.plant import Plant; Plant(load_plant_params());"
            "print('scipy.linalg' in sys.modules, 'holidays.countries' in sys.modules)")
    cold, warm = _cold_then_warm(code, cache)
    assert cold == ["True", "True"] and warm == ["False", "False"]


def test_holiday_dates_from_the_cache_equal_the_library(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The comfort calendar's public holidays (eq:T_min: holidays count as weekend days), read
    back from the cache, equal the holidays library's; another year is asked of the library."""
    import holidays

    from comems4build_ros.core.scenario import comfort

    expected = frozenset(holidays.country_holidays("DE", subdiv="BW", years=[2022, 2023]))
    comfort.holiday_dates.cache_clear()
    assert comfort.holiday_dates("DE", "BW", (2022, 2023)) == expected and len(expected) > 20
    assert len(sorted(cache.glob("holiday-dates-*.npz"))) == 1
    comfort.holiday_dates.cache_clear()

    def no_library(*_a, **_k):
        raise AssertionError("library asked")

    monkeypatch.setattr(holidays, "country_holidays", no_library)
    assert comfort.holiday_dates("DE", "BW", (2022, 2023)) == expected
    with pytest.raises(AssertionError, match="library asked"):
        comfort.holiday_dates("DE", "BW", (2024,))
    comfort.holiday_dates.cache_clear()
