"""``comems4build reproduce``: the paper's table beside ours, its findings, and the interpretation study.

The paper (Kovacevic et al., Applied Energy) reports weekly medians of cost, purchased and
sold energy, battery charging and the H2 left for its MPC, ComEMS4Build and RBC over twelve
winter weeks (``sec:results``). :func:`reproduce` runs the three EMS on the default
scenario (the paper's winter from measured data), puts every figure beside the paper's with
its relative error, checks the paper's qualitative findings, and, for every ambiguity of
``config/reproduce.yaml``, runs each reading on top of the defaults and reports the table's
error under it (the interpretation study, docs/calibration.md).

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
from ..kpi import DISCOMFORT_TOL_KH, HOURS_PER_WEEK
from .paper import PAPER_RESULTS_FILE, h2_empty_days_before_end, load_paper_results
from .runner import RunTask, run_tasks
from .runs import RunData, RunSpec, read_run

#: The paper's three EMS, in the order of its tables.
EMS = ("mpc", "fuzzy", "rbc")
#: Display names.
EMS_LABEL = {"mpc": "MPC", "fuzzy": "ComEMS4Build", "rbc": "RBC"}
#: Figures whose relative error is measured: (paper_results.yaml key, summary key, scale, unit).
ERROR_FIGURES: tuple[tuple[str, str, float, str], ...] = (
    ("cost", "cost_eur_week_median", 1.0, "EUR/week"),
    ("buy", "buy_kwh_week_median", 1.0, "kWh/week"),
    ("sell", "sell_kwh_week_median", 1.0, "kWh/week"),
    ("bess_charged", "bess_charged_kwh_week_median", 1.0, "kWh/week"),
    ("loh_end", "loh_end", 100.0, "%"),
)
#: RBC "empties the store early": LOH_min reached at least this many days before the end [d]
#: (paper: 16 days; the finding asks for at least a week).
EARLY_EMPTY_DAYS = 7.0
#: "Not empty at the end": LOH above LOH_min by more than this fraction of the store [-].
H2_LEFT_TOL = 0.01
#: Study file.
STUDY_FILE = "reproduce.yaml"
#: Run directory of the default runs.
BASE = "base"


# --------------------------------------------------------------------------- the study file


@dataclass(frozen=True)
class Reading:
    """One reading of an ambiguity: the settings that differ from nothing (applied on the defaults)."""

    name: str
    text: str
    overrides: dict[str, Any] = field(default_factory=dict)
    scenario_overrides: dict[str, Any] = field(default_factory=dict)
    ems_options: dict[str, dict[str, Any]] = field(default_factory=dict)


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
class Study:
    """The contents of ``config/reproduce.yaml``."""

    weeks: float
    eta_sys: float
    ambiguities: tuple[Ambiguity, ...]
    ratio_tolerance: float
    median_error_target: float
    explain_above: float
    source: str


def _need(data: Mapping[str, Any], key: str, where: str, kind: type | tuple[type, ...]) -> Any:
    if key not in data:
        raise ConfigError(f"{where}: missing '{key}'")
    value = data[key]
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise ConfigError(f"{where}: '{key}' must be {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


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
        readings = []
        for j, r in enumerate(_need(a, "readings", where, list)):
            rwhere = f"{where}, readings[{j}]"
            if not isinstance(r, dict):
                raise ConfigError(f"{rwhere}: must be a mapping")
            extra = set(r) - {"name", "text", "overrides", "scenario_overrides", "ems_options"}
            if extra:
                raise ConfigError(f"{rwhere}: unknown entries {', '.join(sorted(extra))}")
            opts = dict(r.get("ems_options") or {})
            bad = [e for e in opts if e not in ems]
            if bad:
                raise ConfigError(f"{rwhere}: ems_options for {', '.join(bad)}, not among the ambiguity's EMS")
            readings.append(Reading(
                name=_need(r, "name", rwhere, str),
                text=_need(r, "text", rwhere, str),
                overrides=dict(r.get("overrides") or {}),
                scenario_overrides=dict(r.get("scenario_overrides") or {}),
                ems_options={e: dict(v or {}) for e, v in opts.items()},
            ))
        names = [r.name for r in readings]
        if len(set(names)) != len(names) or len(names) < 2:
            raise ConfigError(f"{where}: needs at least two readings with distinct names (got {names})")
        default = _need(a, "default", where, str)
        if default not in names:
            raise ConfigError(f"{where}: default '{default}' is not one of its readings ({', '.join(names)})")
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
            readings=tuple(readings),
            kpi_only=kpi_only,
        ))
    return Study(
        weeks=float(_need(data, "weeks", str(path), (int, float))),
        eta_sys=float(_need(data, "eta_sys", str(path), (int, float))),
        ambiguities=tuple(ambiguities),
        ratio_tolerance=float(_need(data, "ratio_tolerance", str(path), (int, float))),
        median_error_target=float(_need(data, "median_error_target", str(path), (int, float))),
        explain_above=float(_need(data, "explain_above", str(path), (int, float))),
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
    holds (empty when the study file and the defaults agree).
    """
    from ..scenario import load_measured_settings, load_scenario_settings

    params = params or load_plant_params()
    sections = {"scenario": load_scenario_settings(), "measured": load_measured_settings()}
    problems = []
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


