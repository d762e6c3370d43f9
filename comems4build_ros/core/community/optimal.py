"""The community's horizon problem and the cost-optimal central coordinator (``--coordinator central``).

The community's horizon problem at step ``k`` (24 steps, as the MPC's ``sec:MPC``) is composed,
not written anew: every house is its own MPC's horizon MILP
(:class:`~comems4build_ros.core.ems.mpc.milp.MILPModel` through
:func:`~comems4build_ros.core.ems.mpc.controller.milp_model`, built from the house's plant
parameters and updated from the house's MPC-level observation by the MPC's own
:meth:`~comems4build_ros.core.ems.mpc.controller.MPCController.prepare`), with its store an
account at the hub (``h2_exchange``: H2 moved into and out of the account). The hub
(:class:`HubModel`) adds, per step ``t``:

- the electrolysers: ``P_EL,min,1 m <= P_EL <= P_EL,max,1 m`` with ``m`` the modules running
  (integer, ``0..n``), producing ``eta_EL P_EL`` (rated LHV efficiency, compression included,
  the MPC's constant ``eta_el``);
- the pool: ``pool[t] = pool[t-1] + dt (eta_EL P_EL - sum_i (h2_in_i - h2_out_i))``, within
  ``0 .. E_hub LOH_max - `` the accounts' H2 at step ``k``;
- the connection point: ``P_buy,cp - P_sell,cp = sum_i (P_buy,i - P_sell,i) + P_EL``
  (``eq:power_balance`` summed over the members), each within ``connection_kw_per_house`` times
  the houses.

Objective: the cost at the connection point ``dt (p_buy P_buy,cp - p_sell P_sell,cp)``, the
houses' lifecycle costs and soft-bound penalties (their MPC's ``eq:mpc_objective`` without its
grid terms, which the connection point takes: a house's own meter is priced at
``meter_eur_per_kwh``, a tie-breaker), ``transfer_eur_per_kwh`` per kWh of H2 moved between
the pool and an account, and, for the year-round plant outside the heating season, the H2 in
the pool at the horizon's end valued as the MPC values its store's (``h2_value_eur_per_kwh``).
Electricity shared inside the community is netted at the connection point: the rule sets'
charges on shared energy (``config/sharing.yaml``) are what the settlement adds afterwards; the
coordinator minimises what the community exchanges with the grid.

Central coordinator: the whole problem solved as one MILP with the MPC's solver layer
(:func:`~comems4build_ros.core.ems.mpc.controller.milp_backend`: PuLP's model, HiGHS) every
step; of the plan it applies the first step's hub decisions: the electrolysers' set-point, and
the H2 moved into and out of every account (all production goes to the pool first). Each
house's EMS still runs its house (``tab:level_of_information``: the coordinator reads every
house's MPC-level observation, its states and forecasts, as the house's MPC would). The
problem grows with the houses (binaries per house and step); above ``max_houses`` the
coordinator refuses to be built (``docs/community.md`` gives the measured time per decision).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pulp
from pydantic import Field

from comems4build_ros.core.community.coordinator import (
    Allotment,
    CommunityInfo,
    CommunityView,
    Dispatch,
    Request,
)
from comems4build_ros.core.config import W_PER_KW, ConfigError, Section, parse_model
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.mpc.controller import MPCController, milp_backend
from comems4build_ros.core.ems.mpc.milp import shift_plan
from comems4build_ros.core.ems.mpc.solvers import MatrixForm

#: The coupling variables of a house's model: grid exchange at its meter and H2 moved [W].
HOUSE_COUPLING = ("p_buy", "p_sell", "h2_in", "h2_out")


class HorizonOptions(Section):
    """Options of the optimising coordinators' horizon problem (``config/coordinators.yaml``)."""

    mpc: dict[str, Any] = Field(default_factory=dict)
    transfer_eur_per_kwh: float = Field(ge=0)
    meter_eur_per_kwh: float = Field(ge=0)
    connection_kw_per_house: float = Field(gt=0)


class CentralOptions(HorizonOptions):
    """Options of the central coordinator (row ``central``)."""

    max_houses: int = Field(ge=1)
    time_limit_s: float = Field(gt=0)
    mip_rel_gap: float | None = Field(default=None, ge=0, lt=1)
    relaxed: bool = False


