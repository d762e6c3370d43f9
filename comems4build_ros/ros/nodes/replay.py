"""``replay``: publishes the messages of a recorded bag again.

Usage: ``replay BAG [--rate R] [--inputs-only] [--source-namespace NS] [--ros-args ...]``
(or the parameters ``bag_path``, ``rate``, ``inputs_only``, ``source_namespace``,
``lookahead_steps``, ``topic_interval_s``). The bag may be complete or cut short by a SIGKILL of the recorder.

Which messages: those recorded under ``source_namespace`` (default: the node's own
namespace, or the only namespace of the bag), published under the same contract names
in the node's namespace, as recorded (the CDR bytes are published unchanged). The
recorder's own ``recorder/ready`` is never replayed.

Pacing, full replay (default): the recorded receive times are replayed scaled by
``1 / rate``: ``rate = 1`` is real time, ``rate = 10`` ten times faster, ``rate <= 0`` as
fast as possible (at most :data:`BURST` messages per 1 ms timer tick), in every case with
no topic faster than one message per ``topic_interval_s`` (default :data:`TOPIC_INTERVAL_S`,
0.02 s): a simulated run records its steps in milliseconds, and a default subscriber
(``ros2 topic echo``: best effort, or reliable when publishers exist as it starts, keep-last
depth 5) loses messages that come faster than it prints them (measured: 27 of 48 arrived at
full speed); ``topic_interval_s:=0`` takes the limit off (the recorder keeps up with any
pace: its queues are deep). The node says its pace when it starts. The replay
starts once every topic it has messages of has a subscriber (at most
``wait_for_subscribers_s``, default 5 s, then it starts anyway and names the topics nobody
listens to).

Pacing, ``--inputs-only``: only the feed's topics (``feed/*``, ``forecast/*``) are
replayed, so that a plant and another EMS can run against the recorded inputs. Time is
then given by the new closed loop, not by the recording: the node behaves like the feed
and publishes the recorded inputs of steps ``k .. k + lookahead_steps`` when the plant
announces step ``k`` on ``plant/step`` (a repeated announcement makes it publish them
again); ``rate`` does not apply. It exits once the plant has announced the last step.
The recorded messages are grouped by their element 0 (``step``), the first message per
topic and step is used. With a recorder in the new run, give ``wait_for_recorder:=true``
(as the launcher gives the feed): the first inputs are then published only once every
writer of the node has matched the recorder's readers
(:meth:`~comems4build_ros.ros.node.RecorderGate.is_open`); without it, the inputs of
the first steps can reach the EMS but not the recorder, and the new bag has gaps.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future

from comems4build_ros.bags.bag import BagInfo, decode, iter_messages
from comems4build_ros.ros.node import RECORDER_NODE, ContractEndpoints, RecorderGate
from comems4build_ros.ros.package_node import NodeParameters, node_options, sim_time_logger, steady_timer
from comems4build_ros.ros.process import run_node

NODE_NAME = "replay"
#: Messages published at most per timer tick.
BURST = 64
#: Wait for the acknowledgement of the last messages before exiting [s].
ACK_TIMEOUT_S = 5.0
#: Timer period of the full replay [s].
TICK_S = 0.001
#: Default steps published ahead of the plant in --inputs-only mode (as the feed).
LOOKAHEAD_STEPS = 4
#: Default wait for a subscriber on every replayed topic before the full replay starts [s].
WAIT_FOR_SUBSCRIBERS_S = 5.0
#: Wait after every topic has a subscriber, for the subscribers' side of discovery [s].
SETTLE_S = 0.3
#: Default shortest interval between two messages of one topic in a full replay [s]: what a
#: default subscriber (``ros2 topic echo``, keep-last depth 5) keeps up with on a loaded
#: 2-core machine (docs/ros_tools.md "replay node").
TOPIC_INTERVAL_S = 0.02
#: Contract node whose topics --inputs-only replays.
INPUT_ROLE = "feed"
#: Topics never replayed.
SKIP_TOPICS = frozenset({"recorder/ready", "recorder/progress"})


def _split(topic: str, names: set[str]) -> tuple[str, str] | None:
    """``/house_1/feed/truth`` -> (``/house_1``, ``feed/truth``) for a known contract name;
    an absolute contract name (``/clock``) -> (``""``, ``/clock``): it belongs to every namespace."""
    if topic in names and topic.startswith("/"):
        return "", topic
    for name in names:
        if topic == f"/{name}":
            return "/", name
        if topic.endswith(f"/{name}"):
            return topic[: -len(name) - 1], name
    return None


class Replay(Node):
    """Bag replay node (see the module docstring).

    Parameters
    ----------
    cli : the non-ROS arguments (:func:`parse_cli`)
    """

    def __init__(self, cli: argparse.Namespace) -> None:
        super().__init__(NODE_NAME, **node_options({}))
        self.log = sim_time_logger(self)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, NODE_NAME)
        bag_path = self.parameters.param("bag_path", "")
        bag = cli.bag or bag_path
        if not bag:
            raise ValueError(f"node '{NODE_NAME}': give the bag (argument BAG or parameter 'bag_path')")
        rate = self.parameters.param("rate", 1.0)
        self.rate = float(cli.rate if cli.rate is not None else rate)
        inputs_only = self.parameters.param("inputs_only", False)
        self.inputs_only = cli.inputs_only or inputs_only
        self.lookahead = self.parameters.param("lookahead_steps", LOOKAHEAD_STEPS)
        source_ns = self.parameters.param("source_namespace", "")
        wanted_ns = cli.source_namespace or source_ns
        self.wait_s = self.parameters.param("wait_for_subscribers_s", WAIT_FOR_SUBSCRIBERS_S)
        self.gate = RecorderGate(self, self.parameters.param("wait_for_recorder", False),
                                 self.parameters.param("recorder_node", RECORDER_NODE))
        self.settle_s = self.parameters.param("settle_s", SETTLE_S)
        self.topic_interval_s = self.parameters.param("topic_interval_s", TOPIC_INTERVAL_S)
        self._last_out: dict[str, float] = {}  # topic -> when its last message went out [s, monotonic]
        self._t_created = time.monotonic()
        self._matched_at: float | None = None

        contract = self.endpoints.contract
        names = set(contract.topics) - SKIP_TOPICS
        if self.inputs_only:
            names = {t.name for t in contract.published_by(INPUT_ROLE)}
        ns, messages = self._read_bag(bag, names, wanted_ns)
        # every topic of the replayed set gets its publisher, also one without messages
        # (feed/events of a run without input events) or not recorded at all (the inputs the
        # run's EMS did not read): a recorder waits for the publishers of its topics
        self._pubs = {name: self.endpoints.publisher(name) for name in sorted(names)}
        self.published = 0
        self._finishing = False
        self.finished = Future()
        if self.inputs_only:
            self._steps = self._steps_of(messages)
            self.last_step = max(self._steps)
            self._next = 0
            self._last_request = -1
            self.endpoints.subscription("plant/step", self._on_plant_step)
            self.get_logger().info(
                f"inputs-only replay of {bag} ({ns}): steps 0..{self.last_step}, paced by plant/step, "
                f"{self.lookahead} steps ahead"
            )
        else:
            self._messages = messages
            self._replayed = {name for name, _t, _raw in messages}
            self._i = 0
            self._t_first = messages[0][1]
            self._t0: float | None = None
            steady_timer(self, TICK_S, self._tick)
            pace = "as fast as possible" if self.rate <= 0 else f"at {self.rate:g}x the recorded pace"
            limit = (f", at most one message per topic every {self.topic_interval_s:g} s (what a default "
                     "subscriber keeps up with; topic_interval_s:=0 lifts it)" if self.topic_interval_s > 0 else "")
            self.get_logger().info(f"replaying {len(messages)} messages of {bag} ({ns}) {pace}{limit}")

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def _read_bag(self, bag: str, names: set[str], wanted_ns: str) -> tuple[str, list[tuple[str, int, bytes]]]:
        """The namespace to replay and its messages ``(contract name, receive time [ns], raw)`` in
        time order (``/clock`` belongs to every namespace)."""
        by_ns: dict[str, list[tuple[str, int, bytes]]] = {}
        info = BagInfo(Path(bag), [], False)
        for topic, _msgtype, t_ns, raw in iter_messages(bag, info=info):
            hit = _split(topic, names)
            if hit is not None:
                by_ns.setdefault(hit[0], []).append((hit[1], t_ns, bytes(raw)))
        everywhere = by_ns.pop("", [])  # /clock: replayed with whichever namespace is
        if not by_ns:
            raise ValueError(f"bag {bag}: no message on the topics to replay ({', '.join(sorted(names))})")
        if wanted_ns:
            ns = "/" + wanted_ns.strip("/") if wanted_ns.strip("/") else "/"
        elif len(by_ns) == 1:
            ns = next(iter(by_ns))
        else:
            ns = self.get_namespace()
        if ns not in by_ns:
            raise ValueError(
                f"bag {bag}: no recorded namespace '{ns}' (recorded: {', '.join(sorted(by_ns))}); "
                "set 'source_namespace'"
            )
        return ns, sorted(by_ns[ns] + everywhere, key=lambda m: m[1])

    def _steps_of(self, messages: list[tuple[str, int, bytes]]) -> dict[int, list[tuple[str, bytes]]]:
        """--inputs-only: the first message of each topic and step, by step (``feed/info``, not
        one a step, is published once now: transient local)."""
        steps: dict[int, list[tuple[str, bytes]]] = {}
        seen: set[tuple[str, int]] = set()
        for name, _t, raw in messages:
            if not self.endpoints.contract.topic(name).is_array:
                if (name, -1) not in seen:
                    seen.add((name, -1))
                    self._pubs[name].publish(raw)
                continue
            step = int(decode("std_msgs/msg/Float64MultiArray", raw).data[0])
            if (name, step) not in seen:
                seen.add((name, step))
                steps.setdefault(step, []).append((name, raw))
        return steps

    # ------------------------------------------------------------------ full replay
    def _tick(self) -> None:
        if self._i >= len(self._messages) or self.finished.done():
            return
        now = time.monotonic()
        if self._t0 is None:
            if not self._subscribers_ready(now):
                return
            self._t0 = now
        n = 0
        while self._i < len(self._messages):
            name, t_ns, raw = self._messages[self._i]
            if self.rate > 0 and self._t0 + (t_ns - self._t_first) / 1e9 / self.rate > now:
                break
            if now - self._last_out.get(name, -1e9) < self.topic_interval_s:
                break  # the recorded order is kept: the next message waits for its topic's interval
            self._last_out[name] = now
            self._pubs[name].publish(raw)
            self._i += 1
            self.published += 1
            n += 1
            if n >= BURST:
                break
        if self._i >= len(self._messages) and not self._finishing:
            self._finishing = True
            self._wait_acks()
            self.get_logger().info(f"replay done: {self.published} messages; exiting once the recorder has left")
            self.gate.finish_when_recorded(self.finished, next(iter(self._pubs)))

    def _subscribers_ready(self, now: float) -> bool:
        """Every topic with messages to replay has a subscriber (plus ``settle_s``), or
        ``wait_for_subscribers_s`` passed."""
        pubs = [(n, p) for n, p in self._pubs.items() if n in self._replayed]
        if now - self._t_created > self.wait_s:
            missing = [n for n, p in pubs if p.get_subscription_count() == 0]
            if missing:
                self.get_logger().warning(f"no subscriber after {self.wait_s} s on: {', '.join(missing)}")
            return True
        if any(p.get_subscription_count() == 0 for _n, p in pubs):
            self._matched_at = None
            return False
        if self._matched_at is None:
            self._matched_at = now
        return now - self._matched_at >= self.settle_s

    def _wait_acks(self) -> None:
        for pub in self._pubs.values():
            pub.wait_for_all_acked(Duration(nanoseconds=int(ACK_TIMEOUT_S * 1e9)))

    # ------------------------------------------------------------------ inputs only
    def _on_plant_step(self, msg: Any) -> None:
        if not self.gate.is_open():  # not yet: answered once the gate opens
            self.gate.when_open(lambda: self._on_plant_step(msg))
            return
        k = int(msg.data)
        last = min(k + self.lookahead, self.last_step)
        first = k if k <= self._last_request else max(self._next, k)
        for j in range(first, last + 1):
            for name, raw in self._steps.get(j, ()):
                self._pubs[name].publish(raw)
                self.published += 1
        self._next = max(self._next, last + 1)
        self._last_request = max(self._last_request, k)
        if k >= self.last_step and not self._finishing:
            self._finishing = True
            self._wait_acks()
            self.get_logger().info(f"inputs-only replay done: plant at step {k}, {self.published} messages; "
                                   "exiting once the recorder has left")
            self.gate.finish_when_recorded(self.finished, next(iter(self._pubs)))


def parse_cli(argv: list[str]) -> argparse.Namespace:
    """The non-ROS arguments of ``replay``."""
    parser = argparse.ArgumentParser(prog="replay", description=__doc__.splitlines()[0])
    parser.add_argument("bag", nargs="?", default=None, help="rosbag2 directory or .mcap file")
    parser.add_argument("--rate", type=float, default=None, help="1 = real time, 10 = 10x, 0 = as fast as possible")
    parser.add_argument("--inputs-only", action="store_true", help="replay only the feed topics, paced by the plant")
    parser.add_argument("--source-namespace", default=None, help="namespace of the bag to replay (multi-house)")
    return parser.parse_args(argv)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``replay`` (``ros2 run comems4build_ros replay BAG --rate 0``)."""
    from rclpy.utilities import remove_ros_args

    argv = list(sys.argv if args is None else args)
    cli = parse_cli(remove_ros_args(argv)[1:])
    return run_node(lambda: Replay(cli), argv, NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
