"""``comems4build house``: the shipped EnergyPlus house beside the paper's 4R3C, line by line with tolerances."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from comems4build_ros.app.commands.options import WEEKS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``house``."""
    parser.add_argument("--weeks", type=WEEKS, default=12.0, metavar="N",
                        help="weeks of the thermostat run from 2022-12-01, one hour .. 30 years (default: the "
                             "paper's 12)")
    parser.add_argument("--json", metavar="FILE", default=None, help="also write the figures as JSON")


def _num(x: Any) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "-"
    if not math.isfinite(v):
        return "-"
    return f"{v:.0f}" if abs(v) >= 100 else f"{v:.2f}"


def table_text(f: dict[str, Any]) -> str:
    """The side-by-side table of :func:`~comems4build_ros.study.house.house_figures` as text."""
    head = (f"house: the EnergyPlus house (TABULA DE.N.SFH.09.Gen, advanced refurbishment, "
            f"{f['heated_floor_m2']:.1f} m2) beside the paper's 4R3C (config/plant.yaml, section building)")
    width = max(len(line["name"]) for line in f["lines"])
    rows = [head, f"{'':{width}}  {'unit':6} {'EnergyPlus':>10} {'4R3C':>10}  {'tolerance':18} result"]
    notes = []
    for i, line in enumerate(f["lines"], start=1):
        result = {True: "pass", False: "FAIL", None: "-"}[line["pass"]]
        rows.append(f"{line['name']:{width}}  {line['unit']:6} {_num(line['energyplus']):>10} {_num(line['rc']):>10}  "
                    f"{line['tolerance']:18} {result}")
        if line["note"]:
            notes.append(f"  [{i}] {line['name']}: {line['note']}")
    rows.append("notes:")
    rows.extend(notes)
    rows.append(f"typology (TABULA method): H_tr = {f['h_tr_typology_w_per_k']:.1f} W/K (TABULA's H_tr of the variant "
                f"{f['h_tr_tabula_w_per_k']:.0f} W/K), H_ve = {f['h_ve_typology_w_per_k']:.1f} W/K; design heat load "
                f"at {f['design_t_amb_c']:g} degC, 20 degC inside: EnergyPlus {f['design_load_energyplus_w']:.0f} W, "
                f"typology H x dT {f['design_load_typology_w']:.0f} W; EnergyPlus received the heat it was given to "
                f"{f['heat_balance_max_rel']:.1e} (largest relative difference of a winter hour)")
    failed = [line["name"] for line in f["lines"] if line["pass"] is False]
    rows.append("all lines within their tolerances" if not failed else
                f"{len(failed)} line(s) outside their tolerance: {'; '.join(failed)}")
    return "\n".join(rows)


def run(args: argparse.Namespace) -> int:
    """Measure both models and print them side by side (exit 0 also when a line fails: it is a finding)."""
    from comems4build_ros.app.commands.options import load_params, output_file
    from comems4build_ros.study.house import house_figures

    json_file = output_file(args, "house", path=args.json, option="--json") if args.json else None
    if json_file is not None:
        json_file.check()
    params = load_params([])
    f = house_figures(params, None, args.weeks, progress=lambda text: print(f"house: {text}", file=sys.stderr))
    print(table_text(f))
    if json_file is not None:
        with json_file:
            json_file.file.write_text(json.dumps(f, indent=1) + "\n", encoding="utf-8")
            json_file.commit()
    return 0
