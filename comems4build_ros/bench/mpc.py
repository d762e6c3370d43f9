"""MPC solve times: the same horizon problems with every solver and formulation step, plus a full run.

1. Runs the MPC (default settings of ``config/mpc.yaml``) in closed loop over the default
   scenario (12 weeks) and reports its wall time.
2. Takes the horizon problems of whole days from that run: the coldest, the mildest and
   the sunniest day (``--days-per-kind`` of each, 24 consecutive problems per day, so a
   warm start from the previous plan is possible as in closed loop).
3. Solves them with each configuration (formulation steps and solvers, see ``CONFIGS``)
   and prints, per configuration, the median and p95 solve time and the objective gap
   to the best known solution (the best objective any exact configuration reached,
   including a gap-0 reference solve). For a relaxed-tail configuration the gap is that of
   the exact problem with its first-step binaries fixed (the decision it applies).
4. Optionally (``--kpi-weeks W``) runs the first W weeks in closed loop with the default
   settings and with the exact gap-0 reference settings and compares their weekly KPIs.

Solve time = wall time of one solve call including PuLP's hand-over to the solver.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..commands.options import COUNT, SECONDS, WEEKS, real
from ..progress import ProgressBar, ProgressCallback

#: Options of the exact reference solve (best known solution): full binaries, gap 0.
REFERENCE = {"integer_steps": 24, "mip_rel_gap": 0.0, "warm_start": False, "time_limit_s": 120.0}
#: HiGHS defaults restored (the config file turns some heuristics off).
HIGHS_DEFAULTS = {"highs_options": {}}

#: label -> (options over config/mpc.yaml, exact problem?) ; the formulation steps in order.
CONFIGS: dict[str, tuple[dict[str, Any], bool]] = {
    "1 paper formulation, HiGHS defaults": (
        {"formulation": "paper", "integer_steps": 24, "warm_start": False, **HIGHS_DEFAULTS}, True),
    "2 tight big-M / fewer binaries": ({"integer_steps": 24, "warm_start": False, **HIGHS_DEFAULTS}, True),
    "3 + HiGHS options": ({"integer_steps": 24, "warm_start": False}, True),
    "4 + warm start": ({"integer_steps": 24, "warm_start": True}, True),
    "5 + relaxed tail (default)": ({}, False),
    "CBC, tight, warm start": ({"solver": "cbc", "integer_steps": 24, "warm_start": True}, True),
    "CBC, relaxed tail": ({"solver": "cbc"}, False),
    "Gurobi, tight, warm start": ({"solver": "gurobi", "integer_steps": 24, "warm_start": True}, True),
    "Gurobi, relaxed tail": ({"solver": "gurobi"}, False),
}

#: KPIs compared between the default and the gap-0 run (summary keys).
KPI_KEYS = (
    "cost_eur_total", "reimbursement_eur_total", "discomfort_kh_total", "buy_kwh_total", "sell_kwh_total",
    "bess_charged_kwh_total", "h2_kwh_total", "fc_working_hours", "fc_toggles",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench mpc``."""
    parser.add_argument("--weeks", metavar="N", type=WEEKS, default=12.0,
                        help="length of the closed-loop run [weeks], > 0")
    parser.add_argument("--days-per-kind", metavar="N", type=COUNT, default=1,
                        help="days taken per kind (cold, mild, sunny); 24 problems each (default 1 -> 72)")
    parser.add_argument("--configs", metavar="LIST", default="all",
                        help="comma-separated config numbers/labels prefixes (default all available)")
    parser.add_argument("--time-limit", metavar="S", type=SECONDS, default=30.0,
                        help="time limit per benchmark solve [s], > 0")
    parser.add_argument("--kpi-weeks", metavar="W", type=real(0), default=0.0,
                        help="also compare KPIs of W weeks at default settings with a gap-0 run, >= 0 (0: skip)")
    parser.add_argument("--skip-full-run", action="store_true",
                        help="take the problems from a run of --weeks with the default settings without timing")
    parser.add_argument("--out", metavar="DIR", default=None, help="directory for per-problem results (CSV/JSON)")


def _closed_loop(ctrl: Any, scenario: Any, params: Any, n_steps: int, progress: ProgressCallback | None = None) -> Any:
    """First ``n_steps`` steps of the closed loop (daily H2 allowance of the whole scenario)."""
    from ..plant import Plant
    from ..sim import TIMESERIES_COLUMNS, ObservationBuilder, evaluate_timeseries, exogenous_series, record_row

    ctrl.reset()
    plant = Plant(params)
    exo = exogenous_series(scenario, params)
    builder = ObservationBuilder(scenario, params, ctrl.info_level, exo)
    state = plant.initial_state()
    rows, infos = [], []
    for k in range(n_steps):
        action = ctrl.act(builder.build(k, state))
        infos.append(dict(ctrl.step_info))
        state, flows = plant.step(state, action, exo[k])
        rows.append(record_row(scenario.time[k].isoformat(), k, flows, state, action, exo[k],
                               (scenario.ghi_w_m2[k], scenario.spot_eur_per_mwh[k]), False))
        if progress is not None:
            progress(k + 1, n_steps)
    ts = pd.DataFrame(rows, columns=list(TIMESERIES_COLUMNS))
    ts = pd.concat([ts, pd.DataFrame(infos).add_prefix("ems_")], axis=1)
    return evaluate_timeseries(ts, params)


