"""Identification of the MPC's 4R3C from a building's response, and the MPC's state observer."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# ---------------------------------------------------------------- physical bounds of the fit

def test_bounds_come_from_the_house():
    """H within 20 % of the typology's, capacities from the constructions' layers, shares in their ranges."""
    import dataclasses

    from comems4build_ros.core.models import house_idf as house

    spec = house.HouseSpec()
    b = {x.name: x for x in ident.physical_bounds(spec)}
    h = house.heat_loss_coefficient(spec)["h_w_per_k"]
    assert (b["h_w_per_k"].lo, b["h_w_per_k"].hi) == pytest.approx((0.8 * h, 1.2 * h))
    cap = house.heat_capacity(spec)
    assert cap["total"] == pytest.approx(sum(v for k, v in cap.items() if k != "total"))
    assert b["c_air_j_per_k"].lo == pytest.approx(cap["air"]) and b["c_wall_j_per_k"].hi == pytest.approx(
        cap["total"] / 2)
    assert (b["f_gains_air"].lo, b["f_gains_air"].hi) == (0.0, ident.F_GAINS_MAX)
    assert (b["f_conv"].lo, b["f_conv"].hi) == (0.0, 1.0)
    assert b["g_s_m2"].hi == pytest.approx(spec.window_m2 * spec.g_window)
    heavy = {x.name: x for x in ident.physical_bounds(dataclasses.replace(spec, construction="masonry"))}
    assert heavy["c_wall_j_per_k"].hi > 1.5 * b["c_wall_j_per_k"].hi  # derived from the layers, not fixed
    assert heavy["air_share"].hi < b["air_share"].hi  # masonry walls buffer their loss, timber frame hardly
    assert all(x.reason for x in b.values())


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=10, max_size=10))
def test_fitted_quantities_and_building_parameters_are_inverse(params, u):
    """Any point of the bounded box maps to building parameters and back (the reparametrised resistances)."""
    bounds = ident.physical_bounds()
    theta = np.array([np.log(b.lo) + x * (np.log(b.hi) - np.log(b.lo)) if b.log else b.lo + x * (b.hi - b.lo)
                      for b, x in zip(bounds, u)])
    b = ident.params_of(theta, params.building, bounds)
    assert min(b.r_air_amb_k_per_w, b.r_w_air_k_per_w, b.r_w_k_per_w, b.r_w_amb_k_per_w) > 0
    back = ident.fitted_of(b)
    for bound, x in zip(bounds, theta):
        assert back[bound.name] == pytest.approx(np.exp(x) if bound.log else x, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize(("update", "hits"), [
    ({"r_air_amb_k_per_w": 0.0275 / 1.8, "r_w_air_k_per_w": 0.00066 / 1.8, "r_w_k_per_w": 0.00825 / 1.8,
      "r_w_amb_k_per_w": 0.00695 / 1.8}, "h_w_per_k"),  # H = 179 W/K, above the typology's + 20 %
    ({"g_s_m2": 30.0}, "g_s_m2"),  # more sun than the windows' area times their g-value
    ({"f_gains_air": 2.0}, "f_gains_air"),  # twice the appliance load as heat
])
def test_fit_stays_within_the_physical_bounds_and_names_the_bound_it_hits(params, update, hits):
    """A house outside the bounds gives a fit on its bounds, named in at_bounds, never an unphysical value."""
    truth = params.building.model_copy(update={"f_gains_air": 0.5, **update})
    bounds = ident.physical_bounds()
    b, _ = ident.fit(_data(truth, 2 * 168, 3), params.building, bounds)
    fitted = ident.fitted_of(b)
    for bound in bounds:
        assert bound.lo * (1 - 1e-9) <= fitted[bound.name] <= bound.hi * (1 + 1e-9), bound.name
    assert hits in ident.at_bounds(fitted, bounds, rel=1e-3)