class HouseModel:
    """One house's horizon MILP (its MPC's), its store an account at the hub.

    Parameters
    ----------
    params : the house's plant parameters (its share as its store, no electrolyser)
    index : the house's position (its names' prefix ``n<index>_``)
    options : the horizon options (``mpc``: overrides of ``config/mpc.yaml`` section ``mpc``)
    integer_steps : steps whose binaries stay binary (0: the LP relaxation)
    """

    def __init__(self, params: Any, index: int, options: HorizonOptions, integer_steps: int | None = None) -> None:
        model_options: dict[str, Any] = {"prefix": f"n{index}_", "h2_exchange": True}
        if integer_steps is not None:
            model_options["integer_steps"] = integer_steps
        self.mpc = MPCController(params, {**options.mpc, "observer": "measured"}, model_options)
        self.model = self.mpc.model
        self.const = self.mpc.const
        self.options = options
        self.plan: dict[str, np.ndarray] | None = None
        v = self.model.v
        self.vars = {name: v[name] for name in HOUSE_COUPLING}

    def prepare(self, obs: Observation, warm: bool = True) -> Any:
        """Update the model from the house's MPC-level observation; the meter at the tie-breaker price.

        Returns the horizon's numbers (:class:`~comems4build_ros.core.ems.mpc.horizon.HorizonData`).
        """
        h = self.mpc.prepare(obs)
        obj = self.model.prob.objective
        c = self.const.dt_h / W_PER_KW
        for t in range(self.model.n):
            obj[self.vars["p_buy"][t]] = c * self.options.meter_eur_per_kwh
            obj[self.vars["p_sell"][t]] = c * self.options.meter_eur_per_kwh
            obj[self.vars["h2_in"][t]] = c * self.options.transfer_eur_per_kwh
            obj[self.vars["h2_out"][t]] = c * self.options.transfer_eur_per_kwh
        self.model.set_start(shift_plan(self.plan) if warm and self.plan else None)
        return h

    def values(self, x: np.ndarray, form: MatrixForm) -> dict[str, np.ndarray]:
        """Return the house's variables' values in the solution ``x`` of the problem ``form``."""
        return {name: x[[form.col_index[var.name] for var in vars_]] for name, vars_ in self.model.v.items()}


class HubModel:
    """The hub's part of the horizon problem (module docstring): electrolysers, pool, connection point.

    ``e0[t] = P_EL - P_buy,cp + P_sell,cp`` and ``q0[t] = (pool[t] - pool[t-1]) / dt - eta_EL P_EL``
    are the hub's side of the two balances: ``e0 + sum_i (P_buy,i - P_sell,i) = 0`` and
    ``q0 + sum_i (h2_in_i - h2_out_i) = 0``.

    Parameters
    ----------
    info : the community's fixed figures
    n : horizon steps
    options : the horizon options
    integer : the modules running are integer (``False``: the LP relaxation)
    prob : the problem to add to (default: a new one)
    """

    def __init__(self, info: CommunityInfo, n: int, options: HorizonOptions, integer: bool = True,
                 prob: pulp.LpProblem | None = None) -> None:
        self.info, self.n, self.options = info, n, options
        self.prob = prob if prob is not None else pulp.LpProblem("hub_horizon", pulp.LpMinimize)
        n_mod = info.n_modules
        cap = options.connection_kw_per_house * W_PER_KW * len(info.names)
        cat = pulp.LpInteger if integer else pulp.LpContinuous

        def series(name: str, low: float | None, up: float | None, kind: str = pulp.LpContinuous) -> list:
            return [pulp.LpVariable(f"hub_{name}_{t}", low, up, kind) for t in range(n)]

        self.p_el = series("p_el", 0.0, n_mod * info.p_el_module_max_w)
        self.m = series("modules", 0, n_mod, cat)
        self.gb = series("cp_buy", 0.0, cap)
        self.gs = series("cp_sell", 0.0, cap)
        self.pool = series("pool", 0.0, None)
        self.e0 = series("e0", None, None)
        self.q0 = series("q0", None, None)
        self.pool_rows = []
        dt = info.dt_h
        for t in range(n):
            add = self.prob.addConstraint
            add(self.p_el[t] - info.p_el_module_max_w * self.m[t] <= 0.0, f"hub_el_max_{t}")
            add(self.p_el[t] - info.p_el_module_min_w * self.m[t] >= 0.0, f"hub_el_min_{t}")
            add(self.e0[t] - self.p_el[t] + self.gb[t] - self.gs[t] == 0.0, f"hub_e0_{t}")
            prev = self.pool[t - 1] if t else 0.0
            row = self.q0[t] - (self.pool[t] - prev) / dt + info.eta_el * self.p_el[t] == 0.0
            add(row, f"hub_q0_{t}")
            self.pool_rows.append(row)
        self.objective = pulp.LpAffineExpression()
        for t in range(n):
            self.objective += 1e-9 * self.gb[t] + 1e-9 * self.gs[t]  # placeholders, set by update
        self.objective += 1e-9 * self.pool[n - 1]

    def update(self, view: CommunityView, value_eur_per_kwh: float) -> None:
        """Set the step's pool, the store's room, the prices of the day ahead and the pool's end value."""
        info, obj, dt = self.info, self.objective, self.info.dt_h
        self.pool_rows[0].changeRHS(-view.hub.pool_wh / dt)
        accounts = sum(h.account_wh for h in view.houses)
        room = max(info.hub_e_max_wh * info.hub_loh_max - accounts, 0.0)
        prices = list(view.prices_buy_24h) or [view.price_buy_eur_per_kwh]
        for t in range(self.n):
            self.pool[t].upBound = room
            p_buy = float(prices[min(t, len(prices) - 1)])
            obj[self.gb[t]] = dt * p_buy / W_PER_KW
            obj[self.gs[t]] = -dt * float(view.price_sell_eur_per_kwh) / W_PER_KW
        obj[self.pool[self.n - 1]] = -value_eur_per_kwh / W_PER_KW

    def plan(self, x: np.ndarray, form: MatrixForm) -> dict[str, np.ndarray]:
        """Return the hub's variables' values in the solution ``x``."""
        out = {}
        for name in ("p_el", "m", "gb", "gs", "pool", "e0", "q0"):
            out[name] = x[[form.col_index[v.name] for v in getattr(self, name)]]
        return out


