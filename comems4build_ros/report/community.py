"""The report of a community comparison (``compare --community``): the coordinators side by side.

Built from the run directories of the comparison (``runs/<coordinator>/`` with
``community.json``, ``houses.csv`` and ``hub.csv``) and its manifest
(:data:`MANIFEST`); it never simulates. Figures (the style of :mod:`.style`):

- ``hub_loh``: the hub's level of hydrogen over the run, one line per coordinator;
- ``household_cost``: the cost per household under every sharing rule set, one bar per coordinator;
- ``house_costs``: every house's cost under every rule set, one panel per coordinator;
- ``connection_exchange``: the connection point's exchange sorted from the largest import to the
  largest export (a duration curve), one line per coordinator, with the sums of the houses'
  own peaks.

The document holds the community's KPIs per coordinator, the rule sets with their legal
status and every house's KPIs and settlement.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from comems4build_ros.core.community.coordinator import coordinator_table  # noqa: E402
from comems4build_ros.core.community.sharing import load_sharing_rules  # noqa: E402
from comems4build_ros.files.inputs import InputFileError, load_json_file  # noqa: E402
from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.build import Report  # noqa: E402
from comems4build_ros.report.document import Document  # noqa: E402
from comems4build_ros.report.figures import _local_naive, group_bar_x, percent_run_axes  # noqa: E402
from comems4build_ros.report.runs import RUNS_DIR, RunDirError  # noqa: E402
from comems4build_ros.report.style import axis_label, figsize, save_figure, styled  # noqa: E402

#: The comparison's manifest in its directory.
MANIFEST = "community_compare.json"
#: Colours of the rule sets (Okabe & Ito), in ``config/sharing.yaml`` order.
RULE_COLOURS = (style.GREY, style.OKABE_ITO["blue"], style.OKABE_ITO["bluish_green"], style.OKABE_ITO["sky_blue"],
                style.OKABE_ITO["reddish_purple"], style.OKABE_ITO["black"])
PERCENT = 100.0
#: The community's KPI rows of the report: (key, label, unit, decimals; None = scientific).
KPI_TABLE = (
    ("houses", "houses", "-", 0),
    ("discomfort_kh_total", "discomfort, all houses", "Kh", 2),
    ("houses_with_discomfort", "houses with discomfort", "-", 0),
    ("cost_cp_eur", "cost at the connection point", "EUR", 2),
    ("self_sufficiency", "self-sufficiency", "-", 3),
    ("grid_buy_kwh", "bought at the connection point", "kWh", 0),
    ("grid_sell_kwh", "sold at the connection point", "kWh", 0),
    ("houses_buy_kwh", "bought at the houses' meters", "kWh", 0),
    ("houses_sell_kwh", "sold at the houses' meters", "kWh", 0),
    ("peak_import_w", "peak import, connection point", "W", 0),
    ("peak_import_houses_sum_w", "sum of the houses' peak imports", "W", 0),
    ("peak_export_w", "peak export, connection point", "W", 0),
    ("peak_export_houses_sum_w", "sum of the houses' peak exports", "W", 0),
    ("h2_produced_kwh", "H2 produced (LHV)", "kWh", 0),
    ("h2_used_kwh", "H2 used by the fuel cells (LHV)", "kWh", 0),
    ("h2_lost_kwh", "H2 lost (LHV)", "kWh", 1),
    ("el_input_kwh", "electrolyser input", "kWh", 0),
    ("el_module_hours", "electrolyser module hours", "h", 0),
    ("hub_e_max_kwh", "hub store", "kWh", 0),
    ("hub_modules", "electrolyser modules", "-", 0),
    ("hub_loh_init", "hub LOH at the start", "-", 3),
    ("hub_loh_min", "hub LOH, lowest", "-", 3),
    ("hub_loh_end", "hub LOH at the end", "-", 3),
    ("h2_balance_max_rel", "H2 balance residual / throughput", "-", None),
    ("electricity_balance_max_w", "electricity balance residual", "W", None),
    ("coordinator_messages_per_step", "coordinator messages per step", "-", 1),
    ("coordinator_iterations_mean", "coordinator iterations per step, mean", "-", 1),
    ("coordinator_s_per_decision_mean", "coordinator time per decision, mean", "s", None),
    ("coordinator_s_per_decision_max", "coordinator time per decision, max", "s", None),
    ("wall_s", "wall time of the run", "s", 1),
)


@dataclass
class CommunityRun:
    """One coordinator's run of a comparison."""

    coordinator: str
    path: Path
    summary: dict[str, Any]
    houses: pd.DataFrame
    hub: pd.DataFrame


