"""In-process tests of the node helpers: contract enforcement, command checks, parameters.

These create rclpy nodes in the test process (no DDS peers needed); the closed-loop and
fault tests with real processes are in test_ros_nodes.py.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from waits import BUDGET_S

rclpy = pytest.importorskip("rclpy")

from comems4build_ros.core.config import ConfigError, load_plant_params, scenario_config_files  # noqa: E402
from comems4build_ros.core.types import HP_DHW  # noqa: E402
from comems4build_ros.ros.node import ArrayPublisher, ContractEndpoints, layout_sizes  # noqa: E402
from comems4build_ros.wire.contract import ContractError, load_contract  # noqa: E402
from comems4build_ros.wire.ems_command import CommandError, command_bounds, command_to_action  # noqa: E402

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[1]



@pytest.fixture()
def context(rclpy_context):
    return rclpy_context


def _node(role: str, context: object, **kwargs: object) -> tuple[object, ContractEndpoints]:
    """A node named ``role`` and its contract endpoints (as a node of the package composes them)."""
    from rclpy.node import Node

    from comems4build_ros.ros.package_node import node_options

    node = Node(role, context=context, **node_options(kwargs))
    try:
        return node, ContractEndpoints(node, role)
    except Exception:
        node.destroy_node()
        raise



def test_undeclared_publisher_and_subscription_are_refused(context):
    from std_msgs.msg import Float64MultiArray

    node, ep = _node("fuzzy_ems", context)
    try:
        ep.publisher("ems/command")  # declared
        with pytest.raises(ContractError, match="'fuzzy_ems' may not publish 'state/soc'"):
            ep.create_publisher(Float64MultiArray, "state/soc", 10)
        with pytest.raises(ContractError, match="'fuzzy_ems' may not subscribe to 'forecast/p_load_w'"):
            ep.subscription("forecast/p_load_w", lambda msg: None)
        with pytest.raises(ContractError, match="may not subscribe to 'feed/t_amb'"):
            ep.create_subscription(Float64MultiArray, "feed/t_amb", lambda msg: None, 10)
        with pytest.raises(ContractError, match="'no/such' is not in the contract"):
            ep.publisher("no/such")
        pubs, subs = ep.declared_topics()
        assert pubs == {"ems/command"} and subs == set()
    finally:
        node.destroy_node()


def test_enforcement_under_a_namespace(context):
    from std_msgs.msg import Float64MultiArray

    node, ep = _node("rbc_ems", context, namespace="/house_2")
    try:
        ep.subscription("state/soc", lambda msg: None)
        assert node.resolve_topic_name("state/soc") == "/house_2/state/soc"
        with pytest.raises(ContractError, match="outside its namespace"):
            ep.create_publisher(Float64MultiArray, "/ems/command", 10)
        with pytest.raises(ContractError, match="'rbc_ems' may not subscribe to 'feed/solar'"):
            ep.subscription("feed/solar", lambda msg: None)
        assert ep.declared_topics() == (set(), {"state/soc"})
    finally:
        node.destroy_node()


def test_unknown_node_name_is_refused(context):
    with pytest.raises(ContractError, match="node 'intruder' is not in the contract"):
        _node("intruder", context)


def test_array_publisher_packs_in_layout_order(context, params):
    node, ep = _node("plant_sim", context)
    try:
        pub = ArrayPublisher(ep, "state/t_wall", layout_sizes(params))
        assert pub.layout.labels == ("step", "t_wall_in_c", "t_wall_out_c")
        from rclpy.serialization import deserialize_message
        from std_msgs.msg import Float64MultiArray

        sent: list[bytes] = []
        pub.publisher.publish = sent.append  # what goes to the middleware
        pub.publish_values({"step": 4, "t_wall_in_c": 19.5, "t_wall_out_c": 3.25})
        msg = deserialize_message(sent[0], Float64MultiArray)
        assert list(msg.data) == [4.0, 19.5, 3.25]
        (dim,) = msg.layout.dim  # any ROS tool shows what each element is
        assert (dim.label, dim.size, dim.stride) == ("step,t_wall_in_c,t_wall_out_c", 3, 3)
    finally:
        node.destroy_node()


def test_layout_sizes_follow_the_in_process_loop(params):
    from comems4build_ros.core.loop import BOUNDS_AHEAD, PRICE_WINDOW

    s = layout_sizes(params)
    assert s == {"horizon": PRICE_WINDOW, "comfort_ahead": BOUNDS_AHEAD + 1}
    lay = load_contract().topic("feed/comfort_ahead").layout(s)
    assert lay.length == 1 + 6  # k .. k+5 (sec:information: 5 h ahead)


# ---------------------------------------------------------------------- commands
@pytest.fixture(scope="module")
def cmd_layout(params):
    return load_contract().topic("ems/command").layout(layout_sizes(params))


def test_valid_command_becomes_an_action(params, cmd_layout):
    step, action = command_to_action([12.0, 0.6, 2.0, 800.0, -500.0, 0.0, 7.0], cmd_layout, command_bounds(params))
    assert step == 12
    assert (action.hp_mod, action.hp_mode, action.p_fc_w, action.p_bess_w, action.p_el_w) == (
        0.6, HP_DHW, 800.0, -500.0, 0.0)
    assert isinstance(action.hp_mode, int)
    # cooling (hp_mode 3) and the electrolyser are part of the command (the plant refuses what it lacks)
    year = load_plant_params(scenario_config_files("year"))
    _, action = command_to_action([3.0, 1.0, 3.0, 0.0, 0.0, 2000.0, 7.0], cmd_layout, command_bounds(year))
    assert (action.hp_mode, action.p_el_w) == (3, 2000.0)


def test_command_bounds_are_device_limits_plus_tolerance(params):
    b = command_bounds(params)
    # p_bess: [-1000, 1000] W (config/plant.yaml) widened by 1 % of 1000 W + 1 W = 11 W
    assert b["p_bess_w"] == pytest.approx((-1011.0, 1011.0))
    # p_fc: [0, 2441.6] W widened by 24.416 W + 1 W
    assert b["p_fc_w"] == pytest.approx((-25.416, 2441.6 + 25.416))
    assert b["hp_mod"] == pytest.approx((-0.01, 1.01))
    assert b["p_el_w"] == pytest.approx((-1.0, 1.0))  # no electrolyser in the paper's plant


@pytest.mark.parametrize(
    "data, field, reason",
    [
        ([1.0, 0.5, 1.0, 0.0, 0.0, 3.0], "(length)", "6 elements"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0, 3.0], "(length)", "8 elements"),
        ([1.0, math.nan, 1.0, 0.0, 0.0, 0.0, 3.0], "hp_mod", "non-finite"),
        ([1.0, 0.5, 1.0, math.inf, 0.0, 0.0, 3.0], "p_fc_w", "non-finite"),
        ([1.0, 0.5, 1.0, 0.0, -math.inf, 0.0, 3.0], "p_bess_w", "non-finite"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, math.nan, 3.0], "p_el_w", "non-finite"),
        ([math.nan, 0.5, 1.0, 0.0, 0.0, 0.0, 3.0], "step", "non-finite"),
        ([1.5, 0.5, 1.0, 0.0, 0.0, 0.0, 3.0], "step", "not a non-negative integer"),
        ([-1.0, 0.5, 1.0, 0.0, 0.0, 0.0, 3.0], "step", "not a non-negative integer"),
        ([1.0, 0.5, 4.0, 0.0, 0.0, 0.0, 3.0], "hp_mode", "is not one of"),
        ([1.0, 0.5, 1.5, 0.0, 0.0, 0.0, 3.0], "hp_mode", "is not one of"),
        ([1.0, 1.5, 1.0, 0.0, 0.0, 0.0, 3.0], "hp_mod", "outside the accepted range"),
        ([1.0, 0.5, 1.0, 5000.0, 0.0, 0.0, 3.0], "p_fc_w", "outside the accepted range"),
        ([1.0, 0.5, 1.0, -100.0, 0.0, 0.0, 3.0], "p_fc_w", "outside the accepted range"),
        ([1.0, 0.5, 1.0, 0.0, 1e6, 0.0, 3.0], "p_bess_w", "outside the accepted range"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, 2000.0, 3.0], "p_el_w", "outside the accepted range"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, 0.0, 0.0], "token", r"not an integer in 1\.\.2\^53-1"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, 0.0, 2.5], "token", "not an integer"),
        ([1.0, 0.5, 1.0, 0.0, 0.0, 0.0, 2.0**53], "token", "not an integer"),
    ],
)
def test_invalid_command_names_the_field(params, cmd_layout, data, field, reason):
    with pytest.raises(CommandError, match=reason) as err:
        command_to_action(data, cmd_layout, command_bounds(params))
    assert err.value.field == field
    assert f"field '{field}'" in str(err.value)


# ---------------------------------------------------------------------- parameters
def test_plant_params_from_ros_parameters(context, tmp_path):
    from rclpy.parameter import Parameter

    extra = tmp_path / "bigger_battery.yaml"
    extra.write_text("/**:\n  ros__parameters:\n    battery:\n      e_max_kwh: 10.0\n")
    from comems4build_ros.ros.package_node import NodeParameters

    node, _ = _node(
        "plant_sim",
        context,
        parameter_overrides=[
            Parameter("config_files", value=[str(extra)]),
            Parameter("dhw.v_max_l", value=350.0),  # as `--params-file` with a dhw section sets it
            Parameter("overrides", value=["pv.n_modules=20"]),
        ],
    )
    try:
        p = NodeParameters(node).plant_params()
        assert p.battery.e_max_kwh == 10.0
        assert p.dhw.v_max_l == 350.0
        assert p.pv.n_modules == 20
        assert p.fuel_cell.p_max_w == load_plant_params().fuel_cell.p_max_w  # untouched default
    finally:
        node.destroy_node()


def test_invalid_ros_parameter_names_the_parameter(context):
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.package_node import NodeParameters

    node, _ = _node("feed", context, parameter_overrides=[Parameter("battery.soc_min", value=0.95)])
    try:
        with pytest.raises(ConfigError, match="battery"):
            NodeParameters(node).plant_params()
    finally:
        node.destroy_node()


# ---------------------------------------------------------------------- ros2 run lookup
EXECUTABLES = ("plant_sim", "feed", "fuzzy_ems", "rbc_ems", "mpc_ems", "thermostat_ems", "mpc_qp_ems", "recorder",
               "replay")


def test_ros2_run_lookup_finds_every_executable(monkeypatch):
    """What `ros2 run comems4build_ros X` does: ament index -> <prefix>/lib/<pkg>/X."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    monkeypatch.setenv("AMENT_PREFIX_PATH", sys.prefix)
    try:
        prefix = Path(get_package_prefix("comems4build_ros"))
    except PackageNotFoundError:
        pytest.skip("package not installed into the venv (run tools/setup.sh --no-run)")
    for name in EXECUTABLES:
        exe = prefix / "lib" / "comems4build_ros" / name
        assert exe.is_file() and os.access(exe, os.X_OK), exe


