"""The report of a year-round comparison (``compare --scenario year``): seasonal figures and tables.

Built from the run directories of a comparison whose manifest names the ``year`` scenario
(``runs/<ems>/`` with ``summary.json``, ``timeseries.csv`` and ``monthly.csv``); it never
simulates. Figures (PDF, SVG, 300 dpi PNG, the style of :mod:`.style`):

- ``loh_year``: level of hydrogen of every EMS over the year, with LOH_init, half the store
  and the start of the heating season marked;
- ``monthly_energy``: per EMS, monthly bought, sold and PV energy, electrolyser input, FC
  output and heat-pump electricity for heating, hot water and cooling;
- ``sankey_<ems>``: the year's electricity flows of one EMS (``matplotlib.sankey``): sources
  PV, grid, FC and battery; sinks appliances, heat pump (heating, hot water, cooling),
  electrolyser, grid and battery; the hydrogen made and used in the title.

The document holds the year's KPIs of every EMS side by side and each EMS's monthly table.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.sankey import Sankey  # noqa: E402

from comems4build_ros.core.config import load_plant_params  # noqa: E402
from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.build import Report  # noqa: E402
from comems4build_ros.report.document import Document  # noqa: E402
from comems4build_ros.report.figures import _local_naive, colour, group_bar_x, label, ordered, percent_run_axes  # noqa: E402
from comems4build_ros.report.runs import RunData, RunDirError, read_comparison  # noqa: E402
from comems4build_ros.report.style import axis_label, figsize, save_figure, styled  # noqa: E402

#: Year KPI rows of the report: (summary key, label, unit, decimals).
YEAR_TABLE = (
    ("loh_init", "LOH at the start (2022-03-01)", "-", 3),
    ("loh_heating_season_start", "LOH at the start of the heating season", "-", 3),
    ("loh_end", "LOH at the end", "-", 3),
    ("h2_produced_kwh", "H2 produced (LHV)", "kWh", 0),
    ("h2_kwh_total", "H2 used by the FC (LHV)", "kWh", 0),
    ("el_input_kwh", "electrolyser input", "kWh", 0),
    ("el_working_hours", "electrolyser working hours", "h", 0),
    ("el_starts", "electrolyser starts", "-", 0),
    ("el_mean_eta", "electrolyser mean efficiency (LHV)", "-", 3),
    ("fc_kwh_total", "FC electrical output", "kWh", 0),
    ("h2_round_trip", "H2 round trip (FC out / EL in)", "-", 3),
    ("self_sufficiency", "self-sufficiency", "-", 3),
    ("buy_kwh_total", "bought", "kWh", 0),
    ("sell_kwh_total", "sold", "kWh", 0),
    ("cost_net_eur", "cost, bought - sold", "EUR", 0),
    ("discomfort_kh_total", "discomfort", "Kh", 1),
    ("overheating_kh", "overheating (above the upper bound)", "Kh", 1),
    ("heating_season_discomfort_weeks", "heating-season weeks with discomfort", "-", 0),
    ("heating_season_weeks", "heating-season weeks", "-", 0),
    ("hp_cooling_kwh", "HP electricity for cooling", "kWh", 0),
    ("energy_balance_rel_error", "energy balance error / throughput", "-", None),
)
#: Monthly table columns: (monthly.csv column, header, decimals).
MONTHLY_TABLE = (
    ("bought_kwh", "bought", 0), ("sold_kwh", "sold", 0), ("pv_kwh", "PV", 0), ("el_input_kwh", "EL in", 0),
    ("h2_produced_kwh", "H2 made", 0), ("fc_output_kwh", "FC out", 0), ("hp_heating_kwh", "HP heat", 0),
    ("hp_dhw_kwh", "HP DHW", 0), ("hp_cooling_kwh", "HP cool", 0), ("discomfort_kh", "disc. Kh", 1),
    ("overheating_kh", "overh. Kh", 1), ("cost_eur", "cost EUR", 0), ("loh_end", "LOH end", 3),
)
#: Monthly bars: (column, legend label, colour).
BARS = (
    ("bought_kwh", "bought", "#0072B2"), ("sold_kwh", "sold", "#56B4E9"), ("pv_kwh", "PV", "#E69F00"),
    ("el_input_kwh", "EL input", "#009E73"), ("fc_output_kwh", "FC output", "#D55E00"),
    ("hp_heat_dhw_kwh", "HP heating + DHW", "#CC79A7"), ("hp_cooling_kwh", "HP cooling", "#7A7A7A"),
)
PERCENT = 100.0


def _cell(value, digits: int | None) -> str:
    if value is None:
        return "-"
    if digits is None:
        return f"{float(value):.2e}"
    return f"{float(value):.{digits}f}"


@styled
def loh_year_figure(runs: Mapping[str, RunData], tz: str, loh_init: float, season_start: pd.Timestamp | None
                    ) -> Figure:
    """LOH of every EMS over the year."""
    fig, ax = plt.subplots(figsize=figsize("double", 70))
    for e, r in runs.items():
        t = _local_naive(r.timeseries["time"], tz)
        ax.plot(t, PERCENT * r.timeseries["loh"], color=colour(e), label=label(e), lw=1.2)
    ax.axhline(PERCENT * loh_init, color=style.GREY, lw=0.8, ls="--", label=r"LOH$_{init}$")
    ax.axhline(50.0, color=style.GREY, lw=0.8, ls=":", label="half the store")
    if season_start is not None:
        ax.axvline(season_start.tz_localize(None).to_datetime64(), color=style.GREY, lw=0.8, ls="-.",
                   label="heating season starts")
    percent_run_axes(ax, "loh", next(iter(runs.values())).timeseries["time"], tz)
    return fig


@styled
def monthly_energy_figure(monthly: Mapping[str, pd.DataFrame]) -> Figure:
    """Monthly energy bars, one panel per EMS."""
    n = len(monthly)
    fig, axes = plt.subplots(n, 1, figsize=figsize("double", 45 + 45 * n), sharex=True, squeeze=False)
    width = 0.8 / len(BARS)
    for ax, (e, m) in zip(axes[:, 0], monthly.items()):
        m = m.assign(hp_heat_dhw_kwh=m["hp_heating_kwh"] + m["hp_dhw_kwh"])
        x = np.arange(len(m))
        for i, (col, lab, c) in enumerate(BARS):
            ax.bar(group_bar_x(x, i, len(BARS), width), m[col], width=width, color=c, label=lab)
        ax.set_ylabel(axis_label("energy", "kWh"))
        ax.text(0.99, 0.95, label(e), transform=ax.transAxes, ha="right", va="top")
        ax.set_xticks(x, [str(s)[2:] for s in m["month"]])
    axes[-1, 0].set_xlabel("month (yy-mm)")
    style.outside_legend(axes[0, 0])
    return fig


def sankey_flows(summary: Mapping[str, float], monthly: pd.DataFrame, ts: pd.DataFrame) -> list[tuple[str, float]]:
    """The year's electricity flows [kWh]: sources positive, sinks negative (they balance)."""
    def kwh(col: str, mask: np.ndarray | None = None) -> float:
        v = ts[col].to_numpy(dtype=float)
        return float(v[mask].sum() if mask is not None else v.sum()) / 1000.0

    mode = ts["hp_mode"].to_numpy(dtype=float)
    return [
        ("PV", kwh("p_pv_w")), ("grid", kwh("p_buy_w")), ("FC", kwh("p_fc_w")), ("battery out", kwh("p_dis_w")),
        ("appliances", -kwh("p_load_w")), ("HP heating", -kwh("p_hp_el_w", mode == 1)),
        ("HP hot water", -kwh("p_hp_el_w", mode == 2)), ("HP cooling", -kwh("p_hp_el_w", mode == 3)),
        ("electrolyser", -kwh("p_el_w")), ("sold", -kwh("p_sell_w")), ("battery in", -kwh("p_ch_w")),
    ]