def _cell(value: Any, digits: int | None) -> str:
    if value is None:
        return "-"
    if digits is None:
        return f"{float(value):.2e}"
    return f"{float(value):,.{digits}f}"


def coordinator_label(name: str) -> str:
    """The coordinator's label (``config/coordinators.yaml``; the name if not in the table)."""
    entry = coordinator_table().get(name)
    return entry.label if entry else name


def coordinator_colour(name: str, i: int = 0) -> str:
    """The coordinator's colour (a spare colour if not in the table)."""
    entry = coordinator_table().get(name)
    return entry.colour if entry else style.SPARE_COLOURS[i % len(style.SPARE_COLOURS)]


def read_community_comparison(root: str | Path) -> tuple[dict[str, Any], dict[str, CommunityRun]]:
    """The manifest and every coordinator's run of a comparison directory.

    Raises
    ------
    RunDirError
        Naming the missing or corrupt manifest or run file.
    """
    root = Path(root)
    try:
        manifest = load_json_file(root / MANIFEST, "a community comparison's manifest")
    except InputFileError as exc:
        raise RunDirError(str(exc)) from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("coordinators"), list):
        raise RunDirError(f"{root / MANIFEST}: needs a list 'coordinators'")
    runs: dict[str, CommunityRun] = {}
    for name in manifest["coordinators"]:
        path = root / RUNS_DIR / str(name)
        try:
            summary = load_json_file(path / "community.json", "a community run's summary")
            houses = pd.read_csv(path / "houses.csv", index_col="house")
            hub = pd.read_csv(path / "hub.csv")
        except (InputFileError, OSError, ValueError, KeyError) as exc:
            raise RunDirError(f"{path}: not a complete community run ({exc})") from None
        hub["time"] = pd.to_datetime(hub["time"].astype(str), utc=True)
        runs[str(name)] = CommunityRun(str(name), path, summary, houses, hub)
    if not runs:
        raise RunDirError(f"{root / MANIFEST}: no coordinator's run")
    return manifest, runs


@styled
def hub_loh_figure(runs: Mapping[str, CommunityRun], tz: str) -> Figure:
    """The hub's LOH over the run, one line per coordinator."""
    fig, ax = plt.subplots(figsize=figsize("double", 65))
    for i, (name, r) in enumerate(runs.items()):
        t = _local_naive(r.hub["time"], tz)
        ax.plot(t, PERCENT * r.hub["loh"], color=coordinator_colour(name, i), label=coordinator_label(name), lw=1.2)
    percent_run_axes(ax, "hub LOH", next(iter(runs.values())).hub["time"], tz)
    return fig


@styled
def household_cost_figure(runs: Mapping[str, CommunityRun], rules: Mapping[str, str]) -> Figure:
    """The cost per household under every rule set, one bar per coordinator."""
    fig, ax = plt.subplots(figsize=figsize("double", 70))
    x = np.arange(len(rules))
    width = 0.8 / len(runs)
    for i, (name, r) in enumerate(runs.items()):
        values = [float(r.summary.get(f"cost_eur_per_household_{rule}", np.nan)) for rule in rules]
        ax.bar(group_bar_x(x, i, len(runs), width), values, width=width, color=coordinator_colour(name, i),
               label=coordinator_label(name))
    ax.set_xticks(x, [str(lab) for lab in rules.values()])
    ax.tick_params(axis="x", labelsize=6)
    ax.set_ylabel(axis_label("cost per household", "EUR"))
    style.outside_legend(ax)
    return fig


