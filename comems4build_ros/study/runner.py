"""Running the EMS of a comparison, a sweep or a reproduction: one task per run.

A :class:`RunTask` is a plain picklable record (EMS, scenario spec, overrides, output
directory); :func:`run_task` executes it (in-process simulation or the ROS 2 node set
through the launcher) and returns the summary. :func:`run_tasks` hands a study's tasks to
a study pool (:mod:`comems4build_ros.study.pool`): local worker processes, longest
first, or a Dask cluster; each finished run is stored as it finishes, so a study resumes.
A task is a job of that pool: :meth:`RunTask.spec` is its full specification (hashed
to recognise a stored run), :meth:`RunTask.portable` carries the files it reads from
outside the package (``--config`` files, a scenario CSV) to a worker on another host.
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import load_json_file
from comems4build_ros.run.progress import ProgressCallback
from comems4build_ros.study.pool import RunFailedError

if TYPE_CHECKING:
    from comems4build_ros.study.pool import StudyPool

__all__ = ["RunFailedError", "RunTask", "run_task", "run_tasks"]


@dataclass
class RunTask:
    """One run.

    Attributes
    ----------
    ems : EMS name
    out_dir : run directory to write (timeseries.csv, weekly.csv, summary.json, bag/)
    scenario : an embedded scenario (``default``, ``validation/<id>``, ...) or a scenario CSV
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
    inputs : contents of the files named by ``config`` and a scenario CSV, by the name given
        there (filled by :meth:`portable`; the run reads these instead of the paths)
    building : the building model (``--building``: ``rc``, ``energyplus[:IDF]``, ``fmu:PATH``;
        in-process runs)
    forecast : the MPC's forecasts (``perfect``/``imperfect``; None = ``config/forecast.yaml``)
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
    inputs: dict[str, bytes] = field(default_factory=dict, repr=False)
    building: str = "rc"
    forecast: str | None = None

    @property
    def weight(self) -> float:
        """Relative cost of the run: its EMS's ``weight`` (``config/ems.yaml``) times its weeks (longest first)."""
        from comems4build_ros.core.ems import ems_table

        default_weeks = 52.0 if str(self.scenario) == "year" else 12.0  # the year's 52 weeks, else the winter's 12
        entry = ems_table().get(self.ems)
        return (entry.weight if entry else 1.0) * float(self.weeks or default_weeks)

    def _input_files(self) -> list[str]:
        from comems4build_ros.core.scenario import is_embedded

        return [*self.config, *([] if is_embedded(self.scenario) else [str(self.scenario)])]

    def _read(self, path: str) -> bytes:
        return self.inputs[path] if path in self.inputs else Path(path).read_bytes()

    def spec(self) -> dict[str, Any]:
        """Everything that decides the run's outputs (JSON-ready; ``out_dir`` is not part of it).

        The run's settings, the name and SHA-256 of every file it reads from outside the
        package, and the environment record (:func:`comems4build_ros.study.spec.environment`).
        """
        from comems4build_ros.core.scenario import is_embedded
        from comems4build_ros.study.spec import environment, file_digest

        def file(path: str) -> dict[str, str]:
            return {"name": Path(path).name, "sha256": file_digest(self._read(path))}

        spec: dict[str, Any] = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                                if f.name not in ("out_dir", "inputs", "config", "scenario", "building", "forecast")}
        if self.building != "rc":  # the 4R3C's runs keep the specification (and store hash) they had
            spec["building"] = self.building
        if self.forecast is not None:
            spec["forecast"] = self.forecast
        spec["config"] = [file(p) for p in self.config]
        spec["scenario"] = str(self.scenario) if is_embedded(self.scenario) else file(str(self.scenario))
        spec["environment"] = environment()
        return json.loads(json.dumps(spec, default=str))

    def portable(self) -> RunTask:
        """This task with the contents of its ``--config`` files and scenario CSV inside it."""
        return dataclasses.replace(self, inputs={p: self._read(p) for p in self._input_files()})

    def run(self, out_dir: str, progress: ProgressCallback | None = None) -> dict[str, Any]:
        """Run into ``out_dir``; the summary as written to ``summary.json``, with ``task_wall_s``.

        Carried ``inputs`` are written to a temporary directory under their file names and
        read from there, so the run needs no file of the machine that made the task.
        """
        with tempfile.TemporaryDirectory(prefix="comems4build-inputs-") as tmp:
            paths = local_inputs(self.inputs, Path(tmp))
            task = dataclasses.replace(self, out_dir=str(out_dir), inputs={},
                                       config=[paths.get(c, c) for c in self.config],
                                       scenario=paths.get(str(self.scenario), self.scenario))
            summary = run_task(task, progress)
        written = load_json_file(Path(out_dir) / "summary.json", "a run's summary")
        return {**written, "task_wall_s": summary["task_wall_s"]}