@dataclass(frozen=True)
class Case:
    """One reading evaluated: which run serves each EMS (a base run or a variant)."""

    ambiguity: str
    reading: str
    runs: dict[str, str]  # EMS -> run directory name
    overrides: dict[str, Any]  # evaluation-only overrides (kpi_only ambiguities)


def plan(study: Study, with_study: bool = True) -> tuple[dict[str, RunTask], list[Case]]:
    """Runs to make (name -> task without ``out_dir``) and the cases of the study.

    The base runs are ``base_<ems>``; a non-default reading adds a run for each EMS it
    affects (``<ambiguity>__<reading>__<ems>``); other EMS and default readings reuse the
    base run. ``kpi_only`` readings add no run.
    """
    tasks: dict[str, RunTask] = {}
    for e in EMS:
        tasks[f"{BASE}_{e}"] = RunTask(ems=e, out_dir="", weeks=study.weeks)
    cases = [Case("", BASE, {e: f"{BASE}_{e}" for e in EMS}, {})]
    if not with_study:
        return tasks, cases
    for a in study.ambiguities:
        for r in a.readings:
            runs = {e: f"{BASE}_{e}" for e in EMS}
            if r.name != a.default and not a.kpi_only:
                for e in a.ems:
                    name = f"{a.key}__{r.name}__{e}"
                    tasks[name] = RunTask(
                        ems=e, out_dir="", weeks=study.weeks, overrides=dict(r.overrides),
                        scenario_overrides=dict(r.scenario_overrides), ems_options=dict(r.ems_options.get(e, {})),
                    )
                    runs[e] = name
            cases.append(Case(a.key, r.name, runs, dict(r.overrides) if a.kpi_only else {}))
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


# --------------------------------------------------------------------------- evaluation


def paper_figures(path: str | Path = PAPER_RESULTS_FILE) -> dict[str, dict[str, float]]:
    """The paper's values of :data:`ERROR_FIGURES` per figure and EMS (floats)."""
    rows = {row["key"]: row for row in load_paper_results(path)["rows"]}
    out: dict[str, dict[str, float]] = {}
    for key, _, _, _ in ERROR_FIGURES:
        out[key] = {e: float(rows[key]["paper"][e]) for e in EMS}
    return out


def ours(run: RunData, key: str) -> float:
    """Our value of an error figure for one run (in the paper's unit)."""
    for k, summary_key, scale, _ in ERROR_FIGURES:
        if k == key:
            return float(run.summary[summary_key]) * scale
    raise KeyError(key)


