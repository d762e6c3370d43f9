"""``comems4build`` command line.

Each subcommand lives in ``comems4build_ros/app/commands/<module>.py`` exposing
``add_arguments(parser)`` and ``run(args) -> int``. Only the chosen subcommand's module is
imported and its options built (:func:`main`), and heavy imports happen inside ``run``, so
``comems4build --help`` imports no command module and no numerical library. Exit codes:
0 success, 1 failure of the job, 2 invalid usage or input (unknown EMS, unreadable file,
invalid option, an output that cannot be written).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Collection, Sequence

#: What ``comems4build --help`` says above the command list (plain text: argparse prints it as is).
DESCRIPTION = ("ComEMS4Build energy management: simulations in-process and over ROS 2, studies, reports and "
               "benchmarks.")
#: What it says below the list.
EPILOG = "'comems4build COMMAND --help' explains a command's options. Exit codes: 0 done, 1 the job failed, " \
         "2 invalid usage or input, 130 interrupted."

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
    "compare": ("compare", "RBC, fuzzy and MPC on one scenario; DIR/report.md, DIR/report.html (contents, figures "
                           "linked to their vector versions) and the paper-style figures as PDF, SVG and 300 dpi PNG; "
                           "a progress bar per run on a terminal"),
    "sweep": ("sweep", "sensitivity grid on local processes or a Dask cluster; one table and one plot per KPI "
                       "(PDF, SVG, PNG)"),
    "reproduce": ("reproduce", "the paper's table beside ours, its findings and the interpretation study"),
    "export-fmu": ("export_fmu", "the paper's 4R3C building model as an FMI 2.0 co-simulation FMU (pythonfmu) with its "
                                 "variable map, for --building fmu:FILE.fmu"),
    "house": ("house", "the EnergyPlus house against its typology: heat loss coefficient (typology method and "
                       "EnergyPlus steady states), design heat load, heating demand with the thermostat"),
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


class UsageError(Exception):
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
    from comems4build_ros.core.config import ConfigError  # after parsing: --help imports no core module

    try:
        return int(args._run(args) or 0)
    except (UsageError, ConfigError, FileNotFoundError, ValueError) as exc:
        print(f"comems4build {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # an output that cannot be written (full disk, read-only, removed directory)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"comems4build {args.command}: error: {where}{exc.strerror or exc}; nothing partial was kept",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"comems4build {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    # ``python -m comems4build_ros.app.cli``: run the package's module, not this ``__main__`` copy,
    # whose exception classes (UsageError, ...) are not the ones the commands raise.
    from comems4build_ros.app.cli import main as _main

    sys.exit(_main())
