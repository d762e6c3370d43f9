"""A community run as a job of a study: one coordinator over one community file (``compare --community``).

A :class:`CommunityTask` is a plain picklable record, as a
:class:`~comems4build_ros.study.runner.RunTask` is: it runs in-process on a local worker or a
Dask worker (:mod:`comems4build_ros.study.pool`), is stored as it finishes and resumes.
Its output directory holds the community run (:func:`~comems4build_ros.core.community.loop.write_community`).
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.files.inputs import load_json_file
from comems4build_ros.run.progress import ProgressCallback
from comems4build_ros.study.runner import local_inputs

#: The community run's summary file in its directory.
SUMMARY_FILE = "community.json"


@dataclass
class CommunityTask:
    """One community run.

    Attributes
    ----------
    coordinator : coordinator name (``config/coordinators.yaml``)
    out_dir : run directory to write
    community : the community file
    houses : number of houses (the run's weight)
    ems : the EMS of every house
    scenario, start, weeks, seed : the run's scenario and window
    overrides : dotted plant overrides of every house (``--set``)
    config : parameter files merged over ``config/plant.yaml``
    coordinator_options, ems_options : options of the coordinator and of every house's EMS
    forecast : the MPC's forecasts (None = ``config/forecast.yaml``)
    timeseries : write the houses' and the hub's timeseries
    hub : hub fields of the community file replaced (``store_kwh``, ``electrolyser_modules``; a sizing study)
    house : run only this house of the file (with ``hub`` its own H2 system: an isolated house)
    inputs : contents of the community file, ``config`` files and a scenario CSV (:meth:`portable`)
    """

    coordinator: str
    out_dir: str
    community: str
    houses: int = 1
    ems: str = "fuzzy"
    scenario: str = "default"
    start: str | None = None
    weeks: float | None = None
    seed: int | None = None
    overrides: dict[str, Any] = field(default_factory=dict)
    config: list[str] = field(default_factory=list)
    coordinator_options: dict[str, Any] = field(default_factory=dict)
    ems_options: dict[str, Any] = field(default_factory=dict)
    forecast: str | None = None
    timeseries: bool = True
    hub: dict[str, Any] = field(default_factory=dict)
    house: str | None = None
    inputs: dict[str, bytes] = field(default_factory=dict, repr=False)

    @property
    def weight(self) -> float:
        """Relative cost: houses x weeks x the EMS's ``weight`` (``config/ems.yaml``)."""
        from comems4build_ros.core.ems import ems_table

        default_weeks = 52.0 if str(self.scenario) == "year" else 12.0
        entry = ems_table().get(self.ems)
        return self.houses * (entry.weight if entry else 1.0) * float(self.weeks or default_weeks)

    def _input_files(self) -> list[str]:
        from comems4build_ros.core.scenario import is_embedded

        return [self.community, *self.config, *([] if is_embedded(self.scenario) else [str(self.scenario)])]

    def _read(self, path: str) -> bytes:
        return self.inputs[path] if path in self.inputs else Path(path).read_bytes()

    def spec(self) -> dict[str, Any]:
        """Everything that decides the run's outputs: its settings and the name and SHA-256 of every file it reads."""
        from comems4build_ros.core.scenario import is_embedded
        from comems4build_ros.study.spec import environment, file_digest

        def file(path: str) -> dict[str, str]:
            return {"name": Path(path).name, "sha256": file_digest(self._read(path))}

        spec = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if f.name not in ("out_dir", "inputs", "config", "scenario", "community")}
        spec["kind"] = "community"
        spec["community"] = file(self.community)
        spec["config"] = [file(p) for p in self.config]
        spec["scenario"] = str(self.scenario) if is_embedded(self.scenario) else file(str(self.scenario))
        spec["environment"] = environment()
        return json.loads(json.dumps(spec, default=str))

    def portable(self) -> CommunityTask:
        """This task with the contents of the files it reads inside it."""
        return dataclasses.replace(self, inputs={p: self._read(p) for p in self._input_files()})

    def run(self, out_dir: str, progress: ProgressCallback | None = None) -> dict[str, Any]:
        """Run into ``out_dir``; the community summary as written, with ``task_wall_s``."""
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="comems4build-inputs-") as tmp:
            paths = local_inputs(self.inputs, Path(tmp))
            task = dataclasses.replace(self, out_dir=str(out_dir), inputs={},
                                       community=paths.get(self.community, self.community),
                                       config=[paths.get(c, c) for c in self.config],
                                       scenario=paths.get(str(self.scenario), self.scenario))
            run_community_task(task, progress)
        written = load_json_file(Path(out_dir) / SUMMARY_FILE, "a community run's summary")
        return {**written, "task_wall_s": time.perf_counter() - t0}


def run_community_task(task: CommunityTask, progress: ProgressCallback | None = None) -> dict[str, Any]:
    """Build the community of ``task`` and run it into ``task.out_dir``; the summary."""
    from comems4build_ros.core.community.loop import simulate_community, write_community
    from comems4build_ros.core.community.spec import build_community, load_community, resized
    from comems4build_ros.core.loop import load_forecast_settings

    spec = load_community(task.community)
    if task.hub or task.house is not None:
        spec = resized(spec, task.hub, task.house, source=Path(task.community).name)
    community = build_community(spec, task.scenario, task.config, task.overrides, source=Path(task.community).name,
                                start=task.start, weeks=task.weeks, seed=task.seed)
    forecast = load_forecast_settings(mode=task.forecast) if task.forecast else None
    result = simulate_community(community, task.coordinator, task.ems, task.ems_options, task.coordinator_options,
                                progress=progress, forecast=forecast)
    write_community(result, task.out_dir, timeseries=task.timeseries)
    return result.summary
