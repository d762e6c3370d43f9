"""Plant step: hand-checked single steps, clipping flags and invalid input."""

import math

import pytest

from comems4build_ros.core.config import ConfigError, load_plant_params
from comems4build_ros.core.models import fuel_cell
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import (
    CLIP_BESS_POWER,
    CLIP_BESS_SOC,
    CLIP_FC_H2,
    CLIP_FC_RANGE,
    CLIP_HP_DHW_FULL,
    CLIP_HP_MOD,
    CLIP_HP_MODE,
    CLIP_NONFINITE,
    FLOW_FIELDS,
    HP_DHW,
    HP_OFF,
    HP_SH,
    Action,
    Exogenous,
    PlantState,
)

J_PER_L = 0.998 * 4186.0 * 35.0  # heat per litre of DHW [J/l]



@pytest.fixture(scope="module")
def plant(params):
    return Plant(params)


def exo(**kw):
    base = dict(
        t_amb_c=7.0,
        ghi_w_m2=0.0,
        p_pv_w=0.0,
        p_load_w=500.0,
        dhw_l_per_h=0.0,
        price_buy_eur_per_kwh=0.4,
        price_sell_eur_per_kwh=0.0794,
        t_min_c=21.0,
        t_max_c=24.0,
    )
    base.update(kw)
    return Exogenous(**base)


def state(**kw):
    base = dict(soc=0.5, loh=0.5, t_air_c=20.0, t_wall_in_c=19.5, t_wall_out_c=8.0, v_dhw_l=150.0)
    base.update(kw)
    return PlantState(**base)


def test_initial_state(params, plant):
    s = plant.initial_state()
    assert (s.soc, s.loh, s.t_air_c, s.v_dhw_l) == (0.5, 1.0, 21.0, 200.0)
    # Wall nodes on the resistor chain between 21 degC and t_amb_init 4.2 degC:
    # T_w,in = 21 - 16.8 * 0.00066 / 0.01586, T_w,out = 21 - 16.8 * 0.00891 / 0.01586
    assert s.t_wall_in_c == pytest.approx(21 - 16.8 * 0.00066 / 0.01586)
    assert s.t_wall_out_c == pytest.approx(21 - 16.8 * 0.00891 / 0.01586)
    assert not s.fc_on


def test_idle_step_grid_covers_load(plant):
    s, f = plant.step(state(), Action(), exo(p_pv_w=200.0))
    assert f.p_buy_w == pytest.approx(300.0) and f.p_sell_w == 0.0
    assert f.clipped == 0 and f.balance_residual_w == 0.0
    assert set(f.as_dict()) == set(FLOW_FIELDS)


def test_heat_pump_space_heating(plant):
    # A7: P_el,max = 1560 W, COP(7, 55) = 1.6 + 22/35 * 2.55 = 3.202857
    s, f = plant.step(state(), Action(hp_mod=0.5, hp_mode=HP_SH), exo())
    assert f.p_hp_el_w == pytest.approx(780.0)
    assert f.cop == pytest.approx(1.6 + 22 / 35 * 2.55)
    assert f.q_hp_sh_w == pytest.approx(780.0 * (1.6 + 22 / 35 * 2.55))
    assert f.q_hp_dhw_w == 0.0 and f.hp_mode == HP_SH
    s_off, _ = plant.step(state(), Action(), exo())
    assert s.t_air_c > s_off.t_air_c
    assert f.p_buy_w == pytest.approx(500.0 + 780.0)


def test_heat_pump_dhw(plant):
    # COP(7, 45) = 1.93 + 22/35 * 3.23 = 3.960286; full modulation, no draw:
    # dV = (1560 * COP - 35 W) * 3600 s / J_PER_L
    s, f = plant.step(state(v_dhw_l=100.0), Action(hp_mod=1.0, hp_mode=HP_DHW), exo())
    cop = 1.93 + 22 / 35 * 3.23
    assert f.q_hp_dhw_w == pytest.approx(1560.0 * cop) and f.q_hp_sh_w == 0.0
    assert f.clipped == 0
    assert s.v_dhw_l == pytest.approx(100.0 + (1560.0 * cop - 35.0) * 3600.0 / J_PER_L)


def test_battery_charge_one_hour(plant):
    s, f = plant.step(state(), Action(p_bess_w=1000.0), exo())
    assert s.soc == pytest.approx(0.5 + 930.0 / 6500.0)
    assert f.p_ch_w == 1000.0 and f.p_dis_w == 0.0 and f.p_buy_w == pytest.approx(1500.0)


def test_battery_one_hour_to_the_soc_bounds(plant):
    """eq:batt_soc with eq:SOC_const: 1 kW discharging from 0.5 -> 0.5 - 1000 / 0.93 / 6500; charging
    from 0.89 stops at 0.9 (65 Wh of room at 93 %), discharging from 0.12 at 0.1 (120.9 W)."""
    s, _ = plant.step(state(), Action(p_bess_w=-1000.0), exo())
    assert s.soc == pytest.approx(0.5 - 1000.0 / 0.93 / 6500.0, rel=1e-12)
    s, f = plant.step(state(soc=0.89), Action(p_bess_w=800.0), exo())
    assert s.soc == pytest.approx(0.9, abs=1e-12) and f.p_ch_w == pytest.approx(65.0 / 0.93)
    s, f = plant.step(state(soc=0.12), Action(p_bess_w=-800.0), exo())
    assert s.soc == pytest.approx(0.1, abs=1e-12) and f.p_dis_w == pytest.approx(120.9)


