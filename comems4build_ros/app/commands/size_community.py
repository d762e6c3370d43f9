"""``comems4build size --community FILE``: isolated houses against one shared H2 hub over the year.

The houses of FILE each with its own H2 system (isolated) against the same houses sharing one
hub, at every hub size of ``--hub-kwh`` x ``--hub-modules``, settled under every rule set of
``config/sharing.yaml``; per household the annual cost, the self-sufficiency and whether the
seasonal cycle closes (:mod:`comems4build_ros.study.community_sizing`,
:mod:`comems4build_ros.report.community_sizing`; docs/community.md). The runs go through the
study's pool of workers (``--jobs``, ``--scheduler``, ``--resume``); ``--from-runs DIR`` rebuilds the
tables and the report of an earlier study from its runs.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import UsageError, output_dir, parse_values, study_pool

#: The coordinator of the hub when ``--coordinator`` is not given.
DEFAULT_COORDINATOR = "rule"
#: Plant sections the hub and the isolated houses' own H2 systems size (not ``--set``).
SIZED_SECTIONS = ("hydrogen.", "electrolyser.n_modules")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The community options of ``size``."""
    parser.add_argument("--community", metavar="FILE", default=None,
                        help="compare the houses of the community FILE (e.g. config/community/default.yaml), each with "
                             "its own H2 system, against the same houses sharing one hub, per household and sharing "
                             "rule set (docs/community.md); --ems then names the EMS of every house (default fuzzy)")
    parser.add_argument("--hub-kwh", metavar="V1,V2,...", default=None,
                        help="with --community: the hub's H2 store sizes [kWh LHV], values > 0; every isolated house "
                             "gets its nominal share of each (default: the sum of the houses' own stores)")
    parser.add_argument("--hub-modules", metavar="N1,N2,...", default=None,
                        help="with --community: the hub's electrolyser modules, integers >= 1 (default: the sum of the "
                             "houses' own)")
    parser.add_argument("--coordinator", metavar="NAME", default=None,
                        help=f"with --community: the hub's coordinator of config/coordinators.yaml (default "
                             f"{DEFAULT_COORDINATOR}); the isolated houses need none")
    parser.add_argument("--coordinator-option", action="append", default=[], metavar="NAME.KEY=VALUE",
                        help="with --community: an option of the coordinator, e.g. rule.h2_split=need (repeatable)")
    parser.add_argument("--from-runs", metavar="DIR", default=None,
                        help="rebuild the tables, figures and report of an earlier size --community in DIR from its "
                             "runs (nothing runs; --out defaults to DIR)")


def _refuse(args: argparse.Namespace) -> None:
    """Options of ``size`` that the community study does not take, and its own without ``--community``."""
    from comems4build_ros.study.sizing import AXES

    given = [a.option for a in AXES if getattr(args, a.option[2:].replace("-", "_")) is not None]
    if given:
        raise UsageError(f"{given[0]} sizes one house; with --community the houses are those of the community file "
                         "and the hub is sized with --hub-kwh and --hub-modules")
    if args.sample is not None:
        raise UsageError("--sample draws one house's sizes; with --community give --hub-kwh and --hub-modules")
    if args.building != "rc" or args.building_map or args.epw:
        raise UsageError("--community runs every house on the 4R3C (no --building, --building-map, --epw)")


def refuse_without_community(args: argparse.Namespace) -> None:
    """The community options given without ``--community`` (or ``--from-runs``)."""
    for option in ("hub_kwh", "hub_modules", "coordinator"):
        if getattr(args, option) is not None:
            raise UsageError(f"--{option.replace('_', '-')} applies with --community")
    if args.coordinator_option:
        raise UsageError("--coordinator-option applies with --community")


