"""``comems4build reproduce``: the paper's stated figures beside ours, its findings, figures and the study."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from comems4build_ros.app.commands.options import add_building_options, add_pool_options, real
from comems4build_ros.files.errors import InputError

if TYPE_CHECKING:
    from comems4build_ros.report.reproduce import ReproduceResult


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``reproduce``."""
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory (reproduce.md, reproduce.html, "
                                                     "reproduce.json, figures/, runs/)")
    parser.add_argument("--no-study", action="store_true",
                        help="only the default runs on every seed, the stated figures, the findings and the figures "
                             "(no interpretation study)")
    parser.add_argument("--only", default=None, metavar="KEY[,KEY...]",
                        help="study only these ambiguities of config/reproduce.yaml")
    add_pool_options(parser)
    add_building_options(parser)
    parser.add_argument("--weeks", type=real(1 / 168, 12), default=None, metavar="N",
                        help="run length in weeks, one hour (1/168) .. 12 (default 12, the paper's; shorter runs "
                             "are quick checks that do not compare with the paper's table)")
    parser.add_argument("--seeds", default=None, metavar="N[,N...]",
                        help="seeds of the modelled radiation and appliance load, integers in 0..2^32-1 (default: "
                             "the study's, config/reproduce.yaml; the first is the default scenario's)")
    parser.add_argument("--no-figures", action="store_true", help="do not draw the paper's figures")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars (one per run)")
    parser.add_argument("--update-doc", default=None, metavar="MD",
                        help="also write the tables between the reproduce markers of MD (docs/calibration.md)")
    parser.add_argument("--from-json", default=None, metavar="FILE",
                        help="no runs: write the documents (and --update-doc) from an earlier reproduce.json")
    parser.add_argument("--from-runs", default=None, metavar="DIR",
                        help="no runs: evaluate the run directories of an earlier reproduce --out DIR of the same "
                             "study again (after a change to the evaluation); the runs must come from the same "
                             "code and config/")


#: What ``reproduce`` writes into its output directory.
REPRODUCE_FILES = ("runs", "figures", "reproduce.md", "reproduce.html", "reproduce.json")
#: What ``reproduce --from-json`` writes (the documents, and the figures beside another directory's JSON).
DOCUMENT_FILES = ("figures", "reproduce.md", "reproduce.html")


