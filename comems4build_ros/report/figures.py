"""Figures of a comparison, after the figures of the paper's ``sec:results``.

Each figure has a builder ``<name>_figure(...) -> Figure``; the figures are saved with
:func:`~comems4build_ros.report.style.save_figure` (PDF, SVG and a 300 dpi PNG).
:data:`FIGURES` lists the figures of a report
(built from :class:`FigureInputs`), :func:`iter_figures` yields them and
:func:`all_figures` writes them, in parallel processes. The style (sizes of a two-column paper,
colour-blind-safe colours, one colour per EMS, mathtext labels with units, legends outside
the data) is :mod:`comems4build_ros.report.style`.

Three-day windows of the time-series figures: the paper's, located as its text describes
them (:func:`comems4build_ros.report.paper.paper_windows`): fig:performance_comparison from
2022-12-03, fig:performance_comparison_highSolar after two months, with high PV and buy
prices down to 0.23 EUR/kWh; other runs get the days of highest mean buy price and the
sunniest days.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from comems4build_ros.core.config import W_PER_KW  # noqa: E402
from comems4build_ros.core.ems.base import INFO_LEVELS  # noqa: E402
from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.paper import paper_windows  # noqa: E402
from comems4build_ros.report.runs import RunData  # noqa: E402
from comems4build_ros.report.style import SIGNAL_COLOURS, axis_label, figsize, save_figure, styled  # noqa: E402

#: Longest span whose date axis labels every day [d].
DAY_LABEL_MAX_DAYS = 8
#: Longest span whose date axis writes day and month at about eight ticks [d].
DATE_LABEL_MAX_DAYS = 42
#: Longest span with ticks on the 1st and 15th of each month [d].
HALF_MONTH_MAX_DAYS = 130
#: Percent per fraction.
PERCENT = 100.0
#: Head room above the tallest bar for its value label [fraction of the tallest bar].
BAR_HEADROOM = 0.16
#: Transparency of boxes and of the bars of the non-base FC efficiencies [-].
BOX_ALPHA = 0.35
OTHER_ETA_ALPHA = 0.35
#: Neutral colour of the efficiency entries of the heat-recovery legend.
ETA_LEGEND_COLOUR = "#333333"

colour = style.ems_colour
label = style.ems_label


def _local_naive(time: pd.Series, tz: str) -> np.ndarray:
    """UTC times as naive local ``datetime64`` (cheap for matplotlib's date axis)."""
    return time.dt.tz_convert(tz).dt.tz_localize(None).to_numpy()


def _date_axis(ax: plt.Axes, days: float) -> None:
    """Horizontal date ticks that never wrap or collide with a neighbour's.

    Up to :data:`DAY_LABEL_MAX_DAYS` days: grid lines at midnight and the date written at
    noon, inside its day (no label at the edges of the axes); up to
    :data:`DATE_LABEL_MAX_DAYS` days: about eight dated ticks; up to
    :data:`HALF_MONTH_MAX_DAYS` days: the 1st and 15th of each month; longer: concise dates.
    """
    if days <= DAY_LABEL_MAX_DAYS:
        ax.xaxis.set_major_locator(mdates.DayLocator())
        ax.xaxis.set_major_formatter(plt.NullFormatter())
        ax.xaxis.set_minor_locator(mdates.HourLocator(byhour=(12,)))
        ax.xaxis.set_minor_formatter(mdates.DateFormatter("%-d %b"))
        ax.tick_params(axis="x", which="minor", length=0)
    elif days <= DATE_LABEL_MAX_DAYS:
        ax.xaxis.set_major_locator(mdates.DayLocator(interval=max(1, int(np.ceil(days / 8)))))
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%-d %b"))
    elif days <= HALF_MONTH_MAX_DAYS:
        ax.xaxis.set_major_locator(mdates.DayLocator(bymonthday=(1, 15)))
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%-d %b"))
    else:
        locator = mdates.AutoDateLocator(minticks=3, maxticks=8)
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator, show_offset=False))
    for t in ax.get_xticklabels(which="both"):
        t.set_rotation(0)


def run_time_axis(ax: plt.Axes, time: pd.Series, tz: str) -> None:
    """The date axis of a run over its span (:func:`_date_axis`) with the local-time label (UTC ``time``)."""
    t = _local_naive(time, tz)
    _date_axis(ax, float((t[-1] - t[0]) / np.timedelta64(1, "D")) if len(t) > 1 else 1.0)
    ax.set_xlabel(f"local time ({tz})")


