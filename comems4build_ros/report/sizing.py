"""Sizing study: a design of component sizes per EMS over the year, its costs and Pareto front.

The paper's third item of future work (``sec:conclusion``): at which level the H2 house is
economically beneficial and which component dimensions are optimal. A design point gives
five sizes (:data:`AXES`); :func:`size_overrides` turns them into plant parameters of
``config/plant.yaml`` / ``config/year.yaml``; each point runs the year for each EMS; the
table joins each run's summary with its annual costs (:mod:`comems4build_ros.economics`)
and whether it closes the seasonal cycle (:func:`comems4build_ros.economics.cycle_closes`);
the Pareto front is that of annual cost (lower is better) against self-sufficiency (higher
is better), per EMS.
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

from .. import economics  # noqa: E402
from . import style  # noqa: E402
from .document import Document  # noqa: E402
from .style import figsize, save_figure, styled  # noqa: E402


@dataclass(frozen=True)
class Axis:
    """One size axis: its key, command-line option, unit, whether integer, and label."""

    key: str
    option: str
    unit: str
    integer: bool
    label: str


#: The sized components, in table order.
AXES: tuple[Axis, ...] = (
    Axis("pv_kwp", "--pv-kwp", "kWp", False, "PV"),
    Axis("battery_kwh", "--battery-kwh", "kWh", False, "battery"),
    Axis("el_modules", "--el-modules", "-", True, "electrolyser modules (EL 2.1)"),
    Axis("fc_kw", "--fc-kw", "kW", False, "fuel cell, nominal"),
    Axis("h2_kwh", "--h2-kwh", "kWh", False, "H2 store, LHV"),
)
AXIS_KEYS = tuple(a.key for a in AXES)


def plant_sizes(plant: Any) -> dict[str, float]:
    """The sizes of a plant (its parameters as loaded): PV kWp at STC, battery kWh, EL modules,
    FC nominal kW, H2 store kWh (LHV)."""
    return {
        "pv_kwp": plant.pv.n_modules * plant.pv.a_module_m2 * plant.pv.eta_stc,  # 1 kW/m2 at STC
        "battery_kwh": plant.battery.e_max_kwh,
        "el_modules": plant.electrolyser.n_modules,
        "fc_kw": plant.fuel_cell.p_nom_w / 1000.0,
        "h2_kwh": plant.hydrogen.e_max_kwh,
    }


def size_overrides(sizes: Mapping[str, float], plant: Any) -> tuple[dict[str, Any], dict[str, float]]:
    """Plant-parameter overrides realising ``sizes`` on ``plant``, and the sizes as realised.

    - PV: a whole number of the plant's modules, ``round(kWp / (A_module eta_STC))``;
    - battery: capacity, with the charging and discharging power scaled alike (the plant's
      C-rate kept: more modules of the same battery) and its investment of
      ``tab:degradation_HESS`` (which the MPC's degradation weight uses) in proportion;
    - electrolyser: the number of EL 2.1 modules;
    - FC: a whole number of cells of the plant's stack (``n_cells``), P_max, P_nom and P_min
      scaled by the cell ratio (the same cell polarisation), its investment in proportion;
    - H2 store: its LHV energy.

    Raises
    ------
    ValueError
        Naming the option when a size cannot be realised (a PV of no module, an FC of no cell).
    """
    pv, bat, fc, deg = plant.pv, plant.battery, plant.fuel_cell, plant.degradation
    kwp_per_module = pv.a_module_m2 * pv.eta_stc
    n_pv = round(sizes["pv_kwp"] / kwp_per_module)
    if n_pv < 1:
        raise ValueError(f"--pv-kwp {sizes['pv_kwp']}: less than half a module of {kwp_per_module:.3f} kWp")
    ratio_b = sizes["battery_kwh"] / bat.e_max_kwh
    n_cells = round(fc.n_cells * sizes["fc_kw"] * 1000.0 / fc.p_nom_w)
    if n_cells < 1:
        raise ValueError(f"--fc-kw {sizes['fc_kw']}: less than one cell of the stack "
                         f"({fc.p_nom_w / fc.n_cells:.0f} W nominal per cell)")
    ratio_fc = n_cells / fc.n_cells
    overrides = {
        "pv.n_modules": n_pv,
        "battery.e_max_kwh": sizes["battery_kwh"],
        "battery.p_ch_max_w": bat.p_ch_max_w * ratio_b,
        "battery.p_d_max_w": bat.p_d_max_w * ratio_b,
        "degradation.sigma_in_b_eur": deg.sigma_in_b_eur * ratio_b,
        "electrolyser.n_modules": int(sizes["el_modules"]),
        "fuel_cell.n_cells": n_cells,
        "fuel_cell.p_max_w": fc.p_max_w * ratio_fc,
        "fuel_cell.p_nom_w": fc.p_nom_w * ratio_fc,
        "fuel_cell.p_min_w": fc.p_min_w * ratio_fc,
        "degradation.sigma_in_fc_eur": deg.sigma_in_fc_eur * ratio_fc,
        "hydrogen.e_max_kwh": sizes["h2_kwh"],
    }
    realised = {"pv_kwp": round(n_pv * kwp_per_module, 3), "battery_kwh": float(sizes["battery_kwh"]),
                "el_modules": int(sizes["el_modules"]), "fc_kw": round(fc.p_nom_w * ratio_fc / 1000.0, 3),
                "h2_kwh": float(sizes["h2_kwh"])}
    return overrides, realised


def grid_points(values: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """Every combination of the axis values (axes in :data:`AXES` order)."""
    keys = [a.key for a in AXES]
    return [dict(zip(keys, combo)) for combo in itertools.product(*(values[k] for k in keys))]


def sampled_points(values: Mapping[str, Sequence[float]], n: int, seed: int) -> list[dict[str, float]]:
    """``n`` points of a Latin hypercube (``scipy.stats.qmc``, seeded) between the smallest and
    the largest value of each axis; integer axes rounded; points made equal by rounding once."""
    from scipy.stats import qmc

    free = [a for a in AXES if min(values[a.key]) != max(values[a.key])]
    if not free:
        raise ValueError("--sample needs at least one size option with two different values (its range)")
    unit = qmc.LatinHypercube(d=len(free), seed=seed).random(n)
    points, seen = [], set()
    for row in unit:
        p = {a.key: float(min(values[a.key])) for a in AXES}
        for a, u in zip(free, row):
            lo, hi = float(min(values[a.key])), float(max(values[a.key]))
            v = lo + u * (hi - lo)
            p[a.key] = int(round(v)) if a.integer else round(v, 3)
        key = tuple(p[k] for k in AXIS_KEYS)
        if key not in seen:
            seen.add(key)
            points.append(p)
    return points


def point_name(ems: str, sizes: Mapping[str, float]) -> str:
    """Run directory name of a point: ``<ems>__pv9.6_bat6.5_el1_fc2_h21800``."""
    def num(v: float) -> str:
        return f"{v:g}"

    return (f"{ems}__pv{num(sizes['pv_kwp'])}_bat{num(sizes['battery_kwh'])}_el{int(sizes['el_modules'])}"
            f"_fc{num(sizes['fc_kw'])}_h2{num(sizes['h2_kwh'])}")


#: Columns of size.csv after the sizes: (column, unit, from where).
COLUMNS: tuple[tuple[str, str], ...] = (
    ("total_eur_a", "EUR/a"), ("energy_eur_a", "EUR/a"), ("annuity_eur_a", "EUR/a"), ("om_eur_a", "EUR/a"),
    ("invest_eur", "EUR"), ("self_sufficiency", "-"), ("closes", "-"), ("pareto", "-"),
    ("loh_heating_season_start", "-"), ("loh_end", "-"), ("h2_produced_kwh", "kWh"),
    ("el_hours_a", "h/a"), ("fc_hours_a", "h/a"), ("fc_toggles_a", "1/a"), ("battery_cycles_a", "1/a"),
    ("life_fuel_cell_a", "a"), ("life_battery_a", "a"), ("life_electrolyser_a", "a"),
    ("discomfort_kh_total", "K h"), ("heating_season_discomfort_weeks", "-"), ("why", ""),
)


def row(ems: str, name: str, sizes: Mapping[str, float], summary: Mapping[str, Any], costs: economics.Costs,
        usable_battery_kwh: float) -> dict[str, Any]:
    """One row of the table: EMS, sizes, annual costs, self-sufficiency, closure, wear."""
    closes, why = economics.cycle_closes(summary)
    out: dict[str, Any] = {"ems": ems, **{k: sizes[k] for k in AXIS_KEYS}}
    out.update(economics.annual_costs(sizes, summary, costs, usable_battery_kwh))
    out.update({"self_sufficiency": float(summary["self_sufficiency"]), "closes": closes, "why": why,
                "loh_heating_season_start": summary.get("loh_heating_season_start"),
                "loh_end": float(summary["loh_end"]), "h2_produced_kwh": float(summary.get("h2_produced_kwh", 0.0)),
                "discomfort_kh_total": float(summary["discomfort_kh_total"]),
                "heating_season_discomfort_weeks": int(summary.get("heating_season_discomfort_weeks") or 0),
                "run": f"runs/{name}", "wall_s": float(summary.get("task_wall_s", 0.0))})
    return out


def pareto_mask(cost: Sequence[float], gain: Sequence[float]) -> list[bool]:
    """Non-dominated points of (``cost`` lower is better, ``gain`` higher is better).

    A point is dominated when another is no worse in both and better in one.
    """
    pts = list(zip(cost, gain))
    return [not any((c2 <= c and g2 >= g) and (c2 < c or g2 > g) for c2, g2 in pts) for c, g in pts]


def table(rows: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """The study's table with the Pareto front marked per EMS (``pareto``), columns in a fixed order."""
    df = pd.DataFrame(list(rows))
    df["pareto"] = False
    for _, idx in df.groupby("ems", sort=False).groups.items():
        sub = df.loc[idx]
        df.loc[idx, "pareto"] = pareto_mask(sub["total_eur_a"].tolist(), sub["self_sufficiency"].tolist())
    cols = ["ems", *AXIS_KEYS, *[c for c, _ in COLUMNS], "run", "wall_s"]
    return df[cols]


def smallest_closing(df: pd.DataFrame) -> pd.DataFrame:
    """Per EMS, the closing point of the least investment (ties: the least annual cost)."""
    ok = df[df["closes"] == True]  # noqa: E712 (a column of True/False/None)
    if ok.empty:
        return ok
    return ok.sort_values(["invest_eur", "total_eur_a"]).groupby("ems", sort=False).head(1)


@styled
def pareto_figure(df: pd.DataFrame) -> plt.Figure:
    """Annual cost over self-sufficiency, one colour per EMS; filled markers close the cycle, the
    Pareto front of each EMS joined by a line."""
    fig, ax = plt.subplots(figsize=figsize("one-and-half", 80))
    for ems, sub in df.groupby("ems", sort=False):
        colour = style.ems_colour(str(ems))
        closing = sub["closes"] == True  # noqa: E712
        if closing.any():
            ax.scatter(sub.loc[closing, "self_sufficiency"], sub.loc[closing, "total_eur_a"], color=colour,
                       marker="o", s=22, zorder=3, label=f"{style.ems_label(str(ems))}, cycle closes")
        if (~closing).any():
            ax.scatter(sub.loc[~closing, "self_sufficiency"], sub.loc[~closing, "total_eur_a"], facecolors="none",
                       edgecolors=colour, marker="o", s=22, zorder=3,
                       label=f"{style.ems_label(str(ems))}, does not close")
        front = sub[sub["pareto"]].sort_values("self_sufficiency")
        ax.plot(front["self_sufficiency"], front["total_eur_a"], color=colour, lw=1.0, zorder=2,
                label=f"{style.ems_label(str(ems))}, Pareto front")
    ax.set_xlabel("self-sufficiency [–]")
    ax.set_ylabel("annual cost: energy + annuity + O&M [EUR/a]")
    style.outside_legend(ax, ncol=2)
    return fig


def _cell(v: Any) -> Any:
    if v is None or (isinstance(v, float) and pd.isna(v)):
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.3f}" if abs(v) < 10 else f"{v:.0f}"
    return v


