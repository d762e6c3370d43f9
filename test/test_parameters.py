"""Node parameters as in every ROS 2 package: typed, described, ranged, read-only or live, no typo unnoticed.

The value rule (:func:`comems4build_ros.ros.parameters.coerce`) is checked with property tests
over the kinds; the nodes are created in this process (rclpy, no DDS peer needed) with
``parameter_overrides`` as the command line gives them; ``test_ros2_cli.py`` repeats the
users' cases with the real ``ros2`` tools.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from comems4build_ros.core.config import load_plant_params, scenario_config_files
from comems4build_ros.ros.parameters import (
    PARAMETERS,
    ParameterError,
    ParamSpec,
    coerce,
    plant_param_spec,
    plant_params_file_text,
)

rclpy = pytest.importorskip("rclpy")

pytestmark = pytest.mark.ros

INT = ParamSpec("int", "an integer", "steps", 0, 100)
FLOAT = ParamSpec("float", "a number", "s", 1e-9, None)
BOOL = ParamSpec("bool", "a flag")
TEXT = ParamSpec("str", "a text")
LIST = ParamSpec("str[]", "a list", split=",")


# ---------------------------------------------------------------------- the value rule
@given(st.floats(allow_nan=False, allow_infinity=False).filter(lambda x: not float(x).is_integer()))
def test_a_fraction_is_no_integer(x: float) -> None:
    with pytest.raises(ParameterError, match="expected an integer"):
        coerce(INT, x, "parameter 'n'")


@given(st.integers(min_value=-10**6, max_value=10**6))
def test_an_integer_is_kept_in_its_range_and_refused_outside(n: int) -> None:
    if 0 <= n <= 100:
        assert coerce(INT, n, "parameter 'n'") == n and type(coerce(INT, n, "p")) is int
    else:
        with pytest.raises(ParameterError, match=r"outside its range 0 \.\. 100 steps"):
            coerce(INT, n, "parameter 'n'")


@given(st.integers(min_value=1, max_value=10**9))
def test_an_integer_where_a_number_is_declared_is_that_number(n: int) -> None:
    out = coerce(FLOAT, n, "parameter 'x'")
    assert out == float(n) and type(out) is float


@given(st.one_of(st.text(), st.integers(), st.floats(allow_nan=False), st.none(), st.lists(st.booleans())))
def test_only_a_boolean_is_a_flag(value: object) -> None:
    with pytest.raises(ParameterError, match="expected true or false"):
        coerce(BOOL, value, "parameter 'f'")


@given(st.one_of(st.text(), st.booleans(), st.just(float("nan")), st.just(math.inf), st.just(-math.inf)))
def test_text_flags_and_non_finite_values_are_no_numbers(value: object) -> None:
    with pytest.raises(ParameterError, match="parameter 'x' = "):
        coerce(FLOAT, value, "parameter 'x'")


@given(st.one_of(st.integers(), st.floats(), st.booleans()))
def test_a_number_or_flag_is_no_text(value: object) -> None:
    with pytest.raises(ParameterError, match="expected text"):
        coerce(TEXT, value, "parameter 't'")


@given(st.lists(st.text(alphabet="abcxyz/_", min_size=1), max_size=5))
def test_a_string_array_may_come_as_one_comma_separated_string(items: list[str]) -> None:
    assert coerce(LIST, ",".join(items), "p") == [s.strip() for s in items if s.strip()]
    assert coerce(LIST, items, "p") == items


def test_every_node_parameter_has_a_kind_description_and_source() -> None:
    for name, spec in PARAMETERS.items():
        assert spec.kind in ("bool", "int", "float", "str", "str[]"), name
        assert spec.description and spec.source, name
        if spec.kind in ("int", "float"):
            assert spec.unit, name


@pytest.mark.parametrize("name, kind, unit", [
    ("battery.e_max_kwh", "float", "kWh"), ("pv.n_modules", "int", "-"), ("heat_pump.cop_45c", "float[]", "-"),
    ("comfort.home_hours_weekday", "int[]", "-"), ("pv.sky_model", "str", ""),
])
def test_plant_parameters_take_kind_and_unit_from_the_model(name: str, kind: str, unit: str) -> None:
    spec = plant_param_spec(name)
    assert spec is not None and spec.kind == kind and spec.unit == unit
    assert plant_param_spec("battery.no_such_key") is None


# ---------------------------------------------------------------------- the plan's parameter file
@settings(max_examples=25, deadline=None)
@given(e_max=st.floats(min_value=0.5, max_value=50.0), modules=st.integers(min_value=1, max_value=60),
       soc=st.floats(min_value=0.11, max_value=0.89), year=st.booleans())
def test_the_plan_file_gives_the_validated_parameters_back_exactly(tmp_path_factory: pytest.TempPathFactory,
                                                                   e_max: float, modules: int, soc: float,
                                                                   year: bool) -> None:
    """What the launcher validated is what every node parses: one file, the same object."""
    files = scenario_config_files("year" if year else "default")
    params = load_plant_params(files, {"battery.e_max_kwh": e_max, "pv.n_modules": modules,
                                       "simulation.soc_init": soc})
    path = tmp_path_factory.mktemp("plan") / "plant.yaml"
    path.write_text(plant_params_file_text(params), encoding="utf-8")
    assert load_plant_params([path]) == params


# ---------------------------------------------------------------------- nodes
@pytest.fixture()
def context(rclpy_context):
    return rclpy_context


def _make(kind: str, context: object, tmp_path: Path, **given: object) -> object:
    """A node of ``kind`` with ``given`` parameters (as ``-p name:=value`` gives them)."""
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.ems_node import EMSNode
    from comems4build_ros.ros.nodes.feed import Feed
    from comems4build_ros.ros.nodes.plant_sim import PlantSimNode
    from comems4build_ros.ros.nodes.recorder import Recorder

    if kind == "recorder":
        given.setdefault("bag_path", str(tmp_path / "bag"))
    if kind == "feed":
        given.setdefault("steps", 24)
    overrides = [Parameter(k, value=v) for k, v in given.items()]
    make = {"plant": PlantSimNode, "feed": Feed, "recorder": Recorder, "ems": lambda **kw: EMSNode("rbc", **kw)}
    node = make[kind](context=context, parameter_overrides=overrides)
    node.parameters.refuse_undeclared()
    return node


@pytest.mark.parametrize("kind, name, value, says", [
    # the cases
    ("feed", "weeks", 1.5, "expected an integer"),
    ("feed", "weeks", "abc", "expected an integer"),
    ("plant", "exit_when_done", "maybe", "expected true or false"),
    ("plant", "wait_for_recorder", "maybe", "expected true or false"),
    # more of the same classes
    ("feed", "lookahead_steps", 2.5, "expected an integer"),
    ("recorder", "tick_s", -0.1, "outside its range"),
    ("recorder", "stop_when_done", 1, "expected true or false"),
    ("plant", "stall_steps", "3", "expected an integer"),
    ("plant", "battery.e_max_kwh", "ten", "expected a number"),
    ("ems", "run_token", 1.0, "expected an integer"),
    ("feed", "seed", 2**40, "outside its range"),
    ("plant", "use_sim_time", "yes", "expected true or false"),
    ("feed", "weeks", 13, "the data of scenario 'default' hold 12 whole week"),
])
def test_a_value_of_the_wrong_type_or_range_is_refused_naming_the_parameter(context, tmp_path, kind, name, value,
                                                                           says) -> None:
    with pytest.raises(ValueError, match=says) as err:
        _make(kind, context, tmp_path, **{name: value})
    assert f"parameter '{name}'" in str(err.value)


@pytest.mark.parametrize("kind, typo, nearest", [
    ("plant", "step_timout_s", "step_timeout_s"),
    ("plant", "battery.e_maxx_kwh", "battery.e_max_kwh"),
    ("recorder", "bag_pth", "bag_path"),
    ("ems", "ems_option", "ems_options"),
    ("feed", "lookahead", "lookahead_steps"),
])
def test_a_typo_is_refused_naming_the_nearest_known_parameter(context, tmp_path, kind, typo, nearest) -> None:
    with pytest.raises(ValueError, match=f"parameter '{typo}': not a parameter of this node "
                                         f"\\(did you mean '{nearest}'\\?\\)"):
        _make(kind, context, tmp_path, **{typo: 1.0})


@pytest.mark.parametrize("kind", ["plant", "feed", "ems", "recorder"])
def test_every_parameter_has_a_value_to_read_and_a_static_type(context, tmp_path, kind) -> None:
    """What ``ros2 param dump`` asks: every declared parameter answers (none uninitialised, the
    empty string arrays included), with its declared type, not a dynamic one."""
    node = _make(kind, context, tmp_path)
    try:
        names = node.list_parameters([], 0).names
        values = node.get_parameters(names)
        assert len(values) == len(names) > 10
        own = [n for n in names if n not in ("use_sim_time", "start_type_description_service")]
        for name, d in zip(own, node.describe_parameters(own)):
            assert not d.dynamic_typing and d.type != 0, name
        if kind != "recorder":
            assert {"config_files", "battery.e_max_kwh", "pv.n_modules"} <= set(names)
            assert node.get_parameter("config_files").value == []
    finally:
        node.destroy_node()


def test_read_only_parameters_are_refused_and_live_ones_take_effect(context, tmp_path) -> None:
    from rclpy.parameter import Parameter

    plant = _make("plant", context, tmp_path, step_timeout_s=5.0)
    recorder = _make("recorder", context, tmp_path)
    try:
        for node, name, value in ((plant, "battery.e_max_kwh", 3.0), (plant, "wait_for_recorder", True),
                                  (plant, "publish_clock", False), (recorder, "bag_path", "/elsewhere")):
            (res,) = node.set_parameters([Parameter(name, value=value)])
            assert not res.successful and "read-only" in res.reason, (name, res.reason)
        (res,) = plant.set_parameters([Parameter("step_timeout_s", value=2)])  # an integer: the number 2.0
        assert res.successful and plant.loop.step_timeout_s == 2.0
        (res,) = plant.set_parameters([Parameter("watchdog_period_s", value=0.05)])
        assert res.successful and plant.loop._watchdog_timer.timer_period_ns == 50_000_000
        (res,) = plant.set_parameters([Parameter("stall_steps", value=1.5)])
        assert not res.successful and plant.loop.stall_steps == 0
        (res,) = plant.set_parameters([Parameter("step_timeout_s", value=float("nan"))])
        assert not res.successful and plant.loop.step_timeout_s == 2.0
        (res,) = recorder.set_parameters([Parameter("done_grace_s", value=0.5)])
        assert res.successful and recorder.done_grace_s == 0.5
        (res,) = plant.set_parameters([Parameter("use_sim_time", value=True)])  # the time source subscribes
        assert res.successful and plant.get_clock().ros_time_is_active
    finally:
        plant.destroy_node()
        recorder.destroy_node()


def test_the_time_source_may_subscribe_to_clock_under_any_namespace_and_name(context) -> None:
    """use_sim_time:=true on the command line: rclpy's time source reads /clock (absolute)."""
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.ems_node import EMSNode

    node = EMSNode("fuzzy", context=context, namespace="/house_3", cli_args=["--ros-args", "-r", "__node:=shadow"],
                   parameter_overrides=[Parameter("use_sim_time", value=True)])
    try:
        assert node.get_name() == "shadow" and node.endpoints.role == "fuzzy_ems"
        assert "/clock" in node.endpoints.declared_topics()[1]
        assert node.get_clock().ros_time_is_active
    finally:
        node.destroy_node()
