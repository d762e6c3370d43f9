"""``comems4build compare``: run RBC, fuzzy and MPC on one scenario and write the report.

``--from-runs DIR`` only rebuilds the report from the runs an earlier ``compare`` wrote.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from comems4build_ros.app.commands.options import (
    add_forecast_option,
    add_scenario_options,
    add_study_options,
    ems_help,
    output_dir,
    scenario_of,
    study_inputs,
    study_pool,
)
from comems4build_ros.files.errors import InputError

if TYPE_CHECKING:
    from comems4build_ros.report.build import Report

#: EMS compared by default (the paper's three schedulers).
DEFAULT_EMS = "rbc,fuzzy,mpc"
#: FC system efficiencies by default (paper sec:heat_recovery); the first is the base.
DEFAULT_ETAS = "0.75,0.90"
#: What the report of a comparison writes into its output directory (``--from-runs`` writes only these).
REPORT_FILES = ("figures", "report.md", "report.html", "findings.json", "paper_comparison.csv")
#: What ``compare`` writes: its runs, its manifest and the report.
COMPARE_FILES = ("runs", "compare.json", *REPORT_FILES)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``compare``."""
    parser.add_argument("--ems", metavar="NAME[,NAME...]", default=None,
                        help=f"{ems_help(many=True)} (default {DEFAULT_EMS}; with --community one, default fuzzy)")
    add_scenario_options(parser, hours=False)
    parser.add_argument("--via", choices=("inprocess", "ros"), default="inprocess",
                        help="run in-process or through the ROS 2 node set (bags evaluated)")
    parser.add_argument("--fc-efficiency", default=None, metavar="ETA[,ETA...]",
                        help="FC system efficiencies (fuel_cell.eta_sys); the first gives runs/<ems>/, the others "
                             f"runs/<ems>_eta<percent>/ for the heat-recovery figure (default {DEFAULT_ETAS}; "
                             "fuel_cell.eta_sys from --set or --config instead runs that one efficiency, and "
                             "giving both is refused)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter for every run, e.g. --set battery.e_max_kwh=10")
    add_study_options(parser, jobs_default="CPU count in-process, 1 with --via ros")
    add_forecast_option(parser)
    parser.add_argument("--from-runs", default=None, metavar="DIR",
                        help="only build the report from DIR/compare.json and DIR/runs/ (no simulation)")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="output directory (default with --from-runs: that DIR)")
    from comems4build_ros.app.commands import compare_community

    compare_community.add_arguments(parser)


