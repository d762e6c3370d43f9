"""``comems4build sweep``: a grid of plant-parameter variations, one table and one plot per KPI."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from comems4build_ros.app.commands import options as opt
from comems4build_ros.files.errors import InputError

#: What ``sweep`` writes into its output directory.
SWEEP_FILES = ("runs", "figures", "sweep.csv", "sweep.md", "sweep.json")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``sweep``."""
    parser.add_argument("--param", action="append", required=True, metavar="PATH=V1,V2,...",
                        help="dotted plant parameter and its values, e.g. battery.e_max_kwh=5,6.5,10 (repeatable; "
                             "the grid is the product of all)")
    parser.add_argument("--ems", metavar="NAME[,NAME...]", required=True, help=opt.ems_help(many=True))
    opt.add_scenario_options(parser, hours=False)
    opt.add_study_options(parser)
    parser.add_argument("--timeseries", action="store_true", help="also write each run's timeseries.csv")
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")


def run(args: argparse.Namespace) -> int:
    """Run every case of the grid and write sweep.csv, sweep.md, figures/<kpi>.{png,pdf,svg} and runs/."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.report.sweep import sweep_kpis
    from comems4build_ros.study.sweep import grid, parse_param

    params: dict[str, list] = {}
    for text in args.param:
        try:
            path, values = parse_param(text)
        except InputError as exc:
            raise UsageError(str(exc)) from None
        if path in params:
            raise UsageError(f"--param {path} given twice")
        params[path] = values
    emss = opt.study_inputs(args)
    cases = grid(params, emss)
    for case in cases[: len(cases) // len(emss)]:  # check every parameter set before running
        plant = load_plant_params(args.config, case.values)
    opt.scenario_of(args, plant)  # the scenario and the run length, checked once before any run
    output = opt.output_dir(args, "sweep", writes=SWEEP_FILES, replaces=SWEEP_FILES)
    output.check()
    with output, opt.study_pool(args, args.out) as pool:  # finished runs kept in OUT/.runstore until the end
        wall = _sweep(args, params, emss, cases, output.stage)
        output.commit()  # runs/, tables and figures replace an older sweep's when all are written
        pool.complete()
    out = Path(args.out)
    print(f"{len(cases)} runs in {wall:.1f} s; wrote {out / 'sweep.csv'}, {out / 'sweep.md'} and "
          f"{len(sweep_kpis(args.scenario))} plots in {out / 'figures'}")
    return 0


def _sweep(args: argparse.Namespace, params: dict[str, list], emss: list[str], cases: list, out: Path) -> float:
    """Run every case of the grid into ``out/runs/``, write the tables and plots into ``out``; the wall time [s]."""
    from comems4build_ros.app.commands.compare import building_task_options
    from comems4build_ros.report.sweep import markdown_table, plot_kpi, sweep_kpis, table
    from comems4build_ros.study.runner import RunTask, run_tasks

    tasks = [RunTask(ems=c.ems, out_dir=str(out / "runs" / c.name), scenario=args.scenario, start=args.start,
                     weeks=args.weeks, seed=args.seed, extend=args.extend, overrides=dict(c.values),
                     config=[str(Path(p).resolve()) for p in args.config],
                     timeseries=args.timeseries, **building_task_options(c.ems, args)) for c in cases]
    print(f"sweep: {len(cases)} runs ({len(emss)} EMS x {len(cases) // len(emss)} parameter sets)", file=sys.stderr)
    t0 = time.perf_counter()
    summaries = run_tasks(tasks, progress=False if args.no_progress else None)
    wall = time.perf_counter() - t0
    kpis = [k for k, _ in sweep_kpis(args.scenario)]
    df = table(cases, summaries, kpis)
    df.to_csv(out / "sweep.csv", index=False)
    md = [f"# Sweep over {', '.join(params)}", "",
          f"EMS: {', '.join(emss)}; scenario {args.scenario}, weeks {args.weeks or 'default'}; "
          f"{len(cases)} runs in {wall:.1f} s wall.", "", markdown_table(df), "## Figures", ""]
    for key, ylabel in sweep_kpis(args.scenario):
        png = plot_kpi(df, list(params), key, ylabel, out / "figures" / key)
        md.append(f"![{key} over {next(iter(params))}](figures/{png.name})\n\n`{key}` over "
                  f"`{next(iter(params))}`; vector versions: [PDF](figures/{key}.pdf), [SVG](figures/{key}.svg)\n")
    (out / "sweep.md").write_text("\n".join(md), encoding="utf-8")
    (out / "sweep.json").write_text(json.dumps({"params": params, "ems": emss, "scenario": args.scenario,
                                                "weeks": args.weeks, "wall_s": wall}, indent=2) + "\n",
                                    encoding="utf-8")
    return wall
