"""``comems4build simulate``: one EMS in-process over a scenario."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``simulate``."""
    parser.add_argument("--ems", required=True, help="EMS name: thermostat, rbc, fuzzy, mpc, mpc-qp")
    parser.add_argument("--scenario", default="default", help="'default' (embedded) or a scenario CSV file")
    parser.add_argument("--start", default=None, help="first step of the window (ISO date/time), CSV only")
    parser.add_argument("--weeks", type=float, default=None, help="run length in weeks (default: 12 / whole CSV)")
    parser.add_argument(
        "--config", action="append", default=[], metavar="FILE",
        help="parameter file merged over config/plant.yaml (repeatable)",
    )
    parser.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="override one plant parameter, e.g. --set battery.e_max_kwh=10 (repeatable)",
    )
    parser.add_argument("--ems-option", action="append", default=[], metavar="KEY=VALUE",
                        help="option passed to the EMS, e.g. --ems-option solver=CBC (repeatable)")
    parser.add_argument("--forecast", choices=("perfect", "imperfect"), default=None,
                        help="forecasts given to the MPC (default: config/forecast.yaml, perfect)")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def parse_assignments(items: list[str], what: str) -> dict[str, object]:
    """``["a.b=1.5", "c=x"]`` -> ``{"a.b": 1.5, "c": "x"}`` (values parsed as YAML scalars)."""
    import yaml

    from ..cli import UsageError

    out: dict[str, object] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"{what} '{item}' is not KEY=VALUE")
        out[key.strip()] = yaml.safe_load(value)
    return out


def run(args: argparse.Namespace) -> int:
    """Run the simulation and write timeseries.csv, weekly.csv and summary.json."""
    from ..cli import UsageError
    from ..config import load_plant_params
    from ..ems import UnknownEMSError, controller_class
    from ..scenario import resolve_scenario
    from ..sim import load_forecast_settings, simulate, write_run

    for path in args.config:
        if not Path(path).is_file():
            raise UsageError(f"--config {path}: no such file")
    params = load_plant_params(args.config, parse_assignments(args.set, "--set"))
    try:
        controller_class(args.ems)
    except UnknownEMSError as exc:
        raise UsageError(str(exc)) from None
    scenario = resolve_scenario(args.scenario, params, start=args.start, weeks=args.weeks)
    result = simulate(
        args.ems, scenario, params,
        ems_options=parse_assignments(args.ems_option, "--ems-option"),
        progress=not args.no_progress and sys.stderr.isatty(),
        forecast=load_forecast_settings(**({"mode": args.forecast} if args.forecast else {})),
    )
    out = write_run(result, args.out)
    s = result.summary
    keys = (
        "weeks", "cost_eur_week_median", "discomfort_kh_week_median", "discomfort_weeks_nonzero",
        "buy_kwh_week_median", "sell_kwh_week_median", "loh_end", "max_balance_residual_w", "wall_s",
    )
    print(json.dumps({k: s[k] for k in keys}, indent=1))
    print(f"wrote {out / 'timeseries.csv'}, {out / 'weekly.csv'}, {out / 'summary.json'}")
    return 0
