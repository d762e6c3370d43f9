"""Build the comparison report (``report.md``, ``report.html``, figures) from run directories.

Report generation only reads the runs written before (``runs/<name>/`` and the manifest
``compare.json``); it never simulates. The Markdown and the HTML come from the same
:class:`~comems4build_ros.report.document.Document`, so they hold the same numbers; the
HTML embeds the figures as base64 PNG (readable without any other file) and links their
vector versions in ``figures/``. ``findings.json`` and ``paper_comparison.csv`` carry the
same content for scripts.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.kpi import median_weeks
from comems4build_ros.report import figures
from comems4build_ros.report.document import Document
from comems4build_ros.report.figures import CAPTIONS
from comems4build_ros.report.findings import Context, evaluate_findings
from comems4build_ros.report.paper import Evidence, evaluate_statements, fmt, load_paper_results, printed
from comems4build_ros.report.runs import Manifest, RunData, RunDirError, read_comparison

#: Weekly table columns: (weekly.csv column, header, unit, decimals).
WEEKLY_TABLE = (
    ("discomfort_kh", "discomfort", "Kh", 2),
    ("cost_eur", "cost", "EUR", 2),
    ("reimbursement_eur", "reimb.", "EUR", 2),
    ("buy_kwh", "bought", "kWh", 2),
    ("sell_kwh", "sold", "kWh", 2),
    ("bess_charged_kwh", "BESS ch.", "kWh", 2),
    ("h2_kwh", "H2", "kWh", 2),
    ("heat_recovered_kwh", "FC heat", "kWh", 2),
    ("dhw_demand_kwh", "DHW dem.", "kWh", 2),
    ("fc_working_hours", "FC hours", "h", 0),
    ("fc_toggles", "FC starts", "-", 0),
)
#: Summary table rows: (summary.json key, label, unit, decimals; None = printed as is).
SUMMARY_TABLE = (
    ("cost_eur_week_median", "cost, weekly median", "EUR", 2),
    ("reimbursement_eur_week_median", "reimbursement, weekly median", "EUR", 2),
    ("discomfort_kh_week_median", "discomfort, weekly median", "Kh", 2),
    ("discomfort_weeks_nonzero", "weeks with discomfort", "-", 0),
    ("buy_kwh_week_median", "bought, weekly median", "kWh", 2),
    ("sell_kwh_week_median", "sold, weekly median", "kWh", 2),
    ("bess_charged_kwh_week_median", "BESS charged, weekly median", "kWh", 2),
    ("h2_kwh_week_min", "H2 use, weekly min", "kWh", 2),
    ("h2_kwh_week_max", "H2 use, weekly max", "kWh", 2),
    ("fc_working_hours", "FC working hours", "h", 0),
    ("fc_toggles", "FC toggles", "-", 0),
    ("fc_mean_load_w", "FC mean load when on", "W", 0),
    ("fc_mean_eta_el", "FC mean electrical efficiency", "-", 3),
    ("loh_end", "LOH at the end", "-", 4),
    ("h2_empty_at", "LOH_min reached at", None, None),
    ("dhw_unmet_kwh", "unmet DHW", "kWh", 2),
    ("wall_s", "run wall time", "s", 1),
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


def weekly_rows(run: RunData) -> list[list[str]]:
    """Rows of the weekly KPI table of one run, a median row last.

    The median is taken over the full weeks only (:func:`kpi.median_weeks`); a partial
    last week keeps its own row, its week number marked "(partial)".
    """
    rows = []
    for r in run.weekly.itertuples(index=False):
        d = r._asdict()
        week = str(int(d["week"]))
        if not bool(d.get("full_week", True)):
            week += " (partial)"
        rows.append([week, str(d["start"])[:10],
                     *(_cell(d[c], digits) for c, _, _, digits in WEEKLY_TABLE)])
    med = median_weeks(run.weekly).median(numeric_only=True)
    rows.append(["median", "", *(_cell(med[c], digits) for c, _, _, digits in WEEKLY_TABLE)])
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


@dataclass
class Comparison:
    """A comparison directory read back: manifest, runs by EMS, plant parameters, figure inputs."""

    manifest: Manifest
    runs: dict[str, RunData]
    variants: dict[tuple[str, float], RunData]
    params: Any
    figures: figures.FigureInputs


def read_report_inputs(compare_dir: str | Path) -> Comparison:
    """Read what the report of ``compare_dir`` is built from.

    Raises
    ------
    RunDirError
        If the manifest or a run directory is missing or corrupt, or no run is at the base
        FC efficiency (the message names it).
    """
    root = Path(compare_dir)
    manifest, run_list = read_comparison(root)
    runs, variants = _by_ems(manifest, run_list)
    if not runs:
        raise RunDirError(f"{root / 'compare.json'}: no run at the base FC efficiency {manifest.base_eta}")
    params = load_plant_params(manifest.config, {**manifest.overrides, "fuel_cell.eta_sys": manifest.base_eta})
    levels = {e: (r.spec.info_level or _level_of(e)) for e, r in runs.items()}
    inputs = figures.FigureInputs(runs, variants, levels, params.site.timezone, manifest.base_eta,
                                  params.dhw.v_max_l)
    return Comparison(manifest, runs, variants, params, inputs)


def build_report(compare_dir: str | Path, out_dir: str | Path | None = None) -> Report:
    """Write ``report.md``, ``report.html``, ``figures/*.{png,pdf,svg}``, ``findings.json`` from the runs.

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
    cmp = read_report_inputs(root)
    manifest, runs, variants, params = cmp.manifest, cmp.runs, cmp.variants, cmp.params
    out.mkdir(parents=True, exist_ok=True)
    figs = figures.all_figures(cmp.figures, out / "figures")
    ctx = Context(runs=runs, variants=variants, params=params, base_eta=manifest.base_eta)
    verdicts = evaluate_findings(ctx)
    statements = load_paper_results()
    figs_paper = evaluate_statements(Evidence(runs=runs, params=params, base_eta=manifest.base_eta,
                                              variants=variants), statements)
    paper_rows = statement_rows(figs_paper, statements)
    doc = _document(cmp, figs, verdicts, paper_rows, statements.source)
    md_path = out / "report.md"
    md_path.write_text(doc.markdown(), encoding="utf-8")
    html_path = out / "report.html"
    html_path.write_text(doc.html(), encoding="utf-8")
    found = [{"key": f.key, "claim": f.claim, "source": f.source, "verdict": v.status, "evidence": v.evidence}
             for f, v in verdicts]
    (out / "findings.json").write_text(json.dumps(found, indent=2) + "\n", encoding="utf-8")
    pd.DataFrame([dict(zip(["quantity", "unit", "source", "ems", "paper", "measured", "error"], row))
                  for row in paper_rows]).to_csv(out / "paper_comparison.csv", index=False)
    return Report(md_path, html_path, figs, found, time.perf_counter() - t0)


def _document(cmp: Comparison, figs: dict[str, Path], verdicts: list, paper_rows: list[list[str]],
              paper_source: str) -> Document:
    """The report's content: findings, the paper's figures beside ours, summaries, weekly KPIs, figures."""
    manifest, runs, variants = cmp.manifest, cmp.runs, cmp.variants
    tz = cmp.params.site.timezone
    spans = figures.window_spans(runs, tz)
    first = next(iter(runs.values()))
    t = first.timeseries["time"].dt.tz_convert(tz)
    doc = Document("ComEMS4Build comparison report")
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
          "Each verdict is computed from the runs by a check in comems4build_ros/report/findings.py; the source "
          "column names the section of the paper the finding is stated in.")
    doc.table(["#", "finding", "source", "verdict", "figures behind it"],
              [[str(i), f.claim, f.source, v.status, v.evidence] for i, (f, v) in enumerate(verdicts, start=1)])

    doc.h(2, "The paper's stated figures and the measured ones")
    doc.p(f"Paper: {paper_source}. Every quantitative statement, with our value for the EMS that were run and "
          "the relative error |ours - paper| / |paper| (for a bound or a set of weeks: whether it holds). The "
          "statements and where the paper makes them are in comems4build_ros/report/paper_results.yaml; "
          "`comems4build reproduce` evaluates them over several seeds of the modelled inputs.")
    doc.table(["quantity", "unit", "source", "EMS", "paper", "measured", "error"], paper_rows)

    doc.h(2, "Run summary")
    doc.table(["quantity", "unit", *(figures.label(e) for e in runs)],
              [[lab, unit or "", *(_cell(runs[e].summary.get(key), d) for e in runs)]
               for key, lab, unit, d in SUMMARY_TABLE])

    doc.h(2, "Weekly KPIs")
    for e, run in runs.items():
        doc.h(3, f"{figures.label(e)} ({e}), FC system efficiency {_eta_name(run.spec.eta_sys)}")
        doc.table(["week", "start", *(h for _, h, _, _ in WEEKLY_TABLE)], weekly_rows(run),
                  units=[None, None, *(u for _, _, u, _ in WEEKLY_TABLE)])

    doc.h(2, "Figures")
    doc.p("Each figure is drawn at its printed size for a two-column journal page and written as PDF and SVG "
          "(vector) and as a 300 dpi PNG in figures/; the links under each figure open them.")
    spans_text = {k: f"{a} to {b}" for k, (a, b) in spans.items()}
    for key, path in figs.items():
        doc.figure(path, "figures", CAPTIONS[key].format(**spans_text))

    doc.h(2, "Inputs each EMS may use")
    doc.p("The information level of each EMS after the paper's table of the level of information (sec:information), "
          "generated from the observation fields each level may read (comems4build_ros/core/ems/base.py).")
    ih, ir = figures.level_of_information_rows(cmp.figures.levels)
    doc.table(ih, ir)
    return doc


def statement_rows(figs: list, statements: Any) -> list[list[str]]:
    """Table rows of the paper's statements: quantity, unit, source, EMS, paper, measured, error or verdict."""
    info = {s.key: s for s in statements.statements}
    rows = []
    for f in figs:
        s = info[f.key]
        if f.ours is None:
            verdict = "not run"
        elif s.locates:
            verdict = "locates the window"
        elif f.rel_error is not None:
            verdict = f"{100 * f.rel_error:.1f} %"
        else:
            verdict = "holds" if f.held else "does not hold"
        rows.append([s.label, s.unit, s.where, "input" if f.ems == "input" else figures.label(f.ems),
                     printed(f.paper, s.unit), printed(f.ours, s.unit), verdict])
    return rows


def _level_of(ems: str) -> str:
    from comems4build_ros.core.ems import ems_entry

    return str(ems_entry(ems).info_level)
