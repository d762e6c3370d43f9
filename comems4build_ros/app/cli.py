"""``comems4build`` command line.

Each subcommand lives in ``comems4build_ros/app/commands/<module>.py`` exposing
``add_arguments(parser)`` and ``run(args) -> int``. Only the chosen subcommand's module is
imported and its options built (:func:`main`), and heavy imports happen inside ``run``, so
``comems4build --help`` imports no command module and no numerical library. Exit codes:
0 success, 1 failure of the job, 2 invalid usage or input (an error of the input checks,
:class:`~comems4build_ros.files.errors.InputError`: unknown EMS, unreadable file, invalid
option; or a file the operating system refuses, such as an output on a full disk), 70
(``EX_SOFTWARE``) an internal error: any other exception is a defect of the program, never
reported as the user's input (:func:`internal_error`).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Collection, Sequence

from comems4build_ros.files.errors import InputError

#: What ``comems4build --help`` says above the command list (plain text: argparse prints it as is).
DESCRIPTION = ("ComEMS4Build energy management: simulations in-process and over ROS 2, studies, reports and "
               "benchmarks.")
#: What it says below the list.
EPILOG = "'comems4build COMMAND --help' explains a command's options. Exit codes: 0 done, 1 the job failed, " \
         "2 invalid usage or input, 70 internal error (a defect: report it with the file named), 130 interrupted."
#: Exit code of an internal error (``EX_SOFTWARE`` of sysexits.h).
EX_SOFTWARE = 70

#: subcommand -> (module under comems4build_ros.app.commands, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("simulate", "one EMS in-process over a scenario; writes DIR/timeseries.csv (every state, command "
                             "and flow per step), DIR/weekly.csv (one row per week, a partial week marked) and "
                             "DIR/summary.json"),
    "bench": ("bench", "benchmarks that print figures: plant, ems, mpc, ros, cut, study, year, cosim"),
    "data": ("data", "build scenario CSVs from real sources (aWATTar, DWD, DHWCalc, load CSV)"),
    "fuzzy-surface": ("fuzzy_surface", "draw the input-output maps of the three fuzzy controllers (fig:FLC_3D) as "
                                       "PDF, SVG and PNG"),
    "launch": ("launch", "the ROS 2 node set (plant_sim, feed, EMS, recorder) as separate processes over DDS on an "
                         "isolated domain; writes DIR/bag/ (MCAP), DIR/weekly.csv and DIR/summary.json from the bag"),
    "evaluate": ("evaluate", "weekly KPIs and summary from any recorded bag (a damaged bag is salvaged and marked "
                             "incomplete)"),
    "compare": ("compare", "RBC, fuzzy and MPC on one scenario (or, with --community FILE, the coordinators on a "
                           "community of houses sharing one H2 hub); DIR/report.md, DIR/report.html (contents, figures "
                           "linked to their vector versions) and the paper-style figures as PDF, SVG and 300 dpi PNG; "
                           "a progress bar per run on a terminal"),
    "sweep": ("sweep", "sensitivity grid on local processes or a Dask cluster; one table and one plot per KPI "
                       "(PDF, SVG, PNG)"),
    "reproduce": ("reproduce", "the paper's table beside ours, its findings and the interpretation study"),
    "export-fmu": ("export_fmu", "the paper's 4R3C building model as an FMI 2.0 co-simulation FMU (pythonfmu) with its "
                                 "variable map, for --building fmu:FILE.fmu"),
    "house": ("house", "the EnergyPlus house and the 4R3C side by side, measured the same way: heat loss, internal "
                       "gains, effective heat capacity, solar aperture, winter heat demand, summer overheating "
                       "(DIN 4108-2), each with its tolerance; the typology's figures"),
    "identify": ("identify", "the MPC's 4R3C fitted to a detailed building's response under a documented excitation "
                             "(outside the evaluation weeks); its 24-h open-loop T_air error on held-out weeks; "
                             "writes the parameter file the MPC reads"),
    "cosim-study": ("cosim_study", "RBC, ComEMS4Build, MPC and the thermostat on the 4R3C and on the EnergyPlus "
                                   "house (MPC on an identified model): the paper's table and findings on both, "
                                   "reports and figures as compare, and docs/cosimulation.md"),
    "validate": ("validate", "the three EMS on the calibration set and on cases the defaults were not chosen on "
                             "(other winters, stations and households): the share of cases where each of the "
                             "paper's findings holds, cost ratios, H2 left, weeks with discomfort"),
    "size": ("size", "sizing study over the year: a grid or sampled design of PV, battery, electrolyser, FC and "
                     "H2 store sizes per EMS; annual cost (energy, annuities, O&M, wear), self-sufficiency, whether "
                     "the seasonal cycle closes, the Pareto front; table, figure and report"),
}


class UsageError(InputError):
    """Invalid input or option; reported with exit code 2."""


def build_parser(commands: Collection[str] | None = None) -> argparse.ArgumentParser:
    """Parser of ``comems4build`` with every subcommand.

    Parameters
    ----------
    commands
        The subcommands whose module is imported and whose options are added; the others are
        listed with their one-line help only (enough for ``comems4build --help``). ``None``
        (default): every subcommand, as the README's command table needs.

    Returns
    -------
    argparse.ArgumentParser
        The top-level parser; a built subcommand's parser carries its ``run`` as ``_run``.
    """
    parser = argparse.ArgumentParser(prog="comems4build", description=DESCRIPTION, epilog=EPILOG)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        if commands is None or name in commands:
            mod = importlib.import_module(f"comems4build_ros.app.commands.{module}")
            mod.add_arguments(p)
            p.set_defaults(_run=mod.run)
    return parser


def chosen_command(argv: Sequence[str]) -> list[str]:
    """The subcommand ``argv`` names (its first word, as the top-level parser has no option but
    ``--help``), as a list of at most one name for :func:`build_parser`."""
    return [argv[0]] if argv and argv[0] in COMMANDS else []


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``comems4build``; returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(chosen_command(argv))
    except KeyboardInterrupt:  # Ctrl-C while the command is imported: nothing was started
        print("comems4build: interrupted", file=sys.stderr)
        return 130
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except InputError as exc:  # the input checks' errors, and only these, are the user's
        print(f"comems4build {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file the operating system refuses (full disk, read-only, removed directory)
        if exc.errno is None:  # an OSError raised by the program itself, not by the system: a defect
            return internal_error(args.command, argv, exc, getattr(args, "out", None))
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"comems4build {args.command}: error: {where}{exc.strerror or exc}; nothing partial was kept",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"comems4build {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 (the point: whatever else is raised is a defect, named as one)
        return internal_error(args.command, argv, exc, getattr(args, "out", None))


def internal_error(command: str, argv: Sequence[str], exc: BaseException, out: object = None) -> int:
    """Report a defect: one line on stderr, the traceback in a file; returns :data:`EX_SOFTWARE`.

    The file is written in the command's output folder ``out`` when it is one (under a name
    the output layer never counts as a result), else in the temporary folder
    (:func:`comems4build_ros.files.outputs.write_internal_report`); it holds the command line,
    the package version and the traceback.
    """
    import platform
    import traceback

    from comems4build_ros.files.outputs import write_internal_report

    try:
        from importlib.metadata import version

        release = version("comems4build_ros")
    except Exception:  # noqa: BLE001 (a source tree without metadata)
        release = "unknown"
    text = (f"comems4build {' '.join(str(a) for a in argv)}\ncomems4build_ros {release}, Python "
            f"{platform.python_version()}, {platform.platform()}\n\n"
            + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    try:
        report: object = write_internal_report(None if out is None else str(out), text)
    except OSError as err:  # no file could take it: the traceback goes to stderr after the line
        report = f"the traceback below (no file could be written: {err})"
        text_after = text
    else:
        text_after = ""
    first = (str(exc).strip().splitlines() or [""])[0]
    what = f"{type(exc).__name__}: {first}" if first else type(exc).__name__
    print(f"comems4build {command}: internal error: {what}, report with {report}", file=sys.stderr)
    if text_after:
        print(text_after, file=sys.stderr, end="")
    return EX_SOFTWARE


if __name__ == "__main__":
    # ``python -m comems4build_ros.app.cli``: run the package's module, not this ``__main__`` copy,
    # whose exception classes (UsageError, ...) are not the ones the commands raise.
    from comems4build_ros.app.cli import main as _main

    sys.exit(_main())