def percent_run_axes(ax: plt.Axes, quantity: str, time: pd.Series, tz: str) -> None:
    """Finish the axes of a level over a run: its label [%], the range 0 to 102 %, the run's date
    axis (:func:`run_time_axis`) and the legend outside."""
    ax.set_ylabel(axis_label(quantity, "%"))
    ax.set_ylim(0, 102)
    run_time_axis(ax, time, tz)
    style.outside_legend(ax)


def group_bar_x(x: np.ndarray, i: int, n: int, width: float) -> np.ndarray:
    """Positions of the ``i``-th of ``n`` bars side by side around each group position ``x``."""
    return x + (i - (n - 1) / 2) * width


def _boxes(ax: plt.Axes, runs: Mapping[str, RunData], column: str, ylabel: str, title: str) -> None:
    """Weekly box plot of one KPI, one box per EMS, weekly values as dots."""
    names = list(runs)
    data = [runs[e].weekly[column].to_numpy(float) for e in names]
    bp = ax.boxplot(data, patch_artist=True, widths=0.55, medianprops={"color": "black", "linewidth": 1.0},
                    showfliers=False)
    for patch, e in zip(bp["boxes"], names):
        patch.set_facecolor(colour(e))
        patch.set_alpha(BOX_ALPHA)
        patch.set_edgecolor(colour(e))
    rng = np.random.default_rng(0)
    for i, (e, vals) in enumerate(zip(names, data), start=1):
        ax.scatter(i + rng.uniform(-0.12, 0.12, len(vals)), vals, s=7, color=colour(e), zorder=3, linewidths=0)
    ax.set_xticks(range(1, len(names) + 1), [label(e) for e in names])
    ax.tick_params(axis="x", length=0)
    ax.set_ylabel(ylabel)
    ax.set_title(title, loc="left")
    ax.grid(axis="x", visible=False)


@styled
def quality_indicators_figure(runs: Mapping[str, RunData]) -> Figure:
    """Weekly discomfort, electricity cost and reimbursement (after ``fig:quality_indicators_occupants``)."""
    fig, axes = plt.subplots(1, 3, figsize=figsize("double", 62))
    _boxes(axes[0], runs, "discomfort_kh", "discomfort [K h/week]", "(a) Thermal discomfort")
    _boxes(axes[1], runs, "cost_eur", "cost [EUR/week]", "(b) Electricity cost")
    _boxes(axes[2], runs, "reimbursement_eur", "reimbursement [EUR/week]", "(c) Reimbursement")
    return fig


@styled
def hess_usage_figure(runs: Mapping[str, RunData]) -> Figure:
    """Weekly BESS charged energy and H2 consumption (after ``fig:HESS_usage``)."""
    fig, axes = plt.subplots(2, 1, figsize=figsize("single", 100), sharex=True)
    _boxes(axes[0], runs, "bess_charged_kwh", "charged [kWh/week]", "(a) Battery charging")
    # the paper's weekly "H2 consumption" (54.11..78.54 kWh for ComEMS4Build) fits the FC's
    # electrical output, not the LHV drawn from the store (about twice as much)
    _boxes(axes[1], runs, "fc_kwh", r"$\mathrm{H_2}$ used, FC output [kWh/week]", "(b) Hydrogen consumption")
    return fig


@styled
def grid_usage_figure(runs: Mapping[str, RunData]) -> Figure:
    """Weekly purchased and sold energy (after ``fig:grid_usage``)."""
    fig, axes = plt.subplots(2, 1, figsize=figsize("single", 100), sharex=True)
    _boxes(axes[0], runs, "buy_kwh", "purchased [kWh/week]", "(a) Energy bought from the grid")
    _boxes(axes[1], runs, "sell_kwh", "sold [kWh/week]", "(b) Energy sold to the grid")
    return fig


@styled
def working_hours_fc_figure(runs: Mapping[str, RunData]) -> Figure:
    """FC working hours and start-ups over the run (after ``fig:working_hours_FC``)."""
    names = list(runs)
    fig, axes = plt.subplots(1, 2, figsize=figsize("one-and-half", 55))
    for ax, key, ylabel, title in (
        (axes[0], "fc_working_hours", "working hours [h]", "(a) Fuel-cell working hours"),
        (axes[1], "fc_toggles", "start-ups [–]", "(b) Fuel-cell start-ups"),
    ):
        vals = [float(runs[e].summary[key]) for e in names]
        bars = ax.bar([label(e) for e in names], vals, color=[colour(e) for e in names], width=0.6)
        ax.bar_label(bars, fmt="%.0f", padding=1.5, fontsize=7)
        ax.set_ylim(0, max(max(vals), 1.0) * (1.0 + BAR_HEADROOM))
        ax.set_ylabel(ylabel)
        ax.set_title(title, loc="left")
        ax.tick_params(axis="x", length=0)
        ax.grid(axis="x", visible=False)
    return fig


