"""Heat pump, sec:hp: COP(T_amb, T_supply), P_el,max(T_amb), modulation."""

import numpy as np
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import heat_pump
from comems4build_ros.core.types import CLIP_HP_DHW_FULL, CLIP_HP_MOD, HP_COOL, HP_DHW, HP_OFF, HP_SH


@pytest.fixture(scope="module")
def hp():
    return load_plant_params().heat_pump


@pytest.mark.parametrize(
    ("t_amb", "t_sup", "expected"),
    [(-15.0, 45.0, 1.93), (20.0, 45.0, 5.16), (-15.0, 55.0, 1.6), (20.0, 55.0, 4.15)],
)
def test_cop_range_ends(hp, t_amb, t_sup, expected):
    assert heat_pump.cop(t_amb, t_sup, hp) == pytest.approx(expected)


def test_cop_interpolation(hp):
    # T_amb 2.5 degC is the middle of -15..20: COP45 = 1.93 + 0.5 * 3.23 = 3.545,
    # COP55 = 1.6 + 0.5 * 2.55 = 2.875; T_supply 50 degC -> mean 3.21
    assert heat_pump.cop(2.5, 45.0, hp) == pytest.approx(3.545)
    assert heat_pump.cop(2.5, 55.0, hp) == pytest.approx(2.875)
    assert heat_pump.cop(2.5, 50.0, hp) == pytest.approx(3.21)


def test_cop_clipped_outside_range(hp):
    assert heat_pump.cop(-30.0, 55.0, hp) == pytest.approx(1.6)
    assert heat_pump.cop(35.0, 45.0, hp) == pytest.approx(5.16)
    assert heat_pump.cop(20.0, 65.0, hp) == pytest.approx(4.15)
    assert heat_pump.cop(-15.0, 35.0, hp) == pytest.approx(1.93)


def test_cop_vectorised(hp):
    out = heat_pump.cop(np.array([-15.0, 20.0]), 55.0, hp)
    np.testing.assert_allclose(out, [1.6, 4.15])


def test_p_el_max(hp):
    assert heat_pump.p_el_max_w(7.0, hp) == pytest.approx(1560.0)
    # halfway between 2 degC (1650 W) and 7 degC (1560 W)
    assert heat_pump.p_el_max_w(4.5, hp) == pytest.approx(1605.0)
    assert heat_pump.p_el_max_w(-40.0, hp) == pytest.approx(2200.0)


def test_heat_capacity_about_5kw_at_a7(hp):
    q7 = heat_pump.heat_capacity_w(7.0, 55.0, hp)
    assert 4800.0 < q7 < 5200.0
    assert heat_pump.heat_capacity_w(-15.0, 55.0, hp) < q7


# ------------------------------------------------------------------ the device of the plant step
@pytest.mark.parametrize(("request_mod", "mode", "expected"), [
    (0.5, HP_SH, (0.5, HP_SH, 0)),
    (1.4, HP_DHW, (1.0, HP_DHW, CLIP_HP_MOD)),
    (0.15, HP_SH, (0.2, HP_SH, CLIP_HP_MOD)),  # from half of eta_min on: raised to eta_min (eq:zetas)
    (0.05, HP_SH, (0.0, HP_OFF, CLIP_HP_MOD)),  # below half of it: off
    (0.7, HP_OFF, (0.0, HP_OFF, CLIP_HP_MOD)),  # a modulation without a circuit
    (0.0, HP_SH, (0.0, HP_OFF, 0)),  # a circuit without modulation is off, no clip
    (-0.3, HP_SH, (0.0, HP_OFF, CLIP_HP_MOD)),
])
def test_modulation_onto_zero_or_eta_min_to_one(request_mod, mode, expected):
    assert heat_pump.modulation(request_mod, mode, 0.2) == expected


@pytest.mark.parametrize("t_amb", [-20.0, -15.0, -9.3, 0.0, 2.0, 4.7, 7.0, 13.1, 20.0, 31.0])
def test_device_cop_is_the_model_cop(params, t_amb):
    """The plant's scalar evaluation of the COP tables equals heat_pump.cop (up to the last bit)."""
    dev = heat_pump.HeatPump(params.heat_pump, params.cooling)
    for mode, t_sup in ((HP_SH, 55.0), (HP_DHW, 45.0)):
        c, p_max = dev.operating_point(mode, t_amb)
        assert c == pytest.approx(heat_pump.cop(t_amb, t_sup, params.heat_pump), rel=1e-15)
        assert p_max == pytest.approx(heat_pump.p_el_max_w(t_amb, params.heat_pump), rel=1e-15)


def test_device_run_heat_is_cop_times_modulated_intake(params):
    """eq:heat_flux_SH at A2: P_el,max(2 degC) = 1650 W, COP55(2) = 1.6 + 17/35 * 2.55."""
    dev = heat_pump.HeatPump(params.heat_pump, params.cooling)
    mode, mod, c, p_max, p_el, q, clip = dev.run(0.5, HP_SH, 2.0)
    cop55 = 1.6 + 17.0 / 35.0 * (4.15 - 1.6)
    assert (mode, mod, clip) == (HP_SH, 0.5, 0)
    assert c == pytest.approx(cop55) and p_max == pytest.approx(1650.0)
    assert p_el == pytest.approx(825.0) and q == pytest.approx(825.0 * cop55)
    assert dev.run(0.0, HP_SH, 2.0) == (HP_OFF, 0.0, 0.0, 0.0, 0.0, 0.0, 0)


def test_device_fit_heat_to_what_the_tank_takes(params):
    dev = heat_pump.HeatPump(params.heat_pump, params.cooling)
    mod, p_el, q, clip = dev.fit_heat(1500.0, 4.0, 1500.0)  # 1500 W of 6000 W at full modulation
    assert clip == CLIP_HP_DHW_FULL and mod == pytest.approx(0.25)
    assert p_el == pytest.approx(375.0) and q == pytest.approx(1500.0)
    assert dev.fit_heat(600.0, 4.0, 1500.0) == (0.0, 0.0, 0.0, CLIP_HP_DHW_FULL)  # 0.1 < eta_min: off
    assert dev.fit_heat(-5.0, 4.0, 1500.0)[0] == 0.0


def test_device_cooling_intake_is_capacity_over_eer():
    p = load_plant_params(overrides={"cooling.enabled": True})
    dev = heat_pump.HeatPump(p.heat_pump, p.cooling)
    eer, p_max = dev.operating_point(HP_COOL, 25.0)  # EER 6.7 .. 4.3 over 15 .. 35 degC: 5.5 at 25
    assert eer == pytest.approx(5.5) and p_max == pytest.approx(3000.0 / 5.5)
