"""``comems4build compare --community FILE``: the coordinators of ``config/coordinators.yaml`` side by side.

Every coordinator runs the community of FILE (``config/community/default.yaml`` is the
default one) in-process over the run's scenario, one run each (``runs/<coordinator>/``), on
the study's worker pool (``--jobs``, ``--scheduler``, ``--resume``); the report
(:mod:`comems4build_ros.report.community`) puts them side by side. A coordinator added to the
table appears here without a change.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import UsageError, output_dir, study_pool, table_names

#: The EMS of every house when ``--ems`` is not given: ComEMS4Build.
DEFAULT_COMMUNITY_EMS = "fuzzy"
#: What a community comparison writes into its output directory.
COMMUNITY_FILES = ("runs", "community_compare.json", "figures", "report.md", "report.html")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The community options of ``compare``."""
    parser.add_argument("--community", metavar="FILE", default=None,
                        help="compare the coordinators of config/coordinators.yaml on the community of FILE "
                             "(e.g. config/community/default.yaml; docs/community.md); --ems then names the EMS of "
                             f"every house (default {DEFAULT_COMMUNITY_EMS})")
    parser.add_argument("--coordinator", metavar="NAME[,NAME...]", default=None,
                        help="with --community: the coordinators to compare (default: every one of the table)")
    parser.add_argument("--coordinator-option", action="append", default=[], metavar="NAME.KEY=VALUE",
                        help="with --community: an option of one coordinator, e.g. rule.h2_split=need (repeatable)")


def coordinator_names(text: str | None) -> list[str]:
    """``--coordinator``: names of the table, each once; None = all."""
    from comems4build_ros.core.community.coordinator import (
        UnknownCoordinatorError,
        coordinator_class,
        coordinator_table,
    )

    text = ",".join(coordinator_table()) if text is None else text
    return table_names(text, "--coordinator", "coordinator", coordinator_class, UnknownCoordinatorError)


def coordinator_options(items: list[str], names: list[str]) -> dict[str, dict[str, Any]]:
    """``--coordinator-option NAME.KEY=VALUE`` items by coordinator (each must be compared)."""
    from comems4build_ros.core.config import parse_assignments

    out: dict[str, dict[str, Any]] = {n: {} for n in names}
    for key, value in parse_assignments(items, "--coordinator-option").items():
        name, _, option = key.partition(".")
        if not option:
            raise UsageError(f"--coordinator-option {key}={value}: give NAME.KEY=VALUE (e.g. rule.h2_split=need)")
        if name not in out:
            raise UsageError(f"--coordinator-option {key}: '{name}' is not among the compared coordinators "
                             f"({', '.join(names)})")
        out[name][option] = value
    return out


def community_ems(args: argparse.Namespace) -> str:
    """The one EMS of every house of a community run (``--ems``, default :data:`DEFAULT_COMMUNITY_EMS`),
    after the check that ``--out`` is given (both refused with a UsageError)."""
    from comems4build_ros.app.commands.options import ems_names

    if args.out is None:
        raise UsageError("--out is required (unless --from-runs)")
    emss = ems_names(args.ems or DEFAULT_COMMUNITY_EMS)
    if len(emss) != 1:
        raise UsageError(f"--ems {args.ems}: with --community give the one EMS of every house")
    return emss[0]


def _refuse_house_options(args: argparse.Namespace) -> None:
    """Options of ``compare`` that a community comparison does not take."""
    if args.via != "inprocess":
        raise UsageError("--community runs in-process (--via ros is not available for a community yet)")
    if args.fc_efficiency is not None:
        raise UsageError("--community compares coordinators at the plant's FC efficiency; set it with "
                         "--set fuel_cell.eta_sys=ETA instead of --fc-efficiency")
    if args.extend:
        raise UsageError("--community runs the scenario's data only (no --extend)")
    if args.building != "rc" or args.building_map or args.epw:
        raise UsageError("--community runs every house on the 4R3C (no --building, --building-map, --epw)")


def run_community(args: argparse.Namespace) -> int:
    """Run every coordinator on the community and write the report (``compare --community``)."""
    from comems4build_ros.app.commands.options import add_scenario_config, check_config_files
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.community.coordinator import make_coordinator
    from comems4build_ros.core.community.hub import community_hub
    from comems4build_ros.core.community.hubrun import community_info
    from comems4build_ros.core.community.spec import build_community, load_community
    from comems4build_ros.report.community import build_community_report, write_manifest
    from comems4build_ros.report.runs import RUNS_DIR
    from comems4build_ros.study.community import CommunityTask
    from comems4build_ros.study.runner import run_tasks

    _refuse_house_options(args)
    ems = community_ems(args)
    names = coordinator_names(args.coordinator)
    options = coordinator_options(args.coordinator_option, names)
    add_scenario_config(args)
    check_config_files(args.config)
    overrides = parse_assignments(args.set, "--set")
    spec = load_community(args.community)
    community = build_community(spec, args.scenario, args.config, overrides, source=str(args.community),
                                start=args.start, weeks=args.weeks, seed=args.seed)
    info = community_info(community, community_hub(community))
    for name in names:  # every coordinator's options checked before any run
        make_coordinator(name, info, options[name])
    output = output_dir(args, "compare", writes=COMMUNITY_FILES, replaces=COMMUNITY_FILES)
    output.check()
    config = [str(Path(c).resolve()) for c in args.config]
    with output, study_pool(args, output.path) as pool:
        stage = output.stage
        tasks = [CommunityTask(coordinator=name, out_dir=str(stage / RUNS_DIR / name),
                               community=str(Path(args.community).resolve()), houses=len(community.houses),
                               ems=ems, scenario=args.scenario, start=args.start, weeks=args.weeks,
                               seed=args.seed, overrides=overrides, config=config,
                               coordinator_options=options[name], forecast=args.forecast) for name in names]
        print(f"compare: {len(tasks)} community runs ({', '.join(names)}) of {len(community.houses)} houses",
              file=sys.stderr)
        t0 = time.perf_counter()
        walls: dict[str, float] = {}
        run_tasks(tasks, on_done=lambda t, s: walls.__setitem__(Path(t.out_dir).name, float(s["task_wall_s"])),
                  progress=False if args.no_progress else None)
        wall = time.perf_counter() - t0
        write_manifest(stage, {"kind": "community", "community_file": str(args.community), "coordinators": names,
                               "ems": ems, "scenario": args.scenario, "start": args.start, "weeks": args.weeks,
                               "overrides": overrides, "config": config, "coordinator_options": options,
                               "timezone": community.houses[0].params.site.timezone,
                               "wall_s": {**walls, "all_runs": wall}})
        print(f"runs: {wall:.1f} s wall for {len(tasks)} community runs", file=sys.stderr)
        rep = build_community_report(stage)
        output.commit()
        pool.complete()
    md, html = (output.path / Path(p).relative_to(stage) for p in (rep.markdown, rep.html))
    print(f"report: built in {rep.seconds:.2f} s")
    print(f"wrote {md}, {html} and {len(rep.figures)} figures in {md.parent / 'figures'}")
    return 0
