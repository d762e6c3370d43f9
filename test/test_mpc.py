"""Tests of the MILP MPC (comems4build_ros.core.ems.mpc): costs, small known optima, soft bounds,
fallback on a real solver failure, and the information restriction."""

from __future__ import annotations

import dataclasses
import itertools
from types import MappingProxyType

import numpy as np
import pytest

from comems4build_ros.core.config import W_PER_KW, load_plant_params
from comems4build_ros.core.ems.base import FORECAST_KEYS, InformationError, Observation
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.ems.mpc import MPCController
from comems4build_ros.core.ems.mpc.costs import lifecycle_costs
from comems4build_ros.core.ems.mpc.horizon import loh_min_schedule
from comems4build_ros.core.types import HP_OFF

SELL = 0.0794



@pytest.fixture(scope="module")
def params3():
    """3-step horizon, battery without power (so only the FC and the grid matter)."""
    return load_plant_params(overrides={"simulation.horizon_h": 3, "battery.p_ch_max_w": 0.0,
                                        "battery.p_d_max_w": 0.0})


def mpc_obs(n: int, *, prices, load_w, t_air=21.0, t_min=-50.0, t_max=60.0, v_dhw=200.0, soc=0.5, loh=1.0,
            fc_on_prev=False, dloh=1.0, t_amb=5.0, dhw_l=0.0, day_index=0, hour=0, step=0,
            t_wall_in=20.0, t_wall_out=10.0) -> Observation:
    """An observation of level "mpc" with constant weather and the given series."""
    prices = tuple(float(p) for p in prices)
    fc = {
        "t_amb_c": (t_amb,) * n, "ghi_w_m2": (0.0,) * n, "p_pv_w": (0.0,) * n,
        "p_load_w": tuple(np.broadcast_to(load_w, n).astype(float)), "dhw_l_per_h": (dhw_l,) * n,
        "t_min_c": tuple(np.broadcast_to(t_min, n).astype(float)), "t_max_c": (t_max,) * n,
        "price_buy_eur_per_kwh": prices,
    }
    data = dict(step=step, day_index=day_index, hour_of_day=hour, weekday=0, is_weekend=False, t_air_c=t_air,
                v_dhw_l=v_dhw, soc=soc, loh=loh, hp_mod_prev=0.0, p_pv_w=0.0, p_load_w=fc["p_load_w"][0],
                t_min_c=fc["t_min_c"][0], t_max_c=t_max, price_buy_eur_per_kwh=prices[0],
                price_sell_eur_per_kwh=SELL, prices_buy_24h=prices, t_min_5h_c=fc["t_min_c"][:1] * 6,
                ghi_w_m2=0.0, dloh_per_day=dloh, fc_on_prev=fc_on_prev, el_on_prev=False,
                days_to_heating_season=0.0, heating_season_days_left=84.0, t_amb_c=t_amb, t_wall_in_c=t_wall_in,
                t_wall_out_c=t_wall_out, forecast=MappingProxyType(fc))
    return Observation("mpc", data)


def test_lifecycle_costs_from_table(params):
    """eq:batt_andFC_operation_degradation / eq:batt_lifecycle with tab:degradation_HESS by hand."""
    c = lifecycle_costs(params, "eta_el_mpc")
    # L_B = 6.5 kWh / 1 kW * 6000 = 39000 h; sigma = 900 / 39000 / 0.93 per h at 1 kW
    assert c.l_b_ch_h == pytest.approx(39000.0)
    assert c.sigma_b_ch_eur_per_kwh == pytest.approx(900.0 / 39000.0 / 0.93)
    assert c.sigma_b_d_eur_per_kwh == pytest.approx(0.024814, abs=1e-6)
    # (10908 / 35000 + 0.038) / 0.48
    assert c.sigma_fc_eur_per_h == pytest.approx(0.728452, abs=1e-6)
    assert lifecycle_costs(params, "one").sigma_fc_eur_per_h == pytest.approx(0.349657, abs=1e-6)
    assert (c.sigma_fc_on_eur, c.sigma_fc_off_eur) == (0.10, 0.053)


def test_loh_min_schedule(params):
    """eq:LOHmin_MPC: LOH_init - dLOH * day number (from 1); 'step' mode rolls into the next day."""
    ctrl = MPCController(params, {})
    day = loh_min_schedule(2, 20, 1 / 84, ctrl.const, "day")
    assert np.allclose(day, 1 - 3 / 84)
    step = loh_min_schedule(2, 20, 1 / 84, ctrl.const, "step")
    assert np.allclose(step[:4], 1 - 3 / 84) and np.allclose(step[4:], 1 - 4 / 84)
    assert np.all(loh_min_schedule(200, 0, 1 / 84, ctrl.const, "day") == 0.0)  # never below the store's min


