"""MILP solvers behind PuLP: HiGHS (highspy, in-process), CBC (bundled), Gurobi (optional).

:func:`make_solver` returns a configured ``pulp.LpSolver``. The HiGHS solver is PuLP's
``pulp.HiGHS`` with two changes measured in docs/mpc.md: the model is handed to highspy
in one ``passModel`` call (PuLP adds it column by column and row by row), and the
variables' current values are passed as a MIP start (``Highs.setSolution``), which
PuLP's HiGHS class does not support. CBC takes a MIP start through PuLP's ``warmStart``
(a .mst file); Gurobi through PuLP's ``warmStart`` (variable ``Start`` attributes).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pulp

from ...config import ConfigError


def gurobi_available() -> bool:
    """True if gurobipy can be imported (never required)."""
    return importlib.util.find_spec("gurobipy") is not None


def available_solvers() -> list[str]:
    """Names accepted by :func:`make_solver` on this machine."""
    out = ["highs", "cbc"]
    if gurobi_available():
        out.append("gurobi")
    return out


class FastHiGHS(pulp.HiGHS):
    """``pulp.HiGHS`` with a bulk model hand-over and an optional MIP start.

    Parameters
    ----------
    warm_start : pass the variables' current ``varValue`` of integer variables as a
        (partial) MIP start; HiGHS completes it by solving the LP with them fixed.
    **kwargs : as ``pulp.HiGHS`` (``gapRel``, ``timeLimit``, ``threads``, ``msg``, HiGHS options)
    """

    def __init__(self, warm_start: bool = False, **kwargs) -> None:
        super().__init__(**kwargs)
        self.warm_start = warm_start

    def buildSolverModel(self, lp: pulp.LpProblem) -> None:  # noqa: N802 - PuLP's name
        import highspy

        inf = highspy.kHighsInf
        variables = lp.variables()
        n = len(variables)
        sign = -1.0 if lp.sense == pulp.LpMaximize else 1.0
        cost = np.zeros(n)
        lower = np.empty(n)
        upper = np.empty(n)
        integ = np.zeros(n, dtype=np.uint8)
        for i, var in enumerate(variables):
            var.index = i
            lower[i] = -inf if var.lowBound is None else var.lowBound
            upper[i] = inf if var.upBound is None else var.upBound
            if var.cat == pulp.LpInteger and self.mip:
                integ[i] = 1
        for var, coef in lp.objective.items():
            cost[var.index] = sign * coef
        row_lo, row_up, starts, index, value = [], [], [0], [], []
        for i, con in enumerate(lp.constraints.values()):
            con.index = i
            for var, coef in con.items():
                if coef != 0:
                    index.append(var.index)
                    value.append(coef)
            starts.append(len(index))
            lb, ub = con.getLb(), con.getUb()
            row_lo.append(-inf if lb is None else lb)
            row_up.append(inf if ub is None else ub)
        model = highspy.HighsLp()
        model.num_col_ = n
        model.num_row_ = len(row_lo)
        model.col_cost_ = cost
        model.col_lower_ = lower
        model.col_upper_ = upper
        model.row_lower_ = np.asarray(row_lo, dtype=float)
        model.row_upper_ = np.asarray(row_up, dtype=float)
        model.offset_ = sign * float(lp.objective.constant)
        model.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
        model.a_matrix_.start_ = np.asarray(starts, dtype=np.int32)
        model.a_matrix_.index_ = np.asarray(index, dtype=np.int32)
        model.a_matrix_.value_ = np.asarray(value, dtype=float)
        if integ.any():
            model.integrality_ = [
                highspy.HighsVarType.kInteger if f else highspy.HighsVarType.kContinuous for f in integ
            ]
        lp.solverModel.passModel(model)
        if self.warm_start and integ.any():
            idx = [i for i in np.flatnonzero(integ) if variables[i].varValue is not None]
            if idx:
                vals = np.array([round(variables[i].varValue) for i in idx], dtype=float)
                lp.solverModel.setSolution(len(idx), np.asarray(idx, dtype=np.int32), vals)


def make_solver(
    name: str,
    mip_rel_gap: float = 0.0,
    time_limit_s: float | None = None,
    threads: int = 1,
    warm_start: bool = False,
    msg: bool = False,
    highs_options: dict | None = None,
) -> pulp.LpSolver:
    """A configured PuLP solver.

    Parameters
    ----------
    name : ``highs``, ``cbc`` or ``gurobi``
    mip_rel_gap : relative MIP gap at which the solver stops [-]
    time_limit_s : wall-clock limit per solve [s] (``None``: none)
    threads : solver threads
    warm_start : use the variables' current values as a MIP start
    highs_options : further HiGHS options (name -> value), HiGHS only

    Raises
    ------
    ConfigError
        Unknown solver name, or ``gurobi`` without gurobipy installed.
    """
    if name == "highs":
        opts = {"mip_rel_gap": mip_rel_gap, "threads": threads, **(highs_options or {})}
        return FastHiGHS(warm_start=warm_start, msg=msg, timeLimit=time_limit_s, **opts)
    if name == "cbc":
        return pulp.PULP_CBC_CMD(msg=msg, gapRel=mip_rel_gap, timeLimit=time_limit_s, threads=threads,
                                 warmStart=warm_start)
    if name == "gurobi":
        if not gurobi_available():
            raise ConfigError("solver 'gurobi': gurobipy is not installed (optional; use highs or cbc)")
        return pulp.GUROBI(msg=msg, gapRel=mip_rel_gap, timeLimit=time_limit_s, warmStart=warm_start,
                           Threads=threads)
    raise ConfigError(f"solver: unknown value '{name}' (known: {', '.join(available_solvers())})")
