"""Tests of the continuous OSQP variant (comems4build_ros.core.ems.mpc.qp)."""

from __future__ import annotations

import numpy as np
import pytest
from test_mpc import mpc_obs, params3  # noqa: F401 (fixture)

from comems4build_ros.core.ems.mpc import MPCController, QPController
from comems4build_ros.core.ems.mpc.qp import _round_semicontinuous
from comems4build_ros.core.types import HP_OFF


def test_round_semicontinuous():
    assert _round_semicontinuous(0.05, 0.2, 1.0) == 0.0
    assert _round_semicontinuous(0.15, 0.2, 1.0) == 0.2
    assert _round_semicontinuous(0.5, 0.2, 1.0) == 0.5
    assert _round_semicontinuous(1.3, 0.2, 1.0) == 1.0


def test_qp_plan_obeys_the_model_and_devices(params):
    n = params.simulation.horizon_h
    prices = 0.3 + 0.2 * np.sin(np.arange(n) / 24 * 2 * np.pi)
    ctrl = QPController(params, {})
    action = ctrl.act(mpc_obs(n, prices=prices, load_w=600.0, t_air=19.0, t_min=18.0, t_max=24.0, dloh=1 / 84,
                              dhw_l=8.0, t_amb=2.0))
    assert ctrl.step_info["fallback"] == 0.0 and ctrl.step_info["status"] in (1.0, 2.0)
    plan = ctrl.last_plan
    # eq:power_balance holds in the plan (W), to the solver tolerance
    resid = (plan["p_buy"] - plan["p_sell"] + plan["p_fc"] + plan["p_dis"] - plan["p_ch"] - plan["p_hp_sh"]
             - plan["p_hp_dhw"] - (600.0 - 0.0))
    assert np.max(np.abs(resid)) < 5.0
    # the applied action lies in the device sets
    assert action.hp_mod == 0.0 or params.heat_pump.mod_min <= action.hp_mod <= 1.0
    if action.hp_mod == 0.0:
        assert action.hp_mode == HP_OFF
    fc = params.fuel_cell
    assert action.p_fc_w == 0.0 or fc.p_min_w <= action.p_fc_w <= fc.zeta * fc.p_max_w + 1e-6
    # the LOH never goes below the day's LOH_min (soft bound not needed here)
    assert plan["loh"].min() >= 1 - 1 / 84 - 1e-3


def test_qp_cost_is_a_lower_bound_of_the_milp(params):
    """Relaxing binaries can only lower the cost part shared with the MILP (without quadratic terms)."""
    n = params.simulation.horizon_h
    obs = mpc_obs(n, prices=np.full(n, 0.45), load_w=900.0, t_air=20.0, t_min=18.0, t_max=24.0, dloh=1 / 84)
    qp = QPController(params, {"w_fc_smooth_eur_per_kw2": 0.0, "w_comfort_track_eur_per_k2": 0.0,
                               "w_reg_eur_per_kw2": 1e-4, "max_iter": 200000})
    qp.act(obs)
    assert qp.step_info["fallback"] == 0.0
    milp = MPCController(params, {"mip_rel_gap": 0.0, "integer_steps": 24})
    milp.act(obs)
    p = qp.last_plan
    grid_qp = np.sum(0.45 * p["p_buy"] - 0.0794 * p["p_sell"]) / 1000
    m = milp.last_result.plan
    grid_milp = np.sum(0.45 * m["p_buy"] - 0.0794 * m["p_sell"]) / 1000
    c = milp.const.costs
    life_qp = np.sum(c.sigma_fc_eur_per_h * p["p_fc"] / milp.const.p_fc_max_w)
    life_milp = np.sum(c.sigma_fc_eur_per_h * m["s_fc"] + c.sigma_fc_on_eur * m["s_fc_on"]
                       + c.sigma_fc_off_eur * m["s_fc_off"])
    bat_qp = np.sum(c.sigma_b_ch_eur_per_kwh * p["p_ch"] + c.sigma_b_d_eur_per_kwh * p["p_dis"]) / 1000
    bat_milp = np.sum(c.sigma_b_ch_eur_per_kwh * m["p_ch"] + c.sigma_b_d_eur_per_kwh * m["p_dis"]) / 1000
    assert grid_qp + life_qp + bat_qp <= grid_milp + life_milp + bat_milp + 0.02


@pytest.mark.parametrize("dump", [False, True])
def test_full_tank_and_fc_heat(params3, dump):  # noqa: F811 (fixture)
    """As the MILP: with eq:DHW_heat as printed (``fc_heat_dump: false``, the default) the recovered
    FC heat must enter the tank, so with the tank at V_max and no draw the relaxed plan keeps the FC
    off at a high price, up to the heat the tank loses; with the dump allowed it runs the FC and dumps its heat."""
    assert QPController(params3, {}).settings.fc_heat_dump is False
    ctrl = QPController(params3, {"fc_heat_dump": dump, "eps_abs": 1e-5, "eps_rel": 1e-5, "max_iter": 200000})
    v_max = params3.dhw.v_max_l
    action = ctrl.act(mpc_obs(3, prices=(0.6, 0.6, 0.6), load_w=2500.0, v_dhw=v_max))
    plan = ctrl.last_plan
    assert ctrl.step_info["fallback"] == 0.0
    if dump:
        assert action.p_fc_w > 0.0 and plan["q_dump"][0] > 100.0
    else:
        assert action.p_fc_w == 0.0 and np.all(np.abs(plan["q_dump"]) < 1.0)
        # at most the standing losses (eq:DHW_model) are made up by recovered heat
        k = ctrl.const
        assert np.all(k.k_fc_heat * plan["p_fc"] <= k.q_dhw_loss_w + 5.0)