@styled
def sankey_figure(ems: str, flows: list[tuple[str, float]], h2_made: float, h2_used: float) -> Figure:
    """Electricity flows of one EMS's year as a Sankey diagram (``matplotlib.sankey``)."""
    fig = plt.figure(figsize=figsize("double", 95))
    ax = fig.add_subplot(1, 1, 1, xticks=[], yticks=[])
    ax.grid(False)
    for side in ("top", "right", "bottom", "left"):
        ax.spines[side].set_visible(False)
    kept = [(n, v) for n, v in flows if abs(v) >= 0.5]
    total = sum(v for _, v in kept if v > 0)
    values = [v / total for _, v in kept]
    labels = [f"{n}\n{abs(v):.0f} kWh" for n, v in kept]
    # PV and appliances on the main axis, the grid and the HP above, FC, battery and
    # electrolyser below; arrows on one side alternate in length so their labels do not collide
    side = {"PV": 0, "appliances": 0, "sold": 0, "grid": 1, "HP heating": 1, "HP hot water": 1, "HP cooling": 1}
    orient = [side.get(n, -1) for n, _ in kept]
    seen: dict[tuple[int, bool], int] = {}
    lengths = []
    for (_, v), o in zip(kept, orient):
        key = (o, v > 0)
        i = seen[key] = seen.get(key, -1) + 1
        lengths.append(0.25 if o == 0 else 0.25 + 0.35 * (i % 2))
    sk = Sankey(ax=ax, scale=1.0, unit=None, gap=0.25, radius=0.05, shoulder=0.03, head_angle=120, margin=0.3)
    sk.add(flows=values, labels=labels, orientations=orient, pathlengths=lengths, facecolor=colour(ems), alpha=0.55,
           trunklength=1.5)
    diagrams = sk.finish()
    ax.set_aspect("equal", adjustable="box")  # keep the limits finish() set (no datalim adjustment)
    for text in diagrams[0].texts:
        text.set_fontsize(6)
    ax.set_title(f"{label(ems)}: electricity of the year; H2 made {h2_made:.0f} kWh, used {h2_used:.0f} kWh (LHV)",
                 loc="left")
    return fig


