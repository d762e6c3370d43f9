"""Electrolyser, cooling and their plant step against the datasheet points of config/plant.yaml."""

from __future__ import annotations

import math

import pytest

from comems4build_ros.core.config import ConfigError, load_plant_params
from comems4build_ros.core.models.cooling import dew_point_c, eer, p_el_max_cool_w
from comems4build_ros.core.models.electrolyser import ElectrolyserTable, compression_wh_per_kg
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import CLIP_EL_H2, CLIP_EL_RANGE, HP_COOL, Action, Exogenous

YEAR = {"electrolyser.n_modules": 1, "cooling.enabled": True, "simulation.loh_init": 0.1}


def _exo(t_amb: float = 20.0, pv: float = 5000.0) -> Exogenous:
    return Exogenous(t_amb, 600.0, pv, 400.0, 10.0, 0.3, 0.0794, 21.0, 26.0)


def test_rated_point_is_the_datasheet() -> None:
    """EL 2.1: 500 NL/h at 2.4 kW = 4.8 kWh/Nm3 (without compression)."""
    t = ElectrolyserTable(load_plant_params(overrides=YEAR).electrolyser)
    assert t.specific_kwh_per_nm3(1.0) == pytest.approx(4.8, abs=1e-9)
    assert t.p_stack_w(1.0) == pytest.approx(2400.0)
    assert t.h2_w(1.0) == pytest.approx(0.5 * 0.08988 * 33330.0)  # 1.498 kW LHV
    # LHV efficiency at rated load, compression to 300 bar included: 1498 / (2400 + 65)
    assert t.efficiency(1.0) == pytest.approx(1497.8 / (2400.0 + 64.8), rel=1e-3)


def test_part_load_point() -> None:
    """60 % of nominal production (datasheet minimum) at the documented 1454 W."""
    t = ElectrolyserTable(load_plant_params(overrides=YEAR).electrolyser)
    assert t.p_stack_w(0.6) == pytest.approx(1454.0)
    assert t.specific_kwh_per_nm3(0.6) == pytest.approx(1.454 / 0.3, rel=1e-12)
    assert t.efficiency(0.6) == pytest.approx(0.6 * 1497.8 / (1454.0 + 0.6 * 64.8), rel=1e-3)
    for x in (0.6, 0.75, 0.9, 1.0):
        assert t.load_of_power(t.p_total_w(x)) == pytest.approx(x, abs=1e-12)


def test_compression_work() -> None:
    """Isothermal 35 -> 300 bar at 20 degC: 0.721 kWh/kg ideal, 1.44 kWh/kg at efficiency 0.5."""
    el = load_plant_params().electrolyser
    ideal = 8.314462618 * 293.15 * math.log(300 / 35) / 2.01588e-3 / 3600.0
    assert ideal == pytest.approx(721.0, rel=2e-3)
    assert compression_wh_per_kg(el) == pytest.approx(ideal / 0.5)


def test_eer_and_dew_point() -> None:
    cool = load_plant_params().cooling
    assert eer(35.0, cool) == pytest.approx(4.3)  # A35/W18 rating point
    assert eer(50.0, cool) == pytest.approx(3.1)  # held outside the table
    assert p_el_max_cool_w(35.0, cool) == pytest.approx(3000.0 / 4.3)
    assert dew_point_c(26.0, 0.6) == pytest.approx(17.6, abs=0.05)
    assert dew_point_c(20.0, 1.0) == pytest.approx(20.0, abs=1e-9)
    with pytest.raises(ConfigError, match="dew point"):
        load_plant_params(overrides={"cooling.t_supply_c": 17.0})


def test_plant_electrolyser_step_balances_and_fills_the_store() -> None:
    params = load_plant_params(overrides=YEAR)
    plant = Plant(params)
    s0 = plant.initial_state()
    s1, f1 = plant.step(s0, Action(p_el_w=plant.el_table.p_max_w), _exo())
    assert f1.el_on and f1.el_start
    # the start loses 10 min of production
    assert f1.p_h2_el_w == pytest.approx(plant.el_table.h2_w(1.0) * (1 - 0.1667))
    assert s1.loh - s0.loh == pytest.approx(f1.p_h2_el_w / 1.8e6)
    assert abs(f1.balance_residual_w) < 1e-9
    s2, f2 = plant.step(s1, Action(p_el_w=plant.el_table.p_max_w), _exo())
    assert not f2.el_start and f2.p_h2_el_w == pytest.approx(plant.el_table.h2_w(1.0))
    # off: standby draw only
    _, f3 = plant.step(s2, Action(), _exo())
    assert f3.p_el_w == pytest.approx(15.0) and not f3.el_on and f3.p_h2_el_w == 0.0


def test_plant_electrolyser_clips() -> None:
    params = load_plant_params(overrides={**YEAR, "simulation.loh_init": 0.9999})
    plant = Plant(params)
    s0 = plant.initial_state()
    s1, f = plant.step(s0, Action(p_el_w=2000.0), _exo())
    assert f.clipped & CLIP_EL_H2 and not f.el_on and s1.loh == pytest.approx(0.9999)
    _, f = plant.step(plant.initial_state(), Action(p_el_w=9000.0), _exo())
    assert f.clipped & CLIP_EL_RANGE
    winter = Plant(load_plant_params())
    _, f = winter.step(winter.initial_state(), Action(p_el_w=2000.0), _exo())
    assert f.clipped & CLIP_EL_RANGE and f.p_el_w == 0.0 and f.p_h2_el_w == 0.0


def test_heat_recovery_into_the_tank() -> None:
    params = load_plant_params(overrides={**YEAR, "electrolyser.heat_recovery": 0.8})
    plant = Plant(params)
    s0 = plant.initial_state()
    s1, f = plant.step(s0.copy(), Action(p_el_w=plant.el_table.p_max_w), _exo())
    assert f.q_el_rec_w > 0.0 and f.q_el_dump_w == 0.0
    base = Plant(load_plant_params(overrides=YEAR))
    s1b, _ = base.step(base.initial_state(), Action(p_el_w=plant.el_table.p_max_w), _exo())
    assert s1.v_dhw_l > s1b.v_dhw_l


def test_cooling_takes_heat_from_the_rooms() -> None:
    params = load_plant_params(overrides=YEAR)
    plant = Plant(params)
    s0 = plant.initial_state()
    s_cool, f = plant.step(s0.copy(), Action(hp_mod=1.0, hp_mode=HP_COOL), _exo(t_amb=35.0))
    s_off, _ = plant.step(s0.copy(), Action(), _exo(t_amb=35.0))
    assert f.hp_mode == HP_COOL and f.q_cool_w == pytest.approx(3000.0)
    assert f.p_hp_el_w == pytest.approx(3000.0 / 4.3) and f.cop == pytest.approx(4.3)
    assert f.q_hp_sh_w == 0.0 and s_cool.t_air_c < s_off.t_air_c
    winter = Plant(load_plant_params())
    _, f = winter.step(winter.initial_state(), Action(hp_mod=1.0, hp_mode=HP_COOL), _exo())
    assert f.hp_mode == 0 and f.q_cool_w == 0.0