def run(args: argparse.Namespace) -> int:
    """Run the reproduction and print where the report is."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import output_dir, study_pool

    if args.from_json and args.from_runs:
        raise UsageError("--from-json and --from-runs exclude each other")
    if (args.from_json or args.from_runs) and (args.scheduler or args.resume):
        raise UsageError("--scheduler and --resume apply to runs; --from-json and --from-runs make none")
    if args.update_doc:
        from comems4build_ros.files.inputs import check_markers
        from comems4build_ros.files.outputs import check_out_file, check_out_text
        from comems4build_ros.report.reproduce_doc import DOC_BEGIN, DOC_END

        check_out_file(check_out_text(args.update_doc, "--update-doc"), "--update-doc")
        check_markers(args.update_doc, DOC_BEGIN, DOC_END, "--update-doc")  # before the first run
    if args.from_json:
        return _from_json(args)
    if args.from_runs:
        from pathlib import Path

        if not (Path(args.from_runs) / "runs").is_dir():
            raise UsageError(f"--from-runs {args.from_runs}: no runs/ directory (the --out of an earlier reproduce)")
    from comems4build_ros.app.commands.options import building_choice

    building = building_choice(args).text
    only = [k for k in args.only.split(",") if k] if args.only else None
    seeds = None
    if args.seeds is not None:
        from comems4build_ros.files.inputs import parse_integer

        try:
            seeds = [parse_integer(x) for x in args.seeds.split(",") if x.strip()]
        except InputError:
            raise UsageError(f"--seeds {args.seeds}: a comma-separated list of integers") from None
        if not seeds or len(set(seeds)) != len(seeds) or not all(0 <= s < 2**32 for s in seeds):
            raise UsageError(f"--seeds {args.seeds}: distinct integers in 0..2^32-1")
    writes = DOCUMENT_FILES + ("reproduce.json",) if args.from_runs else REPRODUCE_FILES
    output = output_dir(args, "reproduce", writes=writes, replaces=writes)
    output.check()
    with output, study_pool(args, args.out) as pool:  # the runs' pool; finished runs kept in OUT/.runstore
        res = reproduce(output.stage, with_study=not args.no_study, jobs=args.jobs, weeks=args.weeks, only=only,
                        seeds=seeds, show_progress=False if args.no_progress else None,
                        from_runs=args.from_runs, figures=not args.no_figures, building=building)
        output.commit()  # runs/, figures, documents and reproduce.json replace an earlier reproduction's whole
        pool.complete()
    out = output.path

    def pct(x: float | None) -> str:
        return "-" if x is None else f"{100 * x:.1f} %"

    print(f"seed-median relative error: every stated figure {pct(res.median_rel_error)}, headline table "
          f"{pct(res.table_rel_error)}; cost ratios " + ", ".join(f"{k} {v:.2f}" for k, v in res.ratios.items())
          + f"; ComEMS4Build's FC vs MPC: hours {res.fc['fuzzy_hours']:+.1f} %, "
          f"toggles {res.fc['fuzzy_toggles']:+.1f} %"
          + f"; findings held {res.findings_held} of {res.findings_total}")
    made = (f"runs of {args.from_runs} evaluated again" if args.from_runs
            else f"{res.runs_made} runs in {res.wall_s:.0f} s")
    print(f"{made}; wrote {out / res.markdown.name}, {out / res.html.name}, {out / res.json.name}")
    if args.update_doc:
        from comems4build_ros.files.inputs import load_json_file
        from comems4build_ros.report.reproduce_doc import update_doc

        print(f"updated {update_doc(args.update_doc, load_json_file(out / res.json.name, 'reproduce.json'), out)}")
    return 0


def _from_json(args: argparse.Namespace) -> int:
    """``--from-json FILE``: the documents (and ``--update-doc``) from an earlier ``reproduce.json``, no runs."""
    import shutil
    from pathlib import Path

    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import output_dir
    from comems4build_ros.files.inputs import InputFileError, load_json_file
    from comems4build_ros.report.reproduce_doc import ReportFileError, check_report, update_doc, write_documents

    try:
        report = check_report(load_json_file(args.from_json, "a reproduce.json"), str(args.from_json))
    except (InputFileError, ReportFileError) as exc:
        raise UsageError(f"--from-json {exc}") from None
    src = Path(args.from_json).parent
    output = output_dir(args, "reproduce", writes=DOCUMENT_FILES, replaces=("reproduce.md", "reproduce.html"))
    with output:
        out = output.stage
        report = {**report, "figures": {k: v for k, v in report.get("figures", {}).items() if (src / v).is_file()}}
        if report["figures"] and src.resolve() != output.path.resolve():
            shutil.copytree(src / "figures", out / "figures")
        try:
            md, html = write_documents(report, out)
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise UsageError(f"--from-json {args.from_json}: not a reproduce.json this version can read "
                             f"({type(exc).__name__}: {exc})") from None
    print(f"wrote {output.path / md.name}, {output.path / html.name}")
    if args.update_doc:
        print(f"updated {update_doc(args.update_doc, report, output.path)}")
    return 0


def reproduce(
    out_dir: str | Path,
    with_study: bool = True,
    jobs: int | None = None,
    study_path: str | Path | None = None,
    weeks: float | None = None,
    only: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    show_progress: bool | None = None,
    from_runs: str | Path | None = None,
    figures: bool = True,
    building: str = "rc",
) -> ReproduceResult:
    """Make the study's runs, then evaluate them beside the paper.

    The runs are those of :mod:`comems4build_ros.study.reproduce`, the evaluation is
    :mod:`comems4build_ros.report.reproduce`.

    Parameters
    ----------
    out_dir : output directory (runs go to ``out_dir/runs/<name>``)
    with_study, study_path, weeks, only, seeds : what to run
        (:func:`comems4build_ros.study.reproduce.prepare`)
    jobs : parallel processes (default: CPU count)
    progress : callback ``(done, total, name)`` after each run
    show_progress : one progress bar per run on stderr (None = when stderr is a terminal)
    from_runs : no simulation: evaluate the run directories of an earlier ``reproduce`` of
        the same study (``from_runs/runs/<name>``) again, e.g. after a change to the
        evaluation; the runs are taken as they are (they must come from the same code and
        configuration). Wall time and run count are those of the earlier command, read
        from its ``reproduce.json``.
    figures : draw the paper's figures from the default seed's runs
    building : the building model of every run (``--building``; an MPC on a detailed building
        plans with the plant file's 4R3C and estimates its walls, ``observer=kalman``)
    """
    import time

    from comems4build_ros.core.config import ConfigError
    from comems4build_ros.report.reproduce import evaluate
    from comems4build_ros.study.reproduce import prepare
    from comems4build_ros.study.runner import missing_in, run_into

    t0 = time.perf_counter()
    prepared = prepare(with_study, study_path, weeks, only, seeds)
    if building != "rc":
        for task in prepared.tasks.values():
            task.building = building
            if task.ems == "mpc":
                task.ems_options = {**task.ems_options, "observer": "kalman"}
    out = Path(out_dir)
    if from_runs is not None:
        runs_dir = Path(from_runs) / "runs"
        missing = missing_in(prepared.tasks, runs_dir)
        if missing:
            raise ConfigError(f"{runs_dir}: no run directory with a summary.json for {', '.join(missing)} "
                              f"(this study needs {len(prepared.tasks)} runs)")
        earlier: dict[str, Any] = {}
        earlier_json = Path(from_runs) / "reproduce.json"
        if earlier_json.is_file():
            from comems4build_ros.files.inputs import InputFileError, load_json_file
            from comems4build_ros.report.reproduce_doc import ReportFileError, check_report

            try:
                earlier = check_report(load_json_file(earlier_json, "a reproduce.json"), str(earlier_json))
            except (InputFileError, ReportFileError) as exc:
                raise ConfigError(str(exc)) from None
        out.mkdir(parents=True, exist_ok=True)
        return evaluate(prepared, runs_dir, out, int(earlier.get("runs_made", 0)), float(earlier.get("wall_s", 0.0)),
                        runs_from=str(from_runs), figures=figures)
    runs_dir = out / "runs"
    made = run_into(prepared.tasks, runs_dir, jobs=jobs, progress=progress, show_progress=show_progress)
    return evaluate(prepared, runs_dir, out, made, time.perf_counter() - t0, figures=figures)