def fc_enumeration(prices, load_w, params, fc_on_prev=False, fc_eta="one"):
    """Cost of every FC on/off pattern for the 3-step case, by hand.

    Load above zeta * P_max, no PV and no battery power: an FC that is on runs at
    zeta * P_max (H2 has no price in eq:mpc_objective), the grid buys the rest.
    """
    p_fc = params.fuel_cell.zeta * params.fuel_cell.p_max_w
    c = lifecycle_costs(params, fc_eta)
    out = {}
    for pattern in itertools.product((0, 1), repeat=len(prices)):
        cost, prev = 0.0, int(fc_on_prev)
        for s, p in zip(pattern, prices):
            cost += p * (load_w - s * p_fc) / W_PER_KW + c.sigma_fc_eur_per_h * s
            cost += c.sigma_fc_on_eur * (s and not prev) + c.sigma_fc_off_eur * (prev and not s)
            prev = s
        out[pattern] = cost
    return out


@pytest.mark.parametrize("fc_eta", ["one", "eta_el_mpc"])
@pytest.mark.parametrize("formulation", ["tight", "paper"])
@pytest.mark.parametrize("prices", [(0.2, 0.6, 0.2), (0.6, 0.6, 0.2), (0.15, 0.15, 0.15), (0.6, 0.1, 0.6)])
def test_three_step_optimum_matches_enumeration(params3, prices, formulation, fc_eta):
    load = 2500.0
    ctrl = MPCController(params3, {"mip_rel_gap": 0.0, "warm_start": False, "formulation": formulation,
                                   "integer_steps": 3, "fc_lifecycle_eta": fc_eta})
    action = ctrl.act(mpc_obs(3, prices=prices, load_w=load))
    costs = fc_enumeration(prices, load, params3, fc_eta=fc_eta)
    best = min(costs, key=costs.get)
    res = ctrl.last_result
    assert res.optimal
    assert res.objective == pytest.approx(costs[best], abs=1e-6)
    assert tuple(int(round(v)) for v in res.plan["s_fc"]) == best
    p_fc = params3.fuel_cell.zeta * params3.fuel_cell.p_max_w
    assert action.p_fc_w == pytest.approx(p_fc * best[0], abs=1e-3)
    assert action.hp_mode == HP_OFF and action.p_bess_w == 0.0
    assert ctrl.step_info["slack_used"] == 0.0 and ctrl.step_info["fallback"] == 0.0


def test_three_step_running_fc_is_kept_on(params3):
    """With the FC on before the horizon, stopping costs sigma_off (eq:on_off_logic)."""
    prices, load = (0.2, 0.2, 0.1), 2500.0
    ctrl = MPCController(params3, {"mip_rel_gap": 0.0, "warm_start": False, "fc_lifecycle_eta": "one"})
    ctrl.act(mpc_obs(3, prices=prices, load_w=load, fc_on_prev=True))
    costs = fc_enumeration(prices, load, params3, fc_on_prev=True)
    best = min(costs, key=costs.get)
    assert ctrl.last_result.objective == pytest.approx(costs[best], abs=1e-6)
    assert tuple(int(round(v)) for v in ctrl.last_result.plan["s_fc"]) == best


@pytest.mark.parametrize("dump", [False, True])
def test_full_tank_and_fc_heat(params3, dump):
    """eq:DHW_heat as printed (``fc_heat_dump: false``, the default): recovered FC heat must enter the
    tank, so with the tank at V_max and no draw the plan keeps the FC off at a high price; with the
    dump allowed it runs the FC and dumps its heat."""
    assert MPCController(params3, {}).settings.fc_heat_dump is False
    ctrl = MPCController(params3, {"mip_rel_gap": 0.0, "warm_start": False, "fc_heat_dump": dump})
    v_max = params3.dhw.v_max_l
    action = ctrl.act(mpc_obs(3, prices=(0.6, 0.6, 0.6), load_w=2500.0, v_dhw=v_max))
    plan = ctrl.last_result.plan
    assert ctrl.last_result.optimal
    if dump:
        assert action.p_fc_w > 0.0 and plan["q_dump"][0] > 0.0
        assert np.all(plan["v_dhw"] <= v_max + 1e-6)
    else:
        assert action.p_fc_w == 0.0 and np.all(plan["q_dump"] == 0.0)
        assert np.all(np.round(plan["s_fc"]) == 0)


