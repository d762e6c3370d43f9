"""Identification of the MPC's 4R3C from a building's response, and the MPC's state observer."""

from __future__ import annotations

import numpy as np
import pytest

from comems4build_ros.core.ems.mpc.observer import KalmanObserver, wall_split
from comems4build_ros.core.models.building import RCBuilding
from comems4build_ros.core.types import Exogenous
from comems4build_ros.study import identify as ident


@pytest.fixture(scope="module")
def truth(params):
    """A 4R3C with internal gains (f_gains_air = 0.8) standing in for the detailed house."""
    return params.building.model_copy(update={"f_gains_air": 0.8, "g_s_m2": 2.5})


def _data(b, n: int, seed: int) -> ident.Data:
    """Hourly data of the model ``b`` under the excitation, with a winter-like weather and load."""
    rng = np.random.default_rng(seed)
    rc = RCBuilding(b, 1.0)
    heat = ident.excitation(seed)
    hours = np.arange(n)
    t_amb = 4.0 + 4.0 * np.sin(2 * np.pi * (hours - 9) / 24) + np.cumsum(rng.normal(0, 0.2, n))
    ghi = np.clip(300 * np.sin(np.pi * ((hours % 24) - 8) / 8), 0, None)
    load = 300 + 400 * rng.random(n)
    x = rc.initial_temperatures(21.0, float(t_amb[0]))
    rows = []
    for k in range(n):
        q = heat(x[0])
        x = rc.step(x, q, Exogenous(float(t_amb[k]), float(ghi[k]), 0.0, float(load[k]), 0.0, 0.3, 0.08, 21.0, 24.0))
        rows.append((q, t_amb[k], ghi[k], load[k], x[0]))
    a = np.asarray(rows)
    return ident.Data(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], 21.0)


def test_excitation_is_seeded_and_keeps_the_band():
    a, b = ident.excitation(5), ident.excitation(5)
    seq = [a(21.0) for _ in range(200)]
    assert seq == [b(21.0) for _ in range(200)]
    assert set(seq) <= {0.0, 1125.0, 2250.0, 3375.0, 4500.0} and len(set(seq)) >= 4
    assert a(ident.T_HIGH_C + 0.1) == 0.0 and a(ident.T_LOW_C - 0.1) == ident.Q_EXCITE_W


def test_rc_with_gains_equals_zoh_of_the_fit(truth):
    """The in-process 4R3C with f_gains_air and the fit's ZOH compute the same model."""
    ad, bd = ident.zoh(truth)
    rc = RCBuilding(truth, 1.0)
    assert np.allclose(ad, rc.Ad, rtol=1e-10) and np.allclose(bd, rc.Bd, rtol=1e-10)


def test_fit_recovers_a_known_model_to_millikelvin_predictions(params, truth):
    train, valid = _data(truth, 3 * 168, 1), _data(truth, 168, 2)
    b, info = ident.fit(train, params.building)
    assert info["fit_rmse_k"] < 0.02
    report = ident.rmse_report(ident.predictions_24h(b, valid))
    assert report["rmse_k"] < 0.05
    assert report["predictions"] == 168 - 2 * 24 + 1
    assert ident.heat_loss_coefficient(b) == pytest.approx(ident.heat_loss_coefficient(truth), rel=0.05)


def test_the_paper_model_with_no_gains_is_unchanged(params):
    """f_gains_air = 0 (the default): three inputs, the matrices the MPC and the plant always had."""
    rc = RCBuilding(params.building, 1.0)
    assert rc.Bd.shape == (3, 3)


def test_kalman_observer_finds_the_walls_from_the_air_temperature(truth):
    """From the steady profile's guess (errors of 1.2 and 2.3 K in the walls) to 0.01 K within a week."""
    rc = RCBuilding(truth, 1.0)
    obs = KalmanObserver(rc.Ad, rc.Bd, wall_split(truth))
    x = (21.0, 19.0, 8.0)
    exo = Exogenous(2.0, 0.0, 0.0, 400.0, 0.0, 0.3, 0.08, 21.0, 24.0)
    first = obs.update(x[0], exo.t_amb_c)
    assert np.abs(first - x)[1:].min() > 1.0
    for k in range(168):
        q = 2500.0 if k % 5 else 0.0
        obs.applied(q, exo.t_amb_c, exo.ghi_w_m2, exo.p_load_w)
        x = rc.step(x, q, exo)
        est = obs.update(x[0], exo.t_amb_c)
    assert np.allclose(est, x, atol=0.01)
