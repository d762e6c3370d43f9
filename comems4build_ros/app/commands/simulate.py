"""``comems4build simulate``: one EMS in-process over a scenario."""

from __future__ import annotations

import argparse
import json
import sys

from comems4build_ros.app.commands.options import (
    add_building_options,
    add_forecast_option,
    add_scenario_options,
    ems_help,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``simulate``."""
    parser.add_argument("--ems", metavar="NAME", required=True, help=ems_help())
    add_scenario_options(parser)
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
    add_forecast_option(parser)
    add_building_options(parser)
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def parse_assignments(items: list[str], what: str) -> dict[str, object]:
    """``["a.b=1.5", "c=x"]`` -> ``{"a.b": 1.5, "c": "x"}`` (values parsed as YAML scalars;
    :func:`comems4build_ros.core.config.parse_assignments`, a bad item is a usage error)."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.core.config import ConfigError
    from comems4build_ros.core.config import parse_assignments as parse

    if any(not str(item).strip() for item in items):
        raise UsageError(f"{what} '' is not KEY=VALUE")
    try:
        return parse(items, what)
    except ConfigError as exc:
        raise UsageError(str(exc)) from None


def run(args: argparse.Namespace) -> int:
    """Run the simulation and write timeseries.csv, weekly.csv and summary.json."""
    from comems4build_ros.app.commands.options import add_scenario_config

    add_scenario_config(args)
    from comems4build_ros.app.commands.options import (
        UsageError,
        building_choice,
        check_building_covers,
        ems_controller,
        load_params,
        output_dir,
        scenario_of,
    )
    from comems4build_ros.core.ems import UnknownEMSError, controller_class
    from comems4build_ros.core.loop import RUN_FILES, load_forecast_settings, simulate, write_run
    from comems4build_ros.run.progress import ProgressBar

    try:
        controller_class(args.ems)
    except UnknownEMSError as exc:
        raise UsageError(str(exc)) from None
    params = load_params(args.config, parse_assignments(args.set, "--set"))
    controller = ems_controller(args.ems, params, args.ems_option)
    building = building_choice(args)
    output = output_dir(args, "simulate", writes=RUN_FILES, replaces=RUN_FILES)
    output.check()
    scenario = scenario_of(args, params)
    check_building_covers(building, scenario, params)
    with output, ProgressBar(f"simulate {args.ems}", unit="h", enable=False if args.no_progress else None) as bar:
        result = simulate(
            controller, scenario, params,
            progress=bar,
            forecast=load_forecast_settings(**({"mode": args.forecast} if args.forecast else {})),
            building=building,
        )
        write_run(result, output.stage)
    out = output.path
    s = result.summary
    keys = (
        "weeks", "cost_eur_week_median", "discomfort_kh_week_median", "discomfort_weeks_nonzero",
        "buy_kwh_week_median", "sell_kwh_week_median", "loh_end", "max_balance_residual_w", "wall_s",
    )
    if "building" in s:
        keys = (*keys, "building", "building_heat_balance_max_rel")
    print(json.dumps({k: s[k] for k in keys if k in s}, indent=1))
    print(f"wrote {out / 'timeseries.csv'}, {out / 'weekly.csv'}, {out / 'summary.json'}")
    return warn_run(s, "simulate")


#: Words of the fallback causes of ``summary.json``'s ``fallback_causes`` in the warning.
FALLBACK_CAUSE_WORDS = {
    "late_command": "because no valid command of the EMS came in time",
    "watchdog": "because the watchdog found a measurement missing, stale or out of range",
    "user_switch": "because the user switched the EMS off or the fallback on",
}


def warn_run(summary: dict, command: str) -> int:
    """Warnings at the end of a run: fallback steps, unmet hot-water demand, a synthetic extension.

    Returns
    -------
    int
        The exit code the run earns: 1 when the EMS decided no step at all (every step ran on
        the safe fallback action: the results are the fallback's, no EMS's; said as an error),
        else 0. Steps the user put on the fallback (a building's forced-fallback switch) are
        the user's choice, not a failure: a run whose every step the user switched is exit 0.
    """
    n, steps = summary.get("fallback_steps") or 0, summary.get("steps") or 0
    unmet = summary.get("dhw_unmet_steps") or 0
    if unmet:
        print(f"comems4build {command}: warning: the hot-water demand was not met in {unmet} of {steps} steps "
              f"({summary.get('dhw_unmet_kwh', 0.0):.3g} kWh in all, the first from {summary.get('dhw_unmet_first')}): "
              "the tank was at V_DHW,min; see dhw_unmet_kwh in summary.json and q_dhw_unmet_w per step",
              file=sys.stderr)
    if n:
        ems_n = summary.get("ems_fallback_steps") or 0
        causes = summary.get("fallback_causes") or {"late_command": n - ems_n}
        words = [f"{ems_n} because the EMS found no solution or failed"] if ems_n else []
        words += [f"{c} {FALLBACK_CAUSE_WORDS.get(cause, cause)}" for cause, c in causes.items() if c]
        print(f"comems4build {command}: warning: {n} of {steps} steps ran on the safe fallback action "
              f"({', '.join(words)}); see fallback_steps and fallback_causes in summary.json", file=sys.stderr)
    mqtt = summary.get("mqtt") or {}
    if mqtt.get("foreign_messages"):
        print(f"comems4build {command}: warning: {mqtt['foreign_messages']} MQTT message(s) from someone else than "
              "the run's house or bridge were not applied (no valid authentication code, or of another run); "
              "see 'foreign_mqtt' on plant/events", file=sys.stderr)
    if mqtt.get("setpoints_held"):
        print(f"comems4build {command}: warning: {mqtt['setpoints_held']} step(s) ran on set-points the house "
              "held from an earlier step (their own did not reach it in time: a broker outage); see "
              "'setpoints_held' on plant/events", file=sys.stderr)
    ext = summary.get("scenario_extended")
    if ext:
        print(f"comems4build {command}: note: the scenario was extended with {ext['rows']} generated hours from "
              f"{ext['from']} ({ext['method']}, seed {ext['seed']})", file=sys.stderr)
    chosen = (summary.get("fallback_causes") or {}).get("user_switch") or 0  # the user's own choice
    if steps and n >= steps and chosen < n:
        print(f"comems4build {command}: error: the EMS decided none of the {steps} steps (every one ran on the safe "
              "fallback action): the results written are the fallback's, not the EMS's; see fallback_causes in "
              "summary.json (an MPC: its time_limit_s, solver and options)", file=sys.stderr)
        return 1
    return 0
