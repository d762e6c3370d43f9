"""``comems4build identify``: the MPC's 4R3C fitted to a detailed building's response, as on a real house."""

from __future__ import annotations

import argparse

from comems4build_ros.app.commands.options import SEED, add_building_options

#: The 24-h open-loop RMSE of T_air on held-out weeks that the identified model should reach [K].
RMSE_TARGET_K = 1.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``identify``."""
    add_building_options(parser)
    parser.set_defaults(building="energyplus")
    parser.add_argument("--seed", type=SEED, default=1, metavar="N",
                        help="seed of the excitation (the validation window uses N + 1000; default 1)")
    parser.add_argument("--out", metavar="FILE.yaml", required=True,
                        help="parameter file with the identified building section (give it to the MPC with --config)")
    parser.add_argument("--report", metavar="FILE.json", default=None,
                        help="the fit and validation figures as JSON (default: FILE.json beside --out)")


def run(args: argparse.Namespace) -> int:
    """Collect the training and validation data, fit, validate on held-out weeks, write the files."""
    import sys
    from pathlib import Path

    from comems4build_ros.app.commands.options import UsageError, building_choice, load_params, output_file
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import resolve_scenario
    from comems4build_ros.study.identify import identify, write_parameter_file, write_report

    choice = building_choice(args)
    if choice.kind == "rc" and args.building != "rc":
        raise UsageError("--building: give the building to identify")
    out_file = output_file(args, "identify")  # refuses an empty or ambiguous --out first
    out = Path(args.out)
    report_path = Path(args.report) if args.report else out.with_suffix(".json")
    report_file = output_file(args, "identify", path=report_path, option="--report")
    out_file.check()
    report_file.check()
    params = load_params([])
    say = lambda text: print(f"identify: {text}", file=sys.stderr)  # noqa: E731
    say("the twelve evaluation weeks under the thermostat (held out)")
    held = simulate("thermostat", resolve_scenario("default", params), params, building=choice).timeseries
    report = identify(params, choice, seed=args.seed, held_out_run=held, progress=say)
    b = report.pop("_params")
    with out_file, report_file:  # both files, each all or nothing
        write_parameter_file(out_file.file, b, report)
        write_report(report_file.file, report)
        out_file.commit()
        report_file.commit()
    v, e = report["validation"], report["evaluation_weeks_thermostat"]
    print(f"building {choice.text}: fit RMSE {report['fit']['fit_rmse_k']:.3f} K over the training window "
          f"({report['train']['weeks']:g} weeks from {report['train']['start']})")
    print(f"24-h open-loop T_air prediction (Kalman state from measured T_air, true inputs): RMSE "
          f"{v['rmse_k']:.3f} K on the held-out week from {v['start']} ({v['predictions']} predictions), "
          f"{e['rmse_k']:.3f} K on the 12 evaluation weeks under the thermostat ({e['predictions']}); target "
          f"<= {RMSE_TARGET_K:g} K: {'met' if max(v['rmse_k'], e['rmse_k']) <= RMSE_TARGET_K else 'NOT met'}")
    print(f"identified heat loss coefficient {report['heat_loss_coefficient_w_per_k']:.1f} W/K; f_gains_air "
          f"{report['identified']['f_gains_air']:.2f}")
    print(f"wrote {out} and {report_path}")
    return 0
