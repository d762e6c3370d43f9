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