def pool_value_eur_per_kwh(obs: Observation, house: HouseModel) -> float:
    """Return what the MPC values a kWh of H2 left at the horizon's end [EUR/kWh].

    The year-round plant outside the heating season values it at ``h2_value_eur_per_kwh`` (as
    :class:`~.milp.MILPModel`), otherwise it is worth nothing.
    """
    if not house.const.year_round or float(obs.heating_season_days_left) > 0.0:
        return 0.0
    return float(house.model.year.h2_value_eur_per_kwh)


def transfers_from(plans: Sequence[Mapping[str, np.ndarray]], view: CommunityView, dt_h: float) -> tuple[float, ...]:
    """Return the H2 moved into each account at the step's start [Wh].

    The plans' first step, within what the pool and the accounts hold (H2 moved out first
    enters the pool).
    """
    moves = [float(p["h2_in"][0] - p["h2_out"][0]) * dt_h for p in plans]
    out = [max(m, -max(h.account_wh - h.floor_wh, 0.0)) for m, h in zip(moves, view.houses)]
    pool = view.hub.pool_wh - sum(m for m in out if m < 0.0)
    want = sum(m for m in out if m > 0.0)
    scale = min(1.0, pool / want) if want > 0.0 else 1.0
    return tuple(m * scale if m > 0.0 else m for m in out)


def plan_dispatch(hub_plan: Mapping[str, np.ndarray] | None, n_houses: int) -> Dispatch:
    """Return the hub's dispatch of a plan.

    The electrolysers run at the plan's first step (off without a plan, and below 1 mW, a
    solver's zero); all production goes to the pool (the plan's moves share it out).
    """
    p_el = float(hub_plan["p_el"][0]) if hub_plan else 0.0
    return Dispatch(p_el if p_el > 1e-3 else 0.0, (0.0,) * n_houses)


def check_mpc_view(name: str, view: CommunityView, n_houses: int) -> None:
    """Refuse a view without the houses' MPC-level observations (a loop that does not give them)."""
    if len(view.observations) != n_houses:
        raise ValueError(f"coordinator '{name}': needs every house's MPC-level observation (info_level 'mpc'), "
                         f"got {len(view.observations)} for {n_houses} houses")


