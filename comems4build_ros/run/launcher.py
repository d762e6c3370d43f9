"""Python launcher of the node set: separate OS processes on an isolated ROS 2 domain.

:func:`launch` locks a free ROS domain id, builds the plan of the run
(:func:`comems4build_ros.run.plans.plan_any`: per house ``plant_sim``, ``feed`` and
the EMS node, plus the recorders, each as its own OS process or, for several houses,
one process per role), has the supervisor start and watch it
(:func:`comems4build_ros.run.supervisor.run_plan`), then evaluates the bag with the
in-process KPI code (:func:`comems4build_ros.bags.evaluation.evaluate_bag`). No rclpy in this
process.

``--houses N``: house ``i`` runs under the namespace ``/house_<i>`` with
scenario seed ``seed + i`` (default scenario) and its own recorder writing
``bag/house_<i>/`` (one recorder for all namespaces spent its time in rclpy's executor,
whose per-wake-up bookkeeping grows with the square of the number of subscriptions: 512
subscriptions for 16 houses could not keep up).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from comems4build_ros.files.outputs import open_dir
from comems4build_ros.run.plan import LaunchOptions
from comems4build_ros.run.plans import plan_any
from comems4build_ros.run.progress import ProgressBar
from comems4build_ros.run.supervisor import LaunchError, acquire_domain_id, run_plan


@dataclass
class LaunchResult:
    """Outcome of :func:`launch`."""

    out: Path
    bag: Path
    domain_id: int
    wall_s: float  # from the first process start to the end of the run [s]
    run_s: float  # from the recorder's first record to the end of the run [s]
    summaries: dict[str, dict[str, Any]]  # namespace -> summary
    community: dict[str, Any] | None = None  # a community's summary (community.json), None for independent houses


def launch(opts: LaunchOptions) -> LaunchResult:
    """Run the node set, wait for the end, stop every process, evaluate the bag.

    Raises
    ------
    LaunchError
        If a node crashes or leaves before the end, the run stalls, or ``timeout_s``
        passes. The bag is kept and marked incomplete (:func:`cut_short`); the error
        carries the summaries of the cut run when its bag could be read.
    KeyboardInterrupt
        On Ctrl-C or SIGTERM (after every child has been stopped).
    """
    from comems4build_ros.bags.evaluation import evaluate_bag
    from comems4build_ros.core.config import load_plant_params

    out = Path(opts.out)
    bag = Path(opts.bag) if opts.bag is not None else out / "bag"
    if bag.exists():
        raise FileExistsError(f"{bag} exists: choose another --out or remove it")
    params = opts.params or load_plant_params(opts.config_files, opts.overrides)
    bar = ProgressBar(f"launch {opts.ems} x{opts.houses}", unit="step",
                      enable=bool(opts.progress) and opts.on_progress is None)
    try:
        with acquire_domain_id(opts.domain_id) as domain_id:
            plan = plan_any(opts, domain_id, params)
            out.mkdir(parents=True, exist_ok=True)
            if len(plan.houses) > 1 or opts.community is not None:  # the bags hold the run tokens (ems/command):
                # this user's, no link followed
                os.close(open_dir(bag, create=True, private=True, what="the folder of the run's bags"))
            try:
                times = run_plan(plan, opts.on_progress or bar)
            except LaunchError as exc:
                bar.close()
                cut_short(exc, bag, out, params, opts.community is not None)
                raise
    finally:
        bar.close()
    wall = times.t_end - times.t0
    run_s = times.t_end - (times.t_first_record or times.t0)
    if opts.community is not None:  # every house's bag and the coordinator's, composed
        from comems4build_ros.bags.community import evaluate_community_bags

        try:
            result = evaluate_community_bags(bag, out, wall_s=wall)
        except (ValueError, OSError) as exc:  # the run's bags and logs are kept for a look
            raise LaunchError(f"the community's bags could not be evaluated: {exc}") from None
        summaries = {f"{opts.namespace.rstrip('/')}/{name}": r.summary for name, r in result.houses.items()}
        warn_lost(summaries)
        return LaunchResult(out, bag, domain_id, wall, run_s, summaries, result.summary)
    summaries = evaluate_bag(bag, out, params=params, wall_s=wall, accept_gaps=True)
    warn_lost(summaries)
    warn_stand_in(summaries)
    return LaunchResult(out, bag, domain_id, wall, run_s, summaries)


def warn_lost(summaries: dict[str, dict[str, Any]]) -> None:
    """Say on the console which topics the recording misses messages of (``lost_messages`` of the summaries)."""
    lost = {t: n for s in summaries.values() for t, n in s.get("lost_messages", {}).items()}
    if lost:
        print(f"launcher: warning: the recording misses messages on {len(lost)} topic(s): {lost} "
              "(summary.json 'lost_messages')", file=sys.stderr)


def warn_stand_in(summaries: dict[str, dict[str, Any]]) -> None:
    """Say on the console how many steps of a run on live inputs ran on stand-in prices or
    weather (``live_inputs`` of the summaries; nothing for a run without)."""
    for ns, s in summaries.items():
        live = s.get("live_inputs") or {}
        price, weather = live.get("stand_in_price_steps", 0), live.get("stand_in_weather_steps", 0)
        if price or weather:
            where = "" if ns == "/" else f" ({ns.strip('/')})"
            print(f"launcher: warning: live inputs{where}: {price} of {s.get('steps')} steps ran on stand-in prices "
                  "(no live price for their hour: the same hour of the latest day with prices stood in), "
                  f"{weather} on the scenario's weather (no forecast for their hour, or no weather source); "
                  "summary.json 'live_inputs', "
                  "feed/events 'stand_in' lines in the bag", file=sys.stderr)


def cut_short(exc: LaunchError, bag: Path, out: Path, params: Any, community: bool = False) -> None:
    """A run the launcher cut short: mark every bag (:data:`~comems4build_ros.bags.evaluation.RUN_CUT_FILE`:
    cause, process, exit code, log, the ROS nodes of that process) and evaluate what was
    recorded into ``out`` (summaries with ``run_cut`` and ``bag_incomplete``, put on
    ``exc.summaries``); a bag that cannot be read is noted on stderr."""
    from comems4build_ros.bags.evaluation import RUN_CUT_FILE, evaluate_bag, mark_run_cut

    try:
        marked = mark_run_cut(bag, {"cause": exc.cause, "process": exc.process, "exit_code": exc.code,
                                    "log": None if exc.log is None else str(exc.log), "nodes": list(exc.nodes)})
    except OSError as err:  # the bag's file system is full or read-only (often the cause of the cut)
        print(f"launcher: the cut run's bag {bag} could not be marked ({RUN_CUT_FILE}): {err.filename or bag}: "
              f"{err.strerror or err}", file=sys.stderr)
        marked = [bag]
    if not marked:
        return
    try:
        if community:  # what the bags hold of every house and of the coordinator
            from comems4build_ros.bags.community import evaluate_community_bags

            result = evaluate_community_bags(bag, out)
            exc.summaries = {name: r.summary for name, r in result.houses.items()}
            return
        exc.summaries = evaluate_bag(bag, out, params=params, accept_gaps=True)
    except (ValueError, OSError) as err:
        print(f"launcher: the cut run's bag {bag} (marked in {RUN_CUT_FILE}) could not be evaluated: {err}",
              file=sys.stderr)
