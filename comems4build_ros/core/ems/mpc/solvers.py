"""MILP solvers behind the PuLP model: HiGHS and Gurobi through their Python APIs, CBC through PuLP.

The PuLP problem (:class:`.milp.MILPModel`) is the source of the model: it is built once,
and every step changes its right-hand sides, objective coefficients, bounds and a few
matrix coefficients in place. :class:`MatrixForm` reads the problem's arrays once, in a
fixed column and row order with PuLP's time-indexed names (``soc_3``, ``balance_0``), and
re-reads the parts that can change before each solve, so the PuLP objects are not walked
and converted in full at every step (what PuLP's own solver interfaces do):

- :class:`HighsBackend` (``highs``, default): HiGHS through highspy; the cached arrays go
  to a new ``highspy.Highs`` instance in one ``passModel`` call per solve (see the class for
  why not one instance changed in place); MIP start with ``setSolution`` (integer values
  only, HiGHS completes them by an LP).
- :class:`GurobiBackend` (``gurobi``, optional, needs ``gurobipy``; ``pip install
  .[gurobi]``): one ``gurobipy.Model`` for the run, and only the entries that changed are
  passed through the ``RHS``, ``Obj``, ``LB``, ``UB`` and ``VType`` attributes and
  ``chgCoeff``; MIP start through ``Start``.
- :class:`PulpBackend` (``cbc``, and ``highs_pulp`` for comparison): PuLP's solver
  interfaces, which hand the whole model to the solver at every solve: CBC through a
  subprocess and an .mst MIP start file, HiGHS through :class:`PulpHiGHS` (PuLP's HiGHS
  class with the model passed in one ``passModel`` call and a MIP start).

docs/mpc.md measures the backends against each other (``comems4build bench mpc``).
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pulp

from comems4build_ros.core.config import ConfigError

#: PuLP categories of integer columns (PuLP turns ``LpBinary`` into ``LpInteger`` at creation).
_INTEGER = (pulp.LpInteger, pulp.LpBinary)
#: Solver names (``gurobi`` only when gurobipy is importable).
SOLVER_NAMES = ("highs", "highs_pulp", "cbc", "gurobi")


def gurobi_available() -> bool:
    """Tell whether gurobipy can be imported (an optional extra, never required).

    Returns
    -------
    bool
        True if it can.
    """
    return importlib.util.find_spec("gurobipy") is not None


def available_solvers() -> list[str]:
    """List the solver names :func:`make_backend` accepts on this machine.

    Returns
    -------
    list[str]
        Names of :data:`SOLVER_NAMES` (``gurobi`` only with gurobipy installed).
    """
    return [name for name in SOLVER_NAMES if name != "gurobi" or gurobi_available()]


@dataclass
class RawSolution:
    """What a backend returns from one solve.

    Attributes
    ----------
    sol_status : int
        PuLP solution status code (``pulp.LpSolutionOptimal``,
        ``pulp.LpSolutionIntegerFeasible``, ``pulp.LpSolutionNoSolutionFound``, ...).
    x : numpy.ndarray or None
        Column values in :class:`MatrixForm` order (``None`` without a solution).
    objective : float
        Objective value incl. the constant [EUR] (NaN without a solution).
    gap : float
        Relative MIP gap reported by the solver [-] (NaN if unknown).
    error : str
        Solver error text ("" if none).
    """

    sol_status: int
    x: np.ndarray | None
    objective: float = math.nan
    gap: float = math.nan
    error: str = ""


class MatrixForm:
    """The arrays of a PuLP problem in a fixed order, read once; the changing parts re-read per solve.

    Parameters
    ----------
    prob : pulp.LpProblem
        The PuLP problem (its variables and constraints never change after this).
    mutable : Sequence[tuple[pulp.LpConstraint, pulp.LpVariable]]
        (constraint, variable) pairs whose matrix coefficient may change between solves.
    """

    def __init__(self, prob: pulp.LpProblem, mutable: Sequence[tuple[pulp.LpConstraint, pulp.LpVariable]] = ()):
        self.prob = prob
        self.variables: list[pulp.LpVariable] = prob.variables()
        self.constraints: list[pulp.LpConstraint] = list(prob.constraints.values())
        self.col_names = [v.name for v in self.variables]
        self.row_names = list(prob.constraints.keys())
        self.col_index = {name: j for j, name in enumerate(self.col_names)}
        row_of = {id(con): i for i, con in enumerate(self.constraints)}
        starts, index, value = [0], [], []
        for con in self.constraints:
            for var, coef in con.items():
                index.append(self.col_index[var.name])
                value.append(float(coef))
            starts.append(len(index))
        self.row_start = np.asarray(starts, dtype=np.int32)
        self.row_col = np.asarray(index, dtype=np.int32)
        self.row_val = np.asarray(value, dtype=float)
        #: row sense: -1 for <=, 0 for =, 1 for >= (PuLP's codes)
        self.sense = np.array([con.sense for con in self.constraints], dtype=int)
        self.mutable = [(row_of[id(con)], self.col_index[var.name], con, var) for con, var in mutable]
        self.mutable_rows = np.array([m[0] for m in self.mutable], dtype=np.int32)
        self.mutable_cols = np.array([m[1] for m in self.mutable], dtype=np.int32)
        #: position of each mutable coefficient in ``row_val``
        self.mutable_pos = np.array([self.row_start[r] + int(np.flatnonzero(self.row_col[self.row_start[r]:
                                                                                    self.row_start[r + 1]] == j)[0])
                                     for r, j, _, _ in self.mutable], dtype=np.int64)

    @property
    def n_cols(self) -> int:
        """Number of variables."""
        return len(self.variables)

    @property
    def n_rows(self) -> int:
        """Number of constraints."""
        return len(self.constraints)

    def costs(self) -> np.ndarray:
        """Read the objective coefficients per column (minimisation).

        Returns
        -------
        numpy.ndarray
            Coefficients [EUR per unit of each variable].
        """
        c = np.zeros(self.n_cols)
        idx = self.col_index
        for var, coef in self.prob.objective.items():
            c[idx[var.name]] = coef
        return c

    def offset(self) -> float:
        """Read the constant of the objective.

        Returns
        -------
        float
            The constant [EUR].
        """
        return float(self.prob.objective.constant)

    def col_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Read the column bounds.

        Returns
        -------
        lo, up : numpy.ndarray
            Lower and upper bounds (``-inf`` / ``inf`` where PuLP has none).
        """
        lo = np.array([-math.inf if v.lowBound is None else v.lowBound for v in self.variables], dtype=float)
        up = np.array([math.inf if v.upBound is None else v.upBound for v in self.variables], dtype=float)
        return lo, up

    def rhs(self) -> np.ndarray:
        """Read the right-hand side of every row (``expr <sense> rhs``).

        Returns
        -------
        numpy.ndarray
            One value per row.
        """
        return np.array([-con.constant for con in self.constraints], dtype=float)

    def integrality(self) -> np.ndarray:
        """Mark the integer (binary) columns.

        Returns
        -------
        numpy.ndarray
            True for an integer column.
        """
        return np.array([v.cat in _INTEGER for v in self.variables], dtype=bool)

    def mutable_values(self) -> np.ndarray:
        """Read the current values of the mutable matrix coefficients.

        Returns
        -------
        numpy.ndarray
            One value per mutable (constraint, variable) pair.
        """
        return np.array([con[var] for _, _, con, var in self.mutable], dtype=float)

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """Collect the MIP start: the integer columns with a ``varValue``.

        Returns
        -------
        idx : numpy.ndarray
            Their column indices.
        vals : numpy.ndarray
            Their rounded values.
        """
        idx = [j for j, v in enumerate(self.variables) if v.cat in _INTEGER and v.varValue is not None]
        vals = np.array([round(self.variables[j].varValue) for j in idx], dtype=float)
        return np.asarray(idx, dtype=np.int32), vals

    def set_values(self, x: np.ndarray | None) -> None:
        """Write a solution into the PuLP variables.

        Parameters
        ----------
        x : numpy.ndarray or None
            Column values in this form's order; None clears them.
        """
        for j, var in enumerate(self.variables):
            var.varValue = None if x is None else float(x[j])