def parse_etas(text: str) -> list[float]:
    """``"0.75,0.90"`` -> ``[0.75, 0.9]`` (each in (0, 1], no duplicates)."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.files.inputs import parse_decimal

    etas = []
    for part in text.split(","):
        try:
            eta = parse_decimal(part)
        except InputError:
            raise UsageError(f"--fc-efficiency: '{part}' is not a number") from None
        if not 0.0 < eta <= 1.0:
            raise UsageError(f"--fc-efficiency: {eta} is outside (0, 1]")
        if any(abs(eta - e) < 1e-9 for e in etas):
            raise UsageError(f"--fc-efficiency: {eta} given twice")
        etas.append(eta)
    return etas


def fc_efficiencies(option: str | None, config: list[str], overrides: dict) -> list[float]:
    """FC system efficiencies of the comparison: the one rule for ``--fc-efficiency`` against ``eta_sys``.

    ``--fc-efficiency`` gives them; without it, a ``fuel_cell.eta_sys`` from ``--set`` or a
    ``--config`` file runs that one efficiency (it is never silently replaced by the
    default); neither gives :data:`DEFAULT_ETAS`. Both at once are a conflict and refused.
    """
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.core.config import load_plant_params, read_ros_params

    eta = load_plant_params(config, overrides).fuel_cell.eta_sys  # every file and --set checked first
    sources = [f"--set fuel_cell.eta_sys={overrides['fuel_cell.eta_sys']}"] if "fuel_cell.eta_sys" in overrides else []
    sources += [f"--config {path} (fuel_cell.eta_sys)" for path in config
                if "eta_sys" in (read_ros_params(path).get("fuel_cell") or {})]
    if option is not None and sources:
        raise UsageError(f"--fc-efficiency {option} and {sources[0]} both set the FC system efficiency; give it "
                         "once (--fc-efficiency for the efficiencies the comparison runs)")
    if option is not None:
        return parse_etas(option)
    if sources:
        return [eta]
    return parse_etas(DEFAULT_ETAS)


def run_name(ems: str, eta: float, base_eta: float) -> str:
    """Run directory name: ``<ems>`` at the base efficiency, else ``<ems>_eta<percent>``."""
    return ems if abs(eta - base_eta) < 1e-9 else f"{ems}_eta{eta * 100:.0f}"


def run(args: argparse.Namespace) -> int:
    """Run the comparison (unless --from-runs) and write the report."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.config import ConfigError, load_plant_params
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.report.runs import RunDirError

    if args.from_runs and (args.scheduler or args.resume):
        raise UsageError("--scheduler and --resume apply to runs; --from-runs makes none")
    if args.via == "ros" and args.scheduler:
        raise UsageError("--via ros runs the ROS 2 node set on this machine; --scheduler applies to in-process runs")
    if args.from_runs:
        output = output_dir(args, "compare", writes=REPORT_FILES, replaces=REPORT_FILES,
                            path=args.out if args.out is not None else args.from_runs)
        try:
            with output:  # the report files replace the older ones only when all are written
                rep = _report_builder(args.from_runs)(args.from_runs, output.stage)
                stage = output.stage
        except RunDirError as exc:
            raise UsageError(str(exc)) from None
        _print_report(rep, stage, output.path)
        return 0
    if args.community is not None:
        from comems4build_ros.app.commands.compare_community import run_community

        return run_community(args)
    if args.coordinator is not None or args.coordinator_option:
        raise UsageError("--coordinator and --coordinator-option apply with --community")
    if args.out is None:
        raise UsageError("--out is required (unless --from-runs)")
    args.ems = args.ems or DEFAULT_EMS
    emss = study_inputs(args)
    if args.building_choice.kind != "rc" and args.via == "ros":
        raise UsageError("--building with --via ros: use comems4build launch --building (compare runs it in-process)")
    levels = {ems: str(ems_entry(ems).info_level) for ems in emss}
    overrides = parse_assignments(args.set, "--set")
    etas = fc_efficiencies(args.fc_efficiency, args.config, overrides)
    if args.scenario == "year" and args.fc_efficiency is None:
        etas = etas[:1]  # the year's report compares the EMS at the plant's FC efficiency
    for eta in etas:  # check every parameter set before starting any run
        try:
            params = load_plant_params(args.config, {**overrides, "fuel_cell.eta_sys": eta})
        except ConfigError as exc:  # an efficiency the plant cannot have (below its electrical one)
            if args.fc_efficiency is None:
                raise
            raise UsageError(f"--fc-efficiency {eta!r}: {exc}") from None
    if args.extend and args.via == "ros":
        raise UsageError("--extend applies to in-process runs; the ROS feed runs the scenario's data only")
    scenario_of(args, params)  # the scenario and the run length, checked once before any run
    output = output_dir(args, "compare", writes=COMPARE_FILES, replaces=COMPARE_FILES)
    output.check()
    out = output.path
    jobs = args.jobs if args.jobs is not None else (1 if args.via == "ros" else None)
    with output, study_pool(args, out, jobs) as pool:  # finished runs kept in OUT/.runstore until the end
        stage = output.stage
        rep = _compare(args, emss, etas, levels, overrides, stage)
        output.commit()  # runs/, manifest, report, figures replace an older comparison's when all are written
        pool.complete()
    _print_report(rep, stage, out)
    return 0


