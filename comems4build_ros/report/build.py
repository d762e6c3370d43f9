"""Build the comparison report (``report.md``, ``report.html``, figures) from run directories.

Report generation only reads the runs written before (``runs/<name>/`` and the manifest
``compare.json``); it never simulates. The Markdown and the HTML come from the same list
of blocks, so they hold the same numbers; the HTML embeds the figures as base64 PNG and
needs no other file. ``findings.json`` and ``paper_comparison.csv`` carry the same content
for scripts.
"""

from __future__ import annotations

import base64
import html
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from ..config import load_plant_params
from . import figures
from .findings import Context, evaluate_findings
from .paper import fmt, paper_table
from .runs import Manifest, RunData, read_comparison

#: Weekly table columns: (weekly.csv column, header, decimals).
WEEKLY_TABLE = (
    ("discomfort_kh", "discomfort [Kh]", 2),
    ("cost_eur", "cost [EUR]", 2),
    ("reimbursement_eur", "reimb. [EUR]", 2),
    ("buy_kwh", "bought [kWh]", 2),
    ("sell_kwh", "sold [kWh]", 2),
    ("bess_charged_kwh", "BESS ch. [kWh]", 2),
    ("h2_kwh", "H2 [kWh]", 2),
    ("heat_recovered_kwh", "FC heat [kWh]", 2),
    ("dhw_demand_kwh", "DHW dem. [kWh]", 2),
    ("fc_working_hours", "FC hours [h]", 0),
    ("fc_toggles", "FC starts [-]", 0),
)
#: Summary table rows: (summary.json key, label, decimals; None = printed as is).
SUMMARY_TABLE = (
    ("cost_eur_week_median", "cost, weekly median [EUR]", 2),
    ("reimbursement_eur_week_median", "reimbursement, weekly median [EUR]", 2),
    ("discomfort_kh_week_median", "discomfort, weekly median [Kh]", 2),
    ("discomfort_weeks_nonzero", "weeks with discomfort [-]", 0),
    ("buy_kwh_week_median", "bought, weekly median [kWh]", 2),
    ("sell_kwh_week_median", "sold, weekly median [kWh]", 2),
    ("bess_charged_kwh_week_median", "BESS charged, weekly median [kWh]", 2),
    ("h2_kwh_week_min", "H2 use, weekly min [kWh]", 2),
    ("h2_kwh_week_max", "H2 use, weekly max [kWh]", 2),
    ("fc_working_hours", "FC working hours [h]", 0),
    ("fc_toggles", "FC toggles [-]", 0),
    ("fc_mean_load_w", "FC mean load when on [W]", 0),
    ("fc_mean_eta_el", "FC mean electrical efficiency [-]", 3),
    ("loh_end", "LOH at the end [-]", 4),
    ("h2_empty_at", "LOH_min reached at", None),
    ("dhw_unmet_kwh", "unmet DHW [kWh]", 2),
    ("wall_s", "run wall time [s]", 1),
)


@dataclass
class Report:
    """Paths written and the time taken."""

    markdown: Path
    html: Path
    figures: dict[str, Path]
    findings: list[dict[str, str]]
    seconds: float


def _eta_name(eta: float) -> str:
    return f"{eta * 100:.0f} %"


def _cell(value: Any, digits: int | None) -> str:
    if value is None:
        return "-"
    if digits is None:
        return str(value)
    return fmt(float(value), digits)


