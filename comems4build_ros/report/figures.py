"""Paper-style figures of a comparison (matplotlib, Agg backend, PNG).

One function per figure of the paper's ``sec:results``; each takes the runs (EMS name ->
:class:`~comems4build_ros.report.runs.RunData`) and an output path and returns the path.
Every EMS keeps one colour in every figure (:data:`EMS_COLOURS`).

Three-day windows for ``fig:performance_comparison`` (:func:`select_windows`): the
candidates are all runs of three consecutive local days starting at midnight. The *cold
high-price* window maximises ``z(mean buy price) - z(mean T_amb)`` (z-scores over the
candidates); the *sunny* window maximises the mean global radiation among the candidates
that do not overlap the first (any candidate when all overlap).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ..config import W_PER_KW  # noqa: E402
from ..ems.base import INFO_LEVELS  # noqa: E402
from .runs import RunData  # noqa: E402

#: One colour per EMS, used in every figure.
EMS_COLOURS: dict[str, str] = {
    "mpc": "#1f77b4",
    "fuzzy": "#2ca02c",
    "rbc": "#d62728",
    "thermostat": "#7f7f7f",
    "mpc-qp": "#9467bd",
}
#: Colours for EMS not listed above.
_SPARE = ("#8c564b", "#e377c2", "#bcbd22", "#17becf", "#ff7f0e")
#: Display names.
EMS_LABELS: dict[str, str] = {"mpc": "MPC", "fuzzy": "ComEMS4Build", "rbc": "RBC", "thermostat": "Thermostat",
                              "mpc-qp": "MPC-QP"}
#: Figure resolution [dpi].
DPI = 110
#: Length of the time-series windows [d].
WINDOW_DAYS = 3
#: Percent per fraction.
PERCENT = 100.0


def colour(ems: str) -> str:
    """The EMS's colour (stable for names outside :data:`EMS_COLOURS`)."""
    if ems in EMS_COLOURS:
        return EMS_COLOURS[ems]
    return _SPARE[sum(map(ord, ems)) % len(_SPARE)]


def label(ems: str) -> str:
    """Display name of an EMS."""
    return EMS_LABELS.get(ems, ems)


def _local_naive(time: pd.Series, tz: str) -> np.ndarray:
    """UTC times as naive local ``datetime64`` (cheap for matplotlib's date axis)."""
    return time.dt.tz_convert(tz).dt.tz_localize(None).to_numpy()


