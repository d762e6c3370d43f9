"""DHW tank, eq:DHW_model."""

import pytest

from comems4build_ros.config import load_plant_params
from comems4build_ros.models import dhw


@pytest.fixture(scope="module")
def dp():
    return load_plant_params().dhw


def test_heat_per_litre(dp):
    # 0.998 kg/l * 4186 J/(kg K) * (45 - 10) K = 146216.98 J/l
    assert dhw.heat_per_litre_j(dp) == pytest.approx(146216.98)


def test_heat_from_draw(dp):
    # 200 l/day = 8.333 l/h -> 8.333 / 3600 l/s * 146216.98 J/l = 338.465 W
    assert float(dhw.heat_w_from_l_per_h(200.0 / 24.0, dp)) == pytest.approx(338.4652, rel=1e-6)


def test_volume_change(dp):
    # net 2000 - 338.465 - 35 = 1626.535 W for 3600 s -> 40.0466 l
    q_dm = float(dhw.heat_w_from_l_per_h(200.0 / 24.0, dp))
    v = float(dhw.volume_next_l(100.0, 2000.0, q_dm, dp, 1.0))
    assert v == pytest.approx(100.0 + 1626.535 * 3600.0 / 146216.98, rel=1e-6)
    assert v - 100.0 == pytest.approx(40.0466, abs=1e-3)


def test_standing_loss_only(dp):
    # 35 W for 1 h: 126000 J / 146216.98 J/l = 0.86173 l
    assert float(dhw.volume_next_l(100.0, 0.0, 0.0, dp, 1.0)) == pytest.approx(100.0 - 0.86173, abs=1e-5)