class CentralCoordinator:
    """The whole community's horizon MILP, solved in one piece every step (module docstring).

    Parameters
    ----------
    info : the community's fixed figures (with every house's parameters)
    options : the row ``central`` of ``config/coordinators.yaml`` with the user's overrides
        (``relaxed``: the LP relaxation, every binary and the modules continuous, for comparing
        with the distributed coordinator's fixed point)

    Raises
    ------
    ConfigError
        Above ``max_houses`` houses, naming the limit and the time per decision it stands for.
    """

    name = "central"
    info_level = "mpc"

    def __init__(self, info: CommunityInfo, options: Mapping[str, Any] | None = None) -> None:
        self.info = info
        self.options = parse_model(CentralOptions, dict(options or {}), "coordinator 'central' options")
        o = self.options
        if len(info.names) > o.max_houses:
            raise ConfigError(
                f"coordinator 'central': {len(info.names)} houses exceed its limit of {o.max_houses} (option "
                f"max_houses): the community's MILP grows with every house's binaries and its time per decision "
                f"with it (docs/community.md, 'The central coordinator's limit'); use the distributed coordinator")
        if len(info.house_params) != len(info.names):
            raise ConfigError("coordinator 'central': needs every house's parameters (CommunityInfo.house_params)")
        steps = 0 if o.relaxed else None
        self.houses = [HouseModel(p, i, o, integer_steps=steps) for i, p in enumerate(info.house_params)]
        n = self.houses[0].model.n
        self.prob = pulp.LpProblem("community_horizon", pulp.LpMinimize)
        self.hub = HubModel(info, n, o, integer=not o.relaxed, prob=self.prob)
        mutable = []
        for house in self.houses:
            for cname, con in house.model.prob.constraints.items():
                self.prob.addConstraint(con, cname)
            mutable += house.model.mutable
        for t in range(n):
            self.prob.addConstraint(self.hub.e0[t] + pulp.lpSum(h.vars["p_buy"][t] - h.vars["p_sell"][t]
                                                                 for h in self.houses) == 0.0, f"community_e_{t}")
            self.prob.addConstraint(self.hub.q0[t] + pulp.lpSum(h.vars["h2_in"][t] - h.vars["h2_out"][t]
                                                                 for h in self.houses) == 0.0, f"community_q_{t}")
        self.prob.setObjective(self._objective())
        self.form = MatrixForm(self.prob, mutable)
        self.backend = milp_backend(self.form, self.houses[0].mpc.settings, o.time_limit_s, o.mip_rel_gap)
        self.step_info: dict[str, float] = {}
        self.reset()

    def _objective(self) -> pulp.LpAffineExpression:
        total = pulp.LpAffineExpression()
        for house in self.houses:
            total += house.model.prob.objective
        total += self.hub.objective
        return total

    def reset(self) -> None:
        """Forget the last plan and the houses' seasonal memory."""
        for house in self.houses:
            house.mpc.reset()
            house.plan = None
        self.last: dict[str, Any] = {}
        self._hub_plan: dict[str, np.ndarray] | None = None
        self.step_info = {}

    def solve(self, view: CommunityView) -> dict[str, Any]:
        """Update and solve the community's horizon problem for ``view``.

        Returns
        -------
        dict with ``objective`` [EUR], ``optimal``, ``gap``, ``solve_s`` [s], ``houses`` (each house's
        plan), ``hub`` (the hub's plan); plans are empty without a solution
        """
        check_mpc_view(self.name, view, len(self.houses))
        for house, obs in zip(self.houses, view.observations):
            house.prepare(obs)
        self.hub.update(view, pool_value_eur_per_kwh(view.observations[0], self.houses[0]))
        if self._hub_plan is not None:
            for name in ("m",):
                for var, val in zip(getattr(self.hub, name), shift_plan({name: self._hub_plan[name]})[name]):
                    var.varValue = float(val)
        self.prob.setObjective(self._objective())
        t0 = time.perf_counter()
        raw = self.backend.solve()
        solve_s = time.perf_counter() - t0
        out: dict[str, Any] = {"objective": math.nan, "optimal": False, "gap": math.nan, "solve_s": solve_s,
                               "houses": [], "hub": {}}
        if raw.x is None or not np.all(np.isfinite(raw.x)):
            for house in self.houses:
                house.plan = None
            self._hub_plan = None
            return out
        out.update(objective=float(raw.objective), optimal=raw.sol_status == pulp.LpSolutionOptimal,
                   gap=float(raw.gap), houses=[h.values(raw.x, self.form) for h in self.houses],
                   hub=self.hub.plan(raw.x, self.form))
        for house, plan in zip(self.houses, out["houses"]):
            house.plan = plan
        self._hub_plan = out["hub"]
        return out

    def allot(self, view: CommunityView) -> Allotment:
        """Solve the horizon problem; move the first step's H2; every house keeps its own ``eq:deltaLOH``."""
        self.last = self.solve(view)
        own = tuple(h.dloh_own_per_day for h in view.houses)
        ok = bool(self.last["houses"])
        transfers = transfers_from(self.last["houses"], view, self.info.dt_h) if ok else (0.0,) * len(own)
        self.step_info = {"solve_s": self.last["solve_s"], "objective_eur": self.last["objective"],
                          "optimal": 1.0 if self.last["optimal"] else 0.0, "gap": self.last["gap"],
                          "fallback": 0.0 if ok else 1.0}
        return Allotment(own, transfers)

    def dispatch(self, view: CommunityView, requests: tuple[Request, ...]) -> Dispatch:
        """Run the electrolysers at the plan's first step (off without a plan); all production goes to the pool."""
        return plan_dispatch(self.last.get("hub"), len(requests))
