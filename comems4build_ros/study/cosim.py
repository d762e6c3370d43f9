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
#: Folder of the runs inside a building's comparison folder (as ``compare`` writes it).
RUNS_DIR = "runs"


def study_tasks(out: Path, identified: Path, forecast: str | None = None, weeks: float | None = None) -> dict[str, Any]:
    """The runs per building: ``{building: [RunTask, ...]}`` into ``out/<building>/runs/<ems>``."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.study.runner import RunTask

    plan: dict[str, Any] = {}
    for building in BUILDINGS:
        tasks = []
        for ems in STUDY_EMS:
            level = str(ems_entry(ems).info_level)
            config: list[str] = []
            options: dict[str, Any] = {}
            if building != "rc" and level == "mpc":
                config = [str(Path(identified).resolve())]
                options = {"observer": "kalman"}
            tasks.append(RunTask(ems=ems, out_dir=str(out / building / RUNS_DIR / ems), weeks=weeks,
                                 overrides={"fuel_cell.eta_sys": BASE_ETA}, config=config, ems_options=options,
                                 building=building, forecast=forecast))
        plan[building] = tasks
    return plan


def run_study(out: Path, identified: Path, forecast: str | None = None, weeks: float | None = None,
              jobs: int | None = None, progress: bool | None = None) -> tuple[dict[str, Any], dict[str, dict]]:
    """Run every task, one batch per building; returns the tasks and the wall times [s] per building and EMS."""
    from comems4build_ros.study.runner import run_tasks

    plan = study_tasks(out, identified, forecast, weeks)
    walls: dict[str, dict[str, float]] = {b: {} for b in plan}

    def done(task: Any, summary: dict) -> None:
        walls[task.building][task.ems] = float(summary["task_wall_s"])

    for tasks in plan.values():  # one batch per building (run names are unique within a batch)
        run_tasks(tasks, jobs=jobs, on_done=done, progress=progress)
    return plan, walls
