"""One EMS table (``config/ems.yaml``): everything that names an EMS agrees with it.

The command line's choices, the controller classes, the node executables (console scripts
and ``ros2 run`` wrappers, from setup.py), the EMS nodes of the topic contract, the run plan
and the ROS launch file's use of ``ros2 run`` are all derived from the table; this module
checks each against it, and that a new row is enough to add an EMS everywhere.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import pytest
import yaml

from comems4build_ros.app.cli import build_parser
from comems4build_ros.core.config import ConfigError, config_dir
from comems4build_ros.core.ems import (
    UnknownEMSError,
    controller_class,
    ems_entry,
    ems_names,
    ems_table,
    parse_ems_table,
)
from comems4build_ros.core.ems.base import INFO_LEVELS
from comems4build_ros.wire.contract import load_contract, parse_contract

REPO = Path(__file__).resolve().parents[1]


def _setup_module():
    """setup.py as a module, without running ``setup()``."""
    spec = importlib.util.spec_from_file_location("comems4build_setup", REPO / "setup.py")
    module = importlib.util.module_from_spec(spec)
    source = (REPO / "setup.py").read_text(encoding="utf-8").split("\nsetup(\n")[0]
    exec(compile(source, str(REPO / "setup.py"), "exec"), module.__dict__)  # noqa: S102 (the project's own file)
    return module


def test_the_table_lists_every_ems_with_a_controller_of_its_name_and_level() -> None:
    table = ems_table()
    assert list(table) == ["thermostat", "rbc", "fuzzy", "mpc", "mpc-qp"]
    for name, entry in table.items():
        cls = controller_class(name)
        assert cls.name == name and cls.info_level == entry.info_level in INFO_LEVELS


def test_cli_choices_are_the_table() -> None:
    """`--ems` of every command names the table's EMS, and an unknown name is refused naming them."""
    assert ems_names() == tuple(ems_table())
    parser = build_parser()
    for command in ("simulate", "launch", "compare", "sweep", "size"):
        sub = parser._subparsers._group_actions[0].choices[command]  # noqa: SLF001 (argparse keeps them here)
        ems = next(a for a in sub._actions if "--ems" in a.option_strings)  # noqa: SLF001
        assert all(name in ems.help for name in ems_names()), (command, ems.help)
    with pytest.raises(UnknownEMSError, match="known: fuzzy, mpc, mpc-qp, rbc, thermostat"):
        ems_entry("nope")


def test_node_executables_are_the_table_nodes() -> None:
    """setup.py installs one executable per EMS, named after its node, and the installed ones run it."""
    setup = _setup_module()
    exes = setup.executables()
    for entry in ems_table().values():
        assert exes[entry.node][0] == "comems4build_ros.ros.nodes.ems_node"
    from comems4build_ros.run.plan import NODE_MODULES, ros_node_executables

    assert set(exes) == set(NODE_MODULES) | {e.node for e in ems_table().values()}
    assert {n: m for n, (m, _) in setup.NODES.items()} == NODE_MODULES
    assert ros_node_executables() == set(exes) - {"mqtt_plant"}
    bindir = Path(sys.executable).parent
    lib = Path(sys.prefix) / "lib" / "comems4build_ros"
    if not lib.is_dir():
        pytest.skip("package not installed into this environment (tools/setup.sh --no-run)")
    for entry in ems_table().values():
        for exe in (bindir / entry.node, lib / entry.node):
            assert exe.is_file() and os.access(exe, os.X_OK), exe


def test_ems_of_the_executable_name() -> None:
    from comems4build_ros.ros.nodes.ems_node import ems_of_program

    for entry in ems_table().values():
        assert ems_of_program(f"/opt/ros/lib/comems4build_ros/{entry.node}") == entry.name
    assert ems_of_program("python3") is None


def test_contract_ems_nodes_are_the_table_rows_and_subscribe_by_level() -> None:
    contract = load_contract()
    ems_nodes = {n.name: (n.ems, n.info_level) for n in contract.nodes.values() if n.role == "ems"}
    assert ems_nodes == {e.node: (e.name, e.info_level) for e in ems_table().values()}
    for entry in ems_table().values():
        assert contract.ems_node_name(entry.name) == entry.node
        fields = contract.input_fields(entry.node)
        # an EMS reads exactly its level's fields that the feed and plant topics carry (tab:level_of_information)
        assert fields <= INFO_LEVELS[entry.info_level], (entry.name, fields - INFO_LEVELS[entry.info_level])
        assert "ems/command" in {t.name for t in contract.published_by(entry.node)}
    assert contract.input_fields("rbc_ems") < contract.input_fields("fuzzy_ems") < contract.input_fields("mpc_ems")


def test_a_new_row_adds_an_ems_node_to_the_contract(tmp_path: Path) -> None:
    """A table with one more EMS gives the contract one more EMS node subscribed by its level."""
    doc = yaml.safe_load((REPO / "msg_defs" / "topics.yaml").read_text(encoding="utf-8"))
    nodes = {e.node: (e.name, e.info_level) for e in ems_table().values()}
    contract = parse_contract(doc, tmp_path / "topics.yaml", {**nodes, "mine_ems": ("mine", "fuzzy")})
    assert contract.ems_node_name("mine") == "mine_ems"
    assert contract.input_fields("mine_ems") == contract.input_fields("fuzzy_ems")
    assert "mine_ems" in contract.topic("ems/command").publishers


def test_run_plan_uses_the_table(tmp_path: Path) -> None:
    """The plan's EMS node and executable are the table's; the per-step time limit follows the level."""
    from comems4build_ros.run.plan import (
        TIME_LIMIT_PER_STEP_MPC_S,
        TIME_LIMIT_PER_STEP_S,
        LaunchOptions,
        default_time_limit,
        node_command,
        plan_run,
        run_steps,
    )

    for entry in ems_table().values():
        plan = plan_run(LaunchOptions(ems=entry.name, out=tmp_path / entry.name, steps=2), 0)
        names = [n.name for p in plan.processes for n in p.nodes]
        assert entry.node in names
        cmd = node_command("ems", entry.name)
        assert Path(cmd[0]).name == entry.node or cmd[-2:] == ["--ems", entry.name]
        opts = LaunchOptions(ems=entry.name, out=tmp_path, steps=10)
        per = TIME_LIMIT_PER_STEP_MPC_S if entry.info_level == "mpc" else TIME_LIMIT_PER_STEP_S
        assert default_time_limit(opts) == pytest.approx(300.0 + per * run_steps(opts))


@pytest.mark.parametrize(("edit", "message"), [
    ({"info_level": "psychic"}, "info_level 'psychic' is not one of"),
    ({"controller": "no_colon"}, "controller must be 'module:Class'"),
    ({"weight": 0}, "weight must be a number > 0"),
    ({"node": "rbc_ems"}, "node must be a unique ROS node name"),
    ({"colour": None, "extra": 1}, "unknown extra"),
])
def test_a_bad_row_is_refused_naming_the_ems_and_key(edit: dict, message: str) -> None:
    doc = yaml.safe_load((config_dir() / "ems.yaml").read_text(encoding="utf-8"))
    doc["ems"]["fuzzy"] = {**doc["ems"]["fuzzy"], **edit}
    if edit.get("colour", 0) is None:
        del doc["ems"]["fuzzy"]["colour"]
    with pytest.raises(ConfigError, match=message) as info:
        parse_ems_table(doc, "ems.yaml")
    assert "ems 'fuzzy'" in str(info.value)
