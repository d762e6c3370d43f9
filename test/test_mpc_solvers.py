"""Solver backends of the MILP MPC: the solver model kept in memory and updated in place gives
the same optimum as a model built afresh, the time-indexed names reach the solver, the
battery binary relaxation keeps the optimum, and Gurobi (when gurobipy is installed) agrees
with HiGHS."""

from __future__ import annotations

import numpy as np
import pytest
import test_mpc
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mpc import fc_enumeration, mpc_obs

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.ems.mpc import MPCController, horizon
from comems4build_ros.core.ems.mpc import solvers as solvers_mod
from comems4build_ros.core.ems.mpc.solvers import gurobi_available

needs_gurobi = pytest.mark.skipif(not gurobi_available(),
                                  reason="gurobipy is not installed (optional extra: pip install .[gurobi])")
EXACT = {"mip_rel_gap": 0.0, "time_limit_s": 60.0, "log_fallback": False}
#: Lifecycle reading of the 3-step enumeration cases (the same in controller and enumeration).
FC_ETA = "eta_sys"

params3 = test_mpc.params3  # the 3-step plant; the full one is the shared fixture (conftest)


def varied_observations(n: int, sell: float = 0.0794) -> list:
    """Horizons that differ in every updated number: prices, loads, T_amb (COP, P_max), comfort
    bounds, DHW draw, initial states, the FC's previous state, the day (LOH_min)."""
    rng = np.random.default_rng(7)
    out = []
    for i in range(5):
        prices = rng.uniform(0.1, 0.7, n)
        obs = mpc_obs(n, prices=prices, load_w=rng.uniform(200.0, 2500.0, n), t_air=20.0 + 0.5 * i,
                      t_min=rng.choice([18.0, 20.0], n), t_max=24.0, v_dhw=120.0 + 20 * i, soc=0.2 + 0.15 * i,
                      loh=1.0 - 0.005 * i, fc_on_prev=bool(i % 2), dloh=1 / 84, t_amb=-5.0 + 4.0 * i,
                      dhw_l=3.0 * i, day_index=i, step=i, t_wall_in=19.0 + 0.3 * i, t_wall_out=8.0 + i)
        if sell != 0.0794:
            data = obs.as_dict()
            data["price_sell_eur_per_kwh"] = sell
            obs = type(obs)("mpc", data)
        out.append(obs)
    return out


@pytest.mark.parametrize("solver", ["highs", pytest.param("gurobi", marks=needs_gurobi)])
@pytest.mark.parametrize("formulation", ["tight", "paper"])
def test_model_updated_in_place_equals_fresh_model(params, solver, formulation):
    """One controller solving a sequence of different horizons (its solver model updated in
    place) reaches the same optimum as a new controller per horizon."""
    opts = {**EXACT, "solver": solver, "formulation": formulation, "warm_start": False}
    kept = MPCController(params, opts)
    for obs in varied_observations(params.simulation.horizon_h):
        kept.act(obs)
        fresh = MPCController(params, opts)
        fresh.act(obs)
        assert kept.last_result.optimal and fresh.last_result.optimal
        assert kept.last_result.objective == pytest.approx(fresh.last_result.objective, rel=1e-6, abs=1e-6)


def test_fixing_the_first_step_reaches_the_solver(params):
    """Bounds changed through PuLP (fix_first_step) reach the HiGHS model and are released again."""
    n = params.simulation.horizon_h
    obs = varied_observations(n)[2]
    ctrl = MPCController(params, {**EXACT, "warm_start": False})
    free = ctrl.plan(obs).objective
    ctrl.model.fix_first_step({name: 1.0 for name in ctrl.model.binary_names() if name == "s_fc"} | {
        name: 0.0 for name in ctrl.model.binary_names() if name != "s_fc"})
    fixed = ctrl.plan(obs)
    assert fixed.plan["s_fc"][0] == pytest.approx(1.0) and fixed.plan["p_fc"][0] > 0
    assert fixed.objective >= free - 1e-9
    ctrl.model.fix_first_step(None)
    assert ctrl.plan(obs).objective == pytest.approx(free, abs=1e-6)