@styled
def house_costs_figure(runs: Mapping[str, CommunityRun], rules: Mapping[str, str]) -> Figure:
    """Every house's cost under every rule set, one panel per coordinator."""
    n = len(runs)
    fig, axes = plt.subplots(n, 1, figsize=figsize("double", 40 + 45 * n), sharex=True, squeeze=False)
    for ax, (name, r) in zip(axes[:, 0], runs.items()):
        houses = list(r.houses.index)
        x = np.arange(len(houses))
        width = 0.8 / len(rules)
        for j, (rule, lab) in enumerate(rules.items()):
            ax.bar(group_bar_x(x, j, len(rules), width), r.houses[f"cost_eur_{rule}"], width=width,
                   color=RULE_COLOURS[j % len(RULE_COLOURS)], label=lab)
        ax.set_ylabel(axis_label("cost", "EUR"))
        ax.text(0.99, 0.95, coordinator_label(name), transform=ax.transAxes, ha="right", va="top")
        ax.set_xticks(x, [str(h) for h in houses])
    axes[-1, 0].set_xlabel("house")
    style.outside_legend(axes[0, 0], ncol=2)
    return fig


@styled
def connection_exchange_figure(runs: Mapping[str, CommunityRun]) -> Figure:
    """Duration curves of the connection point's exchange (import > 0, export < 0), with the houses' peak sums."""
    fig, ax = plt.subplots(figsize=figsize("double", 70))
    for i, (name, r) in enumerate(runs.items()):
        net = np.sort((r.hub["cp_p_buy_w"] - r.hub["cp_p_sell_w"]).to_numpy(float))[::-1] / 1000.0
        hours = np.arange(1, len(net) + 1)
        c = coordinator_colour(name, i)
        ax.plot(hours, net, color=c, lw=1.2, label=coordinator_label(name))
        ax.axhline(float(r.summary["peak_import_houses_sum_w"]) / 1000.0, color=c, lw=0.8, ls="--",
                   label=f"{coordinator_label(name)}: sum of the houses' peak imports")
        ax.axhline(-float(r.summary["peak_export_houses_sum_w"]) / 1000.0, color=c, lw=0.8, ls=":",
                   label=f"{coordinator_label(name)}: sum of the houses' peak exports")
    ax.axhline(0.0, color=style.GREY, lw=0.6)
    ax.set_xlabel("hours of the run, sorted")
    ax.set_ylabel(axis_label("import - export at the connection point", "kW"))
    style.outside_legend(ax, ncol=min(3, 3 * len(runs)))
    return fig


