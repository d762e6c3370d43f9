"""Physical ranges of the plant parameters (``Phys`` in core/config.py) and values the code does not expect.

A value no building has is refused naming the parameter (exit code 2) before anything runs;
every value the ranges admit runs (finite states); every shipped configuration, the
reproduction study's readings and the sizing grids of docs/sizing.md are admitted.
"""

from __future__ import annotations

import math
import re
import shlex
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import run_cli

from comems4build_ros.core.config import ConfigError, PlantParams, config_dir, load_plant_params

REPO = Path(__file__).resolve().parents[1]

REFUSED = [
    ("building.c_air_j_per_k=1e-300", "building.c_air_j_per_k"),  # was "t_air_c is not finite"
    ("grid.price_sell_eur_per_kwh=1e300", "grid.price_sell_eur_per_kwh"),  # the MPC fell back on every step
    ("building.r_w_k_per_w=1e-30", "building.r_w_k_per_w"),
    ("dhw.t_dhw_c=500", "dhw.t_dhw_c"),
    ("fuel_cell.e_ocv_v=5", "fuel_cell.e_ocv_v"),
    ("battery.eta_ch=0.01", "battery.eta_ch"),
    ("hydrogen.e_max_kwh=1e12", "hydrogen.e_max_kwh"),
    ("heat_pump.p_el_max_w=[2200, 1e9]", "heat_pump"),
]


@pytest.mark.parametrize(("assignment", "named"), REFUSED, ids=[a for a, _ in REFUSED])
def test_a_value_no_building_has_is_refused_naming_the_parameter(assignment: str, named: str, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "mpc", "--hours", "3", "--set", assignment,
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and named in err and "not finite" not in err, err
    assert not (tmp_path / "r").exists()


def test_an_ems_that_cannot_work_with_the_plant_is_named_before_the_run(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "fuzzy", "--scenario", "year", "--weeks", "1",
                            "--set", "electrolyser.n_modules=5", "--out", tmp_path / "r"], capsys)
    assert code == 2 and "electrolyser.n_modules = 5" in err and "TypeError" not in err, err
    # size builds every EMS at every point first: no run starts, nothing is written
    code, _, err = run_cli(["size", "--ems", "rbc,fuzzy", "--el-modules", "1,5", "--weeks", "1",
                            "--out", tmp_path / "s"], capsys)
    assert code == 2 and "size point" in err and "el5" in err and "electrolyser.n_modules = 5" in err, err
    assert not (tmp_path / "s").exists()


def test_scenario_times_off_the_hour_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from comems4build_ros.core.scenario import resolve_scenario, write_scenario_csv

    good = tmp_path / "g.csv"
    write_scenario_csv(resolve_scenario("default", load_plant_params(), hours=30), good)
    text = good.read_text()
    for name, edit in (("half", (":00:00+01:00", ":30:00+01:00")), ("second", (":00:00+01:00", ":00:01+01:00")),
                       ("quarter", (":00:00+01:00", ":15:00+01:00"))):
        bad = tmp_path / f"{name}.csv"
        bad.write_text(text.replace(*edit))
        code, _, err = run_cli(["simulate", "--ems", "rbc", "--scenario", bad, "--out", tmp_path / "r"], capsys)
        assert code == 2 and f"{bad}: line 2, column 'time'" in err and "not on a whole hour" in err, err


# ---------------------------------------------------------------------------- every parameter, any value
def _numeric_fields() -> list[str]:
    out = []
    for section, field in PlantParams.model_fields.items():
        for name, f in field.annotation.model_fields.items():
            if f.annotation in (float, int):
                out.append(f"{section}.{name}")
    return out


NUMERIC = _numeric_fields()


@pytest.fixture(scope="module")
def short_scenario() -> object:
    from comems4build_ros.core.scenario import resolve_scenario

    return resolve_scenario("default", load_plant_params(), hours=30)


@settings(max_examples=120, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(name=st.sampled_from(NUMERIC), value=st.floats(allow_nan=False, allow_infinity=False, width=64)
       | st.integers(-10**12, 10**12) | st.sampled_from([0, 1e-300, 1e300, -1e-300, 1e-6, 1e6]))
def test_any_value_of_any_parameter_is_refused_naming_it_or_runs(short_scenario: object, name: str,
                                                                 value: float) -> None:
    """A value inside every range (and the cross-field rules) gives a run with finite states."""
    from comems4build_ros.core.loop import simulate

    try:
        params = load_plant_params(None, {name: value})
    except ConfigError as exc:
        assert name in str(exc) or name.split(".")[0] in str(exc), str(exc)
        return
    try:
        result = simulate("rbc", short_scenario, params)
    except (ConfigError, ValueError) as exc:  # refused by a model or the EMS, naming what it refuses
        assert "not finite" not in str(exc), f"{name}={value}: {exc}"
        return
    ts = result.timeseries
    for col in ("t_air_c", "soc", "loh", "v_dhw_l"):
        assert ts[col].map(math.isfinite).all(), f"{name}={value}: {col} not finite"


# ---------------------------------------------------------------------------- shipped configurations
def test_every_shipped_configuration_is_admitted() -> None:
    from comems4build_ros.app.commands.options import parse_values
    from comems4build_ros.study.reproduce import prepare
    from comems4build_ros.study.sizing import AXES, grid_points, plant_sizes, size_overrides

    load_plant_params()
    year = load_plant_params([config_dir() / "year.yaml"])
    assert len(prepare(True, None, None, None, None).tasks) > 0  # every reading of config/reproduce.yaml built
    doc = (REPO / "docs" / "sizing.md").read_text(encoding="utf-8").replace("\\\n", " ")
    commands = re.findall(r"comems4build size [^\n`]*", doc)
    assert commands
    for command in commands:
        argv = shlex.split(command.split("#")[0])
        values = {a.key: [plant_sizes(year)[a.key]] for a in AXES}
        for axis in AXES:
            if axis.option in argv:
                values[axis.key] = parse_values(argv[argv.index(axis.option) + 1], axis.option, axis.integer)
        for point in grid_points(values):
            overrides, _ = size_overrides(point, year)
            load_plant_params([config_dir() / "year.yaml"], overrides)
