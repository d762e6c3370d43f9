"""``comems4build reproduce``: every stated figure of the paper beside ours, its findings and the interpretation study.

The paper (Kovacevic et al., Applied Energy) states its results in its abstract,
``sec:results`` and ``sec:discussion``. :func:`reproduce` runs the three EMS on the default
scenario (the paper's winter from measured data) for every seed of the modelled radiation
and appliance load listed in ``config/reproduce.yaml``, measures every statement of
``paper_results.yaml`` (:mod:`comems4build_ros.report.paper`) on each seed, and reports
each figure as the median over the seeds with its range and the seed-median relative error;
it checks every qualitative finding of :mod:`comems4build_ros.report.findings` on every
seed; it draws the paper's figures from the runs of the default seed; and, for every
ambiguity of ``config/reproduce.yaml``, it runs each reading on top of the defaults on all
seeds and reports the same errors under it (the interpretation study, docs/calibration.md).

All numbers come from runs made by this command (in parallel processes); nothing is typed
in. ``reproduce.json`` holds everything the Markdown and HTML show.
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from ..config import ConfigError, PlantParams, config_dir, load_plant_params, read_ros_params
from ..kpi import heat_recovered_at
from .paper import (
    Evidence,
    Statements,
    aggregate,
    evaluate_statements,
    load_paper_results,
    paper_windows,
)
from .runner import RunTask, run_tasks
from .runs import RunData, RunSpec, read_run

#: The paper's three EMS, in the order of its tables.
EMS = ("mpc", "fuzzy", "rbc")
#: Display names.
EMS_LABEL = {"mpc": "MPC", "fuzzy": "ComEMS4Build", "rbc": "RBC"}
#: Study file.
STUDY_FILE = "reproduce.yaml"
#: Run directory prefix of the default runs.
BASE = "base"
#: How the runs at the second FC efficiency of sec:heat_recovery are obtained.
HEAT_MODES = ("posthoc", "rerun")
#: The headline figures whose values the study tables list: (statement key, short label).
TABLE_FIGURES = (
    ("cost", "cost"),
    ("buy", "bought"),
    ("sell", "sold"),
    ("bess_charged", "BESS charged"),
    ("loh_end", "LOH left"),
)


# --------------------------------------------------------------------------- the study file


@dataclass(frozen=True)
class Reading:
    """One reading of an ambiguity: the settings applied on top of the defaults.

    ``heat`` (only for the ambiguity of sec:heat_recovery) says how the runs at the second
    FC efficiency are obtained: ``posthoc`` evaluates the runs' own dispatch at that
    efficiency, ``rerun`` simulates every EMS again at it.
    """

    name: str
    text: str
    overrides: dict[str, Any] = field(default_factory=dict)
    scenario_overrides: dict[str, Any] = field(default_factory=dict)
    ems_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    heat: str | None = None


@dataclass(frozen=True)
class Ambiguity:
    """A place where the paper is silent or reads two ways, with its readings."""

    key: str
    title: str
    source: str
    ems: tuple[str, ...]
    default: str
    reason: str
    readings: tuple[Reading, ...]
    kpi_only: bool = False

    def reading(self, name: str) -> Reading:
        """The reading called ``name``."""
        for r in self.readings:
            if r.name == name:
                return r
        raise KeyError(name)


@dataclass(frozen=True)
class Targets:
    """What the reproduction aims at (``targets`` in ``config/reproduce.yaml``).

    Attributes
    ----------
    median_error : seed-median relative error, median over every stated figure [-]
    table_error : the same over the figures of the paper's headline table [-]
    explain_above : figures off by more than this are explained in docs/calibration.md [-]
    ratio_tolerance : cost ratios within this share of the paper's [-]
    fuzzy_fc_hours : band of ComEMS4Build's FC working hours relative to the MPC's [%]
    fuzzy_fc_toggles : band of ComEMS4Build's FC toggles relative to the MPC's [%]
    findings_seeds : a finding holds when it holds on at least this many seeds
    """

    median_error: float
    table_error: float
    explain_above: float
    ratio_tolerance: float
    fuzzy_fc_hours: tuple[float, float]
    fuzzy_fc_toggles: tuple[float, float]
    findings_seeds: int


@dataclass(frozen=True)
class Study:
    """The contents of ``config/reproduce.yaml``."""

    weeks: float
    eta_sys: float
    heat_eta: float
    seeds: tuple[int, ...]
    targets: Targets
    ambiguities: tuple[Ambiguity, ...]
    source: str

    @property
    def heat_mode(self) -> str:
        """How the runs at :attr:`heat_eta` are obtained under the default readings."""
        for a in self.ambiguities:
            r = a.reading(a.default)
            if r.heat:
                return r.heat
        return HEAT_MODES[0]


def _need(data: Mapping[str, Any], key: str, where: str, kind: type | tuple[type, ...]) -> Any:
    if key not in data:
        raise ConfigError(f"{where}: missing '{key}'")
    value = data[key]
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise ConfigError(f"{where}: '{key}' must be {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


def _band(data: Mapping[str, Any], key: str, where: str) -> tuple[float, float]:
    value = _need(data, key, where, list)
    if len(value) != 2 or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value) \
            or value[0] > value[1]:
        raise ConfigError(f"{where}: '{key}' must be [low, high] with low <= high, got {value!r}")
    return float(value[0]), float(value[1])


def _readings(a: Mapping[str, Any], ems: tuple[str, ...], where: str) -> tuple[Reading, ...]:
    readings = []
    for j, r in enumerate(_need(a, "readings", where, list)):
        rwhere = f"{where}, readings[{j}]"
        if not isinstance(r, dict):
            raise ConfigError(f"{rwhere}: must be a mapping")
        extra = set(r) - {"name", "text", "overrides", "scenario_overrides", "ems_options", "heat"}
        if extra:
            raise ConfigError(f"{rwhere}: unknown entries {', '.join(sorted(extra))}")
        opts = dict(r.get("ems_options") or {})
        bad = [e for e in opts if e not in ems]
        if bad:
            raise ConfigError(f"{rwhere}: ems_options for {', '.join(bad)}, not among the ambiguity's EMS")
        heat = r.get("heat")
        if heat is not None and heat not in HEAT_MODES:
            raise ConfigError(f"{rwhere}: 'heat' must be one of {', '.join(HEAT_MODES)}, got {heat!r}")
        readings.append(Reading(
            name=_need(r, "name", rwhere, str),
            text=_need(r, "text", rwhere, str),
            overrides=dict(r.get("overrides") or {}),
            scenario_overrides=dict(r.get("scenario_overrides") or {}),
            ems_options={e: dict(v or {}) for e, v in opts.items()},
            heat=heat,
        ))
    names = [r.name for r in readings]
    if len(set(names)) != len(names) or len(names) < 2:
        raise ConfigError(f"{where}: needs at least two readings with distinct names (got {names})")
    if any(r.heat for r in readings) and not all(r.heat for r in readings):
        raise ConfigError(f"{where}: either every reading or none gives 'heat'")
    return tuple(readings)


def load_study(path: str | Path | None = None) -> Study:
    """Read and check the study file (default ``config/reproduce.yaml``).

    Raises
    ------
    ConfigError
        Naming the file and the entry that is missing or invalid.
    """
    path = Path(path) if path is not None else config_dir() / STUDY_FILE
    data = read_ros_params(path).get("reproduce")
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: no 'reproduce' section under ros__parameters")
    ambiguities = []
    keys: set[str] = set()
    for i, a in enumerate(_need(data, "ambiguities", str(path), list)):
        where = f"{path}: ambiguities[{i}]"
        if not isinstance(a, dict):
            raise ConfigError(f"{where}: must be a mapping")
        key = _need(a, "key", where, str)
        where = f"{path}: ambiguity '{key}'"
        if key in keys:
            raise ConfigError(f"{where}: key given twice")
        keys.add(key)
        ems = tuple(_need(a, "ems", where, list))
        unknown = [e for e in ems if e not in EMS]
        if unknown or not ems:
            raise ConfigError(f"{where}: 'ems' must list some of {', '.join(EMS)} (got {ems})")
        readings = _readings(a, ems, where)
        default = _need(a, "default", where, str)
        if default not in {r.name for r in readings}:
            raise ConfigError(f"{where}: default '{default}' is not one of its readings "
                              f"({', '.join(r.name for r in readings)})")
        kpi_only = bool(a.get("kpi_only", False))
        if kpi_only and any(r.scenario_overrides or r.ems_options for r in readings):
            raise ConfigError(f"{where}: a kpi_only ambiguity may only override plant (evaluation) parameters")
        ambiguities.append(Ambiguity(
            key=key,
            title=_need(a, "title", where, str),
            source=" ".join(_need(a, "source", where, str).split()),
            ems=ems,
            default=default,
            reason=" ".join(_need(a, "reason", where, str).split()),
            readings=readings,
            kpi_only=kpi_only,
        ))
    if sum(any(r.heat for r in a.readings) for a in ambiguities) > 1:
        raise ConfigError(f"{path}: only one ambiguity may give 'heat' readings")
    seeds = _need(data, "seeds", str(path), list)
    if not seeds or len(set(seeds)) != len(seeds) or not all(
            isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**32 for s in seeds):
        raise ConfigError(f"{path}: 'seeds' must list distinct integers in 0..2^32-1, got {seeds!r}")
    t = _need(data, "targets", str(path), dict)
    where = f"{path}: targets"
    targets = Targets(
        median_error=float(_need(t, "median_error", where, (int, float))),
        table_error=float(_need(t, "table_error", where, (int, float))),
        explain_above=float(_need(t, "explain_above", where, (int, float))),
        ratio_tolerance=float(_need(t, "ratio_tolerance", where, (int, float))),
        fuzzy_fc_hours=_band(t, "fuzzy_fc_hours_pct", where),
        fuzzy_fc_toggles=_band(t, "fuzzy_fc_toggles_pct", where),
        findings_seeds=int(_need(t, "findings_seeds", where, int)),
    )
    if not 1 <= targets.findings_seeds <= len(seeds):
        raise ConfigError(f"{where}: 'findings_seeds' must lie in 1..{len(seeds)} (the number of seeds)")
    return Study(
        weeks=float(_need(data, "weeks", str(path), (int, float))),
        eta_sys=float(_need(data, "eta_sys", str(path), (int, float))),
        heat_eta=float(_need(data, "heat_eta", str(path), (int, float))),
        seeds=tuple(int(s) for s in seeds),
        targets=targets,
        ambiguities=tuple(ambiguities),
        source=str(path),
    )


def _dotted(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = obj[part] if isinstance(obj, Mapping) else getattr(obj, part)
    return obj


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def current_ems_option(ems: str, dotted: str, params: PlantParams) -> Any:
    """The value the shipped configuration gives an EMS option (``--ems-option`` key)."""
    if ems == "rbc":
        from ..ems.rbc import load_rbc_options

        return _dotted(load_rbc_options().model_dump(), dotted)
    if ems == "mpc":
        from ..ems.mpc.settings import MILPOptions, load_options

        return _dotted(load_options(MILPOptions, "mpc", None).model_dump(), dotted)
    if ems == "fuzzy":
        from ..ems.fuzzy.controller import load_flcs

        flc, _, rest = dotted.partition(".")
        return _dotted(load_flcs(params)[flc][1], rest)
    raise ValueError(f"unknown EMS '{ems}'")


def check_defaults(study: Study, params: PlantParams | None = None) -> list[str]:
    """Differences between each ambiguity's default reading and the shipped configuration.

    Returns one message per setting of a default reading that is not what ``config/``
    holds (empty when the study file and the defaults agree), and one if the first seed
    is not the default scenario's.
    """
    from ..scenario import load_measured_settings, load_scenario_settings

    params = params or load_plant_params()
    sections = {"scenario": load_scenario_settings(), "measured": load_measured_settings()}
    problems = []
    if sections["measured"].seed != study.seeds[0]:
        problems.append(f"seeds: the first seed {study.seeds[0]} is not the default scenario's "
                        f"(measured.seed {sections['measured'].seed} in config/scenario.yaml)")
    for a in study.ambiguities:
        r = a.reading(a.default)
        for key, want in r.overrides.items():
            have = _dotted(params, key)
            if not _same(have, want):
                problems.append(f"{a.key}/{r.name}: plant parameter {key} is {have!r} in config/, not {want!r}")
        for key, want in r.scenario_overrides.items():
            head, _, rest = key.partition(".")
            have = _dotted(sections[head], rest)
            if not _same(have, want):
                problems.append(f"{a.key}/{r.name}: scenario setting {key} is {have!r} in config/, not {want!r}")
        for ems, opts in r.ems_options.items():
            for key, want in opts.items():
                have = current_ems_option(ems, key, params)
                if not _same(have, want):
                    problems.append(f"{a.key}/{r.name}: {ems} option {key} is {have!r} in config/, not {want!r}")
    return problems


# --------------------------------------------------------------------------- runs


def run_name(stem: str, seed: int) -> str:
    """Directory name of the run ``stem`` on ``seed``."""
    return f"{stem}_s{seed}"


@dataclass(frozen=True)
class Case:
    """One reading evaluated: which run serves each EMS on each seed.

    Attributes
    ----------
    ambiguity, reading : names ("" and ``base`` for the defaults)
    runs : seed -> EMS -> run directory name
    overrides : evaluation-only overrides (``kpi_only`` ambiguities)
    heat : how the runs at the second FC efficiency are obtained (``posthoc`` or ``rerun``)
    """

    ambiguity: str
    reading: str
    runs: dict[int, dict[str, str]]
    overrides: dict[str, Any]
    heat: str


def _heat_stem(ems: str, heat_eta: float) -> str:
    return f"{BASE}_{ems}_eta{round(100 * heat_eta)}"


def plan(study: Study, with_study: bool = True) -> tuple[dict[str, RunTask], list[Case]]:
    """Runs to make (name -> task without ``out_dir``) and the cases of the study.

    The base runs are ``base_<ems>_s<seed>``; a non-default reading adds a run per EMS it
    affects and seed (``<ambiguity>__<reading>__<ems>_s<seed>``); other EMS and default
    readings reuse the base runs. ``kpi_only`` readings add no run; the ``rerun`` reading of
    sec:heat_recovery adds the base runs at the second FC efficiency.
    """
    tasks: dict[str, RunTask] = {}
    base_runs = {s: {e: run_name(f"{BASE}_{e}", s) for e in EMS} for s in study.seeds}

    def add_heat_runs() -> None:
        for s in study.seeds:
            for e in EMS:
                tasks[run_name(_heat_stem(e, study.heat_eta), s)] = RunTask(
                    ems=e, out_dir="", weeks=study.weeks, seed=s, overrides={"fuel_cell.eta_sys": study.heat_eta})

    for s in study.seeds:
        for e in EMS:
            tasks[base_runs[s][e]] = RunTask(ems=e, out_dir="", weeks=study.weeks, seed=s)
    if study.heat_mode == "rerun":
        add_heat_runs()
    cases = [Case("", BASE, base_runs, {}, study.heat_mode)]
    if not with_study:
        return tasks, cases
    for a in study.ambiguities:
        for r in a.readings:
            runs = {s: dict(base_runs[s]) for s in study.seeds}
            if r.heat == "rerun":
                add_heat_runs()
            if r.name != a.default and not a.kpi_only and not r.heat:
                for s in study.seeds:
                    for e in a.ems:
                        name = run_name(f"{a.key}__{r.name}__{e}", s)
                        tasks[name] = RunTask(
                            ems=e, out_dir="", weeks=study.weeks, seed=s, overrides=dict(r.overrides),
                            scenario_overrides=dict(r.scenario_overrides), ems_options=dict(r.ems_options.get(e, {})),
                        )
                        runs[s][e] = name
            cases.append(Case(a.key, r.name, runs, dict(r.overrides) if a.kpi_only else {},
                              r.heat or study.heat_mode))
    return tasks, cases


def reevaluate(run: RunData, params: PlantParams) -> RunData:
    """``run`` evaluated again with ``params`` (e.g. another discomfort sample); no simulation."""
    from ..sim import evaluate_timeseries

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


# --------------------------------------------------------------------------- evaluation


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
    from .findings import Context, evaluate_findings

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
    from .paper import full_weeks

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


# --------------------------------------------------------------------------- the command


@dataclass
class ReproduceResult:
    """What :func:`reproduce` wrote and its headline figures."""

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


def check_tasks(tasks: Iterable[RunTask]) -> None:
    """Build the plant parameters and the controller of every task, as its run will, before any run starts.

    A bad plant override or EMS option of the study file is reported at once (a
    :class:`~comems4build_ros.config.ConfigError` naming it) instead of in a worker after
    other runs have taken their time.
    """
    from ..ems import make_controller

    seen: set[str] = set()
    for task in tasks:
        key = json.dumps([task.ems, task.config, task.overrides, task.ems_options], sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            make_controller(task.ems, load_plant_params(task.config, task.overrides), task.ems_options)


def _read_runs(runs_dir: Path, names: Sequence[str], tasks: Mapping[str, RunTask], study: Study,
               params: PlantParams) -> dict[str, RunData]:
    from ..ems.rbc import loh_floor

    data = {}
    for name in names:
        task = tasks[name]
        eta = float(task.overrides.get("fuel_cell.eta_sys", study.eta_sys))
        run = read_run(runs_dir / name, RunSpec(name=name, ems=task.ems, eta_sys=eta))
        if task.ems == "rbc":  # the RBC's store is empty at its own limit (config/rbc.yaml)
            run.summary["rbc_loh_floor"] = loh_floor(params, task.ems_options)
        data[name] = run
    return data


def _runs_of(cases: Sequence[Case], study: Study) -> set[str]:
    """Names of the runs that ``cases`` read (their own and, for ``rerun``, those at the second efficiency)."""
    names = {n for c in cases for per_seed in c.runs.values() for n in per_seed.values()}
    names |= {run_name(_heat_stem(e, study.heat_eta), s) for c in cases if c.heat == "rerun"
              for s in c.runs for e in EMS}
    return names


def _seed_runs(case: Case, data: Mapping[str, RunData], study: Study) -> list[SeedRuns]:
    out = []
    for seed, names in case.runs.items():
        runs = {e: data[n] for e, n in names.items()}
        if case.overrides:
            p = load_plant_params(overrides=case.overrides)
            runs = {e: reevaluate(r, p) for e, r in runs.items()}
        if case.heat == "rerun":
            variants = {(e, study.heat_eta): data[run_name(_heat_stem(e, study.heat_eta), seed)] for e in EMS}
        else:
            variants = {(e, study.heat_eta): at_efficiency(r, study.heat_eta) for e, r in runs.items()}
        out.append(SeedRuns(seed, runs, variants))
    return out


def reproduce(
    out_dir: str | Path,
    with_study: bool = True,
    jobs: int | None = None,
    study_path: str | Path | None = None,
    weeks: float | None = None,
    only: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    show_progress: bool | None = None,
    from_runs: str | Path | None = None,
    figures: bool = True,
) -> ReproduceResult:
    """Run the reproduction and write ``reproduce.md``, ``reproduce.html``, ``reproduce.json``, ``figures/``.

    Parameters
    ----------
    out_dir : output directory (runs go to ``out_dir/runs/<name>``)
    with_study : also run the interpretation study
    jobs : parallel processes (default: CPU count)
    study_path : study file (default ``config/reproduce.yaml``)
    weeks : run length (default: the study's 12 weeks; shorter runs are for quick checks and
        do not compare with the paper's twelve weeks)
    only : ambiguity keys to study (default: all)
    seeds : seeds of the modelled inputs (default: the study's; the first should be the
        default scenario's)
    progress : callback ``(done, total, name)`` after each run
    show_progress : one progress bar per run on stderr (None = when stderr is a terminal)
    from_runs : no simulation: evaluate the run directories of an earlier ``reproduce`` of
        the same study (``from_runs/runs/<name>``) again, e.g. after a change to the
        evaluation; the runs are taken as they are (they must come from the same code and
        configuration). Wall time and run count are those of the earlier command, read
        from its ``reproduce.json``.
    figures : draw the paper's figures from the default seed's runs
    """
    t0 = time.perf_counter()
    study = load_study(study_path)
    if weeks is not None:
        study = dataclasses.replace(study, weeks=float(weeks))
    if seeds is not None:
        n = len(study.seeds)
        need = math.ceil(study.targets.findings_seeds * len(seeds) / n)  # the same share of fewer or more seeds
        study = dataclasses.replace(study, seeds=tuple(int(s) for s in seeds),
                                    targets=dataclasses.replace(study.targets, findings_seeds=need))
    if only:
        unknown = sorted(set(only) - {a.key for a in study.ambiguities})
        if unknown:
            raise ConfigError(f"{study.source}: no ambiguity {', '.join(unknown)} "
                              f"(known: {', '.join(a.key for a in study.ambiguities)})")
        # the ambiguity of sec:heat_recovery stays: its default decides how every case is evaluated
        study = dataclasses.replace(study, ambiguities=tuple(
            a for a in study.ambiguities if a.key in only or any(r.heat for r in a.readings)))
    params = load_plant_params()
    if abs(params.fuel_cell.eta_sys - study.eta_sys) > 1e-12:
        raise ConfigError(f"{study.source}: eta_sys {study.eta_sys} differs from config/plant.yaml "
                          f"fuel_cell.eta_sys {params.fuel_cell.eta_sys}")
    drift = [p for p in check_defaults(study, params) if seeds is None or not p.startswith("seeds:")]
    if drift:
        raise ConfigError(f"{study.source}: default readings differ from config/: " + "; ".join(drift))
    statements = load_paper_results()
    out = Path(out_dir)
    tasks, cases = plan(study, with_study)
    check_tasks(tasks.values())
    if only:
        cases = [cases[0], *(c for c in cases[1:] if c.ambiguity in only)]
        tasks = {n: t for n, t in tasks.items() if n in _runs_of(cases, study)}
    names = list(tasks)
    earlier: dict[str, Any] = {}
    if from_runs is not None:
        runs_dir = Path(from_runs) / "runs"
        missing = [n for n in names if not (runs_dir / n / "summary.json").is_file()]
        if missing:
            raise ConfigError(f"{runs_dir}: no run directory with a summary.json for {', '.join(missing)} "
                              f"(this study needs {len(names)} runs)")
        earlier_json = Path(from_runs) / "reproduce.json"
        if earlier_json.is_file():
            try:
                earlier = json.loads(earlier_json.read_text(encoding="utf-8"))
            except json.JSONDecodeError as exc:
                raise ConfigError(f"{earlier_json}: {exc}") from None
        todo: list[RunTask] = []
    else:
        runs_dir = out / "runs"
        runs_dir.mkdir(parents=True, exist_ok=True)
        todo = []
        for name in names:
            task = tasks[name]
            task.out_dir = str(runs_dir / name)
            todo.append(task)
    out.mkdir(parents=True, exist_ok=True)
    done = [0]

    def on_done(task: RunTask, _: dict[str, Any]) -> None:
        done[0] += 1
        if progress:
            progress(done[0], len(todo), Path(task.out_dir).name)

    if todo:
        run_tasks(todo, jobs=jobs, on_done=on_done, progress=show_progress)
    data = _read_runs(runs_dir, names, tasks, study, params)
    results = [case_result(c, _seed_runs(c, data, study), params, statements, study) for c in cases]
    base = results[0]
    default_seed = study.seeds[0]
    base_runs = {e: data[run_name(f"{BASE}_{e}", default_seed)] for e in EMS}
    written = _draw_figures(cases[0], data, study, params, out) if figures else {}
    windows = paper_windows(base_runs["fuzzy"], params.site.timezone, statements.windows)
    local = base_runs["fuzzy"].timeseries["time"].dt.tz_convert(params.site.timezone)
    t = study.targets
    report = {
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
        ] if with_study else [],
        "runs_made": int(earlier.get("runs_made", 0)) if from_runs is not None else len(todo),
        "wall_s": float(earlier.get("wall_s", 0.0)) if from_runs is not None else time.perf_counter() - t0,
        "runs_from": str(from_runs) if from_runs is not None else None,
    }
    from .reproduce_doc import write_documents

    md, html_path = write_documents(report, out)
    json_path = out / "reproduce.json"
    json_path.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return ReproduceResult(
        out=out, markdown=md, html=html_path, json=json_path, median_rel_error=base["median_rel_error"],
        table_rel_error=base["table_rel_error"], ratios={k: v["median"] for k, v in base["ratios"].items()},
        fc={k: v["median"] for k, v in base["fc"].items()}, findings_held=base["findings_held"],
        findings_total=base["findings_total"], runs_made=report["runs_made"], wall_s=report["wall_s"])


def _draw_figures(case: Case, data: Mapping[str, RunData], study: Study, params: PlantParams,
                  out: Path) -> dict[str, Path]:
    """The paper's figures from the default seed's runs of ``case`` (``out/figures``)."""
    from ..ems import controller_class
    from . import figures as fig

    sr = _seed_runs(dataclasses.replace(case, runs={study.seeds[0]: case.runs[study.seeds[0]]}), data, study)[0]
    variants = {**{(e, study.eta_sys): r for e, r in sr.runs.items()}, **sr.variants}
    levels = {e: str(controller_class(e).info_level) for e in sr.runs}
    inputs = fig.FigureInputs(dict(sr.runs), variants, levels, params.site.timezone, study.eta_sys,
                              params.dhw.v_max_l)
    return fig.all_figures(inputs, out / "figures")
