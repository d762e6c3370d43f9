"""The distributed coordinator (``--coordinator distributed``): ADMM on the community's horizon problem.

The community's horizon problem of :mod:`.optimal` couples the houses through two balances
per step ``t``: the connection point's (``e0 + sum_i e_i = 0``, ``e_i = P_buy,i - P_sell,i``)
and the pool's (``q0 + sum_i q_i = 0``, ``q_i = h2_in_i - h2_out_i``). Written as an exchange
problem, ``min sum_j f_j(x_j)`` subject to ``sum_j x_j = 0`` over the agents ``j`` (the hub,
``x_0 = (e0, q0)``, and every house, ``x_i = (e_i, q_i)``), it is solved by the alternating
direction method of multipliers in its exchange form (Boyd, Parikh, Chu, Peleato, Eckstein,
"Distributed Optimization and Statistical Learning via the Alternating Direction Method of
Multipliers", Foundations and Trends in Machine Learning 3(1), 2011, section 7.3.2). Each
iteration ``k``:

1. every agent solves its own problem at the current prices ``rho u`` with a proximal term
   around its balanced exchange ``z_j``: ``x_j <- argmin f_j(x_j) + rho u . x_j +
   rho/2 ||x_j - z_j||^2``: a house its own horizon problem (its MPC's model, the LP relaxation
   of its MILP; it reads only its own observation), the hub its electrolysers, pool and
   connection point;
2. the coordinator averages what they return (optionally over-relaxed, ``relaxation``),
   ``xbar = sum_j x_j / (N + 1)`` (the imbalance of the two balances per step, over the
   agents), projects every exchange onto the balances, ``z_j <- x_j - xbar``, and updates the
   scaled prices ``u <- u + xbar`` (``rho u`` is the price of electricity and of H2 at the
   hub in EUR per W and step).

Only prices and totals cross between the coordinator and the houses: a house receives the
prices and its balanced exchange (2 x 24 numbers each) and returns its exchange (2 x 24
numbers); its states, forecasts and model stay at the house. The iterations stop when both
balances close within ``tol_kw`` in every step and no price would change by more than
``tol_eur_per_kwh`` (``rho`` times the largest change of a balanced exchange, the dual
residual), or after ``max_iterations``; ``rho`` may adapt by residual balancing
(``rho_adapt_factor``). ADMM converges for convex problems: the fixed point is the optimum of
the LP relaxation of the community's MILP. The first decision starts from the day-ahead buy
prices (as if the community bought every kWh), every later one from the last decision's
prices and balanced exchanges one step on (warm start).

Applied, as the central coordinator: the hub's first-step electrolysis and, for every house,
the H2 of its first step's balanced exchange ``z_i`` (all production to the pool).
``comems4build bench coordinators`` compares its objective with the central optimum's on the
same decisions.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
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
from comems4build_ros.core.community.optimal import (
    HorizonOptions,
    HouseModel,
    HubModel,
    check_mpc_view,
    plan_dispatch,
    pool_value_eur_per_kwh,
    transfers_from,
)
from comems4build_ros.core.config import W_PER_KW, ConfigError, parse_model
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.mpc.controller import milp_backend
from comems4build_ros.core.ems.mpc.solvers import MatrixForm

#: HiGHS's primal solution status "feasible" (``highspy.SolutionStatus.kSolutionStatusFeasible``).
_FEASIBLE = 2
#: rho is given per kW^2 and the problems are in W.
_W2_PER_KW2 = W_PER_KW * W_PER_KW


class DistributedOptions(HorizonOptions):
    """Options of the distributed coordinator (row ``distributed`` of ``config/coordinators.yaml``)."""

    rho_eur_per_kw2: float = Field(gt=0)
    rho_adapt_factor: float = Field(ge=1)
    rho_adapt_ratio: float = Field(gt=1)
    max_iterations: int = Field(ge=1, le=100_000)
    tol_kw: float = Field(gt=0)
    tol_eur_per_kwh: float = Field(gt=0)
    relaxation: float = Field(gt=0, lt=2)


def breakpoints(tol_w: float, largest_w: float) -> np.ndarray:
    """Return where the piecewise-linear proximal term meets the quadratic.

    Parameters
    ----------
    tol_w : float
        The first breakpoint after 0 (the tolerance) [W].
    largest_w : float
        The breakpoints double until they reach or pass this [W].

    Returns
    -------
    numpy.ndarray
        0, ``tol_w`` and its doublings up to ``largest_w`` or beyond [W].
    """
    j = int(math.ceil(math.log2(max(largest_w / tol_w, 1.0)))) + 1
    return np.concatenate([[0.0], tol_w * 2.0 ** np.arange(j)])


class _Agent:
    """One agent's problem with the ADMM's price and proximal term, solved by the MPC's solver layer (an LP).

    The proximal term ``rho/2 (x_t - c_t)^2`` of every exchange ``x_t`` around its centre ``c_t``
    is the quadratic's secant interpolation between :func:`breakpoints` ``b``: the deviation
    ``x_t - c_t`` is the sum of segments ``y+_k - y-_k`` (each within ``b_{k+1} - b_k``, the last
    unbounded) costing ``rho (b_k + b_{k+1}) / 2`` per W, increasing, so the LP fills them in
    order (a convex piecewise-linear function, no binaries). A new centre changes one
    right-hand side per exchange and step, a new price the exchange's costs. The breakpoints
    are dense where the exchange settles (from ``tol_kw`` on, doubling): the ADMM's fixed point
    is the optimum at the converged prices whatever their spacing.

    Parameters
    ----------
    prob : the agent's problem (the segments are added to it)
    mutable : the problem's changing matrix coefficients (:class:`MatrixForm`)
    e_pos, e_neg, q_pos, q_neg : the variables of its exchange ``e = e_pos - e_neg`` and
        ``q = q_pos - q_neg`` per step (``None``: no negative part)
    rho_w : the ADMM penalty [EUR/W^2]
    options : the coordinator's options; mpc : the MPC's options (the solver and its settings)
    tag : the agent's names' prefix
    """

    def __init__(self, prob: pulp.LpProblem, mutable: list, e_pos: list, e_neg: list | None, q_pos: list,
                 q_neg: list | None, rho_w: float, options: DistributedOptions, mpc: Any, tag: str) -> None:
        self.prob = prob
        n = len(e_pos)
        b = breakpoints(options.tol_kw * W_PER_KW / 4.0, options.connection_kw_per_house * W_PER_KW)
        widths = [*np.diff(b).tolist(), None]
        slopes = [*(rho_w * (b[:-1] + b[1:]) / 2.0).tolist(), rho_w * (b[-2] + b[-1]) / 2.0]
        self.rows: list[list[pulp.LpConstraint]] = []
        self.segments: list[tuple[pulp.LpVariable, float]] = []
        for c, (pos, neg) in enumerate(((e_pos, e_neg), (q_pos, q_neg))):
            rows = []
            for t in range(n):
                x = pos[t] - neg[t] if neg is not None else pos[t] + 0.0
                for k, (width, slope) in enumerate(zip(widths, slopes)):
                    for sign, side in ((1.0, "p"), (-1.0, "n")):
                        y = pulp.LpVariable(f"{tag}admm_y{side}{c}_{t}_{k}", 0.0, width)
                        x = x - sign * y
                        self.segments.append((y, slope))
                con = x == 0.0
                prob.addConstraint(con, f"{tag}admm_dev{c}_{t}")
                rows.append(con)
            self.rows.append(rows)
        self.form = MatrixForm(prob, mutable)
        self.backend = milp_backend(self.form, mpc)
        idx = self.form.col_index

        def cols(vars_: list | None) -> np.ndarray | None:
            return None if vars_ is None else np.array([idx[v.name] for v in vars_])

        self.vars = ((e_pos, e_neg), (q_pos, q_neg))
        self.cols = ((cols(e_pos), cols(e_neg)), (cols(q_pos), cols(q_neg)))
        rix = {name: i for i, name in enumerate(self.form.row_names)}
        self.row_index = [np.array([rix[con.name] for con in rows], dtype=np.int32) for rows in self.rows]
        self.y_cols = np.array([idx[y.name] for y, _ in self.segments])
        self.y_cost0 = np.array([slope for _, slope in self.segments])
        self.y_cost = self.y_cost0.copy()
        self.x = (np.zeros(n), np.zeros(n))
        self.cost = 0.0
        self.solution = np.zeros(self.form.n_cols)
        self.cold_restarts = 0

    def base(self) -> None:
        """Keep the exchange's own costs after the problem's update for a decision.

        The segments' costs go into the objective.
        """
        obj = self.prob.objective
        for (y, _), cost in zip(self.segments, self.y_cost):
            obj[y] = float(cost)
        self._own = [[np.array([float(obj.get(var, 0.0)) for var in vars_]) if vars_ is not None else None
                      for vars_ in pair] for pair in self.vars]
        raw = self.backend.solve()  # through the solver layer: its options, a new instance, a first basis
        self.highs = self.backend.h
        self.time_limit_s = float(getattr(self.backend, "options", {}).get("time_limit", 0.0) or 0.0)
        if raw.x is None:
            raise RuntimeError(f"coordinator 'distributed': an agent's problem has no solution "
                               f"({raw.error or raw.sol_status})")

    def scale_proximal(self, factor: float) -> None:
        """``rho`` times ``factor``: the segments' costs with it."""
        self.y_cost = self.y_cost * factor
        self.highs.changeColsCost(len(self.y_cols), self.y_cols.astype(np.int32), self.y_cost)

    def respond(self, price: tuple[np.ndarray, np.ndarray], centre: tuple[np.ndarray, np.ndarray]
                ) -> tuple[np.ndarray, np.ndarray]:
        """Solve at the ``price`` of each exchange [EUR/W] with the proximal term around ``centre`` [W].

        Return the exchange (its own cost, without price and proximal term, in ``cost``).

        Raises
        ------
        RuntimeError
            If the solver finds no solution (every agent's problem has soft bounds, so this is a
            solver failure).
        """
        # the last decision's instance, warm: only the exchange's costs and the centres change
        h = self.highs
        for (pos, neg), (own_pos, own_neg), p in zip(self.cols, self._own, price):
            h.changeColsCost(len(pos), pos.astype(np.int32), own_pos + p)
            if neg is not None:
                h.changeColsCost(len(neg), neg.astype(np.int32), own_neg - p)
        for rows, target in zip(self.row_index, centre):
            c = np.asarray(target, dtype=float)
            h.changeRowsBounds(len(rows), rows, c, c)
        if self.time_limit_s:  # HiGHS counts an instance's time over all its runs: the limit per solve
            h.setOptionValue("time_limit", h.getRunTime() + self.time_limit_s)
        h.run()
        info = h.getInfo()
        if int(info.primal_solution_status) != _FEASIBLE:  # a warm start that failed: once more from scratch
            h.clearSolver()
            h.run()
            info = h.getInfo()
            self.cold_restarts += 1
        if int(info.primal_solution_status) != _FEASIBLE:
            raise RuntimeError(f"coordinator 'distributed': an agent's problem has no solution "
                               f"({h.modelStatusToString(h.getModelStatus())})")
        x = self.solution = np.asarray(h.getSolution().col_value, dtype=float)
        objective = float(info.objective_function_value)

        def exchange(pos: np.ndarray, neg: np.ndarray | None) -> np.ndarray:
            return x[pos] - x[neg] if neg is not None else x[pos].copy()

        self.x = tuple(exchange(pos, neg) for pos, neg in self.cols)
        paid = sum(float(np.dot(p, xc)) for p, xc in zip(price, self.x))
        self.cost = objective - float(self.y_cost @ x[self.y_cols]) - paid
        return self.x


