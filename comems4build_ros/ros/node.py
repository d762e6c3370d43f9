"""What a node of the contract composes: endpoints checked against the contract, the waits for the recorder.

* :class:`ContractEndpoints`: the node's publishers and subscriptions of the topic contract
  (``msg_defs/topics.yaml``), each refused unless the contract declares it for the node's
  role, so a node cannot quietly publish or read something outside its row of
  ``tab:level_of_information``; :meth:`ContractEndpoints.publisher` and
  :meth:`ContractEndpoints.subscription` take the type and QoS from the contract. The check
  is on what an endpoint is, not on the name it ends up with: the node's contract role (the
  node name its class gives, whatever ``-r __node:=`` makes of it), the contract topic the
  code asks for (before ``-r from:=to`` remapping, so a topic can be moved into any naming
  scheme), the message type and the QoS (a publisher's must be the contract's; a
  subscription's must match it: ROS 2's time source reads ``/clock`` best effort).
* :class:`RecorderGate`: the two waits a recorded run needs: the first publication until the
  node's writers matched the recorder (:meth:`RecorderGate.is_open`), and the end of the node
  until the recorder has left (:meth:`RecorderGate.finish_when_recorded`).
* :class:`RunEnd`: what a node that ends with the run (feed, EMS) knows of its end.
* :class:`ArrayPublisher` publishes one contract array topic in its layout order, as ready
  CDR bytes (:mod:`comems4build_ros.wire.cdr`).
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node

from comems4build_ros.core.config import PlantParams
from comems4build_ros.ros.interfaces import message_class, qos_profile
from comems4build_ros.ros.package_node import steady_timer
from comems4build_ros.wire.cdr import cdr_prefix
from comems4build_ros.wire.contract import Contract, ContractError, Layout, load_contract, relative, resolve, sizes

#: Topics rclpy itself creates for every node (parameter events, logging); not in the contract.
INFRASTRUCTURE_TOPICS = frozenset({"/parameter_events", "/rosout"})

#: Longest wait of a finished node for the recorder to leave [s] (RecorderGate.finish_when_recorded).
LINGER_S = 30.0
#: Period of that check [s].
LINGER_CHECK_S = 0.05
#: Node name of the recorder in the contract.
RECORDER_NODE = "recorder"
#: Longest hold of a node's first publication for its writers to match the recorder [s].
RECORDER_GATE_TIMEOUT_S = 30.0
#: Period of the check for an answer held back by the closed gate (:meth:`RecorderGate.when_open`) [s].
GATE_POLL_S = 0.01
#: ``(namespace, name)`` of the recorder nodes of this process that have closed their run
#: (every message taken). In a container process (:mod:`comems4build_ros.ros.container`) such a
#: recorder stays in the graph until the process ends; the nodes beside it need not wait.
FINISHED_LOCAL_RECORDERS: set[tuple[str, str]] = set()


def _qos_words(qos: Any) -> str:
    return (f"{qos.reliability.name.lower()}, {qos.durability.name.lower()}, {qos.history.name.lower()} "
            f"depth {qos.depth}")


class ContractEndpoints:
    """The contract's endpoints of one node: every publisher and subscription checked against it.

    Parameters
    ----------
    node : the node whose endpoints these are
    role : node name and contract role of the node; must be a node of the contract
    contract : contract to enforce (default: the package's ``msg_defs/topics.yaml``)

    Raises
    ------
    ContractError
        For a role the contract does not declare.
    """

    def __init__(self, node: Node, role: str, contract: Contract | None = None) -> None:
        self.node = node
        self.contract = contract or load_contract()
        self.contract.node(role)  # raises ContractError for an undeclared node
        #: the node's name in the contract (its role), whatever name it runs under
        self.role = role

    # -- enforcement -------------------------------------------------------------
    def who(self) -> str:
        """``node 'fuzzy_ems' (running as 'shadow')``: the node in words."""
        name = self.node.get_name()
        return f"node '{self.role}'" + (f" (running as '{name}')" if name != self.role else "")

    def contract_name(self, topic: str) -> str:
        """Contract name of ``topic`` as the node's code asks for it (before remapping)."""
        if topic in INFRASTRUCTURE_TOPICS or topic in self.contract.topics:
            return topic  # rclpy's own topics and the contract's absolute ones (/clock)
        if not topic.startswith("/"):
            return topic.removeprefix("~/")
        rel = relative(self.node.get_namespace(), topic)
        if rel is None:
            raise ContractError(f"{self.who()}: topic '{topic}' lies outside its namespace "
                                f"'{self.node.get_namespace()}'")
        return rel

    def _check(self, kind: str, name: str, msg_type: Any, qos: Any) -> None:
        """Refuse an endpoint of the wrong role, type or QoS (see the module docstring)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        allowed = (self.contract.may_publish if kind == "publish" else self.contract.may_subscribe)
        if not allowed(self.role, name):
            raise ContractError(f"{self.who()} may not {kind}{' to' if kind == 'subscribe' else ''} '{name}' "
                                f"({self.contract.path} does not declare it)")
        spec = self.contract.topic(name)
        want_type = message_class(spec)
        if msg_type is not want_type:
            got = getattr(msg_type, "__name__", msg_type)
            raise ContractError(f"{self.who()}: topic '{name}': message type {got}, the contract says {spec.type}")
        want = qos_profile(spec)
        got_qos = qos if isinstance(qos, QoSProfile) else QoSProfile(depth=int(qos))
        if kind == "publish":
            same = (got_qos.reliability, got_qos.durability, got_qos.history, got_qos.depth) == (
                want.reliability, want.durability, want.history, want.depth)
        else:  # a reader may ask for less than the writer offers, never more
            same = not (got_qos.reliability == ReliabilityPolicy.RELIABLE and want.reliability !=
                        ReliabilityPolicy.RELIABLE) and not (got_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                                             and want.durability != DurabilityPolicy.TRANSIENT_LOCAL)
        if not same:
            raise ContractError(f"{self.who()}: topic '{name}': QoS {_qos_words(got_qos)}, the contract says "
                                f"{_qos_words(want)}")

    def create_publisher(self, msg_type: Any, topic: str, qos_profile: Any, **kwargs: Any) -> Any:
        """``Node.create_publisher``, refused unless the contract declares it (type and QoS included)."""
        name = self.contract_name(topic)
        if name not in INFRASTRUCTURE_TOPICS:
            self._check("publish", name, msg_type, qos_profile)
        kwargs.setdefault("event_callbacks", no_default_event_callbacks("publisher"))
        return self.node.create_publisher(msg_type, topic, qos_profile, **kwargs)

    def create_subscription(self, msg_type: Any, topic: str, callback: Any, qos_profile: Any, **kwargs: Any) -> Any:
        """``Node.create_subscription``, refused unless the contract declares it (type and QoS included)."""
        name = self.contract_name(topic)
        if name not in INFRASTRUCTURE_TOPICS:
            self._check("subscribe", name, msg_type, qos_profile)
        kwargs.setdefault("event_callbacks", no_default_event_callbacks("subscription"))
        return self.node.create_subscription(msg_type, topic, callback, qos_profile, **kwargs)

    # -- contract-typed helpers --------------------------------------------------
    def publisher(self, topic: str, namespace: str | None = None) -> Any:
        """Publisher of the contract topic ``topic`` with its type and QoS; in ``namespace`` (a house's,
        for a community's coordinator) instead of the node's own when given."""
        spec = self.contract.topic(topic)
        if namespace is None:
            return self.create_publisher(message_class(spec), topic, qos_profile(spec))
        self._check("publish", topic, message_class(spec), qos_profile(spec))
        return self.node.create_publisher(message_class(spec), resolve(namespace, topic), qos_profile(spec),
                                          event_callbacks=no_default_event_callbacks("publisher"))

    def subscription(self, topic: str, callback: Callable[[Any], None], raw: bool = False,
                     namespace: str | None = None) -> Any:
        """Subscription to the contract topic ``topic`` with its type and QoS; in ``namespace`` instead of
        the node's own when given."""
        spec = self.contract.topic(topic)
        if namespace is None:
            return self.create_subscription(message_class(spec), topic, callback, qos_profile(spec), raw=raw)
        self._check("subscribe", topic, message_class(spec), qos_profile(spec))
        return self.node.create_subscription(message_class(spec), resolve(namespace, topic), callback,
                                             qos_profile(spec), raw=raw,
                                             event_callbacks=no_default_event_callbacks("subscription"))

    def declared_topics(self) -> tuple[set[str], set[str]]:
        """Contract names of the node's actual publishers and subscriptions (infrastructure excluded)."""
        ns = self.node.get_namespace()

        def names(endpoints: Any) -> set[str]:
            full = {e.topic_name for e in endpoints} - INFRASTRUCTURE_TOPICS
            return {t if t in self.contract.topics else relative(ns, t) or t for t in full}

        return names(self.node.publishers), names(self.node.subscriptions)


class RecorderGate:
    """The waits of a node in a recorded run (see the module docstring).

    Parameters
    ----------
    node : the node
    wait_for_recorder : hold the first publication until :meth:`matched` (parameter
        ``wait_for_recorder``, set by the launcher)
    recorder_node : node name of the recorder whose readers :meth:`matched` looks for
    """

    def __init__(self, node: Node, wait_for_recorder: bool = False, recorder_node: str = RECORDER_NODE) -> None:
        self.node = node
        self.wait_for_recorder = wait_for_recorder
        self.recorder_node = recorder_node
        self._open = False
        self._t0: float | None = None
        self._timer: Any = None
        self._action: Callable[[], None] | None = None

    def when_open(self, action: Callable[[], None]) -> None:
        """Call ``action`` as soon as the gate opens (:meth:`is_open`, polled every
        :data:`GATE_POLL_S`; a later request replaces a pending one): an answer the gate held
        back goes out then, not at the master's next repeated announcement (0.5 s later)."""
        self._action = action
        if self._timer is None:
            self._timer = steady_timer(self.node, GATE_POLL_S, self._poll)

    def _poll(self) -> None:
        if not self.is_open():
            return
        self.node.destroy_timer(self._timer)
        self._timer = None
        action, self._action = self._action, None
        if action is not None:
            action()

    def is_open(self) -> bool:
        """True once the node may publish its first message of the run: without
        ``wait_for_recorder`` at once, else when :meth:`matched` holds, or
        :data:`RECORDER_GATE_TIMEOUT_S` after the first ask (with a warning naming the
        topics; a reader that died without leaving the graph must not stop the run)."""
        if self._open or not self.wait_for_recorder:
            return True
        now = time.monotonic()
        if self._t0 is None:
            self._t0 = now
        node = self.node
        if self.matched():
            self._open = True
            node.get_logger().info(f"every writer matched the recorder's readers after {now - self._t0:.2f} s: "
                                   "publishing")
        elif now - self._t0 > RECORDER_GATE_TIMEOUT_S:
            self._open = True
            unmatched = [p.topic_name for p in node.publishers if p.topic_name not in INFRASTRUCTURE_TOPICS
                         and p.get_subscription_count() < len(node.get_subscriptions_info_by_topic(p.topic_name))]
            node.get_logger().warning(f"publishing after {RECORDER_GATE_TIMEOUT_S:g} s without every reader "
                                      f"matched on: {', '.join(unmatched) or '(none; no recorder reader)'}")
        return self._open

    def matched(self) -> bool:
        """Whether every contract publisher of the node has a recorder's reader and has
        matched every reader the graph shows on its topic.

        A reader sees a writer (``get_publisher_count``) before, or after, the writer sees
        the reader: the recorder's ``recorder/ready`` only says that its readers matched.
        Samples a writer publishes before it has matched a reader are not sent to it
        (volatile durability), so a node run with ``wait_for_recorder`` publishes its
        first message only once this holds (measured: the first 2 to 5 steps of 16 feed
        topics missing in one of six 12-week runs on a quiet machine).
        """
        node = self.node
        for pub in node.publishers:
            if pub.topic_name in INFRASTRUCTURE_TOPICS:
                continue
            infos = node.get_subscriptions_info_by_topic(pub.topic_name)
            if not any(i.node_name == self.recorder_node for i in infos) or pub.get_subscription_count() < len(infos):
                return False
        return True

    def finish_when_recorded(self, finished: Any, topic: str, code: int = 0, timeout_s: float | None = None) -> None:
        """Complete the future ``finished`` with ``code`` once no recorder subscribes to ``topic``.

        A DDS reader drops the samples of a writer that leaves before they were taken, so
        a node that exited at once on ``plant/done`` could take its last messages out of
        a busy recorder's queue. The node therefore stays until the recorder (node name
        :attr:`recorder_node`) has closed its bag and left, at most ``timeout_s``
        (:data:`LINGER_S`); without a recorder, or once the recorders are finished ones of
        this process (:data:`FINISHED_LOCAL_RECORDERS`), it ends at the next check.
        """
        node = self.node
        full = node.resolve_topic_name(topic)
        limit = LINGER_S if timeout_s is None else timeout_s
        t0 = time.monotonic()

        def check() -> None:
            if finished.done():
                return
            recorders = [i for i in node.get_subscriptions_info_by_topic(full) if i.node_name == self.recorder_node
                         and (i.node_namespace, i.node_name) not in FINISHED_LOCAL_RECORDERS]
            if not recorders or time.monotonic() - t0 > limit:
                finished.set_result(code)

        steady_timer(node, LINGER_CHECK_S, check)


class RunEnd:
    """How a node that ends with the run (feed, EMS) ends, for
    :func:`comems4build_ros.ros.process.run_complete` (the node's ``run_end``).

    Parameters
    ----------
    exit_when_done : the node exits on ``plant/done``, once the recorder has left
    """

    def __init__(self, exit_when_done: bool = True) -> None:
        from rclpy.task import Future

        self.exit_when_done = exit_when_done
        self.saw_done = False  # plant/done came
        #: completed with the node's exit code (:meth:`RecorderGate.finish_when_recorded`)
        self.finished = Future()

    @property
    def over(self) -> bool:
        """``plant/done`` came (the node may still wait for the recorder to leave)."""
        return self.saw_done

    @property
    def complete(self) -> bool:
        """A signal from now on is a normal end (exit code 0): ``plant/done`` came and, with
        ``exit_when_done``, the recorder has left (until then the node's last messages may
        still be in the recorder's queues)."""
        return self.saw_done and (not self.exit_when_done or self.finished.done())


class ArrayPublisher:
    """Publishes ``Float64MultiArray`` messages of one contract topic, reusing one message.

    Parameters
    ----------
    endpoints : the publishing node's contract endpoints
    topic : contract topic name
    layout_sizes : values of the layout size symbols (:func:`contract.sizes`)
    namespace : publish in this namespace instead of the node's (:meth:`ContractEndpoints.publisher`)
    """

    def __init__(self, endpoints: ContractEndpoints, topic: str, layout_sizes: dict[str, int],
                 namespace: str | None = None) -> None:
        from std_msgs.msg import Float64MultiArray, MultiArrayDimension

        spec = endpoints.contract.topic(topic)
        self.topic = topic
        self.layout: Layout = spec.layout(layout_sizes)
        self.publisher = endpoints.publisher(topic, namespace)
        self._msg = Float64MultiArray()
        n = self.layout.length
        self._msg.layout.dim = [MultiArrayDimension(label=self.layout.dim_label, size=n, stride=n)]

        self._prefix = cdr_prefix(self.layout.dim_label, n)

    def publish(self, data: Sequence[float]) -> None:
        """Publish ``data`` as is.

        An ``array('d')`` of the layout's length is sent as ready CDR bytes (the fixed
        prefix of :func:`cdr_prefix` plus the array's bytes; the profile of a step showed
        rclpy's conversion of the message object as the largest cost of plant_sim and
        feed); anything else through the ``Float64MultiArray`` message.
        """
        if type(data) is array and len(data) == self.layout.length and data.typecode == "d":
            self.publisher.publish(self._prefix + data.tobytes())
            return
        self._msg.data = data
        self.publisher.publish(self._msg)

    def publish_values(self, values: dict[str, Any]) -> None:
        """Pack ``values`` (by field name) in layout order and publish."""
        self.publish(self.layout.pack(values))


def layout_sizes(params: PlantParams) -> dict[str, int]:
    """Layout size symbols for ``params`` (horizon and comfort look-ahead of sim.py)."""
    from comems4build_ros.core.ems.base import BOUNDS_AHEAD, PRICE_WINDOW

    out = sizes(params, comfort_ahead=BOUNDS_AHEAD + 1)
    out["horizon"] = PRICE_WINDOW  # the loop's price window and forecast length [steps]
    return out


def no_default_event_callbacks(kind: str) -> Any:
    """Event callbacks without rclpy's default QoS-incompatibility handlers.

    rclpy adds two event handlers (waitables) to every publisher and subscription that
    only log an incompatible QoS or type; the executor polls them at every wake-up. The
    topic contract gives every endpoint of a topic the same QoS and type, so the nodes
    leave them out (``kind``: ``publisher`` or ``subscription``).
    """
    from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks

    cls = PublisherEventCallbacks if kind == "publisher" else SubscriptionEventCallbacks
    return cls(use_default_callbacks=False)
