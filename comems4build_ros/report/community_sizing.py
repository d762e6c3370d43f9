"""The tables, figure and report of ``size --community``: isolated houses against a shared H2 hub.

Built from the study's run directories (``runs/hub__*`` community runs, ``runs/isolated__*``
one-house runs) and its manifest (:data:`MANIFEST`); it never simulates. Every household's
annual cost under every sharing rule set of ``config/sharing.yaml``
(:func:`comems4build_ros.study.community_sizing.household_costs`):

- hub arm: the household's settlement of the community run (its meter and its part of the
  hub's electricity, ``houses.csv``), its own PV, battery and FC, its part of the hub's
  annuity and O&M (:data:`~comems4build_ros.study.community_sizing.HUB_COST_SPLIT`);
- isolated arm: the isolated houses' meters (each with its electrolyser behind it) settled
  together under the rule set (:func:`comems4build_ros.core.community.kpi.settle_meters`: neighbours
  without a hub share their electricity too), its PV, battery, FC, electrolyser and store.

Outputs: ``households.csv`` (one row per arm, hub size, rule set and household),
``points.csv`` (one row per arm, hub size and rule set: the households' mean, the
community's total, the seasonal cycle), ``figures/household_cost.{pdf,svg,png}`` and
``report.md``/``report.html`` with the answer.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from comems4build_ros.core import economics  # noqa: E402
from comems4build_ros.core.community.kpi import household_self_sufficiency, settle_meters  # noqa: E402
from comems4build_ros.core.community.sharing import load_sharing_rules  # noqa: E402
from comems4build_ros.core.config import W_PER_KW  # noqa: E402
from comems4build_ros.files.inputs import InputFileError, load_json_file  # noqa: E402
from comems4build_ros.report import style  # noqa: E402
from comems4build_ros.report.document import Document  # noqa: E402
from comems4build_ros.report.runs import RunDirError  # noqa: E402
from comems4build_ros.report.sizing import cost_figures, markdown_rows  # noqa: E402
from comems4build_ros.report.style import axis_label, figsize, save_figure, styled  # noqa: E402
from comems4build_ros.study.community_sizing import (  # noqa: E402
    HUB_COST_SPLIT,
    HubSize,
    community_cycle,
    household_costs,
    hub_annual_costs,
    run_weeks,
    smallest_closing,
)

#: The study's manifest in its directory.
MANIFEST = "size_community.json"
#: What the report writes (``--from-runs`` replaces these).
REPORT_FILES = ("figures", "households.csv", "points.csv", "report.md", "report.html")
#: What ``size --community`` writes into its output directory.
FILES = ("runs", MANIFEST, *REPORT_FILES)
#: The base case among the rule sets (German law from 2026-06-01).
BASE_RULE = "enwg_42c"
#: Columns of ``households.csv``.
HOUSEHOLD_COLUMNS = (
    "arm", "hub_kwh", "modules", "rule", "house", "h2_kwh", "el_modules", "total_eur_a", "energy_eur_a",
    "annuity_eur_a", "om_eur_a", "hub_annuity_eur_a", "hub_om_eur_a", "invest_eur", "self_sufficiency", "grid_kwh",
    "use_kwh", "fc_hours_a", "fc_toggles_a", "el_hours_a", "battery_cycles_a", "life_fuel_cell_a",
    "life_electrolyser_a", "loh_end", "discomfort_kh_total", "closes", "why", "run")
#: Columns of ``points.csv``.
POINT_COLUMNS = (
    "arm", "hub_kwh", "modules", "rule", "households", "h2_kwh_per_house", "el_modules_per_house",
    "total_eur_a_per_household", "vs_isolated_eur_a_per_household", "energy_eur_a_per_household",
    "capital_eur_a_per_household", "invest_eur_per_household", "total_eur_a", "self_sufficiency",
    "charges_on_shared_eur", "h2_produced_kwh", "loh_end", "closes", "houses_closing", "why")
PERCENT = 100.0


@dataclass
class StudyResult:
    """The study's tables, its answer in sentences and the figure written."""

    households: pd.DataFrame
    points: pd.DataFrame
    answer: list[str] = field(default_factory=list)
    figure: Path | None = None


