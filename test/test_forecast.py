"""The MPC's forecasts: perfect = future values; imperfect = persistence and noisy weather."""

from __future__ import annotations

import numpy as np
import pytest

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.ems.base import FORECAST_KEYS
from comems4build_ros.core.loop import ForecastModel, load_forecast_settings


def series(n: int = 96) -> dict[str, list[float]]:
    k = np.arange(n + 24, dtype=float)
    return {key: (k + 100 * i).tolist() for i, key in enumerate(FORECAST_KEYS)}


def test_perfect_is_the_future() -> None:
    fm = ForecastModel(series(), load_forecast_settings(mode="perfect"), 24)
    w = fm.window(30)
    for i, key in enumerate(FORECAST_KEYS):
        assert w[key] == tuple(float(v + 100 * i) for v in range(30, 54))


def test_imperfect_persistence_and_noise() -> None:
    s = series()
    fm = ForecastModel(s, load_forecast_settings(mode="imperfect", seed=3), 24)
    w = fm.window(30)
    # lead 0 is measured: exact for every key
    for key in FORECAST_KEYS:
        assert w[key][0] == s[key][30]
    # persistence: lead i forecasts the value 24 h earlier (step 30 + i - 24)
    assert w["p_load_w"][5] == s["p_load_w"][11]
    assert w["dhw_l_per_h"][23] == s["dhw_l_per_h"][29]
    # prices and bounds stay exact
    assert w["price_buy_eur_per_kwh"] == tuple(s["price_buy_eur_per_kwh"][30:54])
    assert w["t_min_c"] == tuple(s["t_min_c"][30:54])
    # weather is perturbed, reproducibly
    assert w["t_amb_c"] != tuple(s["t_amb_c"][30:54])
    assert fm.window(30) == w
    ratio = np.asarray(w["p_pv_w"][1:]) / np.asarray(s["p_pv_w"][31:54])
    ghi_ratio = np.asarray(w["ghi_w_m2"][1:]) / np.asarray(s["ghi_w_m2"][31:54])
    assert np.allclose(ratio, ghi_ratio)  # one multiplicative factor for irradiance and PV
    assert (ratio >= 0).all()


def test_noise_grows_with_lead_time() -> None:
    s = series(2000)
    fm = ForecastModel(s, load_forecast_settings(mode="imperfect", sigma_t_amb_k_24h=1.5), 24)
    err = np.array([np.asarray(fm.window(k)["t_amb_c"]) - np.asarray(s["t_amb_c"][k : k + 24]) for k in range(1500)])
    sd = err.std(axis=0)
    assert sd[0] == 0.0
    assert sd[23] == pytest.approx(1.5 * np.sqrt(23 / 24), rel=0.1)
    assert sd[6] == pytest.approx(1.5 * np.sqrt(6 / 24), rel=0.12)


def test_bad_mode_is_named() -> None:
    with pytest.raises(ConfigError, match="forecast.yaml.*mode"):
        load_forecast_settings(mode="clairvoyant")
