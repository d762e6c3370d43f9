"""Sizing study: a design of component sizes per EMS over the year, its costs and Pareto front.

The paper's third item of future work (``sec:conclusion``): at which level the H2 house is
economically beneficial and which component dimensions are optimal. A design point gives
five sizes (:data:`AXES`); :func:`size_overrides` turns them into plant parameters of
``config/plant.yaml`` / ``config/year.yaml``; each point runs the year for each EMS; the
table joins each run's summary with its annual costs (:mod:`comems4build_ros.core.economics`)
and whether it closes the seasonal cycle (:func:`comems4build_ros.core.economics.cycle_closes`);
the Pareto front is that of annual cost (lower is better) against self-sufficiency (higher
is better), per EMS.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from comems4build_ros.core import economics  # noqa: E402
from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.document import Document  # noqa: E402
from comems4build_ros.report.style import figsize, save_figure, styled  # noqa: E402
from comems4build_ros.study.sizing import AXIS_KEYS  # noqa: E402

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


def cost_figures(doc: Document, costs: economics.Costs) -> None:
    """Add the ``Cost figures`` section to ``doc``: the interest rate and every component's figures."""
    doc.h(2, "Cost figures")
    rows = [[c, k, f"{v:g}"] for c in economics.COMPONENTS for k, v in costs[c].items()]
    doc.table(["component", "figure", "value"], [["all", "interest_rate", f"{costs.interest_rate:g}"], *rows])


def report(df: pd.DataFrame, meta: Mapping[str, Any], costs: economics.Costs, figure_png: Path) -> Document:
    """The study's report: design, cost figures, table, Pareto figure, the smallest closing sizes."""
    doc = Document("ComEMS4Build: sizing study over the year")
    weeks = meta["weeks"]
    doc.p(f"Scenario: year (config/year.yaml over config/plant.yaml) from {meta['start'] or '2022-03-01'}, "
          f"{weeks} weeks; EMS: {', '.join(style.ems_label(e) for e in meta['ems'])}; design: {meta['design']} "
          f"of {meta['points']} size points; {len(df)} runs in {meta['wall_s']:.1f} s wall on {meta['workers']}.")
    if float(weeks) < economics.WEEKS_PER_YEAR:
        doc.p(f"The run is {weeks} weeks, not the year: the annual figures are the run's scaled to 52 weeks, "
              "and the seasonal cycle is tested only over the run (n/a when it has no heating-season week).")
    doc.h(2, "Definitions")
    doc.p("Annual cost = energy (bought - sold, eq:costs, per 52 weeks) + annuity of the investments "
          f"(interest {costs.interest_rate:.1%}/a; life = min(calendar life, wear life): the FC's and the "
          "electrolyser's hour life over their working hours per year, the battery's cycle life N_B over its "
          "equivalent full cycles per year, tab:degradation_HESS) + O&M (a share of the investment per year, "
          "the FC's hourly O&M and on/off costs, tab:degradation_HESS). Components not sized (heat pump, tank, "
          "house) are the same at every point and left out. Self-sufficiency = 1 - bought / (appliances + "
          "heat pump + electrolyser).")
    doc.p("The seasonal cycle closes when the summer fills the store (LOH at the heating season's start above "
          "LOH_init; not tested for a run starting inside the season), the store ends the run with at least the "
          "LOH it started with (LOH_end >= LOH_init), never runs dry (LOH never at LOH_min) and the heating season "
          "is served (no heating-season week with discomfort, eq:discomfort). Not tested (n/a) for a run without a "
          "full heating-season week.")
    cost_figures(doc, costs)
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
    from comems4build_ros.report.document import markdown_table

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
