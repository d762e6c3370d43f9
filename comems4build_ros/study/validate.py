"""The validation study's runs: the three EMS on the calibration set and on the validation set.

The calibration set is the paper's winter (the default scenario) on the seeds of
``config/reproduce.yaml``, on which the defaults were chosen; the validation set is
``config/validation.yaml`` (:mod:`comems4build_ros.core.scenario.validation`): other winters
at two other stations and other households, split into a development and a held-out subset.
:func:`plan` turns the cases, and optionally the readings of the reproduction's ambiguities
(``config/reproduce.yaml``), into runs; :func:`~comems4build_ros.study.runner.run_into` runs them on local workers or a
Dask cluster (:func:`comems4build_ros.study.runner.run_tasks`). What the runs show is
:mod:`comems4build_ros.report.validation`.

A reading is run on every case when it changes only controller options (the fuzzy EMS,
the RBC or the MPC) or only the evaluation (``kpi_only``). Readings that change the plant
or the scenario's data (the building envelope, the appliance load, the tariff, the
temperature fill of the paper's winter) describe the calibration scenario, not the EMS,
and are left to ``reproduce``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.core.config import ConfigError
from comems4build_ros.study.reproduce import EMS, Study, check_tasks, load_study
from comems4build_ros.study.runner import RunTask

#: The subset of the cases the defaults were chosen on.
CALIBRATION = "calibration"
#: The subset that may be looked at while choosing, and the one that is only reported.
DEVELOPMENT, HELD_OUT = "development", "held-out"
#: Subsets in the order of every table.
SUBSETS = (CALIBRATION, DEVELOPMENT, HELD_OUT)
#: The steps of the validation and the subsets each runs: ``choose`` reads only the cases the
#: defaults may be chosen on, ``judge`` only the held-out cases, ``all`` both in one command.
STEPS: dict[str, tuple[str, ...]] = {"choose": (CALIBRATION, DEVELOPMENT), "judge": (HELD_OUT,), "all": SUBSETS}
#: Separator of the parts of a run name.
SEP = "__"
#: Name of the default readings (every ambiguity at its default).
BASE = "base"


@dataclass(frozen=True)
class StudyCase:
    """One case of the study: a scenario, the plant overrides it needs, and its subset.

    Attributes
    ----------
    id : case name (``paper-s57``, ``muenchen-2015-16``, ``household-101``)
    subset : ``calibration``, ``development`` or ``held-out``
    kind : ``calibration``, ``winter`` or ``household``
    scenario : scenario name (``default`` or ``validation/<id>``)
    seed : seed of the default scenario's modelled inputs (calibration cases; None otherwise)
    overrides : plant parameters the case needs (a winter case's site and holidays)
    """

    id: str
    subset: str
    kind: str
    scenario: str
    seed: int | None = None
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Variant:
    """A reading of an ambiguity of ``config/reproduce.yaml`` run on every case.

    ``ems_options`` per EMS; ``overrides`` are evaluation-only plant parameters
    (``kpi_only``); ``default`` marks the reading the shipped configuration uses.
    """

    ambiguity: str
    reading: str
    text: str
    ems: tuple[str, ...]
    default: bool
    ems_options: dict[str, dict[str, Any]] = field(default_factory=dict)
    overrides: dict[str, Any] = field(default_factory=dict)
    kpi_only: bool = False

    @property
    def key(self) -> str:
        """``<ambiguity>__<reading>``."""
        return f"{self.ambiguity}{SEP}{self.reading}"


def study_cases(seeds: Sequence[int], settings: Any = None, only: Sequence[str] | None = None,
                step: str = "all") -> list[StudyCase]:
    """The calibration cases (the default scenario on ``seeds``) and the validation cases of a step.

    Parameters
    ----------
    seeds : seeds of the default scenario's modelled radiation and load (calibration set)
    settings : ``config/validation.yaml`` (default: read)
    only : case ids to keep (None: all of the step)
    step : ``choose`` (calibration and development cases), ``judge`` (held-out cases) or ``all``

    Raises
    ------
    ConfigError
        For an id in ``only`` that is no case, naming the known ones, or a case of a subset the
        step does not run (a held-out case in the choosing step).
    """
    from comems4build_ros.core.scenario.validation import load_validation_settings, validation_cases

    s = settings or load_validation_settings()
    cases = [StudyCase(f"paper-s{seed}", CALIBRATION, CALIBRATION, "default", int(seed)) for seed in seeds]
    cases += [StudyCase(c.id, c.subset, c.kind, c.scenario, None, c.plant_overrides(s)) for c in validation_cases(s)]
    if step not in STEPS:
        raise ConfigError(f"no validation step '{step}' (known: {', '.join(STEPS)})")
    if only is not None:
        known = {c.id: c for c in cases}
        unknown = [c for c in only if c not in known]
        if unknown:
            raise ConfigError(f"--cases: no case {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        other = [c for c in only if known[c].subset not in STEPS[step]]
        if other:
            raise ConfigError(f"--cases: {', '.join(other)} {'is' if len(other) == 1 else 'are'} not read by the "
                              f"{step} step, which runs only the {' and '.join(STEPS[step])} cases"
                              + (" (held-out cases are run by validate --judge, never while choosing)"
                                 if step == "choose" else ""))
        cases = [c for c in cases if c.id in set(only)]
    return [c for c in cases if c.subset in STEPS[step]]


def eligible(ambiguity: Any) -> bool:
    """A reproduction ambiguity the validation can run: controller options or the evaluation only."""
    if any(r.heat for r in ambiguity.readings):
        return False
    if ambiguity.kpi_only:
        return True
    return all(not r.overrides and not r.scenario_overrides for r in ambiguity.readings)


def study_variants(study: Study, keys: Sequence[str] | None) -> list[Variant]:
    """The readings of the ambiguities ``keys`` (``["all"]``: every eligible one; None or empty: none).

    Raises
    ------
    ConfigError
        For an unknown key or one the validation cannot run (it changes the plant or the data).
    """
    if not keys:
        return []
    by_key = {a.key: a for a in study.ambiguities}
    if list(keys) == ["all"]:
        chosen = [a for a in study.ambiguities if eligible(a)]
    else:
        unknown = [k for k in keys if k not in by_key]
        if unknown:
            raise ConfigError(f"--study: no ambiguity {', '.join(unknown)} in {study.source} "
                              f"(known: {', '.join(by_key)})")
        bad = [k for k in keys if not eligible(by_key[k])]
        if bad:
            raise ConfigError(f"--study: {', '.join(bad)} change the plant or the scenario's data, which the "
                              "validation cases define; only reproduce studies them")
        chosen = [by_key[k] for k in keys]
    out = []
    for a in chosen:
        for r in a.readings:
            out.append(Variant(a.key, r.name, r.text, tuple(a.ems), r.name == a.default,
                               {e: dict(v) for e, v in r.ems_options.items()},
                               dict(r.overrides) if a.kpi_only else {}, a.kpi_only))
    return out


def run_name(case: StudyCase, ems: str, variant: Variant | None = None) -> str:
    """``<case>__<ems>`` for the defaults, ``<case>__<ambiguity>__<reading>__<ems>`` for a reading."""
    return SEP.join([case.id, *([variant.ambiguity, variant.reading] if variant else []), ems])


@dataclass
class Plan:
    """The study's runs and which run serves each case, reading and EMS.

    Attributes
    ----------
    cases : the cases
    variants : the readings studied (empty: the defaults only)
    tasks : run name -> task (``out_dir`` filled by :func:`~comems4build_ros.study.runner.run_into`)
    runs : (case id, variant key or :data:`BASE`) -> EMS -> run name
    weeks : run length [weeks]
    ems : the EMS run
    study : the reproduction study file (seeds, targets, ambiguities)
    step : the step planned (:data:`STEPS`)
    forecast : the MPC's forecasts (``--forecast``; None = ``config/forecast.yaml``)
    """

    cases: list[StudyCase]
    variants: list[Variant]
    tasks: dict[str, RunTask]
    runs: dict[tuple[str, str], dict[str, str]]
    weeks: float
    ems: tuple[str, ...]
    study: Study
    step: str = "all"
    forecast: str | None = None


def plan(
    study_keys: Sequence[str] | None = None,
    weeks: float | None = None,
    cases: Sequence[str] | None = None,
    ems: Sequence[str] = EMS,
    seeds: Sequence[int] | None = None,
    study_path: str | Path | None = None,
    validation_path: str | Path | None = None,
    step: str = "all",
    forecast: str | None = None,
) -> Plan:
    """Plan the study: every case with every EMS at the defaults, and each reading of ``study_keys`` on top.

    Parameters
    ----------
    study_keys : ambiguities of ``config/reproduce.yaml`` to study (``["all"]``: every eligible one)
    weeks : run length [weeks] (default ``config/validation.yaml``'s 12; shorter runs are checks)
    cases : case ids to run (default: all)
    ems : the EMS to run (default the paper's three)
    seeds : seeds of the calibration cases (default: the reproduction's)
    study_path, validation_path : the study files (default ``config/``)
    step : which subsets to run (:data:`STEPS`): ``choose`` never plans a held-out case, ``judge``
        plans only those
    forecast : the MPC's forecasts (``perfect``, ``imperfect``, ``realistic``; None = ``config/forecast.yaml``),
        part of the MPC runs' specification (the other EMS read no forecast)

    Raises
    ------
    ConfigError
        For an unknown case, EMS or ambiguity, a default reading that is not what
        ``config/`` holds, or an option that does not build.
    """
    from comems4build_ros.core.ems import ems_table
    from comems4build_ros.core.scenario.validation import load_validation_settings
    from comems4build_ros.study.reproduce import check_defaults

    study = load_study(study_path)
    drift = [p for p in check_defaults(study) if not p.startswith("seeds:")]
    if drift:
        raise ConfigError(f"{study.source}: default readings differ from config/: " + "; ".join(drift))
    bad = [e for e in ems if e not in EMS]
    if bad or not ems:
        raise ConfigError(f"--ems: {', '.join(bad) or 'none'}: the validation runs some of {', '.join(EMS)}")
    vs = load_validation_settings(validation_path)
    n_weeks = float(vs.weeks if weeks is None else weeks)
    the_cases = study_cases(study.seeds if seeds is None else seeds, vs, cases, step)
    variants = study_variants(study, study_keys)

    def forecast_of(e: str) -> str | None:
        entry = ems_table().get(e)
        return forecast if entry is not None and entry.info_level == "mpc" else None

    tasks: dict[str, RunTask] = {}
    runs: dict[tuple[str, str], dict[str, str]] = {}
    for c in the_cases:
        base = {}
        for e in ems:
            name = run_name(c, e)
            tasks[name] = RunTask(ems=e, out_dir="", scenario=c.scenario, weeks=n_weeks, seed=c.seed,
                                  overrides=dict(c.overrides), forecast=forecast_of(e))
            base[e] = name
        runs[(c.id, BASE)] = base
        for v in variants:
            per = dict(base)
            if not v.default and not v.kpi_only:
                for e in v.ems:
                    if e not in ems:
                        continue
                    name = run_name(c, e, v)
                    tasks[name] = RunTask(ems=e, out_dir="", scenario=c.scenario, weeks=n_weeks, seed=c.seed,
                                          overrides=dict(c.overrides), ems_options=dict(v.ems_options.get(e, {})),
                                          forecast=forecast_of(e))
                    per[e] = name
            runs[(c.id, v.key)] = per
    check_tasks(tasks.values())
    return Plan(the_cases, variants, tasks, runs, n_weeks, tuple(ems), study, step, forecast)