@styled
def hydrogen_timeseries_figure(runs: Mapping[str, RunData], tz: str) -> Figure:
    """LOH of every EMS, buy price and global radiation over the run (after ``fig:hydrogen_timeseries``)."""
    fig, axes = plt.subplots(2, 1, figsize=figsize("double", 105), sharex=True,
                             gridspec_kw={"height_ratios": [3, 2]})
    for e, r in runs.items():
        t = _local_naive(r.timeseries["time"], tz)
        axes[0].plot(t, PERCENT * r.timeseries["loh"], color=colour(e), label=label(e), lw=1.3)
    axes[0].set_ylabel(axis_label("loh", "%"))
    axes[0].set_ylim(0, 102)
    style.outside_legend(axes[0])
    ts = next(iter(runs.values())).timeseries
    t = _local_naive(ts["time"], tz)
    ax = axes[1]
    ax.plot(t, ts["price_buy_eur_per_kwh"], color=SIGNAL_COLOURS["main"], lw=0.7,
            label="buy price " + axis_label("p_buy"))
    ax.set_ylabel(axis_label("p_buy", "EUR_kWh"))
    ax2 = ax.twinx()
    style.no_twin_grid(ax2)
    ax2.fill_between(t, ts["ghi_w_m2"], color=SIGNAL_COLOURS["radiation"], alpha=0.45, lw=0,
                     label="global radiation " + axis_label("q_s"))
    ax2.set_ylabel(axis_label("q_s", "W_m2"))
    ax2.set_ylim(bottom=0)
    ax.set_zorder(ax2.get_zorder() + 1)  # price line over the radiation area
    ax.patch.set_visible(False)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    style.outside_legend(ax, h1 + h2, l1 + l2)
    ax.set_xlabel(f"local time ({tz})")
    days = (t[-1] - t[0]) / np.timedelta64(1, "D") if len(t) > 1 else 1.0
    _date_axis(ax, float(days))
    return fig


@styled
def heat_recovery_figure(variants: Mapping[tuple[str, float], RunData], base_eta: float) -> Figure:
    """Weekly recovered FC heat per EMS at each FC system efficiency (after ``fig:heat_recovery``).

    Bars at the base efficiency are opaque, bars at other efficiencies transparent and
    drawn behind; a black tick over each bar marks that run's weekly DHW demand including
    the tank losses.
    """
    emss = ordered(list(dict.fromkeys(e for e, _ in variants)))
    etas = sorted({eta for _, eta in variants}, reverse=True)
    base = variants[(emss[0], base_eta)] if (emss[0], base_eta) in variants else next(iter(variants.values()))
    weeks = base.weekly["week"].to_numpy(int)
    width = 0.8 / len(emss)
    fig, ax = plt.subplots(figsize=figsize("double", 72))
    for i, e in enumerate(emss):
        x = weeks - 0.4 + width * (i + 0.5)
        for eta in etas:
            run = variants.get((e, eta))
            if run is None:
                continue
            is_base = abs(eta - base_eta) < 1e-9
            ax.bar(x, run.weekly["heat_recovered_kwh"], width=width * 0.92, color=colour(e),
                   alpha=1.0 if is_base else OTHER_ETA_ALPHA, edgecolor=colour(e), linewidth=0.5)
        demand = variants.get((e, base_eta), next(r for (ee, _), r in variants.items() if ee == e))
        ax.scatter(x, demand.weekly["dhw_demand_kwh"], marker="_", s=60, color="black", zorder=4, linewidths=1.2)
    handles = [Patch(color=colour(e), label=label(e)) for e in emss]
    for eta in etas:
        is_base = abs(eta - base_eta) < 1e-9
        handles.append(Patch(facecolor=ETA_LEGEND_COLOUR, alpha=1.0 if is_base else OTHER_ETA_ALPHA,
                             label=f"{axis_label('eta_fc_sys')} = {eta * PERCENT:.0f} %"))
    handles.append(Line2D([], [], color="black", marker="_", ls="none", markersize=9, markeredgewidth=1.2,
                          label="DHW demand incl. tank losses"))
    style.outside_legend(ax, handles, [h.get_label() for h in handles])
    ax.set_xticks(weeks)
    ax.set_xlim(weeks[0] - 0.6, weeks[-1] + 0.6)
    ax.set_xlabel("week of the evaluation period")
    ax.set_ylabel(f"recovered heat {axis_label('Q_fc_hr')} [kWh/week]")
    ax.grid(axis="x", visible=False)
    return fig