def local_inputs(inputs: Mapping[str, bytes], folder: Path) -> dict[str, str]:
    """Write carried input files into ``folder`` under their own names; the name given -> the local path."""
    paths: dict[str, str] = {}
    for k, (name, data) in enumerate(inputs.items()):
        local = folder / str(k) / Path(name).name
        local.parent.mkdir(parents=True)
        local.write_bytes(data)
        paths[name] = str(local)
    return paths


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
        raise InputError(f"unknown --via '{task.via}' (inprocess, ros)")
    summary = dict(summary)
    summary["task_wall_s"] = time.perf_counter() - t0
    return summary


def _run_inprocess(task: RunTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    from comems4build_ros.core.config import load_plant_params, scenario_config_files
    from comems4build_ros.core.loop import simulate, write_run
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_plant_params(scenario_config_files(task.scenario, task.config), task.overrides)
    scenario = resolve_scenario(task.scenario, params, start=task.start, weeks=task.weeks, seed=task.seed,
                                extend=task.extend, settings_overrides=task.scenario_overrides or None)
    from comems4build_ros.core.loop import load_forecast_settings

    forecast = load_forecast_settings(mode=task.forecast) if task.forecast else None
    result = simulate(task.ems, scenario, params, ems_options=task.ems_options, progress=progress,
                      forecast=forecast, building=None if task.building == "rc" else task.building)
    result.summary["eta_sys"] = params.fuel_cell.eta_sys
    write_run(result, task.out_dir, timeseries=task.timeseries)
    return result.summary


def _run_ros(task: RunTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Run through the ROS 2 node set (:func:`comems4build_ros.run.launcher.launch`).

    The launcher starts plant_sim, feed, the EMS node and the recorder as separate
    processes on a free ROS domain, and evaluates the recorded bag into the run
    directory (``bag/``, ``timeseries.csv``, ``weekly.csv``, ``summary.json``) with the
    in-process KPI code. ``eta_sys`` is added to the summary as for in-process runs.
    """
    import json

    from comems4build_ros.core.config import scenario_config_files
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.plan import LaunchOptions
    from comems4build_ros.run.supervisor import LaunchError

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
        raise RunFailedError(f"{out}: expected one house in the bag, got {len(result.summaries)}")
    summary = dict(next(iter(result.summaries.values())))
    from comems4build_ros.core.config import load_plant_params, scenario_config_files

    summary["eta_sys"] = load_plant_params(scenario_config_files(task.scenario, task.config),
                                           task.overrides).fuel_cell.eta_sys
    path = out / "summary.json"
    data = load_json_file(path, "a run's summary")
    data["eta_sys"] = summary["eta_sys"]
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return summary


def run_tasks(
    tasks: Sequence[RunTask],
    jobs: int | None = None,
    on_done: Callable[[RunTask, dict[str, Any]], None] | None = None,
    progress: bool | None = None,
    pool: StudyPool | None = None,
) -> list[dict[str, Any]]:
    """Run ``tasks`` with ``pool``: default the enclosing study's, else ``jobs`` local processes.

    Tasks start longest first (:attr:`RunTask.weight`); summaries come back in task order
    (as written to each run's ``summary.json``, with ``task_wall_s``), ``on_done`` is
    called as each run finishes. The first failure stops the tasks not yet started and is
    raised once the running ones ended. ``progress``: one bar per run on stderr while it
    runs (None = when stderr is a terminal, False = never); print from ``on_done`` with
    :func:`comems4build_ros.run.progress.echo` to keep the bars intact. ``jobs`` applies only
    when no pool is given or current (:func:`comems4build_ros.study.pool.current`).
    """
    from comems4build_ros.study.pool import LocalBackend, StudyPool, current, run_jobs

    ex = pool or current() or StudyPool(LocalBackend(jobs))
    return run_jobs(tasks, ex, on_done=on_done, progress=progress)


def run_into(tasks: Mapping[str, RunTask], runs_dir: Path, jobs: int | None = None,
             progress: Callable[[int, int, str], None] | None = None, show_progress: bool | None = None) -> int:
    """Make every run of ``tasks`` (name -> task) into ``runs_dir/<name>`` with :func:`run_tasks`;
    the number of runs made. ``progress``: callback ``(done, total, name)`` after each run;
    ``show_progress``: one progress bar per run on stderr (None = when stderr is a terminal)."""
    runs_dir.mkdir(parents=True, exist_ok=True)
    todo = []
    for name, task in tasks.items():
        task.out_dir = str(runs_dir / name)
        todo.append(task)
    done = [0]

    def on_done(task: RunTask, _: dict[str, Any]) -> None:
        done[0] += 1
        if progress:
            progress(done[0], len(todo), Path(task.out_dir).name)

    if todo:
        run_tasks(todo, jobs=jobs, on_done=on_done, progress=show_progress)
    return len(todo)


def missing_in(names: Iterable[str], runs_dir: Path) -> list[str]:
    """The names of ``names`` without a finished run directory (``summary.json``) in ``runs_dir``."""
    return [n for n in names if not (runs_dir / n / "summary.json").is_file()]