@pytest.mark.parametrize("solver", ["highs", pytest.param("gurobi", marks=needs_gurobi)])
def test_a_solve_does_not_depend_on_the_solves_before(params, solver):
    """Default settings without warm start: the plan for a horizon is the same after a sequence
    of other solves as from a new controller (no solver state carried between solves)."""
    n = params.simulation.horizon_h
    obs = varied_observations(n)
    opts = {"solver": solver, "warm_start": False, "log_fallback": False}
    kept = MPCController(params, opts)
    for o in obs:
        kept.act(o)
    fresh = MPCController(params, opts)
    fresh.act(obs[-1])
    for name, vals in fresh.last_result.plan.items():
        np.testing.assert_array_equal(kept.last_result.plan[name], vals, err_msg=name)


@pytest.mark.parametrize("sell", [0.0794, -0.05])
def test_battery_binary_relaxation_keeps_the_optimum(params, sell):
    """Relaxing b_ch (sell price >= 0) leaves the optimum unchanged; with a negative sell price
    b_ch is binary again in the same kept model (integrality passed in place)."""
    n = params.simulation.horizon_h
    relaxed = MPCController(params, {**EXACT, "relax_battery_binary": True, "warm_start": False})
    binary = MPCController(params, {**EXACT, "relax_battery_binary": False, "warm_start": False})
    for obs in varied_observations(n, sell=sell)[:3]:
        relaxed.act(obs)
        binary.act(obs)
        assert relaxed.model.v["b_ch"][0].cat == ("Continuous" if sell >= 0 else "Integer")
        assert relaxed.last_result.objective == pytest.approx(binary.last_result.objective, rel=1e-6, abs=1e-6)
        plan = relaxed.last_result.plan
        if sell < 0:  # exclusion enforced: never both in one hour
            assert np.all(np.minimum(plan["p_ch"][:6], plan["p_dis"][:6]) < 1e-6)


@pytest.mark.parametrize("solver", ["highs", "highs_pulp", "cbc", pytest.param("gurobi", marks=needs_gurobi)])
def test_every_solver_matches_the_enumeration(params3, solver):
    """The 3-step FC case solved by hand (test_mpc.fc_enumeration), through every backend."""
    prices, load = (0.2, 0.6, 0.5), 2500.0
    costs = fc_enumeration(prices, load, params3, fc_eta=FC_ETA)
    best = min(costs, key=costs.get)
    ctrl = MPCController(params3, {"solver": solver, "mip_rel_gap": 0.0, "warm_start": True, "integer_steps": 3,
                                   "fc_lifecycle_eta": FC_ETA})
    for _ in range(2):  # the second solve is warm-started and runs on the updated model
        ctrl.act(mpc_obs(3, prices=prices, load_w=load))
        assert ctrl.last_result.objective == pytest.approx(costs[best], abs=1e-6)
        assert tuple(int(round(v)) for v in ctrl.last_result.plan["s_fc"]) == best


def test_highs_model_carries_the_time_indexed_names(params):
    ctrl = MPCController(params, {})
    ctrl.act(varied_observations(params.simulation.horizon_h)[0])
    lp = ctrl.backend.h.getLp()
    assert list(lp.col_names_) == [v.name for v in ctrl.model.prob.variables()]
    assert list(lp.row_names_) == list(ctrl.model.prob.constraints)
    assert {"soc_0", "p_fc_23", "s_fc_5"} <= set(lp.col_names_)
    assert {"balance_0", "comfort_lo_12", "fc_switch_23"} <= set(lp.row_names_)


def test_model_fits_the_restricted_gurobi_licence(params):
    """gurobipy's bundled licence solves models of up to 2000 variables and 2000 constraints."""
    for formulation in ("tight", "paper"):
        form = MPCController(params, {"formulation": formulation}).model.form
        assert form.n_cols <= 2000 and form.n_rows <= 2000, (formulation, form.n_cols, form.n_rows)


def test_gurobi_without_gurobipy_is_a_clear_error(params, monkeypatch):
    monkeypatch.setattr(solvers_mod, "gurobi_available", lambda: False)
    with pytest.raises(ConfigError, match="gurobipy is not installed"):
        MPCController(params, {"solver": "gurobi"})


def test_unknown_highs_option_is_a_clear_error(params):
    with pytest.raises(ConfigError, match="no_such_option"):
        MPCController(params, {"highs_options": {"no_such_option": 1}})


