"""Reading the run directories a comparison is built from.

A comparison directory holds ``runs/<name>/`` per run (``summary.json``, ``weekly.csv``,
``timeseries.csv`` and, for ROS runs, ``bag/``) and a manifest ``compare.json`` that lists
the runs with their EMS, FC system efficiency and parameter overrides. Every reader here
checks what it reads and raises :class:`RunDirError` naming the directory or file, so a
missing or corrupt run never turns into a silently wrong report.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from comems4build_ros.core.kpi import REQUIRED_COLUMNS
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import InputFileError, load_json_file

#: Name of the manifest file in a comparison directory.
MANIFEST = "compare.json"
#: Sub-directory holding one directory per run.
RUNS_DIR = "runs"
#: Weekly KPI columns the report reads (see ``kpi.weekly_kpis``).
WEEKLY_COLUMNS = (
    "week",
    "start",
    "discomfort_kh",
    "cost_eur",
    "reimbursement_eur",
    "buy_kwh",
    "sell_kwh",
    "bess_charged_kwh",
    "h2_kwh",
    "heat_recovered_kwh",
    "dhw_demand_kwh",
    "fc_working_hours",
    "fc_toggles",
)
#: Summary keys the report reads (see ``kpi.summarize``).
SUMMARY_KEYS = (
    "weeks",
    "steps",
    "cost_eur_week_median",
    "reimbursement_eur_week_median",
    "discomfort_kh_week_median",
    "discomfort_weeks_nonzero",
    "buy_kwh_week_median",
    "sell_kwh_week_median",
    "bess_charged_kwh_week_median",
    "h2_kwh_week_min",
    "h2_kwh_week_max",
    "fc_working_hours",
    "fc_toggles",
    "fc_mean_load_w",
    "fc_mean_eta_el",
    "loh_end",
    "h2_empty_at",
    "dhw_unmet_kwh",
)
#: Timeseries columns the figures and findings read, beyond the KPI columns.
TIMESERIES_EXTRA = ("soc", "v_dhw_l", "ghi_w_m2", "t_amb_c")


class RunDirError(InputError):
    """A run or comparison directory is missing, incomplete or corrupt (message names it)."""


@dataclass
class RunSpec:
    """One entry of the manifest.

    Attributes
    ----------
    name : directory name under ``runs/`` (``<ems>`` or ``<ems>_eta<NN>``)
    ems : EMS name
    eta_sys : FC system efficiency of the run [-]
    info_level : information level of the EMS (``tab:level_of_information``)
    overrides : dotted plant-parameter overrides of the run
    """

    name: str
    ems: str
    eta_sys: float
    info_level: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunData:
    """A run read back from disk."""

    spec: RunSpec
    path: Path
    summary: dict[str, Any]
    weekly: pd.DataFrame
    timeseries: pd.DataFrame


@dataclass
class Manifest:
    """What a comparison ran: scenario, weeks, path (ROS or in-process), runs."""

    scenario: str
    weeks: float | None
    via: str
    base_eta: float
    runs: list[RunSpec]
    overrides: dict[str, Any] = field(default_factory=dict)
    config: list[str] = field(default_factory=list)
    wall_s: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return {
            "scenario": self.scenario,
            "weeks": self.weeks,
            "via": self.via,
            "base_eta": self.base_eta,
            "overrides": self.overrides,
            "config": self.config,
            "wall_s": self.wall_s,
            "runs": [vars(r) for r in self.runs],
        }


def write_manifest(manifest: Manifest, compare_dir: str | Path) -> Path:
    """Write ``compare.json`` into ``compare_dir``."""
    path = Path(compare_dir) / MANIFEST
    path.write_text(json.dumps(manifest.to_json(), indent=2) + "\n", encoding="utf-8")
    return path


def read_manifest(compare_dir: str | Path) -> Manifest:
    """Read ``compare.json`` of a comparison directory.

    Raises
    ------
    RunDirError
        If the directory or manifest is missing or the manifest is not valid.
    """
    root = Path(compare_dir)
    if not root.is_dir():
        raise RunDirError(f"{root}: comparison directory does not exist")
    path = root / MANIFEST
    if not path.is_file():
        raise RunDirError(f"{path}: manifest missing (not a directory written by 'comems4build compare')")
    try:
        data = load_json_file(path, "a comparison's manifest")
        runs = [RunSpec(**r) for r in data["runs"]]
        return Manifest(
            scenario=str(data["scenario"]),
            weeks=data.get("weeks"),
            via=str(data.get("via", "inprocess")),
            base_eta=float(data["base_eta"]),
            runs=runs,
            overrides=dict(data.get("overrides") or {}),
            config=list(data.get("config") or []),
            wall_s=dict(data.get("wall_s") or {}),
        )
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise RunDirError(f"{path}: corrupt manifest ({type(exc).__name__}: {exc})") from None


def _read_csv(path: Path, required: tuple[str, ...]) -> pd.DataFrame:
    if not path.is_file():
        raise RunDirError(f"{path}: missing")
    try:
        df = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise RunDirError(f"{path}: not a readable CSV ({exc})") from None
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise RunDirError(f"{path}: lacks column(s) {', '.join(missing)}")
    if df.empty:
        raise RunDirError(f"{path}: no rows")
    numeric = [c for c in required if c not in ("start", "time")]
    bad = [c for c in numeric if not pd.api.types.is_numeric_dtype(df[c])]
    if bad:
        raise RunDirError(f"{path}: non-numeric values in column(s) {', '.join(bad)}")
    return df


def read_run(path: str | Path, spec: RunSpec | None = None, timeseries: bool = True) -> RunData:
    """Read one run directory (summary, weekly table and, optionally, the timeseries).

    Parameters
    ----------
    path : ``runs/<name>`` directory
    spec : its manifest entry (default: inferred from the summary's ``ems`` and the name)
    timeseries : also read ``timeseries.csv`` (needed by the time-series figures)

    Raises
    ------
    RunDirError
        Naming the directory or file that is missing, unreadable or inconsistent.
    """
    run_dir = Path(path)
    if not run_dir.is_dir():
        raise RunDirError(f"{run_dir}: run directory missing")
    summary_path = run_dir / "summary.json"
    if not summary_path.is_file():
        raise RunDirError(f"{summary_path}: missing")
    try:
        summary = load_json_file(summary_path, "a run's summary")
    except InputFileError as exc:
        raise RunDirError(f"{summary_path}: not valid JSON ({exc.problem})") from None
    if not isinstance(summary, dict):
        raise RunDirError(f"{summary_path}: not a JSON object")
    missing = [k for k in SUMMARY_KEYS if k not in summary]
    if missing:
        raise RunDirError(f"{summary_path}: lacks key(s) {', '.join(missing)}")
    for key in SUMMARY_KEYS:
        value = summary[key]
        if key == "h2_empty_at":
            continue
        if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
            raise RunDirError(f"{summary_path}: key '{key}' is not a finite number ({value!r})")
    weekly = _read_csv(run_dir / "weekly.csv", WEEKLY_COLUMNS)
    if len(weekly) != int(summary["weeks"]):
        raise RunDirError(
            f"{run_dir}: weekly.csv has {len(weekly)} rows but summary.json says {summary['weeks']} weeks"
        )
    ts = pd.DataFrame()
    if timeseries:
        ts = _read_csv(run_dir / "timeseries.csv", (*REQUIRED_COLUMNS, *TIMESERIES_EXTRA))
        if len(ts) != int(summary["steps"]):
            raise RunDirError(
                f"{run_dir}: timeseries.csv has {len(ts)} rows but summary.json says {summary['steps']} steps"
            )
        try:
            ts["time"] = pd.to_datetime(ts["time"], utc=True)
        except (ValueError, TypeError) as exc:
            raise RunDirError(f"{run_dir / 'timeseries.csv'}: column 'time' is not ISO times ({exc})") from None
    if spec is None:
        ems = str(summary.get("ems", run_dir.name.split("_eta")[0]))
        spec = RunSpec(name=run_dir.name, ems=ems, eta_sys=float(summary.get("eta_sys", float("nan"))))
    return RunData(spec=spec, path=run_dir, summary=summary, weekly=weekly, timeseries=ts)


def read_comparison(compare_dir: str | Path) -> tuple[Manifest, list[RunData]]:
    """Manifest and every run it lists (in manifest order).

    Raises
    ------
    RunDirError
        If the manifest or any listed run directory is missing or corrupt, or the runs
        do not cover the same steps.
    """
    root = Path(compare_dir)
    manifest = read_manifest(root)
    runs = [read_run(root / RUNS_DIR / spec.name, spec) for spec in manifest.runs]
    if not runs:
        raise RunDirError(f"{root / MANIFEST}: lists no runs")
    ref = runs[0]
    for run in runs[1:]:
        if len(run.timeseries) != len(ref.timeseries) or not run.timeseries["time"].equals(ref.timeseries["time"]):
            raise RunDirError(f"{run.path}: covers other time steps than {ref.path} (not the same scenario window)")
    return manifest, runs