class _Snapshot:
    """Arrays last passed to a backend's model; :meth:`diff` gives the entries to update."""

    def __init__(self, form: MatrixForm) -> None:
        self.form = form
        self.cost = form.costs()
        self.col_lo, self.col_up = form.col_bounds()
        self.rhs = form.rhs()
        self.integ = form.integrality()
        self.coef = form.mutable_values()

    def refresh(self) -> None:
        """Read the changing parts of the PuLP problem again."""
        self.diff()

    def diff(self) -> dict[str, np.ndarray]:
        """Read the changing parts again and keep them.

        Returns
        -------
        dict[str, numpy.ndarray]
            Per kind (``cost``, ``bounds``, ``rhs``, ``integ``, ``coef``) the indices that changed.
        """
        form = self.form
        cost = form.costs()
        lo, up = form.col_bounds()
        rhs = form.rhs()
        integ = form.integrality()
        coef = form.mutable_values()
        out = {
            "cost": np.flatnonzero(cost != self.cost),
            "bounds": np.flatnonzero((lo != self.col_lo) | (up != self.col_up)),
            "rhs": np.flatnonzero(rhs != self.rhs),
            "integ": np.flatnonzero(integ != self.integ),
            "coef": np.flatnonzero(coef != self.coef),
        }
        self.cost, self.col_lo, self.col_up, self.rhs, self.integ, self.coef = cost, lo, up, rhs, integ, coef
        return out

    def values(self) -> np.ndarray:
        """Return the row-wise matrix values with the current mutable coefficients."""
        vals = self.form.row_val.copy()
        vals[self.form.mutable_pos] = self.coef
        return vals


