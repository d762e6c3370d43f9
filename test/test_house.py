"""``comems4build house``: the EnergyPlus house beside the 4R3C, each line within its tolerance (a short window)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.app.commands.house import table_text
from comems4build_ros.core.models import house_idf as house
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.study import house as study

pytest.importorskip("pyenergyplus")


@pytest.fixture(scope="module")
def figures(params):
    """Two winter weeks and four-day steady states (the command runs twelve weeks, twelve days and the year)."""
    return study.house_figures(params, weeks=2.0, year=False, steady_days=4)


def _line(figures, start: str) -> dict:
    return next(line for line in figures["lines"] if line["name"].startswith(start))


@pytest.mark.parametrize(("start", "tol"), [
    ("heat loss coefficient", study.H_TOLERANCE),
    ("effective heat capacity", study.CAPACITY_TOLERANCE),
    ("solar aperture of the windows", study.APERTURE_TOLERANCE),
    ("heat demand", study.DEMAND_TOLERANCE),
])
def test_each_relative_line_is_judged_by_its_tolerance(figures, start, tol):
    line = _line(figures, start)
    assert line["energyplus"] > 0 and line["rc"] > 0
    assert line["pass"] == (abs(line["energyplus"] / line["rc"] - 1.0) <= tol)


@pytest.mark.parametrize("start", ["heat loss coefficient", "internal gains", "effective heat capacity"])
def test_the_two_models_are_one_house_in_these_lines(figures, start):
    """Heat loss, gains and effective mass within their tolerances (these do not depend on the window)."""
    assert _line(figures, start)["pass"] is True


@pytest.mark.slow
def test_heat_demand_of_the_paper_weeks_within_ten_percent(params):
    """The twelve weeks the criterion is stated for (single weeks differ by up to about 20 %: the house's ground
    loss weighs more in mild weeks, its larger sun in sunny ones)."""
    scenario = resolve_scenario("default", params)
    ep, rc = (study.controlled_run(params, b, scenario) for b in (None, "rc"))
    assert abs(ep.q_w.sum() / rc.q_w.sum() - 1.0) <= study.DEMAND_TOLERANCE
    assert ep.t_air_c.mean() == pytest.approx(rc.t_air_c.mean(), abs=0.5)


def test_neither_model_has_internal_gains_and_energyplus_got_the_heat_it_was_given(figures):
    gains = _line(figures, "internal gains")
    assert gains["energyplus"] == pytest.approx(0.0, abs=1e-9) and gains["rc"] == 0.0
    assert figures["heat_balance_max_rel"] <= 1e-6
    assert figures["winter_t_air_mean_c"]["energyplus"] == pytest.approx(figures["winter_t_air_mean_c"]["rc"], abs=0.5)


def test_the_sun_saves_heat_in_both_and_the_windows_are_part_of_it(figures):
    for key in ("energyplus", "rc"):
        heat = figures["winter_heat_kwh"][key]
        assert heat["dark"] > heat["windows"] > heat["sun"]


def test_the_table_prints_every_line_and_its_result(figures):
    text = table_text(figures)
    for line in figures["lines"]:
        row = next(r for r in text.splitlines() if r.startswith(line["name"]))
        assert row.endswith({True: "pass", False: "FAIL", None: "-"}[line["pass"]])
    failed = [line for line in figures["lines"] if line["pass"] is False]
    assert (f"{len(failed)} line(s) outside their tolerance" in text) == bool(failed)


def test_summer_protection_and_window_ventilation_cool_the_house_in_a_heat_wave(params, tmp_path):
    """July 2022's hottest week: the shipped house against the same house without either measure."""
    scenario = resolve_scenario("year", params, start="2022-07-14T01:00:00", hours=7 * 24)
    bare = dataclasses.replace(house.HouseSpec(), sun_protection_w_m2=1e6, sun_protection_north_w_m2=1e6,
                               window_ach_day=0.0, window_ach_night=0.0)
    protected = study.controlled_run(params, None, scenario)
    unprotected = study.controlled_run(params, house.write_idf(tmp_path / "bare.idf", bare), scenario)
    assert protected.solar_w.sum() < 0.8 * unprotected.solar_w.sum()
    assert protected.t_air_c.max() < unprotected.t_air_c.max() - 1.0
    assert (protected.t_air_c > study.HOT_C).sum() < (unprotected.t_air_c > study.HOT_C).sum()


@pytest.mark.parametrize(("t_air", "hours", "kh"), [(28.0, 8760, 8760.0), (26.5, 8760, 0.0), (20.0, 0, 0.0)])
def test_summer_figures_count_hours_and_din_degree_hours(t_air, hours, kh):
    time = pd.date_range("2022-03-01", periods=8760, freq="h", tz="Europe/Berlin")
    t = np.full(8760, t_air)
    run = study.ControlledRun(time, np.zeros(8760), t, t, np.zeros(8760), np.zeros(8760), np.zeros(8760),
                              np.zeros(8760))
    f = study.summer_figures(run)
    assert f["hours_above_26"] == hours and f["kh_above_reference"] == pytest.approx(kh)
