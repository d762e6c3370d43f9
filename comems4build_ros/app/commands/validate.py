"""``comems4build validate``: the three EMS on the calibration and the validation set, the paper's checks on each."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from comems4build_ros.app.commands.options import add_executor_options, real


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``validate``."""
    parser.add_argument("--out", metavar="DIR", required=True,
                        help="output directory (validation.md, validation.html, validation.json, figures/, runs/)")
    parser.add_argument("--study", default=None, metavar="KEY[,KEY...]|all",
                        help="also run these ambiguities of config/reproduce.yaml on every case, each reading on "
                             "top of the defaults ('all': every one that changes only controller options or the "
                             "evaluation)")
    parser.add_argument("--cases", default=None, metavar="ID[,ID...]",
                        help="only these cases (ids as in docs/validation.md: paper-s57, muenchen-2015-16, "
                             "household-101, ...; default: all)")
    parser.add_argument("--ems", default=None, metavar="NAME[,NAME...]",
                        help="only these of the paper's EMS: mpc, fuzzy, rbc (default: all three; the checks that "
                             "need a missing EMS are reported as not run)")
    add_executor_options(parser)
    parser.add_argument("--weeks", type=real(1 / 168, 12), default=None, metavar="N",
                        help="run length in weeks, one hour (1/168) .. 12 (default 12; shorter runs are quick checks)")
    parser.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars (one per run)")
    parser.add_argument("--update-doc", default=None, metavar="MD",
                        help="also write the tables and figures between the validation markers of MD "
                             "(docs/validation.md)")
    parser.add_argument("--from-runs", default=None, metavar="DIR",
                        help="no runs: evaluate the run directories of an earlier validate --out DIR of the same "
                             "plan again (after a change to the evaluation)")


#: What ``validate`` writes into its output directory.
VALIDATE_FILES = ("runs", "figures", "validation.md", "validation.html", "validation.json")
#: What ``validate --from-runs`` writes (the documents and their figures, no runs).
DOCUMENT_FILES = ("figures", "validation.md", "validation.html", "validation.json")


def _names(text: str | None, option: str) -> list[str] | None:
    from comems4build_ros.app.cli import UsageError

    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError(f"{option} '{text}': no name given")
    if len(set(names)) != len(names):
        raise UsageError(f"{option} {text}: a name given twice")
    return names


def run(args: argparse.Namespace) -> int:
    """Run the validation and print the checks per subset and where the report is."""
    import time

    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import output_dir, study_executor
    from comems4build_ros.files.inputs import load_json_file
    from comems4build_ros.report.validation import CRITERIA, evaluate
    from comems4build_ros.study.reproduce import EMS
    from comems4build_ros.study.runner import missing_in, run_into
    from comems4build_ros.study.validate import plan

    if args.from_runs and (args.scheduler or args.resume):
        raise UsageError("--scheduler and --resume apply to runs; --from-runs makes none")
    if args.from_runs and not (Path(args.from_runs) / "runs").is_dir():
        raise UsageError(f"--from-runs {args.from_runs}: no runs/ directory (the --out of an earlier validate)")
    if args.update_doc:
        from comems4build_ros.files.inputs import check_markers
        from comems4build_ros.files.outputs import check_out_file, check_out_text
        from comems4build_ros.report.validation_doc import DOC_BEGIN, DOC_END

        check_out_file(check_out_text(args.update_doc, "--update-doc"), "--update-doc")
        check_markers(args.update_doc, DOC_BEGIN, DOC_END, "--update-doc")  # before the first run
    ems = _names(args.ems, "--ems") or list(EMS)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    p = plan(_names(args.study, "--study"), args.weeks, _names(args.cases, "--cases"), tuple(ems))
    writes = DOCUMENT_FILES if args.from_runs else VALIDATE_FILES
    output = output_dir(args, "validate", writes=writes, replaces=writes)
    output.check()
    if args.from_runs:
        runs_dir = Path(args.from_runs) / "runs"
        missing = missing_in(p.tasks, runs_dir)
        if missing:
            raise UsageError(f"--from-runs {args.from_runs}: no finished run for {', '.join(missing[:5])}"
                             f"{' ...' if len(missing) > 5 else ''} (this plan needs {len(p.tasks)} runs)")
        earlier: dict = {}
        if (Path(args.from_runs) / "validation.json").is_file():
            earlier = load_json_file(Path(args.from_runs) / "validation.json", "validation.json")
        with output:
            res = evaluate(p, runs_dir, output.stage, int(earlier.get("runs_made", 0)),
                           float(earlier.get("wall_s", 0.0)), figures=not args.no_figures,
                           runs_from=str(args.from_runs), load_at_start=earlier.get("load_at_start"),
                           runs_resumed=int(earlier.get("runs_resumed", 0)))
            output.commit()
    else:
        # the runs' executor; finished runs kept in OUT/.runstore (--resume takes them)
        with output, study_executor(args, args.out) as executor:
            planned = run_into(p.tasks, output.stage / "runs", jobs=args.jobs,
                                show_progress=False if args.no_progress else None)
            res = evaluate(p, output.stage / "runs", output.stage, planned - executor.resumed,
                           time.perf_counter() - t0, figures=not args.no_figures, load_at_start=load,
                           runs_resumed=executor.resumed)
            output.commit()  # runs/, figures and documents replace an earlier validation's whole
            executor.complete()
    out = output.path
    rep = res.report
    for key, (label, _) in CRITERIA.items():
        parts = []
        for s, d in rep["subsets"].items():
            c = d["criteria"][key]
            parts.append(f"{s} {c['held']}/{c['cases']}" if c["cases"] else f"{s} -")
        print(f"{label}: " + ", ".join(parts))
    resumed = f", {rep['runs_resumed']} more taken from {out / '.runstore'}" if rep.get("runs_resumed") else ""
    done = (f"runs of {args.from_runs} evaluated again" if args.from_runs else
            f"{rep['runs_made']} runs made{resumed} in {rep['wall_s']:.0f} s (load average "
            f"{rep['load_at_start']:.2f} at the start)")
    print(f"{len(rep['cases'])} cases; {done}; wrote {out / res.markdown.name}, {out / res.html.name}, "
          f"{out / res.json.name}")
    if args.update_doc:
        from comems4build_ros.report.validation_doc import update_doc

        print(f"updated {update_doc(args.update_doc, rep, out)}")
    return 0
