"""MPC solve times: closed loops side by side, the formulation and solver steps on fixed problems, a full run.

1. **Closed loops side by side** (``--loop-weeks``, default 1 week of a scenario of that
   length, as ``simulate --ems mpc --weeks 1``): the default settings (HiGHS through
   highspy), the same with 2 threads, the settings before (HiGHS through PuLP per solve),
   Gurobi, CBC and the full MILP (``integer_steps=24``), each with its own plant, stepped
   in turn so that all see the same machine load. Prints per configuration the solve-time
   median / p95, the median CPU time per step (calling thread plus CBC's subprocess: less
   affected by other jobs than wall time) and the KPIs.
2. **Full run** (``--weeks``, default 12) with the default settings: wall time.
3. **Problem set**: the horizon problems of whole days of that run (the coldest, the
   mildest and the sunniest day, ``--days-per-kind`` of each, 24 consecutive problems per
   day so that the warm start chains as in closed loop), solved by every configuration of
   ``CONFIGS`` (formulation steps 1-9 and the solvers): median and p95 solve time and the
   objective gap to the best known solution (the best objective of any exact
   configuration, including a gap-0 reference). For a relaxed-tail configuration the gap
   is that of the exact problem with its first-step binaries fixed (the decision it applies).
4. Optionally (``--kpi-weeks W``) the first W weeks in closed loop with the default
   settings and with the exact gap-0 MILP, and their KPIs.

Solve time = ``ems_solve_s``: wall time of one solve call including passing the changes to
the solver and reading the solution. Gurobi rows say "not installed" without gurobipy.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from comems4build_ros.app.commands.options import COUNT, SECONDS, WEEKS, WEEKS_OR_OFF
from comems4build_ros.run.progress import ProgressBar, ProgressCallback

if TYPE_CHECKING:
    import pandas as pd

#: Options of the exact reference solve (best known solution): full binaries, gap 0.
REFERENCE = {"integer_steps": 24, "mip_rel_gap": 0.0, "warm_start": False, "time_limit_s": 120.0}
#: HiGHS options of the relaxed-tail default before the solver model was kept in memory.
HIGHS_OPTIONS_BEFORE = {"mip_heuristic_run_rins": False, "mip_heuristic_run_rens": False,
                        "mip_heuristic_run_root_reduced_cost": False}
#: The default settings before: PuLP hands the model to HiGHS per solve, battery binary kept.
BEFORE = {"solver": "highs_pulp", "relax_battery_binary": False, "highs_options": HIGHS_OPTIONS_BEFORE,
          "threads": 1}
_STEPS_1_4 = {"solver": "highs_pulp", "relax_battery_binary": False, "integer_steps": 24, "threads": 1}

#: label -> (options over config/mpc.yaml, exact problem?); the formulation steps in order, then solvers.
CONFIGS: dict[str, tuple[dict[str, Any], bool]] = {
    "1 paper formulation, HiGHS defaults": (
        {**_STEPS_1_4, "formulation": "paper", "warm_start": False, "highs_options": {}}, True),
    "2 tight big-M / fewer binaries": ({**_STEPS_1_4, "warm_start": False, "highs_options": {}}, True),
    "3 + HiGHS options (RINS, RENS, root red. cost off)": (
        {**_STEPS_1_4, "warm_start": False, "highs_options": HIGHS_OPTIONS_BEFORE}, True),
    "4 + warm start": ({**_STEPS_1_4, "highs_options": HIGHS_OPTIONS_BEFORE}, True),
    "5 + relaxed tail (default before)": (BEFORE, False),
    "6 + HiGHS through highspy (cached arrays)": (
        {"relax_battery_binary": False, "highs_options": HIGHS_OPTIONS_BEFORE, "threads": 1}, False),
    "7 + feasibility jump and restart off": ({"relax_battery_binary": False, "threads": 1}, False),
    "8 + battery binary relaxed (default)": ({}, False),
    "9 + 2 threads": ({"threads": 2}, False),
    "HiGHS full MILP (integer_steps=24)": ({"integer_steps": 24}, True),
    "CBC, full MILP, warm start": ({"solver": "cbc", "integer_steps": 24}, True),
    "CBC, default settings": ({"solver": "cbc"}, False),
    "Gurobi, full MILP, warm start": ({"solver": "gurobi", "integer_steps": 24}, True),
    "Gurobi, default settings": ({"solver": "gurobi"}, False),
}

#: Closed loops run side by side: label -> options over config/mpc.yaml.
LOOP_CONFIGS: dict[str, dict[str, Any]] = {
    "default (HiGHS through highspy)": {},
    "default with 2 threads": {"threads": 2},
    "before (HiGHS through PuLP per solve)": BEFORE,
    "Gurobi, default settings": {"solver": "gurobi"},
    "CBC, default settings": {"solver": "cbc"},
    "HiGHS full MILP (integer_steps=24)": {"integer_steps": 24},
    "Gurobi full MILP (integer_steps=24)": {"solver": "gurobi", "integer_steps": 24},
}

#: KPIs compared between closed loops (summary keys).
KPI_KEYS = (
    "cost_eur_total", "reimbursement_eur_total", "discomfort_kh_total", "buy_kwh_total", "sell_kwh_total",
    "bess_charged_kwh_total", "h2_kwh_total", "fc_working_hours", "fc_toggles",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench mpc``."""
    parser.add_argument("--loop-weeks", metavar="W", type=WEEKS_OR_OFF, default=1.0,
                        help="length of the side-by-side closed loops, scenario of that length: 0 (skip) or one "
                             "hour .. 30 years")
    parser.add_argument("--weeks", metavar="N", type=WEEKS, default=12.0,
                        help="length of the full run [weeks], one hour .. 30 years")
    parser.add_argument("--days-per-kind", metavar="N", type=COUNT, default=1,
                        help="days taken per kind (cold, mild, sunny); 24 problems each (default 1 -> 72)")
    parser.add_argument("--configs", metavar="LIST", default="all",
                        help="problem-set configurations: comma-separated label prefixes, 'all' or 'none'")
    parser.add_argument("--time-limit", metavar="S", type=SECONDS, default=30.0,
                        help="time limit per benchmark solve [s], 0.01 .. a year")
    parser.add_argument("--kpi-weeks", metavar="W", type=WEEKS_OR_OFF, default=0.0,
                        help="also compare KPIs of W weeks at default settings with a gap-0 run: 0 (skip) or one "
                             "hour .. 30 years")
    parser.add_argument("--skip-full-run", action="store_true",
                        help="take the problems from a run of --weeks with the default settings without timing")
    parser.add_argument("--out", metavar="DIR", default=None, help="directory for per-problem results (CSV/JSON)")