def select_days(scenario: Any, n_steps: int, per_kind: int) -> dict[str, list[int]]:
    """First steps of whole days: coldest (daily mean T_amb), mildest, sunniest (daily GHI sum).

    Day 0 is skipped (the start state is arbitrary); days are distinct across kinds.
    """
    n_days = n_steps // 24
    t = scenario.t_amb_c[: n_days * 24].reshape(n_days, 24).mean(axis=1)
    g = scenario.ghi_w_m2[: n_days * 24].reshape(n_days, 24).sum(axis=1)
    taken: set[int] = {0}
    out: dict[str, list[int]] = {}
    for kind, order in (("cold", np.argsort(t)), ("mild", np.argsort(-t)), ("sunny", np.argsort(-g))):
        days = [int(d) for d in order if int(d) not in taken][:per_kind]
        taken.update(days)
        out[kind] = [d * 24 for d in days]
    return out


def problems_from_run(ts: pd.DataFrame, scenario: Any, params: Any, starts: Mapping[str, list[int]]) -> list[tuple]:
    """(kind, step, Observation) for 24 consecutive steps from each start, states from the run."""
    from ..ems.base import INFO_LEVELS  # noqa: F401 - documents the level used
    from ..sim import ObservationBuilder, exogenous_series
    from ..types import PlantState

    builder = ObservationBuilder(scenario, params, "mpc", exogenous_series(scenario, params))
    out = []
    for kind, firsts in starts.items():
        for k0 in firsts:
            for k in range(k0, k0 + 24):
                r = ts.iloc[k - 1]
                state = PlantState(soc=r.soc, loh=r.loh, t_air_c=r.t_air_c, t_wall_in_c=r.t_wall_in_c,
                                   t_wall_out_c=r.t_wall_out_c, v_dhw_l=r.v_dhw_l, hp_mod=r.hp_mod,
                                   fc_on=bool(r.fc_on))
                out.append((kind, k, builder.build(k, state)))
    return out


def solve_set(params: Any, options: Mapping[str, Any], problems: Sequence[tuple],
              progress: ProgressCallback | None = None) -> list[dict[str, Any]]:
    """Solve every problem in order; warm start chains within a day as in closed loop."""
    from ..ems.mpc import MPCController

    ctrl = MPCController(params, {**options, "log_fallback": False})
    out = []
    prev_k = None
    for kind, k, obs in problems:
        if prev_k is None or k != prev_k + 1:
            ctrl.reset()
        res = ctrl.plan(obs)
        ctrl._prev_plan = res.plan if res.has_solution else None
        first = {name: float(res.plan[name][0]) for name in ctrl.model.binary_names()} if res.has_solution else None
        out.append({"kind": kind, "step": k, "solve_s": res.solve_s, "objective": res.objective,
                    "status": res.status, "first": first})
        prev_k = k
        if progress is not None:
            progress(len(out), len(problems))
    return out


def exact_with_first_fixed(params: Any, problems: Sequence[tuple], firsts: Sequence[dict | None],
                           time_limit: float) -> list[float]:
    """Exact objective of each problem with the step-0 binaries fixed (NaN if none given)."""
    from ..ems.mpc import MPCController

    ctrl = MPCController(params, {**REFERENCE, "time_limit_s": time_limit, "mip_rel_gap": 1e-4,
                                  "log_fallback": False})
    out = []
    for (_, _, obs), first in zip(problems, firsts):
        if first is None:
            out.append(math.nan)
            continue
        ctrl.model.fix_first_step(first)
        res = ctrl.plan(obs)
        ctrl.model.fix_first_step(None)
        out.append(res.objective)
    return out


def _pick_configs(spec: str, available: Sequence[str]) -> dict[str, tuple[dict[str, Any], bool]]:
    out = {}
    for label, (opts, exact) in CONFIGS.items():
        if opts.get("solver", "highs") not in available:
            continue
        if spec == "all" or any(label.startswith(s.strip()) for s in spec.split(",")):
            out[label] = (opts, exact)
    return out


