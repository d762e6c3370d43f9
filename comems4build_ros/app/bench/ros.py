"""Speed of the ROS 2 node set: step round trip, 12-week fuzzy run, throughput with N houses.

``comems4build bench ros`` prints, in one run:

1. the 12-week fuzzy run over ROS (``comems4build launch``: plant_sim, feed, fuzzy_ems
   and the recorder as separate processes over Fast DDS) next to the same run
   in-process, with a check that both summaries are equal (timing entries aside);
2. the median and 99th percentile of the step round trip plant -> EMS -> plant in that
   run, as measured by plant_sim (from the state announcement of step k to the arrival
   of the command for step k; ``plant/events`` "stats" line in the bag);
3. the throughput with ``--houses 1, 4, 16`` (N independent houses under
   ``/house_<i>``; see :mod:`comems4build_ros.ros.container`): wall time and
   house-steps per second.

The one-house run goes twice: one OS process per node (the default of ``launch``) and
composed into one container process (``launch --layout house``: recorder, EMS, feed
and plant as four rclpy nodes of one process, still exchanging every message through
DDS). Runs with more houses use ``--layout`` (default ``house``, the launcher's
default: one container per core, ``--containers`` to change).

Targets on 2 cores: round trip median < 2 ms and p99 < 10 ms, 12-week fuzzy run over ROS
< 5 s (one process per node as well as composed), 16 houses x 12 weeks < 2 min, and no
message lost by the recorder in any run.
Wall times include process start-up (imports, scenario generation) and the bag
evaluation is not included. Figures depend on the load of the machine: the benchmark
prints the load average before and after each run.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import COUNT, HOUSES, SECONDS, WEEKS

TARGET_RTT_MEDIAN_MS = 2.0
TARGET_RTT_P99_MS = 10.0
TARGET_FUZZY_12W_S = 5.0
TARGET_16_HOUSES_S = 120.0
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")  # only in summaries from a bag


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench ros``."""
    parser.add_argument("--weeks", metavar="N", type=WEEKS, default=12,
                        help="run length [weeks], one hour .. 30 years (default 12)")
    parser.add_argument("--houses", metavar="N[,N...]", default="1,4,16",
                        help="house counts of the throughput runs (default 1,4,16)")
    parser.add_argument("--ems", metavar="NAME", default="fuzzy", help="EMS of every run (default fuzzy)")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="keep the runs in this directory (default: a temporary one)")
    parser.add_argument("--layout", choices=("house", "role", "node"), default="house",
                        help="process layout of the runs with more than one house (launch --layout; default "
                             "house, the launcher's default)")
    parser.add_argument("--containers", metavar="N", type=COUNT, default=None,
                        help="container processes of the layout 'house' (default: one per core)")
    parser.add_argument("--timeout", metavar="S", type=SECONDS, default=600.0,
                        help="give up a throughput run after this [s], 0.01 .. a year")


def plant_stats(bag: Path) -> dict[str, dict[str, float]]:
    """plant_sim's end-of-run statistics per namespace, from the ``plant/events`` "stats" lines."""
    from comems4build_ros.bags.bag import decode, iter_messages

    out: dict[str, dict[str, float]] = {}
    for topic, msgtype, _t, raw in iter_messages(bag):
        if not topic.endswith("plant/events"):
            continue
        parts = str(decode(msgtype, raw).data).split()
        if len(parts) > 2 and parts[1] == "stats":
            ns = topic[: -len("/plant/events")] or "/"
            out[ns] = {k: float(v) for k, v in (p.split("=", 1) for p in parts[2:] if "=" in p)}
    return out


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min) on {os.cpu_count()} cores"


def _mark(ok: bool) -> str:
    return "meets target" if ok else "MISSES target"


def _options(args: argparse.Namespace, out: Path, weeks: float, houses: int, layout: str) -> Any:
    """LaunchOptions of one benchmark run in ``layout`` (node, house or role)."""
    from comems4build_ros.run.plan import LaunchOptions
    from comems4build_ros.run.progress import is_terminal

    return LaunchOptions(ems=args.ems, out=out, weeks=weeks, houses=houses, timeout_s=args.timeout,
                         progress=is_terminal(), layout=layout,
                         containers=args.containers if layout == "house" else None)


def _layout_label(opts: Any) -> str:
    from comems4build_ros.run.plan import container_count, effective_layout

    layout = effective_layout(opts)
    if layout == "house":
        return f"{container_count(opts)} container process(es)"
    return "one process per node" if layout == "node" else "one process per role"