#: Thread count of HiGHS's process-wide task scheduler (set by the first solve; 0: not started).
_highs_scheduler_threads = 0


def _highs_scheduler(highspy: Any, threads: int) -> None:
    """Restart HiGHS's process-wide scheduler if ``threads`` differs from its thread count.

    HiGHS starts one scheduler per process with the thread count of the first solve; a later
    solve that asks for another count fails ("Not Set"), so controllers with different
    ``threads`` in one process (benchmarks, tests) need the restart.
    """
    global _highs_scheduler_threads
    if threads != _highs_scheduler_threads:
        if _highs_scheduler_threads:
            highspy.Highs.resetGlobalScheduler(True)
        _highs_scheduler_threads = threads


def _highs_lp(highspy: Any, form: MatrixForm, snap: _Snapshot, names: bool = True) -> Any:
    """Build a ``HighsLp`` of the problem's current arrays (``snap``)."""
    inf = highspy.kHighsInf
    lp = highspy.HighsLp()
    lp.num_col_ = form.n_cols
    lp.num_row_ = form.n_rows
    lp.col_cost_ = snap.cost
    lp.offset_ = form.offset()
    lp.col_lower_ = np.clip(snap.col_lo, -inf, inf)
    lp.col_upper_ = np.clip(snap.col_up, -inf, inf)
    lp.row_lower_ = np.where(form.sense == pulp.LpConstraintLE, -inf, snap.rhs)
    lp.row_upper_ = np.where(form.sense == pulp.LpConstraintGE, inf, snap.rhs)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.start_ = form.row_start
    lp.a_matrix_.index_ = form.row_col
    lp.a_matrix_.value_ = snap.values()
    if names:
        lp.col_names_ = form.col_names
        lp.row_names_ = form.row_names
    if snap.integ.any():
        kint, kcont = highspy.HighsVarType.kInteger, highspy.HighsVarType.kContinuous
        lp.integrality_ = [kint if f else kcont for f in snap.integ]
    return lp