def test_dhw_tank_one_hour(plant):
    """eq:DHW_model: the standing loss alone, 35 W for 1 h = 126000 J / 146216.98 J/l = 0.86173 l;
    with 200 l/day drawn (338.465 W) and the HP's DHW heat the net heat fills the tank."""
    s, _ = plant.step(state(v_dhw_l=100.0), Action(), exo(dhw_l_per_h=0.0))
    assert s.v_dhw_l == pytest.approx(100.0 - 0.86173, abs=1e-5)
    s, f = plant.step(state(v_dhw_l=100.0), Action(hp_mod=0.5, hp_mode=HP_DHW), exo(dhw_l_per_h=200.0 / 24.0))
    q_net = f.q_hp_dhw_w - 200.0 / 24.0 / 3600.0 * J_PER_L - 35.0
    assert s.v_dhw_l == pytest.approx(100.0 + q_net * 3600.0 / J_PER_L, rel=1e-9)


def test_fuel_cell_step(params, plant):
    fc = params.fuel_cell
    p_h2, eta = fuel_cell.operating_point(1500.0, fc)
    s, f = plant.step(state(), Action(p_fc_w=1500.0), exo())
    assert f.p_fc_w == 1500.0 and f.fc_on and f.fc_start and not f.fc_stop
    assert f.p_h2_w == pytest.approx(p_h2, rel=1e-6)
    assert f.eta_fc_el == pytest.approx(eta, rel=1e-6)
    # LOH falls by P_H2 * 1 h / 1800 kWh (eq:LOH)
    assert s.loh == pytest.approx(0.5 - p_h2 / 1.8e6, rel=1e-9)
    # Q_hr = 0.75 * P_H2 - P_el goes to the tank (eq:FC_sys_efficiency, eq:DHW_heat)
    assert f.q_fc_rec_w == pytest.approx(0.75 * p_h2 - 1500.0, rel=1e-6)
    assert f.p_sell_w == pytest.approx(1000.0) and f.p_buy_w == 0.0
    # eq:on_off_logic: staying on is neither start nor stop; switching off is a stop.
    s2, f2 = plant.step(s, Action(p_fc_w=1000.0), exo())
    assert f2.fc_on and not f2.fc_start and not f2.fc_stop
    _, f3 = plant.step(s2, Action(), exo())
    assert not f3.fc_on and f3.fc_stop and not f3.fc_start


def test_fuel_cell_range_clipping(params, plant):
    top = params.fuel_cell.zeta * params.fuel_cell.p_max_w
    _, f = plant.step(state(), Action(p_fc_w=5000.0), exo())
    assert f.p_fc_w == pytest.approx(top) and f.clipped & CLIP_FC_RANGE
    _, f = plant.step(state(), Action(p_fc_w=300.0), exo())  # above P_min/2 -> P_min
    assert f.p_fc_w == pytest.approx(399.2) and f.clipped & CLIP_FC_RANGE
    _, f = plant.step(state(), Action(p_fc_w=100.0), exo())  # below P_min/2 -> off
    assert f.p_fc_w == 0.0 and not f.fc_on and f.clipped & CLIP_FC_RANGE


def test_fuel_cell_limited_by_h2(params, plant):
    # 1 kWh of H2 left: the FC may consume at most 1000 W of H2 in the hour.
    s, f = plant.step(state(loh=1.0 / 1800.0), Action(p_fc_w=1900.0), exo())
    assert f.clipped & CLIP_FC_H2
    assert f.p_h2_w == pytest.approx(1000.0, rel=1e-9)
    assert s.loh == pytest.approx(0.0, abs=1e-12) and s.loh >= 0.0
    assert f.p_fc_w >= params.fuel_cell.p_min_w
    # 0.2 kWh left: P_min cannot be held -> off
    s, f = plant.step(state(loh=0.2 / 1800.0), Action(p_fc_w=1900.0), exo())
    assert f.p_fc_w == 0.0 and f.clipped & CLIP_FC_H2 and s.loh == pytest.approx(0.2 / 1800.0)


def test_dhw_overflow_reduces_heat_pump(plant):
    # Room for 10 l in 1 h: HP DHW heat cut to 10 * J_PER_L / 3600 + 35 W = 441.2 W,
    # which is 0.11 of its full output at A7 (below mod_min 0.2) -> HP off.
    s, f = plant.step(state(v_dhw_l=290.0), Action(hp_mod=1.0, hp_mode=HP_DHW), exo())
    assert f.clipped & CLIP_HP_DHW_FULL and f.hp_mode == HP_OFF and f.p_hp_el_w == 0.0
    # Room for 100 l: 100 * J_PER_L / 3600 + 35 W = 4096.6 W = 0.663 of full output.
    s, f = plant.step(state(v_dhw_l=200.0), Action(hp_mod=1.0, hp_mode=HP_DHW), exo())
    assert f.clipped & CLIP_HP_DHW_FULL and f.hp_mode == HP_DHW
    assert f.q_hp_dhw_w == pytest.approx(100.0 * J_PER_L / 3600.0 + 35.0)
    assert s.v_dhw_l == pytest.approx(300.0)


