"""``comems4build launch``: the ROS 2 node set as separate processes, evaluated from the bag."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``launch``."""
    parser.add_argument("--ems", required=True, help="EMS node: fuzzy, rbc, mpc (also thermostat, mpc-qp)")
    parser.add_argument("--scenario", default="default", help="'default' (embedded) or a scenario CSV file")
    parser.add_argument("--start", default=None, help="first step of the window (ISO date/time)")
    parser.add_argument("--weeks", type=float, default=None, help="run length in weeks (default: 12 / whole CSV)")
    parser.add_argument("--steps", type=int, default=None, help="cut the run to its first N steps (short runs)")
    parser.add_argument("--buildings", type=int, default=1,
                        help="independent buildings under /building_<i>/, scenario seed + i (default 1)")
    parser.add_argument("--seed", type=int, default=None, help="scenario seed of building 0 (default scenario)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="parameter file merged over config/plant.yaml (repeatable)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter, e.g. --set battery.e_max_kwh=10 (repeatable)")
    parser.add_argument("--ems-option", action="append", default=[], metavar="KEY=VALUE",
                        help="option passed to the EMS (repeatable)")
    parser.add_argument("--forecast", choices=("perfect", "imperfect"), default=None,
                        help="forecasts given to the MPC (default: config/forecast.yaml)")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID of the run (default: a free id, locked for the run)")
    parser.add_argument("--step-timeout", type=float, default=None,
                        help="plant_sim's wait for a command before its safe fallback [s]")
    parser.add_argument("--timeout", type=float, default=None, help="give up after this wall time [s]")
    parser.add_argument("--out", required=True, help="output directory (bag/, log/, weekly.csv, summary.json)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--print-plan", action="store_true",
                        help="print the run plan (processes, nodes, parameters) and exit without starting anything")


def run(args: argparse.Namespace) -> int:
    """Launch, wait, evaluate; print the main figures."""
    from ..cli import UsageError
    from ..ems import UnknownEMSError, controller_class
    from ..ros.launcher import LaunchError, LaunchOptions, launch
    from .simulate import parse_assignments

    try:
        controller_class(args.ems)
    except UnknownEMSError as exc:
        raise UsageError(str(exc)) from None
    for path in args.config:
        if not Path(path).is_file():
            raise UsageError(f"--config {path}: no such file")
    if args.buildings < 1:
        raise UsageError(f"--buildings must be >= 1, got {args.buildings}")
    if args.steps is not None and args.steps < 1:
        raise UsageError(f"--steps must be >= 1, got {args.steps}")
    if args.scenario != "default" and not Path(args.scenario).is_file():
        raise UsageError(f"--scenario {args.scenario}: no such file (use 'default' or a scenario CSV)")
    opts = LaunchOptions(
        ems=args.ems,
        out=Path(args.out),
        scenario=args.scenario,
        weeks=args.weeks,
        steps=args.steps,
        start=args.start,
        buildings=args.buildings,
        seed=args.seed,
        config_files=list(args.config),
        overrides=parse_assignments(args.set, "--set"),
        ems_options=list(args.ems_option),
        forecast=args.forecast,
        domain_id=args.domain_id,
        timeout_s=args.timeout,
        progress=not args.no_progress and sys.stderr.isatty(),
        plant_params={} if args.step_timeout is None else {"step_timeout_s": float(args.step_timeout)},
    )
    if args.print_plan:
        from ..ros.plan import plan_run

        print(plan_run(opts, args.domain_id if args.domain_id is not None else 0).describe())
        return 0
    try:
        result = launch(opts)
    except LaunchError as exc:
        print(f"comems4build launch: {exc}", file=sys.stderr)
        return 1
    keys = ("weeks", "cost_eur_week_median", "discomfort_kh_week_median", "discomfort_weeks_nonzero",
            "buy_kwh_week_median", "sell_kwh_week_median", "loh_end", "fallback_steps")
    for ns, s in result.summaries.items():
        print(json.dumps({"building": ns, **{k: s.get(k) for k in keys}}))
    print(f"ROS domain {result.domain_id}: {len(result.summaries)} building(s), wall {result.wall_s:.1f} s "
          f"(run {result.run_s:.1f} s after the first record)")
    print(f"wrote {result.bag}, {result.out / 'weekly.csv'}, {result.out / 'summary.json'}")
    return 0