def test_installed_executable_runs_with_the_venv_python(tmp_path, domain_id):
    """The shell/Python first line finds <prefix>/bin/python even with a bare PATH."""
    exe = Path(sys.prefix) / "lib" / "comems4build_ros" / "feed"
    if not exe.is_file():
        pytest.skip("package not installed into the venv (run tools/setup.sh --no-run)")
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": str(tmp_path),
        "ROS_LOG_DIR": str(tmp_path / "log"),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_DOMAIN_ID": str(domain_id),
    }
    missing = tmp_path / "missing.csv"
    proc = subprocess.run(
        [str(exe), "--ros-args", "-p", f"scenario:={missing}"], env=env, capture_output=True, text=True,
        timeout=BUDGET_S,
    )
    assert proc.returncode == 2, proc.stderr
    assert "[feed]: refused to start: scenario" in proc.stderr and "missing.csv" in proc.stderr


def test_ready_cdr_bytes_equal_rclpy_serialisation(params) -> None:
    """ArrayPublisher's ready CDR bytes decode to the message rclpy would send and have its length
    (padding bytes are unspecified in CDR: rclpy leaves whatever was in memory there)."""
    from array import array

    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension

    from comems4build_ros.wire.cdr import cdr_prefix

    contract = load_contract()
    for spec in contract.topics.values():
        if not spec.is_array:
            continue
        lay = spec.layout(layout_sizes(params))
        data = array("d", [0.1 * i - 3.0 for i in range(lay.length)])
        msg = Float64MultiArray(data=data)
        msg.layout.dim = [MultiArrayDimension(label=lay.dim_label, size=lay.length, stride=lay.length)]
        ready = cdr_prefix(lay.dim_label, lay.length) + data.tobytes()
        assert len(ready) == len(serialize_message(msg)), spec.name
        back = deserialize_message(ready, Float64MultiArray)
        assert list(back.data) == list(data) and back.layout.data_offset == 0, spec.name
        (dim,) = back.layout.dim
        assert (dim.label, dim.size, dim.stride) == (lay.dim_label, lay.length, lay.length), spec.name


