"""Running the EMS of a comparison or a sweep: one task per run, in parallel processes.

A :class:`RunTask` is a plain picklable record (EMS, scenario spec, overrides, output
directory); :func:`run_task` executes it in a worker process (in-process simulation or
the ROS 2 node set through the launcher) and returns the summary. :func:`run_tasks`
spreads tasks over at most ``os.cpu_count()`` worker processes, longest first.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

#: Relative cost of one step per EMS (orders tasks longest first; unknown EMS count 1).
EMS_WEIGHT = {"mpc": 50.0, "mpc-qp": 10.0, "fuzzy": 2.0, "rbc": 1.0, "thermostat": 1.0}


@dataclass
class RunTask:
    """One run.

    Attributes
    ----------
    ems : EMS name
    out_dir : run directory to write (timeseries.csv, weekly.csv, summary.json, bag/)
    scenario : ``default`` or a scenario CSV
    start, weeks : window of the scenario (None = its default)
    overrides : dotted plant-parameter overrides
    config : parameter files merged over ``config/plant.yaml``
    via : ``inprocess`` or ``ros``
    timeseries : write timeseries.csv (in-process runs)
    ems_options : options passed to the controller
    """

    ems: str
    out_dir: str
    scenario: str = "default"
    start: str | None = None
    weeks: float | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    config: list[str] = field(default_factory=list)
    via: str = "inprocess"
    timeseries: bool = True
    ems_options: dict[str, Any] = field(default_factory=dict)


class RunFailedError(RuntimeError):
    """A run ended without its outputs (message names the run directory and the cause)."""


def run_task(task: RunTask) -> dict[str, Any]:
    """Execute one task; return its summary (with ``wall_s`` of the whole task)."""
    t0 = time.perf_counter()
    if task.via == "ros":
        summary = _run_ros(task)
    elif task.via == "inprocess":
        summary = _run_inprocess(task)
    else:
        raise ValueError(f"unknown --via '{task.via}' (inprocess, ros)")
    summary = dict(summary)
    summary["task_wall_s"] = time.perf_counter() - t0
    return summary


def _run_inprocess(task: RunTask) -> dict[str, Any]:
    from ..config import load_plant_params
    from ..scenario import resolve_scenario
    from ..sim import simulate, write_run

    params = load_plant_params(task.config, task.overrides)
    scenario = resolve_scenario(task.scenario, params, start=task.start, weeks=task.weeks)
    result = simulate(task.ems, scenario, params, ems_options=task.ems_options)
    result.summary["eta_sys"] = params.fuel_cell.eta_sys
    write_run(result, task.out_dir, timeseries=task.timeseries)
    return result.summary


def override_file(overrides: dict[str, Any], path: Path) -> Path:
    """Write dotted plant overrides as a ROS 2 parameter file (``/**: ros__parameters``)."""
    nested: dict[str, Any] = {}
    for key, value in overrides.items():
        node = nested
        parts = key.split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("# plant overrides of this run (written by comems4build compare)\n"
                    + yaml.safe_dump({"/**": {"ros__parameters": nested}}, sort_keys=True), encoding="utf-8")
    return path


def _run_ros(task: RunTask) -> dict[str, Any]:
    """Run through the ROS 2 node set with ``comems4build launch`` and rebuild the timeseries from the bag."""
    import json

    out = Path(task.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "comems4build_ros.cli", "launch", "--ems", task.ems, "--scenario", task.scenario,
           "--out", str(out)]
    if task.weeks is not None:
        cmd += ["--weeks", str(task.weeks)]
    if task.start is not None:
        cmd += ["--start", task.start]
    for cfg in task.config:
        cmd += ["--config", cfg]
    if task.overrides:
        cmd += ["--config", str(override_file(task.overrides, out / "overrides.yaml"))]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    (out / "launch.log").write_text(proc.stdout + proc.stderr, encoding="utf-8")
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-5:]
        raise RunFailedError(f"{out}: 'comems4build launch --ems {task.ems}' exited with {proc.returncode}: "
                             + " / ".join(tail))
    bag = out / "bag"
    if not bag.exists():
        raise RunFailedError(f"{out}: the launcher wrote no bag/")
    _evaluate_bag(bag, out, task)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return summary


def _evaluate_bag(bag: Path, out: Path, task: RunTask) -> None:
    """Rebuild timeseries.csv, weekly.csv and summary.json from the bag (the evaluator's code)."""
    from ..config import load_plant_params

    params = load_plant_params(task.config, task.overrides)
    try:
        from ..ros import evaluate as ros_evaluate  # the bag evaluator (ROS issue)
    except ImportError as exc:
        raise RunFailedError(f"{bag}: no bag evaluator available ({exc})") from None
    result = ros_evaluate.evaluate_bag(bag, params)
    from ..sim import write_run

    result.summary["eta_sys"] = params.fuel_cell.eta_sys
    result.summary.setdefault("ems", task.ems)
    write_run(result, out, timeseries=True)


def run_tasks(
    tasks: Sequence[RunTask],
    jobs: int | None = None,
    on_done: Callable[[RunTask, dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run ``tasks`` in at most ``min(jobs, os.cpu_count(), len(tasks))`` processes.

    Tasks start longest first (by :data:`EMS_WEIGHT`); summaries come back in task order.
    The first failure cancels the tasks not yet started and is raised.
    """
    cpus = os.cpu_count() or 1
    workers = max(1, min(jobs or cpus, cpus, len(tasks)))
    order = sorted(range(len(tasks)), key=lambda i: -EMS_WEIGHT.get(tasks[i].ems, 1.0))
    results: list[dict[str, Any] | None] = [None] * len(tasks)
    if workers == 1:
        for i in order:
            results[i] = run_task(tasks[i])
            if on_done:
                on_done(tasks[i], results[i])
        return [r for r in results if r is not None]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(run_task, tasks[i]): i for i in order}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_EXCEPTION)
            for fut in done:
                i = futures[fut]
                exc = fut.exception()
                if exc is not None:
                    for other in pending:
                        other.cancel()
                    raise exc
                results[i] = fut.result()
                if on_done:
                    on_done(tasks[i], results[i])
    return [r for r in results if r is not None]
