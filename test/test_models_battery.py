"""Battery model, eq:batt_soc, eq:SOC_const, eq:bat_ch_dis_const."""

import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import battery


@pytest.fixture(scope="module")
def bp():
    return load_plant_params().battery


def test_split_power_rating(bp):
    assert battery.split_power(2500.0, 0.5, bp, 1.0) == (1000.0, 0.0, True, False)
    assert battery.split_power(-2500.0, 0.5, bp, 1.0) == (0.0, 1000.0, True, False)
    assert battery.split_power(0.0, 0.5, bp, 1.0) == (0.0, 0.0, False, False)


def test_split_power_soc_bounds(bp):
    # SOC 0.89, charging: room = 0.01 * 6500 Wh / (0.93 * 1 h) = 69.89 W
    p_ch, p_d, pc, sc = battery.split_power(800.0, 0.89, bp, 1.0)
    assert p_ch == pytest.approx(65.0 / 0.93) and p_d == 0.0 and sc and not pc
    # SOC 0.12, discharging: room = 0.02 * 6500 * 0.93 = 120.9 W
    p_ch, p_d, pc, sc = battery.split_power(-800.0, 0.12, bp, 1.0)
    assert p_d == pytest.approx(120.9) and sc


def test_split_power_exact_room_is_no_clip(bp):
    """A request for exactly the room left, computed with other rounding, is no SOC clip."""
    room = 0.01 * 6500.0 / 0.93  # SOC 0.89 -> 0.9
    for p in (room * (1 + 1e-15), room + 1e-9):
        p_ch, _, _, sc = battery.split_power(p, 0.89, bp, 1.0)
        assert p_ch == pytest.approx(room, rel=1e-12) and not sc
    assert battery.split_power(room + 1e-3, 0.89, bp, 1.0)[3]  # a milliwatt over: a clip


def test_split_power_minimum(bp):
    b = bp.model_copy(update={"p_ch_min_w": 200.0, "p_d_min_w": 200.0})
    assert battery.split_power(100.0, 0.5, b, 1.0) == (0.0, 0.0, True, False)
    # SOC room of 69.89 W is below the 200 W minimum: no charging at all.
    assert battery.split_power(800.0, 0.89, b, 1.0) == (0.0, 0.0, False, True)


def test_power_limits(bp):
    assert battery.power_limits_w(0.5, bp, 1.0) == (1000.0, 1000.0)
    ch, d = battery.power_limits_w(0.9, bp, 1.0)
    assert ch == 0.0 and d == 1000.0


def test_step_is_eq_batt_soc(bp):
    """SOC[k] = SOC[k-1] + (eta_ch P_ch - P_d / eta_d) t_s / E_B,max, by hand."""
    p_ch, p_dis, soc, power_clip, soc_clip = battery.step(800.0, 0.5, bp, 1.0)
    assert (p_ch, p_dis, power_clip, soc_clip) == (800.0, 0.0, False, False)
    assert soc == pytest.approx(0.5 + 0.93 * 800.0 / 6500.0)
    p_ch, p_dis, soc, *_ = battery.step(-650.0, 0.5, bp, 1.0)
    assert (p_ch, p_dis) == (0.0, 650.0) and soc == pytest.approx(0.5 - 650.0 / 0.93 / 6500.0)


def test_step_stays_within_the_soc_bounds(bp):
    _, _, soc, _, soc_clip = battery.step(1000.0, 0.89, bp, 1.0)
    assert soc == pytest.approx(0.9) and soc <= 0.9 and soc_clip
    _, _, soc, _, soc_clip = battery.step(-1000.0, 0.1, bp, 1.0)
    assert soc == 0.1 and soc_clip