#: Fixed layout of the window figure [mm]: margins, gaps, the space for the twin axes'
#: labels right of the last column and the legend column (no layout engine: fast and the
#: same for every run).
WINDOW_LAYOUT_MM = {"width": 190.0, "height": 225.0, "left": 14.0, "right": 1.0, "top": 7.0, "bottom": 11.0,
                    "column_gap": 2.5, "row_gap": 2.5, "twin_labels": 11.5, "legend": 33.0}


def _window_grid(fig: Figure, n: int) -> tuple[object, list[int], int]:
    """Grid of the window figure: the grid spec, the grid columns of the EMS and of the legends."""
    m = WINDOW_LAYOUT_MM
    data_w = (m["width"] - m["left"] - m["right"] - m["column_gap"] * (n - 1) - m["twin_labels"] - m["legend"]) / n
    ratios: list[float] = []
    columns = []
    for j in range(n):
        columns.append(len(ratios))
        ratios.append(data_w)
        if j < n - 1:
            ratios.append(m["column_gap"])
    ratios += [m["twin_labels"], m["legend"]]
    row_h = (m["height"] - m["top"] - m["bottom"] - 4 * m["row_gap"]) / 5
    gs = fig.add_gridspec(5, len(ratios), width_ratios=ratios, wspace=0.0, hspace=m["row_gap"] / row_h,
                          left=m["left"] / m["width"], right=1.0 - m["right"] / m["width"],
                          top=1.0 - m["top"] / m["height"], bottom=m["bottom"] / m["height"])
    return gs, columns, len(ratios) - 1


def _step(ax: plt.Axes, t: np.ndarray, y: pd.Series | np.ndarray, **kwargs: object) -> None:
    ax.step(t, y, where="post", **kwargs)


