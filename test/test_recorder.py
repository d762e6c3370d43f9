"""Bag writer/reader and the recorder node (real rclpy processes for the ``ros`` tests)."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import yaml
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from waits import BUDGET_S, log_has, wait_exit, wait_until

from comems4build_ros.bags.bag import BagInfo, BagWriter, decode, iter_messages, typestore
from comems4build_ros.run.plan import node_command, ros_args
from comems4build_ros.run.supervisor import ProcessGroup, acquire_domain_id, child_env

ARRAY = "std_msgs/msg/Float64MultiArray"


def _array(values: list[float]) -> bytes:
    ts = typestore()
    cls = ts.types[ARRAY]
    layout = ts.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    import numpy as np

    return bytes(ts.serialize_cdr(cls(layout=layout, data=np.array(values, dtype=float)), ARRAY))


def test_bag_writer_round_trip_rosbags_and_mcap(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        w.add_topic("/state/soc", ARRAY)
        w.add_topic("/plant/step", "std_msgs/msg/UInt32")
        w.set_custom_data("comems4build.run_info", '{"ems":"fuzzy"}')
        for k in range(3):
            w.write("/state/soc", 1_000 + k, _array([k, 0.5 + 0.1 * k]))
        w.write("/plant/step", 2_000, bytes(typestore().serialize_cdr(typestore().types["std_msgs/msg/UInt32"](7),
                                                                       "std_msgs/msg/UInt32")))
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 8
    assert meta["ros_distro"] == "jazzy"  # rosbags writes its own name; the bag is for Jazzy
    assert meta["storage_identifier"] == "mcap"
    assert meta["message_count"] == 4
    assert meta["custom_data"] == {"comems4build.run_info": '{"ems":"fuzzy"}'}
    # rosbags
    with AnyReader([bag]) as reader:
        got = [(c.topic, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
    assert [g[1] for g in got] == [1000, 1001, 1002, 2000]
    assert list(got[2][2].data) == [2.0, 0.7]
    assert got[3][2].data == 7
    # mcap with the ROS 2 decoder
    with (bag / "bag.mcap").open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary.statistics.message_count == 4
        # channel metadata as rosbag2's own writer gives it: offered QoS and the type hash
        for ch in summary.channels.values():
            msgtype = "std_msgs/msg/Float64MultiArray" if ch.topic == "/state/soc" else "std_msgs/msg/UInt32"
            assert ch.metadata["topic_type_hash"] == typestore().hash_rihs01(msgtype)
            assert ch.metadata["topic_type_hash"].startswith("RIHS01_")
            assert "reliability" in ch.metadata["offered_qos_profiles"]
        decoded = [(ch.topic, list(m.data) if ch.topic == "/state/soc" else m.data)
                   for _, ch, _, m in reader.iter_decoded_messages()]
    assert decoded == [("/state/soc", [0.0, 0.5]), ("/state/soc", [1.0, 0.6]), ("/state/soc", [2.0, 0.7]),
                       ("/plant/step", 7)]


def test_bag_writer_refuses_existing_directory(tmp_path: Path) -> None:
    (tmp_path / "bag").mkdir()
    with pytest.raises(FileExistsError, match="bag"):
        BagWriter(tmp_path / "bag")


WRITER_SCRIPT = textwrap.dedent(
    """
    import signal, sys, time
    import numpy as np
    from comems4build_ros.bags.bag import BagWriter, typestore
    ts = typestore()
    cls, lay = ts.types["std_msgs/msg/Float64MultiArray"], ts.types["std_msgs/msg/MultiArrayLayout"]
    w = BagWriter(sys.argv[1], chunk_period_s=0.1)
    w.add_topic("/state/soc", "std_msgs/msg/Float64MultiArray")
    for k in range(40):
        raw = ts.serialize_cdr(cls(layout=lay(dim=[], data_offset=0), data=np.array([k, k / 100.0])),
                               "std_msgs/msg/Float64MultiArray")
        w.write("/state/soc", 1000 + k, raw)
    time.sleep(0.3)  # the chunk's age passes its period (0.1 s): the rule under test is one of time
    w.tick()  # the 40 messages are now a closed chunk on disk
    for k in range(40, 45):
        raw = ts.serialize_cdr(cls(layout=lay(dim=[], data_offset=0), data=np.array([k, k / 100.0])),
                               "std_msgs/msg/Float64MultiArray")
        w.write("/state/soc", 1000 + k, raw)  # pending chunk, lost with the process
    print("written", flush=True)
    signal.pause()  # alive until the test kills it
    """
)


def test_sigkilled_writer_leaves_readable_mcap(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    proc = subprocess.Popen([sys.executable, "-c", WRITER_SCRIPT, str(bag)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "written"
    finally:
        proc.send_signal(signal.SIGKILL)
        wait_exit(proc, "the writer killed")
    assert not (bag / "metadata.yaml").exists()
    # the mcap library reads the file sequentially up to the cut
    msgs = []
    with (bag / "bag.mcap").open("rb") as fh:
        records = StreamReader(fh).records
        with pytest.raises(EndOfFile):
            for rec in records:
                if isinstance(rec, Message):
                    msgs.append(rec)
    assert len(msgs) == 40
    # and so does the project's reader, which flags the bag as cut short
    info = BagInfo(bag, [], False)
    values = [list(decode(t, raw).data) for _, t, _, raw in iter_messages(bag, info=info)]
    assert values[0] == [0.0, 0.0] and values[-1] == [39.0, 0.39]
    assert not info.complete and info.truncated and info.message_count == 40


# ---------------------------------------------------------------------- recorder node
#: Publishes ``n`` messages on /state/soc once the recorder said ready (its readers matched this
#: writer) and this writer matched the recorder's reader; waits until the recorder acknowledged
#: them; with ``stay`` it stays until stopped. Each wait within the budget given (test/waits.py).
PUBLISHER_SCRIPT = textwrap.dedent(
    """
    import signal, sys, time
    import rclpy
    from rclpy.duration import Duration
    from std_msgs.msg import Bool, Float64MultiArray
    from comems4build_ros.ros.interfaces import qos_profile
    from comems4build_ros.wire.contract import load_contract
    n, stay, budget = int(sys.argv[1]), sys.argv[2] == "stay", float(sys.argv[3])
    rclpy.init()
    node = rclpy.create_node("test_publisher")
    contract = load_contract()
    pub = node.create_publisher(Float64MultiArray, "/state/soc", qos_profile(contract.topic("state/soc")))
    ready = []
    node.create_subscription(Bool, "/recorder/ready", lambda m: ready.append(m.data),
                             qos_profile(contract.topic("recorder/ready")))
    end = time.monotonic() + budget
    while not (ready and pub.get_subscription_count() > 0):
        assert time.monotonic() < end, "the recorder not ready within the budget"
        rclpy.spin_once(node, timeout_sec=0.05)
    for k in range(n):
        pub.publish(Float64MultiArray(data=[float(k), k / 10.0]))
    assert pub.wait_for_all_acked(Duration(seconds=budget)), "not acknowledged within the budget"
    print("published", flush=True)
    if stay:
        signal.pause()  # until the test stops it
    node.destroy_node()
    rclpy.shutdown()
    """
)


def _start_recorder(group: ProcessGroup, bag: Path, **params: object) -> subprocess.Popen:
    p = {"bag_path": str(bag), "wait_for_topics": ["state/soc"], "stop_when_done": False, **params}
    return group.start("recorder", "recorder", [*node_command("recorder"), *ros_args("", p)]).proc


def _publish(group: ProcessGroup, n: int, stay: bool = False) -> subprocess.Popen:
    proc = group.start("publisher", "test", [sys.executable, "-c", PUBLISHER_SCRIPT, str(n),
                                             "stay" if stay else "go", str(BUDGET_S)],
                       on_stdout_line=lambda line: None).proc
    return proc


@pytest.mark.ros
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_recorder_records_and_closes_on_signal(tmp_path: Path, sig: signal.Signals) -> None:
    bag = tmp_path / "bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = _start_recorder(group, bag, chunk_period_s=0.1)
        pub = _publish(group, 25)
        assert wait_exit(pub, "the 25 messages published and acknowledged") == 0
        wait_until(lambda: len(iter_messages_safe(bag)) == 25, "the 25 messages in the bag's closed chunks")
        rec.send_signal(sig)
        # stop_when_done false: it records until stopped, a signal is its end
        assert wait_exit(rec, "the recorder closing its bag") == 0
    assert (bag / "metadata.yaml").is_file()
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == "/state/soc"]
        data = [list(reader.deserialize(raw, c.msgtype).data) for c, _, raw in reader.messages(connections=conns)]
        topics = {c.topic for c in reader.connections}
    assert data == [[float(k), k / 10.0] for k in range(25)]
    assert {"/state/soc", "/plant/record", "/ems/command", "/feed/truth", "/clock"} <= topics  # every topic


@pytest.mark.ros
def test_recorder_sigkill_keeps_closed_chunks(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = _start_recorder(group, bag, chunk_period_s=0.2)
        pub = _publish(group, 30, stay=True)
        wait_until(lambda: len(iter_messages_safe(bag)) == 30, "the 30 messages in the bag's closed chunks")
        rec.send_signal(signal.SIGKILL)
        wait_exit(rec, "the recorder killed")
        pub.send_signal(signal.SIGINT)
    assert not (bag / "metadata.yaml").exists()
    expected = [[float(k), k / 10.0] for k in range(30)]
    decoded = []
    with (bag / "bag.mcap").open("rb") as fh:  # the mcap library with the ROS 2 decoder, sequentially
        reader = NonSeekingReader(fh, decoder_factories=[DecoderFactory()])
        with pytest.raises(EndOfFile):
            for _, ch, _, m in reader.iter_decoded_messages(log_time_order=False):
                if ch.topic == "/state/soc":
                    decoded.append(list(m.data))
    assert decoded == expected
    data = [list(decode(t, raw).data) for topic, t, _, raw in iter_messages(bag) if topic == "/state/soc"]
    assert data == expected


def iter_messages_safe(bag: Path) -> list:
    """Messages of the /state/soc topic on disk so far (empty while the file has none)."""
    try:
        return [m for m in iter_messages(bag) if m[0] == "/state/soc"]
    except (FileNotFoundError, ValueError):
        return []


@pytest.mark.ros
def test_recorder_waits_only_briefly_for_optional_ems_info(tmp_path: Path) -> None:
    """No publisher of ems/info (an EMS without step info): ready about 1 s after the others, and said so."""
    bag = tmp_path / "bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        _start_recorder(group, bag, wait_for_topics=["state/soc", "ems/info"], ready_timeout_s=60.0)
        _publish(group, 1, stay=True)
        log = tmp_path / "log" / "recorder.log"
        wait_until(lambda: log_has(log, "optional topics without a publisher after 1 s, recorded if they appear: "
                                        "/ems/info"), "the recorder naming the optional topic")
        wait_until(lambda: log_has(log, "ready: subscribed to every topic"), "the recorder ready")
        assert "no publisher after 60" not in log.read_text()


def test_bag_writer_writes_the_bytes_rosbags_writes(tmp_path: Path) -> None:
    """BagWriter's own MCAP message records: the same records and metadata.yaml as rosbags' Writer.write;
    the channel records differ only by the ``topic_type_hash`` that rosbag2's writer adds."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from comems4build_ros.bags.bag import METADATA_VERSION, qos_for_bag, ros_type_to_bag_type, set_ros_distro

    msgs = [("/state/soc", 1_000 + 7 * k, _array([k, 0.5])) for k in range(50)]
    msgs += [("/plant/step", 5_000 + k, bytes(typestore().serialize_cdr(typestore().types["std_msgs/msg/UInt32"](k),
                                                                        "std_msgs/msg/UInt32"))) for k in range(5)]
    topics = {"/state/soc": ARRAY, "/plant/step": "std_msgs/msg/UInt32"}
    ours = tmp_path / "ours" / "bag"
    ours.parent.mkdir()
    with BagWriter(ours, chunk_max_bytes=1 << 30) as w:
        for t, typ in topics.items():
            w.add_topic(t, typ)
        for topic, t_ns, raw in msgs:
            w.write(topic, t_ns, raw)
    ref = tmp_path / "ref" / "bag"
    ref.parent.mkdir()
    writer = Writer(ref, version=METADATA_VERSION, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns = {t: writer.add_connection(t, ros_type_to_bag_type(typ), typestore=typestore(),
                                      offered_qos_profiles=[qos_for_bag()]) for t, typ in topics.items()}
    for topic, t_ns, raw in msgs:
        writer.write(conns[topic], t_ns, raw)
    writer.close()
    set_ros_distro(ref / "metadata.yaml")
    from mcap.records import (
        Channel,
        ChunkIndex,
        DataEnd,
        Footer,
        MessageIndex,
        MetadataIndex,
        Statistics,
        SummaryOffset,
    )
    from mcap.stream_reader import StreamReader

    def records(path: Path) -> list[object]:
        with (path / "bag.mcap").open("rb") as fh:
            out = []
            for rec in StreamReader(fh).records:
                if isinstance(rec, Channel):
                    assert rec.metadata.pop("topic_type_hash", None) in (None, typestore().hash_rihs01(
                        topics[rec.topic]))
                offsets = (ChunkIndex, MessageIndex, MetadataIndex, SummaryOffset, Footer, DataEnd, Statistics)
                if not isinstance(rec, offsets):
                    out.append(rec)  # offsets and CRCs shift with the longer channel records
            return out

    assert records(ours) == records(ref)
    assert (ours / "metadata.yaml").read_text() == (ref / "metadata.yaml").read_text()


def test_gap_check_of_a_cut_bag_stops_at_each_topics_last_step() -> None:
    """A killed recorder leaves topics cut at different steps (its queues were apart): a cut bag
    is checked per topic up to its own last step; a complete bag up to the last record."""
    from comems4build_ros.bags.evaluation import find_gaps
    from comems4build_ros.wire.contract import load_contract

    contract = load_contract()
    n = 40
    seen = {f"/{t.name}": set(range(n)) for t in contract.topics.values()}
    seen["/feed/solar"] = set(range(20))  # its queue was 20 steps behind at the cut
    seen["/state/soc"] = set(range(n)) - {7}  # a message lost inside the recorded span
    assert find_gaps(contract, "/", n, set(), seen, complete=False) == {"/state/soc": [7]}
    full = find_gaps(contract, "/", n, set(), seen, complete=True)
    assert full == {"/feed/solar": list(range(20, n)), "/state/soc": [7]}


def test_inputs_the_ems_does_not_read_are_not_gaps_when_never_published() -> None:
    """A feed serving the RBC publishes no forecast/*: no message at all on them is no gap for
    an RBC run, a forecast message lost inside the run still is, and every topic the RBC
    reads stays checked."""
    from comems4build_ros.bags.evaluation import find_gaps
    from comems4build_ros.wire.contract import load_contract

    contract = load_contract()
    unread = set(contract.inputs_not_read("rbc_ems"))
    n = 12
    seen = {f"/{t.name}": set(range(n)) for t in contract.topics.values() if t.name not in unread}
    assert find_gaps(contract, "/", n, set(), seen, complete=True, unread=unread) == {}
    assert set(find_gaps(contract, "/", n, set(), seen, complete=True)) == {f"/{t}" for t in unread}
    seen["/forecast/p_pv_w"] = set(range(n)) - {3}
    del seen["/feed/prices"]
    assert find_gaps(contract, "/", n, set(), seen, complete=True, unread=unread) == {
        "/forecast/p_pv_w": [3], "/feed/prices": list(range(n))}


@pytest.mark.ros
def test_recorder_ends_only_when_every_per_step_topic_is_complete(tmp_path: Path) -> None:
    """plant/record complete and no message for done_grace_s is not the end while a topic
    published once a step lacks steps (its writer may still be repairing a delivery);
    EMS topics need every step but the fallback steps. recorder/progress is capped by the
    slowest plant or feed topic, so plant_sim's back-pressure covers every topic."""
    import rclpy

    ctx = rclpy.context.Context()
    with acquire_domain_id() as did:
        rclpy.init(context=ctx, domain_id=did)
        try:
            _check_end_of_run(ctx, tmp_path)
        finally:
            rclpy.try_shutdown(context=ctx)


def _check_end_of_run(ctx: object, tmp_path: Path) -> None:
    import json

    from rclpy.parameter import Parameter

    from comems4build_ros.ros.nodes.recorder import Recorder

    rec = Recorder(context=ctx, namespace="/b", parameter_overrides=[
        Parameter("bag_path", value=str(tmp_path / "bag")), Parameter("done_grace_s", value=0.0),
        Parameter("done_timeout_s", value=3600.0)])
    seen = {c.topic: c for c in rec.per_step["/b"]}
    assert seen["/b/ems/command"].from_ems and not seen["/b/state/soc"].from_ems
    assert "/b/plant/step" in seen and "/b/ems/info" in seen and "/b/plant/events" not in seen
    rec.n_steps["/b"], rec.records["/b"], rec.contiguous["/b"] = 10, 10, 10
    rec.done_at["/b"] = time.monotonic() - 1.0
    info = typestore().types["std_msgs/msg/String"]
    for c in rec.per_step["/b"]:  # the steps as the real messages carry them
        for k in range(10):
            if c.from_ems and k in (3, 4):
                continue  # fallback steps: no command
            if c.topic.endswith("ems/info"):
                raw = bytes(typestore().serialize_cdr(info(data=json.dumps({"step": k, "info": {}})),
                                                      "std_msgs/msg/String"))
            elif c.topic.endswith("plant/step"):
                raw = bytes(typestore().serialize_cdr(typestore().types["std_msgs/msg/UInt32"](data=k),
                                                      "std_msgs/msg/UInt32"))
            else:
                raw = _array([float(k), 0.5])
            c.add(raw)
    prices = seen["/b/feed/prices"]
    prices.steps -= {7, 8, 9}
    for _ in range(3):  # a repeated announcement: step 2 again, not three more steps
        prices.add(_array([2.0, 0.1]))
    prices.add(b"\x00\x01garbage")  # malformed: recorded, not counted
    assert rec.behind() == {"/b/feed/prices": 3, "/b/ems/command": 2, "/b/ems/info": 2}
    for k in range(2):  # two fallback events (plant/events "<step> fallback ...")
        rec._special("/b", "plant/events", bytes(typestore().serialize_cdr(
            info(data=f"{3 + k} fallback no command within 5 s"), "std_msgs/msg/String")))
    assert rec.fallbacks["/b"] == 2 and rec.behind() == {"/b/feed/prices": 3}
    assert rec.progress("/b") == 7
    rec._last_msg_at = rec._last_record_at = time.monotonic() - 1.0
    rec._tick()
    assert not rec.finished.done()  # quiet, every record in, but a topic is short
    for k in (7, 8, 9):
        prices.add(_array([float(k), 0.2]))
    seen["/b/ems/info"].steps.clear()  # a topic never seen (an EMS without step info) is not waited for
    assert rec.behind() == {} and rec.progress("/b") == 10
    late = seen["/b/forecast/t_min_c"]
    late.steps.clear()
    late.add(_array([6.0, 1.0]))  # a topic first seen at step 6 counts from there
    assert rec.progress("/b") == 7
    for k in (7, 8, 9):
        late.add(_array([float(k), 1.0]))
    assert rec.progress("/b") == 10 and rec.behind() == {"/b/forecast/t_min_c": 6}  # steps 0..5 are a gap
    rec._tick()
    assert not rec.finished.done()  # waits (done_timeout_s) in case they still come
    late.steps |= set(range(6))
    rec._tick()
    assert rec.finished.done() and rec.finished.result() == 0
    rec.destroy_node()
