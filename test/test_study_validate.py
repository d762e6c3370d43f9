"""The validation study's plan: its cases, the readings it can run and the runs that serve each."""

from __future__ import annotations

import json

import pytest

from comems4build_ros.core.config import ConfigError
from comems4build_ros.study import validate as sv
from comems4build_ros.study.reproduce import load_study
from comems4build_ros.study.runner import RunTask


def test_calibration_cases_first_then_the_validation_set():
    cases = sv.study_cases([57, 1, 2, 3, 4])
    assert [c.id for c in cases[:5]] == ["paper-s57", "paper-s1", "paper-s2", "paper-s3", "paper-s4"]
    assert all(c.scenario == "default" and c.subset == sv.CALIBRATION for c in cases[:5])
    assert len(cases) == 29
    assert {c.subset for c in cases[5:]} == {"development", "held-out"}
    munich = next(c for c in cases if c.id == "muenchen-2018-19")
    assert munich.scenario == "validation/muenchen-2018-19" and munich.seed is None
    assert munich.overrides["comfort.holidays_subdivision"] == "BY"
    with pytest.raises(ConfigError, match="--cases: no case atlantis"):
        sv.study_cases([57], only=["atlantis"])


def test_only_readings_of_controllers_or_the_evaluation_are_run():
    study = load_study()
    keys = {v.ambiguity for v in sv.study_variants(study, ["all"])}
    assert keys == {"fc_lifecycle_cost", "mpc_fc_heat", "fc_rules", "fc_off_term", "price_terms", "flex_pv_storage",
                    "h2_carry_over", "fc_cap_to_demand", "hp_zero", "battery_grid_charging", "rbc_thresholds",
                    "rbc_h2_reserve", "discomfort_sample"}
    with pytest.raises(ConfigError, match="building_envelope change the plant or the scenario's data"):
        sv.study_variants(study, ["building_envelope"])
    with pytest.raises(ConfigError, match="no ambiguity nonsense"):
        sv.study_variants(study, ["nonsense"])
    assert sv.study_variants(study, None) == []


def test_plan_reuses_the_base_runs_for_defaults_and_evaluation_only_readings():
    p = sv.plan(["fc_rules", "discomfort_sample"], weeks=1, cases=["paper-s57", "hamburg-2015-16"])
    fc_readings = [v for v in p.variants if v.ambiguity == "fc_rules"]
    extra = sum(not v.default for v in fc_readings)  # each non-default reading: one fuzzy run per case
    assert len(p.tasks) == 2 * 3 + 2 * extra
    assert p.runs[("paper-s57", sv.BASE)] == {e: f"paper-s57__{e}" for e in ("mpc", "fuzzy", "rbc")}
    for v in p.variants:
        runs = p.runs[("hamburg-2015-16", v.key)]
        if v.default or v.kpi_only:
            assert runs == p.runs[("hamburg-2015-16", sv.BASE)]
        else:
            assert runs["fuzzy"] == f"hamburg-2015-16__fc_rules__{v.reading}__fuzzy"
            assert runs["mpc"] == "hamburg-2015-16__mpc"
    task = p.tasks["hamburg-2015-16__rbc"]
    assert (task.scenario, task.weeks, task.overrides["site.latitude_deg"]) == ("validation/hamburg-2015-16", 1.0,
                                                                               53.6332)
    assert task.portable().inputs == {}  # built from package data by its name: nothing to carry to a worker


@pytest.mark.parametrize("forecast", ["realistic", "imperfect", "perfect"])
def test_forecast_is_part_of_the_mpc_runs_spec_only(forecast):
    """``validate --forecast``: the MPC runs carry the mode in their specification (a stored run of
    another mode is not taken for it); the fuzzy EMS and the RBC read no forecast and keep theirs."""
    base = sv.plan(None, weeks=1, cases=["paper-s57", "hamburg-2015-16"])
    p = sv.plan(None, weeks=1, cases=["paper-s57", "hamburg-2015-16"], forecast=forecast)
    assert p.forecast == forecast and base.forecast is None
    for name, task in p.tasks.items():
        other = base.tasks[name]
        if task.ems == "mpc":
            assert task.forecast == forecast and task.spec()["forecast"] == forecast
            assert task.spec() != other.spec()
        else:
            assert task.forecast is None and task.spec() == other.spec()


def test_plan_refuses_unknown_ems():
    with pytest.raises(ConfigError, match="--ems: thermostat"):
        sv.plan(None, weeks=1, cases=["paper-s57"], ems=("thermostat",))


def test_a_task_runs_from_its_name_alone(tmp_path):
    """What a Dask worker does: the pickled task, no file of the client's disk."""
    import pickle

    p = sv.plan(None, weeks=1 / 7, cases=["muenchen-2023-24"], ems=("rbc",))
    task: RunTask = pickle.loads(pickle.dumps(p.tasks["muenchen-2023-24__rbc"].portable()))
    summary = task.run(str(tmp_path / "run"))
    assert summary["steps"] == 24 and summary["scenario"] == "validation/muenchen-2023-24"
    spec = task.spec()
    assert spec["scenario"] == "validation/muenchen-2023-24"
    assert json.loads(json.dumps(spec))["overrides"]["site.altitude_m"] == 453.0


@pytest.mark.parametrize("step, subsets", [("choose", {"calibration", "development"}), ("judge", {"held-out"}),
                                           ("all", {"calibration", "development", "held-out"})])
def test_each_step_plans_only_its_subsets(step, subsets):
    p = sv.plan(["rbc_h2_reserve"], weeks=1, step=step)
    assert {c.subset for c in p.cases} == subsets and p.step == step
    held_out = {c.id for c in sv.study_cases(load_study().seeds) if c.subset == "held-out"}
    names = set(p.tasks) | {n for per in p.runs.values() for n in per.values()}
    touched = {n.split(sv.SEP)[0] for n in names}
    assert (touched & held_out) == (held_out if step != "choose" else set())


@pytest.mark.parametrize("case", ["household-102", "muenchen-2016-17", "hamburg-2023-24"])
def test_the_choosing_step_refuses_a_held_out_case(case):
    with pytest.raises(ConfigError, match="never while choosing"):
        sv.plan(None, weeks=1, cases=["paper-s57", case], step="choose")
