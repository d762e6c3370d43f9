"""``comems4build validate``: the three EMS on the calibration and the validation set, the paper's checks on each."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from comems4build_ros.app.commands.options import add_forecast_option, add_pool_options, real


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``validate``."""
    parser.add_argument("--out", metavar="DIR", required=True,
                        help="output directory (validation.md, validation.html, validation.json, figures/, runs/; "
                             "choice.json of the choosing step)")
    step = parser.add_mutually_exclusive_group()
    step.add_argument("--choose", action="store_true",
                      help="the choosing step: run and read only the calibration and development cases, and write "
                           "which reading of each studied ambiguity the rule chooses (choice.json, with the runs and "
                           "figures it was chosen from); held-out cases are refused")
    step.add_argument("--judge", action="store_true",
                      help="the judging step: run only the held-out cases, recording the commit and content hashes "
                           "of the defaults they judge")
    parser.add_argument("--choice", default=None, metavar="FILE",
                        help="with --judge: the choice.json of the choosing step; the report says whether the "
                             "shipped defaults are its choice and were chosen on the same code and parameters")
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
    add_pool_options(parser)
    parser.add_argument("--weeks", type=real(1 / 168, 12), default=None, metavar="N",
                        help="run length in weeks, one hour (1/168) .. 12 (default 12; shorter runs are quick checks)")
    add_forecast_option(parser)
    parser.add_argument("--no-figures", action="store_true", help="do not draw the figures")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars (one per run)")
    parser.add_argument("--update-doc", action="append", default=None, metavar="FILE",
                        help="also write the validation into FILE (again for more files): a Markdown file gets the "
                             "tables and figures between its validation markers and the report stored beside it "
                             "(results/validation.json); every file its quoted figures (<!--fig KEY-->...) filled "
                             "(docs/validation.md, config/reproduce.yaml); needs both steps (no --choose or --judge)")
    parser.add_argument("--from-runs", default=None, metavar="DIR",
                        help="no runs: evaluate the run directories of an earlier validate --out DIR of the same "
                             "plan again (after a change to the evaluation)")


#: What ``validate --from-runs`` writes (the documents and their figures, no runs).
DOCUMENT_FILES = ("figures", "validation.md", "validation.html", "validation.json", "choice.json")
#: What ``validate`` writes into its output directory.
VALIDATE_FILES = ("runs", *DOCUMENT_FILES)


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
    from comems4build_ros.app.commands.options import output_dir, study_pool
    from comems4build_ros.files.inputs import load_json_file
    from comems4build_ros.report.validation import CRITERIA, evaluate
    from comems4build_ros.study.identity import defaults_identity
    from comems4build_ros.study.reproduce import EMS
    from comems4build_ros.study.runner import missing_in, run_into
    from comems4build_ros.study.validate import plan

    if args.from_runs and (args.scheduler or args.resume):
        raise UsageError("--scheduler and --resume apply to runs; --from-runs makes none")
    step = "choose" if args.choose else "judge" if args.judge else "all"
    if args.choice and not args.judge:
        raise UsageError("--choice is read by the judging step only (--judge)")
    if args.update_doc and step != "all":
        raise UsageError(f"--update-doc needs both steps' cases; --{step} runs only some")
    choice = None
    if args.choice:
        choice = load_json_file(Path(args.choice), "--choice")
        if not isinstance(choice, dict) or "ambiguities" not in choice or "defaults" not in choice:
            raise UsageError(f"--choice {args.choice}: not a choice.json of validate --choose")
    if args.from_runs and not (Path(args.from_runs) / "runs").is_dir():
        raise UsageError(f"--from-runs {args.from_runs}: no runs/ directory (the --out of an earlier validate)")
    for doc in args.update_doc or ():
        from comems4build_ros.files.inputs import check_markers, read_text
        from comems4build_ros.files.outputs import check_out_file, check_out_text
        from comems4build_ros.report.validation_doc import DOC_BEGIN, DOC_END

        check_out_file(check_out_text(doc, "--update-doc"), "--update-doc")
        if Path(doc).suffix == ".md":  # a Markdown file gets the generated part: its markers before the first run
            check_markers(doc, DOC_BEGIN, DOC_END, "--update-doc")
        else:  # any other file only its quoted figures: readable text before the first run
            read_text(doc, "the document of --update-doc")
    ems = _names(args.ems, "--ems") or list(EMS)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    p = plan(_names(args.study, "--study"), args.weeks, _names(args.cases, "--cases"), tuple(ems), step=step,
             forecast=args.forecast)
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
                           runs_resumed=int(earlier.get("runs_resumed", 0)),
                           runs_identity=(earlier.get("defaults") or {}).get("runs"), choice=choice)
            output.commit()
    else:
        # the runs' pool; finished runs kept in OUT/.runstore (--resume takes them)
        identity = defaults_identity()
        with output, study_pool(args, args.out) as pool:
            planned = run_into(p.tasks, output.stage / "runs", jobs=args.jobs,
                                show_progress=False if args.no_progress else None)
            res = evaluate(p, output.stage / "runs", output.stage, planned - pool.resumed,
                           time.perf_counter() - t0, figures=not args.no_figures, load_at_start=load,
                           runs_resumed=pool.resumed, runs_identity=identity, choice=choice)
            output.commit()  # runs/, figures and documents replace an earlier validation's whole
            pool.complete()
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
    for amb, a in (rep.get("choice") or {}).get("ambiguities", {}).items():
        print(f"choice {amb} ({a['decided_by']}): {a['chosen']}"
              + ("" if a["agrees"] else f" -- the shipped default is {a['shipped']}"))
    judged = rep.get("judged")
    if judged and judged.get("choice"):
        c = judged["choice"]
        print("judged: the choice was made on " + ("the same" if c["same_defaults"] else "other")
              + " code and parameters" + ("" if not c["differ"] else "; shipped and chosen differ for "
                                          + ", ".join(c["differ"])))
    print(f"{len(rep['cases'])} cases; {done}; wrote {out / res.markdown.name}, {out / res.html.name}, "
          f"{out / res.json.name}" + (f", {out / 'choice.json'}" if "choice" in rep else ""))
    stored = load_json_file(out / res.json.name, "validation.json") if args.update_doc else None
    for doc in args.update_doc or ():
        from comems4build_ros.report.validation_doc import update_doc

        try:
            print(f"updated {update_doc(doc, stored, out)}")
        except ValueError as err:
            raise UsageError(f"--update-doc {doc}: {err}") from None
    return 0
