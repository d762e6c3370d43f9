"""The reproduction evaluated: every stated figure of the paper beside ours, its findings, its figures.

The paper (Kovacevic et al., Applied Energy) states its results in its abstract,
``sec:results`` and ``sec:discussion``. :func:`evaluate` reads the runs of a prepared
study (:mod:`comems4build_ros.study.reproduce`: the three EMS on the default scenario for
every seed of the modelled radiation and appliance load, and every reading of every
ambiguity), measures every statement of ``paper_results.yaml``
(:mod:`comems4build_ros.report.paper`) on each seed, and reports each figure as the median
over the seeds with its range and the seed-median relative error; it checks every
qualitative finding of :mod:`comems4build_ros.report.findings` on every seed; it draws the
paper's figures from the runs of the default seed; and for every ambiguity it reports the
same errors under each reading (the interpretation study, docs/calibration.md).

All numbers come from the runs; nothing is typed in. ``reproduce.json`` holds everything
the Markdown and HTML show.
"""

from __future__ import annotations

import dataclasses
import json
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from comems4build_ros.core.config import PlantParams, load_plant_params
from comems4build_ros.core.kpi import heat_recovered_at
from comems4build_ros.report.paper import (
    Evidence,
    Statements,
    aggregate,
    evaluate_statements,
    load_paper_results,
    paper_windows,
)
from comems4build_ros.report.runs import RunData, RunSpec, read_run
from comems4build_ros.study.reproduce import (
    BASE,
    EMS,
    Case,
    Prepared,
    Study,
    heat_stem,
    run_name,
)
from comems4build_ros.study.runner import RunTask

#: The headline figures whose values the study tables list: (statement key, short label).
TABLE_FIGURES = (
    ("cost", "cost"),
    ("buy", "bought"),
    ("sell", "sold"),
    ("bess_charged", "BESS charged"),
    ("loh_end", "LOH left"),
)


def reevaluate(run: RunData, params: PlantParams) -> RunData:
    """``run`` evaluated again with ``params`` (e.g. another discomfort sample); no simulation."""
    from comems4build_ros.core.loop import evaluate_timeseries

    ts = pd.read_csv(run.path / "timeseries.csv")
    extra = {k: run.summary[k] for k in ("ems", "scenario") if k in run.summary}
    res = evaluate_timeseries(ts, params, extra)
    ts["time"] = pd.to_datetime(ts["time"], utc=True)
    # what the evaluation does not compute (the controller's figures, e.g. the RBC's own H2
    # limit ``rbc_loh_floor`` or the solve times) stays as the run reported it
    summary = {**{k: v for k, v in run.summary.items() if k not in res.summary}, **res.summary}
    return RunData(spec=run.spec, path=run.path, summary=summary, weekly=res.weekly, timeseries=ts)