class DistributedCoordinator:
    """ADMM over the houses' own horizon problems and the hub's (module docstring).

    Parameters
    ----------
    info : the community's fixed figures (the houses' parameters go to their agents only)
    options : the row ``distributed`` of ``config/coordinators.yaml`` with the user's overrides
    """

    name = "distributed"
    info_level = "mpc"

    def __init__(self, info: CommunityInfo, options: Mapping[str, Any] | None = None) -> None:
        self.info = info
        self.options = parse_model(DistributedOptions, dict(options or {}), "coordinator 'distributed' options")
        o = self.options
        if len(info.house_params) != len(info.names):
            raise ConfigError("coordinator 'distributed': needs every house's parameters for its agents")
        self.rho_w = o.rho_eur_per_kw2 / _W2_PER_KW2
        # residual balancing keeps rho within three orders of magnitude of the configured one
        self.rho_min_w, self.rho_max_w = self.rho_w / 1e3, self.rho_w * 1e3
        # the houses' agents: each its own relaxed model and solver (at the house over ROS)
        self.houses = [HouseModel(p, i, o, integer_steps=0) for i, p in enumerate(info.house_params)]
        mpc = self.houses[0].mpc.settings
        self.agents = [_Agent(h.model.prob, h.model.mutable, h.vars["p_buy"], h.vars["p_sell"], h.vars["h2_in"],
                              h.vars["h2_out"], self.rho_w, o, mpc, f"n{i}_") for i, h in enumerate(self.houses)]
        n = self.houses[0].model.n
        self.n = n
        self.hub = HubModel(info, n, o, integer=False)
        self.hub.prob.setObjective(self.hub.objective)
        self.hub_agent = _Agent(self.hub.prob, [], self.hub.e0, None, self.hub.q0, None, self.rho_w, o, mpc, "hub_")
        self.step_info: dict[str, float] = {}
        self.reset()

    def reset(self) -> None:
        """Forget the prices, the exchanges, the adapted ``rho`` and the houses' seasonal memory."""
        self.rho_w = self.options.rho_eur_per_kw2 / _W2_PER_KW2
        for agent in (self.hub_agent, *self.agents):
            agent.y_cost = agent.y_cost0.copy()
        for house in self.houses:
            house.mpc.reset()
            house.plan = None
        self.u = (np.zeros(self.n), np.zeros(self.n))
        self.zs: list[tuple[np.ndarray, np.ndarray]] | None = None
        self._milps: list[tuple[HouseModel, Any]] | None = None
        self.last: dict[str, Any] = {}
        self.step_info = {}

    def _prepare(self, view: CommunityView) -> None:
        for house, agent, obs in zip(self.houses, self.agents, view.observations):
            self._prepare_house(house, agent, obs)
        self.hub.update(view, pool_value_eur_per_kwh(view.observations[0], self.houses[0]))
        self.hub_agent.base()

    @staticmethod
    def _prepare_house(house: HouseModel, agent: _Agent, obs: Observation) -> None:
        house.prepare(obs, warm=False)
        agent.base()

    def solve(self, view: CommunityView) -> dict[str, Any]:
        """Run the ADMM for ``view`` (module docstring).

        Returns
        -------
        dict with ``objective`` (the sum of the agents' own costs at the last iterate [EUR]),
        ``iterations``, ``residual_kw`` (the largest imbalance of a balance in a step),
        ``converged``, ``solve_s``, ``x`` (every agent's last exchange, hub first), ``z`` (the balanced
        exchanges), ``u`` (the scaled prices), ``hub`` (the hub agent's plan)
        """
        check_mpc_view(self.name, view, len(self.houses))
        t0 = time.perf_counter()
        self._prepare(view)
        agents = [self.hub_agent, *self.agents]
        if self.zs is None:  # the first decision: electricity at the day-ahead buy prices, H2 free
            zs = [(np.zeros(self.n), np.zeros(self.n)) for _ in agents]
            prices = np.resize(np.asarray(view.prices_buy_24h or (view.price_buy_eur_per_kwh,), dtype=float), self.n)
            self.u = (self.info.dt_h * prices / W_PER_KW / self.rho_w, np.zeros(self.n))
        else:  # warm start: the last decision's balanced exchanges and prices, one step on
            zs = [tuple(_shift(a) for a in z) for z in self.zs]
            self.u = tuple(_shift(a) for a in self.u)
        out = self._iterate(agents, zs)
        out["solve_s"] = time.perf_counter() - t0
        self.last = out
        return out

    def _iterate(self, agents: list[_Agent], zs: list[tuple[np.ndarray, np.ndarray]]) -> dict[str, Any]:
        """Run the ADMM's iterations from the balanced exchanges ``zs`` and the prices ``u`` (module docstring)."""
        o = self.options
        n_agents = len(agents)
        tol_w = o.tol_kw * W_PER_KW
        alpha = o.relaxation
        residual = math.inf
        converged = False
        iterations = 0
        xs = zs
        while iterations < o.max_iterations:
            iterations += 1
            price = tuple(self.rho_w * self.u[c] for c in range(2))
            xs = [agent.respond(price, z) for agent, z in zip(agents, zs)]
            residual = max(float(np.max(np.abs(sum(x[c] for x in xs)))) for c in range(2))
            # over-relaxation (Boyd et al. 2011, section 3.4.3), then the projection onto the balances
            xh = [tuple(alpha * x[c] + (1.0 - alpha) * z[c] for c in range(2)) for x, z in zip(xs, zs)]
            hbar = tuple(sum(x[c] for x in xh) / n_agents for c in range(2))
            new_z = [tuple(x[c] - hbar[c] for c in range(2)) for x in xh]
            self.u = tuple(self.u[c] + hbar[c] for c in range(2))
            moved = max(float(np.max(np.abs(nz[c] - z[c]))) for nz, z in zip(new_z, zs) for c in range(2))
            zs = new_z
            # both residuals relative to their tolerances: the balances' in W, the prices' change
            # rho * moved (the dual residual) in EUR/kWh
            r_rel = residual / tol_w
            s_rel = self.rho_w * moved * W_PER_KW / o.tol_eur_per_kwh
            if r_rel <= 1.0 and s_rel <= 1.0:
                converged = True
                break
            if o.rho_adapt_factor > 1.0:
                self._adapt(r_rel, s_rel, agents)
        self.zs = zs
        return {"objective": sum(agent.cost for agent in agents), "iterations": iterations,
                "residual_kw": residual / W_PER_KW, "converged": converged, "x": xs, "z": zs, "u": self.u,
                "hub": self.hub.plan(self.hub_agent.solution, self.hub_agent.form)}

    def _adapt(self, r_rel: float, s_rel: float, agents: list[_Agent]) -> None:
        """Adapt ``rho`` by residual balancing (Boyd et al. 2011, section 3.4.1).

        Each residual is taken relative to its tolerance: ``rho`` times ``rho_adapt_factor``
        while the primal residual exceeds the dual one ``rho_adapt_ratio`` times, divided by it
        in the opposite case, within 1e-3..1e3 of the configured ``rho``; the scaled prices
        follow so that the prices ``rho u`` stay.
        """
        o = self.options
        if r_rel > o.rho_adapt_ratio * s_rel:
            factor = o.rho_adapt_factor
        elif s_rel > o.rho_adapt_ratio * r_rel:
            factor = 1.0 / o.rho_adapt_factor
        else:
            return
        rho = self.rho_w * factor
        if not self.rho_min_w <= rho <= self.rho_max_w:
            return
        self.rho_w = rho
        self.u = tuple(u / factor for u in self.u)
        for agent in agents:
            agent.scale_proximal(factor)

    def balanced(self) -> list[dict[str, np.ndarray]]:
        """Return every house's balanced exchange of the last solve.

        Returns
        -------
        list of dict
            Per house the projection ``z`` onto the balances as ``h2_in`` / ``h2_out`` and
            ``p_buy`` / ``p_sell`` [W].
        """
        out = []
        for e, q in self.last["z"][1:]:
            out.append({"p_buy": np.maximum(e, 0.0), "p_sell": np.maximum(-e, 0.0), "h2_in": np.maximum(q, 0.0),
                        "h2_out": np.maximum(-q, 0.0)})
        return out

    def recover(self, view: CommunityView) -> dict[str, Any]:
        """Find an integer plan from the last solve, for comparing with the central MILP's optimum.

        Every house solves its own MILP (its MPC's, binaries kept where the MPC keeps them, its
        relaxed tail relaxed) once at the converged prices of electricity and H2, the hub its
        electrolysers as integer modules; each agent then fixes those binaries and its modules to
        the answers, and the ADMM runs again from the converged
        prices and exchanges. The result is a plan of the community's MILP (its integer variables
        integral, its balances closed to the tolerance), found by the houses themselves; its
        ``objective`` is the agents' costs at it [EUR]. The agents' binaries are freed again
        afterwards. Call after :meth:`solve` on the same view.

        Returns
        -------
        dict as :meth:`solve`'s, with ``solve_s`` of the MILPs and the second ADMM
        """
        t0 = time.perf_counter()
        o = self.options
        if self._milps is None:  # the houses' MILPs and the hub's, built once
            mpc = self.houses[0].mpc.settings
            self._milps = [(h, milp_backend(h.model.form, mpc)) for h in
                           (HouseModel(p, i, o) for i, p in enumerate(self.info.house_params))]
            hub = HubModel(self.info, self.n, o, integer=True)
            hub.prob.setObjective(hub.objective)
            self._milps.append((hub, milp_backend(MatrixForm(hub.prob), mpc)))
        price = [self.rho_w * u for u in self.u]
        fixed: list[Any] = []
        for (house, backend), agent_house, obs in zip(self._milps[:-1], self.houses, view.observations):
            house.prepare(obs)
            obj, v = house.model.prob.objective, house.vars
            for t in range(self.n):
                for var, sign, c in ((v["p_buy"][t], 1.0, 0), (v["p_sell"][t], -1.0, 0), (v["h2_in"][t], 1.0, 1),
                                     (v["h2_out"][t], -1.0, 1)):
                    obj[var] += sign * float(price[c][t])
            raw = backend.solve()
            if raw.x is None:
                return {"objective": math.nan, "solve_s": time.perf_counter() - t0, "converged": False}
            plan = house.values(raw.x, backend.form)
            for name in house.model.binary_names():  # the steps the MPC keeps integral (its relaxed tail stays)
                for var, milp_var, value in zip(agent_house.model.v[name], house.model.v[name], plan[name]):
                    if milp_var.cat in (pulp.LpInteger, pulp.LpBinary):
                        fixed.append((var, var.lowBound, var.upBound))
                        var.lowBound = var.upBound = float(round(value))
        hub, backend = self._milps[-1]
        hub.update(view, pool_value_eur_per_kwh(view.observations[0], self.houses[0]))
        for t in range(self.n):
            hub.objective[hub.e0[t]] = float(price[0][t])
            hub.objective[hub.q0[t]] = float(price[1][t])
        raw = backend.solve()
        if raw.x is None:
            return {"objective": math.nan, "solve_s": time.perf_counter() - t0, "converged": False}
        for var, value in zip(self.hub.m, hub.plan(raw.x, backend.form)["m"]):
            fixed.append((var, var.lowBound, var.upBound))
            var.lowBound = var.upBound = float(round(value))
        state = (self.u, self.zs, self.rho_w)
        try:
            for agent in (self.hub_agent, *self.agents):
                agent.base()
            out = self._iterate([self.hub_agent, *self.agents], self.zs)
        finally:  # the decision's own prices and exchanges stay the next decision's warm start
            for var, low, up in fixed:
                var.lowBound, var.upBound = low, up
            self.u, self.zs, self.rho_w = state
        out["solve_s"] = time.perf_counter() - t0
        return out

    def allot(self, view: CommunityView) -> Allotment:
        """Run the ADMM and move the first step's H2 of the balanced exchanges.

        Every house keeps its own ``eq:deltaLOH``.
        """
        res = self.solve(view)
        n = len(self.houses)
        own = tuple(h.dloh_own_per_day for h in view.houses)
        transfers = transfers_from(self.balanced(), view, self.info.dt_h)
        self.step_info = {"solve_s": res["solve_s"], "objective_eur": res["objective"],
                          "iterations": float(res["iterations"]), "residual_kw": res["residual_kw"],
                          "converged": 1.0 if res["converged"] else 0.0,
                          # per iteration: prices and totals to every house, its exchange back;
                          # per step: the allotment, the requests and the hub's set-point
                          "messages": float(2 * n * res["iterations"] + 2 * n + 1)}
        return Allotment(own, transfers)

    def dispatch(self, view: CommunityView, requests: tuple[Request, ...]) -> Dispatch:
        """Run the electrolysers at the hub agent's first step; all production goes to the pool."""
        return plan_dispatch(self.last.get("hub"), len(requests))


def _shift(values: np.ndarray) -> np.ndarray:
    """One step on, the last value repeated (the next decision's warm start)."""
    return np.concatenate([values[1:], values[-1:]])
