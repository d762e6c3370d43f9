"""The cost-optimal MILP model-predictive controller (``--ems mpc``, paper sec:MPC).

Each step: build the horizon numbers from the observation (:func:`.horizon.build_horizon`),
rounded so that every CPU solves the same problem (:func:`.horizon.same_on_every_cpu`),
update the MILP in place, warm-start it with the previous plan shifted by one step, solve,
and apply the first step of the plan. A solve that ends without proven optimality (time
limit) still uses the best solution found; a solve with no solution at all applies the
shared safe fallback (:func:`comems4build_ros.core.ems.fallback.safe_action`: hot water to
V_min, rooms to T_air,min, battery and FC idle, the grid covers the load), counts it in
``step_info["fallback"]`` and logs it; the run never stops.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.ems.mpc.horizon import (
    HorizonData,
    PlantConstants,
    build_horizon,
    same_on_every_cpu,
    season_schedules,
)
from comems4build_ros.core.ems.mpc.milp import SLACKS, MILPModel, Penalties, SolveResult, YearTerms, shift_plan
from comems4build_ros.core.ems.mpc.solvers import MatrixForm, make_backend
from comems4build_ros.core.ems.settings import MILPSettings, load_settings
from comems4build_ros.core.types import HP_COOL, HP_DHW, HP_OFF, HP_SH, Action

#: Values below this are treated as zero when turning a plan into an action [W] / [-].
POWER_EPS_W = 1e-3
#: step_info keys reported every step (the loop records them as ems_<key>).
STEP_INFO_KEYS = (
    "solve_s", "status", "optimal", "objective_eur", "gap", "fallback", "slack_used",
    "slack_t_lo_k", "slack_t_hi_k", "slack_v_lo_l", "slack_v_hi_l", "slack_soc", "slack_loh",
    "slack_steps_plan",
)
#: Status codes of step_info["status"]: 1 optimal, 2 feasible (not proven optimal), 0 no solution.
STATUS_OPTIMAL, STATUS_FEASIBLE, STATUS_NONE = 1, 2, 0


def penalties_from(opts: Any) -> Penalties:
    """Collect the soft-bound penalties of the MPC settings.

    Parameters
    ----------
    opts : MILPSettings or QPSettings
        The MPC's settings (``penalty_*`` [EUR per unit of the bound and hour]).

    Returns
    -------
    Penalties
        Comfort [EUR/(K h)], tank [EUR/(l h)], SOC and LOH [EUR/h per unit] penalties.
    """
    return Penalties(opts.penalty_comfort_eur_per_kh, opts.penalty_dhw_eur_per_lh, opts.penalty_soc_eur_per_h,
                     opts.penalty_loh_eur_per_h)


def action_from_plan(plan: Mapping[str, np.ndarray], h: HorizonData, const: PlantConstants) -> Action:
    """Turn the first step of a plan into an :class:`Action` (the plant clips whatever remains off-limits).

    Parameters
    ----------
    plan : Mapping[str, numpy.ndarray]
        The solved horizon: powers per step [W] (``p_hp_sh``, ``p_hp_dhw``, ``p_fc``,
        ``p_ch``, ``p_dis``, and ``p_hp_cool``, ``p_el`` on a year-round plant).
    h : HorizonData
        The horizon's numbers (``p_hp_max_w``, ``p_cool_max_w`` [W]).
    const : PlantConstants
        The plant's constants.

    Returns
    -------
    Action
        The circuit with the larger heat pump power and its modulation (power / P_el,max),
        FC, battery (> 0 charging) and electrolyser powers [W]; values below
        :data:`POWER_EPS_W` are 0.
    """
    p_sh = float(plan["p_hp_sh"][0])
    p_dhw = float(plan["p_hp_dhw"][0])
    pmax = float(h.p_hp_max_w[0])
    if max(p_sh, p_dhw) <= POWER_EPS_W or pmax <= 0:
        mode, mod = HP_OFF, 0.0
    elif p_sh >= p_dhw:
        mode, mod = HP_SH, min(p_sh / pmax, 1.0)
    else:
        mode, mod = HP_DHW, min(p_dhw / pmax, 1.0)
    if "p_hp_cool" in plan:  # year-round plant with cooling
        p_cool = float(plan["p_hp_cool"][0])
        pc = float(h.p_cool_max_w[0])
        if p_cool > POWER_EPS_W and pc > 0 and p_cool > max(p_sh, p_dhw):
            mode, mod = HP_COOL, min(p_cool / pc, 1.0)
    p_fc = float(plan["p_fc"][0])
    p_bess = float(plan["p_ch"][0] - plan["p_dis"][0])
    p_el = float(plan["p_el"][0]) if "p_el" in plan else 0.0
    return Action(
        hp_mod=mod,
        hp_mode=mode,
        p_fc_w=p_fc if p_fc > POWER_EPS_W else 0.0,
        p_bess_w=p_bess if abs(p_bess) > POWER_EPS_W else 0.0,
        p_el_w=p_el if p_el > POWER_EPS_W else 0.0,
    )


def slack_info(plan: Mapping[str, np.ndarray] | None, tol: float) -> dict[str, float]:
    """Report the slack of the applied step (t = 0) per bound and the plan steps with any slack.

    Parameters
    ----------
    plan : Mapping[str, numpy.ndarray] or None
        The solved horizon's slack variables (``sl_*``), or None without a solution.
    tol : float
        A slack above this counts as used [unit of its bound: K, l or -].

    Returns
    -------
    dict[str, float]
        ``slack_t_lo_k``, ``slack_t_hi_k`` [K], ``slack_v_lo_l``, ``slack_v_hi_l`` [l],
        ``slack_soc``, ``slack_loh`` [-] of step 0, ``slack_used`` (0 or 1) and
        ``slack_steps_plan`` (steps of the plan with any slack).
    """
    keys = {"sl_t_lo": "slack_t_lo_k", "sl_t_hi": "slack_t_hi_k", "sl_v_lo": "slack_v_lo_l",
            "sl_v_hi": "slack_v_hi_l", "sl_soc_lo": "slack_soc", "sl_soc_hi": "slack_soc", "sl_loh": "slack_loh"}
    out = dict.fromkeys(keys.values(), 0.0)
    if plan is None:
        out.update(slack_used=0.0, slack_steps_plan=0.0)
        return out
    any_step = np.zeros(len(plan["sl_t_lo"]), dtype=bool)
    for name, key in keys.items():
        out[key] += float(plan[name][0])
        any_step |= plan[name] > tol
    out["slack_used"] = 1.0 if any(plan[name][0] > tol for name in SLACKS) else 0.0
    out["slack_steps_plan"] = float(any_step.sum())
    return out


def milp_model(const: PlantConstants, o: MILPSettings, **model_options: Any) -> MILPModel:
    """Build the horizon MILP (``eq:mpc_objective``) of the plant ``const`` with the settings ``o``.

    Parameters
    ----------
    const : PlantConstants
        The plant's constants.
    o : MILPSettings
        The MPC's settings (formulation, penalties, year terms).
    **model_options : Any
        ``prefix``, ``h2_exchange``, ``integer_steps`` for :class:`.milp.MILPModel`: a community's
        coordinators compose houses' models into one problem with them.

    Returns
    -------
    MILPModel
        The model, not yet updated with a horizon's numbers.
    """
    kwargs: dict[str, Any] = {"integer_steps": o.integer_steps, **model_options}
    year = YearTerms(o.penalty_loh_season_eur_per_h, o.h2_value_eur_per_kwh, o.sigma_el_on_eur)
    return MILPModel(const, penalties_from(o), o.formulation, o.big_m_loose_w,
                     relax_battery_binary=o.relax_battery_binary, year=year, fc_heat_dump=o.fc_heat_dump, **kwargs)


def milp_backend(form: MatrixForm, o: MILPSettings, time_limit_s: float | None = None,
                 mip_rel_gap: float | None = None) -> Any:
    """Make the solver backend of the settings ``o`` for the problem ``form``.

    Parameters
    ----------
    form : MatrixForm
        The problem in matrix form.
    o : MILPSettings
        The MPC's settings (solver, gap, time limit, threads, warm start, solver options).
    time_limit_s : float, optional
        Time limit per solve [s] instead of the settings' own.
    mip_rel_gap : float, optional
        Relative MIP gap [-] instead of the settings' own.

    Returns
    -------
    Any
        The backend of :func:`.solvers.make_backend`.
    """
    return make_backend(o.solver, form, o.mip_rel_gap if mip_rel_gap is None else mip_rel_gap,
                        o.time_limit_s if time_limit_s is None else time_limit_s, o.threads, o.warm_start,
                        highs_options=o.highs_options, gurobi_options=o.gurobi_options)


class MPCController:
    """MILP MPC over a 24 h horizon (``eq:mpc_objective``).

    Parameters
    ----------
    params : PlantParams
        Plant parameters (the MPC's forecasting models).
    options : Mapping[str, Any], optional
        Overrides of ``config/mpc.yaml`` section ``mpc``
        (:class:`~comems4build_ros.core.ems.settings.MILPSettings`).
    model_options : Mapping[str, Any], optional
        Passed to :func:`milp_model` (a community's coordinators; none for a house's EMS).
    """

    name = "mpc"
    info_level = "mpc"
    settings_class = MILPSettings

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None,
                 model_options: Mapping[str, Any] | None = None) -> None:
        self.params = params
        self.settings = load_settings(MILPSettings, options)
        o = self.settings
        self.const = PlantConstants.from_params(params, o.fc_lifecycle_eta)
        self.model = milp_model(self.const, o, **dict(model_options or {}))
        self.backend = milp_backend(self.model.form, o)
        self.step_info: dict[str, float] = {}
        self.observer = None
        if o.observer == "kalman":
            from comems4build_ros.core.ems.mpc.observer import KalmanObserver, wall_split

            self.observer = KalmanObserver(self.const.ad, self.const.bd, wall_split(params.building))
        self.reset()

    def reset(self) -> None:
        """Forget the previous plan, the counters and the observer's estimate."""
        if self.observer is not None:
            self.observer.reset()
        self._prev_plan: dict[str, np.ndarray] | None = None
        self.n_fallback = 0
        self.n_slack = 0
        self.n_solves = 0
        self.last_result: SolveResult | None = None
        self.last_horizon: HorizonData | None = None
        self.step_info = dict.fromkeys(STEP_INFO_KEYS, 0.0)
        self._season_loh0: float | None = None

    def plan(self, obs: Observation) -> SolveResult:
        """Update the horizon problem for ``obs`` (:meth:`prepare`) and solve it (no action, no counters).

        Returns
        -------
        SolveResult
            The solver's status, plan, objective [EUR] and solve time [s].
        """
        self.prepare(obs)
        return self.model.solve(self.backend)

    def prepare(self, obs: Observation) -> HorizonData:
        """Update the horizon problem for ``obs`` in place and set its warm start.

        Parameters
        ----------
        obs : Observation
            States of step k-1 and 24-step forecasts (:func:`.horizon.build_horizon`).

        Returns
        -------
        HorizonData
            The horizon's numbers the model was updated with.
        """
        h = build_horizon(obs, self.const, self.settings.loh_min_mode)
        if self.const.year_round:  # seasonal schedules (memory: the LOH at the season's start)
            left = float(obs.heating_season_days_left)
            if left <= 0.0:
                self._season_loh0 = None
            elif self._season_loh0 is None:
                self._season_loh0 = float(obs.loh)
            bound, target = season_schedules(float(obs.days_to_heating_season), left, self._season_loh0,
                                             self.const, self.settings.loh_season_target)
            h = dataclasses.replace(h, loh_min=bound, loh_season=target)
        h = self.last_horizon = same_on_every_cpu(h)  # the same plan on every CPU (docs/mpc.md)
        self.model.update(h)
        self.model.set_start(shift_plan(self._prev_plan) if self.settings.warm_start and self._prev_plan else None)
        return h

    def act(self, obs: Observation) -> Action:
        """Solve the horizon problem (``eq:mpc_objective``) and return its first step.

        Parameters
        ----------
        obs : Observation
            The step's inputs (MPC level, ``tab:level_of_information``).

        Returns
        -------
        Action
            The plan's first step, or the safe fallback
            (:func:`~comems4build_ros.core.ems.fallback.safe_action`) without a solution;
            the solve's figures go to :attr:`step_info`.
        """
        if self.observer is not None:  # the model's wall nodes estimated from the measured T_air
            x = self.observer.update(obs.t_air_c, obs.t_amb_c)
            data = obs.as_dict()
            data.update(t_wall_in_c=float(x[1]), t_wall_out_c=float(x[2]))
            obs = Observation(obs.level, data)
        res = self.plan(obs)
        h = self.last_horizon
        self.last_result = res
        self.n_solves += 1
        tol = self.settings.slack_report_tol
        if res.has_solution:
            action = action_from_plan(res.plan, h, self.const)
            self._prev_plan = res.plan
            status = STATUS_OPTIMAL if res.optimal else STATUS_FEASIBLE
        else:
            action = safe_action(obs.t_air_c, obs.v_dhw_l, h.t_min_c[0], self.params)
            self._prev_plan = None
            self.n_fallback += 1
            status = STATUS_NONE
            if self.settings.log_fallback:
                print(f"mpc: step {obs.step}: no solution ({res.status}, {res.solve_s:.3f} s); "
                      f"safe fallback {action} (fallback #{self.n_fallback})", file=sys.stderr)
        info = slack_info(res.plan if res.has_solution else None, tol)
        self.n_slack += int(info["slack_used"])
        info.update(
            solve_s=res.solve_s,
            status=float(status),
            optimal=1.0 if res.optimal else 0.0,
            objective_eur=res.objective,
            gap=res.gap if math.isfinite(res.gap) else math.nan,
            fallback=0.0 if res.has_solution else 1.0,
        )
        self.step_info = {key: float(info[key]) for key in STEP_INFO_KEYS}
        if self.observer is not None:
            q = float(res.plan["p_hp_sh"][0] * h.cop_sh[0]) if res.has_solution else 0.0
            if res.has_solution and "p_hp_cool" in res.plan and h.eer is not None:
                q -= float(res.plan["p_hp_cool"][0] * h.eer[0])
            self.observer.applied(q, float(obs.t_amb_c), float(obs.ghi_w_m2), float(obs.p_load_w))
        return action
