"""The optimising coordinators on the same community horizon problems: central MILP against distributed ADMM.

``comems4build bench coordinators`` runs a community (``--community``; ``--houses N`` takes
its first N houses, or, beyond the file's, its houses again as further households: another
realisation of the load model and the hot-water draws a week later per copy) in closed loop
under the rule-based coordinator (every house ComEMS4Build) over ``--hours`` of the
scenario, and at every ``--every``-th step solves the community's horizon problem of that
step (``core/community/optimal.py``) on the same view: the central MILP, its LP relaxation,
the distributed ADMM (which runs every step, warm-started from the step before, as in closed
loop; its fixed point is the relaxation's optimum) and the distributed integer plan
(:meth:`~comems4build_ros.core.community.admm.DistributedCoordinator.recover`: each house's
MILP at the converged prices fixes its binaries, then the ADMM again). It prints per decision
the objectives [EUR], the gaps ``(distributed - central) / |central|`` of the integer plan
against the MILP and of the ADMM against the relaxation, the ADMM's iterations and residual,
and the times per decision; then their means. Above the central
coordinator's ``max_houses`` the central problem is refused (printed) and only the
distributed one runs, unless ``--central-max N`` raises the limit for a measurement.

The figures depend on the machine's load: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time
from pathlib import Path
from typing import Any

#: The gap the distributed coordinator must stay within on 8 houses [-].
TARGET_GAP = 0.01


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench coordinators``."""
    parser.add_argument("--community", metavar="FILE", default="config/community/default.yaml",
                        help="the community file (default config/community/default.yaml)")
    parser.add_argument("--houses", metavar="N", type=int, default=8,
                        help="houses: the file's first N, or its houses again beyond them (default 8)")
    parser.add_argument("--scenario", default="default", help="scenario (default: the paper's winter)")
    parser.add_argument("--start", metavar="ISO", default=None, help="start of the window (default: the scenario's)")
    parser.add_argument("--hours", metavar="H", type=int, default=24, help="closed-loop hours (default 24)")
    parser.add_argument("--every", metavar="K", type=int, default=3,
                        help="solve centrally at every K-th step (default 3)")
    parser.add_argument("--no-central", action="store_true", help="the distributed coordinator only")
    parser.add_argument("--central-max", metavar="N", type=int, default=None,
                        help="raise the central coordinator's max_houses for this measurement")
    parser.add_argument("--option", action="append", default=[], metavar="NAME.KEY=VALUE",
                        help="an option of central or distributed (repeatable), e.g. distributed.rho_eur_per_kw2=0.5")
    parser.add_argument("--out", metavar="FILE.json", default=None, help="write the figures as JSON")


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} cores"


def community_of(path: str, houses: int) -> Any:
    """The community file's spec with ``houses`` houses (module docstring)."""
    from comems4build_ros.core.community.spec import load_community

    spec = load_community(path)
    base = list(spec.houses)
    out = []
    for i in range(houses):
        h = base[i % len(base)]
        copy = i // len(base)
        if copy:
            seed = (h.load_seed if h.load_seed is not None else 100) + 10_000 * copy
            h = h.model_copy(update={"name": f"{h.name}_{copy}", "load_seed": seed,
                                     "dhw_shift_days": h.dhw_shift_days + 7 * copy,
                                     "reason": f"{h.reason}; another household of the same kind"})
        out.append(h)
    return spec.model_copy(update={"houses": out})