def test_buy_price_below_the_sell_price_is_bounded(params3):
    """Spot below (p_sell - a) / b (-16 EUR/MWh with the default tariff): buying to sell would be
    unbounded without the physical bound P_sell <= P_PV + P_FC,max + P_d,max in those steps (winters
    before 2022 have such hours). Hand value: no PV, battery without power, so at most P_FC,max is
    sold, and the step with the dearer buy price is not bounded."""
    ctrl = MPCController(params3, {"mip_rel_gap": 0.0, "warm_start": False})
    ctrl.act(mpc_obs(3, prices=(0.05, 0.05, 0.3), load_w=500.0))
    res = ctrl.last_result
    assert res.optimal and ctrl.n_fallback == 0
    fc_max = ctrl.const.p_fc_max_w
    assert np.all(res.plan["p_sell"][:2] <= fc_max + 1e-6)
    sell = ctrl.model.v["p_sell"]
    assert sell[0].upBound == pytest.approx(fc_max) and sell[2].upBound is None


def test_names_are_time_indexed(params):
    ctrl = MPCController(params, {})
    names = set(ctrl.model.prob.constraints)
    for base in ("balance", "soc", "loh", "dhw", "air", "comfort_lo", "fc_max", "hp_excl"):
        assert f"{base}_0" in names and f"{base}_23" in names
    var_names = {v.name for v in ctrl.model.prob.variables()}
    assert {"soc_0", "p_fc_23", "s_fc_5", "t_air_12"} <= var_names


def test_soft_comfort_bound_reports_slack(params):
    """A room 10 K below T_min cannot be heated in one hour: the slack is used and reported."""
    n = params.simulation.horizon_h
    ctrl = MPCController(params, {"mip_rel_gap": 0.0})
    obs = mpc_obs(n, prices=[0.4] * n, load_w=500.0, t_air=11.0, t_min=21.0, t_max=24.0,
                  t_wall_in=11.0, t_wall_out=5.0, t_amb=0.0, dloh=1 / 84)
    action = ctrl.act(obs)
    info = ctrl.step_info
    assert info["fallback"] == 0.0 and info["slack_used"] == 1.0
    assert info["slack_t_lo_k"] > 5.0  # about 10 K minus what one hour of full heating gives
    assert info["slack_steps_plan"] >= 2
    # the predicted air temperature plus the slack is exactly T_min
    assert ctrl.last_result.plan["t_air"][0] + info["slack_t_lo_k"] == pytest.approx(21.0, abs=1e-6)
    assert action.hp_mode != HP_OFF and action.hp_mod == pytest.approx(1.0)
    assert ctrl.n_slack == 1


def test_no_slack_in_a_feasible_case(params):
    n = params.simulation.horizon_h
    ctrl = MPCController(params, {})
    ctrl.act(mpc_obs(n, prices=[0.4] * n, load_w=500.0, t_air=21.5, t_min=18.0, t_max=24.0, t_wall_in=21.0,
                     t_wall_out=12.0, dloh=1 / 84, dhw_l=5.0))
    assert ctrl.step_info["slack_used"] == 0.0 and ctrl.step_info["slack_steps_plan"] == 0.0


#: HiGHS options that stop every solve before a solution (a time limit that short is refused as no real limit).
NO_ITERATION = {"simplex_iteration_limit": 0, "mip_max_nodes": 0}


def test_a_time_limit_no_solve_can_meet_is_refused(params):
    from comems4build_ros.core.config import ConfigError

    for limit in (0.0, 5e-324, 0.05):
        with pytest.raises(ConfigError, match=r"'time_limit_s': .* is below 0.1, the smallest real value"):
            MPCController(params, {"time_limit_s": limit})


def test_solver_failure_falls_back_and_run_continues(params, capsys):
    """HiGHS stopped before any solution (no simplex iteration, no node): safe fallback, counted, logged."""
    n = params.simulation.horizon_h
    ctrl = MPCController(params, {"highs_options": NO_ITERATION})
    for step in range(2):
        obs = mpc_obs(n, prices=[0.4] * n, load_w=500.0, t_air=18.2, t_min=18.0, t_max=24.0, v_dhw=150.0,
                      dloh=1 / 84, step=step)
        action = ctrl.act(obs)
        assert ctrl.last_result.status == "No Solution Found"
        assert ctrl.step_info["fallback"] == 1.0 and ctrl.step_info["status"] == 0.0
        assert action == safe_action(18.2, 150.0, 18.0, params)
    assert ctrl.n_fallback == 2
    assert "no solution" in capsys.readouterr().err