def _compare(args: argparse.Namespace, emss: list[str], etas: list[float], levels: dict[str, str],
             overrides: dict, out: Path) -> Report:
    """Run every EMS at every efficiency into ``out`` (runs/, compare.json) and build the report there."""
    from comems4build_ros.report.runs import RUNS_DIR, Manifest, RunSpec, write_manifest
    from comems4build_ros.study.runner import RunTask, run_tasks

    base = etas[0]
    specs, tasks = [], []
    for ems in emss:
        for eta in etas:
            name = run_name(ems, eta, base)
            ov = {**overrides, "fuel_cell.eta_sys": eta}
            specs.append(RunSpec(name=name, ems=ems, eta_sys=eta, info_level=levels[ems], overrides=ov))
            tasks.append(RunTask(ems=ems, out_dir=str(out / RUNS_DIR / name), scenario=args.scenario,
                                 start=args.start, weeks=args.weeks, seed=args.seed, extend=args.extend, overrides=ov,
                                 config=[str(Path(c).resolve()) for c in args.config], via=args.via,
                                 **building_task_options(ems, args)))
    walls: dict[str, float] = {}

    def done(task: RunTask, summary: dict) -> None:
        walls[Path(task.out_dir).name] = float(summary["task_wall_s"])

    print(f"compare: {len(tasks)} runs ({', '.join(s.name for s in specs)}) via {args.via}", file=sys.stderr)
    t0 = time.perf_counter()
    run_tasks(tasks, on_done=done, progress=False if args.no_progress else None)
    wall = time.perf_counter() - t0
    manifest = Manifest(scenario=args.scenario, weeks=args.weeks, via=args.via, base_eta=base, runs=specs,
                        overrides=overrides, config=[str(Path(c).resolve()) for c in args.config],
                        wall_s={**walls, "all_runs": wall})
    write_manifest(manifest, out)
    print(f"runs: {wall:.1f} s wall for {len(tasks)} runs", file=sys.stderr)
    return _report_builder(out)(out)


def building_task_options(ems: str, args: argparse.Namespace) -> dict[str, Any]:
    """A task's ``building`` and ``forecast``; an MPC on a detailed building estimates its walls (``observer=kalman``).

    The MPC plans with the plant file's ``building`` section (an identified model given with
    ``--config``); on EnergyPlus or an FMU the plant's wall temperatures are not its model's
    nodes, so it estimates them from the measured T_air (:mod:`comems4build_ros.core.ems.mpc.observer`).
    """
    from comems4build_ros.core.ems import ems_entry

    choice = getattr(args, "building_choice", None)
    out: dict[str, Any] = {"forecast": getattr(args, "forecast", None)}
    if choice is not None and choice.kind != "rc":
        out["building"] = choice.text
        if ems == "mpc" and str(ems_entry(ems).info_level) == "mpc":
            out["ems_options"] = {"observer": "kalman"}
    return out


def _report_builder(compare_dir: str | Path) -> Any:
    """The report of a comparison: a community's (``report/community.py``) for ``--community``, the
    year-round one (``report/year.py``) for ``--scenario year``, else the paper's (``report/build.py``)."""
    from comems4build_ros.files.inputs import InputFileError, load_json_file
    from comems4build_ros.report import community
    from comems4build_ros.report.build import build_report
    from comems4build_ros.report.runs import MANIFEST
    from comems4build_ros.report.year import build_year_report

    if (Path(compare_dir) / community.MANIFEST).is_file() and not (Path(compare_dir) / MANIFEST).is_file():
        return community.build_community_report

    try:
        manifest = load_json_file(Path(compare_dir) / MANIFEST, "a comparison's manifest")
    except InputFileError:
        manifest = None  # build_report names the missing or corrupt manifest
    scenario = manifest.get("scenario") if isinstance(manifest, dict) else None
    return build_year_report if scenario == "year" else build_report


def _print_report(rep: Report, stage: Path, out: Path) -> None:
    """The findings count and the files written (``rep`` was built in ``stage``, now renamed to ``out``)."""
    held = sum(f["verdict"] == "held" for f in rep.findings)
    evaluated = sum(f["verdict"] != "n/a" for f in rep.findings)
    if rep.findings:
        print(f"report: {held} of {evaluated} evaluated findings held; built in {rep.seconds:.2f} s")
    else:  # the year's report: no finding of the paper's winter applies
        print(f"report: built in {rep.seconds:.2f} s")
    md, html = (out / Path(p).relative_to(stage) for p in (rep.markdown, rep.html))
    print(f"wrote {md}, {html} and {len(rep.figures)} figures in {md.parent / 'figures'}")