@needs_gurobi
def test_gurobi_model_carries_the_time_indexed_names(params):
    ctrl = MPCController(params, {"solver": "gurobi"})
    m = ctrl.backend.model
    assert [v.VarName for v in m.getVars()] == [v.name for v in ctrl.model.prob.variables()]
    assert [c.ConstrName for c in m.getConstrs()] == list(ctrl.model.prob.constraints)


@needs_gurobi
def test_gurobi_and_highs_agree_on_full_horizons(params):
    """Exact optima of 24-step horizons with both solvers, warm-started chains."""
    n = params.simulation.horizon_h
    ctrls = {s: MPCController(params, {**EXACT, "solver": s}) for s in ("highs", "gurobi")}
    for obs in varied_observations(n):
        objs = {}
        for s, ctrl in ctrls.items():
            ctrl.act(obs)
            assert ctrl.step_info["fallback"] == 0.0 and ctrl.step_info["status"] == 1.0
            objs[s] = ctrl.last_result.objective
        assert objs["gurobi"] == pytest.approx(objs["highs"], rel=1e-6, abs=1e-6)


@needs_gurobi
def test_gurobi_time_limit_zero_falls_back(params):
    """Gurobi stopped before any solution (no iteration): safe fallback, as with HiGHS."""
    n = params.simulation.horizon_h
    ctrl = MPCController(params, {"solver": "gurobi", "gurobi_options": {"IterationLimit": 0, "NodeLimit": 0},
                                  "log_fallback": False})
    ctrl.act(mpc_obs(n, prices=[0.4] * n, load_w=500.0, t_air=18.2, t_min=18.0, t_max=24.0, dloh=1 / 84))
    assert ctrl.step_info["fallback"] == 1.0 and ctrl.n_fallback == 1


def test_controllers_with_different_thread_counts_in_one_process(params3):
    """HiGHS runs one task scheduler per process; the backends restart it when the thread count
    changes, so controllers with 1 and 2 threads can alternate (no "Not Set" failure)."""
    prices, load = (0.2, 0.6, 0.5), 2500.0
    costs = fc_enumeration(prices, load, params3, fc_eta=FC_ETA)
    ctrls = [MPCController(params3, {"solver": s, "threads": t, "mip_rel_gap": 0.0, "integer_steps": 3,
                                     "fc_lifecycle_eta": FC_ETA})
             for t in (2, 1) for s in ("highs", "highs_pulp")]
    for _ in range(2):
        for ctrl in ctrls:
            ctrl.act(mpc_obs(3, prices=prices, load_w=load))
            assert ctrl.step_info["fallback"] == 0.0
            assert ctrl.last_result.objective == pytest.approx(min(costs.values()), abs=1e-6)


@pytest.mark.parametrize("solver", ["cbc", "highs_pulp", pytest.param("gurobi", marks=needs_gurobi)])
def test_solvers_agree_within_the_mip_gap(params, solver):
    """Default settings (relaxed tail, gap 1 %) on 24-step horizons: HiGHS and each other solver
    return objectives within the relative gap of the same MILP's optimum (HiGHS at gap 0)."""
    n = params.simulation.horizon_h
    gap = 0.01
    exact = MPCController(params, {**EXACT, "warm_start": False})
    ctrls = {s: MPCController(params, {"solver": s, "mip_rel_gap": gap, "warm_start": False, "log_fallback": False})
             for s in ("highs", solver)}
    for obs in varied_observations(n)[:3]:
        exact.act(obs)
        best = exact.last_result.objective
        for s, ctrl in ctrls.items():
            ctrl.act(obs)
            assert ctrl.step_info["fallback"] == 0.0, s
            obj = ctrl.last_result.objective
            assert best - 1e-6 <= obj <= best + gap * abs(best) + 1e-6, (s, obj, best)


# ---------------------------------------------------------------------- the same plans on every CPU
@settings(max_examples=200, derandomize=True, database=None, deadline=None)
@given(st.floats(min_value=-1e300, max_value=1e300, allow_subnormal=False).filter(lambda v: v != 0.0),
       st.integers(min_value=8, max_value=40))