@styled
# Long on purpose: one block per row of the paper's fig:performance_comparison, each setting up
# its axes and legend; the rows share the figure's grid, scales and colours.
def performance_comparison_figure(
    runs: Mapping[str, RunData], window: tuple[int, int], tz: str, v_max_l: float
) -> Figure:
    """A window of every EMS, one column per EMS (after ``fig:performance_comparison``).

    Rows: T_air with its bounds and V_DHW; PV and demand (appliances + HP); grid exchange
    with the buy price; battery SOC and power; LOH and FC power. Every row has one y scale
    for all columns (shared axes); the legends of the rows are in a column of their own.
    """
    names = list(runs)
    n = len(names)
    a, b = window
    m = WINDOW_LAYOUT_MM
    fig = plt.figure(figsize=figsize(m["width"], m["height"]), layout="none")
    gs, grid_columns, legend_column = _window_grid(fig, n)
    axes: list[list[plt.Axes]] = [[] for _ in range(5)]
    twins: list[list[plt.Axes | None]] = [[] for _ in range(5)]
    for j, e in enumerate(names):
        ts = runs[e].timeseries.iloc[a:b]
        t = _local_naive(ts["time"], tz)
        col = []
        for r in range(5):
            ax = fig.add_subplot(gs[r, grid_columns[j]], sharex=col[0] if col else None,
                                 sharey=axes[r][0] if j else None)
            col.append(ax)
            axes[r].append(ax)
        ax = col[0]
        ax.plot(t, ts["t_air_c"], color=SIGNAL_COLOURS["main"], lw=1.1, label=axis_label("t_air"))
        _step(ax, t, ts["t_min_c"], color=SIGNAL_COLOURS["bound"], ls="--", lw=0.8,
              label=f"{axis_label('t_air_min')}, {axis_label('t_air_max')}")
        _step(ax, t, ts["t_max_c"], color=SIGNAL_COLOURS["bound"], ls="--", lw=0.8)
        ax.set_title(label(e), color=colour(e), fontweight="bold")
        twin = ax.twinx()
        twin.plot(t, PERCENT * ts["v_dhw_l"] / v_max_l, color=SIGNAL_COLOURS["dhw"], lw=0.9,
                  label=axis_label("v_dhw"))
        twin.set_ylim(0, 105)
        twins[0].append(twin)

        ax = col[1]
        ax.fill_between(t, ts["p_pv_w"] / W_PER_KW, step="post", color=SIGNAL_COLOURS["pv"], alpha=0.5, lw=0,
                        label=axis_label("P_pv"))
        _step(ax, t, (ts["p_load_w"] + ts["p_hp_el_w"]) / W_PER_KW, color=SIGNAL_COLOURS["main"], lw=0.9,
              label=f"{axis_label('P_load')} + {axis_label('P_hp')}")
        _step(ax, t, ts["p_hp_el_w"] / W_PER_KW, color=SIGNAL_COLOURS["hp"], lw=0.9, label=axis_label("P_hp"))
        twins[1].append(None)

        ax = col[2]
        _step(ax, t, ts["p_buy_w"] / W_PER_KW, color=SIGNAL_COLOURS["main"], lw=0.9, label=axis_label("P_buy"))
        _step(ax, t, -ts["p_sell_w"] / W_PER_KW, color=SIGNAL_COLOURS["sell"], lw=0.9,
              label="$-$" + axis_label("P_sell"))
        twin = ax.twinx()
        _step(twin, t, ts["price_buy_eur_per_kwh"], color=SIGNAL_COLOURS["price"], lw=0.9, ls=":",
              label=axis_label("p_buy"))
        twins[2].append(twin)

        ax = col[3]
        ax.plot(t, PERCENT * ts["soc"], color=SIGNAL_COLOURS["main"], lw=1.1, label=axis_label("soc"))
        ax.set_ylim(0, 100)
        twin = ax.twinx()
        _step(twin, t, (ts["p_ch_w"] - ts["p_dis_w"]) / W_PER_KW, color=SIGNAL_COLOURS["battery"], lw=0.8,
              label=f"{axis_label('P_b')} (charging > 0)")
        twins[3].append(twin)

        ax = col[4]
        ax.plot(t, PERCENT * ts["loh"], color=SIGNAL_COLOURS["main"], lw=1.1, label=axis_label("loh"))
        ax.set_ylim(0, 100)
        twin = ax.twinx()
        _step(twin, t, ts["p_fc_w"] / W_PER_KW, color=SIGNAL_COLOURS["fc"], lw=0.8, label=axis_label("P_fc"))
        twins[4].append(twin)
        days = (b - a) / 24.0
        col[4].set_xlim(t[0], t[-1] + np.timedelta64(1, "h"))
        _date_axis(col[4], days)
        for r, ax in enumerate(col):
            if r < 4:
                ax.tick_params(axis="x", which="both", labelbottom=False)
            if j:
                ax.tick_params(axis="y", which="both", labelleft=False)
    labels = (
        (axis_label("t_air", "degC"), f"{axis_label('v_dhw')} [% of {axis_label('v_dhw_max')}]"),
        ("power [kW]", None),
        ("grid power [kW]", axis_label("p_buy", "EUR_kWh")),
        (axis_label("soc", "%"), axis_label("P_b", "kW")),
        (axis_label("loh", "%"), axis_label("P_fc", "kW")),
    )
    for r, (left, right) in enumerate(labels):
        axes[r][0].set_ylabel(left)
        row_twins = [tw for tw in twins[r] if tw is not None]
        for k, tw in enumerate(row_twins):
            style.no_twin_grid(tw)
            if k:
                tw.sharey(row_twins[0])
            if k < len(row_twins) - 1:
                tw.tick_params(labelright=False)
        if row_twins and right:
            row_twins[-1].set_ylabel(right)
        handles, texts = axes[r][0].get_legend_handles_labels()
        if row_twins:
            h2, t2 = row_twins[0].get_legend_handles_labels()
            handles, texts = handles + h2, texts + t2
        lax = fig.add_subplot(gs[r, legend_column])
        lax.axis("off")
        lax.legend(handles, texts, loc="center left", borderaxespad=0.0, handlelength=1.6)
    fig.supxlabel(f"local time ({tz})", fontsize=8, y=0.004, va="bottom")
    return fig


#: Paper's column groups of tab:level_of_information -> observation fields that carry them.
INFO_COLUMNS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("forecasts (models and profiles)", ("forecast",)),
    ("future temp. bounds", ("t_min_5h_c",)),
    ("24 h-ahead el. tariffs", ("prices_buy_24h",)),
    ("T_amb", ("t_amb_c",)),
    ("solar radiation q_s", ("ghi_w_m2",)),
    ("T_air", ("t_air_c",)),
    ("V_DHW", ("v_dhw_l",)),
    ("SOC", ("soc",)),
    ("LOH", ("loh",)),
    ("daily permissible H2 (dLOH)", ("dloh_per_day",)),
    ("FC previous on/off state", ("fc_on_prev",)),
)


#: Column headers of the table figure (same order as :data:`INFO_COLUMNS`), mathtext symbols.
FIGURE_HEADERS = (
    "forecasts\n(models,\nprofiles)", "comfort\nbounds\n5 h ahead", "24 h-ahead\ntariffs", axis_label("t_amb"),
    axis_label("q_s"), axis_label("t_air"), axis_label("v_dhw"), axis_label("soc"), axis_label("loh"),
    "daily\npermissible\n" + axis_label("dloh"), "FC on/off\nat $k-1$",
)
#: Share of the table width of the first column [-].
TABLE_FIRST_COLUMN = 0.17
#: Height of the header row over a body row [-].
TABLE_HEADER_ROWS = 3.2


