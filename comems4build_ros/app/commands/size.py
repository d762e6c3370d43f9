"""``comems4build size``: a sizing study of the H2 house over the year (docs/sizing.md)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import (
    COUNT,
    SEED,
    WEEKS,
    add_study_options,
    ems_help,
    parse_values,
)
from comems4build_ros.files.errors import InputError

#: What ``size`` writes into its output directory.
SIZE_FILES = ("runs", "figures", "size.csv", "size.md", "size.json", "report.md", "report.html")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``size``."""
    from comems4build_ros.app.commands import size_community
    from comems4build_ros.study.sizing import AXES

    parser.add_argument("--ems", metavar="NAME[,NAME...]", default=None,
                        help=ems_help(many=True) + " (required; with --community the one EMS of every house)")
    for axis in AXES:
        parser.add_argument(axis.option, metavar="V1,V2,...", default=None,
                            help=f"{axis.label} [{axis.unit}], {'integers >= 0' if axis.integer else 'values > 0'} "
                                 "(default: the year plant's size)")
    parser.add_argument("--sample", metavar="N", type=COUNT, default=None,
                        help="instead of the grid of all combinations: N points of a Latin hypercube between the "
                             "smallest and largest value of each size option")
    parser.add_argument("--design-seed", metavar="N", type=SEED, default=0,
                        help="seed of --sample's design (default 0)")
    parser.add_argument("--costs", action="append", default=[], metavar="FILE",
                        help="cost file merged over config/costs.yaml (repeatable; the keys it gives replace)")
    parser.add_argument("--start", metavar="ISO", default=None,
                        help="first step inside the year (ISO date/time; naive = site time; default 2022-03-01)")
    parser.add_argument("--weeks", type=WEEKS, default=None, metavar="N",
                        help="run length in weeks, one hour .. 30 years (default: the year's 52; shorter runs are "
                             "checks: their annual figures are scaled to 52 weeks)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter for every run (not one of the sized ones)")
    add_study_options(parser, "config/plant.yaml and config/year.yaml")
    size_community.add_arguments(parser)
    parser.add_argument("--out", metavar="DIR", default=None, help="output directory (required unless --from-runs)")


