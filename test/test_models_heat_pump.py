"""Heat pump, sec:hp: COP(T_amb, T_supply), P_el,max(T_amb), modulation."""

import numpy as np
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import heat_pump


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