def _json(path: Path, what: str) -> dict[str, Any]:
    try:
        return load_json_file(path, what)
    except (InputFileError, OSError) as exc:
        raise RunDirError(f"{path}: {exc}") from None


def _csv(path: Path, what: str, **kwargs: Any) -> pd.DataFrame:
    if not path.is_file():
        raise RunDirError(f"{path}: missing ({what})")
    try:
        return pd.read_csv(path, **kwargs)
    except (ValueError, OSError) as exc:
        raise RunDirError(f"{path}: not a readable table ({what}): {exc}") from None


def read_manifest(folder: Path) -> dict[str, Any]:
    """The study's manifest (:data:`MANIFEST`) in ``folder``."""
    meta = _json(Path(folder) / MANIFEST, "the manifest of a size --community study")
    if meta.get("kind") != "size_community":
        raise RunDirError(f"{Path(folder) / MANIFEST}: not the manifest of a size --community study")
    return meta


def costs_of(meta: Mapping[str, Any]) -> economics.Costs:
    """The cost figures the study used (kept in its manifest)."""
    return economics.Costs(float(meta["interest_rate"]), {k: dict(v) for k, v in meta["cost_items"].items()})


def hub_households(folder: Path, meta: Mapping[str, Any], costs: economics.Costs,
                   rules: Sequence[str]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every household of every hub run under every rule set, and every hub run's facts."""
    rows, facts = [], []
    houses = meta["houses"]
    total_weight = sum(float(h["weight"]) for h in houses.values())
    for hub in meta["hub_sizes"]:
        size = HubSize(float(hub["store_kwh"]), int(hub["modules"]))
        run = Path(folder) / "runs" / hub["run"]
        summary = _json(run / "community.json", "a community run's summary")
        table = _csv(run / "houses.csv", "a community run's houses", index_col="house")
        table.index = table.index.astype(str)
        own = {name: _json(run / "houses" / name / "summary.json", "a house's summary") for name in houses}
        weeks = run_weeks(summary, float(meta["dt_h"]))
        capital = hub_annual_costs(size, float(summary["el_module_hours"]), weeks, costs)
        closes, why = community_cycle(summary, own)
        facts.append({"arm": "hub", "hub_kwh": size.store_kwh, "modules": size.modules, "closes": closes, "why": why,
                      "h2_produced_kwh": float(summary["h2_produced_kwh"]), "loh_end": float(summary["hub_loh_end"]),
                      "charges": {r: float(summary[f"charges_on_shared_eur_{r}"]) for r in rules},
                      "community_cost_eur": {r: float(summary[f"cost_eur_{r}"]) for r in rules},
                      "capital": capital, "weeks": weeks})
        per_module_h = float(summary["el_module_hours"]) / size.modules
        for rule in rules:
            for name, house in houses.items():
                part = float(house["weight"]) / total_weight
                sizes = {**house["sizes"], "el_modules": 0, "h2_kwh": 0.0}
                c = household_costs(sizes, own[name], float(table.loc[name, f"cost_eur_{rule}"]), costs,
                                    float(house["usable_battery_kwh"]), weeks, 0.0, capital, part)
                use = float(table.loc[name, "consumption_kwh"]) + float(table.loc[name, f"hub_kwh_{rule}"])
                ss = float(table.loc[name, f"self_sufficiency_{rule}"])
                h_closes, h_why = economics.cycle_closes(own[name])
                rows.append({**c, "arm": "hub", "hub_kwh": size.store_kwh, "modules": size.modules, "rule": rule,
                             "house": name, "h2_kwh": size.store_kwh * part, "el_modules": size.modules * part,
                             "el_hours_a": per_module_h * economics.WEEKS_PER_YEAR / weeks,
                             "self_sufficiency": ss, "grid_kwh": (1.0 - ss) * use, "use_kwh": use,
                             "loh_end": float(own[name]["loh_end"]),
                             "discomfort_kh_total": float(own[name]["discomfort_kh_total"]),
                             "closes": h_closes, "why": h_why, "run": f"runs/{hub['run']}"})
    return rows, facts


def _isolated_meters(folder: Path, runs: Mapping[str, Mapping[str, Any]]
                     ) -> tuple[pd.Series, np.ndarray, np.ndarray, np.ndarray, np.ndarray, pd.Series]:
    """Time, every isolated house's purchase and sale at its meter [W], the tariff and every house's use [kWh]."""
    buy, sell, use, first = [], [], {}, None
    for name, iso in runs.items():
        run = Path(folder) / "runs" / iso["run"]
        hub = _csv(run / "hub.csv", "an isolated house's meter (the connection point of its run)")
        buy.append(hub["cp_p_buy_w"].to_numpy(float))
        sell.append(hub["cp_p_sell_w"].to_numpy(float))
        use[name] = hub[["cp_p_load_w", "cp_p_hp_el_w", "cp_p_el_w"]].to_numpy(float).sum()
        if first is None:
            first = _csv(run / "houses" / name / "timeseries.csv", "an isolated house's timeseries",
                         usecols=["time", "price_buy_eur_per_kwh", "price_sell_eur_per_kwh"])
    assert first is not None
    return (first["time"], np.vstack(buy), np.vstack(sell), first["price_buy_eur_per_kwh"].to_numpy(float),
            first["price_sell_eur_per_kwh"].to_numpy(float), pd.Series(use, dtype=float))


def isolated_households(folder: Path, meta: Mapping[str, Any], costs: economics.Costs,
                        rules: Sequence[str]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every isolated household at every store size under every rule set, and every store size's facts."""
    rows, facts = [], []
    houses = meta["houses"]
    dt_h = float(meta["dt_h"])
    for hub_kwh, runs in meta["isolated"].items():
        time, buy, sell, p_buy, p_sell, use_w = _isolated_meters(folder, runs)
        names = list(runs)
        settled = settle_meters(time, meta["timezone"], buy, sell, np.zeros(buy.shape[1]),
                                np.full(buy.shape, 1.0 / len(names)), p_buy, p_sell, dt_h, names)
        use = use_w * dt_h / W_PER_KW
        own, alone = {}, {}
        for name, iso in runs.items():
            run = Path(folder) / "runs" / iso["run"]
            own[name] = _json(run / "houses" / name / "summary.json", "an isolated house's summary")
            alone[name] = _json(run / "community.json", "an isolated house's run summary")
        closing = {n: economics.cycle_closes(own[n]) for n in names}
        verdicts = [c for c, _ in closing.values()]
        closes = None if any(v is None for v in verdicts) else all(verdicts)
        why = "; ".join(f"{n}: {w}" for n, (c, w) in closing.items() if c is not True) or "closes"
        modules = sum(int(houses[n]["sizes"]["el_modules"]) for n in names)
        facts.append({"arm": "isolated", "hub_kwh": float(hub_kwh), "modules": modules, "closes": closes, "why": why,
                      "houses_closing": sum(v is True for v in verdicts),
                      "h2_produced_kwh": sum(float(a["h2_produced_kwh"]) for a in alone.values()),
                      "loh_end": float(np.mean([float(o["loh_end"]) for o in own.values()])),
                      "charges": {r: settled[r].totals["charges_on_shared_eur"] for r in rules}})
        for rule in rules:
            ss = household_self_sufficiency(settled[rule], use)
            for name, iso in runs.items():
                house = houses[name]
                sizes = {**house["sizes"], "h2_kwh": float(iso["store_kwh"])}
                c = household_costs(sizes, own[name], float(settled[rule].houses.loc[name, "cost_eur"]), costs,
                                    float(house["usable_battery_kwh"]), run_weeks(alone[name], dt_h),
                                    float(alone[name]["el_working_hours"]))
                rows.append({**c, "arm": "isolated", "hub_kwh": float(hub_kwh), "modules": modules, "rule": rule,
                             "house": name, "h2_kwh": float(iso["store_kwh"]),
                             "el_modules": int(house["sizes"]["el_modules"]), "self_sufficiency": float(ss[name]),
                             "grid_kwh": (1.0 - float(ss[name])) * float(use[name]), "use_kwh": float(use[name]),
                             "loh_end": float(own[name]["loh_end"]),
                             "discomfort_kh_total": float(own[name]["discomfort_kh_total"]),
                             "closes": closing[name][0], "why": closing[name][1], "run": f"runs/{iso['run']}"})
    return rows, facts


def points_table(households: pd.DataFrame, facts: Sequence[Mapping[str, Any]], n_houses: int) -> pd.DataFrame:
    """One row per arm, hub size and rule set: the households' mean, the community's total, the cycle."""
    rows = []
    by_key = {(f["arm"], float(f["hub_kwh"]), int(f["modules"])): f for f in facts}
    for (arm, hub_kwh, modules, rule), sub in households.groupby(["arm", "hub_kwh", "modules", "rule"], sort=False):
        f = by_key[(str(arm), float(hub_kwh), int(modules))]
        capital = sub["annuity_eur_a"] + sub["om_eur_a"] + sub["hub_annuity_eur_a"] + sub["hub_om_eur_a"]
        houses_closing = f.get("houses_closing", int((sub["closes"] == True).sum()))  # noqa: E712
        rows.append({"arm": arm, "hub_kwh": float(hub_kwh), "modules": int(modules), "rule": rule,
                     "households": len(sub), "h2_kwh_per_house": float(hub_kwh) / n_houses,
                     "el_modules_per_house": int(modules) / n_houses,
                     "total_eur_a_per_household": float(sub["total_eur_a"].mean()),
                     "energy_eur_a_per_household": float(sub["energy_eur_a"].mean()),
                     "capital_eur_a_per_household": float(capital.mean()),
                     "invest_eur_per_household": float(sub["invest_eur"].mean()),
                     "total_eur_a": float(sub["total_eur_a"].sum()),
                     "self_sufficiency": 1.0 - float(sub["grid_kwh"].sum()) / float(sub["use_kwh"].sum()),
                     "charges_on_shared_eur": float(f["charges"][rule]), "h2_produced_kwh": f["h2_produced_kwh"],
                     "loh_end": f["loh_end"], "closes": f["closes"], "houses_closing": houses_closing,
                     "why": f["why"]})
    df = pd.DataFrame(rows)
    iso = df[df["arm"] == "isolated"].set_index(["hub_kwh", "rule"])["total_eur_a_per_household"]
    df["vs_isolated_eur_a_per_household"] = [
        r.total_eur_a_per_household - iso.get((r.hub_kwh, r.rule), np.nan) if r.arm == "hub" else 0.0
        for r in df.itertuples()]
    return df[list(POINT_COLUMNS)]


def _money(v: float) -> str:
    return f"{v:,.0f}".replace(",", " ")


def answer(points: pd.DataFrame, labels: Mapping[str, str]) -> list[str]:
    """The study's answer per rule set, in sentences: the cheapest isolated and shared design, the
    difference per household, and the smallest H2 capacity per house that closes the cycle."""
    lines = []
    for rule, sub in points.groupby("rule", sort=False):
        iso = sub[sub["arm"] == "isolated"]
        hub = sub[sub["arm"] == "hub"]
        if iso.empty or hub.empty:
            continue
        best_iso = iso.loc[iso["total_eur_a_per_household"].idxmin()]
        best_hub = hub.loc[hub["total_eur_a_per_household"].idxmin()]
        diff = best_hub["total_eur_a_per_household"] - best_iso["total_eur_a_per_household"]
        rel = diff / best_iso["total_eur_a_per_household"] * PERCENT
        lines.append(
            f"{labels.get(str(rule), rule)}: cheapest isolated {_money(best_iso['total_eur_a_per_household'])} EUR/a "
            f"per household ({best_iso['h2_kwh_per_house']:g} kWh each), cheapest hub "
            f"{_money(best_hub['total_eur_a_per_household'])} EUR/a ({best_hub['hub_kwh']:g} kWh, "
            f"{_modules(best_hub['modules'])}): {'+' if diff >= 0 else '-'}{_money(abs(diff))} EUR/a "
            f"({rel:+.1f} %); {_closing(iso, hub)}")
    return lines


def _modules(n: Any) -> str:
    return f"{int(n)} module{'s' if int(n) != 1 else ''}"


def _closing(iso: pd.DataFrame, hub: pd.DataFrame) -> str:
    """The smallest H2 capacity per house that closes the cycle, isolated and shared, in words."""
    if iso["closes"].isna().all() and hub["closes"].isna().all():
        return "the seasonal cycle is not tested (the run has no full heating-season week)"
    c_iso = smallest_closing(iso.to_dict("records"))
    c_hub = smallest_closing(hub.to_dict("records"))
    cap_iso = (f"{c_iso['h2_kwh_per_house']:g} kWh per house" if c_iso else
               "no store of the design (largest: "
               f"{int(iso.loc[iso['h2_kwh_per_house'].idxmax(), 'houses_closing'])} of {int(iso['households'].iloc[0])}"
               " houses close)")
    cap_hub = (f"{c_hub['h2_kwh_per_house']:g} kWh per house ({c_hub['hub_kwh']:g} kWh, {_modules(c_hub['modules'])})"
               if c_hub else "no hub of the design")
    return f"the seasonal cycle closes from {cap_iso} isolated, from {cap_hub} shared"


@styled
def cost_figure(points: pd.DataFrame, labels: Mapping[str, str]) -> Figure:
    """Annual cost per household over the H2 store per house, one panel per rule set: the isolated
    houses and the hub per number of modules; a filled marker closes the seasonal cycle."""
    rules = list(dict.fromkeys(points["rule"]))
    ncols = 2 if len(rules) > 1 else 1
    nrows = int(np.ceil(len(rules) / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=figsize("double", 55 * nrows + 20), sharex=True, sharey=True,
                             squeeze=False)
    modules = sorted(set(points.loc[points["arm"] == "hub", "modules"]))
    colours = [style.OKABE_ITO[c] for c in ("blue", "vermillion", "bluish_green", "orange", "reddish_purple")]
    series = [("isolated", None, style.OKABE_ITO["black"], "isolated houses")]
    series += [("hub", m, colours[i % len(colours)], f"shared hub, {m} modules") for i, m in enumerate(modules)]
    for ax, rule in zip(axes.flat, rules):
        sub = points[points["rule"] == rule]
        for arm, m, colour, label in series:
            line = sub[(sub["arm"] == arm) & ((sub["modules"] == m) if m is not None else True)]
            line = line.sort_values("h2_kwh_per_house")
            if line.empty:
                continue
            ax.plot(line["h2_kwh_per_house"], line["total_eur_a_per_household"], color=colour, lw=1.0, label=label)
            closing = (line["closes"] == True).to_numpy()  # noqa: E712
            ax.scatter(line["h2_kwh_per_house"][closing], line["total_eur_a_per_household"][closing], color=colour,
                       s=18, zorder=3)
            ax.scatter(line["h2_kwh_per_house"][~closing], line["total_eur_a_per_household"][~closing],
                       facecolors="white", edgecolors=colour, s=18, zorder=3)
        ax.set_title(labels.get(rule, rule))
    for ax in axes.flat[len(rules):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel(axis_label("H2 store per house (LHV)", "kWh"))
    for ax in axes[:, 0]:
        ax.set_ylabel(axis_label("annual cost per household", "EUR"))
    handles, names = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncol=len(series))
    return fig


def report(meta: Mapping[str, Any], costs: economics.Costs, households: pd.DataFrame, points: pd.DataFrame,
           lines: Sequence[str], png: Path, labels: Mapping[str, str]) -> Document:
    """The study's report: design, definitions, the answer, the points, every household."""
    doc = Document("ComEMS4Build: isolated houses or a shared H2 hub over the year")
    n = len(meta["houses"])
    hubs = ", ".join(f"{h['store_kwh']:g} kWh with {_modules(h['modules'])}" for h in meta["hub_sizes"])
    doc.p(f"Community {meta['community']} ({meta['community_file']}): {n} houses, every house ComEMS4Build's "
          f"house with the EMS '{meta['ems']}'; hub coordinator '{meta['coordinator']}' "
          f"{json.dumps(meta['coordinator_options']) if meta['coordinator_options'] else ''}; scenario: year "
          f"(config/year.yaml) from {meta['start'] or '2022-03-01'}, {meta['weeks']} weeks. Hubs: {hubs}. Isolated "
          f"houses: each with its own electrolyser and a store of its nominal share of each hub store. "
          f"{len(meta['hub_sizes']) + sum(len(v) for v in meta['isolated'].values())} runs in "
          f"{meta.get('wall_s', float('nan')):.0f} s wall on {meta['workers']} (load average "
          f"{meta['load_average_start'][0]:.1f} at the start, {meta.get('load_average_end', [float('nan')])[0]:.1f} "
          "at the end).")
    if float(meta["weeks"]) < economics.WEEKS_PER_YEAR:
        doc.p(f"The runs are {meta['weeks']} weeks, not the year: the annual figures are scaled to 52 weeks and the "
              "seasonal cycle is tested only over the run (n/a without a heating-season week).")
    doc.h(2, "The answer")
    for line in lines:
        doc.p(line)
    doc.figure(png, "figures", "Annual cost per household (energy under the rule set, annuities, O&M and wear of "
               "the PV, battery and H2 system) over the H2 store per house; black: every house with its own H2 "
               "system, coloured: one shared hub per number of electrolyser modules; a filled marker closes the "
               "seasonal cycle.")
    doc.h(2, "Definitions")
    doc.p("Annual cost per household = energy (its meter settled under the rule set and, with a hub, its part of the "
          "hub's electricity, per 52 weeks) + the annuity and O&M of its PV, battery and FC with their wear "
          "(as size: docs/sizing.md) + its own electrolyser and store (isolated) or its part of the hub's (shared). "
          f"The hub's annuity and O&M are split {HUB_COST_SPLIT}. Self-sufficiency = 1 - what the household takes "
          "from the grid / what it uses (appliances, heat pump, electrolysers behind its meter or its part of the "
          "hub's); under a rule set that shares, energy a neighbour exported is not taken from the grid.")
    doc.p("The seasonal cycle closes as in size: isolated, for every house's own store; shared, on the hub: the "
          "summer fills it, it ends the year at least as full as it started, no house's account runs dry and no "
          "house has a heating-season week with discomfort.")
    cost_figures(doc, costs)
    doc.p("Sources and choices: config/costs.yaml. The hub's modules are the houses' Enapter EL 2.1 and its store "
          "the houses' 300 bar steel bottles at the same figures per module and per kWh (no sourced figure for a "
          "cheaper store at this scale).")
    doc.h(2, "Points")
    cols = [c for c in POINT_COLUMNS if c != "why"]
    doc.table(cols, markdown_rows(points, cols))
    doc.p("Why a point does not close: " + "; ".join(
        f"{r.arm} {r.hub_kwh:g} kWh / {r.modules} modules: {r.why}" for r in
        points.drop_duplicates(["arm", "hub_kwh", "modules"]).itertuples() if r.closes is not True) or
        "every point closes the cycle.")
    doc.h(2, "Households")
    cols = [c for c in HOUSEHOLD_COLUMNS if c not in ("why", "run")]
    doc.table(cols, markdown_rows(households[households["rule"] == BASE_RULE]
                                  if BASE_RULE in set(households["rule"]) else households, cols))
    doc.p("The table shows the base rule set; households.csv holds every rule set.")
    return doc


def write_outputs(folder: Path, out: Path | None = None) -> StudyResult:
    """Read the study in ``folder``; write its tables, figure and report into ``out`` (default ``folder``).

    Raises
    ------
    RunDirError
        Naming the file: a missing or corrupt manifest, run summary or table.
    """
    folder = Path(folder)
    out = Path(out) if out is not None else folder
    meta = read_manifest(folder)
    costs = costs_of(meta)
    sharing = load_sharing_rules()
    rules = list(sharing.rule_sets)
    labels = {name: r.label for name, r in sharing.rule_sets.items()}
    iso_rows, iso_facts = isolated_households(folder, meta, costs, rules)
    hub_rows, hub_facts = hub_households(folder, meta, costs, rules)
    households = pd.DataFrame(iso_rows + hub_rows)[list(HOUSEHOLD_COLUMNS)]
    points = points_table(households, iso_facts + hub_facts, len(meta["houses"]))
    lines = answer(points, labels)
    households.to_csv(out / "households.csv", index=False)
    points.to_csv(out / "points.csv", index=False)
    png = save_figure(cost_figure(points, labels), out / "figures" / "household_cost")
    doc = report(meta, costs, households, points, lines, png, labels)
    (out / "report.md").write_text(doc.markdown(), encoding="utf-8")
    (out / "report.html").write_text(doc.html(), encoding="utf-8")
    return StudyResult(households, points, lines, png)

