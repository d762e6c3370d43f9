"""The co-simulation study: the paper's three EMS (and the thermostat) on the 4R3C and on the EnergyPlus house.

``comems4build cosim-study`` (:func:`run_study`) runs, over the paper's twelve weeks of the
default scenario, RBC, ComEMS4Build (fuzzy), the MILP MPC and the thermostat on two building
models, each into a comparison folder of its own (``OUT/rc/``, ``OUT/energyplus/``: the
runs, ``compare.json`` and the report and figures ``compare`` writes):

- ``rc``: the paper's 4R3C, the plant the MPC's model equals (the MPC reads its walls);
- ``energyplus``: the German single-family house in EnergyPlus; the MPC plans with the
  4R3C identified from the house (``comems4build identify``: a training window outside the
  twelve weeks) and estimates its wall nodes from the measured T_air (``observer=kalman``);
  the fuzzy EMS, the RBC and the thermostat are model-free, as in the paper.

:mod:`comems4build_ros.report.cosim` sets the paper's table and findings of both beside each
other and writes ``docs/cosimulation.md``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: EMS of the study (the paper's three and the thermostat baseline).
STUDY_EMS = ("rbc", "fuzzy", "mpc", "thermostat")
#: Building models of the study, in table order.
BUILDINGS = ("rc", "energyplus")
#: FC system efficiency of the runs (the paper's main one).
BASE_ETA = 0.75


def study_tasks(out: Path, identified: Path, forecast: str | None = None, weeks: float | None = None) -> dict[str, Any]:
    """The run specifications and tasks per building: ``{building: (specs, tasks)}``."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.report.runs import RUNS_DIR, RunSpec
    from comems4build_ros.study.runner import RunTask

    plan: dict[str, Any] = {}
    for building in BUILDINGS:
        specs, tasks = [], []
        for ems in STUDY_EMS:
            level = str(ems_entry(ems).info_level)
            ov = {"fuel_cell.eta_sys": BASE_ETA}
            config: list[str] = []
            options: dict[str, Any] = {}
            if building != "rc" and level == "mpc":
                config = [str(Path(identified).resolve())]
                options = {"observer": "kalman"}
            specs.append(RunSpec(name=ems, ems=ems, eta_sys=BASE_ETA, info_level=level, overrides=ov))
            tasks.append(RunTask(ems=ems, out_dir=str(out / building / RUNS_DIR / ems), weeks=weeks, overrides=ov,
                                 config=config, ems_options=options, building=building, forecast=forecast))
        plan[building] = (specs, tasks)
    return plan


def run_study(out: Path, identified: Path, forecast: str | None = None, weeks: float | None = None,
              jobs: int | None = None, progress: bool | None = None) -> dict[str, dict[str, float]]:
    """Run every task, write each building's manifest and report; returns the wall times [s]."""
    import time

    from comems4build_ros.report.build import build_report
    from comems4build_ros.report.runs import Manifest, write_manifest
    from comems4build_ros.study.runner import run_tasks

    plan = study_tasks(out, identified, forecast, weeks)
    walls: dict[str, dict[str, float]] = {b: {} for b in plan}

    def done(task: Any, summary: dict) -> None:
        walls[task.building][task.ems] = float(summary["task_wall_s"])

    for _, tasks in plan.values():  # one batch per building (run names are unique within a study's batch)
        run_tasks(tasks, jobs=jobs, on_done=done, progress=progress)
    for building, (specs, _tasks) in plan.items():
        t0 = time.perf_counter()
        manifest = Manifest(scenario="default", weeks=weeks, via="inprocess", base_eta=BASE_ETA, runs=specs,
                            overrides={}, config=[], wall_s=dict(walls[building]))
        write_manifest(manifest, out / building)
        build_report(out / building)
        walls[building]["report"] = time.perf_counter() - t0
    return walls