def test_time_limited_solve_uses_best_solution(params):
    """A solve stopped by its limit with an incumbent still gives a planned action (status 2 or 1)."""
    n = params.simulation.horizon_h
    ctrl = MPCController(params, {"time_limit_s": 0.1, "mip_rel_gap": 0.0, "integer_steps": 24})
    ctrl.act(mpc_obs(n, prices=np.linspace(0.2, 0.6, n), load_w=800.0, t_air=19.0, t_min=18.0, t_max=24.0,
                     dloh=1 / 84))
    if ctrl.step_info["fallback"] == 0.0:
        assert ctrl.step_info["status"] in (1.0, 2.0)
        assert np.isfinite(ctrl.step_info["objective_eur"])


def test_cbc_and_highs_agree(params3):
    prices, load = (0.2, 0.6, 0.5), 2500.0
    objs = []
    for solver in ("highs", "cbc"):
        ctrl = MPCController(params3, {"solver": solver, "mip_rel_gap": 0.0, "warm_start": True})
        ctrl.act(mpc_obs(3, prices=prices, load_w=load))
        ctrl.act(mpc_obs(3, prices=prices, load_w=load))  # second solve with a warm start
        objs.append(ctrl.last_result.objective)
    assert objs[0] == pytest.approx(objs[1], abs=1e-6)


def test_unknown_solver_and_option_raise(params):
    from comems4build_ros.core.config import ConfigError

    with pytest.raises(ConfigError, match="solver"):
        MPCController(params, {"solver": "cplex"})
    with pytest.raises(ConfigError, match="mip_rel_gap"):
        MPCController(params, {"mip_rel_gap": -1})


# ------------------------------------------------------------------ information restriction
def test_mpc_refuses_fields_outside_its_level(params):
    """The MPC needs the wall temperatures: a fuzzy-level observation makes it raise."""
    obs = mpc_obs(params.simulation.horizon_h, prices=[0.4] * 24, load_w=500.0)
    data = obs.as_dict()
    fuzzy = Observation("fuzzy", data)
    with pytest.raises(InformationError):
        MPCController(params, {}).act(fuzzy)
    with pytest.raises(InformationError):
        obs.spot_eur_per_mwh  # noqa: B018 - reading a field outside the level raises
    assert set(obs.forecast) == set(FORECAST_KEYS)


@pytest.fixture(scope="module")
def week():
    from comems4build_ros.core.scenario import default_scenario

    p = load_plant_params()
    return p, default_scenario(p, weeks=1)


def _action_at(params, scenario, k):
    from comems4build_ros.core.loop import ObservationBuilder, exogenous_series
    from comems4build_ros.core.plant import Plant

    builder = ObservationBuilder(scenario, params, "mpc", exogenous_series(scenario, params))
    obs = builder.build(k, Plant(params).initial_state())
    ctrl = MPCController(params, {"mip_rel_gap": 0.0, "warm_start": False})
    return ctrl.act(obs), ctrl.last_result.objective


def test_action_ignores_the_scenario_beyond_the_horizon(week):
    """Perturbing every series after k + 23 changes nothing; perturbing inside the horizon does."""
    params, scenario = week
    k = 30
    base_action, base_obj = _action_at(params, scenario, k)

    def perturbed(lo, hi):
        s = dataclasses.replace(scenario)
        for name in ("t_amb_c", "ghi_w_m2", "dhi_w_m2", "price_buy_eur_per_kwh", "p_load_w", "dhw_l_per_h",
                     "t_min_c"):
            arr = getattr(scenario, name).copy()
            arr[lo:hi] = arr[lo:hi] * 3.0 + (5.0 if name == "t_min_c" else 1.0)
            setattr(s, name, arr)
        return s

    after_action, after_obj = _action_at(params, perturbed(k + 24, len(scenario.time)), k)
    assert after_action == base_action and after_obj == pytest.approx(base_obj, rel=1e-9)
    inside_action, inside_obj = _action_at(params, perturbed(k, k + 24), k)
    assert inside_obj != pytest.approx(base_obj, rel=1e-3)
