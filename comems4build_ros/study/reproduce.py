"""The reproduction study of the paper: its file, its runs and the cases they serve.

``config/reproduce.yaml`` lists the seeds of the modelled radiation and appliance load, the
targets, and every place where the paper is silent or reads two ways (an *ambiguity*) with
its readings. :func:`prepare` reads and checks it; :func:`plan` turns it into the runs to
make (the three EMS on every seed under the default readings, and each other reading on
top of them) and the cases that read them; :func:`~comems4build_ros.study.runner.run_into` runs them. What the runs show
beside the paper is :mod:`comems4build_ros.report.reproduce` (the evaluation) and
``comems4build reproduce`` joins the two.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams, config_dir, load_plant_params, read_param_section
from comems4build_ros.study.runner import RunTask

#: The paper's three EMS, in the order of its tables.
EMS = ("mpc", "fuzzy", "rbc")




#: Study file.
STUDY_FILE = "reproduce.yaml"


#: Run directory prefix of the default runs.
BASE = "base"


#: How the runs at the second FC efficiency of sec:heat_recovery are obtained.
HEAT_MODES = ("posthoc", "rerun")


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
    data = read_param_section(path, "reproduce")
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
        from comems4build_ros.core.ems.rbc import load_rbc_options

        return _dotted(load_rbc_options().model_dump(), dotted)
    if ems == "mpc":
        from comems4build_ros.core.ems.mpc.settings import MILPParams, load_options

        return _dotted(load_options(MILPParams, "mpc", None).model_dump(), dotted)
    if ems == "fuzzy":
        from comems4build_ros.core.ems.fuzzy.controller import load_flcs

        flc, _, rest = dotted.partition(".")
        return _dotted(load_flcs(params)[flc][1], rest)
    raise ConfigError(f"unknown EMS '{ems}'")


def check_defaults(study: Study, params: PlantParams | None = None) -> list[str]:
    """Differences between each ambiguity's default reading and the shipped configuration.

    Returns one message per setting of a default reading that is not what ``config/``
    holds (empty when the study file and the defaults agree), and one if the first seed
    is not the default scenario's.
    """
    from comems4build_ros.core.scenario import load_measured_settings, load_scenario_settings

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


def heat_stem(ems: str, heat_eta: float) -> str:
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
                tasks[run_name(heat_stem(e, study.heat_eta), s)] = RunTask(
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


def check_tasks(tasks: Iterable[RunTask]) -> None:
    """Build the plant parameters and the controller of every task, as its run will, before any run starts.

    A bad plant override or EMS option of the study file is reported at once (a
    :class:`~comems4build_ros.core.config.ConfigError` naming it) instead of in a worker after
    other runs have taken their time.
    """
    from comems4build_ros.core.ems import make_controller

    seen: set[str] = set()
    for task in tasks:
        key = json.dumps([task.ems, task.config, task.overrides, task.ems_options], sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            make_controller(task.ems, load_plant_params(task.config, task.overrides), task.ems_options)


def runs_of(cases: Sequence[Case], study: Study) -> set[str]:
    """Names of the runs that ``cases`` read (their own and, for ``rerun``, those at the second efficiency)."""
    names = {n for c in cases for per_seed in c.runs.values() for n in per_seed.values()}
    names |= {run_name(heat_stem(e, study.heat_eta), s) for c in cases if c.heat == "rerun"
              for s in c.runs for e in EMS}
    return names



@dataclass
class Prepared:
    """A study checked against ``config/`` and planned: its runs and cases."""

    study: Study
    tasks: dict[str, RunTask]
    cases: list[Case]
    params: PlantParams
    with_study: bool
    only: tuple[str, ...]


def prepare(
    with_study: bool = True,
    study_path: str | Path | None = None,
    weeks: float | None = None,
    only: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
) -> Prepared:
    """Read the study file, apply the command's choices, check it against ``config/`` and plan it.

    Parameters
    ----------
    with_study : also plan the interpretation study (every reading of every ambiguity)
    study_path : study file (default ``config/reproduce.yaml``)
    weeks : run length [weeks] (default: the study's 12; shorter runs are for quick checks
        and do not compare with the paper's twelve weeks)
    only : ambiguity keys to study (default: all)
    seeds : seeds of the modelled inputs (default: the study's; the first should be the
        default scenario's)

    Raises
    ------
    ConfigError
        For an unknown ambiguity, a default reading that is not what ``config/`` holds, or a
        plant override or EMS option that does not build.
    """
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
    tasks, cases = plan(study, with_study)
    check_tasks(tasks.values())
    if only:
        cases = [cases[0], *(c for c in cases[1:] if c.ambiguity in only)]
        tasks = {n: t for n, t in tasks.items() if n in runs_of(cases, study)}
    return Prepared(study, tasks, cases, params, with_study, tuple(only or ()))
