"""Shared EMS features: eq:s_sh, eq:s_dhw, eq:EDF_prices, eq:deltaLOH bookkeeping, HP update."""

import math

import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.ems.features import (
    DailyH2Allowance,
    chi_dhw,
    chi_sh,
    edf_price,
    hp_p_el_ref_w,
    update_modulation,
)


def test_chi_sh_uses_highest_lower_bound_within_five_hours():
    # T_low = max(18, 21) = 21; (22.5 - 21) / (24 - 21) = 0.5 -> sqrt = 0.70711
    assert chi_sh(22.5, (18.0, 18.0, 21.0, 21.0, 21.0, 21.0), 24.0) == pytest.approx(math.sqrt(0.5))
    # Same temperature against the current bound 18 only (RBC): (22.5 - 18) / 6 = 0.75
    assert chi_sh(22.5, 18.0, 24.0) == pytest.approx(math.sqrt(0.75))


@pytest.mark.parametrize(
    ("t_air", "expected"),
    [(21.75, 0.5), (21.0, 0.0), (17.0, 0.0), (24.0, 1.0), (25.0, 1.0)],
)
def test_chi_sh_square_root_and_clipping(t_air, expected):
    # (21.75 - 21) / 3 = 0.25 -> 0.5; below T_min 0, above T_max 1
    assert chi_sh(t_air, 21.0, 24.0) == pytest.approx(expected)


def test_chi_sh_degenerate_band():
    assert chi_sh(20.0, 21.0, 21.0) == 0.0
    assert chi_sh(21.0, 21.0, 21.0) == 1.0


@pytest.mark.parametrize(("v", "expected"), [(170.0, 0.25), (40.0, 0.0), (300.0, 1.0), (10.0, 0.0), (235.0, 0.5625)])
def test_chi_dhw_squared_fill(v, expected):
    # (170 - 40) / 260 = 0.5 -> 0.25; (235 - 40) / 260 = 0.75 -> 0.5625
    assert chi_dhw(v, 40.0, 300.0) == pytest.approx(expected)


def test_edf_price_fraction_at_or_below_current():
    prices = [0.10, 0.20, 0.30, 0.40]
    assert edf_price(0.30, prices) == pytest.approx(0.75)
    assert edf_price(0.40, prices) == pytest.approx(1.0)
    assert edf_price(0.10, prices) == pytest.approx(0.25)
    # 24 prices, current is the 6th cheapest -> 6/24
    day = [float(i) for i in range(24)]
    assert edf_price(5.0, day) == pytest.approx(0.25)
    with pytest.raises(ValueError):
        edf_price(1.0, [])


def test_daily_allowance_fixed_renews_each_day():
    a = DailyH2Allowance("fixed")
    assert a.update(0, 1.0, 0.012) == pytest.approx(1.0)
    assert a.update(0, 0.994, 0.012) == pytest.approx(0.5)  # used 0.006 of 0.012
    assert a.update(0, 0.985, 0.012) == 0.0  # over-used: nothing left
    assert a.update(1, 0.985, 0.012) == pytest.approx(1.0)  # new day, nothing carried over
    assert a.today == pytest.approx(0.012)


def test_daily_allowance_rolling_spreads_unused_hydrogen():
    a = DailyH2Allowance("rolling", loh_init=1.0, loh_min=0.0)
    dloh = 1.0 / 84.0  # 84-day period
    a.update(0, 1.0, dloh)
    assert a.today == pytest.approx(1.0 / 84.0)
    a.update(10, 0.9, dloh)  # 74 days left, 0.9 left
    assert a.today == pytest.approx(0.9 / 74.0)
    a.update(83, 0.05, dloh)  # last day
    assert a.today == pytest.approx(0.05)
    a.update(90, 0.05, dloh)  # past the period: at least one day
    assert a.today == pytest.approx(0.05)
    with pytest.raises(ValueError, match="unknown H2 allowance mode"):
        DailyH2Allowance("weekly")


@pytest.mark.parametrize(
    ("eta_prev", "alpha", "expected"),
    [
        (0.0, 0.8, 0.8),  # leaves zero (the paper's product alpha * 0 cannot)
        (0.0, 0.15, 0.2),  # 0.15 >= mod_min / 2 -> snapped up to mod_min
        (0.0, 0.05, 0.0),  # below mod_min / 2 -> stays off
        (0.0, 0.0, 0.0),
        (0.5, -1.0, 0.0),
        (0.9, 0.5, 1.0),
        (0.3, -0.15, 0.2),
        (0.3, -0.25, 0.0),
        (0.3, 0.0, 0.3),
        (0.6, -0.3, 0.3),
    ],
)
def test_update_modulation(eta_prev, alpha, expected):
    eta = update_modulation(eta_prev, alpha, 0.2)
    assert eta == pytest.approx(expected)
    assert eta == 0.0 or 0.2 <= eta <= 1.0


def test_hp_reference_power_from_device_table():
    params = load_plant_params(
        overrides={"heat_pump.p_el_max_t_amb_c": [-10.0, 10.0], "heat_pump.p_el_max_w": [2000.0, 1000.0]}
    )
    # linear between (-10, 2000) and (10, 1000): at 2 degC 2000 - 12 * 50 = 1400 W
    assert hp_p_el_ref_w(params.heat_pump, 2.0) == pytest.approx(1400.0)