@pytest.mark.parametrize("text", ["", "a", "abcd", '{"step": 3, "ems": "fuzzy", "info": {"h2": 0.5}}', "äöü"])
def test_string_cdr_equals_rclpy_serialisation(text: str) -> None:
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import String

    from comems4build_ros.wire.cdr import string_cdr

    assert string_cdr(text) == serialize_message(String(data=text))
    assert deserialize_message(string_cdr(text), String).data == text


@pytest.mark.parametrize("value", [0, 1, 2016, 2**32 - 1])
def test_uint32_cdr_equals_rclpy_serialisation(value: int) -> None:
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import UInt32

    from comems4build_ros.wire.cdr import uint32_cdr, uint32_value

    assert uint32_cdr(value) == serialize_message(UInt32(data=value))
    assert deserialize_message(uint32_cdr(value), UInt32).data == value == uint32_value(uint32_cdr(value))
    with pytest.raises(ValueError, match="out of range"):
        uint32_cdr(2**32)


@pytest.mark.parametrize("t_ns", [0, 1_669_852_800_000_000_000, 1_669_852_800_999_999_999, -1])
def test_clock_cdr_equals_rclpy_serialisation(t_ns: int) -> None:
    from builtin_interfaces.msg import Time
    from rclpy.serialization import deserialize_message, serialize_message
    from rosgraph_msgs.msg import Clock

    from comems4build_ros.wire.cdr import clock_cdr

    sec, nanosec = divmod(t_ns, 1_000_000_000)
    assert clock_cdr(t_ns) == serialize_message(Clock(clock=Time(sec=sec, nanosec=nanosec)))
    back = deserialize_message(clock_cdr(t_ns), Clock).clock
    assert back.sec * 1_000_000_000 + back.nanosec == t_ns
    with pytest.raises(ValueError, match="out of range"):
        clock_cdr(2**31 * 1_000_000_000)


