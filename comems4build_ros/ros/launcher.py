"""Python launcher of the node set: separate OS processes on an isolated ROS 2 domain.

:func:`launch` locks a free ROS domain id, builds the plan of the run
(:func:`comems4build_ros.ros.plan.plan_run`: per building ``plant_sim``, ``feed`` and
the EMS node, plus the recorders, each as its own OS process or, for several buildings,
one process per role), has the supervisor start and watch it
(:func:`comems4build_ros.ros.supervisor.run_plan`), then evaluates the bag with the
in-process KPI code (:func:`comems4build_ros.ros.bag_eval.evaluate_bag`). No rclpy in this
process.

``--buildings N``: building ``i`` runs under the namespace ``/building_<i>`` with
scenario seed ``seed + i`` (default scenario) and its own recorder writing
``bag/building_<i>/`` (one recorder for all namespaces spent its time in rclpy's executor,
whose per-wake-up bookkeeping grows with the square of the number of subscriptions: 512
subscriptions for 16 buildings could not keep up).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..progress import ProgressBar
from .plan import LaunchOptions, plan_run
from .supervisor import acquire_domain_id, run_plan


@dataclass
class LaunchResult:
    """Outcome of :func:`launch`."""

    out: Path
    bag: Path
    domain_id: int
    wall_s: float  # from the first process start to the end of the run [s]
    run_s: float  # from the recorder's first record to the end of the run [s]
    summaries: dict[str, dict[str, Any]]  # namespace -> summary


def launch(opts: LaunchOptions) -> LaunchResult:
    """Run the node set, wait for the end, stop every process, evaluate the bag.

    Raises
    ------
    LaunchError
        If a node crashes or exits before the end, or ``timeout_s`` passes.
    KeyboardInterrupt
        On Ctrl-C or SIGTERM (after every child has been stopped).
    """
    from ..config import load_plant_params
    from .bag_eval import evaluate_bag

    out = Path(opts.out)
    bag = Path(opts.bag) if opts.bag is not None else out / "bag"
    if bag.exists():
        raise FileExistsError(f"{bag} exists: choose another --out or remove it")
    params = load_plant_params(opts.config_files, opts.overrides)
    bar = ProgressBar(f"launch {opts.ems} x{opts.buildings}", unit="step",
                      enable=bool(opts.progress) and opts.on_progress is None)
    try:
        with acquire_domain_id(opts.domain_id) as domain_id:
            plan = plan_run(opts, domain_id, params)
            out.mkdir(parents=True, exist_ok=True)
            if len(plan.buildings) > 1:
                bag.mkdir(parents=True)
            times = run_plan(plan, opts.on_progress or bar)
    finally:
        bar.close()
    wall = times.t_end - times.t0
    run_s = times.t_end - (times.t_first_record or times.t0)
    summaries = evaluate_bag(bag, out, params=params, wall_s=wall, accept_gaps=True)
    lost = {t: n for s in summaries.values() for t, n in s.get("lost_messages", {}).items()}
    if lost:
        print(f"launcher: warning: the recording misses messages on {len(lost)} topic(s): {lost} "
              "(summary.json 'lost_messages')", file=sys.stderr)
    return LaunchResult(out, bag, domain_id, wall, run_s, summaries)