def level_of_information_rows(levels: Mapping[str, str]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the paper's table of inputs per EMS (``tab:level_of_information``).

    Parameters
    ----------
    levels : EMS name -> its information level (:data:`~comems4build_ros.core.ems.base.INFO_LEVELS`)
    """
    header = ["EMS (level)", *(c for c, _ in INFO_COLUMNS)]
    rows = []
    for ems, level in levels.items():
        fields = INFO_LEVELS[level]
        rows.append([f"{label(ems)} ({level})", *("yes" if all(f in fields for f in fs) else "-"
                                                   for _, fs in INFO_COLUMNS)])
    return header, rows


@styled
def level_of_information_figure(levels: Mapping[str, str]) -> Figure:
    """The inputs each EMS may use, as a table figure (after ``tab:level_of_information``)."""
    _, rows = level_of_information_rows(levels)
    fig, ax = plt.subplots(figsize=figsize("double", 16 + 6.5 * len(rows)))
    ax.axis("off")
    cells = [[("\u2713" if v == "yes" else "") if i else v for i, v in enumerate(r)] for r in rows]
    short = ["EMS\n(information level)", *FIGURE_HEADERS]
    rest = (1.0 - TABLE_FIRST_COLUMN) / len(FIGURE_HEADERS)
    table = ax.table(cellText=cells, colLabels=short, colWidths=[TABLE_FIRST_COLUMN, *([rest] * len(FIGURE_HEADERS))],
                     cellLoc="center", bbox=[0.0, 0.0, 1.0, 1.0])
    table.auto_set_font_size(False)
    table.set_fontsize(7)
    for (r, _c), cell in table.get_celld().items():
        cell.set_linewidth(0.5)
        cell.set_height(TABLE_HEADER_ROWS if r == 0 else 1.0)
        if r == 0:
            cell.set_facecolor("#E8E8E8")
    for i, ems in enumerate(levels, start=1):
        table[i, 0].get_text().set_color(colour(ems))
        table[i, 0].get_text().set_fontweight("bold")
    return fig


#: Criteria of the qualitative comparison (after ``fig:heatmap_comparison``): label, summary
#: key (or ``inputs`` for the count of ``tab:level_of_information`` inputs), unit, and
#: whether a lower value is better. The paper's text judges each of them: costs, comfort and
#: grid exchange (abstract), H2 left (RBC "empties the H2 storage much earlier"), FC hours and
#: toggles (degradation, sec:results), heat recovered (sec:heat_recovery) and the inputs
#: needed (sec:discussion: fewer inputs favour real-world deployment).
HEATMAP_CRITERIA: tuple[tuple[str, str, str, bool], ...] = (
    ("electricity cost", "cost_eur_week_median", "EUR/week", True),
    ("thermal discomfort", "discomfort_kh_week_median", "Kh/week", True),
    ("energy bought", "buy_kwh_week_median", "kWh/week", True),
    ("energy sold", "sell_kwh_week_median", "kWh/week", True),
    ("H2 left at the end", "loh_end", "%", False),
    ("FC working hours", "fc_working_hours", "h", True),
    ("FC toggles", "fc_toggles", "-", True),
    ("FC heat recovered", "heat_recovered_kwh_total", "kWh", False),
    ("inputs required", "inputs", "-", True),
)
#: Values within this share of each other count as equal in the comparison [-].
HEATMAP_TIE = 0.05


def comparison_scores(runs: Mapping[str, RunData], levels: Mapping[str, str]) -> tuple[list[str], np.ndarray,
                                                                                         np.ndarray]:
    """Scores -1 (worst), 0, 1 (best) of every EMS per criterion of :data:`HEATMAP_CRITERIA`.

    Per criterion the EMS are ranked by the measured value; the best gets 1, the worst -1,
    the others 0; values within :data:`HEATMAP_TIE` of the best (worst) share its score.

    Returns
    -------
    labels of the criteria, values (criteria x EMS), scores (criteria x EMS)
    """
    names = list(runs)
    values = np.zeros((len(HEATMAP_CRITERIA), len(names)))
    for i, (_, key, unit, _) in enumerate(HEATMAP_CRITERIA):
        for j, e in enumerate(names):
            if key == "inputs":
                values[i, j] = sum(all(f in INFO_LEVELS[levels[e]] for f in fs) for _, fs in INFO_COLUMNS)
            else:
                values[i, j] = float(runs[e].summary[key]) * (PERCENT if unit == "%" else 1.0)
    scores = np.zeros_like(values)
    for i, (_, _, _, lower_better) in enumerate(HEATMAP_CRITERIA):
        v = -values[i] if lower_better else values[i]
        best, worst = v.max(), v.min()
        tol = HEATMAP_TIE * max(abs(best), abs(worst), 1e-9)
        if best - worst <= tol:
            continue
        scores[i] = np.where(v >= best - tol, 1.0, np.where(v <= worst + tol, -1.0, 0.0))
    return [c[0] for c in HEATMAP_CRITERIA], values, scores


@styled
def heatmap_comparison_figure(runs: Mapping[str, RunData], levels: Mapping[str, str]) -> Figure:
    """Qualitative comparison of the EMS from the measured figures (after ``fig:heatmap_comparison``)."""
    labels, values, scores = comparison_scores(runs, levels)
    names = list(runs)
    fig, ax = plt.subplots(figsize=figsize("single", 18 + 7 * len(labels)))
    ax.imshow(scores, cmap="RdYlGn", vmin=-1.5, vmax=1.5, aspect="auto")
    for i in range(len(labels)):
        unit = HEATMAP_CRITERIA[i][2]
        for j in range(len(names)):
            digits = 0 if abs(values[i, j]) >= 100 or unit in ("-", "h") else 1
            ax.text(j, i, f"{scores[i, j]:+.0f}\n{values[i, j]:.{digits}f}", ha="center", va="center", fontsize=6.5)
    ax.set_xticks(range(len(names)), [label(e) for e in names])
    ax.set_yticks(range(len(labels)), [f"{lab} [{c[2]}]" for lab, c in zip(labels, HEATMAP_CRITERIA)])
    ax.tick_params(length=0)
    ax.grid(False)
    ax.xaxis.tick_top()
    return fig


@dataclass
class FigureInputs:
    """What the figures of a report are drawn from.

    Attributes
    ----------
    runs : EMS name -> run at the base FC system efficiency (in display order)
    variants : (EMS name, eta_sys) -> run, every efficiency
    levels : EMS name -> information level
    tz : local time zone of the site
    base_eta : FC system efficiency of the base runs [-]
    v_max_l : DHW tank volume [l]
    """

    runs: Mapping[str, RunData]
    variants: Mapping[tuple[str, float], RunData]
    levels: Mapping[str, str]
    tz: str
    base_eta: float
    v_max_l: float

    def window(self, kind: str) -> tuple[int, int]:
        """Step range of the paper's window ``performance_comparison`` or ``high_pv`` (:func:`paper_windows`)."""
        return paper_windows(next(iter(self.runs.values())), self.tz)[kind]


#: Caption of each figure: the paper's figure it redraws (its label first), what it shows and
#: where the paper discusses it. ``{performance_comparison}`` and ``{high_pv}`` are replaced
#: by the windows' spans.
CAPTIONS: dict[str, str] = {
    "quality_indicators_occupants": "fig:quality_indicators_occupants. Weekly thermal discomfort, electricity cost "
                                    "and reimbursement, one box per EMS (weeks as dots); sec:results, "
                                    "occupant-oriented metrics.",
    "HESS_usage": "fig:HESS_usage. Weekly energy charged into the BESS and H2 used, as the FC's electrical "
                  "output (the quantity the paper's weekly H2 figures fit); sec:results, HESS utilization.",
    "working_hours_FC": "fig:working_hours_FC. FC working hours and toggles (start-ups) over the run; sec:results, "
                        "HESS utilization.",
    "hydrogen_timeseries": "fig:hydrogen_timeseries. Level of hydrogen (LOH) of every EMS (top) with the buy price "
                           "and the global radiation (bottom) over the evaluation period; sec:results, HESS "
                           "utilization.",
    "grid_usage": "fig:grid_usage. Weekly energy bought from and sold to the grid; sec:results, grid utilization.",
    "heat_recovery": "fig:heat_recovery. Weekly heat recovered from the FC at each FC system efficiency (opaque: "
                     "base, transparent: the other) against the weekly DHW demand including the tank losses; "
                     "sec:heat_recovery.",
    "performance_comparison": "fig:performance_comparison. Three days of all EMS, {performance_comparison} (the "
                              "days the paper describes, from 2022-12-03: high prices, low radiation); "
                              "sec:results, time series comparison.",
    "performance_comparison_highSolar": "fig:performance_comparison_highSolar. Three days of all EMS with high PV "
                                        "generation, {high_pv} (two months into the period, buy prices down to "
                                        "0.23 EUR/kWh, as the paper's caption describes); sec:results, time "
                                        "series comparison.",
    "heatmap_comparison": "fig:heatmap_comparison. Qualitative comparison of the EMS, computed from the runs: per "
                          "criterion the best EMS scores 1 (green), the worst -1 (red), the other 0 (values within "
                          "5 % share a score); each cell gives the score and the measured value; sec:discussion.",
    "level_of_information": "tab:level_of_information. Inputs each EMS may use, as enforced by its observation; "
                            "sec:information.",
}
#: Figure key (file stem) -> builder; the report shows them in this order.
FIGURES: dict[str, Callable[[FigureInputs], Figure]] = {
    "quality_indicators_occupants": lambda f: quality_indicators_figure(f.runs),
    "HESS_usage": lambda f: hess_usage_figure(f.runs),
    "working_hours_FC": lambda f: working_hours_fc_figure(f.runs),
    "hydrogen_timeseries": lambda f: hydrogen_timeseries_figure(f.runs, f.tz),
    "grid_usage": lambda f: grid_usage_figure(f.runs),
    "heat_recovery": lambda f: heat_recovery_figure(f.variants, f.base_eta),
    "performance_comparison": lambda f: performance_comparison_figure(
        f.runs, f.window("performance_comparison"), f.tz, f.v_max_l),
    "performance_comparison_highSolar": lambda f: performance_comparison_figure(
        f.runs, f.window("high_pv"), f.tz, f.v_max_l),
    "heatmap_comparison": lambda f: heatmap_comparison_figure(f.runs, f.levels),
    "level_of_information": lambda f: level_of_information_figure(f.levels),
}
#: Figures that take longest to draw (started first when drawing in parallel).
SLOW_FIGURES = ("performance_comparison", "performance_comparison_highSolar", "hydrogen_timeseries")


def iter_figures(inputs: FigureInputs) -> Iterator[tuple[str, Figure]]:
    """Every figure of the report as ``(key, figure)``, built one at a time (close each after use)."""
    for key, build in FIGURES.items():
        yield key, build(inputs)


#: Inputs of the figures in a worker process (set by :func:`_init_worker`).
_WORKER: tuple[FigureInputs, Path] | None = None


def _init_worker(inputs: FigureInputs, out_dir: Path) -> None:
    global _WORKER
    _WORKER = (inputs, out_dir)


def _write_in_worker(key: str) -> Path:
    assert _WORKER is not None
    inputs, out_dir = _WORKER
    return save_figure(FIGURES[key](inputs), out_dir / key)


def all_figures(inputs: FigureInputs, out_dir: Path, jobs: int | None = None) -> dict[str, Path]:
    """Write every figure as ``<key>.pdf/.svg/.png`` into ``out_dir``; returns key -> PNG path.

    The figures are drawn in up to ``jobs`` (default: CPU count) worker processes of a fork
    server, which get the inputs once each; one job (or no fork server) draws them here.
    The workers are never forked from this process: it may run other threads (DDS, a run
    executor, a progress listener), and a child forked from it keeps only the forking thread
    while locks the others held stay held, which hung or crashed figure workers.
    """
    out_dir = Path(out_dir)
    workers = min(jobs or os.cpu_count() or 1, len(FIGURES))
    if workers <= 1 or "forkserver" not in multiprocessing.get_all_start_methods():
        return {key: save_figure(fig, out_dir / key) for key, fig in iter_figures(inputs)}
    order = [*SLOW_FIGURES, *(k for k in FIGURES if k not in SLOW_FIGURES)]
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver"),
                             initializer=_init_worker, initargs=(inputs, out_dir)) as pool:
        written = dict(zip(order, pool.map(_write_in_worker, order)))
    return {key: written[key] for key in FIGURES}


def window_spans(runs: Mapping[str, RunData], tz: str) -> dict[str, tuple[str, str]]:
    """ISO start and end of the selected windows (for the report text)."""
    first = next(iter(runs.values()))
    windows = paper_windows(first, tz)
    t = first.timeseries["time"].dt.tz_convert(tz)
    return {k: (t.iloc[a].isoformat(), (t.iloc[b - 1] + pd.Timedelta(hours=1)).isoformat())
            for k, (a, b) in windows.items()}


def ordered(names: Sequence[str]) -> list[str]:
    """EMS names in the paper's order (MPC, ComEMS4Build, RBC), others after."""
    rank = {"mpc": 0, "fuzzy": 1, "rbc": 2}
    return sorted(names, key=lambda e: (rank.get(e, 3), e))