def relative_error(value: float, paper: float) -> float | None:
    """``|value - paper| / |paper|``; ``None`` for a zero paper figure (no relative error)."""
    return None if paper == 0 else abs(value - paper) / abs(paper)


def table_rows(runs: Mapping[str, RunData], paper: Mapping[str, Mapping[str, float]]) -> list[dict[str, Any]]:
    """The paper's table beside ours: one row per (figure, EMS) with the relative error."""
    rows = []
    for key, _, _, unit in ERROR_FIGURES:
        for e in EMS:
            value = ours(runs[e], key)
            p = paper[key][e]
            rows.append({"figure": key, "ems": e, "unit": unit, "paper": p, "ours": value,
                         "rel_error": relative_error(value, p)})
    return rows


def median_error(rows: Sequence[Mapping[str, Any]]) -> float:
    """Median relative error over the rows with a nonzero paper figure [-]."""
    errs = [r["rel_error"] for r in rows if r["rel_error"] is not None]
    return float(statistics.median(errs))


def cost_ratios(runs: Mapping[str, RunData]) -> dict[str, float]:
    """Weekly cost medians relative to ComEMS4Build's [-]."""
    fuzzy = float(runs["fuzzy"].summary["cost_eur_week_median"])
    return {f"{e}/fuzzy": float(runs[e].summary["cost_eur_week_median"]) / fuzzy for e in ("rbc", "mpc")}


