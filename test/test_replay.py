"""``replay``: a recorded bag published again (full, as fast as possible; inputs only, paced by the plant)."""

from __future__ import annotations

import json
import time
import warnings
from collections import Counter
from pathlib import Path

import pytest

from comems4build_ros.bags.bag import decode, iter_messages
from comems4build_ros.bags.evaluation import evaluate_bag
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.ros.interfaces import message_class, qos_profile
from comems4build_ros.run.launcher import launch
from comems4build_ros.run.plan import LaunchOptions, node_command, ros_args
from comems4build_ros.run.supervisor import ProcessGroup, acquire_domain_id, child_env
from comems4build_ros.wire.contract import load_contract

pytestmark = pytest.mark.ros
STEPS = 24
#: Topics the recorders publish themselves (never replayed).
RECORDER_OWN = ("/recorder/ready", "/recorder/progress")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 24-step fuzzy run recorded by the launcher."""
    out = tmp_path_factory.mktemp("recorded") / "run"
    return launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=STEPS, timeout_s=150)).bag


def _wait_exit(child, timeout_s: float = 90.0) -> int:
    t0 = time.monotonic()
    while child.proc.poll() is None:
        assert time.monotonic() - t0 < timeout_s, child.tail()
        time.sleep(0.05)
    return child.proc.returncode


def test_full_replay_as_fast_as_possible_is_recorded_again(recorded: Path, tmp_path: Path) -> None:
    bag = tmp_path / "again"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = group.start("recorder", "recorder", [*node_command("recorder"), *ros_args("", {
            "bag_path": str(bag), "wait_for_topics": ["feed/truth"], "stop_when_done": True})])
        rep = group.start("replay", "replay", [*node_command("replay"), str(recorded), "--rate", "0"])
        assert _wait_exit(rep) == 0, rep.tail()
        assert _wait_exit(rec) == 0, rec.tail()  # stops by itself: plant/done was replayed
    original = Counter((t, bytes(raw)) for t, _, _, raw in iter_messages(recorded) if t not in RECORDER_OWN)
    again = Counter((t, bytes(raw)) for t, _, _, raw in iter_messages(bag) if t not in RECORDER_OWN)
    assert again == original


def _drive_with_recorded_inputs(ems: str, inputs: Path, tmp_path: Path,
                                timeout_s: float = 90.0) -> tuple[dict, dict]:
    """Recorder, ``ems``, an inputs-only replay of the bag ``inputs`` and a plant: the summary of the
    new bag, and that of the in-process run of ``ems`` on the same scenario."""
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario.run import load_scenario

    bag = tmp_path / f"{ems}_bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = group.start("recorder", "recorder", [*node_command("recorder"), *ros_args("", {"bag_path": str(bag)})])
        # as the launcher starts the feed and the EMS: their first message waits until their
        # writers matched the recorder's readers (else the first steps can miss in the bag)
        gate = ros_args("", {"wait_for_recorder": True})
        group.start(f"{ems}_ems", "ems", [*node_command("ems", ems), *gate])
        group.start("replay", "replay", [*node_command("replay"), str(inputs), "--inputs-only", *gate])
        plant = group.start("plant_sim", "plant", [*node_command("plant_sim"),
                                                   *ros_args("", {"wait_for_recorder": True})])
        assert _wait_exit(plant, timeout_s) == 0, plant.tail()
        assert _wait_exit(rec) == 0, rec.tail()
    params = load_plant_params()
    summary = evaluate_bag(bag, tmp_path / "eval", params=params)["/"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = simulate(ems, load_scenario("default", params, None, 1, None, STEPS), params).summary
    return summary, ref


@pytest.mark.skipif(
    not load_contract().may_subscribe("replay", "plant/step"),
    reason="contract: 'replay' is not (yet) a subscriber of plant/step, needed for the lock-step --inputs-only mode",
)
def test_inputs_only_replay_drives_another_ems(recorded: Path, tmp_path: Path) -> None:
    """rbc against the inputs recorded with fuzzy gives the in-process rbc run on the same scenario."""
    summary, ref = _drive_with_recorded_inputs("rbc", recorded, tmp_path)
    for key in set(ref) - {"wall_s", "ems_s"}:  # ems and scenario too: announced in the bag (ems/info, feed/info)
        assert summary[key] == ref[key], key
    assert summary["ems"] == "rbc" and summary["lost_messages"] == {}
    assert json.loads((tmp_path / "eval" / "summary.json").read_text())["fallback_steps"] == 0


def test_a_run_records_the_inputs_of_its_ems_and_all_inputs_drive_the_mpc(recorded: Path, tmp_path: Path) -> None:
    """tab:level_of_information: the fuzzy run's feed published (and its bag holds) no MPC
    input; recorded with ``all_inputs``, the same fuzzy run's bag drives an MPC through an
    inputs-only replay to exactly the in-process MPC run."""
    unread = {f"/{t}" for t in load_contract().inputs_not_read("fuzzy_ems")}
    assert "/forecast/p_pv_w" in unread
    topics = Counter(t for t, *_ in iter_messages(recorded))
    # at least one answer per step: the feed answers every announcement, and the plant repeats
    # one every republish_period_s while its answer is late (a loaded machine)
    assert not unread & set(topics) and topics["/feed/solar"] >= STEPS
    full = launch(LaunchOptions(ems="fuzzy", out=tmp_path / "all", weeks=1, steps=STEPS, timeout_s=150,
                                all_inputs=True)).bag
    topics = Counter(t for t, *_ in iter_messages(full))
    assert all(topics[t] >= STEPS for t in unread)
    summary, ref = _drive_with_recorded_inputs("mpc", full, tmp_path, timeout_s=240.0)
    for key in set(ref) - {"wall_s", "ems_s"}:
        assert summary[key] == ref[key], key
    assert summary["ems"] == "mpc" and summary["lost_messages"] == {}


def test_evaluate_refuses_a_bag_with_gaps_unless_accepted(recorded: Path, tmp_path: Path) -> None:
    """A copy of the recorded bag without three state/soc messages: exit 2 naming topic and steps."""
    import subprocess
    import sys

    from comems4build_ros.bags.bag import BagWriter, bag_info, decode

    info = bag_info(recorded)
    gappy = tmp_path / "gappy"
    with BagWriter(gappy) as w:
        w.set_custom_data("comems4build.run_info", (recorded / "run_info.json").read_text())
        for topic, msgtype in sorted(info.topics.items()):
            w.add_topic(topic, msgtype)
        for topic, msgtype, t_ns, raw in iter_messages(recorded):
            if topic == "/state/soc" and int(decode(msgtype, raw).data[0]) in (3, 4, 9):
                continue
            w.write(topic, t_ns, raw)
    (gappy / "run_info.json").write_text((recorded / "run_info.json").read_text())
    cli = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())", "evaluate"]
    res = subprocess.run([*cli, str(gappy), "--out", str(tmp_path / "e1")], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 2, res.stderr
    assert "/state/soc: 3 step(s) missing (3-4, 9)" in res.stderr and "--accept-gaps" in res.stderr
    assert not (tmp_path / "e1" / "summary.json").exists()
    res = subprocess.run([*cli, str(gappy), "--out", str(tmp_path / "e2"), "--accept-gaps"], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    summary = json.loads((tmp_path / "e2" / "summary.json").read_text())
    assert summary["lost_messages"] == {"/state/soc": 3}
    assert "wrote 3 files:" in res.stdout and "timeseries.csv" in res.stdout
    assert summary["wall_s"] is None and summary["bag_duration_s"] > 0  # the bag's duration is not a wall time


def test_inputs_only_replay_holds_its_inputs_until_the_recorder_has_matched(recorded: Path, tmp_path: Path) -> None:
    """With ``wait_for_recorder`` the replay answers the plant's announcement only once its
    writers have matched a recorder's readers (``RecorderGate.is_open``): no input goes
    out while no recorder listens, and the held answer for step 0 reaches the recorder's bag."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    contract = load_contract()
    step_spec, cal_spec = contract.topic("plant/step"), contract.topic("feed/calendar")
    bag = tmp_path / "bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx, domain_id=did)
        node = Node("gate_observer", context=ctx)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        got: list[int] = []
        try:
            step_pub = node.create_publisher(message_class(step_spec), "plant/step", qos_profile(step_spec))
            node.create_subscription(message_class(cal_spec), "feed/calendar", lambda m: got.append(int(m.data[0])),
                                     qos_profile(cal_spec))
            announce = message_class(step_spec)(data=0)

            def spin_for(seconds: float, until=lambda: False) -> None:
                t_end, t_pub = time.monotonic() + seconds, 0.0
                while time.monotonic() < t_end and not until():
                    if time.monotonic() - t_pub > 0.2:  # repeated, as the plant repeats a late step
                        step_pub.publish(announce)
                        t_pub = time.monotonic()
                    executor.spin_once(timeout_sec=0.05)

            rep = group.start("replay", "replay", [*node_command("replay"), str(recorded), "--inputs-only",
                                                   *ros_args("", {"wait_for_recorder": True})])
            spin_for(60.0, lambda: step_pub.get_subscription_count() > 0 and node.count_publishers("feed/calendar") > 0)
            assert step_pub.get_subscription_count() > 0, rep.tail()
            spin_for(3.0)  # announced for 3 s: the gate is closed, nothing is published
            assert got == [], f"published before a recorder listened: steps {got}"
            rec = group.start("recorder", "recorder", [*node_command("recorder"), *ros_args("", {
                "bag_path": str(bag), "stop_when_done": False})])
            spin_for(60.0, lambda: 0 in got)
            assert 0 in got, rep.tail()
            time.sleep(1.5)  # the recorder writes its chunk (chunk_period_s 1 s), then closes on SIGINT
            rec.proc.send_signal(2)
            assert _wait_exit(rec) == 0, rec.tail()
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
    steps = {int(decode("std_msgs/msg/Float64MultiArray", raw).data[0])
             for t, _, _, raw in iter_messages(bag) if t == "/feed/calendar"}
    assert 0 in steps