def _save(fig: plt.Figure, path: Path, tight_bbox: bool = False) -> Path:
    """Write the PNG (the figures lay themselves out; ``tight_bbox`` for legends outside the axes)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, bbox_inches="tight" if tight_bbox else None)
    plt.close(fig)
    return path


def _boxes(ax: plt.Axes, runs: Mapping[str, RunData], column: str, ylabel: str, title: str) -> None:
    """Weekly box plot of one KPI, one box per EMS, weekly values as dots."""
    names = list(runs)
    data = [runs[e].weekly[column].to_numpy(float) for e in names]
    bp = ax.boxplot(data, patch_artist=True, widths=0.55, medianprops={"color": "black"}, showfliers=False)
    for patch, e in zip(bp["boxes"], names):
        patch.set_facecolor(colour(e))
        patch.set_alpha(0.45)
        patch.set_edgecolor(colour(e))
    rng = np.random.default_rng(0)
    for i, (e, vals) in enumerate(zip(names, data), start=1):
        ax.scatter(i + rng.uniform(-0.12, 0.12, len(vals)), vals, s=14, color=colour(e), zorder=3)
    ax.set_xticks(range(1, len(names) + 1), [label(e) for e in names])
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", alpha=0.3)


def quality_indicators(runs: Mapping[str, RunData], path: Path) -> Path:
    """``fig:quality_indicators_occupants``: weekly discomfort, cost and reimbursement."""
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    _boxes(axes[0], runs, "discomfort_kh", "discomfort [K h/week]", "Thermal discomfort")
    _boxes(axes[1], runs, "cost_eur", "electricity cost [EUR/week]", "Electricity cost")
    _boxes(axes[2], runs, "reimbursement_eur", "reimbursement [EUR/week]", "Reimbursement")
    fig.suptitle("Weekly occupant-oriented indicators", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def hess_usage(runs: Mapping[str, RunData], path: Path) -> Path:
    """``fig:HESS_usage``: weekly BESS charged energy and H2 consumption."""
    fig, axes = plt.subplots(2, 1, figsize=(5.5, 6.5), sharex=True)
    _boxes(axes[0], runs, "bess_charged_kwh", "BESS charged [kWh/week]", "Battery charging")
    _boxes(axes[1], runs, "h2_kwh", "H\u2082 consumed, LHV [kWh/week]", "Hydrogen consumption")
    fig.tight_layout()
    return _save(fig, path)


def grid_usage(runs: Mapping[str, RunData], path: Path) -> Path:
    """``fig:grid_usage``: weekly purchased and sold energy."""
    fig, axes = plt.subplots(2, 1, figsize=(5.5, 6.5), sharex=True)
    _boxes(axes[0], runs, "buy_kwh", "purchased [kWh/week]", "Energy bought from the grid")
    _boxes(axes[1], runs, "sell_kwh", "sold [kWh/week]", "Energy sold to the grid")
    fig.tight_layout()
    return _save(fig, path)


def working_hours_fc(runs: Mapping[str, RunData], path: Path) -> Path:
    """``fig:working_hours_FC``: FC working hours (left) and on-switchings (right) of the run."""
    names = list(runs)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, key, ylabel in (
        (axes[0], "fc_working_hours", "FC working hours [h]"),
        (axes[1], "fc_toggles", "FC start-ups (toggles) [-]"),
    ):
        vals = [float(runs[e].summary[key]) for e in names]
        bars = ax.bar([label(e) for e in names], vals, color=[colour(e) for e in names], alpha=0.8)
        ax.bar_label(bars, fmt="%.0f", fontsize=9)
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", alpha=0.3)
    weeks = int(next(iter(runs.values())).summary["weeks"])
    fig.suptitle(f"Fuel-cell operation over the evaluation period ({weeks} weeks)", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


def hydrogen_timeseries(runs: Mapping[str, RunData], path: Path, tz: str) -> Path:
    """``fig:hydrogen_timeseries``: LOH of every EMS, buy price and radiation over the run."""
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    for e, r in runs.items():
        t = _local_naive(r.timeseries["time"], tz)
        axes[0].plot(t, PERCENT * r.timeseries["loh"], color=colour(e), label=label(e), lw=1.6)
    axes[0].set_ylabel("level of hydrogen LOH [%]")
    axes[0].set_ylim(bottom=0)
    axes[0].legend(loc="lower left")
    axes[0].grid(alpha=0.3)
    axes[0].set_title("Hydrogen in the store over the evaluation period", fontsize=10)
    ts = next(iter(runs.values())).timeseries
    t = _local_naive(ts["time"], tz)
    ax = axes[1]
    ax.plot(t, ts["price_buy_eur_per_kwh"], color="#444444", lw=0.8, label="buy price p_buy")
    ax.set_ylabel("buy price [EUR/kWh]")
    ax2 = ax.twinx()
    ax2.fill_between(t, ts["ghi_w_m2"], color="#f2b134", alpha=0.45, lw=0, label="global radiation q_s")
    ax2.set_ylabel("global radiation [W/m\u00b2]")
    ax.set_zorder(ax2.get_zorder() + 1)  # price line over the radiation area
    ax.patch.set_visible(False)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_xlabel(f"local time ({tz})")
    ax.xaxis.set_major_locator(mdates.AutoDateLocator(maxticks=10))
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%d.%m.%Y"))
    ax.grid(alpha=0.3)
    fig.autofmt_xdate()
    fig.tight_layout()
    return _save(fig, path)


def heat_recovery(
    variants: Mapping[tuple[str, float], RunData], path: Path, base_eta: float
) -> Path:
    """``fig:heat_recovery``: weekly recovered FC heat per EMS at each FC system efficiency.

    Bars at the base efficiency are opaque, bars at other efficiencies transparent and
    drawn behind; a black tick over each bar group marks that run's weekly DHW demand
    including the tank losses.
    """
    emss = ordered(list(dict.fromkeys(e for e, _ in variants)))
    etas = sorted({eta for _, eta in variants}, reverse=True)
    base = variants[(emss[0], base_eta)] if (emss[0], base_eta) in variants else next(iter(variants.values()))
    weeks = base.weekly["week"].to_numpy(int)
    width = 0.8 / len(emss)
    fig, ax = plt.subplots(figsize=(11, 4.2))
    for i, e in enumerate(emss):
        x = weeks - 0.4 + width * (i + 0.5)
        for eta in etas:
            run = variants.get((e, eta))
            if run is None:
                continue
            is_base = abs(eta - base_eta) < 1e-9
            ax.bar(x, run.weekly["heat_recovered_kwh"], width=width * 0.95, color=colour(e),
                   alpha=0.9 if is_base else 0.3, edgecolor=colour(e),
                   label=f"{label(e)}, FC system efficiency {eta * PERCENT:.0f} %")
        demand = variants.get((e, base_eta), next(r for (ee, _), r in variants.items() if ee == e))
        ax.scatter(x, demand.weekly["dhw_demand_kwh"], marker="_", s=220, color="black", zorder=4,
                   label="DHW demand incl. tank losses" if i == 0 else None)
    ax.set_xticks(weeks)
    ax.set_xlabel("week of the evaluation period")
    ax.set_ylabel("heat [kWh/week]")
    ax.set_title("Weekly heat recovered from the fuel cell against the DHW demand", fontsize=10)
    ax.legend(fontsize=8, ncol=2, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path, tight_bbox=True)


def select_windows(ts: pd.DataFrame, tz: str, days: int = WINDOW_DAYS) -> dict[str, tuple[int, int]]:
    """Cold high-price and sunny windows as step ranges ``[start, stop)`` (criterion: module doc).

    Runs shorter than ``days`` days give the whole run for both windows.
    """
    local = ts["time"].dt.tz_convert(tz)
    n = len(ts)
    starts = [i for i in range(n) if local.iloc[i].hour == 0 and i + 24 * days <= n]
    if not starts:
        return {"cold": (0, n), "sunny": (0, n)}
    length = 24 * days
    price = np.array([ts["price_buy_eur_per_kwh"].iloc[s : s + length].mean() for s in starts])
    tamb = np.array([ts["t_amb_c"].iloc[s : s + length].mean() for s in starts])
    ghi = np.array([ts["ghi_w_m2"].iloc[s : s + length].mean() for s in starts])

    def z(x: np.ndarray) -> np.ndarray:
        sd = x.std()
        return (x - x.mean()) / sd if sd > 0 else np.zeros_like(x)

    cold = starts[int(np.argmax(z(price) - z(tamb)))]
    free = [j for j, s in enumerate(starts) if s + length <= cold or s >= cold + length]
    pool = free or list(range(len(starts)))
    sunny = starts[max(pool, key=lambda j: ghi[j])]
    return {"cold": (cold, cold + length), "sunny": (sunny, sunny + length)}


def performance_comparison(
    runs: Mapping[str, RunData], window: tuple[int, int], path: Path, tz: str, title: str, v_max_l: float
) -> Path:
    """``fig:performance_comparison``: a window of every EMS, one column per EMS.

    Rows: T_air with its bounds and V_DHW; PV and demand (appliances + HP); grid exchange
    with the buy price; battery SOC and power; LOH and FC power.
    """
    names = list(runs)
    a, b = window
    fig, axes = plt.subplots(5, len(names), figsize=(4.6 * len(names), 12), sharex="col", squeeze=False)
    twins: list[list[plt.Axes]] = [[] for _ in range(5)]
    for j, e in enumerate(names):
        ts = runs[e].timeseries.iloc[a:b]
        t = _local_naive(ts["time"], tz)
        c = colour(e)
        ax = axes[0, j]
        ax.plot(t, ts["t_air_c"], color=c, lw=1.6, label="T_air")
        ax.step(t, ts["t_min_c"], where="post", color="grey", ls="--", lw=1, label="T_air,min, T_air,max")
        ax.step(t, ts["t_max_c"], where="post", color="grey", ls="--", lw=1)
        ax.set_ylabel("air temperature [°C]")
        ax.set_title(label(e), color=c, fontsize=11, fontweight="bold")
        axr = ax.twinx()
        twins[0].append(axr)
        axr.plot(t, PERCENT * ts["v_dhw_l"] / v_max_l, color="#17becf", lw=1, label="V_DHW")
        axr.set_ylabel("DHW volume [% of V_max]")
        axr.set_ylim(0, 105)
        if j == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = axr.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="lower left")
        ax = axes[1, j]
        ax.fill_between(t, ts["p_pv_w"] / W_PER_KW, step="post", color="#f2b134", alpha=0.5, label="PV")
        ax.step(t, (ts["p_load_w"] + ts["p_hp_el_w"]) / W_PER_KW, where="post", color="black", lw=1,
                label="appliances + HP")
        ax.step(t, ts["p_hp_el_w"] / W_PER_KW, where="post", color=c, lw=1, label="HP")
        ax.set_ylabel("power [kW]")
        if j == 0:
            ax.legend(fontsize=7, loc="upper left")
        ax = axes[2, j]
        ax.step(t, ts["p_buy_w"] / W_PER_KW, where="post", color=c, lw=1.2, label="bought")
        ax.step(t, -ts["p_sell_w"] / W_PER_KW, where="post", color="#ff7f0e", lw=1.2, label="sold (negative)")
        ax.set_ylabel("grid power [kW]")
        axr = ax.twinx()
        twins[2].append(axr)
        axr.step(t, ts["price_buy_eur_per_kwh"], where="post", color="grey", lw=0.9, ls=":", label="buy price")
        axr.set_ylabel("buy price [EUR/kWh]")
        if j == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = axr.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
        ax = axes[3, j]
        ax.plot(t, PERCENT * ts["soc"], color=c, lw=1.4, label="SOC")
        ax.set_ylabel("battery SOC [%]")
        ax.set_ylim(0, 100)
        axr = ax.twinx()
        twins[3].append(axr)
        axr.step(t, (ts["p_ch_w"] - ts["p_dis_w"]) / W_PER_KW, where="post", color="#8c564b", lw=0.9,
                 label="BESS power (+ charge)")
        axr.set_ylabel("BESS power [kW]")
        if j == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = axr.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
        ax = axes[4, j]
        ax.plot(t, PERCENT * ts["loh"], color=c, lw=1.4, label="LOH")
        ax.set_ylabel("LOH [%]")
        ax.set_ylim(0, 100)
        axr = ax.twinx()
        twins[4].append(axr)
        axr.step(t, ts["p_fc_w"] / W_PER_KW, where="post", color="#9467bd", lw=0.9, label="FC power")
        axr.set_ylabel("FC power [kW]")
        if j == 0:
            h1, l1 = ax.get_legend_handles_labels()
            h2, l2 = axr.get_legend_handles_labels()
            ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
        ax.set_xlabel(f"local time ({tz})")
        ax.xaxis.set_major_locator(mdates.HourLocator(byhour=(0, 12)))
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%d.%m. %H:%M"))
        for row in axes[:, j]:
            row.grid(alpha=0.3)
    for row in [list(axes[i, :]) for i in range(5)] + twins:  # same scale in every column
        if len(row) > 1:
            lo = min(ax.get_ylim()[0] for ax in row)
            hi = max(ax.get_ylim()[1] for ax in row)
            for ax in row:
                ax.set_ylim(lo, hi)
    fig.suptitle(title, fontsize=12)
    fig.autofmt_xdate()
    fig.tight_layout()
    return _save(fig, path)


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


#: Two-line column headers of the table figure (same order as :data:`INFO_COLUMNS`).
FIGURE_HEADERS = (
    "forecasts\n(models, profiles)", "future temp.\nbounds", "24 h-ahead\ntariffs", "T_amb", "solar\nradiation",
    "T_air", "V_DHW", "SOC", "LOH", "permissible\nH2 (dLOH)", "FC previous\non/off",
)


def level_of_information_rows(levels: Mapping[str, str]) -> tuple[list[str], list[list[str]]]:
    """Header and rows of ``tab:level_of_information`` from :data:`INFO_LEVELS`.

    Parameters
    ----------
    levels : EMS name -> its information level
    """
    header = ["EMS (level)", *(c for c, _ in INFO_COLUMNS)]
    rows = []
    for ems, level in levels.items():
        fields = INFO_LEVELS[level]
        rows.append([f"{label(ems)} ({level})", *("yes" if all(f in fields for f in fs) else "-"
                                                   for _, fs in INFO_COLUMNS)])
    return header, rows


def level_of_information(levels: Mapping[str, str], path: Path) -> Path:
    """``tab:level_of_information`` drawn as a table figure."""
    header, rows = level_of_information_rows(levels)
    fig, ax = plt.subplots(figsize=(14, 0.9 + 0.5 * (len(rows) + 1)))
    ax.axis("off")
    cells = [[("\u2713" if v == "yes" else "") if i else v for i, v in enumerate(r)] for r in rows]
    short = ["EMS\n(information level)", *FIGURE_HEADERS]
    widths = [0.16, *([0.84 / len(FIGURE_HEADERS)] * len(FIGURE_HEADERS))]
    table = ax.table(cellText=cells, colLabels=short, colWidths=widths, loc="center", cellLoc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1, 2.6)
    for (r, _c), cell in table.get_celld().items():
        if r == 0:
            cell.set_facecolor("#dddddd")
    for i, ems in enumerate(levels, start=1):
        table[i, 0].get_text().set_color(colour(ems))
        table[i, 0].get_text().set_fontweight("bold")
    ax.set_title("Inputs each EMS may use (tab:level_of_information, enforced by the observation)", fontsize=10)
    return _save(fig, path, tight_bbox=True)


def all_figures(
    runs: Mapping[str, RunData],
    variants: Mapping[tuple[str, float], RunData],
    levels: Mapping[str, str],
    out_dir: Path,
    tz: str,
    base_eta: float,
    v_max_l: float,
) -> dict[str, Path]:
    """Every figure of the report; returns figure key -> PNG path."""
    first = next(iter(runs.values()))
    windows = select_windows(first.timeseries, tz)
    t = first.timeseries["time"].dt.tz_convert(tz)

    def span(key: str) -> str:
        a, b = windows[key]
        return f"{t.iloc[a]:%Y-%m-%d %H:%M} to {t.iloc[b - 1] + pd.Timedelta(hours=1):%Y-%m-%d %H:%M}"

    out = {
        "quality_indicators_occupants": quality_indicators(runs, out_dir / "quality_indicators_occupants.png"),
        "HESS_usage": hess_usage(runs, out_dir / "HESS_usage.png"),
        "working_hours_FC": working_hours_fc(runs, out_dir / "working_hours_FC.png"),
        "hydrogen_timeseries": hydrogen_timeseries(runs, out_dir / "hydrogen_timeseries.png", tz),
        "grid_usage": grid_usage(runs, out_dir / "grid_usage.png"),
        "heat_recovery": heat_recovery(variants, out_dir / "heat_recovery.png", base_eta),
        "performance_comparison": performance_comparison(
            runs, windows["cold"], out_dir / "performance_comparison.png", tz,
            f"Cold, high-price window: {span('cold')}", v_max_l),
        "performance_comparison_highSolar": performance_comparison(
            runs, windows["sunny"], out_dir / "performance_comparison_highSolar.png", tz,
            f"Sunny window: {span('sunny')}", v_max_l),
        "level_of_information": level_of_information(levels, out_dir / "level_of_information.png"),
    }
    return out


def window_spans(runs: Mapping[str, RunData], tz: str) -> dict[str, tuple[str, str]]:
    """ISO start and end of the selected windows (for the report text)."""
    first = next(iter(runs.values()))
    windows = select_windows(first.timeseries, tz)
    t = first.timeseries["time"].dt.tz_convert(tz)
    return {k: (t.iloc[a].isoformat(), (t.iloc[b - 1] + pd.Timedelta(hours=1)).isoformat())
            for k, (a, b) in windows.items()}


def ordered(names: Sequence[str]) -> list[str]:
    """EMS names in the paper's order (MPC, ComEMS4Build, RBC), others after."""
    rank = {"mpc": 0, "fuzzy": 1, "rbc": 2}
    return sorted(names, key=lambda e: (rank.get(e, 3), e))
