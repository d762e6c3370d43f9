"""The co-simulation study's table, findings and document (``docs/cosimulation.md``).

Reads the two comparison folders of :mod:`comems4build_ros.study.cosim` (``rc/`` and
``energyplus/``), measures the paper's statements (:mod:`~comems4build_ros.report.paper`) and
checks its findings (:mod:`~comems4build_ros.report.findings`) on each, and writes the
document: the paper's headline table on the detailed house beside the 4R3C's and the
paper's, the findings marked as holding or not on each building, the MPC's model error
beside them, and for every finding that does not hold on the detailed house the figures that
explain it. Every number in the document is computed here from the runs, the identification
report and the house figures; the prose around them is fixed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from comems4build_ros.report.findings import Context, evaluate_findings
from comems4build_ros.report.paper import Evidence, evaluate_statements, load_paper_results

#: The paper's headline figures shown in the table, in order (keys of ``paper_results.yaml``).
TABLE_KEYS = ("cost", "reimbursement", "discomfort_median", "weeks_without_discomfort", "buy", "sell",
              "bess_charged", "h2_week_min", "h2_week_max", "loh_end", "fc_hours_vs_mpc", "fc_toggles_vs_mpc")
#: The findings the co-simulation asks about first (keys of ``findings.py``), with a short name.
HEADLINE = (
    ("fuzzy_discomfort_free", "comfort: ComEMS4Build without discomfort in 10 of 12 weeks"),
    ("mpc_cheapest", "cost order: the MPC cheapest"),
    ("fuzzy_cheaper_than_rbc", "cost order: ComEMS4Build cheaper than the RBC"),
    ("fuzzy_fc_more_than_mpc", "FC hours and toggles: ComEMS4Build above the MPC"),
    ("rbc_fc_less_than_mpc", "FC hours and toggles: the RBC below the MPC"),
    ("fuzzy_h2_even", "near-linear H2 use of ComEMS4Build"),
)
EMS_ORDER = ("mpc", "fuzzy", "rbc")
LABELS = {"mpc": "MPC", "fuzzy": "ComEMS4Build", "rbc": "RBC", "thermostat": "thermostat"}
BUILDING_LABELS = {"rc": "4R3C", "energyplus": "EnergyPlus house"}


@dataclass
class BuildingResult:
    """What one building's runs give: figures by (statement, EMS), verdicts by finding, summaries."""

    figures: dict[tuple[str, str], Any]
    verdicts: dict[str, tuple[str, str]]
    summaries: dict[str, dict[str, Any]]
    claims: dict[str, str]
    timeseries: dict[str, Any]
    weekly: dict[str, Any]


def building_result(folder: str | Path) -> BuildingResult:
    """Statements and findings measured on one comparison folder."""
    from comems4build_ros.report.build import read_report_inputs

    cmp = read_report_inputs(folder)
    statements = load_paper_results()
    figs = evaluate_statements(Evidence(runs=cmp.runs, params=cmp.params, base_eta=cmp.manifest.base_eta,
                                        variants=cmp.variants), statements)
    ctx = Context(runs=cmp.runs, variants=cmp.variants, params=cmp.params, base_eta=cmp.manifest.base_eta)
    verdicts = {f.key: (v.status, v.evidence) for f, v in evaluate_findings(ctx)}
    claims = {f.key: f.claim for f, _ in evaluate_findings(ctx)}
    return BuildingResult({(f.key, f.ems): f.ours for f in figs}, verdicts,
                          {e: r.summary for e, r in cmp.runs.items()}, claims,
                          {e: r.timeseries for e, r in cmp.runs.items()}, {e: r.weekly for e, r in cmp.runs.items()})


def _num(value: Any, digits: int = 2) -> str:
    if value is None:
        return "-"
    if isinstance(value, list):
        return ", ".join(str(v) for v in value) or "none"
    if isinstance(value, dict) and "below" in value:
        return f"< {value['below']}"
    try:
        x = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def table_markdown(results: dict[str, BuildingResult]) -> str:
    """The paper's headline figures: paper | 4R3C | EnergyPlus house, per EMS."""
    statements = {s.key: s for s in load_paper_results().statements}
    head = "| figure | unit | EMS | paper | 4R3C | EnergyPlus house |\n|---|---|---|---|---|---|\n"
    rows = []
    for key in TABLE_KEYS:
        s = statements[key]
        for ems in EMS_ORDER:
            if ems not in s.paper:
                continue
            ours = [_num(results[b].figures.get((key, ems))) for b in ("rc", "energyplus")]
            rows.append(f"| {s.label} | {s.unit} | {LABELS[ems]} | {_num(s.paper[ems])} | {ours[0]} | {ours[1]} |")
    return head + "\n".join(rows) + "\n"


