"""``comems4build house``: the shipped EnergyPlus house's heat loss coefficient, design heat load and heating demand."""

from __future__ import annotations

import argparse
import json

from comems4build_ros.app.commands.options import WEEKS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``house``."""
    parser.add_argument("--weeks", type=WEEKS, default=12.0, metavar="N",
                        help="weeks of the thermostat run from 2022-12-01, one hour .. 30 years (default: the "
                             "paper's 12)")
    parser.add_argument("--json", metavar="FILE", default=None, help="also write the figures as JSON")


def run(args: argparse.Namespace) -> int:
    """Print the figures beside the typology's and the 4R3C's."""
    from comems4build_ros.app.commands.options import load_params, output_file
    from comems4build_ros.study.house import H_TOLERANCE, house_figures

    json_file = output_file(args, "house", path=args.json, option="--json") if args.json else None
    if json_file is not None:
        json_file.check()
    params = load_params([])
    f = house_figures(params, None, args.weeks)
    ok = abs(f["h_ratio_to_rc"] - 1.0) <= H_TOLERANCE
    lo, hi = f["heating_kwh_typology_range"]
    lines = [
        f"house: TABULA DE.N.SFH.09.Gen, advanced refurbishment; heated floor area {f['heated_floor_m2']:.1f} m2",
        f"heat loss coefficient, typology method: H = {f['h_typology_w_per_k']:.1f} W/K "
        f"(H_tr = {f['h_tr_typology_w_per_k']:.1f} W/K; TABULA's H_tr of the variant = {f['h_tr_tabula_w_per_k']:.0f} "
        f"W/K; H_ve = {f['h_ve_typology_w_per_k']:.1f} W/K)",
        f"heat loss coefficient, EnergyPlus steady states at -10 and +10 degC: H = {f['h_energyplus_w_per_k']:.1f} W/K "
        f"to the outdoor air; default 4R3C: {f['h_rc_w_per_k']:.1f} W/K; ratio {f['h_ratio_to_rc']:.3f} "
        f"({'within' if ok else 'OUTSIDE'} +-{H_TOLERANCE:.0%})",
        f"design heat load at {f['design_t_amb_c']:g} degC, 20 degC inside: EnergyPlus "
        f"{f['design_load_energyplus_w']:.0f} W; typology H x dT = {f['design_load_typology_w']:.0f} W",
        f"space heating over {f['heating_weeks']:g} weeks with the thermostat: {f['heating_kwh_thermostat']:.0f} kWh; "
        f"typology quasi-steady range {lo:.0f} .. {hi:.0f} kWh "
        f"({'within' if lo <= f['heating_kwh_thermostat'] <= hi else 'OUTSIDE'}); discomfort median "
        f"{f['discomfort_kh_week_median']:.2f} Kh/week; heat balance max rel. error {f['heat_balance_max_rel']:.1e}",
    ]
    print("\n".join(lines))
    if json_file is not None:
        with json_file:
            json_file.file.write_text(json.dumps(f, indent=1) + "\n", encoding="utf-8")
            json_file.commit()
    return 0
