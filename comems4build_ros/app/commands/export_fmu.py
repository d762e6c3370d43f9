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
    from pathlib import Path

    from comems4build_ros.app.commands.options import UsageError, load_params, output_dir
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.models.building_fmu import FMUError, export_rc_fmu

    params = load_params(args.config, parse_assignments(args.set, "--set"))
    from comems4build_ros.files.outputs import check_out_text

    check_out_text(args.out, "--out")  # an empty or ambiguous --out first
    if not str(args.out).endswith(".fmu"):
        raise UsageError(f"--out {args.out}: the FMU file name must end in .fmu")
    target = Path(args.out)
    names = (target.name, target.with_suffix(".map.yaml").name)  # the FMU and its variable map beside it
    output = output_dir(args, "export-fmu", writes=names, replaces=(), path=target.parent)
    output.lock_name = f".{target.name}.comems4build.lock"  # other files of the folder are not this command's
    output.check()
    with output:
        try:
            export_rc_fmu(params.building, output.stage / target.name, params.simulation.t_air_init_c)
        except FMUError as exc:
            raise UsageError(str(exc)) from None
        output.commit()
    fmu, vmap = target.parent / names[0], target.parent / names[1]
    print(f"wrote {fmu} (FMI 2.0 co-simulation, 4R3C of eq:state_update_bldgs) and its variable map {vmap}")
    print(f"run it with: comems4build simulate --building fmu:{fmu} --ems NAME --out DIR")
    return 0