@pytest.mark.parametrize("labels", [[], ["x"], ["step,t_air_c", "ab"], ["a" * 7]])
def test_parse_array_reads_what_rclpy_serialises(labels) -> None:
    from array import array

    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension

    from comems4build_ros.wire.cdr import parse_array

    values = array("d", [3.0, -0.1, 1e300, 7.25])
    msg = Float64MultiArray(data=values)
    msg.layout.dim = [MultiArrayDimension(label=lab, size=4, stride=4) for lab in labels]
    raw = serialize_message(msg)
    assert parse_array(raw) == values
    with pytest.raises(ValueError, match="cut short"):
        parse_array(raw[:-3])
    with pytest.raises(ValueError, match="little-endian"):
        parse_array(b"\x00\x00")


def _descriptions(node) -> dict[str, object]:
    names = node.list_parameters([], 0).names
    rclpy_own = ("use_sim_time", "start_type_description_service")  # declared by rclpy itself
    return {n: node.describe_parameter(n) for n in names if n not in rclpy_own}


def test_every_parameter_has_a_description_unit_and_range(context, tmp_path):
    """What ``ros2 param describe`` shows: each parameter of plant_sim, the EMS and the
    recorder (plant sections included) has a description ending in its unit, and a range
    (numbers) or its allowed values (text, flags)."""
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.ems_node import EMSNode
    from comems4build_ros.ros.nodes.plant_sim import PlantSimNode
    from comems4build_ros.ros.nodes.recorder import Recorder

    overrides = [Parameter("battery.e_max_kwh", value=8.0), Parameter("step_timeout_s", value=3)]
    nodes = [PlantSimNode(context=context, parameter_overrides=overrides), EMSNode("fuzzy", context=context),
             Recorder(context=context, parameter_overrides=[Parameter("bag_path", value=str(tmp_path / "bag"))])]
    try:
        for node in nodes:
            described = _descriptions(node)
            assert "config_files" in described and "exit_when_done" in described or node.get_name() == "recorder"
            for name, d in described.items():
                assert d.description, (node.get_name(), name)
                numeric = d.type in (2, 3)  # integer, double
                if numeric:
                    assert d.description.endswith("]"), (node.get_name(), name, d.description)
                    assert d.floating_point_range or d.integer_range or d.additional_constraints, (name, d)
                else:
                    assert d.additional_constraints, (node.get_name(), name)
        plant = _descriptions(nodes[0])
        assert plant["battery.e_max_kwh"].description.endswith("[kWh]")
        # from its physical lower bound (core/config.py: a tenth of the smallest home battery module)
        assert plant["battery.e_max_kwh"].floating_point_range[0].from_value == 0.1
        # given as the integer 3: the number 3.0 of the declared type (double), with its range
        timeout = plant["step_timeout_s"]
        assert timeout.type == Parameter.Type.DOUBLE.value and timeout.floating_point_range
        assert nodes[0].get_parameter("step_timeout_s").value == 3.0
        assert plant["config_files"].type == Parameter.Type.STRING_ARRAY.value  # not a list holding ""
    finally:
        for node in nodes:
            node.destroy_node()


