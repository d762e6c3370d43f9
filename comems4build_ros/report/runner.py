"""Running the EMS of a comparison or a sweep: one task per run, in parallel processes.

A :class:`RunTask` is a plain picklable record (EMS, scenario spec, overrides, output
directory); :func:`run_task` executes it in a worker process (in-process simulation or
the ROS 2 node set through the launcher) and returns the summary. :func:`run_tasks`
spreads tasks over at most ``os.cpu_count()`` worker processes, longest first, with one
progress bar per run on a terminal (:class:`comems4build_ros.progress.RunProgress`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..progress import ProgressCallback, RunProgress

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
    seed : seed of generated scenario data (None = config/scenario.yaml)
    extend : ``"synthetic"`` allows a run longer than the scenario's data (in-process only)
    overrides : dotted plant-parameter overrides
    config : parameter files merged over ``config/plant.yaml``
    via : ``inprocess`` or ``ros``
    timeseries : write timeseries.csv (in-process runs)
    ems_options : options passed to the controller
    scenario_overrides : dotted settings of ``config/scenario.yaml`` for an embedded scenario
        (``{"scenario.load.annual_kwh": 4000}``; in-process runs)
    """

    ems: str
    out_dir: str
    scenario: str = "default"
    start: str | None = None
    weeks: float | None = None
    seed: int | None = None
    extend: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    config: list[str] = field(default_factory=list)
    via: str = "inprocess"
    timeseries: bool = True
    ems_options: dict[str, Any] = field(default_factory=dict)
    scenario_overrides: dict[str, Any] = field(default_factory=dict)


class RunFailedError(RuntimeError):
    """A run ended without its outputs (message names the run directory and the cause)."""


def run_task(task: RunTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Execute one task; return its summary (with ``task_wall_s`` of the whole task).

    ``progress(done, total)`` is called as the run advances (simulated or recorded steps).
    """
    t0 = time.perf_counter()
    if task.via == "ros":
        summary = _run_ros(task, progress)
    elif task.via == "inprocess":
        summary = _run_inprocess(task, progress)
    else:
        raise ValueError(f"unknown --via '{task.via}' (inprocess, ros)")
    summary = dict(summary)
    summary["task_wall_s"] = time.perf_counter() - t0
    return summary


def _run_inprocess(task: RunTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    from ..config import load_plant_params, scenario_config_files
    from ..scenario import resolve_scenario
    from ..sim import simulate, write_run

    params = load_plant_params(scenario_config_files(task.scenario, task.config), task.overrides)
    scenario = resolve_scenario(task.scenario, params, start=task.start, weeks=task.weeks, seed=task.seed,
                                extend=task.extend, settings_overrides=task.scenario_overrides or None)
    result = simulate(task.ems, scenario, params, ems_options=task.ems_options, progress=progress)
    result.summary["eta_sys"] = params.fuel_cell.eta_sys
    write_run(result, task.out_dir, timeseries=task.timeseries)
    return result.summary


def _run_ros(task: RunTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Run through the ROS 2 node set (:func:`comems4build_ros.ros.launcher.launch`).

    The launcher starts plant_sim, feed, the EMS node and the recorder as separate
    processes on a free ROS domain, and evaluates the recorded bag into the run
    directory (``bag/``, ``timeseries.csv``, ``weekly.csv``, ``summary.json``) with the
    in-process KPI code. ``eta_sys`` is added to the summary as for in-process runs.
    """
    import json

    from ..config import scenario_config_files
    from ..ros.launcher import launch
    from ..ros.plan import LaunchOptions
    from ..ros.supervisor import LaunchError

    out = Path(task.out_dir)
    if task.scenario_overrides:
        raise RunFailedError(f"{out}: scenario settings overrides are not supported over ROS")
    if task.extend:
        raise RunFailedError(f"{out}: extend '{task.extend}' applies to in-process runs only")
    opts = LaunchOptions(ems=task.ems, out=out, scenario=task.scenario, weeks=task.weeks, start=task.start,
                         seed=task.seed, config_files=scenario_config_files(task.scenario, task.config),
                         overrides=dict(task.overrides),
                         ems_options=[f"{k}={json.dumps(v)}" for k, v in task.ems_options.items()],
                         on_progress=progress)
    try:
        result = launch(opts)
    except LaunchError as exc:
        raise RunFailedError(f"{out}: ROS run of {task.ems} failed: {exc}") from None
    if len(result.summaries) != 1:
        raise RunFailedError(f"{out}: expected one building in the bag, got {len(result.summaries)}")
    summary = dict(next(iter(result.summaries.values())))
    from ..config import load_plant_params, scenario_config_files

    summary["eta_sys"] = load_plant_params(scenario_config_files(task.scenario, task.config),
                                           task.overrides).fuel_cell.eta_sys
    path = out / "summary.json"
    data = json.loads(path.read_text(encoding="utf-8"))
    data["eta_sys"] = summary["eta_sys"]
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return summary


def run_tasks(
    tasks: Sequence[RunTask],
    jobs: int | None = None,
    on_done: Callable[[RunTask, dict[str, Any]], None] | None = None,
    progress: bool | None = None,
) -> list[dict[str, Any]]:
    """Run ``tasks`` in at most ``min(jobs, os.cpu_count(), len(tasks))`` processes.

    Tasks start longest first (by :data:`EMS_WEIGHT`); summaries come back in task order,
    ``on_done`` is called as each run finishes. The first failure cancels the tasks not
    yet started and is raised. ``progress``: one bar per run on stderr while it runs (None
    = when stderr is a terminal, False = never); print from ``on_done`` with
    :func:`comems4build_ros.progress.echo` to keep the bars intact.
    """
    with RunProgress([Path(t.out_dir).name for t in tasks], enable=progress) as bars:
        return _run_tasks(tasks, jobs, on_done, bars)


def _run_tasks(
    tasks: Sequence[RunTask],
    jobs: int | None,
    on_done: Callable[[RunTask, dict[str, Any]], None] | None,
    bars: RunProgress,
) -> list[dict[str, Any]]:
    cpus = os.cpu_count() or 1
    workers = max(1, min(jobs or cpus, cpus, len(tasks)))
    order = sorted(range(len(tasks)), key=lambda i: -EMS_WEIGHT.get(tasks[i].ems, 1.0))
    results: list[dict[str, Any] | None] = [None] * len(tasks)
    if workers == 1:
        for i in order:
            results[i] = run_task(tasks[i], bars.callback(i))
            if on_done:
                on_done(tasks[i], results[i])
        return [r for r in results if r is not None]
    with ProcessPoolExecutor(max_workers=workers, initializer=bars.initializer, initargs=bars.initargs) as pool:
        futures = {pool.submit(run_task, tasks[i], bars.reporter(i)): i for i in order}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
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