class HighsBackend:
    """HiGHS through highspy behind the PuLP model: cached arrays, one ``passModel`` per solve.

    The arrays are read from the PuLP problem once and refreshed before each solve; each
    solve passes them to a new ``highspy.Highs`` instance (about 0.4 ms). An instance kept
    across solves and changed in place (``changeRowsBounds``, ``changeColsCost``, ...) was
    as fast, but with HiGHS 1.15.1 its results depended on the solves before it (the same
    sequence of horizons gave different solutions within the MIP gap from run to run), so
    every solve starts from a clean instance and depends only on its problem and MIP start.

    Parameters
    ----------
    form : MatrixForm
        The problem's arrays.
    mip_rel_gap : float
        Relative MIP gap [-].
    time_limit_s : float or None
        Time limit per solve [s] (``None``: none).
    threads : int
        HiGHS threads.
    warm_start : bool
        Pass the integer ``varValue`` s as a MIP start.
    options : Mapping[str, Any], optional
        Further HiGHS options (name -> value).
    msg : bool
        Solver log on stdout.

    Raises
    ------
    ConfigError
        For an option HiGHS rejects.
    """

    name = "highs"

    def __init__(self, form: MatrixForm, mip_rel_gap: float = 0.0, time_limit_s: float | None = None,
                 threads: int = 1, warm_start: bool = False, options: Mapping[str, Any] | None = None,
                 msg: bool = False) -> None:
        import highspy

        self._hs = highspy
        self.form = form
        self.warm_start = warm_start
        self.threads = int(threads)
        opts: dict[str, Any] = {"output_flag": bool(msg), "mip_rel_gap": float(mip_rel_gap), "threads": self.threads}
        if time_limit_s is not None:
            opts["time_limit"] = float(time_limit_s)
        opts.update(options or {})
        probe = highspy.Highs()
        for key, val in opts.items():
            if probe.setOptionValue(key, val) != highspy.HighsStatus.kOk:
                raise ConfigError(f"highs_options: HiGHS rejects option {key} = {val!r}")
        self.options = opts
        self.snapshot = _Snapshot(form)
        #: the ``highspy.Highs`` instance of the last solve (solution, info, the model with its names)
        self.h: Any = None

    def solve(self) -> RawSolution:
        """Refresh the arrays, pass them to a new HiGHS instance with the MIP start, run, read the solution.

        Returns
        -------
        RawSolution
            Status, solution, objective [EUR] and gap [-].
        """
        hs = self._hs
        snap = self.snapshot
        snap.refresh()
        h = self.h = hs.Highs()
        for key, val in self.options.items():
            h.setOptionValue(key, val)
        if h.passModel(_highs_lp(hs, self.form, snap)) != hs.HighsStatus.kOk:
            return RawSolution(pulp.LpSolutionNoSolutionFound, None, error="HiGHS refused the model (passModel)")
        if self.warm_start and snap.integ.any():
            idx, vals = self.form.start()
            if idx.size:
                h.setSolution(int(idx.size), idx, vals)
        _highs_scheduler(hs, self.threads)
        if h.run() == hs.HighsStatus.kError:
            text = h.modelStatusToString(h.getModelStatus())
            return RawSolution(pulp.LpSolutionNoSolutionFound, None, error=f"HiGHS: {text}")
        info = h.getInfo()
        status = h.getModelStatus()
        if int(info.primal_solution_status) != int(hs.SolutionStatus.kSolutionStatusFeasible):
            codes = {hs.HighsModelStatus.kInfeasible: pulp.LpSolutionInfeasible,
                     hs.HighsModelStatus.kUnbounded: pulp.LpSolutionUnbounded}
            code = codes.get(status, pulp.LpSolutionNoSolutionFound)
            return RawSolution(code, None)
        x = np.asarray(h.getSolution().col_value, dtype=float)
        code = pulp.LpSolutionOptimal if status == hs.HighsModelStatus.kOptimal else pulp.LpSolutionIntegerFeasible
        gap = float(info.mip_gap) if snap.integ.any() else 0.0
        return RawSolution(code, x, float(info.objective_function_value), gap)