def run(args: argparse.Namespace) -> int:
    """Run the benchmark; print and optionally write the figures."""
    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.core.community.coordinator import make_coordinator
    from comems4build_ros.core.community.hubrun import community_info
    from comems4build_ros.core.community.loop import simulate_community
    from comems4build_ros.core.community.plant import CommunityPlant
    from comems4build_ros.core.community.spec import build_community
    from comems4build_ros.core.config import ConfigError, parse_assignments

    if args.houses < 1 or args.hours < 1 or args.every < 1:
        raise UsageError("--houses, --hours and --every must be >= 1")
    options: dict[str, dict[str, Any]] = {"central": {}, "distributed": {}}
    for key, value in parse_assignments(args.option, "--option").items():
        name, _, opt = key.partition(".")
        if name not in options or not opt:
            raise UsageError(f"--option {key}: give central.KEY=VALUE or distributed.KEY=VALUE")
        options[name][opt] = value
    if args.central_max is not None:
        options["central"]["max_houses"] = args.central_max
    spec = community_of(args.community, args.houses)
    community = build_community(spec, args.scenario, source=args.community, start=args.start, hours=args.hours)
    info = community_info(community, CommunityPlant(community).hub)
    print(f"bench coordinators: {args.houses} houses, {args.scenario}, {args.hours} h, central every {args.every} "
          f"steps; {_load()}", flush=True)
    t_build = time.perf_counter()
    distributed = make_coordinator("distributed", info, options["distributed"])
    central = relaxed = None
    refused = ""
    if not args.no_central:
        try:
            central = make_coordinator("central", info, options["central"])
            relaxed = make_coordinator("central", info, {**options["central"], "relaxed": True})
        except ConfigError as exc:
            refused = str(exc)
            print(f"central: refused: {refused}", flush=True)
    print(f"coordinators built in {time.perf_counter() - t_build:.1f} s", flush=True)
    rows: list[dict[str, Any]] = []
    dist_steps: list[dict[str, float]] = []

    class Probe:
        """The rule coordinator's decisions; the optimising coordinators solve the same views."""

        name = "rule"
        info_level = "mpc"

        def __init__(self) -> None:
            self.rule = make_coordinator("rule", info)
            self.step_info: dict[str, float] = {}

        def reset(self) -> None:
            self.rule.reset()
            distributed.reset()
            for c in (central, relaxed):
                if c is not None:
                    c.reset()

        def allot(self, view: Any) -> Any:
            d = distributed.solve(view)
            dist_steps.append({"iterations": d["iterations"], "solve_s": d["solve_s"],
                               "residual_kw": d["residual_kw"], "converged": d["converged"]})
            if central is not None and view.step % args.every == 0:
                c = central.solve(view)
                r = relaxed.solve(view)
                m = distributed.recover(view)
                row = {"step": view.step, "time": view.time, "central_eur": c["objective"],
                       "central_gap": c["gap"], "central_s": c["solve_s"], "relaxed_eur": r["objective"],
                       "relaxed_s": r["solve_s"], "distributed_eur": d["objective"],
                       "iterations": d["iterations"], "residual_kw": d["residual_kw"], "distributed_s": d["solve_s"],
                       "integer_eur": m["objective"], "integer_iterations": m["iterations"],
                       "integer_residual_kw": m["residual_kw"], "integer_s": m["solve_s"]}
                row["gap"] = (row["integer_eur"] - row["central_eur"]) / abs(row["central_eur"])
                row["gap_relaxed"] = (row["distributed_eur"] - row["relaxed_eur"]) / abs(row["relaxed_eur"])
                rows.append(row)
                print(f"step {view.step:4d} {view.time[:16]}: central MILP {c['objective']:9.3f} EUR "
                      f"({c['solve_s']:6.2f} s, MIP gap {c['gap']:.2%}), its relaxation {r['objective']:9.3f}; "
                      f"distributed {d['objective']:9.3f} ({d['iterations']:3d} it., residual "
                      f"{d['residual_kw']:.3f} kW, {d['solve_s']:6.2f} s), {row['gap_relaxed']:+.3%} to the "
                      f"relaxation; "
                      f"its integer plan {m['objective']:9.3f} ({m['iterations']:3d} it., {m['solve_s']:6.2f} s), "
                      f"{row['gap']:+.3%} to the MILP", flush=True)
            elif central is None:
                print(f"step {view.step:4d} {view.time[:16]}: distributed {d['objective']:9.3f} EUR "
                      f"({d['iterations']:3d} it., residual {d['residual_kw']:.3f} kW, {d['solve_s']:6.2f} s)",
                      flush=True)
            return self.rule.allot(view)

        def dispatch(self, view: Any, requests: Any) -> Any:
            return self.rule.dispatch(view, requests)

    t0 = time.perf_counter()
    simulate_community(community, Probe(), "fuzzy")
    wall = time.perf_counter() - t0
    its = [s["iterations"] for s in dist_steps]
    secs = [s["solve_s"] for s in dist_steps]
    result: dict[str, Any] = {
        "houses": args.houses, "scenario": args.scenario, "hours": args.hours, "wall_s": wall,
        "central_refused": refused, "decisions": rows,
        "distributed": {"decisions": len(dist_steps), "iterations_mean": statistics.fmean(its),
                        "iterations_max": max(its), "s_per_decision_mean": statistics.fmean(secs),
                        "s_per_decision_max": max(secs),
                        "converged_share": sum(s["converged"] for s in dist_steps) / len(dist_steps),
                        "s_per_iteration_per_agent": sum(secs) / sum(its) / (args.houses + 1)},
    }
    print(f"distributed: {len(dist_steps)} decisions, iterations mean {result['distributed']['iterations_mean']:.1f} "
          f"(max {max(its)}), {result['distributed']['s_per_decision_mean']:.2f} s per decision (max {max(secs):.2f}), "
          f"{result['distributed']['s_per_iteration_per_agent'] * 1e3:.1f} ms per agent and iteration, converged "
          f"{result['distributed']['converged_share']:.0%}")
    if rows:
        gaps = [r["gap"] for r in rows]
        cost_c = sum(r["central_eur"] for r in rows)
        cost_d = sum(r["integer_eur"] for r in rows)
        result["central"] = {"s_per_decision_mean": statistics.fmean(r["central_s"] for r in rows),
                             "s_per_decision_max": max(r["central_s"] for r in rows),
                             "gap_mean": statistics.fmean(gaps), "gap_abs_max": max(abs(g) for g in gaps),
                             "gap_of_sums": (cost_d - cost_c) / abs(cost_c) if cost_c else math.nan,
                             "relaxed_gap_abs_max": max(abs(r["gap_relaxed"]) for r in rows)}
        c = result["central"]
        ok = c["gap_abs_max"] <= TARGET_GAP
        print(f"central: {len(rows)} decisions, {c['s_per_decision_mean']:.2f} s per decision (max "
              f"{c['s_per_decision_max']:.2f}); the distributed integer plan - the central MILP: mean "
              f"{c['gap_mean']:+.3%}, largest |gap| {c['gap_abs_max']:.3%} ({'meets' if ok else 'MISSES'} the "
              f"{TARGET_GAP:.0%} target), over the decisions' sum {c['gap_of_sums']:+.3%}; the distributed "
              f"relaxed optimum - the central relaxation: largest |gap| {c['relaxed_gap_abs_max']:.3%}")
    print(f"wall {wall:.1f} s; {_load()}")
    if args.out:
        Path(args.out).write_text(json.dumps(result, indent=2, default=float) + "\n", encoding="utf-8")
    return 0
