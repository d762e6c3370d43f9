"""The paper's reported figures (``paper_results.yaml``) next to the measured ones.

Each row of ``paper_results.yaml`` names a *measure*: a key of ``summary.json`` or one of
the derived quantities in :data:`DERIVED`. :func:`paper_table` evaluates it for every EMS
of the comparison and returns the rows with the paper's value and the measured one.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from .runs import RunData

#: Data file with the paper's figures (source label inside).
PAPER_RESULTS_FILE = Path(__file__).with_name("paper_results.yaml")
#: Percent per fraction.
PERCENT = 100.0
#: Hours per day.
HOURS_PER_DAY = 24.0


@dataclass
class PaperRow:
    """One compared quantity: label, paper values and measured values per EMS (strings)."""

    key: str
    label: str
    where: str
    paper: dict[str, str | None]
    measured: dict[str, str]


def load_paper_results(path: str | Path = PAPER_RESULTS_FILE) -> dict[str, Any]:
    """Read and check ``paper_results.yaml`` (``source``, ``ems``, ``rows``)."""
    p = Path(path)
    data = yaml.safe_load(p.read_text(encoding="utf-8"))
    if not isinstance(data, dict) or not {"source", "ems", "rows"} <= set(data):
        raise ValueError(f"{p}: needs keys source, ems, rows")
    for i, row in enumerate(data["rows"]):
        missing = {"key", "label", "measure", "where", "paper"} - set(row)
        if missing:
            raise ValueError(f"{p}: rows[{i}] lacks {', '.join(sorted(missing))}")
        if row["measure"] not in DERIVED and not isinstance(row["measure"], str):
            raise ValueError(f"{p}: rows[{i}].measure must be a name")
    return data


def fmt(value: float, digits: int = 2) -> str:
    """Fixed-point number as printed in the report (``digits`` decimals)."""
    return f"{value:.{digits}f}"


def _discomfort_weeks(run: RunData, _: Mapping[str, RunData], __: float) -> str:
    s = run.summary
    return f"{int(s['discomfort_weeks_nonzero'])} of {int(s['weeks'])}"


def _h2_range(run: RunData, _: Mapping[str, RunData], __: float) -> str:
    s = run.summary
    return f"{fmt(s['h2_kwh_week_min'])}..{fmt(s['h2_kwh_week_max'])}"


def _loh_end_pct(run: RunData, _: Mapping[str, RunData], __: float) -> str:
    return fmt(PERCENT * float(run.summary["loh_end"]))


#: The H2 store counts as empty within this fraction of the store above LOH_min [-]
#: (a FC at its minimum power needs about 0.4 kWh of H2 per hour; a remainder of 1 % of the
#: default 1800 kWh store is about a day of minimum operation).
H2_EMPTY_TOL = 0.01


def h2_floor(ems: str, loh_min: float) -> float:
    """The H2 level at which the store of ``ems`` counts as empty [-].

    The plant's ``loh_min``, except for the RBC, which stops its FC at its own limit
    (``rbc.loh_reserve`` in ``config/rbc.yaml``; :func:`comems4build_ros.ems.rbc.loh_floor`).
    """
    if ems != "rbc":
        return loh_min
    from ..ems.rbc import load_rbc_options

    return max(loh_min, load_rbc_options().loh_reserve)


def h2_empty_days_before_end(run: RunData, loh_min: float, tol: float = H2_EMPTY_TOL) -> float | None:
    """Days between the H2 store first falling to ``LOH_min + tol`` and the end of the run, or None [d]."""
    loh = run.timeseries["loh"].to_numpy(dtype=float)
    hit = (loh <= loh_min + tol).nonzero()[0]
    if hit.size == 0:
        return None
    end = pd.Timestamp(run.timeseries["time"].iloc[-1])
    reached = pd.Timestamp(run.timeseries["time"].iloc[int(hit[0])])
    return float((end - reached).total_seconds() / 3600.0 / HOURS_PER_DAY)


def _h2_empty(run: RunData, _: Mapping[str, RunData], loh_min: float) -> str:
    days = h2_empty_days_before_end(run, h2_floor(run.spec.ems, loh_min))
    return "never" if days is None else fmt(days, 1)


def relative_to_mpc_pct(run: RunData, runs: Mapping[str, RunData], key: str) -> float | None:
    """``100 * (x - x_MPC) / x_MPC`` for the summary key ``key``; None without an MPC run [%]."""
    mpc = runs.get("mpc")
    if mpc is None or float(mpc.summary[key]) == 0.0:
        return None
    ref = float(mpc.summary[key])
    return PERCENT * (float(run.summary[key]) - ref) / ref


def _vs_mpc(key: str) -> Callable[[RunData, Mapping[str, RunData], float], str]:
    def measure(run: RunData, runs: Mapping[str, RunData], _: float) -> str:
        value = relative_to_mpc_pct(run, runs, key)
        return "n/a (no MPC run)" if value is None else f"{value:+.2f}"

    return measure


#: Derived measures (name -> function(run, runs by EMS, LOH_min) -> printed value).
DERIVED: dict[str, Callable[[RunData, Mapping[str, RunData], float], str]] = {
    "discomfort_weeks": _discomfort_weeks,
    "h2_range": _h2_range,
    "loh_end_pct": _loh_end_pct,
    "h2_empty_days_before_end": _h2_empty,
    "fc_hours_vs_mpc_pct": _vs_mpc("fc_working_hours"),
    "fc_toggles_vs_mpc_pct": _vs_mpc("fc_toggles"),
}


def measured_value(measure: str, run: RunData, runs: Mapping[str, RunData], loh_min: float) -> str:
    """The measured value of ``measure`` for ``run`` as printed in the report."""
    if measure in DERIVED:
        return DERIVED[measure](run, runs, loh_min)
    if measure not in run.summary:
        raise KeyError(f"{run.path / 'summary.json'}: no key '{measure}' (paper_results.yaml measure)")
    return fmt(float(run.summary[measure]))


def paper_table(
    runs: Mapping[str, RunData], loh_min: float, path: str | Path = PAPER_RESULTS_FILE
) -> tuple[str, list[PaperRow]]:
    """Source label and the paper-vs-measured rows for the EMS in ``runs`` (EMS -> base run)."""
    data = load_paper_results(path)
    rows = []
    for row in data["rows"]:
        paper = {ems: (None if v is None else str(v)) for ems, v in row["paper"].items()}
        measured = {ems: measured_value(row["measure"], run, runs, loh_min) for ems, run in runs.items()}
        rows.append(PaperRow(row["key"], row["label"], row["where"], paper, measured))
    return str(data["source"]).strip(), rows
