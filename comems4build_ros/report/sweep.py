"""Parameter sweeps: a grid of plant-parameter variations per EMS, one table and one plot per KPI.

The paper names a sensitivity analysis of the components as future work
(``sec:conclusion``). A sweep varies any dotted plant parameter of ``config/plant.yaml``
(battery size ``battery.e_max_kwh``, H2 store ``hydrogen.e_max_kwh``, FC efficiency
``fuel_cell.eta_sys``, tariff ``grid.buy_offset_eur_per_kwh``, building resistances
``building.r_*``) over the given values, for every EMS, in parallel processes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.style import figsize, save_figure, styled  # noqa: E402
from comems4build_ros.study.sweep import SweepCase  # noqa: E402

#: KPIs tabulated and plotted by default: (summary.json key, axis label with unit).
SWEEP_KPIS: tuple[tuple[str, str], ...] = (
    ("cost_eur_week_median", "electricity cost, weekly median [EUR/week]"),
    ("reimbursement_eur_week_median", "reimbursement, weekly median [EUR/week]"),
    ("discomfort_kh_week_median", "discomfort, weekly median [K h/week]"),
    ("discomfort_kh_total", "discomfort, total [K h]"),
    ("buy_kwh_week_median", "bought, weekly median [kWh/week]"),
    ("sell_kwh_week_median", "sold, weekly median [kWh/week]"),
    ("bess_charged_kwh_week_median", "BESS charged, weekly median [kWh/week]"),
    ("h2_kwh_total", r"$\mathrm{H_2}$ consumed, LHV, total [kWh]"),
    ("loh_end", r"$\mathit{LOH}$ at the end [–]"),
    ("fc_working_hours", "FC working hours [h]"),
    ("fc_toggles", "FC start-ups [–]"),
    ("heat_recovered_kwh_total", r"recovered FC heat $\dot{Q}_\mathrm{FC,hr}$, total [kWh]"),
    ("dhw_unmet_kwh", "unmet DHW [kWh]"),
)

#: KPIs added for the year-round scenario (``--scenario year``; docs/seasonal.md), the sizing figures.
YEAR_SWEEP_KPIS: tuple[tuple[str, str], ...] = (
    ("loh_heating_season_start", r"$\mathit{LOH}$ at the start of the heating season [–]"),
    ("h2_produced_kwh", r"$\mathrm{H_2}$ produced, LHV [kWh]"),
    ("el_working_hours", "electrolyser working hours [h]"),
    ("self_sufficiency", "self-sufficiency [–]"),
    ("cost_net_eur", "cost, bought - sold [EUR]"),
    ("heating_season_discomfort_weeks", "heating-season weeks with discomfort [–]"),
)


def sweep_kpis(scenario: str) -> tuple[tuple[str, str], ...]:
    """KPIs of a sweep over ``scenario``: :data:`SWEEP_KPIS`, plus :data:`YEAR_SWEEP_KPIS` for the year."""
    return SWEEP_KPIS + YEAR_SWEEP_KPIS if str(scenario) == "year" else SWEEP_KPIS


#: Axis labels of common sweep parameters (dotted path of ``config/plant.yaml`` -> label with unit).
PARAM_LABELS: dict[str, str] = {
    "battery.e_max_kwh": r"battery capacity $E_\mathrm{B,max}$ [kWh]",
    "battery.p_ch_max_w": r"battery charging power $P_\mathrm{B,ch,max}$ [W]",
    "battery.p_d_max_w": r"battery discharging power $P_\mathrm{B,d,max}$ [W]",
    "hydrogen.e_max_kwh": r"$\mathrm{H_2}$ store, LHV [kWh]",
    "fuel_cell.eta_sys": r"FC system efficiency $\eta_\mathrm{sys,FC}$ [–]",
    "fuel_cell.p_max_w": r"FC maximal power $P_\mathrm{FC,max}$ [W]",
    "fuel_cell.zeta": r"FC security factor $\zeta$ [–]",
    "pv.n_modules": r"PV modules $N_\mathrm{PV}$ [–]",
    "dhw.v_max_l": r"DHW tank $V_\mathrm{DHW,max}$ [l]",
    "grid.surcharge_eur_per_kwh": "tariff surcharge [EUR/kWh]",
    "grid.price_sell_eur_per_kwh": r"sell price $p_\mathrm{sell}$ [EUR/kWh]",
    "heat_pump.p_el_max_w": r"HP maximal power $P_\mathrm{el,HP,max}$ [W]",
    "electrolyser.n_modules": "electrolyser modules (EL 2.1) [–]",
}
#: Unit suffixes of parameter names -> unit as printed (longest first).
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_eur_per_kwh", "EUR/kWh"), ("_eur_per_h", "EUR/h"), ("_k_per_w", "K/W"), ("_j_per_k", "J/K"),
    ("_w_m2", r"W/m$^2$"), ("_kwh", "kWh"), ("_eur", "EUR"), ("_deg", "°"), ("_w", "W"), ("_l", "l"),
    ("_c", "°C"), ("_h", "h"), ("_m2", r"m$^2$"),
)


def param_label(path: str) -> str:
    """Axis label of a swept parameter: :data:`PARAM_LABELS`, else its words and the unit of its suffix."""
    if path in PARAM_LABELS:
        return PARAM_LABELS[path]
    section, _, key = path.partition(".")
    unit = "–"
    for suffix, printed in UNIT_SUFFIXES:
        if key.endswith(suffix):
            key, unit = key[: -len(suffix)], printed
            break
    return f"{section.replace('_', ' ')}: {key.replace('_', ' ')} [{unit}]"


def _value_text(path: str, value: Any) -> str:
    """``label = value unit`` for legends (symbol only when the label has one)."""
    lab = param_label(path)
    name, _, unit = lab.rpartition(" [")
    unit = unit.rstrip("]")
    unit = "" if unit in ("–", "-") else f" {unit}"
    return f"{name} = {value}{unit}"


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


@styled
def kpi_figure(df: pd.DataFrame, params: Sequence[str], kpi: str, ylabel: str) -> plt.Figure:
    """KPI over the first swept parameter; one line per EMS and combination of the others."""
    x = params[0]
    rest = list(params[1:])
    fig, ax = plt.subplots(figsize=figsize("one-and-half", 70))
    styles = ["-", "--", ":", "-."]
    markers = ["o", "s", "^", "D", "v"]
    for ems, sub in df.groupby("ems", sort=False):
        groups = sub.groupby(rest, sort=False) if rest else [((), sub)]
        for i, (key, g) in enumerate(groups):
            key = key if isinstance(key, tuple) else (key,)
            g = g.sort_values(x)
            lab = style.ems_label(str(ems)) + "".join(f", {_value_text(k, v)}" for k, v in zip(rest, key))
            ax.plot(g[x], g[kpi], color=style.ems_colour(str(ems)), ls=styles[i % len(styles)],
                    marker=markers[i % len(markers)], label=lab)
    ax.set_xlabel(param_label(x))
    ax.set_ylabel(ylabel)
    n = len(ax.get_legend_handles_labels()[0])
    style.outside_legend(ax, ncol=n if n <= 3 and not rest else 2)
    return fig


def plot_kpi(df: pd.DataFrame, params: Sequence[str], kpi: str, ylabel: str, path: Path) -> Path:
    """Write :func:`kpi_figure` as PDF, SVG and 300 dpi PNG (``path`` without or with suffix); returns the PNG."""
    return save_figure(kpi_figure(df, params, kpi, ylabel), path)
