"""Run plans (``comems4build_ros.run.plan``): built from launch options without starting a process."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import pytest

from comems4build_ros.core.scenario.settings import load_scenario_settings
from comems4build_ros.run.plan import (
    CONTAINER_STEP_TIMEOUT_S,
    DISCOVERY_PORT_BASE,
    STAGE_NODES,
    STAGE_RECORDERS,
    STAGE_SERVICES,
    LaunchOptions,
    node_label,
    plan_run,
)


def _param(argv: tuple[str, ...], name: str) -> str:
    """Value of ``-p name:=value`` in a command line."""
    for i, a in enumerate(argv):
        if a == "-p" and argv[i + 1].startswith(f"{name}:="):
            return argv[i + 1].split(":=", 1)[1]
    raise AssertionError(f"no -p {name} in {argv}")


def test_one_house_one_process_per_node(tmp_path: Path) -> None:
    plan = plan_run(LaunchOptions(ems="fuzzy", out=tmp_path / "run", weeks=1, steps=36), domain_id=42)
    assert plan.layout == "node" and plan.domain_id == 42
    assert [p.name for p in plan.processes] == ["recorder", "fuzzy_ems", "feed", "plant_sim"]
    assert [b.namespace for b in plan.houses] == ["/"] and plan.houses[0].bag == tmp_path / "run" / "bag"
    rec, ems, feed, plant = plan.processes
    assert (rec.finishes, rec.progress, rec.stop_stage) == (True, True, STAGE_RECORDERS)
    assert (plant.finishes, plant.stop_stage) == (True, STAGE_NODES)
    assert ems.finishes and feed.finishes  # every node exits 0 on plant/done
    token, token_file = plan.houses[0].token, plan.houses[0].token_file
    assert 0 < token < 2**53 and token_file == str((tmp_path / "run" / ".secrets" / "root.token").resolve())
    # the run secret reaches EMS and plant through a file (mode 0600, written by the supervisor):
    # never on a command line, in a parameter or in the plan's printed form
    assert _param(ems.argv, "run_token_file") == json.dumps(token_file)
    assert _param(plant.argv, "ems_token_file") == json.dumps(token_file)
    assert plan.secrets == ((token_file, token),)
    assert all(str(token) not in " ".join(p.argv) for p in plan.processes) and str(token) not in plan.describe()
    assert str(token) not in json.dumps(plan.to_dict())
    assert _param(plant.argv, "stall_steps") == "3" and plan.stall_s == pytest.approx(90.0)
    assert plan.timeout_s == pytest.approx(300.0 + 0.1 * 36)  # default overall time limit
    assert _param(plant.argv, "wait_for_recorder") == "true"
    assert _param(feed.argv, "weeks") == "1" and _param(feed.argv, "steps") == "36"
    assert json.loads(json.loads(_param(rec.argv, "run_info")))["ems"] == "fuzzy"
    assert [n.name for _, n in plan.nodes()] == ["recorder", "fuzzy_ems", "feed", "plant_sim"]
    assert plan.nodes("ems")[0][1].namespace == "/"
    assert "ROS_DISCOVERY_SERVER" not in plan.env and all(not p.env for p in plan.processes)
    assert set(plan.sides) == {"local"} and all(p.side == "local" for p in plan.processes)


@pytest.mark.parametrize("layout", ["node", "house", "role"])
def test_feed_publishes_and_recorder_records_what_the_ems_reads(layout: str, tmp_path: Path) -> None:
    """tab:level_of_information: the feed of an RBC run leaves out what the RBC does not read
    and the recorder does not wait for it; ``all_inputs`` keeps every input in the bag."""
    from comems4build_ros.wire.contract import load_contract

    unread = list(load_contract().inputs_not_read("rbc_ems"))
    assert "forecast/p_pv_w" in unread and "feed/solar" in unread
    # an independent house has no link to a community's coordinator: its recorder leaves those topics out
    link = [t.name for t in load_contract().in_scope("community_house")]
    assert "hub/allotment" in link
    for all_inputs in (False, True):
        opts = LaunchOptions(ems="rbc", out=tmp_path / f"run{all_inputs}", steps=6, houses=2, layout=layout,
                             all_inputs=all_inputs)
        plan = plan_run(opts, domain_id=3)
        feeds = [n.params for _, n in plan.nodes("feed")]
        recorders = [n.params for _, n in plan.nodes("recorder")]
        assert len(feeds) == 2 and len(recorders) == 2
        # one clock per run: only the first house's bag records /clock
        if all_inputs:
            assert all("for_ems" not in p for p in feeds) and recorders[0]["skip_topics"] == link
            assert recorders[1]["skip_topics"] == [*link, "/clock"]
        else:
            assert all(p["for_ems"] == "rbc_ems" for p in feeds)
            assert recorders[0]["skip_topics"] == [*unread, *link]
            assert recorders[1]["skip_topics"] == [*unread, *link, "/clock"]


def test_several_houses_one_process_per_role(tmp_path: Path) -> None:
    opts = LaunchOptions(ems="rbc", out=tmp_path / "run", weeks=1, houses=5, houses_per_recorder=2,
                         layout="role")
    plan = plan_run(opts, domain_id=7)
    assert plan.layout == "role"
    assert [p.name for p in plan.processes] == [
        "role_recorder_0", "role_recorder_1", "role_recorder_2", "role_ems", "role_feed", "role_plant"]
    seed = load_scenario_settings().seed
    assert [b.seed for b in plan.houses] == [seed + i for i in range(5)]
    assert [str(b.bag.relative_to(tmp_path)) for b in plan.houses] == [
        f"run/bag/house_{i}" for i in range(5)]
    feed = plan.process("role_feed")
    assert [n.params["seed"] for n in feed.nodes] == [seed + i for i in range(5)]
    ((path, text),) = feed.files
    assert Path(path) == tmp_path / "run" / "containers" / "role_feed.json"
    spec = json.loads(text)
    assert spec["ems"] == "rbc" and [n["namespace"] for n in spec["nodes"]] == [f"/house_{i}" for i in range(5)]
    assert str(path) in feed.argv
    plant = plan.process("role_plant")
    assert plant.finishes and all(n.params["step_timeout_s"] == CONTAINER_STEP_TIMEOUT_S for n in plant.nodes)
    assert [n.namespace for n in plan.process("role_recorder_2").nodes] == ["/house_4"]
    assert not any(p.role == "discovery" for p in plan.processes)
    with pytest.raises(KeyError, match="no process 'nope'.*role_feed"):
        plan.process("nope")


@pytest.mark.parametrize("layout", ["node", "role", "house"])
def test_nodes_of_each_process_are_named_with_the_house_they_serve(layout: str, tmp_path: Path) -> None:
    """What the launcher names when a process leaves the run (``supervisor.left_error``)."""
    from comems4build_ros.run.supervisor import describe_nodes

    plan = plan_run(LaunchOptions(ems="rbc", out=tmp_path, weeks=1, houses=2, layout=layout), domain_id=1)
    labels = {p.name: [node_label(n) for n in p.nodes] for p in plan.processes}
    every = sorted(n for names in labels.values() for n in names)
    assert every == sorted(f"/house_{i}/{n}" for i in (0, 1) for n in ("recorder", "rbc_ems", "feed", "plant_sim"))
    if layout == "node":
        assert labels["house_0/recorder"] == ["/house_0/recorder"]  # started at /, records house_0
    if layout == "role":
        assert describe_nodes(labels["role_ems"]) == "rbc_ems of /house_0, /house_1"
    if layout == "house":
        assert describe_nodes(labels["container_1"]) == "recorder, rbc_ems, feed, plant_sim of /house_1"
    many = [f"/house_{i}/rbc_ems" for i in range(8)]
    assert describe_nodes(many) == "rbc_ems of /house_0 .. /house_7 (8 houses)"


def test_plant_params_override_host_defaults(tmp_path: Path) -> None:
    opts = LaunchOptions(ems="fuzzy", out=tmp_path, houses=2, plant_node_params={"step_timeout_s": 3.0})
    plants = [n for _, n in plan_run(opts, domain_id=1).nodes("plant")]  # containers
    assert [n.params["step_timeout_s"] for n in plants] == [3.0, 3.0]
    plant = plan_run(dataclasses.replace(opts, layout="role"), domain_id=1).process("role_plant")
    assert [n.params["step_timeout_s"] for n in plant.nodes] == [3.0, 3.0]


def test_discovery_server_is_an_option_of_the_plan(tmp_path: Path) -> None:
    opts = LaunchOptions(ems="fuzzy", out=tmp_path, houses=2, layout="node")
    plan = plan_run(opts, domain_id=9)
    first, *rest = plan.processes
    if first.role != "discovery":
        pytest.skip("fast-discovery-server is not installed with the ROS wheels here")
    assert first.stop_stage == STAGE_SERVICES and str(DISCOVERY_PORT_BASE + 9) in first.argv
    assert [p.name for p in rest] == [
        "house_0/recorder", "house_1/recorder", "house_0/fuzzy_ems", "house_0/feed",
        "house_0/plant_sim", "house_1/fuzzy_ems", "house_1/feed", "house_1/plant_sim"]
    assert all(p.env["ROS_DISCOVERY_SERVER"] == f"127.0.0.1:{DISCOVERY_PORT_BASE + 9}" for p in rest)
    assert "ROS_DISCOVERY_SERVER" not in first.env
    assert [p.nodes[0].namespace for p in rest if p.role == "plant"] == ["/house_0", "/house_1"]


def test_time_limit_defaults_and_can_be_switched_off(tmp_path: Path) -> None:
    import math

    plan = plan_run(LaunchOptions(ems="mpc", out=tmp_path, weeks=1, houses=2), domain_id=1)
    assert plan.timeout_s == pytest.approx(300.0 + 1.0 * 168 * 2)
    assert plan_run(LaunchOptions(ems="fuzzy", out=tmp_path), domain_id=1).timeout_s == pytest.approx(300 + 201.6)
    assert plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, timeout_s=math.inf), domain_id=1).timeout_s is None
    tokens = {b.token for b in plan.houses}
    assert len(tokens) == 2  # each house's plant accepts its own EMS only


def test_describe_and_json(tmp_path: Path) -> None:
    plan = plan_run(LaunchOptions(ems="mpc", out=tmp_path, houses=2, timeout_s=30), domain_id=3)
    text = plan.describe()
    assert "layout 'house'" in text and "time limit 30 s" in text and "/house_1/mpc_ems" in text
    data = json.loads(json.dumps(plan.to_dict()))
    assert data["domain_id"] == 3 and data["processes"][-1]["name"].startswith("container_")
    assert [b["namespace"] for b in data["houses"]] == ["/house_0", "/house_1"]


def test_bad_options_name_the_option(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--houses must be >= 1"):
        plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, houses=0), domain_id=1)
    with pytest.raises(ValueError, match="houses_per_recorder"):
        plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, houses=2, houses_per_recorder=0, layout="role"),
                 domain_id=1)


def test_netns_network_is_an_option_of_the_plan(tmp_path: Path) -> None:
    opts = LaunchOptions(ems="rbc", out=tmp_path, weeks=1, network="netns", netem="delay 5ms loss 1%")
    plan = plan_run(opts, domain_id=12)
    assert set(plan.sides) == {"plant_side", "ems_side"}
    groups = {p.name: p.side for p in plan.processes}
    assert groups == {"recorder": "ems_side", "rbc_ems": "ems_side", "feed": "plant_side", "plant_sim": "plant_side"}
    plant_host, ems_host = plan.sides["plant_side"], plan.sides["ems_side"]
    assert (plant_host.netns, plant_host.address, ems_host.netns, ems_host.address) == (
        "c4b12p", "10.231.12.1", "c4b12e", "10.231.12.2")
    assert plant_host.env["ROS_STATIC_PEERS"] == "10.231.12.2" and ems_host.env["ROS_STATIC_PEERS"] == "10.231.12.1"
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"):  # Fast DDS 2.x and 3.x
        assert plant_host.env[var].endswith("fastdds_profile_udp.xml")
    assert plan.process("plant_sim").argv[:4] == ("ip", "netns", "exec", "c4b12p")
    assert ("ip", "netns", "add", "c4b12p") in plan.setup and ("ip", "netns", "del", "c4b12e") in plan.teardown
    assert all("netem" in cmd for cmd in plan.optional_setup) and len(plan.optional_setup) == 2
    with pytest.raises(ValueError, match="network 'cloud': one of local, netns"):
        plan_run(LaunchOptions(ems="rbc", out=tmp_path, network="cloud"), domain_id=1)
    with pytest.raises(ValueError, match="netem applies to the 'netns' network only"):
        plan_run(LaunchOptions(ems="rbc", out=tmp_path, netem="delay 5ms"), domain_id=1)


def test_containers_compose_every_node_of_a_share_of_the_houses(tmp_path: Path) -> None:
    opts = LaunchOptions(ems="fuzzy", out=tmp_path / "run", weeks=1, houses=5, containers=2)
    plan = plan_run(opts, domain_id=9)
    assert plan.layout == "house"
    assert [p.name for p in plan.processes] == ["container_0", "container_1"]
    c0, c1 = plan.processes
    assert [(n.namespace, n.role) for n in c1.nodes] == [
        (ns, role) for ns in ("/house_1", "/house_3") for role in ("recorder", "ems", "feed", "plant")]
    assert {n.namespace for n in c0.nodes} == {"/house_0", "/house_2", "/house_4"}
    assert all(p.role == "container" and p.finishes and p.progress and p.stop_stage == STAGE_RECORDERS
               for p in plan.processes)
    ((path, text),) = c0.files
    spec = json.loads(text)
    assert [e["role"] for e in spec["nodes"]][:4] == ["recorder", "ems", "feed", "plant"]
    assert spec["ems"] == "fuzzy" and str(path) in c0.argv and "container" in c0.argv
    assert "ROS_DISCOVERY_SERVER" not in plan.env and all(not p.env for p in plan.processes)
    # the default for more houses (one container per core); the role layout on request
    default = plan_run(dataclasses.replace(opts, containers=None), domain_id=9)
    assert default.layout == "house" and len(default.processes) == min(5, os.cpu_count() or 1)
    assert plan_run(dataclasses.replace(opts, containers=None, layout="role"), domain_id=9).layout == "role"
    assert plan_run(dataclasses.replace(opts, containers=None, network="netns"), domain_id=9).layout == "role"
    # at most one container per house; a single house composes into one process
    one = plan_run(dataclasses.replace(opts, houses=1, containers=4), domain_id=9)
    assert [p.name for p in one.processes] == ["container_0"] and len(one.processes[0].nodes) == 4
    assert "layout 'house'" in one.describe()
    with pytest.raises(ValueError, match="containers must be >= 1"):
        plan_run(dataclasses.replace(opts, containers=0), domain_id=9)
    with pytest.raises(ValueError, match="network 'local'"):
        plan_run(dataclasses.replace(opts, network="netns"), domain_id=9)