def run(args: argparse.Namespace) -> int:
    """Run every size point for every EMS over the year; write size.csv, size.md, figures/, report.*."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands import size_community
    from comems4build_ros.app.commands.options import (
        check_config_files,
        output_dir,
        scenario_of,
        study_inputs,
        study_pool,
    )
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.economics import load_costs

    if args.from_runs is not None:
        return size_community.rebuild(args)
    if args.community is not None:
        return size_community.run(args)
    size_community.refuse_without_community(args)
    if args.ems is None or args.out is None:
        raise UsageError(f"{'--ems' if args.ems is None else '--out'} is required (unless --from-runs)")
    args.scenario = "year"
    emss = study_inputs(args)
    check_config_files(args.costs, "--costs")
    costs = load_costs(args.costs)
    overrides = parse_assignments(args.set, "--set")
    base = load_plant_params(args.config, overrides)
    sized, values, design = _size_points(args, base, overrides, emss)
    try:
        scenario_of(args, base)  # the window inside the year, checked once before any run
    except UsageError:
        raise
    except InputError as exc:
        raise UsageError(f"--start/--weeks: {exc}") from None
    output = output_dir(args, "size", writes=SIZE_FILES, replaces=SIZE_FILES)
    output.check()
    meta: dict[str, Any] = {"ems": emss, "design": design, "points": len(sized), "start": args.start,
                            "weeks": args.weeks or 52, "values": values, "set": overrides,
                            "costs": [str(Path(c).resolve()) for c in args.costs],
                            "workers": args.scheduler or f"local processes (--jobs {args.jobs or 'CPU count'})"}
    print(f"size: {len(sized) * len(emss)} runs ({len(emss)} EMS x {len(sized)} size points, {design})",
          file=sys.stderr)
    with output, study_pool(args, args.out) as pool:  # finished runs kept in OUT/.runstore until the end
        df = _size(args, emss, sized, costs, meta, output.stage)
        output.commit()  # runs/, tables, figures and report replace an older study's when all are written
        pool.complete()
    out = Path(args.out)
    for ems, sub in df.groupby("ems", sort=False):
        ok = sub[sub["closes"] == True]  # noqa: E712
        names = ", ".join(Path(r).name for r in ok["run"]) or "none"
        print(f"{ems}: {len(ok)} of {len(sub)} size points close the seasonal cycle: {names}")
    print(f"{len(df)} runs in {meta['wall_s']:.1f} s; wrote {out / 'size.csv'}, {out / 'size.md'}, "
          f"{out / 'figures' / 'pareto.png'}, {out / 'report.md'} and {out / 'report.html'}")
    return 0



def _size_points(args: argparse.Namespace, base: Any, overrides: dict[str, Any], emss: list[str]
                 ) -> tuple[list[tuple[dict[str, float], dict[str, Any], Any]], dict[str, list[float]], str]:
    """Every size point of the design, each plant and each EMS on it built and checked before any run.

    Returns the points as (realised sizes, plant overrides, plant parameters), the values
    of each axis and the design's description.
    """
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import ems_controller
    from comems4build_ros.core.config import ConfigError, load_plant_params
    from comems4build_ros.study.sizing import AXES, grid_points, plant_sizes, point_name, sampled_points, size_overrides

    default = plant_sizes(base)
    values: dict[str, list[float]] = {}
    for axis in AXES:
        text = getattr(args, axis.option[2:].replace("-", "_"))
        values[axis.key] = parse_values(text, axis.option, axis.integer) if text is not None else [default[axis.key]]
    if args.sample is not None:
        try:
            points = sampled_points(values, args.sample, args.design_seed)
        except InputError as exc:
            raise UsageError(str(exc)) from None
        design = f"Latin hypercube, {args.sample} samples, seed {args.design_seed}"
    else:
        points = grid_points(values)
        design = "grid " + " x ".join(str(len(values[a.key])) for a in AXES)
    sized = []
    sized_keys = set()
    for p in points:
        try:
            ov, realised = size_overrides(p, base)
        except InputError as exc:
            raise UsageError(str(exc)) from None
        clash = sorted(set(ov) & set(overrides))
        if clash:
            raise UsageError(f"--set {clash[0]}: a sized parameter; give the size option instead")
        key = tuple(realised[a.key] for a in AXES)
        if key in sized_keys:
            continue  # two requested sizes realised alike (PV rounded to whole modules)
        sized_keys.add(key)
        try:
            plant = load_plant_params(args.config, {**overrides, **ov})  # every point's plant checked before any run
            for ems in emss:  # and every EMS built on it, as its run will build it
                ems_controller(ems, plant, [])
        except (ConfigError, UsageError) as exc:
            raise UsageError(f"size point {point_name('', realised).lstrip('_')}: {exc}") from None
        sized.append((realised, {**overrides, **ov}, plant))
    return sized, values, design


def _size(args: argparse.Namespace, emss: list[str], sized: list, costs: Any, meta: dict[str, Any],
          out: Path) -> Any:
    """Run every EMS at every size point into ``out/runs/``; write the outputs; the table."""
    from comems4build_ros.app.commands.compare import building_task_options
    from comems4build_ros.report.sizing import row, table, write_outputs
    from comems4build_ros.study.runner import RunTask, run_tasks
    from comems4build_ros.study.sizing import point_name

    tasks, cases = [], []
    for ems in emss:
        for realised, ov, plant in sized:
            name = point_name(ems, realised)
            usable = plant.battery.e_max_kwh * (plant.battery.soc_max - plant.battery.soc_min)
            cases.append((ems, name, realised, usable))
            tasks.append(RunTask(ems=ems, out_dir=str(out / "runs" / name), scenario="year", start=args.start,
                                 weeks=args.weeks, overrides=ov, config=[str(Path(c).resolve()) for c in args.config],
                                 timeseries=False, **building_task_options(ems, args)))
    t0 = time.perf_counter()
    summaries = run_tasks(tasks, progress=False if args.no_progress else None)
    meta["wall_s"] = time.perf_counter() - t0
    df = table([row(ems, name, realised, s, costs, usable)
                for (ems, name, realised, usable), s in zip(cases, summaries)])
    write_outputs(df, meta, costs, out)
    (out / "size.json").write_text(json.dumps({**meta, "interest_rate": costs.interest_rate,
                                               "cost_items": costs.items}, indent=2, default=str) + "\n",
                                   encoding="utf-8")
    return df