def markdown_rows(df: pd.DataFrame, columns: Sequence[str]) -> list[list[Any]]:
    """Rows of ``df`` as printed in the reports (3 decimals below 10, whole numbers above; yes/no/n/a)."""
    return [[_cell(v) for v in r] for r in df[list(columns)].itertuples(index=False)]


def report(df: pd.DataFrame, meta: Mapping[str, Any], costs: economics.Costs, figure_png: Path) -> Document:
    """The study's report: design, cost figures, table, Pareto figure, the smallest closing sizes."""
    doc = Document("ComEMS4Build: sizing study over the year")
    weeks = meta["weeks"]
    doc.p(f"Scenario: year (config/year.yaml over config/plant.yaml) from {meta['start'] or '2022-03-01'}, "
          f"{weeks} weeks; EMS: {', '.join(style.ems_label(e) for e in meta['ems'])}; design: {meta['design']} "
          f"of {meta['points']} size points; {len(df)} runs in {meta['wall_s']:.1f} s wall on {meta['executor']}.")
    if float(weeks) < economics.WEEKS_PER_YEAR:
        doc.p(f"The run is {weeks} weeks, not the year: the annual figures are the run's scaled to 52 weeks, "
              "and the seasonal cycle is tested only over the run (n/a when it has no heating-season week).")
    doc.h(2, "Definitions")
    doc.p("Annual cost = energy (bought - sold, eq:costs, per 52 weeks) + annuity of the investments "
          f"(interest {costs.interest_rate:.1%}/a; life = min(calendar life, wear life): the FC's and the "
          "electrolyser's hour life over their working hours per year, the battery's cycle life N_B over its "
          "equivalent full cycles per year, tab:degradation_HESS) + O&M (a share of the investment per year, "
          "the FC's hourly O&M and on/off costs, tab:degradation_HESS). Components not sized (heat pump, tank, "
          "building) are the same at every point and left out. Self-sufficiency = 1 - bought / (appliances + "
          "heat pump + electrolyser).")
    doc.p("The seasonal cycle closes when the summer fills the store (LOH at the heating season's start above "
          "LOH_init; not tested for a run starting inside the season), the store ends the run with at least the "
          "LOH it started with (LOH_end >= LOH_init), never runs dry (LOH never at LOH_min) and the heating season "
          "is served (no heating-season week with discomfort, eq:discomfort). Not tested (n/a) for a run without a "
          "full heating-season week.")
    doc.h(2, "Cost figures")
    rows = [[c, k, f"{v:g}"] for c in economics.COMPONENTS for k, v in costs[c].items()]
    doc.table(["component", "figure", "value"], [["all", "interest_rate", f"{costs.interest_rate:g}"], *rows])
    doc.p("Sources and choices: config/costs.yaml (the paper's tab:degradation_HESS for the FC and the battery, "
          "Fraunhofer ISE 2024 for PV; figures marked 'choice' there are assumptions).")
    doc.h(2, "Smallest sizes that close the cycle")
    small = smallest_closing(df)
    if small.empty:
        doc.p("No point of the design closes the seasonal cycle.")
    else:
        doc.p("Per EMS, the closing point of the least investment:")
        cols = ["ems", *AXIS_KEYS, "invest_eur", "total_eur_a", "self_sufficiency", "loh_end"]
        doc.table(cols, markdown_rows(small, cols))
    for ems, sub in df.groupby("ems", sort=False):
        n_ok = int((sub["closes"] == True).sum())  # noqa: E712
        n_na = int(sub["closes"].isna().sum())
        doc.p(f"{style.ems_label(str(ems))}: {n_ok} of {len(sub)} points close the cycle"
              + (f" ({n_na} not tested)" if n_na else "") + ".")
    doc.h(2, "Pareto front")
    doc.figure(figure_png, "figures", "Annual cost against self-sufficiency per EMS; filled markers close the "
               "seasonal cycle; the line joins each EMS's Pareto front (no other point of that EMS is cheaper and "
               "more self-sufficient).")
    front = df[df["pareto"]].sort_values(["ems", "self_sufficiency"])
    cols = ["ems", *AXIS_KEYS, "total_eur_a", "self_sufficiency", "closes"]
    doc.table(cols, markdown_rows(front, cols))
    doc.h(2, "All points")
    cols = ["ems", *AXIS_KEYS, *[c for c, _ in COLUMNS if c != "why"], "run"]
    doc.table(cols, markdown_rows(df, cols))
    doc.p("Why a point does not close: " + "; ".join(
        f"{r.run}: {r.why}" for r in df.itertuples() if r.closes is not True) if (df["closes"] != True).any()  # noqa: E712
          else "Every point closes the cycle.")
    return doc


def write_outputs(df: pd.DataFrame, meta: Mapping[str, Any], costs: economics.Costs, out: Path) -> dict[str, Path]:
    """size.csv, size.md (the table), figures/pareto.{pdf,svg,png}, report.md, report.html in ``out``."""
    from .document import markdown_table

    out = Path(out)
    df.to_csv(out / "size.csv", index=False)
    cols = list(df.columns)
    (out / "size.md").write_text(markdown_table(markdown_rows(df, cols), cols) + "\n", encoding="utf-8")
    png = save_figure(pareto_figure(df), out / "figures" / "pareto")
    doc = report(df, meta, costs, png)
    (out / "report.md").write_text(doc.markdown(), encoding="utf-8")
    (out / "report.html").write_text(doc.html(), encoding="utf-8")
    return {"csv": out / "size.csv", "md": out / "size.md", "figure": png, "report": out / "report.md",
            "html": out / "report.html"}