def ratios(res: BuildingResult) -> dict[str, float]:
    """Cost ratios to ComEMS4Build and FC hours/toggles relative to the MPC [%] of one building."""
    s = res.summaries
    out = {f"cost {LABELS[e]} / ComEMS4Build": s[e]["cost_eur_week_median"] / s["fuzzy"]["cost_eur_week_median"]
           for e in ("mpc", "rbc")}
    for e in ("fuzzy", "rbc"):
        for key, name in (("fc_working_hours", "FC hours"), ("fc_toggles", "FC toggles")):
            ref = float(s["mpc"][key])
            out[f"{name} {LABELS[e]} vs MPC [%]"] = math.nan if ref == 0 else 100.0 * (float(s[e][key]) / ref - 1)
    return out


def h2_linearity(ts: Any, loh_init: float = 1.0) -> float:
    """R^2 of the LOH over time against a straight line (1 = perfectly linear H2 use) [-]."""
    y = ts["loh"].to_numpy(float)
    x = np.arange(len(y), dtype=float)
    if np.ptp(y) == 0:
        return math.nan
    coef = np.polyfit(x, y, 1)
    resid = y - np.polyval(coef, x)
    return float(1.0 - resid.var() / y.var())


def band_violation_kh(ts: Any, dt_h: float = 1.0) -> tuple[float, float]:
    """Kelvin-hours of the end-of-step air temperature above T_max and below T_min over a run [Kh]."""
    t = ts["t_air_c"].to_numpy(float)
    above = np.clip(t - ts["t_max_c"].to_numpy(float), 0.0, None).sum() * dt_h
    below = np.clip(ts["t_min_c"].to_numpy(float) - t, 0.0, None).sum() * dt_h
    return float(above), float(below)


def explain(key: str, res: BuildingResult, rc: BuildingResult, ident: dict[str, Any]) -> str:
    """Figures that explain why a finding does not hold on the detailed house (computed from the runs)."""
    s, s0 = res.summaries, rc.summaries
    v = ident.get("evaluation_weeks_thermostat", {})
    lines = []

    def per_ems(key_: str, unit: str, digits: int = 2) -> str:
        return "; ".join(f"{LABELS[e]} {_num(s[e].get(key_), digits)} {unit} (4R3C {_num(s0[e].get(key_), digits)})"
                         for e in EMS_ORDER if e in s)

    if key.startswith("mpc") or "mpc" in key:
        lines.append(f"The MPC plans with the identified 4R3C, whose 24-h open-loop T_air error on the held-out "
                     f"evaluation weeks is {_num(v.get('rmse_k'), 3)} K RMSE (largest "
                     f"{_num(v.get('max_abs_k'), 2)} K); "
                     "on the 4R3C plant it has no model error.")
    if "discomfort" in key or "comfort" in key:
        lines.append("Discomfort [Kh/week, median]: " + per_ems("discomfort_kh_week_median", "Kh/week") + ".")
        lines.append("Weeks with discomfort: " + per_ems("discomfort_weeks_nonzero", "", 0) + ".")
        split = {b: {e: band_violation_kh(r.timeseries[e]) for e in EMS_ORDER} for b, r in (("rc", rc), ("ep", res))}
        text = "; ".join(f"{LABELS[e]} {split['ep'][e][0]:.1f} / {split['ep'][e][1]:.1f} (4R3C "
                         f"{split['rc'][e][0]:.1f} / {split['rc'][e][1]:.1f})" for e in EMS_ORDER)
        lines.append(f"Over the run, air temperature above T_max / below T_min at the end of each hour [Kh]: {text}.")
        for e in EMS_ORDER:
            up, down = split["ep"][e]
            if up + down > 0:
                lines.append(f"On the house {100.0 * up / (up + down):.0f} % of {LABELS[e]}'s band violation lies "
                             "above T_max.")
    if "cost" in key or "cheap" in key:
        lines.append("Weekly cost [EUR, median]: " + per_ems("cost_eur_week_median", "EUR") + ".")
    if "fc" in key:
        lines.append("Change of the FC working hours from the 4R3C to the house: " + "; ".join(
            f"{LABELS[e]} {100.0 * (float(s[e]['fc_working_hours']) / float(s0[e]['fc_working_hours']) - 1.0):+.1f} %"
            for e in EMS_ORDER if float(s0[e]["fc_working_hours"]) > 0) + ".")
        lines.append("FC working hours: " + per_ems("fc_working_hours", "h", 0) + "; FC toggles: "
                     + per_ems("fc_toggles", "", 0) + ".")
    if "h2" in key:
        lines.append("LOH left: " + per_ems("loh_end", "", 3) + "; R^2 of the LOH against a straight line: "
                     + "; ".join(f"{LABELS[e]} {h2_linearity(res.timeseries[e]):.3f} (4R3C "
                                 f"{h2_linearity(rc.timeseries[e]):.3f})" for e in EMS_ORDER) + ".")
    if "sell" in key or "buy" in key or "bess" in key:
        lines.append("Sold [kWh/week, median]: " + per_ems("sell_kwh_week_median", "kWh") + "; bought: "
                     + per_ems("buy_kwh_week_median", "kWh") + ".")
    heat = {e: float(res.timeseries[e]["q_hp_sh_w"].sum()) / 1000.0 for e in res.timeseries}
    heat0 = {e: float(rc.timeseries[e]["q_hp_sh_w"].sum()) / 1000.0 for e in rc.timeseries}
    lines.append("Space heat over the run [kWh]: " + "; ".join(
        f"{LABELS.get(e, e)} {heat[e]:.0f} (4R3C {heat0.get(e, math.nan):.0f})" for e in heat) + ".")
    return " ".join(lines)