def build_community_report(compare_dir: str | Path, out_dir: str | Path | None = None) -> Report:
    """Write ``report.md``, ``report.html`` and ``figures/`` of a community comparison.

    Raises
    ------
    RunDirError
        If the manifest or a run directory is missing or corrupt.
    """
    t0 = time.perf_counter()
    root = Path(compare_dir)
    out = Path(out_dir) if out_dir is not None else root
    manifest, runs = read_community_comparison(root)
    first = next(iter(runs.values()))
    rules = dict(first.summary.get("rule_sets") or {})
    tz = str(manifest.get("timezone") or "UTC")
    figs_dir = out / "figures"
    figs = {
        "hub_loh": save_figure(hub_loh_figure(runs, tz), figs_dir / "hub_loh"),
        "household_cost": save_figure(household_cost_figure(runs, rules), figs_dir / "household_cost"),
        "house_costs": save_figure(house_costs_figure(runs, rules), figs_dir / "house_costs"),
        "connection_exchange": save_figure(connection_exchange_figure(runs), figs_dir / "connection_exchange"),
    }
    captions = {
        "hub_loh": "Level of hydrogen (LOH) of the hub's store over the run, per coordinator.",
        "household_cost": "Electricity cost per household (net of what it earned, its part of the hub's "
                          "electrolysers included) under every sharing rule set, per coordinator.",
        "house_costs": "Every house's electricity cost under every sharing rule set, one panel per coordinator.",
        "connection_exchange": "The connection point's exchange (import positive, export negative) sorted from "
                               "the largest import, beside the sums of the houses' own peaks: what the houses' "
                               "diversity spares the grid.",
    }
    doc = Document(f"Community '{first.summary.get('community')}': the coordinators side by side")
    t = first.hub["time"].dt.tz_convert(tz)
    doc.p(f"Community file: {manifest.get('community_file')} ({first.summary.get('houses')} houses); scenario "
          f"{manifest.get('scenario')}, {t.iloc[0].isoformat()} to {(t.iloc[-1] + pd.Timedelta(hours=1)).isoformat()} "
          f"({first.summary.get('steps')} steps); every house's EMS: {first.summary.get('ems')}; coordinators: "
          f"{', '.join(coordinator_label(c) for c in runs)}. Parameter overrides: "
          f"{manifest.get('overrides') or 'none'}. Design, the hub's accounts, the rule sets' legal sources and "
          "the coordinator interface: docs/community.md.")
    doc.h(2, "The community's KPIs")
    doc.table(["quantity", "unit", *(coordinator_label(c) for c in runs)],
              [[lab, unit, *(_cell(r.summary.get(key), d) for r in runs.values())] for key, lab, unit, d in KPI_TABLE])
    doc.h(2, "Cost under the sharing rule sets")
    sharing = load_sharing_rules()
    doc.table(["rule set", "legal status", "network", "levies", "electricity tax", *(
        f"{coordinator_label(c)}: cost per household [EUR]" for c in runs), *(
        f"{coordinator_label(c)}: shared [kWh]" for c in runs)],
        [[lab, sharing.rule_sets[rule].legal_status if rule in sharing.rule_sets else "-",
          *(_cell(getattr(sharing.rule_sets.get(rule), k, None), 2) for k in (
              "network_share", "levies_share", "electricity_tax_share")),
          *(_cell(r.summary.get(f"cost_eur_per_household_{rule}"), 2) for r in runs.values()),
          *(_cell(r.summary.get(f"shared_kwh_{rule}"), 0) for r in runs.values())]
         for rule, lab in rules.items()])
    doc.h(2, "Figures")
    for key, path in figs.items():
        doc.figure(path, "figures", captions[key])
    doc.h(2, "The houses")
    for name, r in runs.items():
        doc.h(3, coordinator_label(name))
        cols = ["discomfort_kh_total", "fc_working_hours", "h2_kwh_total", "h2_received_kwh", "buy_kwh_total",
                "sell_kwh_total", "peak_import_w", "peak_export_w", *(f"cost_eur_{rule}" for rule in rules)]
        heads = ["discomfort [Kh]", "FC hours [h]", "H2 used [kWh]", "H2 received [kWh]", "bought [kWh]",
                 "sold [kWh]", "peak import [W]", "peak export [W]", *(f"cost, {lab} [EUR]" for lab in rules.values())]
        digits = [2, 0, 0, 0, 0, 0, 0, 0, *([2] * len(rules))]
        doc.table(["house", *heads], [[str(h), *(_cell(row.get(c), d) for c, d in zip(cols, digits))]
                                      for h, row in r.houses.iterrows()])
    md = out / "report.md"
    md.write_text(doc.markdown(), encoding="utf-8")
    html = out / "report.html"
    html.write_text(doc.html(), encoding="utf-8")
    return Report(md, html, figs, [], time.perf_counter() - t0)


def write_manifest(out: Path, manifest: Mapping[str, Any]) -> Path:
    """Write the comparison's manifest (:data:`MANIFEST`)."""
    path = out / MANIFEST
    path.write_text(json.dumps(dict(manifest), indent=2, default=str) + "\n", encoding="utf-8")
    return path