def load_text() -> str:
    """``os.getloadavg()`` as ``uptime`` prints it, with the core count."""
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f}, {five:.2f}, {fifteen:.2f} on {os.cpu_count()} cores"


def _cpu_s() -> float:
    """CPU time of the calling thread plus that of waited-for child processes [s]."""
    child = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.thread_time() + child.ru_utime + child.ru_stime


class ClosedLoop:
    """One controller with its own plant, stepped from outside (``step(k)``)."""

    def __init__(self, ctrl: Any, scenario: Any, params: Any) -> None:
        from comems4build_ros.core.loop import ObservationBuilder, exogenous_series, load_forecast_settings
        from comems4build_ros.core.plant import Plant

        self.ctrl, self.scenario, self.params = ctrl, scenario, params
        ctrl.reset()
        self.plant = Plant(params)
        self.exo = exogenous_series(scenario, params)
        self.builder = ObservationBuilder(scenario, params, ctrl.info_level, self.exo, load_forecast_settings())
        self.state = self.plant.initial_state()
        self.rows: list[list[Any]] = []
        self.infos: list[dict[str, float]] = []
        self.ems_s = 0.0
        #: CPU time of each ``act`` call [s]: the calling thread plus finished child processes (CBC)
        self.cpu_s: list[float] = []

    def step(self, k: int) -> None:
        """Step ``k``: observe, act, advance the plant, record."""
        from comems4build_ros.core.loop import record_row

        obs = self.builder.build(k, self.state)
        t0, c0 = time.perf_counter(), _cpu_s()
        action = self.ctrl.act(obs)
        self.cpu_s.append(_cpu_s() - c0)
        self.ems_s += time.perf_counter() - t0
        self.infos.append(dict(self.ctrl.step_info))
        self.state, flows = self.plant.step(self.state, action, self.exo[k])
        sc = self.scenario
        self.rows.append(record_row(sc.time[k].isoformat(), k, flows, self.state, action, self.exo[k],
                                    (sc.ghi_w_m2[k], sc.spot_eur_per_mwh[k]), False))

    def result(self) -> Any:
        """Timeseries with the ``ems_*`` columns, weekly KPIs and summary."""
        import pandas as pd

        from comems4build_ros.core.loop import TIMESERIES_COLUMNS, evaluate_timeseries

        ts = pd.DataFrame(self.rows, columns=list(TIMESERIES_COLUMNS))
        ts = pd.concat([ts, pd.DataFrame(self.infos).add_prefix("ems_")], axis=1)
        return evaluate_timeseries(ts, self.params, {"ems_s": self.ems_s})