def _hub_values(args: argparse.Namespace, default_kwh: float, default_modules: int) -> tuple[list[float], list[int]]:
    kwh = parse_values(args.hub_kwh, "--hub-kwh", False) if args.hub_kwh is not None else [default_kwh]
    modules = parse_values(args.hub_modules, "--hub-modules", True) if args.hub_modules is not None \
        else [default_modules]
    if 0 in modules:
        raise UsageError(f"--hub-modules '{args.hub_modules}': a hub needs at least one module")
    return kwh, [int(m) for m in modules]


def run(args: argparse.Namespace) -> int:
    """Run the isolated houses and the hub sizes over the year; write the tables, figure and report."""
    from comems4build_ros.app.commands.compare_community import (
        community_ems,
        coordinator_names,
        coordinator_options,
    )
    from comems4build_ros.app.commands.options import add_scenario_config, check_config_files, check_start
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.community.coordinator import make_coordinator
    from comems4build_ros.core.community.hubrun import community_info
    from comems4build_ros.core.community.plant import CommunityPlant
    from comems4build_ros.core.community.spec import build_community, load_community, resized
    from comems4build_ros.core.config import W_PER_KW, load_plant_params
    from comems4build_ros.core.economics import load_costs
    from comems4build_ros.core.scenario.csvio import ScenarioError
    from comems4build_ros.report.community_sizing import FILES, MANIFEST, write_outputs
    from comems4build_ros.study.community import CommunityTask
    from comems4build_ros.study.community_sizing import HubSize, isolated_name, shares_kwh
    from comems4build_ros.study.runner import run_tasks
    from comems4build_ros.study.sizing import plant_sizes

    _refuse(args)
    ems = community_ems(args)
    names = coordinator_names(args.coordinator or DEFAULT_COORDINATOR)
    if len(names) != 1:
        raise UsageError(f"--coordinator {args.coordinator}: give the one coordinator of the hub")
    coordinator = names[0]
    options = coordinator_options(args.coordinator_option, names)[coordinator]
    args.scenario = "year"
    add_scenario_config(args)
    check_config_files(args.config)
    check_config_files(args.costs, "--costs")
    costs = load_costs(args.costs)
    overrides = parse_assignments(args.set, "--set")
    for key in overrides:
        if key.startswith(SIZED_SECTIONS):
            raise UsageError(f"--set {key}: the H2 systems are sized by the study (--hub-kwh, --hub-modules; each "
                             "isolated house has its share of the hub's store and its own electrolyser)")
    check_start(args.start, load_plant_params(args.config, overrides))
    source = str(args.community)
    spec = load_community(args.community)
    try:
        base = build_community(spec, "year", args.config, overrides, source=source, start=args.start,
                               weeks=args.weeks)
    except ScenarioError as exc:
        raise UsageError(f"--start/--weeks: {exc}") from None
    kwhs, modules = _hub_values(args, base.hub.e_max_wh / W_PER_KW, int(base.hub.electrolyser.n_modules))
    sizes = [HubSize(k, m) for k in kwhs for m in modules]
    weights = {h.name: h.h2_weight for h in spec.houses}
    for size in sizes:  # every hub's community built and its coordinator made before any run
        community = build_community(resized(spec, {"store_kwh": size.store_kwh, "electrolyser_modules": size.modules},
                                            source=source), "year", args.config, overrides, source=source,
                                    start=args.start, weeks=args.weeks)
        make_coordinator(coordinator, community_info(community, CommunityPlant(community).hub), options)
    isolated: dict[str, dict[str, dict[str, Any]]] = {}
    for kwh in kwhs:  # every isolated house: its share of the hub's store and its own electrolyser
        isolated[f"{kwh:g}"] = {}
        for house, share in shares_kwh(kwh, weights).items():
            resized(spec, {"store_kwh": share, "electrolyser_modules": None}, house, source=source)
            isolated[f"{kwh:g}"][house] = {"store_kwh": share, "run": isolated_name(house, share)}
    houses = {h.name: {"weight": h.spec.h2_weight, "reason": h.spec.reason,
                       "sizes": plant_sizes(h.params) | {"el_modules": int(h.params.electrolyser.n_modules)},
                       "usable_battery_kwh": h.params.battery.e_max_kwh * (h.params.battery.soc_max
                                                                           - h.params.battery.soc_min)}
              for h in base.houses}
    output = output_dir(args, "size", writes=FILES, replaces=FILES)
    output.check()
    config = [str(Path(c).resolve()) for c in args.config]
    meta: dict[str, Any] = {
        "kind": "size_community", "community_file": source, "community": spec.name, "ems": ems,
        "coordinator": coordinator, "coordinator_options": options, "start": args.start, "weeks": args.weeks or 52,
        "set": overrides, "config": config, "hub_sizes": [{"store_kwh": s.store_kwh, "modules": s.modules,
                                                           "run": s.name} for s in sizes],
        "isolated": isolated, "houses": houses, "timezone": base.houses[0].params.site.timezone,
        "dt_h": base.hub.dt_h, "costs_files": [str(Path(c).resolve()) for c in args.costs],
        "interest_rate": costs.interest_rate, "cost_items": costs.items,
        "workers": args.scheduler or f"local processes (--jobs {args.jobs or 'CPU count'})",
        "load_average_start": list(os.getloadavg())}
    n_iso = sum(len(v) for v in isolated.values())
    print(f"size: {len(sizes)} hub runs of {len(houses)} houses and {n_iso} isolated house runs "
          f"({len(kwhs)} store sizes x {len(houses)} houses)", file=sys.stderr)
    community_path = str(Path(args.community).resolve())
    with output, study_pool(args, args.out) as pool:
        stage = output.stage
        common = {"community": community_path, "ems": ems, "scenario": "year", "start": args.start,
                  "weeks": args.weeks, "overrides": overrides, "config": config}
        tasks = [CommunityTask(coordinator=coordinator, out_dir=str(stage / "runs" / s.name), houses=len(houses),
                               coordinator_options=options, timeseries=False,
                               hub={"store_kwh": s.store_kwh, "electrolyser_modules": s.modules}, **common)
                 for s in sizes]
        tasks += [CommunityTask(coordinator=DEFAULT_COORDINATOR, out_dir=str(stage / "runs" / iso["run"]), houses=1,
                                hub={"store_kwh": iso["store_kwh"], "electrolyser_modules": None}, house=house,
                                **common)
                  for runs in isolated.values() for house, iso in runs.items()]
        t0 = time.perf_counter()
        run_tasks(tasks, progress=False if args.no_progress else None)
        meta["wall_s"] = time.perf_counter() - t0
        meta["load_average_end"] = list(os.getloadavg())
        (stage / MANIFEST).write_text(json.dumps(meta, indent=2, default=str) + "\n", encoding="utf-8")
        result = write_outputs(stage)
        output.commit()
        pool.complete()
    _print(result, Path(args.out))
    return 0


def rebuild(args: argparse.Namespace) -> int:
    """``--from-runs DIR``: the tables, figures and report again from DIR's runs and manifest."""
    from comems4build_ros.report.community_sizing import REPORT_FILES, write_outputs
    from comems4build_ros.report.runs import RunDirError

    if args.scheduler or args.resume:
        raise UsageError("--scheduler and --resume apply to runs; --from-runs makes none")
    output = output_dir(args, "size", writes=REPORT_FILES, replaces=REPORT_FILES,
                        path=args.out if args.out is not None else args.from_runs)
    try:
        with output:
            result = write_outputs(Path(args.from_runs), output.stage)
    except RunDirError as exc:
        raise UsageError(str(exc)) from None
    _print(result, output.path)
    return 0


def _print(result: Any, out: Path) -> None:
    for line in result.answer:
        print(line)
    print(f"wrote {out / 'households.csv'}, {out / 'points.csv'}, {out / 'figures'}, {out / 'report.md'} and "
          f"{out / 'report.html'}")