def run(args: argparse.Namespace) -> int:
    """The benchmark, its ``--out`` (if given) through the output layer: checked, locked, all or nothing."""
    from comems4build_ros.app.commands.options import bench_output

    with bench_output(args, "bench ros"):
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    """Run the benchmark and print the figures."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.files.outputs import check_out_dir

    try:  # each count by the rule of launch --houses
        counts = [HOUSES(x.strip()) for x in str(args.houses).split(",") if x.strip()]
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f"--houses {args.houses}: {exc}") from None
    if not counts:
        raise UsageError(f"--houses '{args.houses}': no count given")
    if args.out:
        check_out_dir(args.out)
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_ros_"))
    root.mkdir(parents=True, exist_ok=True)
    params = load_plant_params()
    weeks = args.weeks
    steps = int(round(weeks * 168))

    one = _one_house_stage(args, params, root, weeks, steps)
    _round_trip_stage(args, one)
    _throughput_stage(args, counts, one, root, weeks, steps)
    print(f"\nruns kept in {root}")
    return 0


def _one_house_stage(args: argparse.Namespace, params: Any, root: Path, weeks: float, steps: int) -> dict[str, Any]:
    """Stage 1: one house in-process and over ROS in the layouts ``node`` and ``house``; the launch results."""
    from comems4build_ros.bags.evaluation import lost_messages
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario.run import load_scenario
    from comems4build_ros.run.launcher import launch

    whole = math.ceil(weeks - 1e-9)
    print(f"== 1. {args.ems}, {weeks:g} weeks ({steps} steps): ROS node set vs in-process   [{_load()}]")
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = load_scenario("default", params, None, whole, None, steps if steps != whole * 168 else None)
        ref = simulate(args.ems, scenario, params)
    t_in = time.perf_counter() - t0
    print(f"in-process: {t_in:7.2f} s (scenario + run; run alone {ref.summary['wall_s']:.2f} s)")
    one: dict[str, Any] = {}
    for layout in ("node", "house"):  # separate processes (the default), then composed into one container
        opts = _options(args, root / f"{args.ems}_{weeks:g}w_{layout}", weeks, 1, layout)
        res = one[layout] = launch(opts)
        summary = res.summaries["/"]
        diff = sorted(k for k in set(ref.summary) | set(summary) - set(TIMING_KEYS)
                      if k not in TIMING_KEYS and ref.summary.get(k) != summary.get(k))
        lost = lost_messages(res.bag)
        print(f"over ROS, {_layout_label(opts)}: {res.wall_s:7.2f} s (process start to end of run; "
              f"{res.run_s:.2f} s after the first record)  -> {_mark(res.wall_s < TARGET_FUZZY_12W_S)} "
              f"< {TARGET_FUZZY_12W_S:g} s")
        print(f"   summaries equal (timing aside): {'yes' if not diff else 'NO, differ in ' + ', '.join(diff)}; "
              f"messages lost by the recorder: {sum(lost.values())}   ({_load()})")
    return one


def _round_trip_stage(args: argparse.Namespace, one: dict[str, Any]) -> None:
    """Stage 2: the step round trip plant -> EMS -> plant that plant_sim measured, per layout."""
    print(f"\n== 2. step round trip plant -> {args.ems}_ems -> plant over DDS (measured by plant_sim)")
    for layout, res in one.items():
        stats = plant_stats(res.bag).get("/", {})
        med, p99 = stats.get("rtt_median_ms", float("nan")), stats.get("rtt_p99_ms", float("nan"))
        print(f"{layout:>8} layout, {int(stats.get('steps', 0))} steps: median {med:.3f} ms -> "
              f"{_mark(med < TARGET_RTT_MEDIAN_MS)} < {TARGET_RTT_MEDIAN_MS:g} ms; "
              f"p99 {p99:.3f} ms -> {_mark(p99 < TARGET_RTT_P99_MS)} < {TARGET_RTT_P99_MS:g} ms")


def _throughput_stage(args: argparse.Namespace, counts: list[int], one: dict[str, Any], root: Path, weeks: float,
                      steps: int) -> None:
    """Stage 3: runs of N houses (one house: the runs of stage 1) and the 16-house target."""
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.supervisor import LaunchError

    many_layout = getattr(args, "layout", None) or "house"
    print(f"\n== 3. throughput, {args.ems}, {weeks:g} weeks per house; 1 house as above, more in layout "
          f"'{many_layout}'")
    print(f"{'houses':>9} {'layout':>8} {'procs':>5} {'wall_s':>8} {'run_s':>8} {'house-steps/s':>17} "
          f"{'rtt_med_ms':>10} {'rtt_p99_ms':>10} {'fallback':>8} {'held_s':>7} {'lost':>5}  load after (1 min)")
    rows: list[tuple[int, str, Any]] = []
    for n in counts:
        if n == 1:
            for layout, res in one.items():
                rows.append((1, layout, res))
                _print_row(*rows[-1], steps)
            continue
        print(f"   ({_load()})", flush=True)
        try:
            rows.append((n, many_layout, launch(_options(args, root / f"{args.ems}_{weeks:g}w_x{n}", weeks, n,
                                                         many_layout))))
        except LaunchError as exc:
            print(f"{n:>9} {many_layout:>8} FAILED: {str(exc).splitlines()[0]}", flush=True)
            continue
        _print_row(*rows[-1], steps)
    w16 = [r.wall_s for n, _, r in rows if n == 16]
    if 16 in counts and not w16:
        print(f"16 houses x {weeks:g} weeks: failed -> MISSES target < {TARGET_16_HOUSES_S:g} s")
    if w16:
        print(f"16 houses x {weeks:g} weeks: {w16[0]:.1f} s -> {_mark(w16[0] < TARGET_16_HOUSES_S)} "
              f"< {TARGET_16_HOUSES_S:g} s")


def _print_row(n: int, layout: str, r: Any, steps: int) -> None:
    """One row of the throughput table (statistics from the bag)."""
    from comems4build_ros.bags.evaluation import lost_messages

    st = plant_stats(r.bag)
    vals = {key: sorted(v.get(key, float("nan")) for v in st.values()) for key in ("rtt_median_ms", "rtt_p99_ms")}

    def mid(key: str) -> float:
        return vals[key][len(vals[key]) // 2] if vals[key] else float("nan")

    lost_n = sum(lost_messages(r.bag).values())
    procs = len(list((r.out / "log").glob("*.log")))
    fb = sum(int(v.get("fallback_steps", 0)) for v in st.values())
    held = max((v.get("held_for_recorder_s", 0.0) for v in st.values()), default=0.0)
    print(f"{n:>9} {layout:>8} {procs:>5} {r.wall_s:8.2f} {r.run_s:8.2f} {n * steps / r.wall_s:17.1f} "
          f"{mid('rtt_median_ms'):10.3f} {mid('rtt_p99_ms'):10.3f} {fb:>8} {held:7.2f} {lost_n:>5}  "
          f"{os.getloadavg()[0]:.2f}", flush=True)