def _closed_loop(ctrl: Any, scenario: Any, params: Any, n_steps: int, progress: ProgressCallback | None = None) -> Any:
    """First ``n_steps`` steps of the closed loop (daily H2 allowance of the whole scenario)."""
    loop = ClosedLoop(ctrl, scenario, params)
    for k in range(n_steps):
        loop.step(k)
        if progress is not None:
            progress(k + 1, n_steps)
    return loop.result()


def side_by_side(params: Any, scenario: Any, configs: Mapping[str, Mapping[str, Any]], n_steps: int,
                 solvers: Sequence[str], progress: ProgressCallback | None = None) -> pd.DataFrame:
    """Closed loops of ``configs`` stepped in turn; one row per configuration (solve times and KPIs)."""
    import numpy as np
    import pandas as pd

    from comems4build_ros.core.ems.mpc import MPCController

    loops: dict[str, ClosedLoop] = {}
    rows: dict[str, dict[str, Any]] = {}
    for label, opts in configs.items():
        if opts.get("solver", "highs") not in solvers:
            rows[label] = {"configuration": label, "note": "not installed"}
        else:
            loops[label] = ClosedLoop(MPCController(params, {**opts, "log_fallback": False}), scenario, params)
    for k in range(n_steps):
        for loop in loops.values():
            loop.step(k)
        if progress is not None:
            progress(k + 1, n_steps)
    for label, loop in loops.items():
        res = loop.result()
        ts = res.timeseries
        st = ts["ems_solve_s"]
        rows[label] = {"configuration": label, "median_ms": st.median() * 1e3, "p95_ms": st.quantile(0.95) * 1e3,
                       "mean_ms": st.mean() * 1e3, "max_ms": st.max() * 1e3,
                       "cpu_median_ms": float(np.median(loop.cpu_s)) * 1e3,
                       "fallback": int(ts["ems_fallback"].sum()), "slack_steps": int(ts["ems_slack_used"].sum()),
                       "objective_sum_eur": float(ts["ems_objective_eur"].sum()),
                       **{key: float(res.summary[key]) for key in KPI_KEYS}}
    return pd.DataFrame([rows[label] for label in configs])


def select_days(scenario: Any, n_steps: int, per_kind: int) -> dict[str, list[int]]:
    """First steps of whole days: coldest (daily mean T_amb), mildest, sunniest (daily GHI sum).

    Day 0 is skipped (the start state is arbitrary); days are distinct across kinds.
    """
    import numpy as np

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
    from comems4build_ros.core.loop import ObservationBuilder, exogenous_series
    from comems4build_ros.core.types import PlantState

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
    from comems4build_ros.core.ems.mpc import MPCController

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
    from comems4build_ros.core.ems.mpc import MPCController

    ctrl = MPCController(params, {**REFERENCE, "time_limit_s": time_limit, "mip_rel_gap": 1e-4,
                                  "relax_battery_binary": False, "log_fallback": False})
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


def _pick_configs(spec: str) -> dict[str, tuple[dict[str, Any], bool]]:
    """``--configs``: ``all``, ``none`` or label prefixes, each matching at least one configuration."""
    from comems4build_ros.app.cli import UsageError

    if spec == "none":
        return {}
    if spec == "all":
        return dict(CONFIGS)
    prefixes = [p.strip() for p in spec.split(",") if p.strip()]
    unmatched = [p for p in prefixes if not any(label.startswith(p) for label in CONFIGS)]
    if unmatched or not prefixes:
        raise UsageError(f"--configs {spec}: {', '.join(unmatched) or 'no prefix'} matches no configuration "
                         f"(labels: {', '.join(CONFIGS)}; or 'all', 'none')")
    return {label: cfg for label, cfg in CONFIGS.items() if any(label.startswith(p) for p in prefixes)}


def _print_table(table: pd.DataFrame, digits: int = 2) -> None:
    print(table.to_string(index=False, na_rep="", float_format=lambda x: f"{x:.{digits}f}"))


