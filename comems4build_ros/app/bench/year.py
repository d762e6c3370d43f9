"""Speed and seasonal figures of the year-round scenario: the three EMS in-process, the composed ROS year.

``comems4build bench year`` prints, for each EMS of ``--ems`` (default rbc, fuzzy, mpc), the
in-process run of ``--scenario year`` (52 weeks from 2022-03-01, config/year.yaml): the time
to build the scenario, the wall time of the run (controller, plant, KPIs) and the time spent
in the EMS; for the MPC the median and 95th percentile of its solves; and the seasonal
figures (LOH on 2022-12-01 and at the end, heating-season weeks with discomfort). With
``--ros`` it then runs the ``--ros-ems`` year over ROS 2 composed into one container process
(``launch --layout house --containers 1``: plant_sim, feed, the EMS and the recorder as
rclpy nodes of one process, every message still through DDS) and checks that its summary
equals the in-process one.

Targets on 2 cores: fuzzy and RBC year in-process < 3 s, MPC year < 10 min with a median
solve <= 50 ms, the composed ROS year < 60 s. Figures depend on the load of the machine: the
benchmark prints the load average before and after each run.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import SECONDS, WEEKS

TARGET_FAST_S = 3.0
TARGET_MPC_S = 600.0
TARGET_MPC_MEDIAN_SOLVE_S = 0.050
TARGET_ROS_S = 60.0
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench year``."""
    parser.add_argument("--ems", metavar="NAME[,NAME...]", default="rbc,fuzzy,mpc",
                        help="EMS run in-process over the year (default rbc,fuzzy,mpc)")
    parser.add_argument("--weeks", metavar="N", type=WEEKS, default=None,
                        help="run length [weeks], one hour .. 30 years (default: the year's 52)")
    parser.add_argument("--ros", action="store_true", help="also run the composed ROS year of --ros-ems")
    parser.add_argument("--ros-ems", metavar="NAME", default="fuzzy", help="EMS of the ROS run (default fuzzy)")
    parser.add_argument("--timeout", metavar="S", type=SECONDS, default=900.0,
                        help="timeout of the ROS run [s], 0.01 .. a year (default 900)")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="keep the runs in this directory (default: a temporary one)")


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} cores"


def _mark(ok: bool) -> str:
    return "meets target" if ok else "MISSES target"


def _params() -> Any:
    from comems4build_ros.core.config import load_plant_params, scenario_config_files

    return load_plant_params(scenario_config_files("year"))


def _seasonal(summary: dict[str, Any]) -> str:
    loh0 = summary.get("loh_heating_season_start")
    return (f"LOH 2022-12-01 {loh0 if loh0 is None else f'{loh0:.3f}'}, end {summary['loh_end']:.3f} "
            f"(init {summary['loh_init']:.2f}); heating-season weeks with discomfort "
            f"{summary['heating_season_discomfort_weeks']} of {summary['heating_season_weeks']}; "
            f"H2 made {summary['h2_produced_kwh']:.0f} kWh, EL {summary['el_working_hours']:.0f} h")


def run_inprocess(ems: str, weeks: float | None, out: Path | None) -> dict[str, Any]:
    """One in-process year: its summary plus ``scenario_s`` and, for the MPC, the solve times."""
    import numpy as np

    from comems4build_ros.core.loop import simulate, write_run
    from comems4build_ros.core.scenario import resolve_scenario

    params = _params()
    t0 = time.perf_counter()
    scenario = resolve_scenario("year", params, weeks=weeks)
    scenario_s = time.perf_counter() - t0
    result = simulate(ems, scenario, params, ems_options={"log_fallback": False} if ems == "mpc" else None)
    summary = dict(result.summary, scenario_s=scenario_s)
    if "ems_solve_s" in result.timeseries:
        solves = result.timeseries["ems_solve_s"].to_numpy(dtype=float)
        summary["solve_median_s"] = float(np.median(solves))
        summary["solve_p95_s"] = float(np.percentile(solves, 95))
    if out is not None:
        write_run(result, out / ems)
    return summary


def run(args: argparse.Namespace) -> int:
    """The benchmark, its ``--out`` (if given) through the output layer: checked, locked, all or nothing."""
    from comems4build_ros.app.commands.options import bench_output

    with bench_output(args, "bench year"):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the benchmark and print its figures."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.core import ems as ems_registry

    names = [e.strip() for e in str(args.ems).split(",") if e.strip()]
    for name in names:
        try:
            ems_registry.controller_class(name)
        except ems_registry.UnknownEMSError as exc:
            raise UsageError(f"--ems {name}: {exc}") from None
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_year_"))
    print(f"year scenario, {args.weeks or 52:g} weeks from 2022-03-01; {_load()}", flush=True)
    summaries: dict[str, dict[str, Any]] = {}
    for name in names:
        s = run_inprocess(name, args.weeks, root if args.out else None)
        summaries[name] = s
        target = TARGET_MPC_S if name == "mpc" else TARGET_FAST_S
        line = (f"{name:6s} in-process: scenario {s['scenario_s']:.2f} s, run {s['wall_s']:.2f} s "
                f"({_mark(s['wall_s'] < target)} < {target:g} s), EMS {s['ems_s']:.2f} s")
        if "solve_median_s" in s:
            line += (f", solve median {1000 * s['solve_median_s']:.1f} ms "
                     f"({_mark(s['solve_median_s'] <= TARGET_MPC_MEDIAN_SOLVE_S)} <= 50 ms), "
                     f"p95 {1000 * s['solve_p95_s']:.1f} ms, fallback steps {s['fallback_steps']}")
        print(line, flush=True)
        print(f"       {_seasonal(s)}; {_load()}", flush=True)
    if args.ros:
        from comems4build_ros.run.launcher import launch
        from comems4build_ros.run.plan import LaunchOptions

        ref = summaries.get(args.ros_ems) or run_inprocess(args.ros_ems, args.weeks, None)
        out = root / f"ros_{args.ros_ems}"
        steps = None if args.weeks is None else int(round(args.weeks * 168))
        t0 = time.perf_counter()
        launch(LaunchOptions(ems=args.ros_ems, out=out, scenario="year", weeks=args.weeks, steps=steps,
                             timeout_s=args.timeout, layout="house", containers=1))
        wall = time.perf_counter() - t0
        import json

        ros = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        keys = (set(ref) - set(TIMING_KEYS) - {"scenario_s", "solve_median_s", "solve_p95_s"})
        same = all(_equal(ros.get(k), ref.get(k)) for k in keys)
        print(f"{args.ros_ems:6s} over ROS, composed (one container): {wall:.1f} s with start-up and bag "
              f"evaluation ({_mark(wall < TARGET_ROS_S)} < {TARGET_ROS_S:g} s); summary equals in-process: "
              f"{'yes' if same else 'NO'}; {_load()}", flush=True)
    if not args.out:
        import shutil

        shutil.rmtree(root, ignore_errors=True)
    return 0


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b
