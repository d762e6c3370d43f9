"""Parameter sweeps: a grid of plant-parameter variations per EMS, one table and one plot per KPI.

The paper names a sensitivity analysis of the components as future work
(``sec:conclusion``). A sweep varies any dotted plant parameter of ``config/plant.yaml``
(battery size ``battery.e_max_kwh``, H2 store ``hydrogen.e_max_kwh``, FC efficiency
``fuel_cell.eta_sys``, tariff ``grid.buy_offset_eur_per_kwh``, building resistances
``building.r_*``) over the given values, for every EMS, in parallel processes.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from . import figures  # noqa: E402

#: KPIs tabulated and plotted by default: (summary.json key, axis label with unit).
SWEEP_KPIS: tuple[tuple[str, str], ...] = (
    ("cost_eur_week_median", "electricity cost, weekly median [EUR/week]"),
    ("reimbursement_eur_week_median", "reimbursement, weekly median [EUR/week]"),
    ("discomfort_kh_week_median", "discomfort, weekly median [K h/week]"),
    ("discomfort_kh_total", "discomfort, total [K h]"),
    ("buy_kwh_week_median", "bought, weekly median [kWh/week]"),
    ("sell_kwh_week_median", "sold, weekly median [kWh/week]"),
    ("bess_charged_kwh_week_median", "BESS charged, weekly median [kWh/week]"),
    ("h2_kwh_total", "H2 consumed, total [kWh]"),
    ("loh_end", "LOH at the end [-]"),
    ("fc_working_hours", "FC working hours [h]"),
    ("fc_toggles", "FC start-ups [-]"),
    ("heat_recovered_kwh_total", "FC heat recovered, total [kWh]"),
    ("dhw_unmet_kwh", "unmet DHW [kWh]"),
)


@dataclass
class SweepCase:
    """One point of the grid: EMS, parameter values and run directory name."""

    ems: str
    values: dict[str, Any]
    name: str


def parse_param(text: str) -> tuple[str, list[Any]]:
    """``"battery.e_max_kwh=5,10"`` -> ``("battery.e_max_kwh", [5, 10])`` (values as YAML scalars).

    Raises
    ------
    ValueError
        If the text is not ``PATH=V1[,V2...]`` with a dotted path.
    """
    import yaml

    path, sep, vals = text.partition("=")
    path = path.strip()
    if not sep or "." not in path or not vals.strip():
        raise ValueError(f"--param '{text}': expected SECTION.KEY=V1,V2,... (e.g. battery.e_max_kwh=5,10)")
    values = [yaml.safe_load(v) for v in vals.split(",")]
    if any(v is None for v in values):
        raise ValueError(f"--param '{text}': empty value")
    if len({repr(v) for v in values}) != len(values):
        raise ValueError(f"--param '{text}': a value is given twice")
    return path, values


def _slug(value: Any) -> str:
    return str(value).replace("/", "_").replace(" ", "")


def grid(params: Mapping[str, Sequence[Any]], emss: Sequence[str]) -> list[SweepCase]:
    """Every EMS x every combination of the parameter values, with unique run names."""
    keys = list(params)
    cases = []
    for ems in emss:
        for combo in itertools.product(*(params[k] for k in keys)):
            values = dict(zip(keys, combo))
            name = "__".join([ems, *(f"{k}={_slug(v)}" for k, v in values.items())])
            cases.append(SweepCase(ems, values, name))
    return cases


def table(cases: Sequence[SweepCase], summaries: Sequence[Mapping[str, Any]],
          kpis: Sequence[str]) -> pd.DataFrame:
    """One row per case: EMS, parameter values, the KPIs, run wall time."""
    rows = []
    for case, s in zip(cases, summaries):
        missing = [k for k in kpis if k not in s]
        if missing:
            raise KeyError(f"run {case.name}: summary lacks {', '.join(missing)}")
        rows.append({"ems": case.ems, **case.values, **{k: s[k] for k in kpis},
                     "wall_s": s.get("task_wall_s", s.get("wall_s"))})
    return pd.DataFrame(rows)


def markdown_table(df: pd.DataFrame, digits: int = 3) -> str:
    """The sweep table in Markdown (numbers with ``digits`` decimals)."""

    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.{digits}f}"
        return str(v)

    lines = ["| " + " | ".join(df.columns) + " |", "|" + "|".join("---" for _ in df.columns) + "|"]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def plot_kpi(df: pd.DataFrame, params: Sequence[str], kpi: str, ylabel: str, path: Path) -> Path:
    """KPI over the first swept parameter; one line per EMS and combination of the others."""
    x = params[0]
    rest = list(params[1:])
    fig, ax = plt.subplots(figsize=(6.5, 4))
    styles = ["-", "--", ":", "-."]
    markers = ["o", "s", "^", "D", "v"]
    for ems, sub in df.groupby("ems", sort=False):
        groups = sub.groupby(rest, sort=False) if rest else [((), sub)]
        for i, (key, g) in enumerate(groups):
            key = key if isinstance(key, tuple) else (key,)
            g = g.sort_values(x)
            lab = figures.label(str(ems)) + "".join(f", {k}={v}" for k, v in zip(rest, key))
            ax.plot(g[x], g[kpi], color=figures.colour(str(ems)), ls=styles[i % len(styles)],
                    marker=markers[i % len(markers)], label=lab)
    ax.set_xlabel(x)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title(f"{kpi} over {x}", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=figures.DPI, bbox_inches="tight")
    plt.close(fig)
    return path
