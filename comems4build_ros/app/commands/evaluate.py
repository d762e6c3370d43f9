"""``comems4build evaluate``: weekly KPIs and summary from a recorded bag."""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``evaluate``."""
    parser.add_argument("bag", help="rosbag2 directory (MCAP storage) or .mcap file; a bag cut by SIGKILL is read too; "
                                    "the bag directory of a community run (launch --community) evaluates the "
                                    "community: every house's bag and the coordinator's")
    parser.add_argument("--out", metavar="DIR", required=True,
                        help="output directory (timeseries.csv, weekly.csv, summary.json)")
    parser.add_argument("--config", action="append", default=None, metavar="FILE",
                        help="parameter file merged over config/plant.yaml (default: the bag's run_info.json)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter (with --config or alone)")
    parser.add_argument("--no-timeseries", action="store_true", help="do not write timeseries.csv")
    parser.add_argument("--accept-gaps", action="store_true",
                        help="evaluate a bag that misses messages on some topic (default: refuse, exit 2)")
    parser.add_argument("--strict", action="store_true",
                        help="exit 1 when the bag is incomplete or damaged: steps of the run not recorded, the run "
                             "cut, no metadata.yaml, a truncated or damaged file, or messages missing that "
                             "--accept-gaps let through (the files are written all the same)")


def run(args: argparse.Namespace) -> int:
    """Read the bag, compute the KPIs, write the files."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import check_config_files, output_dir
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.bags.evaluation import evaluate_bag, house_dir, read_run_info
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import RUN_FILES

    bag = Path(args.bag)
    if not bag.exists():
        raise UsageError(f"bag {bag}: no such file or directory")
    from comems4build_ros.bags.community import is_community_bag

    if bag.is_dir() and is_community_bag(bag):
        if args.config is not None or args.set:
            raise UsageError("a community's bags carry every house's parameters (no --config, --set)")
        return run_community(args, bag)
    output = output_dir(args, "evaluate", writes=(*RUN_FILES, "house_*"), replaces=(*RUN_FILES, "house_*"))
    output.check()
    params = None
    if args.config is not None or args.set:
        check_config_files(args.config or [])
        info = read_run_info(bag)
        files = args.config if args.config is not None else info.get("config_files") or []
        overrides = dict(info.get("overrides") or {}) if args.config is None else {}
        overrides.update(parse_assignments(args.set, "--set"))
        params = load_plant_params(files, overrides)
    # all or nothing: the results go to a temporary directory, then replace those of an earlier evaluate
    # (no older timeseries.csv or house_<i>/ stays beside them)
    with output:
        summaries = evaluate_bag(bag, output.stage, params=params, timeseries=not args.no_timeseries,
                                 accept_gaps=args.accept_gaps)
    damaged = {ns: s["bag_incomplete"] for ns, s in summaries.items() if "bag_incomplete" in s}
    for ns, d in damaged.items():  # each house with its own bag's damage
        why = "; ".join(d["damage"]) or ("no metadata.yaml (recorder killed?); read the .mcap directly"
                                          if not d["metadata_yaml"] else "")
        if d.get("run_cut"):
            why = f"run cut short: {d['run_cut'].get('cause')}" + (f"; {why}" if why else "")
        where = "" if len(summaries) == 1 else f" (house {ns.strip('/') or 'root'})"
        print(f"bag {bag}{where}: incomplete: {d['steps_recorded']} of {d['steps_expected'] or '?'} steps recorded"
              + (f"; {why}" if why else ""))
    if not damaged:
        print(f"bag {bag}: complete")
    keys = ("weeks", "steps", "cost_eur_week_median", "discomfort_kh_week_median", "loh_end", "fallback_steps")
    for ns, s in summaries.items():  # with what was cut or stood in (a run on live inputs), where it applies
        marks = {k: s[k] for k in ("bag_incomplete", "live_inputs") if k in s}
        print(json.dumps({"house": ns, **{k: s.get(k) for k in keys}, **marks}))
    out = Path(args.out)
    names = [n for n in RUN_FILES if not (args.no_timeseries and n == "timeseries.csv")]
    written = [p for p in (house_dir(out, ns, len(summaries)) / n for ns in summaries for n in names) if p.exists()]
    if len(summaries) > 1 or "/" not in summaries:
        written += [out / "weekly.csv", out / "summary.json"]
    print(f"wrote {len(written)} files: {', '.join(str(p) for p in written)}")
    from comems4build_ros.app.commands.simulate import warn_run

    code = max([warn_run(s, "evaluate") for s in summaries.values()], default=0)
    if args.strict:
        return max(code, strict_verdict(bag, summaries))
    return code


def run_community(args: argparse.Namespace, bag: Path) -> int:
    """A community's bags (``launch --community``): the community's run directory, as the launch wrote it."""
    from comems4build_ros.app.commands.options import output_dir
    from comems4build_ros.bags.community import community_summary_line, evaluate_community_bags
    from comems4build_ros.core.community.loop import COMMUNITY_FILES

    output = output_dir(args, "evaluate", writes=(*COMMUNITY_FILES, "events.txt"),
                        replaces=(*COMMUNITY_FILES, "events.txt"))
    output.check()
    with output:
        result = evaluate_community_bags(bag, output.stage, timeseries=not args.no_timeseries)
    print(community_summary_line(result.summary))
    out = Path(args.out)
    print(f"wrote {out / 'community.json'}, {out / 'hub.csv'}, {out / 'houses.csv'}, {out / 'houses'}/")
    summaries = {name: r.summary for name, r in result.houses.items()}
    lost = {name: s["lost_messages"] for name, s in summaries.items() if s.get("lost_messages")}
    if lost and not args.accept_gaps:
        print(f"comems4build evaluate: messages missing in the houses' bags: {lost}")
    if args.strict:
        return strict_verdict(bag, {f"/{name}": s for name, s in summaries.items()})
    return 0


def strict_verdict(bag: Path, summaries: dict[str, dict]) -> int:
    """``--strict``: 1 (with one line per house on stderr saying what is incomplete) when any
    house's bag is incomplete or damaged or misses messages, else 0."""
    import sys

    failed = 0
    for ns, s in summaries.items():
        d = s.get("bag_incomplete") or {}
        what = []
        if d:
            if d.get("steps_expected") is None or d.get("steps_recorded") != d.get("steps_expected"):
                what.append(f"{d.get('steps_recorded')} of {d.get('steps_expected') or '?'} steps recorded")
            if d.get("run_cut"):
                what.append(f"run cut short ({s.get('run_cut')})")
            if not d.get("metadata_yaml"):
                what.append("no metadata.yaml")
            if d.get("truncated_mcap"):
                what.append("the .mcap file ends early")
            what += list(d.get("damage") or [])
        if s.get("lost_messages"):
            what.append("messages missing on " + ", ".join(f"{t} ({n} step(s))" for t, n in s["lost_messages"].items()))
        if what:
            failed += 1
            where = "" if len(summaries) == 1 else f" (house {ns.strip('/') or 'root'})"
            print(f"comems4build evaluate: --strict: bag {bag}{where} is incomplete: {'; '.join(what)}",
                  file=sys.stderr)
    return 1 if failed else 0