def at_efficiency(run: RunData, eta_sys: float) -> RunData:
    """``run``'s own dispatch evaluated at FC system efficiency ``eta_sys`` (sec:heat_recovery).

    Only the recovered heat changes (``eq:FC_sys_efficiency``: the same H2 flow and
    electrical efficiency, thermal efficiency ``eta_sys - eta_el``); the weekly
    ``heat_recovered_kwh`` is recomputed from the timeseries.
    """
    heat = heat_recovered_at(run.timeseries, eta_sys)
    week = (pd.RangeIndex(len(heat)) // 168) + 1
    weekly = run.weekly.copy()
    per_week = heat.groupby(week.to_numpy()).sum()
    weekly["heat_recovered_kwh"] = [float(per_week.get(int(w), 0.0)) for w in weekly["week"]]
    spec = dataclasses.replace(run.spec, eta_sys=eta_sys)
    return RunData(spec=spec, path=run.path, summary=run.summary, weekly=weekly, timeseries=run.timeseries)


def cost_ratios(runs: Mapping[str, RunData]) -> dict[str, float]:
    """Weekly cost medians relative to ComEMS4Build's [-]."""
    fuzzy = float(runs["fuzzy"].summary["cost_eur_week_median"])
    return {f"{e}/fuzzy": float(runs[e].summary["cost_eur_week_median"]) / fuzzy for e in ("rbc", "mpc")}


def paper_ratios(statements: Statements) -> dict[str, float]:
    """The paper's cost ratios (RBC / ComEMS4Build 1.72, MPC / ComEMS4Build 0.52)."""
    c = statements.get("cost").paper
    return {f"{e}/fuzzy": float(c[e]) / float(c["fuzzy"]) for e in ("rbc", "mpc")}


def fc_operation(runs: Mapping[str, RunData]) -> dict[str, float]:
    """FC working hours and toggles of ComEMS4Build and the RBC relative to the MPC's [%]."""
    out = {}
    for e in ("fuzzy", "rbc"):
        for key, name in (("fc_working_hours", "hours"), ("fc_toggles", "toggles")):
            ref = float(runs["mpc"].summary[key])
            out[f"{e}_{name}"] = float("nan") if ref == 0 else 100.0 * (float(runs[e].summary[key]) / ref - 1.0)
    return out


def _spread(values: Sequence[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "low": min(values), "high": max(values)}


def _median_or_none(values: Sequence[float]) -> float | None:
    return statistics.median(values) if values else None


@dataclass
class SeedRuns:
    """The runs of one case on one seed."""

    seed: int
    runs: dict[str, RunData]
    variants: dict[tuple[str, float], RunData]


def case_result(
    case: Case, per_seed: Sequence[SeedRuns], params: PlantParams, statements: Statements, study: Study,
) -> dict[str, Any]:
    """Every figure of one case over the seeds: errors, ratios, FC operation, findings."""
    from comems4build_ros.report.findings import Context, evaluate_findings

    figures = []
    findings: dict[str, dict[str, Any]] = {}
    ratios, fc = [], []
    for sr in per_seed:
        ev = Evidence(runs=sr.runs, params=params, base_eta=study.eta_sys, variants=sr.variants)
        figures.append(evaluate_statements(ev, statements))
        ctx = Context(runs=dict(sr.runs), variants={**{(e, study.eta_sys): r for e, r in sr.runs.items()},
                                                    **sr.variants}, params=params, base_eta=study.eta_sys)
        for f, v in evaluate_findings(ctx):
            entry = findings.setdefault(f.key, {"key": f.key, "claim": f.claim, "source": f.source,
                                                "held": 0, "evidence": {}})
            entry["held"] += v.status == "held"
            entry["evidence"][str(sr.seed)] = v.evidence
        ratios.append(cost_ratios(sr.runs))
        fc.append(fc_operation(sr.runs))
    agg = aggregate(figures)
    table_keys = {s.key for s in statements.statements if s.table}
    errs = [a.rel_error for a in agg if a.rel_error is not None]
    table_errs = [a.rel_error for a in agg if a.rel_error is not None and a.key in table_keys]
    values = {f"{a.key}/{a.ems}": a.ours for a in agg if a.key in dict(TABLE_FIGURES)}
    return {
        "ambiguity": case.ambiguity,
        "reading": case.reading,
        "figures": [dataclasses.asdict(a) for a in agg],
        "median_rel_error": _median_or_none(errs),
        "table_rel_error": _median_or_none(table_errs),
        "max_rel_error": max(errs) if errs else None,
        "ratios": {k: _spread([r[k] for r in ratios]) for k in ratios[0]},
        "fc": {k: _spread([x[k] for x in fc]) for k in fc[0]},
        "findings": list(findings.values()),
        "findings_held": sum(f["held"] >= study.targets.findings_seeds for f in findings.values()),
        "findings_total": len(findings),
        "not_held": [f["key"] for f in findings.values() if f["held"] < study.targets.findings_seeds],
        "values": values,
        "discomfort": {e: {"median_kh": statistics.median(float(sr.runs[e].summary["discomfort_kh_week_median"])
                                                          for sr in per_seed),
                           "weeks": statistics.median(int(sr.runs[e].summary["discomfort_weeks_nonzero"])
                                                      for sr in per_seed)} for e in EMS},
    }


def h2_figures(runs: Mapping[str, RunData]) -> list[dict[str, Any]]:
    """Weekly H2 use as FC electrical output and as LHV, the value of the H2 left and the net cost."""
    from comems4build_ros.report.paper import full_weeks

    rows = []
    for e in EMS:
        s = runs[e].summary
        weeks = len(full_weeks(runs[e])) or 1
        rows.append({
            "ems": e,
            "fc_kwh_week_min": s["fc_kwh_week_min"], "fc_kwh_week_max": s["fc_kwh_week_max"],
            "h2_kwh_week_min": s["h2_kwh_week_min"], "h2_kwh_week_max": s["h2_kwh_week_max"],
            "loh_end_pct": 100 * float(s["loh_end"]),
            "price_buy_mean_eur_per_kwh": s["price_buy_mean_eur_per_kwh"],
            "h2_left_value_eur": s["h2_left_value_eur"],
            "cost_net_eur_total": s["cost_net_eur_total"],
            "cost_net_eur_week": s["cost_net_eur_total"] / weeks,
            "fc_working_hours": s["fc_working_hours"], "fc_toggles": s["fc_toggles"],
            "fc_mean_load_w": s["fc_mean_load_w"], "fc_mean_eta_el": s["fc_mean_eta_el"],
        })
    return rows


def statement_info(statements: Statements) -> dict[str, dict[str, Any]]:
    """What the report prints about each statement (label, unit, source, quote, flags)."""
    return {s.key: {"label": s.label, "unit": s.unit, "where": s.where, "quote": s.quote, "table": s.table,
                    "note": s.note, "locates": s.locates, "error_on": s.error_on, "eta": s.eta}
            for s in statements.statements}


@dataclass
class ReproduceResult:
    """What :func:`evaluate` wrote and its headline figures."""

    out: Path
    markdown: Path
    html: Path
    json: Path
    median_rel_error: float | None
    table_rel_error: float | None
    ratios: dict[str, float]
    fc: dict[str, float]
    findings_held: int
    findings_total: int
    runs_made: int
    wall_s: float


def _read_runs(runs_dir: Path, names: Sequence[str], tasks: Mapping[str, RunTask], study: Study,
               params: PlantParams) -> dict[str, RunData]:
    from comems4build_ros.core.ems.rbc import loh_floor

    data = {}
    for name in names:
        task = tasks[name]
        eta = float(task.overrides.get("fuel_cell.eta_sys", study.eta_sys))
        run = read_run(runs_dir / name, RunSpec(name=name, ems=task.ems, eta_sys=eta))
        if task.ems == "rbc":  # the RBC's store is empty at its own limit (config/rbc.yaml)
            run.summary["rbc_loh_floor"] = loh_floor(params, task.ems_options)
        data[name] = run
    return data


def _seed_runs(case: Case, data: Mapping[str, RunData], study: Study) -> list[SeedRuns]:
    out = []
    for seed, names in case.runs.items():
        runs = {e: data[n] for e, n in names.items()}
        if case.overrides:
            p = load_plant_params(overrides=case.overrides)
            runs = {e: reevaluate(r, p) for e, r in runs.items()}
        if case.heat == "rerun":
            variants = {(e, study.heat_eta): data[run_name(heat_stem(e, study.heat_eta), seed)] for e in EMS}
        else:
            variants = {(e, study.heat_eta): at_efficiency(r, study.heat_eta) for e, r in runs.items()}
        out.append(SeedRuns(seed, runs, variants))
    return out


def evaluate(
    prepared: Prepared,
    runs_dir: Path,
    out: Path,
    runs_made: int,
    wall_s: float,
    runs_from: str | None = None,
    figures: bool = True,
) -> ReproduceResult:
    """Evaluate the runs of a prepared study in ``runs_dir``; write ``reproduce.md|.html|.json`` and ``figures/``.

    Parameters
    ----------
    prepared : the study and its planned runs (:func:`comems4build_ros.study.reproduce.prepare`)
    runs_dir : folder holding one run directory per planned run
    out : output directory of the documents
    runs_made, wall_s : how many runs the command made and its wall time [s] (stated in the documents)
    runs_from : the earlier ``reproduce --out`` whose runs are evaluated again (None: this command's)
    figures : draw the paper's figures from the default seed's runs
    """
    study, tasks, cases, params = prepared.study, prepared.tasks, prepared.cases, prepared.params
    statements = load_paper_results()
    data = _read_runs(runs_dir, list(tasks), tasks, study, params)
    results = [case_result(c, _seed_runs(c, data, study), params, statements, study) for c in cases]
    base = results[0]
    default_seed = study.seeds[0]
    base_runs = {e: data[run_name(f"{BASE}_{e}", default_seed)] for e in EMS}
    written = _draw_figures(cases[0], data, study, params, out) if figures else {}
    report = _report(prepared, results, base_runs, written, out, statements)
    report.update({"runs_made": runs_made, "wall_s": wall_s, "runs_from": runs_from})
    from comems4build_ros.report.reproduce_doc import write_documents

    md, html_path = write_documents(report, out)
    json_path = out / "reproduce.json"
    json_path.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return ReproduceResult(
        out=out, markdown=md, html=html_path, json=json_path, median_rel_error=base["median_rel_error"],
        table_rel_error=base["table_rel_error"], ratios={k: v["median"] for k, v in base["ratios"].items()},
        fc={k: v["median"] for k, v in base["fc"].items()}, findings_held=base["findings_held"],
        findings_total=base["findings_total"], runs_made=runs_made, wall_s=wall_s)


def _report(prepared: Prepared, results: list[dict[str, Any]], base_runs: Mapping[str, RunData],
            written: Mapping[str, Path], out: Path, statements: Statements) -> dict[str, Any]:
    """The content of ``reproduce.json`` (everything the documents show)."""
    study, params, only = prepared.study, prepared.params, prepared.only
    base = results[0]
    windows = paper_windows(base_runs["fuzzy"], params.site.timezone, statements.windows)
    local = base_runs["fuzzy"].timeseries["time"].dt.tz_convert(params.site.timezone)
    t = study.targets
    return {
        "scenario": base_runs["fuzzy"].summary.get("scenario"),
        "weeks": study.weeks,
        "seeds": list(study.seeds),
        "eta_sys": study.eta_sys,
        "heat_eta": study.heat_eta,
        "heat_mode": study.heat_mode,
        "targets": {"median_error": t.median_error, "table_error": t.table_error, "explain_above": t.explain_above,
                    "ratio_tolerance": t.ratio_tolerance, "fuzzy_fc_hours_pct": list(t.fuzzy_fc_hours),
                    "fuzzy_fc_toggles_pct": list(t.fuzzy_fc_toggles), "findings_seeds": t.findings_seeds},
        "statements": statement_info(statements),
        "source": statements.source,
        "paper_ratios": paper_ratios(statements),
        "base": base,
        "h2": h2_figures(base_runs),
        "windows": {k: [local.iloc[a].isoformat(), (local.iloc[b - 1] + pd.Timedelta(hours=1)).isoformat()]
                    for k, (a, b) in windows.items()},
        "figures": {k: str(Path(p).relative_to(out)) for k, p in written.items()},
        "study": results[1:],
        "ambiguities": [
            {"key": a.key, "title": a.title, "source": a.source, "ems": list(a.ems), "default": a.default,
             "reason": a.reason, "kpi_only": a.kpi_only,
             "readings": [{"name": r.name, "text": r.text} for r in a.readings]}
            for a in study.ambiguities if not only or a.key in only
        ] if prepared.with_study else [],
    }


def _draw_figures(case: Case, data: Mapping[str, RunData], study: Study, params: PlantParams,
                  out: Path) -> dict[str, Path]:
    """The paper's figures from the default seed's runs of ``case`` (``out/figures``)."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.report import figures as fig

    sr = _seed_runs(dataclasses.replace(case, runs={study.seeds[0]: case.runs[study.seeds[0]]}), data, study)[0]
    variants = {**{(e, study.eta_sys): r for e, r in sr.runs.items()}, **sr.variants}
    levels = {e: str(ems_entry(e).info_level) for e in sr.runs}
    inputs = fig.FigureInputs(dict(sr.runs), variants, levels, params.site.timezone, study.eta_sys,
                              params.dhw.v_max_l)
    return fig.all_figures(inputs, out / "figures")
