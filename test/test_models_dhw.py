"""DHW tank, eq:DHW_model."""

import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import dhw


@pytest.fixture(scope="module")
def dp():
    return load_plant_params().dhw


def test_heat_per_litre(dp):
    # 0.998 kg/l * 4186 J/(kg K) * (45 - 10) K = 146216.98 J/l
    assert dhw.heat_per_litre_j(dp) == pytest.approx(146216.98)


def test_heat_from_draw(dp):
    # 200 l/day = 8.333 l/h -> 8.333 / 3600 l/s * 146216.98 J/l = 338.465 W
    assert float(dhw.heat_w_from_l_per_h(200.0 / 24.0, dp)) == pytest.approx(338.4652, rel=1e-6)


# ------------------------------------------------------------------ the tank of the plant step
J_PER_L = 0.998 * 4186.0 * 35.0  # rho * c * (T_DHW - T_cold) [J/l]


def test_tank_step_is_eq_dhw_model(dp):
    """V[k] = V[k-1] + (Q_DHW - Q_dm - Q_l) / (dT rho c) * t_s, by hand for one hour."""
    tank = dhw.Tank(dp, 1.0)
    q_dem = tank.demand_w(20.0)  # 20 l/h at T_DHW
    assert q_dem == pytest.approx(20.0 * J_PER_L / 3600.0)
    room = tank.room_w(150.0, q_dem)
    v, q_fc_in, q_fc_dump, q_el_in, q_el_dump, unmet = tank.step(150.0, 1500.0, 300.0, 0.0, q_dem, room)
    expected = 150.0 + (1500.0 + 300.0 - q_dem - 35.0) * 3600.0 / J_PER_L
    assert v == pytest.approx(expected)
    assert (q_fc_in, q_fc_dump, q_el_in, q_el_dump, unmet) == (300.0, 0.0, 0.0, 0.0, 0.0)


def test_tank_full_takes_fc_heat_first_then_el_heat_and_dumps_the_rest(dp):
    tank = dhw.Tank(dp, 1.0)
    room = tank.room_w(299.0, 0.0)  # 1 l of room plus the standing loss
    assert room == pytest.approx(J_PER_L / 3600.0 + 35.0)
    v, q_fc_in, q_fc_dump, q_el_in, q_el_dump, _ = tank.step(299.0, 0.0, 30.0, 200.0, 0.0, room)
    assert v == pytest.approx(300.0)
    assert q_fc_in == 30.0 and q_fc_dump == 0.0
    assert q_el_in == pytest.approx(room - 30.0) and q_el_dump == pytest.approx(200.0 - (room - 30.0))
    v, q_fc_in, q_fc_dump, *_ = tank.step(299.0, 0.0, 500.0, 0.0, 0.0, room)
    assert v == pytest.approx(300.0) and q_fc_in == pytest.approx(room) and q_fc_dump == pytest.approx(500.0 - room)


def test_tank_draw_below_v_min_is_unmet(dp):
    tank = dhw.Tank(dp, 1.0)
    q_dem = tank.demand_w(100.0)
    v, *_, unmet = tank.step(60.0, 0.0, 0.0, 0.0, q_dem, tank.room_w(60.0, q_dem))
    assert v == 40.0
    # 20 l above V_min are served; the rest of the draw and the loss are unmet
    assert unmet == pytest.approx(q_dem + 35.0 - 20.0 * J_PER_L / 3600.0)
