"""``comems4build bench <target>``: benchmarks that print figures (not timed tests)."""

from __future__ import annotations

import argparse
import importlib

#: bench target -> module under comems4build_ros.app.bench
TARGETS = {
    "plant": "plant",
    "ems": "ems",
    "mpc": "mpc",
    "ros": "ros",
    "cut": "cut",
    "study": "study",
    "year": "year",
    "cosim": "cosim",
    "coordinators": "coordinators",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """One sub-parser per available benchmark target."""
    sub = parser.add_subparsers(dest="target", metavar="TARGET", required=True)
    for name, module in TARGETS.items():
        try:
            mod = importlib.import_module(f"comems4build_ros.app.bench.{module}")
        except ModuleNotFoundError as exc:
            if exc.name != f"comems4build_ros.app.bench.{module}":
                raise
            continue
        p = sub.add_parser(name, help=(mod.__doc__ or name).strip().splitlines()[0])
        mod.add_arguments(p)
        p.set_defaults(_bench=mod.run)


def run(args: argparse.Namespace) -> int:
    """Run the chosen benchmark."""
    return int(args._bench(args) or 0)