def run(args: argparse.Namespace) -> int:
    """Run the benchmark and print the tables."""
    from ..config import load_plant_params
    from ..ems.mpc import MPCController
    from ..ems.mpc.settings import MILPOptions, load_options
    from ..ems.mpc.solvers import available_solvers
    from ..scenario import default_scenario
    from ..sim import simulate

    params = load_plant_params()
    weeks = int(math.ceil(args.weeks))
    scenario = default_scenario(params, weeks=weeks)
    defaults = load_options(MILPOptions, "mpc", {})
    print(f"bench mpc: default settings {defaults.model_dump()}")
    solvers = available_solvers()
    print(f"solvers available: {', '.join(solvers)}" + ("" if "gurobi" in solvers else " (gurobipy not installed)"))

    t0 = time.perf_counter()
    with ProgressBar("full run", unit="step") as bar:
        result = simulate("mpc", scenario, params, progress=bar)
    wall = time.perf_counter() - t0
    ts = result.timeseries
    print(f"\nfull run: {scenario.n_steps} steps ({scenario.n_steps / 168:.1f} weeks) with {defaults.solver}: "
          f"wall {wall:.1f} s (EMS {result.summary.get('ems_s', math.nan):.1f} s), solve median "
          f"{ts['ems_solve_s'].median() * 1e3:.1f} ms, p95 {ts['ems_solve_s'].quantile(0.95) * 1e3:.1f} ms, "
          f"fallbacks {int(ts['ems_fallback'].sum())}, steps with slack {int(ts['ems_slack_used'].sum())}")

    starts = select_days(scenario, scenario.n_steps, args.days_per_kind)
    problems = problems_from_run(ts, scenario, params, starts)
    print(f"\nproblem set: {len(problems)} horizon problems, days starting at steps "
          + ", ".join(f"{kind} {v}" for kind, v in starts.items()))

    configs = _pick_configs(args.configs, solvers)
    results: dict[str, list[dict[str, Any]]] = {}
    with ProgressBar("reference: tight, gap 0", unit="solve") as bar:
        ref = solve_set(params, {**REFERENCE, "time_limit_s": max(args.time_limit, 60.0)}, problems, bar)
    results["reference: tight, gap 0"] = ref
    for label, (opts, _) in configs.items():
        t = time.perf_counter()
        with ProgressBar(label, unit="solve") as bar:
            results[label] = solve_set(params, {"time_limit_s": args.time_limit, **opts}, problems, bar)
        print(f"  solved with '{label}' in {time.perf_counter() - t:.1f} s", flush=True)
    exact_labels = ["reference: tight, gap 0"] + [lb for lb, (_, ex) in configs.items() if ex]
    best = np.nanmin(np.array([[r["objective"] for r in results[lb]] for lb in exact_labels]), axis=0)
    rows = []
    for label, res in results.items():
        exact = label in exact_labels
        if exact:
            obj = np.array([r["objective"] for r in res])
        else:
            obj = np.array(exact_with_first_fixed(params, problems, [r["first"] for r in res], args.time_limit))
        gap = (obj - best) / np.maximum(np.abs(best), 1e-9)
        st = np.array([r["solve_s"] for r in res])
        rows.append({
            "configuration": label,
            "median_ms": np.median(st) * 1e3,
            "p95_ms": np.quantile(st, 0.95) * 1e3,
            "mean_gap_pct": np.nanmean(gap) * 100,
            "max_gap_pct": np.nanmax(gap) * 100,
            "no_solution": int(np.sum(~np.isfinite(obj))),
        })
    table = pd.DataFrame(rows)
    print("\nsolve time and objective gap to the best known solution "
          f"({len(problems)} problems; gap of relaxed-tail rows = exact problem with first step fixed):")
    print(table.to_string(index=False, float_format=lambda x: f"{x:.2f}"))

    kpi_table = None
    if args.kpi_weeks > 0:
        n = int(round(args.kpi_weeks * 168))
        with ProgressBar("default settings", unit="step") as bar:
            chosen = _closed_loop(MPCController(params, {}), scenario, params, n, bar)
        with ProgressBar("exact, gap 0", unit="step") as bar:
            exact = _closed_loop(MPCController(params, {**REFERENCE, "time_limit_s": 300.0}), scenario, params, n,
                                 bar)
        kpi_rows = []
        for key in KPI_KEYS:
            a, b = float(chosen.summary[key]), float(exact.summary[key])
            kpi_rows.append({"kpi": key, "default": a, "gap0_exact": b,
                             "diff_pct": (a - b) / abs(b) * 100 if abs(b) > 1e-9 else math.nan})
        kpi_table = pd.DataFrame(kpi_rows)
        print(f"\nKPIs over the first {args.kpi_weeks:g} weeks: default settings vs exact MILP at gap 0 "
              f"(solve median {chosen.timeseries['ems_solve_s'].median() * 1e3:.0f} ms vs "
              f"{exact.timeseries['ems_solve_s'].median() * 1e3:.0f} ms):")
        print(kpi_table.to_string(index=False, float_format=lambda x: f"{x:.3f}"))

    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "bench_mpc.csv", index=False)
        if kpi_table is not None:
            kpi_table.to_csv(out / "bench_mpc_kpi.csv", index=False)
        per = []
        for label, res in results.items():
            per.extend({"configuration": label, **{k: v for k, v in r.items() if k != "first"}} for r in res)
        pd.DataFrame(per).to_csv(out / "bench_mpc_problems.csv", index=False)
        (out / "bench_mpc_run.json").write_text(json.dumps({"wall_s": wall, "steps": int(scenario.n_steps)}) + "\n")
    return 0