def findings_markdown(results: dict[str, BuildingResult], ident: dict[str, Any]) -> tuple[str, list[str]]:
    """The findings table (headline first) and the explanations of those that do not hold on the house."""
    rc, ep = results["rc"], results["energyplus"]
    head = "| finding | claim | 4R3C | EnergyPlus house | evidence on the EnergyPlus house |\n|---|---|---|---|---|\n"
    keys = [k for k, _ in HEADLINE] + [k for k in ep.verdicts if k not in dict(HEADLINE)]
    rows, notes = [], []
    for k in keys:
        name = dict(HEADLINE).get(k, k)
        st0, st1 = rc.verdicts[k][0], ep.verdicts[k][0]
        evidence = ep.verdicts[k][1].replace("|", "/")
        rows.append(f"| {'**' + name + '**' if k in dict(HEADLINE) else name} | {ep.claims[k]} | {st0} | {st1} | "
                    f"{evidence} |")
        if st1 == "not held":
            notes.append(f"- **{name}** ({'holds' if st0 == 'held' else 'does not hold either'} on the 4R3C). "
                         + explain(k, ep, rc, ident))
    return head + "\n".join(rows) + "\n", notes


def cosim_markdown(results: dict[str, BuildingResult], ident: dict[str, Any], house: dict[str, Any],
                   commands: dict[str, str]) -> str:
    """The whole ``docs/cosimulation.md``."""
    from comems4build_ros.report.cosim_text import document

    fin, notes = findings_markdown(results, ident)
    held = {b: sum(v[0] == "held" for v in r.verdicts.values()) for b, r in results.items()}
    evaluated = {b: sum(v[0] != "n/a" for v in r.verdicts.values()) for b, r in results.items()}
    rat = {b: ratios(r) for b, r in results.items()}
    ratio_rows = "| figure | paper | 4R3C | EnergyPlus house |\n|---|---|---|---|\n"
    st = load_paper_results()
    cost = st.get("cost").paper
    hours, toggles = st.get("fc_hours_vs_mpc").paper, st.get("fc_toggles_vs_mpc").paper
    paper_rat = {"cost MPC / ComEMS4Build": cost["mpc"] / cost["fuzzy"], "cost RBC / ComEMS4Build":
                 cost["rbc"] / cost["fuzzy"], "FC hours ComEMS4Build vs MPC [%]": hours["fuzzy"],
                 "FC toggles ComEMS4Build vs MPC [%]": toggles["fuzzy"], "FC hours RBC vs MPC [%]": hours["rbc"],
                 "FC toggles RBC vs MPC [%]": toggles["rbc"]}
    for k in rat["rc"]:
        ratio_rows += f"| {k} | {_num(paper_rat.get(k))} | {_num(rat['rc'][k])} | {_num(rat['energyplus'][k])} |\n"
    thermo = {b: r.summaries.get("thermostat", {}) for b, r in results.items()}
    lin = "| EMS | 4R3C | EnergyPlus house |\n|---|---|---|\n" + "".join(
        f"| {LABELS[e]} | {h2_linearity(results['rc'].timeseries[e]):.3f} | "
        f"{h2_linearity(results['energyplus'].timeseries[e]):.3f} |\n" for e in EMS_ORDER)
    return document(table=table_markdown(results), findings=fin, notes="\n".join(notes) or "- none",
                    held=held, evaluated=evaluated, ratios=ratio_rows, linearity=lin, ident=ident, house=house,
                    thermostat=thermo, commands=commands, changes=changes_markdown(results, ident))