class GurobiBackend:
    """The model kept in one ``gurobipy.Model``, updated in place before each solve (optional solver).

    Before each solve the model is reset to an unsolved state (``Model.reset``): otherwise
    Gurobi starts from the previous solve's basis and, within the MIP gap, returns plans
    that depend on the solves before (tested); the MIP start is the only state carried over.

    Parameters
    ----------
    form, mip_rel_gap, time_limit_s, threads, warm_start, msg
        As :class:`HighsBackend`.
    options : Mapping[str, Any], optional
        Gurobi parameters (name -> value).

    Raises
    ------
    ConfigError
        For a parameter Gurobi rejects.
    """

    name = "gurobi"

    def __init__(self, form: MatrixForm, mip_rel_gap: float = 0.0, time_limit_s: float | None = None,
                 threads: int = 1, warm_start: bool = False, options: Mapping[str, Any] | None = None,
                 msg: bool = False) -> None:
        import gurobipy as gp
        import scipy.sparse as sp

        self._gp = gp
        self.form = form
        self.warm_start = warm_start
        self.env = gp.Env(empty=True)
        self.env.setParam("OutputFlag", 1 if msg else 0)
        self.env.start()
        m = self.model = gp.Model("mpc_horizon", env=self.env)
        params: dict[str, Any] = {"MIPGap": float(mip_rel_gap), "Threads": int(threads)}
        if time_limit_s is not None:
            params["TimeLimit"] = float(time_limit_s)
        params.update(options or {})
        for key, val in params.items():
            try:
                m.setParam(key, val)
            except gp.GurobiError as exc:
                raise ConfigError(f"gurobi_options: Gurobi rejects parameter {key} = {val!r} ({exc})") from exc
        snap = self.snapshot = _Snapshot(form)
        vtype = np.where(snap.integ, gp.GRB.BINARY, gp.GRB.CONTINUOUS)
        # binaries keep their [0, 1] bounds through LB/UB (fixing the first step sets them equal)
        self.x = m.addMVar(form.n_cols, lb=snap.col_lo, ub=snap.col_up, obj=snap.cost, vtype=vtype,
                           name=form.col_names)
        a = sp.csr_matrix((snap.values(), form.row_col, form.row_start), shape=(form.n_rows, form.n_cols))
        sense = np.where(form.sense == pulp.LpConstraintLE, "<", np.where(form.sense == pulp.LpConstraintGE, ">", "="))
        self.rows = m.addMConstr(a, self.x, sense, snap.rhs, name=form.row_names)
        m.ObjCon = form.offset()
        m.update()
        self.vars = self.x.tolist()
        self.constrs = self.rows.tolist()

    def sync(self) -> None:
        """Pass the entries of the PuLP problem that changed since the last solve."""
        gp, m, d, snap, form = self._gp, self.model, self.snapshot.diff(), self.snapshot, self.form
        if d["cost"].size:
            m.setAttr("Obj", [self.vars[j] for j in d["cost"]], snap.cost[d["cost"]].tolist())
        if d["bounds"].size:
            sel = [self.vars[j] for j in d["bounds"]]
            m.setAttr("LB", sel, snap.col_lo[d["bounds"]].tolist())
            m.setAttr("UB", sel, snap.col_up[d["bounds"]].tolist())
        if d["rhs"].size:
            m.setAttr("RHS", [self.constrs[i] for i in d["rhs"]], snap.rhs[d["rhs"]].tolist())
        if d["integ"].size:
            m.setAttr("VType", [self.vars[j] for j in d["integ"]],
                      [gp.GRB.BINARY if f else gp.GRB.CONTINUOUS for f in snap.integ[d["integ"]]])
        for i in d["coef"]:
            row, col = int(form.mutable_rows[i]), int(form.mutable_cols[i])
            m.chgCoeff(self.constrs[row], self.vars[col], float(snap.coef[i]))

    def solve(self) -> RawSolution:
        """Sync, reset, set the MIP start, optimise, read the solution.

        Returns
        -------
        RawSolution
            Status, solution, objective [EUR] and gap [-].

        Raises
        ------
        ConfigError
            If the model exceeds the Gurobi licence's size limit.
        """
        gp, m = self._gp, self.model
        grb = gp.GRB
        self.sync()
        m.reset()
        start = np.full(self.form.n_cols, grb.UNDEFINED)
        if self.warm_start:
            idx, vals = self.form.start()
            start[idx] = vals
        self.x.Start = start
        try:
            m.optimize()
        except gp.GurobiError as exc:
            if exc.errno == grb.Error.SIZE_LIMIT_EXCEEDED:
                raise ConfigError(f"solver 'gurobi': the model ({self.form.n_cols} variables, {self.form.n_rows} "
                                  f"constraints) exceeds this Gurobi licence's size limit ({exc})") from exc
            return RawSolution(pulp.LpSolutionNoSolutionFound, None, error=f"Gurobi: {exc}")
        if m.SolCount == 0:
            code = {grb.INFEASIBLE: pulp.LpSolutionInfeasible, grb.UNBOUNDED: pulp.LpSolutionUnbounded,
                    grb.INF_OR_UNBD: pulp.LpSolutionInfeasible}.get(m.Status, pulp.LpSolutionNoSolutionFound)
            return RawSolution(code, None)
        code = pulp.LpSolutionOptimal if m.Status == grb.OPTIMAL else pulp.LpSolutionIntegerFeasible
        gap = float(m.MIPGap) if m.IsMIP else 0.0
        return RawSolution(code, np.asarray(self.x.X, dtype=float), float(m.ObjVal), gap)


