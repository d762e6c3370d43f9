"""Property-based tests of the plant step's invariants over random states, actions and inputs."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from comems4build_ros.core.config import SECONDS_PER_HOUR, W_PER_KW, load_plant_params
from comems4build_ros.core.models import dhw as dhw_model
from comems4build_ros.core.models import heat_pump
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action, Exogenous, PlantState

PARAMS = load_plant_params()
PLANT = Plant(PARAMS)
B, FC, H2, HP, DHW = PARAMS.battery, PARAMS.fuel_cell, PARAMS.hydrogen, PARAMS.heat_pump, PARAMS.dhw
J_PER_L = dhw_model.heat_per_litre_j(DHW)

any_float = st.floats(allow_nan=True, allow_infinity=True)
wide = st.one_of(any_float, st.floats(-5000, 5000), st.floats(0, 1.2), st.sampled_from([0.0, 0.1, 0.2, 1.0]))


def bounded(lo, hi):
    return st.one_of(st.floats(lo, hi), st.sampled_from([lo, hi]))


states = st.builds(
    PlantState,
    soc=bounded(B.soc_min, B.soc_max),
    loh=bounded(H2.loh_min, H2.loh_max),
    t_air_c=st.floats(5, 35),
    t_wall_in_c=st.floats(0, 35),
    t_wall_out_c=st.floats(-20, 35),
    v_dhw_l=bounded(DHW.v_min_l, DHW.v_max_l),
    hp_mod=st.floats(0, 1),
    fc_on=st.booleans(),
)
actions = st.builds(
    Action,
    hp_mod=wide,
    hp_mode=st.one_of(st.sampled_from([HP_OFF, HP_SH, HP_DHW, 3, -1]), any_float),
    p_fc_w=st.one_of(wide, st.floats(0, 3000)),
    p_bess_w=st.one_of(wide, st.floats(-2000, 2000)),
)
exos = st.builds(
    Exogenous,
    t_amb_c=st.floats(-25, 35),
    ghi_w_m2=st.floats(0, 1000),
    p_pv_w=st.floats(0, 10000),
    p_load_w=st.floats(0, 8000),
    dhw_l_per_h=st.one_of(st.just(0.0), st.floats(0, 400)),
    price_buy_eur_per_kwh=st.floats(-0.5, 2),
    price_sell_eur_per_kwh=st.floats(0, 0.5),
    t_min_c=st.just(18.0),
    t_max_c=st.just(24.0),
)


@settings(max_examples=1500, deadline=None)
@given(states, actions, exos)
def test_step_invariants(s, a, e):
    n, f = PLANT.step(s, a, e)
    dt_h = PLANT.dt_h

    # eq:power_balance closes; buy or sell, never both.
    assert abs(f.balance_residual_w) < 1e-6
    lhs = f.p_pv_w + f.p_buy_w + f.p_fc_w + f.p_dis_w
    rhs = f.p_sell_w + f.p_load_w + f.p_hp_el_w + f.p_ch_w
    assert abs(lhs - rhs) < 1e-6
    assert f.p_buy_w >= 0 and f.p_sell_w >= 0 and not (f.p_buy_w > 0 and f.p_sell_w > 0)

    # Storage bounds, exactly.
    assert B.soc_min <= n.soc <= B.soc_max
    assert H2.loh_min <= n.loh <= H2.loh_max
    assert DHW.v_min_l <= n.v_dhw_l <= DHW.v_max_l
    assert all(math.isfinite(x) for x in (n.t_air_c, n.t_wall_in_c, n.t_wall_out_c))

    # Battery: one direction, within ratings; eq:batt_soc.
    assert f.p_ch_w >= 0 and f.p_dis_w >= 0 and not (f.p_ch_w > 0 and f.p_dis_w > 0)
    assert f.p_ch_w <= B.p_ch_max_w and f.p_dis_w <= B.p_d_max_w
    soc_eq = s.soc + (B.eta_ch * f.p_ch_w - f.p_dis_w / B.eta_d) * dt_h / (B.e_max_kwh * W_PER_KW)
    assert n.soc == pytest.approx(soc_eq, abs=1e-12)

    # Heat pump: one circuit, modulation in {0} U [mod_min, 1], P_el = mod * P_el,max.
    assert not (f.q_hp_sh_w > 0 and f.q_hp_dhw_w > 0)
    assert f.hp_mod == 0.0 or HP.mod_min - 1e-12 <= f.hp_mod <= 1.0
    assert (f.hp_mode == HP_OFF) == (f.hp_mod == 0.0)
    assert n.hp_mod == f.hp_mod
    if f.hp_mode != HP_OFF:
        t_sup = HP.t_supply_sh_c if f.hp_mode == HP_SH else HP.t_supply_dhw_c
        assert f.p_hp_el_w == pytest.approx(f.hp_mod * heat_pump.p_el_max_w(e.t_amb_c, HP), rel=1e-9)
        assert f.cop == pytest.approx(heat_pump.cop(e.t_amb_c, t_sup, HP), rel=1e-9)
        assert f.q_hp_sh_w + f.q_hp_dhw_w == pytest.approx(f.cop * f.p_hp_el_w, rel=1e-9)
    else:
        assert f.p_hp_el_w == 0.0 and f.q_hp_sh_w == 0.0 and f.q_hp_dhw_w == 0.0

    # Fuel cell: {0} U [P_min, zeta P_max]; H2 use matches LOH drop (eq:LOH); heat split.
    assert f.p_fc_w == 0.0 or FC.p_min_w - 1e-9 <= f.p_fc_w <= FC.zeta * FC.p_max_w + 1e-9
    assert f.fc_on == (f.p_fc_w > 0) == n.fc_on
    assert f.fc_start == (f.fc_on and not s.fc_on) and f.fc_stop == (s.fc_on and not f.fc_on)
    assert (s.loh - n.loh) * H2.e_max_kwh * W_PER_KW == pytest.approx(f.p_h2_w * dt_h, abs=1e-6)
    q_hr = max(0.0, FC.eta_sys * f.p_h2_w - f.p_fc_w)
    assert f.q_fc_rec_w >= 0 and f.q_fc_dump_w >= 0
    assert f.q_fc_rec_w + f.q_fc_dump_w == pytest.approx(q_hr, abs=1e-6)
    if f.fc_on:
        assert f.eta_fc_el == pytest.approx(f.p_fc_w / f.p_h2_w)

    # DHW tank energy conservation (eq:DHW_model): stored = in - (demand + loss - unmet).
    assert f.q_dhw_demand_w == pytest.approx(e.dhw_l_per_h * J_PER_L / SECONDS_PER_HOUR)
    assert 0.0 <= f.q_dhw_unmet_w <= f.q_dhw_demand_w + f.q_dhw_loss_w + 1e-9
    stored_w = (n.v_dhw_l - s.v_dhw_l) * J_PER_L / (dt_h * SECONDS_PER_HOUR)
    served_w = f.q_dhw_demand_w + f.q_dhw_loss_w - f.q_dhw_unmet_w
    assert stored_w == pytest.approx(f.q_hp_dhw_w + f.q_fc_rec_w - served_w, abs=1e-6)
    # Heat is dumped, or HP DHW heat reduced, only when the tank is full.
    if f.q_fc_dump_w > 1e-9:
        assert n.v_dhw_l == pytest.approx(DHW.v_max_l)
    # Unmet demand only when the tank hits V_min.
    if f.q_dhw_unmet_w > 1e-9:
        assert n.v_dhw_l == DHW.v_min_l

    assert f.p_pv_w == e.p_pv_w and f.p_load_w == e.p_load_w
    assert isinstance(f.clipped, int) and f.clipped >= 0


@settings(max_examples=200, deadline=None)
@given(states, exos, st.floats(0, 1), st.floats(FC.p_min_w, FC.zeta * FC.p_max_w), st.floats(-1000, 1000))
def test_valid_actions_are_not_clipped_when_storage_has_room(s, e, mod, p_fc, p_bess):
    """An in-range action on a plant with room in every store passes unchanged."""
    s.soc, s.loh, s.v_dhw_l = 0.5, 0.5, 60.0
    e.dhw_l_per_h = 0.0
    mod = mod if mod >= HP.mod_min else 0.0
    n, f = PLANT.step(s, Action(hp_mod=mod, hp_mode=HP_SH, p_fc_w=p_fc, p_bess_w=p_bess), e)
    assert f.clipped == 0
    assert f.hp_mod == mod and f.p_fc_w == p_fc
    assert f.p_ch_w - f.p_dis_w == pytest.approx(p_bess)
