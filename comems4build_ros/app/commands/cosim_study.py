"""``comems4build cosim-study``: the paper's EMS on the 4R3C and on the EnergyPlus house, table and findings."""

from __future__ import annotations

import argparse

from comems4build_ros.app.commands.options import COUNT, WEEKS, add_forecast_option


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``cosim-study``."""
    parser.add_argument("--out", metavar="DIR", required=True,
                        help="study folder: rc/ and energyplus/ (runs, report and figures as compare writes them), "
                             "identified.yaml/.json, house.json, cosimulation.md")
    parser.add_argument("--identified", metavar="FILE.yaml", default=None,
                        help="an identified building file of comems4build identify (default: identify the house "
                             "into DIR/identified.yaml first)")
    add_forecast_option(parser)
    parser.add_argument("--weeks", type=WEEKS, default=None, metavar="N",
                        help="run length in weeks, one hour .. 30 years (default: the paper's 12; shorter for a "
                             "quick try)")
    parser.add_argument("--jobs", type=COUNT, default=None, metavar="N",
                        help="parallel runs in local processes, integer >= 1 (default: CPU count)")
    parser.add_argument("--doc", metavar="FILE.md", default=None,
                        help="also write the document here (e.g. docs/cosimulation.md)")
    parser.add_argument("--from-runs", action="store_true",
                        help="no runs: write the document again from the study already in --out (its runs, "
                             "identified.json and house.json)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")


def write_reports(out, plan: dict, walls: dict, weeks: float | None) -> None:
    """Each building's ``compare.json`` and the report and figures ``compare`` writes."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.report.build import build_report
    from comems4build_ros.report.runs import Manifest, RunSpec, write_manifest
    from comems4build_ros.study.cosim import BASE_ETA

    for building, tasks in plan.items():
        specs = [RunSpec(name=t.ems, ems=t.ems, eta_sys=BASE_ETA, info_level=str(ems_entry(t.ems).info_level),
                         overrides=dict(t.overrides)) for t in tasks]
        manifest = Manifest(scenario="default", weeks=weeks, via="inprocess", base_eta=BASE_ETA, runs=specs,
                            overrides={}, config=[], wall_s=dict(walls[building]))
        write_manifest(manifest, out / building)
        build_report(out / building)


#: What cosim-study writes into its --out (and replaces whole when it runs again).
STUDY_FILES = ("rc", "energyplus", "identified.yaml", "identified.json", "house.json", "walls.json", "figures",
               "cosimulation.md")
#: What ``--from-runs`` writes again (the document and its figure).
DOCUMENT_FILES = ("figures", "cosimulation.md")


def run(args: argparse.Namespace) -> int:
    """Identify (unless given), run the eight runs, build the reports, write the document.

    Everything goes through the output layer: ``--out`` is checked, locked and written all or
    nothing (``--from-runs`` rewrites only the document and its figure), ``--doc`` likewise.
    """
    import json
    import sys
    from pathlib import Path

    from comems4build_ros.app.commands.options import UsageError, load_params, output_dir
    from comems4build_ros.core.scenario import resolve_scenario

    out = Path(args.out)
    writes = DOCUMENT_FILES if args.from_runs else STUDY_FILES
    output = output_dir(args, "cosim-study", writes=writes, replaces=writes)
    output.check()
    if args.doc:  # a document of the repository, updated in place as reproduce --update-doc does
        from comems4build_ros.files.outputs import check_out_file, check_out_text

        check_out_file(check_out_text(args.doc, "--doc"), "--doc")
    if args.from_runs:
        missing = [p for p in (out / "identified.json", out / "house.json", out / "rc" / "compare.json",
                               out / "energyplus" / "compare.json") if not p.is_file()]
        if missing:
            raise UsageError(f"--from-runs: {missing[0]} not found (the --out of an earlier cosim-study)")
        with output:
            code = _document(args, out, output.stage, json.loads((out / "identified.json").read_text(encoding="utf-8")),
                             json.loads((out / "house.json").read_text(encoding="utf-8")))
            output.commit()
        return code
    params = load_params([])
    resolve_scenario("default", params, weeks=args.weeks)  # the run length, checked before anything runs
    say = lambda text: print(f"cosim-study: {text}", file=sys.stderr)  # noqa: E731
    with output:
        report, house = _study(args, output.stage, params, say)
        code = _document(args, output.stage, output.stage, report, house)
        output.commit()  # runs, reports, identified model, figures and document replace an earlier study's whole
    return code


