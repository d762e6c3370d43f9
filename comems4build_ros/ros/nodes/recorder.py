"""``recorder``: records every topic of the contract to a rosbag2 directory with MCAP storage.

For each namespace of the parameter ``namespaces`` (default: the node's own namespace)
the node subscribes to every topic of ``msg_defs/topics.yaml`` with ``raw=True`` and
writes the CDR bytes unchanged, stamped with the receive time [ns since the epoch] (as
``ros2 bag record`` does), through :class:`comems4build_ros.bags.bag.BagWriter`: rosbags
0.11.9, metadata version 8 (what Jazzy's ``ros2 bag info`` reads), Jazzy typestore.

Crash safety: the pending MCAP chunk is written out and flushed when it is
``chunk_period_s`` old (default 1 s) or holds ``chunk_max_bytes`` (256 KiB); after a
SIGKILL the ``.mcap`` file holds everything up to the last written chunk (no summary
section and no ``metadata.yaml``; ``comems4build evaluate`` reads such a bag directly
from the ``.mcap`` file). SIGINT and SIGTERM close the bag cleanly.

Readiness: once every subscription has matched a publisher (for the topics of
``wait_for_topics``, default all topics published by plant_sim, feed and the EMS) and
``settle_s`` more seconds have passed (and, for the optional ``ems/info``, at most
``optional_wait_s`` = 1 s more; it is recorded if it appears later), the node publishes
``recorder/ready`` = true (transient local) in every namespace; ``plant_sim`` with ``wait_for_recorder`` starts only
then, so the first step is recorded. After ``ready_timeout_s`` it declares ready anyway
and names the topics without a publisher.

End of run: with ``stop_when_done`` (default) the node closes the bag and exits once
``plant/done`` (or the last ``plant/record``) arrived from every namespace, every ``plant/record`` of the run
(``n_steps`` from ``feed/truth``) is in, every other topic published once a step has every
step (EMS topics: every step without a fallback; the bridge's state topics: every step
without a ``withheld`` event, :data:`~comems4build_ros.bags.evaluation.WITHHELD_EVENT`;
:meth:`Recorder.behind`), and no message
of any topic has come for
``done_grace_s`` (its queues are drained; late ``ems/info`` of the last step); once done
and ``done_timeout_s`` without any message, it stops even if some records are missing,
with a warning.

Back-pressure: per namespace the node publishes ``recorder/progress``, the number of
steps whose ``plant/record`` it has written without a gap, capped by the steps recorded of
every plant and feed topic published once a step (every 16 steps and every tick);
``plant_sim`` announces no step more than ``record_window_steps`` (256) beyond it, and
every topic's keep-last depth (1000) exceeds that window, so a slow recorder slows the
run down instead of losing messages.

Progress: with ``progress_period_s`` > 0 the node prints ``progress <recorded> <total>``
lines on stdout (plant/record messages recorded, steps of all namespaces; total 0 until
known), read by ``comems4build launch``.

The bag directory gets mode 0700: every ``ems/command`` in it carries the run token.

Topics of ``skip_topics`` (contract names; the launcher lists the feed topics the run's
EMS does not read, which its feed does not publish) are not recorded: no subscription,
no channel.

What the recorder follows (parameter ``follows``): ``plant`` (default) records the houses of
``namespaces``: every topic of a house (the contract's scopes ``house`` and
``community_house``, the latter only in a community run and never waited for), its run
known by ``plant/record``, ``feed/truth`` (the steps) and ``plant/done``. ``coordinator``
records the coordinator of a community (docs/community.md "Over ROS") in its namespace:
the topics of scope ``coordinator``, its run known by ``hub/record`` (each row names the
steps) and ``hub/done``; back-pressure and progress as for a plant, on ``hub/record``.

Other parameters: ``tick_s`` (housekeeping timer period, default 0.05 s), ``bag_path``
(directory to create, required), ``run_info`` (JSON string, stored as ``run_info.json`` in
the bag directory and as ``custom_data`` entry ``comems4build.run_info`` of ``metadata.yaml``)
and ``run_id`` (the run's id, added to it as ``run_id``: the feed names it on ``feed/info``, and
evaluate refuses a bag whose records name another run).
``settle_s``, ``ready_timeout_s``, ``optional_wait_s``, ``done_grace_s``,
``done_timeout_s``, ``progress_period_s`` and ``tick_s`` may change during a run (``ros2
param set``); the others are read-only.

Names: every channel of the bag has its contract name under its namespace (``/clock`` once),
whatever a remapping makes of the topic the subscription reads (``-r
/house_0/ems/command:=/house_0/ctrl/setpoints`` records the commands read from
``ctrl/setpoints`` as ``/house_0/ems/command``), so the bag evaluates the same in any naming
scheme; the node's first log line lists the remapped topics.

Time: each message is stamped with its receive time, or with ``use_sim_time`` true with the
node's ROS time, the simulated time of ``/clock`` (as ``ros2 bag record --use-sim-time``);
messages before the node has a time get the first one it has: the start of the run's
first step, or its end when ROS 2's time source (a best-effort reader of depth 1) kept only
the later of two early ticks.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, UInt32

from comems4build_ros.bags.bag import BagWriter, decode, qos_for_bag
from comems4build_ros.bags.evaluation import RECORD_TOPIC, STEP_TOPIC, TRUTH_TOPIC, is_per_step, withheld_topics
from comems4build_ros.ros.interfaces import message_class, qos_profile
from comems4build_ros.ros.node import FINISHED_LOCAL_RECORDERS, no_default_event_callbacks
from comems4build_ros.ros.package_node import NodeParameters, node_options, sim_time_logger, steady_timer
from comems4build_ros.ros.process import run_node
from comems4build_ros.wire.cdr import array_step, parse_array, uint32_value
from comems4build_ros.wire.contract import (
    EVENTS_TOPIC,
    WITHHELD_EVENT,
    Contract,
    event_step_kind,
    load_contract,
    resolve,
)

NODE_NAME = "recorder"
#: History depth of every recording subscription: how many messages per topic may queue
#: while the recorder is busy (the publishers' own depths are 10..1000).
RECORD_DEPTH = 100_000
#: Default wait between "every topic matched" and "ready" for the publishers' side of
#: discovery to complete [s]. Short: a node started with ``wait_for_recorder`` holds its
#: first message until its own writers matched the recorder's readers anyway
#: (:meth:`~comems4build_ros.ros.node.RecorderGate.is_open`).
SETTLE_S = 0.1
#: Default limit on the wait for publishers [s].
READY_TIMEOUT_S = 60.0
#: Default wait for late messages after the last record [s]; the end of a run also waits
#: until every topic published once a step has every step (:meth:`Recorder.behind`).
DONE_GRACE_S = 0.1
#: Default limit on the wait for missing records once every plant is done [s].
DONE_TIMEOUT_S = 10.0
#: Default period of the housekeeping timer (chunk age, readiness, end of run, progress;
#: parameter ``tick_s``) [s].
TICK_S = 0.05
#: Contract roles whose topics the recorder waits for by default.
WAIT_ROLES = ("plant", "feed", "ems")
#: custom_data key of metadata.yaml holding the run information.
RUN_INFO_KEY = "comems4build.run_info"
RUN_INFO_FILE = "run_info.json"
DONE_TOPIC = "plant/done"
PROGRESS_TOPIC = "recorder/progress"
#: recorder/progress is published when the gap-free record count grew by this many steps
#: (and at every housekeeping tick) [steps].
PROGRESS_EVERY_STEPS = 16
#: Topics a run may lack (an EMS without step_info publishes no ems/info): the recorder
#: waits for their publishers only ``optional_wait_s`` after the others matched.
OPTIONAL_TOPICS = frozenset({"ems/info"})
#: Default of ``optional_wait_s`` [s].
OPTIONAL_WAIT_S = 1.0


class StepsSeen:
    """Steps recorded so far of one topic published once a step.

    Counted by step, not by message: plant_sim repeats its announcement while it waits
    (and the feed and EMS answer it again), so a topic can carry a step twice.
    """

    __slots__ = ("topic", "from_ems", "withheld", "step_of", "steps", "first")

    def __init__(self, topic: str, from_ems: bool, step_of: Callable[[bytes], int], withheld: bool = False) -> None:
        self.topic = topic
        self.from_ems = from_ems  # no message is expected at a fallback step
        self.withheld = withheld  # ... nor at a step whose state was withheld (wire.contract.WITHHELD_EVENT)
        self.step_of = step_of
        self.steps: set[int] = set()
        self.first = 0  # first step seen: a topic that starts late does not hold the progress back

    def add(self, raw: bytes) -> None:
        """Note the step of one message (a malformed one is recorded, not counted)."""
        try:
            k = self.step_of(raw)
        except (ValueError, KeyError, TypeError):
            return
        if not self.steps:
            self.first = k
        self.steps.add(k)


def _info_step(raw: bytes) -> int:
    """``step`` of an ``ems/info`` JSON string."""
    try:
        return int(json.loads(decode("std_msgs/msg/String", raw).data)["step"])
    except Exception as exc:  # noqa: BLE001 - anything malformed is "no step"
        raise ValueError(f"ems/info without a step: {exc}") from None


#: What a recorder follows (parameter ``follows``) -> (the contract scopes it records, the topic
#: of one record per step, the topic and label that give the run's steps, the end-of-run topic,
#: the roles whose topics it waits for).
FOLLOWS: dict[str, tuple[tuple[str, ...], str, str, str, str, tuple[str, ...]]] = {
    "plant": (("house", "community_house"), RECORD_TOPIC, TRUTH_TOPIC, "n_steps", DONE_TOPIC, WAIT_ROLES),
    "coordinator": (("coordinator",), "hub/record", "hub/record", "n_steps", "hub/done", ("coordinator",)),
}


def default_wait_topics(contract: Contract, follows: str = "plant") -> list[str]:
    """Topics with a publisher of the roles the recorder waits for (a plant's run: plant, feed and
    EMS), in the scope every such run has (``house``; a coordinator's: ``coordinator``)."""
    roles = {n.name: n.role for n in contract.nodes.values()}
    scope = "house" if follows == "plant" else "coordinator"
    wait_roles = FOLLOWS[follows][5]
    return [t.name for t in contract.topics.values()
            if t.scope == scope and any(roles.get(p) in wait_roles for p in t.publishers)]


class Recorder(Node):
    """Bag recorder node (see the module docstring)."""

    def __init__(self, **node_kwargs: Any) -> None:
        """``node_kwargs`` (e.g. ``namespace``, ``parameter_overrides``) go to ``rclpy.node.Node``."""
        from rclpy.task import Future

        super().__init__(NODE_NAME, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.parameters = NodeParameters(self)
        self.contract = load_contract()
        self.contract.node(NODE_NAME)
        bag_path, wait, info_obj, chunks = self._read_parameters()
        self.writer = self._open_bag(bag_path, info_obj, chunks)
        self.records = dict.fromkeys(self.namespaces, 0)
        # Steps recorded of each topic published once a step (what the bag's gap check
        # expects): the end of the run waits until each topic seen has every step (EMS
        # topics: every step without a fallback), not only plant/record.
        self.per_step: dict[str, list[StepsSeen]] = {ns: [] for ns in self.namespaces}
        self.fallbacks = dict.fromkeys(self.namespaces, 0)
        self.withheld = dict.fromkeys(self.namespaces, 0)  # steps without state by design (WITHHELD_EVENT)
        self.n_steps: dict[str, int] = {}
        self.done_at: dict[str, float] = {}
        self._subs: list[tuple[str, Any]] = []  # (full topic, subscription) of the wait list
        self._optional: list[tuple[str, Any]] = []  # ... of the optional topics of the wait list
        self._pending_sim: list[tuple[str, int, bytes]] = []  # use_sim_time: messages before the first /clock
        remapped = self._subscribe(wait)
        self._create_publishers()
        self.contiguous = dict.fromkeys(self.namespaces, 0)  # steps 0..c-1 of plant/record written
        self._ahead: dict[str, set[int]] = {ns: set() for ns in self.namespaces}
        self._published_progress = dict.fromkeys(self.namespaces, -1)
        self._progress_msg = UInt32()
        self.ready = False
        self._t0 = time.monotonic()
        self._matched_at: float | None = None
        self._last_record_at = self._t0
        self._last_msg_at = self._t0  # last message of any topic (end of run: the queues are drained)
        self._t_progress = 0.0
        self.finished = Future()
        self._tick_timer = steady_timer(self, self.tick_s, self._tick)
        self.get_logger().info(
            f"recording {len(self.contract.topics)} topics x {len(self.namespaces)} namespace(s) to {bag_path}"
            + (f"; remapped: {', '.join(f'{a} -> {b}' for a, b in remapped)}" if remapped else "")
        )

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def _read_parameters(self) -> tuple[str, list[str], Any, tuple[float, int]]:
        """Declare and read every parameter: the bag path, the topics to wait for, the run
        information (parsed) and the chunk limits; the others become attributes (those of the
        end of the run and the progress lines may change during a run)."""
        bag_path = self.bag_path = self.parameters.param("bag_path", "")
        if not bag_path:
            raise ValueError(f"node '{NODE_NAME}': parameter 'bag_path' (bag directory to create) is required")
        namespaces = self.parameters.string_list("namespaces") or [self.get_namespace()]
        self.namespaces = ["/" + ns.strip("/") if ns.strip("/") else "/" for ns in namespaces]
        if len(set(self.namespaces)) != len(self.namespaces):
            raise ValueError(f"node '{NODE_NAME}': parameter 'namespaces' lists a namespace twice: {namespaces}")
        self.follows = self.parameters.param("follows", "plant")
        if self.follows not in FOLLOWS:
            raise ValueError(f"node '{NODE_NAME}': parameter 'follows': '{self.follows}' is not one of "
                             f"{', '.join(FOLLOWS)}")
        (self.scopes, self.record_topic, self.steps_topic, steps_label, self.done_topic,
         _roles) = FOLLOWS[self.follows]
        self._steps_index = self.contract.topic(self.steps_topic).layout({}).index[steps_label]
        wait = self.parameters.param("wait_for_topics", ["*"])
        if wait == ["*"]:
            wait = default_wait_topics(self.contract, self.follows)
        # Topics a run does not publish (the feed serving one EMS leaves out what it does
        # not read, the clock of another house): no subscription, no channel in the bag, no
        # wait for a publisher.
        self.skip = set(self.parameters.string_list("skip_topics"))
        for t in (*wait, *sorted(self.skip)):
            self.contract.topic(t)  # ContractError names an unknown topic
        wait = [t for t in wait if t not in self.skip]

        def setter(name: str) -> Any:
            return lambda value: setattr(self, name, value)

        for name, default in (("settle_s", SETTLE_S), ("ready_timeout_s", READY_TIMEOUT_S),
                              ("optional_wait_s", OPTIONAL_WAIT_S), ("done_grace_s", DONE_GRACE_S),
                              ("done_timeout_s", DONE_TIMEOUT_S), ("progress_period_s", 0.0)):
            setattr(self, name, self.parameters.param(name, default, on_change=setter(name)))
        self.stop_when_done = self.parameters.param("stop_when_done", True)
        self.tick_s = self.parameters.param("tick_s", TICK_S, on_change=self._set_tick)
        run_info = self.parameters.param("run_info", "")
        info_obj: Any = None
        if run_info:
            try:
                info_obj = json.loads(run_info)
            except json.JSONDecodeError as exc:
                raise ValueError(f"node '{NODE_NAME}': parameter 'run_info' is not JSON: {exc}") from None
        run_id = self.parameters.param("run_id", "")
        if run_id:  # the run's id beside its description: evaluate refuses records of another run by it
            if info_obj is not None and not isinstance(info_obj, dict):
                raise ValueError(f"node '{NODE_NAME}': parameter 'run_info' is not a JSON object (with 'run_id')")
            info_obj = {**(info_obj or {}), "run_id": run_id}
        chunks = (self.parameters.param("chunk_period_s", 1.0), self.parameters.param("chunk_max_bytes", 256 * 1024))
        return bag_path, wait, info_obj, chunks

    def _set_tick(self, value: float) -> None:
        self.tick_s = value
        self._tick_timer.timer_period_ns = int(value * 1e9)

    def _open_bag(self, bag_path: str, info_obj: Any, chunks: tuple[float, int]) -> BagWriter:
        """Create the bag (mode 0700: every ``ems/command`` in it carries the run token,
        tokens.py) with the run information, before the first message comes."""
        writer = BagWriter(bag_path, chunk_period_s=chunks[0], chunk_max_bytes=chunks[1])
        os.chmod(bag_path, 0o700)
        if info_obj is not None:
            (Path(bag_path) / RUN_INFO_FILE).write_text(json.dumps(info_obj, indent=2) + "\n", encoding="utf-8")
            writer.set_custom_data(RUN_INFO_KEY, json.dumps(info_obj, separators=(",", ":")))
        return writer

    def _subscribe(self, wait: list[str]) -> list[tuple[str, str]]:
        """One recording subscription per contract topic and namespace (``/clock`` once: it is
        the same in every namespace), each written under its contract name; returns the
        ``(contract name, name it reads)`` pairs a remapping changed."""
        no_state = withheld_topics(self.contract)
        roles = {n.name: n.role for n in self.contract.nodes.values()}
        remapped: list[tuple[str, str]] = []
        seen: set[str] = set()
        for ns in self.namespaces:
            for spec in self.contract.topics.values():
                full = resolve(ns, spec.name)
                if spec.name in self.skip or full in seen or spec.scope not in self.scopes:
                    continue
                seen.add(full)
                self.writer.add_topic(full, spec.type, self._bag_qos(spec.qos))
                holder: list[Any] = []
                counter = None
                if is_per_step(spec):
                    step_of = array_step if spec.is_array else uint32_value if spec.name == STEP_TOPIC else _info_step
                    counter = StepsSeen(full, any(roles.get(p) == "ems" for p in spec.publishers), step_of,
                                        spec.name in no_state)
                    self.per_step[ns].append(counter)
                sub = self.create_subscription(
                    message_class(spec), full, self._callback(ns, spec.name, full, holder, counter),
                    self._record_qos(spec.qos),
                    raw=True, event_callbacks=no_default_event_callbacks("subscription"),
                )
                holder.append(sub)
                if sub.topic_name != full:
                    remapped.append((full, sub.topic_name))
                if spec.name in wait:
                    (self._optional if spec.name in OPTIONAL_TOPICS else self._subs).append((full, sub))
        return remapped

    def _create_publishers(self) -> None:
        """``recorder/ready`` and ``recorder/progress`` of every namespace recorded."""
        self._ready_pubs = []
        self._progress_pubs: dict[str, Any] = {}
        ready_spec = self.contract.topic("recorder/ready")
        progress_spec = self.contract.topic(PROGRESS_TOPIC)
        for ns in self.namespaces:
            self._ready_pubs.append(
                self.create_publisher(message_class(ready_spec), resolve(ns, ready_spec.name), qos_profile(ready_spec))
            )
            self._progress_pubs[ns] = self.create_publisher(
                message_class(progress_spec), resolve(ns, PROGRESS_TOPIC), qos_profile(progress_spec)
            )

    # ------------------------------------------------------------------ qos
    @staticmethod
    def _record_qos(spec: Any) -> QoSProfile:
        """Subscription QoS: the contract's reliability and durability, a deep history."""
        return QoSProfile(
            reliability=ReliabilityPolicy.RELIABLE if spec.reliability == "reliable" else ReliabilityPolicy.BEST_EFFORT,
            history=HistoryPolicy.KEEP_LAST,
            depth=RECORD_DEPTH,
            durability=(
                DurabilityPolicy.TRANSIENT_LOCAL if spec.durability == "transient_local" else DurabilityPolicy.VOLATILE
            ),
        )

    @staticmethod
    def _bag_qos(spec: Any) -> Any:
        return qos_for_bag(spec.reliability == "reliable", spec.durability == "transient_local", spec.depth)

    # ------------------------------------------------------------------ callbacks
    def _callback(self, ns: str, name: str, full: str, holder: list[Any], counter: StepsSeen | None) -> Any:
        """Callback of one subscription: write the message (note its step in ``counter``), then
        drain the queue.

        The executor wakes up once per message it hands over; taking every queued
        message of the topic in one go (``Subscription.handle.take_message``, what the
        executor itself calls) costs one wake-up per burst instead of one per message.
        The receive time is the middleware's ``received_timestamp`` [ns since the epoch].
        """
        write = self.writer.write
        special = name in (self.record_topic, self.steps_topic, self.done_topic, EVENTS_TOPIC)

        def on_msg(raw: bytes, info: Any) -> None:
            while True:
                t_ns = info.get("received_timestamp") or time.time_ns()
                if self.parameters.sim_time:
                    self._write_sim(full, t_ns, raw)
                else:
                    write(full, t_ns, raw)
                if counter is not None:
                    counter.add(raw)
                if special:
                    self._special(ns, name, raw)
                sub = holder[0]
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, True)
                if taken is None:
                    self._last_msg_at = time.monotonic()
                    return
                raw, info = taken

        return on_msg

    def _write_sim(self, full: str, received_ns: int, raw: bytes) -> None:
        """With ``use_sim_time``: write the message stamped with the node's simulated time (as
        ``ros2 bag record --use-sim-time``); one that comes before the node has a time waits for
        the first and gets it (see the module docstring)."""
        t_ns = self.get_clock().now().nanoseconds
        if t_ns <= 0:
            self._pending_sim.append((full, received_ns, raw))
            return
        self._flush_sim(t_ns)
        self.writer.write(full, t_ns, raw)

    def _flush_sim(self, t_ns: int | None) -> None:
        """Write the messages held for the first ``/clock`` at ``t_ns`` (None: at their receive
        time, when the bag closes without any clock)."""
        pending, self._pending_sim = self._pending_sim, []
        for full, received_ns, raw in pending:
            self.writer.write(full, received_ns if t_ns is None else t_ns, raw)

    def _special(self, ns: str, name: str, raw: bytes) -> None:
        """Progress and end-of-run bookkeeping from plant/record, feed/truth, plant/done (a
        coordinator's: hub/record, which also gives the steps, and hub/done)."""
        if name == self.steps_topic and ns not in self.n_steps:
            self.n_steps[ns] = int(parse_array(raw)[self._steps_index])
        if name == self.record_topic:
            self.records[ns] += 1
            step = int(parse_array(raw)[0])
            if step == self.contiguous[ns]:
                c = step + 1
                ahead = self._ahead[ns]
                while c in ahead:
                    ahead.discard(c)
                    c += 1
                self.contiguous[ns] = c
                if c - self._published_progress[ns] >= PROGRESS_EVERY_STEPS:
                    self._publish_progress(ns, PROGRESS_EVERY_STEPS)  # one message per 16 steps
            elif step > self.contiguous[ns]:
                self._ahead[ns].add(step)
            self._last_record_at = time.monotonic()
            if ns not in self.done_at and self.records[ns] >= self.n_steps.get(ns, -1) > 0:
                self.done_at[ns] = self._last_record_at  # every record in: done even if plant/done is lost
        elif name == self.done_topic and decode("std_msgs/msg/Bool", raw).data and ns not in self.done_at:
            self.done_at[ns] = time.monotonic()
        elif name == EVENTS_TOPIC:
            step_kind = event_step_kind(str(decode("std_msgs/msg/String", raw).data))
            if step_kind is not None and step_kind[1] == "fallback":
                self.fallbacks[ns] += 1
            elif step_kind is not None and step_kind[1] == WITHHELD_EVENT:
                self.withheld[ns] += 1

    def behind(self) -> dict[str, int]:
        """Per-step topics seen so far that lack messages of the run's steps -> how many.

        A reliable writer can hold back samples for seconds (a full shared-memory port or
        a retransmission waits for the next heartbeat) while plant/record is complete:
        measured, 4 houses in one recorder process closed their bags up to 820 steps
        short on some topics when the end of the run was "every record in and 0.3 s
        without a message".
        """
        out: dict[str, int] = {}
        for ns in self.namespaces:
            n = self.n_steps.get(ns, 0)
            for c in self.per_step[ns]:
                need = n - (self.fallbacks[ns] if c.from_ems else 0) - (self.withheld[ns] if c.withheld else 0)
                if 0 < len(c.steps) < need:
                    out[c.topic] = need - len(c.steps)
        return out

    # ------------------------------------------------------------------ housekeeping
    def progress(self, ns: str) -> int:
        """Steps of ``ns`` written: plant/record without a gap, and no plant or feed topic
        (per step, seen so far) with fewer messages (each writer's samples come in order)."""
        held = self.withheld[ns]
        return min([self.contiguous[ns], *(c.first + len(c.steps) + (held if c.withheld else 0)
                                           for c in self.per_step[ns] if c.steps and not c.from_ems)])

    def _publish_progress(self, ns: str, every: int = 1) -> None:
        """``recorder/progress`` of ``ns`` (:meth:`progress`; plant_sim's back-pressure) if it
        grew by ``every`` steps since the last one published."""
        value = self.progress(ns)
        if value - self._published_progress[ns] < every:
            return
        self._progress_msg.data = value
        self._progress_pubs[ns].publish(self._progress_msg)
        self._published_progress[ns] = value

    def _tick(self) -> None:
        now = time.monotonic()
        self.writer.tick()
        for ns in self.namespaces:
            self._publish_progress(ns)
        if not self.ready:
            self._check_ready(now)
        if self.progress_period_s > 0 and now - self._t_progress >= self.progress_period_s:
            self._t_progress = now
            self.print_progress()
        if self.stop_when_done and len(self.done_at) == len(self.namespaces) and not self.finished.done():
            complete = all(self.records[ns] >= self.n_steps.get(ns, 0) for ns in self.namespaces)
            first_done = min(self.done_at.values())
            # quiet: no message of any topic for done_grace_s. Every plant/record in does not
            # mean every other topic is: under load the recorder's queues of the feed's and
            # the EMS's topics can be hundreds of steps behind (their writers stay until the
            # recorder has left, so waiting for them loses nothing)
            last = max(max(self.done_at.values()), self._last_record_at, self._last_msg_at)
            quiet = now - last >= self.done_grace_s
            behind = self.behind() if complete else {}
            if (complete and quiet and not behind) or now - max(first_done, self._last_msg_at) > self.done_timeout_s:
                if not complete:
                    missing = {ns: self.n_steps.get(ns, 0) - self.records[ns] for ns in self.namespaces}
                    self.get_logger().warning(f"stopping with plant/record messages missing: {missing}")
                if behind:
                    self.get_logger().warning(f"stopping {self.done_timeout_s:g} s after the last message with "
                                              f"messages missing: {behind}")
                self.print_progress()
                self.get_logger().info(f"every plant is done: {self.writer.message_count} messages recorded")
                FINISHED_LOCAL_RECORDERS.add((self.get_namespace(), self.get_name()))
                self.finished.set_result(0)

    def _check_ready(self, now: float) -> None:
        unmatched = [full for full, sub in self._subs if sub.get_publisher_count() == 0]
        optional = [full for full, sub in self._optional if sub.get_publisher_count() == 0]
        if unmatched:
            self._matched_at = None
            if now - self._t0 > self.ready_timeout_s:
                self.get_logger().warning(
                    f"no publisher after {self.ready_timeout_s} s on: {', '.join(unmatched)}; recording anyway"
                )
                self._declare_ready()
            return
        if self._matched_at is None:
            self._matched_at = now
        if now - self._matched_at < self.settle_s:
            return
        if optional and now - self._matched_at < self.settle_s + self.optional_wait_s:
            return
        if optional:
            self.get_logger().info(
                f"optional topics without a publisher after {self.optional_wait_s:g} s, recorded if they appear: "
                + ", ".join(optional)
            )
        self._declare_ready()

    def _declare_ready(self) -> None:
        self.ready = True
        msg = Bool(data=True)
        for pub in self._ready_pubs:
            pub.publish(msg)
        self.get_logger().info("ready: subscribed to every topic")

    def print_progress(self) -> None:
        """``progress <plant/record messages> <steps of the run, 0 = unknown>`` on stdout."""
        total = sum(self.n_steps.values()) if len(self.n_steps) == len(self.namespaces) else 0
        print(f"progress {sum(self.records.values())} {total}", flush=True)

    @property
    def run_complete(self) -> bool:
        """Every plant is done (or the bag is complete), or the node records until it is
        stopped (``stop_when_done`` false, as ``ros2 bag record``): a signal from now on
        closes the bag as a normal end (exit 0, :func:`comems4build_ros.ros.process.run_complete`)."""
        return not self.stop_when_done or self.finished.done() or len(self.done_at) == len(self.namespaces)

    def destroy_node(self) -> None:
        """Close the bag (last chunk, summary, metadata.yaml), then destroy the node.

        A bag that cannot be closed (the disk full, the file system read-only) raises the
        ``OSError`` naming the bag after the node is destroyed (the process then ends with
        exit code 5 naming it); what was written stays readable (``evaluate`` salvages it).
        """
        try:
            self._flush_sim(None)
            self.writer.close()
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror or str(exc), exc.filename or self.bag_path) from None
        finally:
            super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``recorder`` (``ros2 run comems4build_ros recorder``)."""
    return run_node(Recorder, args, NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