def changes_markdown(results: dict[str, BuildingResult], ident: dict[str, Any]) -> str:
    """What differs between the two buildings, per EMS, as computed bullets."""
    rc, ep = results["rc"], results["energyplus"]
    names = [e for e in (*EMS_ORDER, "thermostat") if e in ep.timeseries and e in rc.timeseries]

    def total(res: BuildingResult, e: str, col: str) -> float:
        return float(res.timeseries[e][col].sum()) / 1000.0

    def row(label: str, col: str, digits: int = 0) -> str:
        return f"- {label}: " + "; ".join(
            f"{LABELS[e]} {total(rc, e, col):.{digits}f} on the 4R3C, {total(ep, e, col):.{digits}f} on the house"
            for e in names) + "."

    first = next(iter(ep.timeseries.values()))
    load = float(first["p_load_w"].sum()) / 1000.0
    e = ident.get("evaluation_weeks_thermostat", {})
    air = {b: {x: float(r.timeseries[x]["t_air_c"].mean()) for x in names} for b, r in results.items()}
    lines = [
        f"- Internal gains: none in either building (the appliance load, {load:.0f} kWh over the run, is "
        "electricity bought, its heat not counted in the rooms: the paper's 4R3C has no internal-gain term, "
        "`eq:dT_i`, and the house is built to match it).",
        row("Space heat of the heat pump [kWh]", "q_hp_sh_w"),
        row("Electricity bought [kWh]", "p_buy_w"),
        row("Fuel-cell electricity [kWh]", "p_fc_w"),
        "- Mean air temperature [degC]: " + "; ".join(
            f"{LABELS[x]} {air['rc'][x]:.2f} on the 4R3C, {air['energyplus'][x]:.2f} on the house" for x in names)
        + ".",
        f"- The MPC plans with the identified 4R3C (24-h open-loop T_air error {_num(e.get('rmse_k'), 3)} K RMSE on "
        "the evaluation weeks under the thermostat) and estimates its wall nodes from the measured air "
        "temperature; on the 4R3C it has the plant's own model and states.",
    ]
    return "\n".join(lines)


def comfort_figure(results: dict[str, BuildingResult], path_stem: str | Path) -> Path:
    """Weekly discomfort per EMS on both buildings, and T_air in the week of ComEMS4Build's largest on the house.

    Top: weekly thermal discomfort (``eq:discomfort``, the weekly table) of each EMS, the 4R3C
    hatched beside the EnergyPlus house. Middle and bottom: T_air of each EMS over that week
    on the 4R3C and on the house, with the comfort band [T_min, T_max].
    """
    import matplotlib.pyplot as plt
    import pandas as pd

    from comems4build_ros.report.style import axis_label, ems_colour, ems_label, figsize, paper_style, save_figure

    ep = results["energyplus"]
    with paper_style():
        fig, axes = plt.subplots(3, 1, figsize=figsize("double", 170.0), layout="constrained")
        ax = axes[0]
        weeks = None
        width = 0.13
        for i, e in enumerate(EMS_ORDER):
            for j, (b, hatch) in enumerate((("rc", "//"), ("energyplus", ""))):
                w = _weekly_discomfort(results[b], e)
                weeks = w.index if weeks is None else weeks
                x = np.arange(len(w)) + (2 * i + j - 2.5) * width
                ax.bar(x, w.to_numpy(), width, color=ems_colour(e), hatch=hatch, edgecolor="black", linewidth=0.3,
                       label=f"{ems_label(e)}, {BUILDING_LABELS[b]}")
        ax.set_xticks(np.arange(len(weeks)), [str(int(k)) for k in weeks])
        ax.set_xlabel("week")
        ax.set_ylabel(axis_label("discomfort", "Kh"))
        ax.legend(ncols=3, fontsize="small")
        fuzzy_weeks = _weekly_discomfort(ep, "fuzzy")
        worst = int(fuzzy_weeks.idxmax()) if len(fuzzy_weeks) else 1
        for ax, b in zip(axes[1:], ("rc", "energyplus")):
            ts = results[b].timeseries
            sel = slice((worst - 1) * 168, worst * 168)
            first = ts["fuzzy"].iloc[sel]
            t = pd.to_datetime(first["time"], utc=True)
            ax.fill_between(t, first["t_min_c"], first["t_max_c"], color="0.9", step="post", label="comfort band")
            for e in EMS_ORDER:
                ax.plot(t, ts[e]["t_air_c"].iloc[sel], color=ems_colour(e), label=ems_label(e), linewidth=0.8)
            ax.set_ylabel(axis_label("T_air", "degC"))
            ax.set_title(f"{BUILDING_LABELS[b]}, week {worst}", fontsize="small")
        axes[1].legend(ncols=4, fontsize="small")
        return save_figure(fig, path_stem)


def _weekly_discomfort(res: BuildingResult, ems: str) -> Any:
    """Weekly discomfort [Kh] of one EMS over its complete weeks, indexed by the week number (1 = the first)."""
    import pandas as pd

    from comems4build_ros.core.kpi import HOURS_PER_WEEK

    w = res.weekly[ems]
    if "hours" in w:
        w = w[w["hours"] >= HOURS_PER_WEEK - 1e-9]
    return pd.Series(w["discomfort_kh"].to_numpy(float), index=np.arange(1, len(w) + 1))