class PulpHiGHS(pulp.HiGHS):
    """``pulp.HiGHS`` with a bulk model hand-over and an optional MIP start (``highs_pulp``).

    PuLP adds the model column by column and row by row at every solve and has no MIP
    start for HiGHS; this passes the arrays in one ``passModel`` call and the integer
    variables' ``varValue`` s through ``setSolution``.

    Parameters
    ----------
    warm_start : bool
        Pass the integer ``varValue`` s as a MIP start.
    threads : int
        HiGHS threads.
    **kwargs : Any
        Further arguments of ``pulp.HiGHS`` (``msg``, ``timeLimit``, HiGHS options).
    """

    def __init__(self, warm_start: bool = False, threads: int = 1, **kwargs: Any) -> None:
        super().__init__(threads=threads, **kwargs)
        self.warm_start = warm_start
        self.n_threads = int(threads)

    def buildSolverModel(self, lp: pulp.LpProblem) -> None:  # noqa: N802 - PuLP's name
        """Pass ``lp`` to PuLP's HiGHS instance in one call, with the MIP start (PuLP calls this).

        Parameters
        ----------
        lp : pulp.LpProblem
            The problem PuLP solves.
        """
        import highspy

        form = MatrixForm(lp)
        for j, var in enumerate(form.variables):
            var.index = j  # PuLP's HiGHS class reads the solution by these indices
        for i, con in enumerate(form.constraints):
            con.index = i
        snap = _Snapshot(form)
        if not self.mip:
            snap.integ[:] = False
        lp.solverModel.passModel(_highs_lp(highspy, form, snap, names=False))
        if self.warm_start and snap.integ.any():
            idx, vals = form.start()
            if idx.size:
                lp.solverModel.setSolution(int(idx.size), idx, vals)
        _highs_scheduler(highspy, self.n_threads)