def build_year_report(compare_dir: str | Path, out_dir: str | Path | None = None) -> Report:
    """Write ``report.md``, ``report.html`` and ``figures/`` of a year-round comparison.

    Raises
    ------
    RunDirError
        If the manifest or a run directory (or its ``monthly.csv``) is missing or corrupt.
    """
    t0 = time.perf_counter()
    root = Path(compare_dir)
    out = Path(out_dir) if out_dir is not None else root
    manifest, run_list = read_comparison(root)
    runs = {r.spec.ems: r for r in run_list if abs(r.spec.eta_sys - manifest.base_eta) < 1e-9}
    runs = {e: runs[e] for e in ordered(list(runs))}
    if not runs:
        raise RunDirError(f"{root / 'compare.json'}: no run at the base FC efficiency {manifest.base_eta}")
    params = load_plant_params(manifest.config, {**manifest.overrides, "fuel_cell.eta_sys": manifest.base_eta})
    tz = params.site.timezone
    monthly: dict[str, pd.DataFrame] = {}
    for e, r in runs.items():
        path = r.path / "monthly.csv"
        if not path.is_file():
            raise RunDirError(f"{path}: missing (a run of a year-round plant writes it)")
        monthly[e] = pd.read_csv(path)
    first = next(iter(runs.values()))
    t = first.timeseries["time"].dt.tz_convert(tz)
    sim = params.simulation
    sm, sd = (int(x) for x in sim.heating_season_start.split("-"))
    season = [d for d in pd.date_range(t.iloc[0].normalize(), t.iloc[-1], freq="D") if (d.month, d.day) == (sm, sd)]
    figs_dir = out / "figures"
    figs: dict[str, Path] = {
        "loh_year": save_figure(loh_year_figure(runs, tz, sim.loh_init, season[0] if season else None),
                                figs_dir / "loh_year"),
        "monthly_energy": save_figure(monthly_energy_figure(monthly), figs_dir / "monthly_energy"),
    }
    for e, r in runs.items():
        flows = sankey_flows(r.summary, monthly[e], r.timeseries)
        figs[f"sankey_{e}"] = save_figure(sankey_figure(e, flows, float(r.summary.get("h2_produced_kwh") or 0.0),
                                                        float(r.summary.get("h2_kwh_total") or 0.0)),
                                          figs_dir / f"sankey_{e}")
    captions = {
        "loh_year": "Level of hydrogen (LOH) of every EMS over the year, with LOH_init, half the store and the "
                    "start of the heating season (the paper's winter, sec:parameters).",
        "monthly_energy": "Monthly energy of every EMS: bought, sold, PV, electrolyser input, FC output and "
                          "heat-pump electricity for heating with hot water and for cooling.",
        **{f"sankey_{e}": f"Electricity flows of {label(e)} over the year (kWh): sources on the left, uses on the "
                          "right." for e in runs},
    }
    doc = Document("ComEMS4Build: the year-round comparison")
    doc.p(f"Scenario: {manifest.scenario}; {t.iloc[0].isoformat()} to "
          f"{(t.iloc[-1] + pd.Timedelta(hours=1)).isoformat()} ({int(first.summary['weeks'])} weeks); runs "
          f"{manifest.via}; EMS: {', '.join(label(e) for e in runs)}. Plant: config/year.yaml over "
          f"config/plant.yaml (electrolyser modules: {params.electrolyser.n_modules}, cooling: "
          f"{'on' if params.cooling.enabled else 'off'}, H2 store {params.hydrogen.e_max_kwh:g} kWh, "
          f"LOH_init {sim.loh_init:g}). Parameter overrides: {manifest.overrides or 'none'}. Models, sources and "
          "the EMS's seasonal rules: docs/seasonal.md.")
    doc.h(2, "The year's KPIs")
    closes = {e: (r.summary.get("loh_heating_season_start") or 0.0) >= 0.5 and r.summary["loh_end"] >= sim.loh_init
              for e, r in runs.items()}
    doc.p("The seasonal cycle closes when the store holds at least half its capacity at the start of the heating "
          "season and at least LOH_init at the end: " + "; ".join(
              f"{label(e)}: {'closes' if ok else 'does not close'}" for e, ok in closes.items()) + ".")
    doc.table(["quantity", "unit", *(label(e) for e in runs)],
              [[lab, unit, *(_cell(r.summary.get(key), d) for r in runs.values())]
               for key, lab, unit, d in YEAR_TABLE])
    doc.h(2, "Figures")
    for key, path in figs.items():
        doc.figure(path, "figures", captions[key])
    doc.h(2, "Monthly tables")
    for e, m in monthly.items():
        doc.h(3, label(e))
        doc.table(["month", *(h for _, h, _ in MONTHLY_TABLE)],
                  [[str(row["month"]), *(_cell(row[c], d) for c, _, d in MONTHLY_TABLE)] for _, row in m.iterrows()])
    md = out / "report.md"
    md.write_text(doc.markdown(), encoding="utf-8")
    html = out / "report.html"
    html.write_text(doc.html(), encoding="utf-8")
    return Report(md, html, figs, [], time.perf_counter() - t0)
