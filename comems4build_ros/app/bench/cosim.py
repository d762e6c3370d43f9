"""Co-simulation speed: ComEMS4Build and the MPC on the EnergyPlus house, and the FMU path's overhead.

``comems4build bench cosim`` times, in-process on the default scenario (the paper's twelve
weeks unless ``--weeks``), with the load average before and after:

1. ComEMS4Build on the EnergyPlus house (``--building energyplus``); target under 60 s;
2. the MILP MPC on the EnergyPlus house, planning with an identified model (``--identified
   FILE`` from ``comems4build identify``; skipped without it or with ``--no-mpc``); target
   under 15 min;
3. ComEMS4Build on the 4R3C in-process and through the exported 4R3C FMU (``export-fmu``,
   run with fmpy); the overhead is the ratio of the two wall times, target at most 3.

Each figure is one run's wall time (the run's ``wall_s``: building, EMS, plant and KPIs).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from typing import Any

from comems4build_ros.app.commands.options import WEEKS

#: Targets [s] and the FMU path's overhead target [-] (reported, not enforced).
TARGET_FUZZY_S = 60.0
TARGET_MPC_S = 900.0
TARGET_FMU_OVERHEAD = 3.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench cosim``."""
    parser.add_argument("--weeks", metavar="N", type=WEEKS, default=None,
                        help="run length [weeks], one hour .. 30 years (default: the scenario's 12)")
    parser.add_argument("--identified", metavar="FILE.yaml", default=None,
                        help="identified building file of comems4build identify, for the MPC's run")
    parser.add_argument("--no-mpc", action="store_true", help="skip the MPC's run")


def _load() -> str:
    a, b, c = os.getloadavg()
    return f"{a:.2f} {b:.2f} {c:.2f}"


def run(args: argparse.Namespace) -> int:
    """Print the three figures against their targets."""
    from comems4build_ros.app.commands.options import UsageError, load_params
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.models.building_fmu import export_rc_fmu
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_params([])
    scenario = resolve_scenario("default", params, weeks=args.weeks)
    weeks = scenario.n_steps / 168.0
    print(f"bench cosim: {weeks:g} weeks, {os.cpu_count()} CPUs; load average before {_load()}")
    out: dict[str, Any] = {}
    r = simulate("fuzzy", scenario, params, building="energyplus")
    out["fuzzy_energyplus_s"] = r.summary["wall_s"]
    print(f"ComEMS4Build on the EnergyPlus house: {r.summary['wall_s']:.1f} s (target < {TARGET_FUZZY_S:g} s; "
          f"heat balance {r.summary['building_heat_balance_max_rel']:.1e}); load {_load()}")
    if args.identified and not args.no_mpc:
        mpc_params = load_params([args.identified])
        r = simulate("mpc", scenario, mpc_params, ems_options={"observer": "kalman"}, building="energyplus")
        out["mpc_energyplus_s"] = r.summary["wall_s"]
        print(f"MPC (identified model, observer=kalman) on the EnergyPlus house: {r.summary['wall_s']:.1f} s "
              f"(target < {TARGET_MPC_S:g} s; solver {r.summary.get('ems_s', float('nan')):.1f} s); load {_load()}")
    elif not args.no_mpc:
        raise UsageError("--identified FILE is needed for the MPC's run (or give --no-mpc)")
    with tempfile.TemporaryDirectory(prefix="c4b_bench_fmu_") as tmp:
        fmu, _ = export_rc_fmu(params.building, f"{tmp}/rc.fmu", params.simulation.t_air_init_c)
        rc = simulate("fuzzy", scenario, params)
        via = simulate("fuzzy", scenario, params, building=f"fmu:{fmu}")
    ratio = via.summary["wall_s"] / rc.summary["wall_s"]
    same = bool((rc.timeseries["t_air_c"] - via.timeseries["t_air_c"]).abs().max() <= 1e-6)
    print(f"ComEMS4Build on the 4R3C: in-process {rc.summary['wall_s']:.2f} s, through the FMU "
          f"{via.summary['wall_s']:.2f} s: overhead x{ratio:.2f} (target <= {TARGET_FMU_OVERHEAD:g}; T_air equal "
          f"within 1e-6 K: {same}); load {_load()}")
    return 0