class _Doc:
    """Blocks rendered to Markdown and HTML alike."""

    def __init__(self) -> None:
        self.blocks: list[tuple[Any, ...]] = []

    def h(self, level: int, text: str) -> None:
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, header: list[str], rows: list[list[str]]) -> None:
        self.blocks.append(("table", header, rows))

    def img(self, path: Path, rel: str, caption: str) -> None:
        self.blocks.append(("img", path, rel, caption))

    def markdown(self) -> str:
        out: list[str] = []
        for b in self.blocks:
            if b[0] == "h":
                out.append("#" * b[1] + " " + b[2])
            elif b[0] == "p":
                out.append(b[1])
            elif b[0] == "table":
                esc = [[str(c).replace("|", "\\|") for c in row] for row in [b[1], *b[2]]]
                out.append("| " + " | ".join(esc[0]) + " |")
                out.append("|" + "|".join("---" for _ in esc[0]) + "|")
                out.extend("| " + " | ".join(r) + " |" for r in esc[1:])
            elif b[0] == "img":
                out.append(f"![{b[3]}]({b[2]})\n\n*{b[3]}*")
            out.append("")
        return "\n".join(out)

    def html(self, title: str) -> str:
        e = html.escape
        parts = [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f"<title>{e(title)}</title>",
            "<style>body{font-family:sans-serif;max-width:1250px;margin:2em auto;padding:0 1em;line-height:1.4}"
            "table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.88em}"
            "th,td{border:1px solid #bbb;padding:3px 7px;text-align:right}th{background:#eee}"
            "td:first-child,th:first-child{text-align:left}img{max-width:100%}"
            "figcaption{font-style:italic;margin-bottom:1.5em}</style></head><body>",
        ]
        for b in self.blocks:
            if b[0] == "h":
                parts.append(f"<h{b[1]}>{e(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                parts.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "table":
                parts.append("<table><thead><tr>" + "".join(f"<th>{e(str(c))}</th>" for c in b[1]) + "</tr></thead>")
                parts.append("<tbody>" + "".join(
                    "<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>" for row in b[2]
                ) + "</tbody></table>")
            elif b[0] == "img":
                data = base64.b64encode(Path(b[1]).read_bytes()).decode("ascii")
                parts.append(f'<figure><img alt="{e(b[3])}" src="data:image/png;base64,{data}">'
                             f"<figcaption>{e(b[3])}</figcaption></figure>")
        parts.append("</body></html>")
        return "\n".join(parts)


def weekly_rows(run: RunData) -> list[list[str]]:
    """Rows of the weekly KPI table of one run, a median row last."""
    rows = []
    for r in run.weekly.itertuples(index=False):
        d = r._asdict()
        rows.append([str(int(d["week"])), str(d["start"])[:10],
                     *(_cell(d[c], digits) for c, _, digits in WEEKLY_TABLE)])
    med = run.weekly.median(numeric_only=True)
    rows.append(["median", "", *(_cell(med[c], digits) for c, _, digits in WEEKLY_TABLE)])
    return rows


def _by_ems(manifest: Manifest, runs: list[RunData]) -> tuple[dict[str, RunData], dict[tuple[str, float], RunData]]:
    base: dict[str, RunData] = {}
    variants: dict[tuple[str, float], RunData] = {}
    for run in runs:
        variants[(run.spec.ems, float(run.spec.eta_sys))] = run
        if abs(run.spec.eta_sys - manifest.base_eta) < 1e-9:
            base[run.spec.ems] = run
    order = figures.ordered(list(base))
    return {e: base[e] for e in order}, variants


def build_report(compare_dir: str | Path, out_dir: str | Path | None = None) -> Report:
    """Write ``report.md``, ``report.html``, ``figures/*.png``, ``findings.json`` from the runs.

    Parameters
    ----------
    compare_dir : directory with ``compare.json`` and ``runs/``
    out_dir : where to write the report (default: ``compare_dir``)

    Raises
    ------
    RunDirError
        If the manifest or a run directory is missing or corrupt (the message names it).
    """
    t0 = time.perf_counter()
    root = Path(compare_dir)
    out = Path(out_dir) if out_dir is not None else root
    manifest, run_list = read_comparison(root)
    out.mkdir(parents=True, exist_ok=True)
    runs, variants = _by_ems(manifest, run_list)
    if not runs:
        from .runs import RunDirError

        raise RunDirError(f"{root / 'compare.json'}: no run at the base FC efficiency {manifest.base_eta}")
    params = load_plant_params(manifest.config, {**manifest.overrides, "fuel_cell.eta_sys": manifest.base_eta})
    tz = params.site.timezone
    levels = {e: (r.spec.info_level or _level_of(e)) for e, r in runs.items()}
    figs = figures.all_figures(runs, variants, levels, out / "figures", tz, manifest.base_eta, params.dhw.v_max_l)
    ctx = Context(runs=runs, variants=variants, params=params, base_eta=manifest.base_eta)
    verdicts = evaluate_findings(ctx)
    source, prows = paper_table(runs, params.hydrogen.loh_min)
    spans = figures.window_spans(runs, tz)
    first = next(iter(runs.values()))
    t = first.timeseries["time"].dt.tz_convert(tz)

    doc = _Doc()
    doc.h(1, "ComEMS4Build comparison report")
    doc.p(f"Scenario: {manifest.scenario}; {t.iloc[0].isoformat()} to "
          f"{(t.iloc[-1] + pd.Timedelta(hours=1)).isoformat()} ({int(first.summary['weeks'])} weeks, "
          f"{int(first.summary['steps'])} hourly steps); runs {manifest.via}; EMS: "
          f"{', '.join(figures.label(e) for e in runs)}; FC system efficiencies: "
          f"{', '.join(_eta_name(eta) for eta in sorted({eta for _, eta in variants}))} (base "
          f"{_eta_name(manifest.base_eta)}). Parameter overrides: {manifest.overrides or 'none'}.")

    n_held = sum(v.status == "held" for _, v in verdicts)
    n_eval = sum(v.status != "n/a" for _, v in verdicts)
    doc.h(2, "Findings of the paper: held or not held")
    doc.p(f"{n_held} of {n_eval} evaluated findings held ({len(verdicts) - n_eval} not evaluable with these runs). "
          "Each verdict is computed from the runs by a check in comems4build_ros/report/findings.py.")
    doc.table(["#", "finding", "source", "verdict", "figures behind it"],
              [[str(i), f.claim, f.source, v.status, v.evidence] for i, (f, v) in enumerate(verdicts, start=1)])

    doc.h(2, "The paper's reported figures and the measured ones")
    doc.p(f"Paper: {source}. The measured scenario is this project's, so the numbers are expected to differ; "
          "the comparison is about orders and shapes.")
    cols = figures.ordered(list(dict.fromkeys([*runs, *(e for pr in prows for e in pr.paper)])))
    header = ["quantity", "source"]
    for e in cols:
        header += [f"{figures.label(e)} paper", f"{figures.label(e)} measured"]
    rows = []
    for pr in prows:
        row = [pr.label, pr.where]
        for e in cols:
            paper_val = pr.paper.get(e)
            row += ["-" if paper_val is None else paper_val, pr.measured.get(e, "not run")]
        rows.append(row)
    doc.table(header, rows)

    doc.h(2, "Run summary")
    doc.table(["quantity", *(figures.label(e) for e in runs)],
              [[lab, *(_cell(runs[e].summary.get(key), d) for e in runs)] for key, lab, d in SUMMARY_TABLE])

    doc.h(2, "Weekly KPIs")
    wh = ["week", "start", *(h for _, h, _ in WEEKLY_TABLE)]
    for e, run in runs.items():
        doc.h(3, f"{figures.label(e)} ({e}), FC system efficiency {_eta_name(run.spec.eta_sys)}")
        doc.table(wh, weekly_rows(run))

    doc.h(2, "Figures")
    captions = {
        "quality_indicators_occupants": "Weekly thermal discomfort, electricity cost and reimbursement "
                                        "(fig:quality_indicators_occupants).",
        "HESS_usage": "Weekly BESS charged energy and H2 consumption (fig:HESS_usage).",
        "working_hours_FC": "FC working hours and start-ups over the run (fig:working_hours_FC).",
        "hydrogen_timeseries": "LOH of every EMS with the buy price and the global radiation "
                               "(fig:hydrogen_timeseries).",
        "grid_usage": "Weekly energy bought and sold (fig:grid_usage).",
        "heat_recovery": "Weekly heat recovered from the FC at each FC system efficiency (opaque: base, "
                         "transparent: the other) against the weekly DHW demand incl. losses (fig:heat_recovery).",
        "performance_comparison": f"Three days of all EMS, cold high-price window {spans['cold'][0]} to "
                                  f"{spans['cold'][1]}: max z(mean price) - z(mean T_amb) over all 3-day windows "
                                  "(fig:performance_comparison).",
        "performance_comparison_highSolar": f"Three days of all EMS, sunny window {spans['sunny'][0]} to "
                                            f"{spans['sunny'][1]}: max mean radiation among windows not "
                                            "overlapping the first (fig:performance_comparison_highSolar).",
        "level_of_information": "Inputs each EMS may use (tab:level_of_information).",
    }
    for key, path in figs.items():
        doc.img(path, f"figures/{path.name}", captions[key])

    doc.h(2, "Inputs each EMS may use (tab:level_of_information)")
    ih, ir = figures.level_of_information_rows(levels)
    doc.table(ih, ir)

    md_path = out / "report.md"
    md_path.write_text(doc.markdown(), encoding="utf-8")
    html_path = out / "report.html"
    html_path.write_text(doc.html("ComEMS4Build comparison report"), encoding="utf-8")
    found = [{"key": f.key, "claim": f.claim, "source": f.source, "verdict": v.status, "evidence": v.evidence}
             for f, v in verdicts]
    (out / "findings.json").write_text(json.dumps(found, indent=2) + "\n", encoding="utf-8")
    pd.DataFrame([{"quantity": pr.label, **{f"{e}_paper": pr.paper.get(e) for e in runs},
                   **{f"{e}_measured": pr.measured[e] for e in runs}} for pr in prows]).to_csv(
        out / "paper_comparison.csv", index=False)
    return Report(md_path, html_path, figs, found, time.perf_counter() - t0)


def _level_of(ems: str) -> str:
    from ..ems import controller_class

    return str(controller_class(ems).info_level)