def test_parameter_outside_its_range_is_refused(context):
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.plant_sim import PlantSimNode

    with pytest.raises(ValueError, match="record_window_steps"):
        PlantSimNode(context=context, parameter_overrides=[Parameter("record_window_steps", value=0)])


@pytest.mark.parametrize("given", ["/house_0", "/house_0, /house_1", ["/house_0", "/house_1"]])
def test_recorder_takes_namespaces_as_string_or_array(context, tmp_path, given):
    """launch_ros hands a list of one substitution over as a string: both forms work."""
    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.recorder import Recorder

    node = Recorder(context=context, parameter_overrides=[Parameter("bag_path", value=str(tmp_path / "bag")),
                                                          Parameter("namespaces", value=given)])
    try:
        want = [given] if given == "/house_0" else ["/house_0", "/house_1"]
        assert node.namespaces == want
    finally:
        node.destroy_node()


def test_a_silent_ems_whose_feed_stopped_answering_names_the_feed(context):
    """The EMS falls silent when its inputs stop; the plant may still hold inputs published
    ahead. Its stall message then names the feed as well, not the EMS alone."""
    import time

    from comems4build_ros.ros.nodes.plant_sim import PlantSimNode

    node = PlantSimNode(context=context)
    try:
        now = time.monotonic()
        node._t_truth = now - 0.2  # the feed answered the last announcement
        assert node.silent_ems_cause(now) == ""
        node._t_truth = now - 3.0 * node.loop.step_timeout_s  # no answer for three step time-outs
        cause = node.silent_ems_cause(now)
        assert "the feed has not answered the step announcements" in cause
        assert "waiting for the feed's inputs on 'feed/truth'" in cause
    finally:
        node.destroy_node()


def test_signals_during_the_clean_up_do_not_cut_it_short():
    """After a node's run, SIGINT and SIGTERM are ignored while it cleans up (a recorder closes
    its bag then); before, both stop the node like Ctrl-C (KeyboardInterrupt)."""
    import subprocess
    import sys

    code = ("import os, signal\n"
            "import rclpy\n"
            "from comems4build_ros.ros.process import ignore_stop_signals, init_rclpy\n"
            "init_rclpy([])\n"
            "try:\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n"
            "    print('SIGTERM not raised')\n"
            "except KeyboardInterrupt:\n"
            "    print('SIGTERM raised KeyboardInterrupt')\n"
            "ignore_stop_signals()\n"
            "os.kill(os.getpid(), signal.SIGTERM)\n"
            "os.kill(os.getpid(), signal.SIGINT)\n"
            "rclpy.try_shutdown()\n"
            "print('clean-up went on')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == ["SIGTERM raised KeyboardInterrupt", "clean-up went on"], res.stdout
