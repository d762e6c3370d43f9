"""Continuous MPC variant (``--ems mpc-qp``): the horizon problem relaxed to a QP, solved by OSQP.

Same linear plant model and soft bounds as the MILP (:mod:`.milp`) with every binary
relaxed: the HP powers only share ``P_SH + P_DHW <= P_el,max`` (relaxed eq:zetas_summ, no
minimum modulation), the FC runs in ``[0, zeta P_max]`` and its per-hour lifecycle cost
becomes ``sigma_FC * P_FC / (zeta P_max)`` (the LP relaxation of ``sigma_FC s_FC``), battery
charge and discharge are not excluded (both at once only lose energy). Quadratic terms
(config/mpc.yaml, section ``mpc_qp``) replace what the binaries did:

- ``w_fc_smooth * (P_FC[t] - P_FC[t-1])^2`` smooths FC power (instead of start/stop costs),
- ``w_comfort_track * (T_air[t] - (T_min[t] + margin))^2`` tracks the lower comfort band,
- ``w_reg * P^2`` on every power makes the problem strictly convex.

Recovered FC heat is read as in the MILP (option ``fc_heat_dump``, default false: eq:DHW_heat
as printed, all of it enters the tank; true: ``q_dump <= k_fc_heat * P_FC`` may be dumped).

Powers are in kW and SOC and LOH in kWh inside the QP (scaling for OSQP; the penalties
per unit SOC / LOH are converted). The problem matrix is set up once;
each step updates ``q``, ``l``, ``u`` and the COP-dependent entries of ``A`` in place and
warm-starts from the previous solution shifted by one step. The first step is rounded to
the device sets ({0} U [mod_min, 1] for the HP, {0} U [P_min, zeta P_max] for the FC, to
the nearer end below the minimum), and the plant still enforces every device limit.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from comems4build_ros.core.config import W_PER_KW, PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.ems.mpc.controller import STATUS_FEASIBLE, STATUS_NONE, STATUS_OPTIMAL
from comems4build_ros.core.ems.mpc.horizon import HorizonData, PlantConstants, build_horizon
from comems4build_ros.core.ems.settings import QPSettings, load_settings
from comems4build_ros.core.numerics import rowdot
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action

#: Decision variables per horizon step (powers in kW).
QP_VARS = (
    "p_buy", "p_sell", "p_ch", "p_dis", "p_fc", "p_hp_sh", "p_hp_dhw", "q_dump",
    "t_air", "t_wall_in", "t_wall_out", "v_dhw", "soc", "loh",
    "sl_t_lo", "sl_t_hi", "sl_v_lo", "sl_v_hi", "sl_soc_lo", "sl_soc_hi", "sl_loh",
)
POWER_VARS = ("p_buy", "p_sell", "p_ch", "p_dis", "p_fc", "p_hp_sh", "p_hp_dhw", "q_dump")
SLACK_VARS = ("sl_t_lo", "sl_t_hi", "sl_v_lo", "sl_v_hi", "sl_soc_lo", "sl_soc_hi", "sl_loh")
_J = {name: j for j, name in enumerate(QP_VARS)}
INF = np.inf


class QPModel:
    """The relaxed horizon problem in OSQP form ``min 1/2 z'Pz + q'z, l <= Az <= u``.

    Powers are in kW and the stores in kWh inside the problem (better scaled for OSQP);
    :meth:`plan` turns them back into W and fractions.

    Parameters
    ----------
    const : PlantConstants
        Plant constants of the MPC.
    opts : QPSettings
        The QP's settings (weights, penalties, OSQP tolerances).
    """

    def __init__(self, const: PlantConstants, opts: QPSettings) -> None:
        self.k, self.o = const, opts
        self.n = const.n
        self.nv = len(QP_VARS)
        self.nz = self.n * self.nv
        self.e_b_kwh = const.params.battery.e_max_kwh
        self.e_h2_kwh = const.params.hydrogen.e_max_kwh
        self._rows: list[tuple[str, int]] = []
        self._coo: list[tuple[int, int, str, float]] = []  # row, col, kind, fixed value
        self._build_structure()
        self.solver: Any = None
        self._x_prev: np.ndarray | None = None

    def idx(self, name: str, t: int) -> int:
        """Return the column of variable ``name`` at step ``t``.

        Parameters
        ----------
        name : str
            Variable name (one of ``QP_VARS``).
        t : int
            Horizon step.

        Returns
        -------
        int
            Column index in z.
        """
        return t * self.nv + _J[name]

    def _row(self, label: str, t: int, entries: list[tuple[str, int, str | float]]) -> int:
        """Add a row; entries are (var, step, coefficient or the name of an updated coefficient)."""
        r = len(self._rows)
        self._rows.append((label, t))
        for name, tt, coef in entries:
            if isinstance(coef, str):
                self._coo.append((r, self.idx(name, tt), coef, 0.0))
            elif coef != 0.0:
                self._coo.append((r, self.idx(name, tt), "", float(coef)))
        return r

    def _build_structure(self) -> None:
        k, n, dt = self.k, self.n, self.k.dt_h
        # SOC and LOH are kept in kWh inside the QP (scaling): multiply by the capacities
        a_ch = k.soc_per_wh_ch * W_PER_KW * dt * self.e_b_kwh
        a_d = k.soc_per_wh_d * W_PER_KW * dt * self.e_b_kwh
        a_h2 = k.loh_per_wh_fc * W_PER_KW * dt * self.e_h2_kwh
        cv = k.l_per_wh * W_PER_KW * dt
        for t in range(n):
            self._row("balance", t, [("p_buy", t, 1.0), ("p_sell", t, -1.0), ("p_fc", t, 1.0), ("p_dis", t, 1.0),
                                     ("p_ch", t, -1.0), ("p_hp_sh", t, -1.0), ("p_hp_dhw", t, -1.0)])
            prev = [] if t == 0 else [("soc", t - 1, -1.0)]
            self._row("soc", t, [("soc", t, 1.0), ("p_ch", t, -a_ch), ("p_dis", t, a_d), *prev])
            prev = [] if t == 0 else [("loh", t - 1, -1.0)]
            self._row("loh", t, [("loh", t, 1.0), ("p_fc", t, a_h2), *prev])
            prev = [] if t == 0 else [("v_dhw", t - 1, -1.0)]
            self._row("dhw", t, [("v_dhw", t, 1.0), ("p_hp_dhw", t, "cop_dhw"), ("p_fc", t, -cv * k.k_fc_heat),
                                 ("q_dump", t, cv), *prev])
            self._row("fc_heat_dump", t, [("q_dump", t, 1.0), ("p_fc", t, -k.k_fc_heat)])
            states = ("t_air", "t_wall_in", "t_wall_out")
            for i, label in enumerate(("air", "wall_in", "wall_out")):
                ent: list[tuple[str, int, str | float]] = [(states[i], t, 1.0)]
                if k.bd[i, 0] != 0.0:
                    ent.append(("p_hp_sh", t, f"cop_sh{i}"))
                if t:
                    ent += [(states[j], t - 1, -k.ad[i, j]) for j in range(3)]
                self._row(label, t, ent)
            self._row("comfort_lo", t, [("t_air", t, 1.0), ("sl_t_lo", t, 1.0)])
            self._row("comfort_hi", t, [("t_air", t, 1.0), ("sl_t_hi", t, -1.0)])
            self._row("dhw_lo", t, [("v_dhw", t, 1.0), ("sl_v_lo", t, 1.0)])
            self._row("dhw_hi", t, [("v_dhw", t, 1.0), ("sl_v_hi", t, -1.0)])
            self._row("soc_lo", t, [("soc", t, 1.0), ("sl_soc_lo", t, 1.0)])
            self._row("soc_hi", t, [("soc", t, 1.0), ("sl_soc_hi", t, -1.0)])
            self._row("loh_lo", t, [("loh", t, 1.0), ("sl_loh", t, 1.0)])
            self._row("hp_share", t, [("p_hp_sh", t, 1.0), ("p_hp_dhw", t, 1.0)])
        self.m_con = len(self._rows)
        rows = np.array([c[0] for c in self._coo], dtype=np.int64)
        cols = np.array([c[1] for c in self._coo], dtype=np.int64)
        # identity rows for variable bounds
        self.m = self.m_con + self.nz
        self._rows_all = np.concatenate([rows, self.m_con + np.arange(self.nz)])
        self._cols_all = np.concatenate([cols, np.arange(self.nz)])
        self._kinds = [c[2] for c in self._coo]
        self._fixed = np.array([c[3] for c in self._coo] + [1.0] * self.nz)
        self._label_rows: dict[str, np.ndarray] = {}
        labels = np.array([lb for lb, _ in self._rows])
        for lb in set(labels):
            self._label_rows[lb] = np.flatnonzero(labels == lb)
        # CSC ordering of the entries (structure never changes)
        order_mat = sp.coo_matrix((np.arange(1, len(self._fixed) + 1, dtype=float),
                                   (self._rows_all, self._cols_all)), shape=(self.m, self.nz)).tocsc()
        self._perm = order_mat.data.astype(np.int64) - 1
        self._csc_indices = order_mat.indices.copy()
        self._csc_indptr = order_mat.indptr.copy()
        # quadratic part (constant)
        o, dtw = self.o, dt
        p = sp.lil_matrix((self.nz, self.nz))
        for t in range(n):
            for name in POWER_VARS:
                i = self.idx(name, t)
                p[i, i] += 2.0 * o.w_reg_eur_per_kw2 * dtw
            i = self.idx("t_air", t)
            p[i, i] += 2.0 * o.w_comfort_track_eur_per_k2 * dtw
            if t:
                a, b = self.idx("p_fc", t - 1), self.idx("p_fc", t)
                w = 2.0 * o.w_fc_smooth_eur_per_kw2
                p[a, a] += w
                p[b, b] += w
                p[a, b] -= w
                p[b, a] -= w
        self.P = sp.triu(p.tocsc(), format="csc")

    def matrices(self, h: HorizonData) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Compute the problem data that change with the horizon.

        Parameters
        ----------
        h : HorizonData
            The step's horizon numbers.

        Returns
        -------
        a_data : numpy.ndarray
            A's values in CSC order (the COPs change them).
        q : numpy.ndarray
            Linear cost [EUR per kW or kWh of each variable].
        lo, up : numpy.ndarray
            Row bounds.
        """
        k, n, dt, o = self.k, self.n, self.k.dt_h, self.o
        cv = k.l_per_wh * W_PER_KW * dt
        vals = self._fixed.copy()
        for e, kind in enumerate(self._kinds):
            if not kind:
                continue
            t = self._rows[self._coo[e][0]][1]
            if kind == "cop_dhw":
                vals[e] = -cv * h.cop_dhw[t]
            else:  # cop_sh<i>
                vals[e] = -k.bd[int(kind[-1]), 0] * W_PER_KW * h.cop_sh[t]
        a_data = vals[self._perm]
        lo = np.full(self.m, -INF)
        up = np.full(self.m, INF)
        L = self._label_rows

        def eq(label: str, rhs: np.ndarray) -> None:
            lo[L[label]] = rhs
            up[L[label]] = rhs

        eq("balance", (h.p_load_w - h.p_pv_w) / W_PER_KW)
        soc = np.zeros(n)
        soc[0] = h.soc0 * self.e_b_kwh
        eq("soc", soc)
        loh = np.zeros(n)
        loh[0] = h.loh0 * self.e_h2_kwh
        eq("loh", loh)
        dhw = -cv * (h.q_dhw_dem_w + k.q_dhw_loss_w) / W_PER_KW
        dhw[0] += h.v0_l
        eq("dhw", dhw)
        up[L["fc_heat_dump"]] = 0.0
        exo = np.outer(h.t_amb_c, k.bd[:, 1]) + np.outer(h.ghi_w_m2, k.bd[:, 2])
        if k.bd.shape[1] > 3:  # an identified model's internal gains (building.f_gains_air)
            exo = exo + np.outer(h.p_load_w, k.bd[:, 3])
        exo[0] += rowdot(k.ad, h.x0)
        for i, label in enumerate(("air", "wall_in", "wall_out")):
            eq(label, exo[:, i])
        lo[L["comfort_lo"]] = h.t_min_c
        up[L["comfort_hi"]] = h.t_max_c
        lo[L["dhw_lo"]] = k.v_min_l
        up[L["dhw_hi"]] = k.v_max_l
        lo[L["soc_lo"]] = k.soc_min * self.e_b_kwh
        up[L["soc_hi"]] = k.soc_max * self.e_b_kwh
        lo[L["loh_lo"]] = h.loh_min * self.e_h2_kwh
        up[L["hp_share"]] = h.p_hp_max_w / W_PER_KW
        # variable bounds (identity rows)
        vb_lo = np.zeros((n, self.nv))
        vb_up = np.full((n, self.nv), INF)
        for name in ("t_air", "t_wall_in", "t_wall_out"):
            vb_lo[:, _J[name]] = -INF
        vb_up[:, _J["p_ch"]] = k.p_ch_max_w / W_PER_KW
        vb_up[:, _J["p_dis"]] = k.p_d_max_w / W_PER_KW
        vb_up[:, _J["p_fc"]] = k.p_fc_max_w / W_PER_KW
        vb_up[:, _J["p_hp_sh"]] = h.p_hp_max_w / W_PER_KW
        vb_up[:, _J["p_hp_dhw"]] = h.p_hp_max_w / W_PER_KW
        if not o.fc_heat_dump:  # eq:DHW_heat as printed: every kWh of recovered heat enters the tank
            vb_up[:, _J["q_dump"]] = 0.0
        lo[self.m_con:] = vb_lo.ravel()
        up[self.m_con:] = vb_up.ravel()
        # linear objective
        c = k.costs
        q = np.zeros((n, self.nv))
        q[:, _J["p_buy"]] = dt * h.price_buy_eur_per_kwh
        q[:, _J["p_sell"]] = -dt * h.price_sell_eur_per_kwh
        q[:, _J["p_ch"]] = dt * c.sigma_b_ch_eur_per_kwh
        q[:, _J["p_dis"]] = dt * c.sigma_b_d_eur_per_kwh
        q[:, _J["p_fc"]] = dt * c.sigma_fc_eur_per_h / (k.p_fc_max_w / W_PER_KW)
        q[:, _J["sl_t_lo"]] = q[:, _J["sl_t_hi"]] = dt * o.penalty_comfort_eur_per_kh
        q[:, _J["sl_v_lo"]] = q[:, _J["sl_v_hi"]] = dt * o.penalty_dhw_eur_per_lh
        q[:, _J["sl_soc_lo"]] = q[:, _J["sl_soc_hi"]] = dt * o.penalty_soc_eur_per_h / self.e_b_kwh
        q[:, _J["sl_loh"]] = dt * o.penalty_loh_eur_per_h / self.e_h2_kwh
        q[:, _J["t_air"]] = -2.0 * o.w_comfort_track_eur_per_k2 * dt * (h.t_min_c + o.comfort_margin_k)
        return a_data, q.ravel(), lo, up

    def solve(self, h: HorizonData) -> tuple[int, np.ndarray | None, float, str]:
        """Solve for ``h``, warm-started from the previous solution shifted by one step.

        Parameters
        ----------
        h : HorizonData
            The horizon (:meth:`matrices` turns it into the problem's data).

        Returns
        -------
        code : int
            ``STATUS_OPTIMAL``, ``STATUS_FEASIBLE`` (solved inaccurately) or ``STATUS_NONE``.
        x : numpy.ndarray or None
            The solution (None without one).
        solve_s : float
            Solve time [s].
        status : str
            OSQP's status text.
        """
        a_data, q, lo, up = self.matrices(h)
        t0 = time.perf_counter()
        if self.solver is None:
            a = sp.csc_matrix((a_data, self._csc_indices, self._csc_indptr), shape=(self.m, self.nz))
            self.solver = osqp.OSQP()
            self.solver.setup(self.P, q, a, lo, up, eps_abs=self.o.eps_abs, eps_rel=self.o.eps_rel,
                              max_iter=self.o.max_iter, polishing=self.o.polish, verbose=False,
                              time_limit=self.o.time_limit_s)
        else:
            self.solver.update(q=q, l=lo, u=up, Ax=a_data)
            if self._x_prev is not None:
                shifted = self._x_prev.reshape(self.n, self.nv)
                shifted = np.vstack([shifted[1:], shifted[-1:]]).ravel()
                self.solver.warm_start(x=shifted)
        res = self.solver.solve(raise_error=False)
        solve_s = time.perf_counter() - t0
        status = str(res.info.status)
        val = res.info.status_val
        if val == osqp.SolverStatus.OSQP_SOLVED:
            code = STATUS_OPTIMAL
        elif val == osqp.SolverStatus.OSQP_SOLVED_INACCURATE:
            code = STATUS_FEASIBLE
        else:
            code = STATUS_NONE
        x = None
        if code != STATUS_NONE and res.x is not None and np.all(np.isfinite(res.x)):
            x = np.asarray(res.x, dtype=float)
            self._x_prev = x
        else:
            code = STATUS_NONE
            self._x_prev = None
        return code, x, solve_s, status

    def plan(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Split a solution vector into the variables' values per step.

        Parameters
        ----------
        x : numpy.ndarray
            The solution z.

        Returns
        -------
        dict[str, numpy.ndarray]
            Variable name -> values per step: powers [W], SOC and LOH (and their slacks) [-],
            the rest in the problem's units.
        """
        z = x.reshape(self.n, self.nv)
        out = {name: z[:, j].copy() for name, j in _J.items()}
        for name in POWER_VARS:
            out[name] *= W_PER_KW
        for name in ("soc", "sl_soc_lo", "sl_soc_hi"):
            out[name] /= self.e_b_kwh
        for name in ("loh", "sl_loh"):
            out[name] /= self.e_h2_kwh
        return out


def _round_semicontinuous(value: float, low: float, high: float) -> float:
    """Round ``value`` to {0} U [low, high]: below ``low`` to the nearer of 0 and ``low``."""
    if value >= low:
        return min(value, high)
    return low if value >= 0.5 * low and low > 0 else 0.0


class QPController:
    """Continuous MPC solved with OSQP (``mpc-qp``).

    Parameters
    ----------
    params : PlantParams
        Plant parameters (the MPC's forecasting models).
    options : Mapping[str, Any], optional
        Overrides of ``config/mpc.yaml`` section ``mpc_qp``
        (:class:`~comems4build_ros.core.ems.settings.QPSettings`).
    """

    name = "mpc-qp"
    info_level = "mpc"
    settings_class = QPSettings

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None) -> None:
        self.params = params
        self.settings = load_settings(QPSettings, options)
        self.const = PlantConstants.from_params(params, self.settings.fc_lifecycle_eta)
        self.step_info: dict[str, float] = {}
        self.reset()

    def reset(self) -> None:
        """Start a new OSQP problem: no warm start, counters zero."""
        self.model = QPModel(self.const, self.settings)
        self.n_fallback = 0
        self.last_plan: dict[str, np.ndarray] | None = None
        self.step_info = {}

    def act(self, obs: Observation) -> Action:
        """Solve the relaxed horizon problem and apply its rounded first step.

        Parameters
        ----------
        obs : Observation
            The step's inputs, as for the MILP (:meth:`.controller.MPCController.act`).

        Returns
        -------
        Action
            The plan's first step with the semicontinuous powers rounded to {0} U [min, max],
            or the safe fallback without a solution.
        """
        h = build_horizon(obs, self.const, self.settings.loh_min_mode)
        code, x, solve_s, status = self.model.solve(h)
        k = self.const
        slack = dict.fromkeys(SLACK_VARS, 0.0)
        if x is None:
            self.n_fallback += 1
            self.last_plan = None
            action = safe_action(obs.t_air_c, obs.v_dhw_l, h.t_min_c[0], self.params)
            print(f"mpc-qp: step {obs.step}: OSQP {status}; safe fallback {action}", file=sys.stderr)
        else:
            plan = self.model.plan(x)
            self.last_plan = plan
            slack = {name: max(float(plan[name][0]), 0.0) for name in SLACK_VARS}
            pmax = float(h.p_hp_max_w[0])
            p_sh, p_dhw = max(plan["p_hp_sh"][0], 0.0), max(plan["p_hp_dhw"][0], 0.0)
            mode = HP_SH if p_sh >= p_dhw else HP_DHW
            mod = _round_semicontinuous(max(p_sh, p_dhw) / pmax, k.hp_mod_min, 1.0) if pmax > 0 else 0.0
            p_fc = _round_semicontinuous(float(plan["p_fc"][0]), k.p_fc_min_w, k.p_fc_max_w)
            p_bess = float(plan["p_ch"][0] - plan["p_dis"][0])
            action = Action(hp_mod=mod, hp_mode=mode if mod > 0 else HP_OFF, p_fc_w=p_fc,
                            p_bess_w=p_bess if abs(p_bess) > 1e-3 else 0.0)
        tol = max(self.settings.slack_report_tol, 100.0 * self.settings.eps_abs)  # above OSQP's tolerance
        self.step_info = {
            "solve_s": solve_s,
            "status": float(code),
            "optimal": 1.0 if code == STATUS_OPTIMAL else 0.0,
            "fallback": 1.0 if x is None else 0.0,
            "slack_used": 1.0 if any(v > tol for v in slack.values()) else 0.0,
            "slack_t_lo_k": slack["sl_t_lo"],
            "slack_t_hi_k": slack["sl_t_hi"],
            "slack_v_lo_l": slack["sl_v_lo"],
            "slack_v_hi_l": slack["sl_v_hi"],
            "slack_soc": slack["sl_soc_lo"] + slack["sl_soc_hi"],
            "slack_loh": slack["sl_loh"],
            "objective_eur": math.nan,
        }
        return action
