"""``comems4build export-fmu``: the paper's 4R3C building model as an FMI 2.0 co-simulation FMU."""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``export-fmu``."""
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="parameter file merged over config/plant.yaml (repeatable): the 4R3C of its section "
                             "building is exported")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter, e.g. --set building.g_s_m2=2 (repeatable)")
    parser.add_argument("--out", metavar="FILE.fmu", required=True,
                        help="the FMU to write; its variable map is written beside it as FILE.map.yaml")


def run(args: argparse.Namespace) -> int:
    """Build the FMU with pythonfmu and write its variable map."""
    from comems4build_ros.app.commands.options import UsageError, load_params
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.models.building_fmu import FMUError, export_rc_fmu
    from comems4build_ros.files.outputs import check_out_file

    params = load_params(args.config, parse_assignments(args.set, "--set"))
    if not str(args.out).endswith(".fmu"):
        raise UsageError(f"--out {args.out}: the FMU file name must end in .fmu")
    check_out_file(args.out)
    try:
        fmu, vmap = export_rc_fmu(params.building, args.out, params.simulation.t_air_init_c)
    except FMUError as exc:
        raise UsageError(str(exc)) from None
    print(f"wrote {fmu} (FMI 2.0 co-simulation, 4R3C of eq:state_update_bldgs) and its variable map {vmap}")
    print(f"run it with: comems4build simulate --building fmu:{fmu} --ems NAME --out DIR")
    return 0