def run(args: argparse.Namespace) -> int:
    """The benchmark, its ``--out`` (if given) through the output layer: checked, locked, all or nothing."""
    from comems4build_ros.app.commands.options import bench_output

    with bench_output(args, "bench mpc"):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the benchmark's stages and print their tables: closed loops side by side, a full run, the
    solver configurations on fixed problems, the KPIs of the default settings against the exact MILP."""
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.ems.mpc.solvers import available_solvers
    from comems4build_ros.core.ems.settings import MILPSettings, load_settings
    from comems4build_ros.core.scenario import default_scenario
    from comems4build_ros.files.outputs import check_out_dir

    configs = _pick_configs(args.configs)  # checked before anything runs
    if args.out:
        check_out_dir(args.out)
    params = load_plant_params()
    defaults = load_settings(MILPSettings)
    print(f"bench mpc: default settings {defaults.model_dump()}")
    solvers = available_solvers()
    print(f"solvers available: {', '.join(solvers)}" + ("" if "gurobi" in solvers else " (gurobipy not installed)"))
    print(f"start: {load_text()}", flush=True)
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    if args.loop_weeks > 0:
        _side_by_side_stage(args, params, solvers, out)
    scenario = default_scenario(params, weeks=int(math.ceil(args.weeks)))
    ts, wall = _full_run_stage(args, params, scenario, defaults.solver, bool(configs))
    if configs:
        _fixed_problems_stage(args, params, scenario, ts, configs, solvers, out)
    if args.kpi_weeks > 0:
        _kpi_stage(args, params, scenario, out)
    if out:
        (out / "bench_mpc_run.json").write_text(json.dumps({"wall_s": wall, "steps": int(scenario.n_steps)}) + "\n")
    print(f"\nend: {load_text()}")
    return 0


def _side_by_side_stage(args: argparse.Namespace, params: Any, solvers: Sequence[str], out: Path | None) -> None:
    """Closed loops of :data:`LOOP_CONFIGS` stepped in turn over ``--loop-weeks``: solve times and KPIs."""
    from comems4build_ros.core.scenario import default_scenario

    loop_scenario = default_scenario(params, weeks=int(math.ceil(args.loop_weeks)))
    n = min(int(round(args.loop_weeks * 168)), loop_scenario.n_steps)
    t = time.perf_counter()
    with ProgressBar("closed loops side by side", unit="step") as bar:
        loops = side_by_side(params, loop_scenario, LOOP_CONFIGS, n, solvers, bar)
    print(f"\nclosed loops side by side: {n} steps of the default scenario of {math.ceil(args.loop_weeks)} "
          f"week(s), stepped in turn ({time.perf_counter() - t:.0f} s; {load_text()}):")
    _print_table(loops[["configuration", "median_ms", "p95_ms", "mean_ms", "max_ms", "cpu_median_ms", "fallback",
                        "slack_steps"]
                       + (["note"] if "note" in loops else [])], 1)
    print("\nKPIs of these closed loops (totals over the run):")
    _print_table(loops[["configuration", *KPI_KEYS, "objective_sum_eur"]], 3)
    if out:
        loops.to_csv(out / "bench_mpc_loops.csv", index=False)


def _full_run_stage(args: argparse.Namespace, params: Any, scenario: Any, solver: str,
                    need_timeseries: bool) -> tuple[pd.DataFrame | None, float]:
    """The MPC over ``--weeks``, default settings (its timeseries give the fixed problems): timeseries, wall [s]."""
    from comems4build_ros.core.loop import simulate

    if args.skip_full_run and not need_timeseries:
        return None, math.nan
    t0 = time.perf_counter()
    with ProgressBar("full run", unit="step") as bar:
        result = simulate("mpc", scenario, params, progress=bar)
    wall = time.perf_counter() - t0
    ts = result.timeseries
    if not args.skip_full_run:
        print(f"\nfull run: {scenario.n_steps} steps ({scenario.n_steps / 168:.1f} weeks) with {solver}: "
              f"wall {wall:.1f} s (EMS {result.summary.get('ems_s', math.nan):.1f} s), solve median "
              f"{ts['ems_solve_s'].median() * 1e3:.1f} ms, p95 {ts['ems_solve_s'].quantile(0.95) * 1e3:.1f} ms, "
              f"fallbacks {int(ts['ems_fallback'].sum())}, steps with slack {int(ts['ems_slack_used'].sum())} "
              f"({load_text()})", flush=True)
    return ts, wall


def _fixed_problems_stage(args: argparse.Namespace, params: Any, scenario: Any, ts: pd.DataFrame,
                          configs: dict[str, Any], solvers: Sequence[str], out: Path | None) -> None:
    """Every configuration on the same horizon problems: solve time and gap to the best known objective."""
    import numpy as np
    import pandas as pd

    starts = select_days(scenario, scenario.n_steps, args.days_per_kind)
    problems = problems_from_run(ts, scenario, params, starts)
    print(f"\nproblem set: {len(problems)} horizon problems, days starting at steps "
          + ", ".join(f"{kind} {v}" for kind, v in starts.items()))
    results: dict[str, list[dict[str, Any]]] = {}
    ref_label = "reference: tight, gap 0"
    with ProgressBar(ref_label, unit="solve") as bar:
        results[ref_label] = solve_set(params, {**REFERENCE, "time_limit_s": max(args.time_limit, 60.0)}, problems, bar)
    missing = []
    for label, (opts, _) in configs.items():
        if opts.get("solver", "highs") not in solvers:
            missing.append(label)
            continue
        t = time.perf_counter()
        with ProgressBar(label, unit="solve") as bar:
            results[label] = solve_set(params, {"time_limit_s": args.time_limit, **opts}, problems, bar)
        print(f"  solved with '{label}' in {time.perf_counter() - t:.1f} s", flush=True)
    exact_labels = [ref_label] + [lb for lb, (_, ex) in configs.items() if ex and lb in results]
    best = np.nanmin(np.array([[r["objective"] for r in results[lb]] for lb in exact_labels]), axis=0)
    rows = []
    for label, res in results.items():
        if label in exact_labels:
            obj = np.array([r["objective"] for r in res])
        else:
            obj = np.array(exact_with_first_fixed(params, problems, [r["first"] for r in res], args.time_limit))
        gap = (obj - best) / np.maximum(np.abs(best), 1e-9)
        st = np.array([r["solve_s"] for r in res])
        rows.append({"configuration": label, "median_ms": np.median(st) * 1e3,
                     "p95_ms": np.quantile(st, 0.95) * 1e3, "mean_gap_pct": np.nanmean(gap) * 100,
                     "max_gap_pct": np.nanmax(gap) * 100, "no_solution": int(np.sum(~np.isfinite(obj)))})
    rows += [{"configuration": label, "note": "not installed"} for label in missing]
    table = pd.DataFrame(rows)
    print("\nsolve time and objective gap to the best known solution "
          f"({len(problems)} problems; gap of relaxed-tail rows = exact problem with first step fixed; "
          f"{load_text()}):")
    _print_table(table)
    if out:
        table.to_csv(out / "bench_mpc.csv", index=False)
        per = [{"configuration": label, **{k: v for k, v in r.items() if k != "first"}}
               for label, res in results.items() for r in res]
        pd.DataFrame(per).to_csv(out / "bench_mpc_problems.csv", index=False)


def _kpi_stage(args: argparse.Namespace, params: Any, scenario: Any, out: Path | None) -> None:
    """KPIs over ``--kpi-weeks``: the default settings against the exact MILP at gap 0."""
    import pandas as pd

    from comems4build_ros.core.ems.mpc import MPCController

    n = int(round(args.kpi_weeks * 168))
    with ProgressBar("default settings", unit="step") as bar:
        chosen = _closed_loop(MPCController(params, {}), scenario, params, n, bar)
    with ProgressBar("exact, gap 0", unit="step") as bar:
        exact = _closed_loop(MPCController(params, {**REFERENCE, "time_limit_s": 300.0}), scenario, params, n, bar)
    kpi_rows = []
    for key in KPI_KEYS:
        a, b = float(chosen.summary[key]), float(exact.summary[key])
        kpi_rows.append({"kpi": key, "default": a, "gap0_exact": b,
                         "diff_pct": (a - b) / abs(b) * 100 if abs(b) > 1e-9 else math.nan})
    kpi_table = pd.DataFrame(kpi_rows)
    print(f"\nKPIs over the first {args.kpi_weeks:g} weeks: default settings vs exact MILP at gap 0 "
          f"(solve median {chosen.timeseries['ems_solve_s'].median() * 1e3:.0f} ms vs "
          f"{exact.timeseries['ems_solve_s'].median() * 1e3:.0f} ms):")
    _print_table(kpi_table, 3)
    if out:
        kpi_table.to_csv(out / "bench_mpc_kpi.csv", index=False)