def paper_ratios(paper: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
    """The paper's cost ratios (RBC / ComEMS4Build 1.72, MPC / ComEMS4Build 0.52)."""
    c = paper["cost"]
    return {f"{e}/fuzzy": c[e] / c["fuzzy"] for e in ("rbc", "mpc")}


def _weeks_full(run: RunData) -> pd.DataFrame:
    w = run.weekly
    return w[w["hours"] >= HOURS_PER_WEEK - 1e-9] if "hours" in w else w


@dataclass(frozen=True)
class Check:
    """A qualitative finding of the paper that the reproduction must show."""

    key: str
    claim: str
    source: str
    test: Callable[[Mapping[str, RunData], PlantParams], tuple[bool, str]]


def _s(runs: Mapping[str, RunData], e: str, key: str) -> float:
    return float(runs[e].summary[key])


def _cost_order(runs, _):
    c = {e: _s(runs, e, "cost_eur_week_median") for e in EMS}
    return c["mpc"] < c["fuzzy"] < c["rbc"], ", ".join(f"{EMS_LABEL[e]} {c[e]:.2f}" for e in EMS) + " EUR/week"


def _mpc_comfort(runs, _):
    n = int(_s(runs, "mpc", "discomfort_weeks_nonzero"))
    return n == 0, f"MPC: {n} of {len(runs['mpc'].weekly)} weeks with discomfort"


def _fuzzy_comfort(runs, _):
    w = runs["fuzzy"].weekly
    free = int((w["discomfort_kh"] <= DISCOMFORT_TOL_KH).sum())
    need = math.ceil(10.0 / 12.0 * len(w))
    return free >= need, f"ComEMS4Build: {free} of {len(w)} weeks without discomfort (at least {need})"


def _rbc_discomfort(runs, _):
    r, f = _s(runs, "rbc", "discomfort_kh_week_median"), _s(runs, "fuzzy", "discomfort_kh_week_median")
    return r > f, f"median RBC {r:.2f}, ComEMS4Build {f:.2f} Kh/week"


def _rbc_sells_most(runs, _):
    s = {e: _s(runs, e, "sell_kwh_week_median") for e in EMS}
    return all(s["rbc"] > s[e] for e in EMS if e != "rbc"), ", ".join(
        f"{EMS_LABEL[e]} {s[e]:.2f}" for e in EMS) + " kWh/week"


def _rbc_charges_most(runs, _):
    b = {e: _s(runs, e, "bess_charged_kwh_week_median") for e in EMS}
    return all(b["rbc"] > b[e] for e in EMS if e != "rbc"), ", ".join(
        f"{EMS_LABEL[e]} {b[e]:.2f}" for e in EMS) + " kWh/week"


def _rbc_empty_early(runs, params):
    floor = float(runs["rbc"].summary.get("rbc_loh_floor", params.hydrogen.loh_min))
    days = h2_empty_days_before_end(runs["rbc"], floor)
    txt = "never empty" if days is None else f"empty {days:.1f} days before the end"
    return days is not None and days >= EARLY_EMPTY_DAYS, (
        f"RBC: {txt} (its LOH_min {100 * floor:.0f} %, LOH at the end "
        f"{100 * float(runs['rbc'].summary['loh_end']):.2f} %; paper: 16 days, 9.94 % left)")


def _fuzzy_h2_left(runs, params):
    end = _s(runs, "fuzzy", "loh_end")
    return end > params.hydrogen.loh_min + H2_LEFT_TOL, f"ComEMS4Build: LOH {100 * end:.2f} % at the end"


def _fuzzy_h2_even(runs, _):
    spread = {}
    for e in EMS:
        w = _weeks_full(runs[e])["h2_kwh"]
        spread[e] = float(w.max() - w.min())
    ok = all(spread["fuzzy"] < spread[e] for e in EMS if e != "fuzzy")
    return ok, "weekly H2 use (LHV) max - min: " + ", ".join(f"{EMS_LABEL[e]} {spread[e]:.1f}" for e in EMS) + " kWh"


def _fuzzy_fc_vs_mpc(runs, _):
    h = {e: _s(runs, e, "fc_working_hours") for e in ("fuzzy", "mpc")}
    load = {e: _s(runs, e, "fc_mean_load_w") for e in ("fuzzy", "mpc")}
    ok = h["fuzzy"] > h["mpc"] and load["fuzzy"] < load["mpc"]
    return ok, (f"FC hours ComEMS4Build {h['fuzzy']:.0f} vs MPC {h['mpc']:.0f} "
                f"({100 * (h['fuzzy'] / h['mpc'] - 1):+.1f} %, paper +48.44 %); mean load "
                f"{load['fuzzy']:.0f} vs {load['mpc']:.0f} W")


#: The findings of ``sec:results`` / ``sec:discussion`` the reproduction must show.
CHECKS: tuple[Check, ...] = (
    Check("cost_order", "weekly cost median: MPC < ComEMS4Build < RBC", "sec:results (12.96 < 25.02 < 43.10 EUR)",
          _cost_order),
    Check("mpc_comfort", "MPC without discomfort in every week", "sec:results", _mpc_comfort),
    Check("fuzzy_comfort", "ComEMS4Build without discomfort in at least 10 of 12 weeks", "sec:results, abstract",
          _fuzzy_comfort),
    Check("rbc_discomfort", "RBC's median discomfort above ComEMS4Build's", "sec:results (0.68 Kh)", _rbc_discomfort),
    Check("rbc_sells_most", "RBC sells the most energy", "sec:results, sec:discussion", _rbc_sells_most),
    Check("rbc_charges_most", "RBC charges the battery the most", "sec:results (HESS utilization)", _rbc_charges_most),
    Check("rbc_empty_early", "RBC's H2 store empty at least 7 days before the end",
          "sec:results (16 days before the end)", _rbc_empty_early),
    Check("fuzzy_h2_left", "ComEMS4Build's H2 store not empty at the end", "sec:results (14.14 % left)",
          _fuzzy_h2_left),
    Check("fuzzy_h2_even", "ComEMS4Build's weekly H2 use the most even (smallest weekly range)",
          "sec:results (HESS utilization)", _fuzzy_h2_even),
    Check("fuzzy_fc_vs_mpc", "ComEMS4Build runs the FC more hours than MPC, at a lower mean load",
          "sec:results (HESS utilization: FC working hours), sec:discussion", _fuzzy_fc_vs_mpc),
)


def evaluate_checks(runs: Mapping[str, RunData], params: PlantParams) -> list[dict[str, Any]]:
    """Every :data:`CHECKS` entry with ``held`` and its evidence."""
    out = []
    for c in CHECKS:
        ok, evidence = c.test(runs, params)
        out.append({"key": c.key, "claim": c.claim, "source": c.source, "held": bool(ok), "evidence": evidence})
    return out


def h2_figures(runs: Mapping[str, RunData]) -> list[dict[str, Any]]:
    """Weekly H2 use as FC electrical output and as LHV, the value of the H2 left and the net cost."""
    rows = []
    for e in EMS:
        s = runs[e].summary
        weeks = len(_weeks_full(runs[e])) or 1
        rows.append({
            "ems": e,
            "fc_kwh_week_min": s["fc_kwh_week_min"], "fc_kwh_week_max": s["fc_kwh_week_max"],
            "h2_kwh_week_min": s["h2_kwh_week_min"], "h2_kwh_week_max": s["h2_kwh_week_max"],
            "loh_end_pct": 100 * float(s["loh_end"]),
            "price_buy_mean_eur_per_kwh": s["price_buy_mean_eur_per_kwh"],
            "h2_left_value_eur": s["h2_left_value_eur"],
            "cost_net_eur_total": s["cost_net_eur_total"],
            "cost_net_eur_week": s["cost_net_eur_total"] / weeks,
        })
    return rows


def case_result(
    case: Case, runs: Mapping[str, RunData], params: PlantParams, paper: Mapping[str, Mapping[str, float]]
) -> dict[str, Any]:
    """Table error, ratios and findings of one case."""
    rows = table_rows(runs, paper)
    errs = [r["rel_error"] for r in rows if r["rel_error"] is not None]
    checks = evaluate_checks(runs, params)
    return {
        "ambiguity": case.ambiguity,
        "reading": case.reading,
        "median_rel_error": median_error(rows),
        "max_rel_error": max(errs),
        "ratios": cost_ratios(runs),
        "findings_held": sum(c["held"] for c in checks),
        "findings": len(checks),
        "not_held": [c["key"] for c in checks if not c["held"]],
        "values": {f"{r['figure']}/{r['ems']}": r["ours"] for r in rows},
        "discomfort": {e: {"median_kh": float(runs[e].summary["discomfort_kh_week_median"]),
                           "weeks": int(runs[e].summary["discomfort_weeks_nonzero"])} for e in EMS},
    }


# --------------------------------------------------------------------------- the command


@dataclass
class ReproduceResult:
    """What :func:`reproduce` wrote and its headline figures."""

    out: Path
    markdown: Path
    html: Path
    json: Path
    median_rel_error: float
    ratios: dict[str, float]
    checks: list[dict[str, Any]]
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


def reproduce(
    out_dir: str | Path,
    with_study: bool = True,
    jobs: int | None = None,
    study_path: str | Path | None = None,
    weeks: float | None = None,
    only: Sequence[str] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    show_progress: bool | None = None,
    from_runs: str | Path | None = None,
) -> ReproduceResult:
    """Run the reproduction and write ``reproduce.md``, ``reproduce.html`` and ``reproduce.json``.

    Parameters
    ----------
    out_dir : output directory (runs go to ``out_dir/runs/<name>``)
    with_study : also run the interpretation study
    jobs : parallel processes (default: CPU count)
    study_path : study file (default ``config/reproduce.yaml``)
    weeks : run length (default: the study's 12 weeks; shorter runs are for quick checks and
        do not compare with the paper's twelve weeks)
    only : ambiguity keys to study (default: all)
    progress : callback ``(done, total, name)`` after each run
    show_progress : one progress bar per run on stderr (None = when stderr is a terminal)
    from_runs : no simulation: evaluate the run directories of an earlier ``reproduce`` of
        the same study (``from_runs/runs/<name>``) again, e.g. after a change to the
        evaluation; the runs are taken as they are (they must come from the same code and
        configuration). Wall time and run count are those of the earlier command, read
        from its ``reproduce.json``.
    """
    t0 = time.perf_counter()
    study = load_study(study_path)
    if weeks is not None:
        study = dataclasses.replace(study, weeks=float(weeks))
    if only:
        unknown = sorted(set(only) - {a.key for a in study.ambiguities})
        if unknown:
            raise ConfigError(f"{study.source}: no ambiguity {', '.join(unknown)} "
                              f"(known: {', '.join(a.key for a in study.ambiguities)})")
        study = dataclasses.replace(study, ambiguities=tuple(a for a in study.ambiguities if a.key in only))
    params = load_plant_params()
    if abs(params.fuel_cell.eta_sys - study.eta_sys) > 1e-12:
        raise ConfigError(f"{study.source}: eta_sys {study.eta_sys} differs from config/plant.yaml "
                          f"fuel_cell.eta_sys {params.fuel_cell.eta_sys}")
    drift = check_defaults(study, params)
    if drift:
        raise ConfigError(f"{study.source}: default readings differ from config/: " + "; ".join(drift))
    out = Path(out_dir)
    tasks, cases = plan(study, with_study)
    check_tasks(tasks.values())
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
    data = {name: read_run(runs_dir / name, RunSpec(name=name, ems=tasks[name].ems, eta_sys=study.eta_sys))
            for name in names}
    from ..ems.rbc import loh_floor

    for name, run in data.items():
        if tasks[name].ems == "rbc":  # the RBC's store is empty at its own limit (config/rbc.yaml)
            run.summary["rbc_loh_floor"] = loh_floor(params, tasks[name].ems_options)
    paper = paper_figures()
    base_runs = {e: data[f"{BASE}_{e}"] for e in EMS}
    rows = table_rows(base_runs, paper)
    checks = evaluate_checks(base_runs, params)
    results = []
    for case in cases[1:]:
        runs = {e: data[n] for e, n in case.runs.items()}
        if case.overrides:
            p = load_plant_params(overrides=case.overrides)
            runs = {e: reevaluate(r, p) for e, r in runs.items()}
        results.append(case_result(case, runs, params, paper))
    report = {
        "scenario": base_runs["fuzzy"].summary.get("scenario"),
        "weeks": study.weeks,
        "table": rows,
        "median_rel_error": median_error(rows),
        "median_error_target": study.median_error_target,
        "explain_above": study.explain_above,
        "ratios": cost_ratios(base_runs),
        "paper_ratios": paper_ratios(paper),
        "ratio_tolerance": study.ratio_tolerance,
        "checks": checks,
        "h2": h2_figures(base_runs),
        "study": results,
        "ambiguities": [
            {"key": a.key, "title": a.title, "source": a.source, "ems": list(a.ems), "default": a.default,
             "reason": a.reason, "kpi_only": a.kpi_only,
             "readings": [{"name": r.name, "text": r.text} for r in a.readings]}
            for a in study.ambiguities
        ] if with_study else [],
        "runs_made": int(earlier.get("runs_made", 0)) if from_runs is not None else len(todo),
        "wall_s": float(earlier.get("wall_s", 0.0)) if from_runs is not None else time.perf_counter() - t0,
        "runs_from": str(from_runs) if from_runs is not None else None,
    }
    from .reproduce_doc import write_documents

    md, html_path = write_documents(report, out)
    json_path = out / "reproduce.json"
    json_path.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return ReproduceResult(out=out, markdown=md, html=html_path, json=json_path,
                           median_rel_error=report["median_rel_error"], ratios=report["ratios"], checks=checks,
                           runs_made=report["runs_made"], wall_s=report["wall_s"])
