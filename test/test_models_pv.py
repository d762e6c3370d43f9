"""PV model, eq:power_pv, and the pvlib plane-of-array irradiance."""

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import pv


def test_power_from_irradiance_hand_computed(params):
    # G = 800 W/m2, T_amb = 5 degC: T_cell = 5 + (50 - 20) / 800 * 800 = 35 degC,
    # derate = 1 - 0.005 * (35 - 25) = 0.95,
    # P = 30 * 1.685 m2 * 800 * 0.19 * 0.9 * 0.95 = 6569.478 W
    assert pv.power_from_irradiance_w(800.0, 5.0, params.pv) == pytest.approx(6569.478, rel=1e-12)


def test_power_from_irradiance_zero_and_vectorised(params):
    out = pv.power_from_irradiance_w([0.0, 400.0], [10.0, -10.0], params.pv)
    # G = 400, T_amb = -10: T_cell = -10 + 15 = 5, derate = 1 + 0.005 * 20 = 1.1
    assert out[0] == 0.0
    assert out[1] == pytest.approx(30 * 1.685 * 400 * 0.19 * 0.9 * 1.1, rel=1e-12)


def _one(ts):
    return pd.DatetimeIndex([pd.Timestamp(ts, tz="Europe/Berlin")])


def test_horizontal_plane_equals_ghi(params):
    # Tilt 0, isotropic sky: beam DNI cos(zenith) = GHI - DHI, sky diffuse = DHI, ground 0.
    flat = params.pv.model_copy(update={"tilt_deg": 0.0})
    g = pv.poa_irradiance_w_m2(_one("2022-12-21 12:00"), [300.0], [100.0], flat, params.site)
    assert g[0] == pytest.approx(300.0, rel=1e-9)


def test_north_facing_wall_sees_no_beam_in_winter(params):
    # Vertical, facing north at winter noon: beam 0, sky diffuse DHI (1 + cos 90)/2,
    # ground GHI * albedo * (1 - cos 90)/2 -> 0.5 * 100 + 0.5 * 0.2 * 300 = 80 W/m2.
    north = params.pv.model_copy(update={"tilt_deg": 90.0, "azimuth_deg": 0.0})
    g = pv.poa_irradiance_w_m2(_one("2022-12-21 12:00"), [300.0], [100.0], north, params.site)
    assert g[0] == pytest.approx(80.0, abs=1e-9)


def test_night_gives_zero_power(params):
    t = pd.date_range("2022-12-01 00:00", periods=3, freq="h", tz="Europe/Berlin")
    p = pv.pv_power_w(t, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], params.pv, params.site)
    assert np.all(p == 0.0)


def test_low_sun_does_not_blow_up(params):
    # 08:00-09:00 on 2022-12-21 in Karlsruhe: the sun rises about 08:20, so the middle of the
    # hour is just above the horizon; (GHI - DHI) / cos(zenith) would be huge.
    g = pv.poa_irradiance_w_m2(_one("2022-12-21 08:00"), [20.0], [5.0], params.pv, params.site)
    assert np.isfinite(g[0]) and 0.0 <= g[0] <= 3 * 20.0


def test_south_plane_gains_in_winter(params):
    # A 30 degree south-facing plane receives more than the horizontal at winter noon.
    g = pv.poa_irradiance_w_m2(_one("2022-12-21 12:00"), [300.0], [100.0], params.pv, params.site)
    assert g[0] > 300.0


@pytest.mark.parametrize(
    ("ghi", "dhi", "match"),
    [([np.nan], [0.0], "ghi_w_m2"), ([10.0], [-1.0], "dhi_w_m2"), ([10.0, 1.0], [1.0], "must match")],
)
def test_invalid_irradiance_raises(params, ghi, dhi, match):
    with pytest.raises(ValueError, match=match):
        pv.poa_irradiance_w_m2(_one("2022-12-21 12:00"), ghi, dhi, params.pv, params.site)


def test_naive_time_raises(params):
    with pytest.raises(ValueError, match="timezone-aware"):
        pv.poa_irradiance_w_m2(pd.DatetimeIndex(["2022-12-21 12:00"]), [1.0], [1.0], params.pv, params.site)


def test_nan_temperature_raises(params):
    with pytest.raises(ValueError, match="t_amb_c"):
        pv.pv_power_w(_one("2022-12-21 12:00"), [1.0], [1.0], [np.nan], params.pv, params.site)


def test_unknown_sky_model_rejected():
    from comems4build_ros.core.config import ConfigError

    with pytest.raises(ConfigError, match="pv.sky_model"):
        load_plant_params(overrides={"pv.sky_model": "nonsense"})