def test_fc_heat_dumped_when_tank_full(plant):
    s, f = plant.step(state(v_dhw_l=300.0), Action(p_fc_w=1500.0), exo())
    # Only the standing loss (35 W) fits into the full tank.
    assert f.q_fc_rec_w == pytest.approx(35.0)
    assert f.q_fc_rec_w + f.q_fc_dump_w == pytest.approx(0.75 * f.p_h2_w - f.p_fc_w)
    assert s.v_dhw_l == pytest.approx(300.0)


def test_dhw_unmet_demand(plant):
    # Tank 10 l above V_min, draw 100 l/h: served 10 l + nothing else; unmet the rest.
    s, f = plant.step(state(v_dhw_l=50.0), Action(), exo(dhw_l_per_h=100.0))
    demand = 100.0 * J_PER_L / 3600.0
    assert f.q_dhw_demand_w == pytest.approx(demand)
    assert f.q_dhw_unmet_w == pytest.approx(demand + 35.0 - 10.0 * J_PER_L / 3600.0)
    assert s.v_dhw_l == 40.0


def test_nonfinite_and_unknown_action(plant):
    s, f = plant.step(state(), Action(hp_mod=math.nan, hp_mode=7, p_fc_w=math.inf, p_bess_w=-math.inf), exo())
    assert f.clipped & CLIP_NONFINITE and f.clipped & CLIP_HP_MODE
    assert f.p_hp_el_w == 0.0 and f.p_fc_w == 0.0 and f.p_dis_w == 0.0
    _, f = plant.step(state(), Action(hp_mod="high", hp_mode=None, p_fc_w=None, p_bess_w="x"), exo())
    assert f.clipped & CLIP_NONFINITE and f.p_buy_w == pytest.approx(500.0)


def test_modulation_clipping(plant):
    _, f = plant.step(state(), Action(hp_mod=1.5, hp_mode=HP_SH), exo())
    assert f.hp_mod == 1.0 and f.clipped & CLIP_HP_MOD
    _, f = plant.step(state(), Action(hp_mod=0.12, hp_mode=HP_SH), exo())
    assert f.hp_mod == 0.2 and f.clipped & CLIP_HP_MOD
    _, f = plant.step(state(), Action(hp_mod=0.05, hp_mode=HP_SH), exo())
    assert f.hp_mod == 0.0 and f.hp_mode == HP_OFF
    _, f = plant.step(state(), Action(hp_mod=0.5, hp_mode=HP_OFF), exo())
    assert f.hp_mod == 0.0 and f.clipped & CLIP_HP_MOD


def test_battery_clipping(plant):
    _, f = plant.step(state(), Action(p_bess_w=3000.0), exo())
    assert f.p_ch_w == 1000.0 and f.clipped & CLIP_BESS_POWER
    s, f = plant.step(state(soc=0.1), Action(p_bess_w=-500.0), exo())
    assert f.p_dis_w == 0.0 and f.clipped & CLIP_BESS_SOC and s.soc == 0.1


def test_surplus_is_sold(plant):
    _, f = plant.step(state(), Action(), exo(p_pv_w=3000.0))
    assert f.p_sell_w == pytest.approx(2500.0) and f.p_buy_w == 0.0


def test_eta_sys_090_recovers_more(params):
    hi = Plant(load_plant_params(overrides={"fuel_cell.eta_sys": 0.9}))
    _, f = hi.step(state(), Action(p_fc_w=1500.0), exo())
    assert f.q_fc_rec_w == pytest.approx(0.9 * f.p_h2_w - 1500.0)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [("t_amb_c", math.nan, "t_amb_c"), ("p_load_w", -1.0, "p_load_w"), ("price_sell_eur_per_kwh", math.inf, "price")],
)
def test_invalid_exogenous_raises(plant, field, value, match):
    with pytest.raises(ValueError, match=match):
        plant.step(state(), Action(), exo(**{field: value}))


@pytest.mark.parametrize(("field", "value"), [("soc", 0.95), ("loh", -0.1), ("v_dhw_l", 10.0), ("t_air_c", math.nan)])
def test_invalid_state_raises(plant, field, value):
    with pytest.raises(ValueError, match=field):
        plant.step(state(**{field: value}), Action(), exo())


def test_invalid_initial_volume_raises():
    """An initial tank volume beyond the tank is refused when the parameters are read, naming both."""
    with pytest.raises(ConfigError, match=r"simulation.v_dhw_init_l \(500 l\) exceeds the tank, dhw.v_max_l"):
        load_plant_params(overrides={"simulation.v_dhw_init_l": 500.0})