def _study(args: argparse.Namespace, stage, params, say) -> tuple[dict, dict]:
    """Identify (or take ``--identified``), measure the house, run the study into ``stage``; the reports."""
    import json
    import shutil
    from pathlib import Path

    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.models.buildings import BuildingChoice
    from comems4build_ros.core.scenario import resolve_scenario
    from comems4build_ros.study.cosim import run_study
    from comems4build_ros.study.house import house_figures
    from comems4build_ros.study.identify import identify, write_parameter_file, write_report

    ident_yaml = stage / "identified.yaml"
    if args.identified:
        src = Path(args.identified)
        if not src.is_file() or not src.with_suffix(".json").is_file():
            raise UsageError(f"--identified {src}: needs the file and its report {src.with_suffix('.json')} "
                             "(both written by comems4build identify)")
        shutil.copy2(src, ident_yaml)
        shutil.copy2(src.with_suffix(".json"), ident_yaml.with_suffix(".json"))
        report = json.loads(ident_yaml.with_suffix(".json").read_text(encoding="utf-8"))
    else:
        say("identifying the house's 4R3C (training outside the 12 weeks)")
        held = simulate("thermostat", resolve_scenario("default", params), params,
                        building=BuildingChoice("energyplus")).timeseries
        report = identify(params, "energyplus", held_out_run=held, progress=say)
        write_parameter_file(ident_yaml, report.pop("_params"), report)
        write_report(ident_yaml.with_suffix(".json"), report)
    say("the house beside the 4R3C (steady states, cool-down, the winter weeks; the year's summer unless --weeks)")
    house = house_figures(params, weeks=args.weeks or 12.0, year=args.weeks is None, progress=say)
    (stage / "house.json").write_text(json.dumps(house, indent=1) + "\n", encoding="utf-8")
    say("running RBC, ComEMS4Build, MPC and the thermostat on the 4R3C and on the EnergyPlus house")
    plan, walls = run_study(stage, ident_yaml, args.forecast, args.weeks, args.jobs,
                            progress=False if args.no_progress else None)
    write_reports(stage, plan, walls, args.weeks)
    (stage / "walls.json").write_text(json.dumps(walls, indent=1) + "\n", encoding="utf-8")
    return report, house


def _document(args: argparse.Namespace, runs, stage, report: dict, house: dict) -> int:
    """Measure both buildings' folders in ``runs`` and write ``cosimulation.md`` and its figure into ``stage``
    (and ``--doc`` with the figure in ``figures/cosim/`` beside it)."""
    from comems4build_ros.report.cosim import building_result, comfort_figure, cosim_markdown

    results = {b: building_result(runs / b) for b in ("rc", "energyplus")}
    png = comfort_figure(results, stage / "figures" / "cosim_comfort")
    weeks = f" --weeks {args.weeks:g}" if args.weeks else ""
    fc = f" --forecast {args.forecast}" if args.forecast else ""
    commands = {"study": f"comems4build cosim-study --out DIR{weeks}{fc}" + (f" --doc {args.doc}" if args.doc
                                                                             else ""),
                "house": "comems4build house", "identify": "comems4build identify --out identified.yaml"}
    text = cosim_markdown(results, report, house, commands)
    (stage / "cosimulation.md").write_text(text, encoding="utf-8")
    if args.doc:
        _write_doc(args, text, png)
    for b, r in results.items():
        held_n = sum(v[0] == "held" for v in r.verdicts.values())
        print(f"{b}: {held_n} of {sum(v[0] != 'n/a' for v in r.verdicts.values())} evaluated findings held")
    print(f"wrote {args.out}/cosimulation.md" + (f" and {args.doc}" if args.doc else "")
          + f"; reports and figures in {args.out}/rc and {args.out}/energyplus")
    return 0


def _write_doc(args: argparse.Namespace, text: str, png) -> None:
    """``--doc`` and its figure under ``figures/cosim/`` beside it, each file written atomically."""
    from pathlib import Path

    from comems4build_ros.files.outputs import atomic_write, write_text_atomic

    write_text_atomic(Path(args.doc), text)
    figures = Path(args.doc).parent / "figures" / "cosim"
    figures.mkdir(parents=True, exist_ok=True)
    for f in png.parent.glob("cosim_comfort.*"):
        with atomic_write(figures / f.name, "wb", encoding=None) as dst:
            dst.write(f.read_bytes())