def test_round_bits_rounds_to_bits(x: float, bits: int) -> None:
    """Rounded to ``bits`` significant bits: within half a step, idempotent, sign kept, and numbers a
    few ulp apart (another CPU's math library) the same unless they straddle a step's middle."""
    q = float(horizon.round_bits(x, bits))
    m, e = np.frexp(x)
    assert abs(q - x) <= 2.0 ** (e - bits - 1)
    assert float(horizon.round_bits(q, bits)) == q
    assert np.sign(q) == np.sign(x) or q == 0.0
    near = [x]
    for _ in range(3):
        near.append(float(np.nextafter(near[-1], np.inf)))
    rounded = {float(v) for v in horizon.round_bits(np.array(near), bits)}
    if len(rounded) > 1:  # only at the middle between two steps (round half to even)
        mids = [(lo + hi) / 2 for lo, hi in zip(sorted(rounded), sorted(rounded)[1:], strict=False)]
        assert all(min(near) <= mid <= max(near) for mid in mids)


def test_round_bits_keeps_zeros_infinities_and_order() -> None:
    x = np.array([-np.inf, -3.0e5, -1.0 / 3.0, 0.0, 1e-300, 0.1, 2.0 / 3.0, 1.0, 1e5, np.inf])
    q = horizon.round_bits(x, 20)
    assert q[0] == -np.inf and q[3] == 0.0 and q[-1] == np.inf
    assert np.all(np.diff(q) >= 0)  # monotone: a bound below another stays below it
    assert q[1] == -3.0e5 and q[7] == 1.0 and q[8] == 1e5  # representable in 20 bits: unchanged
    assert q[2] != x[2] and abs(q[2] - x[2]) <= 2.0 ** -22  # 1/3 = 0.5 * 2**-1: step 2**-21
    np.testing.assert_array_equal(horizon.round_bits(x, 53), x)  # 53 bits: every float as it is


def _nudged_run(seed: int, steps: int) -> list[tuple[float, ...]]:
    """The MPC's commands over the first ``steps`` of the default scenario, its modelled series
    (radiation from pvlib's clear sky, the load model) nudged by up to 3 ulp per value (seed 0:
    as they are), as another CPU's math library gives them."""
    import dataclasses

    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_plant_params()
    scenario = dataclasses.replace(resolve_scenario("default", params, weeks=1), n_steps=steps)
    if seed:
        rng = np.random.default_rng(seed)
        nudged = {}
        for name in ("ghi_w_m2", "dhi_w_m2", "p_load_w"):
            x = getattr(scenario, name).copy()
            for j, k in enumerate(rng.integers(-3, 4, x.size)):
                for _ in range(abs(int(k)) if x[j] != 0.0 else 0):  # zero stays zero (no negative irradiance)
                    x[j] = np.nextafter(x[j], np.inf if k > 0 else -np.inf)
            nudged[name] = x
        scenario = dataclasses.replace(scenario, **nudged)
    ts = simulate("mpc", scenario, params).timeseries
    cmd = [c for c in ts.columns if c.startswith("cmd_")]
    return [tuple(row) for row in ts[cmd].to_numpy(dtype=float)]


#: Steps of the runs below: without the rounding, these nudges change the plan from step 4 on.
NUDGED_STEPS = 12


@pytest.fixture(scope="module")
def unnudged_commands() -> list[tuple[float, ...]]:
    return _nudged_run(0, NUDGED_STEPS)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_plans_do_not_depend_on_the_last_bits_of_the_inputs(seed: int, unnudged_commands) -> None:
    """The MIP search stops at the first plan within the gap, so without the rounding of the
    horizon's numbers (``horizon.same_on_every_cpu``) last-bit differences of the inputs, as
    between CPUs (numpy's AVX-512 code paths against glibc's), lead to another plan; with it,
    the same."""
    assert _nudged_run(seed, NUDGED_STEPS) == unnudged_commands


def test_without_the_rounding_the_nudges_change_the_plans(monkeypatch: pytest.MonkeyPatch) -> None:
    """The control of the test above: every float as it is (53 bits), the same nudges give another plan."""
    monkeypatch.setattr(horizon, "FORECAST_BITS", 53)
    monkeypatch.setattr(horizon, "STATE_BITS", 53)
    assert _nudged_run(1, NUDGED_STEPS) != _nudged_run(0, NUDGED_STEPS)