class PulpBackend:
    """A PuLP solver interface: the whole model is handed over at every solve.

    Parameters
    ----------
    form : MatrixForm
        The problem's arrays (for the column order of the result).
    solver : pulp.LpSolver
        A configured PuLP solver.
    name : str
        The solver's name (``highs_pulp``, ``cbc``).
    """

    def __init__(self, form: MatrixForm, solver: pulp.LpSolver, name: str) -> None:
        self.form = form
        self.solver = solver
        self.name = name

    def solve(self) -> RawSolution:
        """Run ``prob.solve(solver)`` and read the solution from the PuLP variables.

        Returns
        -------
        RawSolution
            Status, solution, objective [EUR] and gap [-] (NaN unless PuLP's HiGHS reports it).
        """
        prob = self.form.prob
        try:
            prob.solve(self.solver)
        except pulp.PulpSolverError as exc:  # e.g. CBC killed or unreadable solution file
            return RawSolution(pulp.LpSolutionNoSolutionFound, None, error=str(exc))
        code = prob.sol_status
        if code not in (pulp.LpSolutionOptimal, pulp.LpSolutionIntegerFeasible):
            return RawSolution(code, None)
        x = np.array([math.nan if v.varValue is None else v.varValue for v in self.form.variables], dtype=float)
        gap = math.nan
        model = getattr(prob, "solverModel", None)
        if model is not None and hasattr(model, "getInfo"):  # PuLP's HiGHS interface
            gap = float(model.getInfo().mip_gap)
        return RawSolution(code, x, float(pulp.value(prob.objective)), gap)


def make_backend(
    name: str,
    form: MatrixForm,
    mip_rel_gap: float = 0.0,
    time_limit_s: float | None = None,
    threads: int = 1,
    warm_start: bool = False,
    msg: bool = False,
    highs_options: Mapping[str, Any] | None = None,
    gurobi_options: Mapping[str, Any] | None = None,
) -> HighsBackend | GurobiBackend | PulpBackend:
    """Build a solver backend for the problem in ``form``.

    Parameters
    ----------
    name : {"highs", "highs_pulp", "cbc", "gurobi"}
        ``highs`` (highspy, arrays passed per solve), ``highs_pulp`` (:class:`PulpHiGHS`,
        model handed over per solve), ``cbc`` (PuLP's bundled CBC) or ``gurobi``.
    form : MatrixForm
        The problem's arrays.
    mip_rel_gap : float
        Relative MIP gap at which the solver stops [-].
    time_limit_s : float or None
        Wall-clock limit per solve [s] (``None``: none).
    threads : int
        Solver threads.
    warm_start : bool
        Use the integer variables' current values as a MIP start.
    msg : bool
        Solver log on stdout.
    highs_options : Mapping[str, Any], optional
        Further HiGHS options (``highs``, ``highs_pulp``).
    gurobi_options : Mapping[str, Any], optional
        Further Gurobi parameters (``gurobi``).

    Returns
    -------
    HighsBackend, GurobiBackend or PulpBackend
        The backend; its ``solve()`` returns a :class:`RawSolution`.

    Raises
    ------
    ConfigError
        Unknown solver name, ``gurobi`` without gurobipy installed, or an option the solver rejects.
    """
    if name == "highs":
        return HighsBackend(form, mip_rel_gap, time_limit_s, threads, warm_start, highs_options, msg)
    if name == "highs_pulp":
        opts = {"mip_rel_gap": mip_rel_gap, **(highs_options or {})}
        solver = PulpHiGHS(warm_start=warm_start, threads=threads, msg=msg, timeLimit=time_limit_s, **opts)
        return PulpBackend(form, solver, name)
    if name == "cbc":
        return PulpBackend(form, pulp.PULP_CBC_CMD(msg=msg, gapRel=mip_rel_gap, timeLimit=time_limit_s,
                                                   threads=threads, warmStart=warm_start), name)
    if name == "gurobi":
        if not gurobi_available():
            raise ConfigError("solver 'gurobi': gurobipy is not installed (optional: pip install .[gurobi]; "
                              "or use highs or cbc)")
        return GurobiBackend(form, mip_rel_gap, time_limit_s, threads, warm_start, gurobi_options, msg)
    raise ConfigError(f"solver: unknown value '{name}' (known: {', '.join(available_solvers())})")
