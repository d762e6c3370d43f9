"""Helpers shared by the ROS 2 nodes: contract-checked pub/sub, parameters, packing, main loop.

* :class:`ContractNode` is the base class of every node of the package. Its
  ``create_publisher`` / ``create_subscription`` refuse any topic the contract
  (``msg_defs/topics.yaml``) does not declare for the node, so a node cannot quietly
  publish or read something outside its row of ``tab:level_of_information``.
  :meth:`ContractNode.contract_publisher` and :meth:`ContractNode.contract_subscription`
  take the type and QoS from the contract.
* :class:`ArrayPublisher` packs values into a reused ``Float64MultiArray`` in the
  contract's layout order.
* :func:`plant_params_from_node` loads the plant parameters named by the node's
  ``config_files`` parameter (or its ``--params-file`` files, see docs/ros_nodes.md).
* :func:`command_to_action` validates an ``ems/command`` message (length, finiteness,
  ranges) and names the field it rejects.
* :func:`run_node` is the body of every ``main()``: init, the lean single-threaded
  executor (:mod:`comems4build_ros.ros.executor`), clean shutdown on Ctrl-C / SIGTERM
  (executor shutdown, destroy node, ``rclpy.try_shutdown``).
"""

from __future__ import annotations

import math
import sys
import time
from array import array
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future

from ..config import ConfigError, PlantParams, load_plant_params
from ..types import ACTION_FIELDS, HP_DHW, HP_OFF, HP_SH, Action
from .contract import Contract, ContractError, Layout, load_contract, relative, sizes
from .tokens import MAX_TOKEN

#: Topics rclpy itself creates for every node (parameter events, logging); not in the contract.
INFRASTRUCTURE_TOPICS = frozenset({"/parameter_events", "/rosout"})

#: Relative tolerance on the command range checks [-]: a command up to 1 % beyond a
#: device limit is accepted and clipped by the plant exactly as in-process (solver and
#: rounding noise); anything further out is rejected as invalid.
COMMAND_RANGE_REL_TOL = 0.01
#: Absolute tolerance on the command power range checks [W].
COMMAND_RANGE_ABS_TOL_W = 1.0
#: Longest wait of a finished node for the recorder to leave [s] (ContractNode.finish_when_recorded).
LINGER_S = 30.0
#: Period of that check [s].
LINGER_CHECK_S = 0.05
#: Node name of the recorder in the contract.
RECORDER_NODE = "recorder"
#: Longest hold of a node's first publication for its writers to match the recorder [s].
RECORDER_GATE_TIMEOUT_S = 30.0
#: ``(namespace, name)`` of the recorder nodes of this process that have closed their run
#: (every message taken). In a container process (:mod:`comems4build_ros.ros.host`) such a
#: recorder stays in the graph until the process ends; the nodes beside it need not wait.
FINISHED_LOCAL_RECORDERS: set[tuple[str, str]] = set()
#: Exit code of a node that refused to start (bad parameters, scenario or contract).
EXIT_BAD_INPUT = 2


class CommandError(ValueError):
    """An ``ems/command`` message is invalid; ``field`` names the offending element."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"field '{field}': {reason}")
        self.field = field
        self.reason = reason


class ContractNode(Node):
    """A ``Node`` whose publishers and subscriptions must be declared in the topic contract.

    Parameters
    ----------
    node_name : node name; must be a node of the contract
    contract : contract to enforce (default: the package's ``msg_defs/topics.yaml``)
    kwargs : passed to ``rclpy.node.Node``
    """

    def __init__(self, node_name: str, contract: Contract | None = None, **kwargs: Any) -> None:
        self.contract = contract or load_contract()
        self.contract.node(node_name)  # raises ContractError for an undeclared node
        super().__init__(node_name, **kwargs)

    # -- enforcement -------------------------------------------------------------
    def _contract_name(self, topic: str) -> str:
        """Contract (relative) name of ``topic`` as this node would resolve it."""
        full = self.resolve_topic_name(topic)
        if full in INFRASTRUCTURE_TOPICS:
            return full
        rel = relative(self.get_namespace(), full)
        if rel is None:
            raise ContractError(
                f"node '{self.get_name()}': topic '{full}' lies outside its namespace '{self.get_namespace()}'"
            )
        return rel

    def create_publisher(self, msg_type: Any, topic: str, *args: Any, **kwargs: Any) -> Any:  # noqa: D102
        name = self._contract_name(topic)
        if name not in INFRASTRUCTURE_TOPICS and not self.contract.may_publish(self.get_name(), name):
            raise ContractError(
                f"node '{self.get_name()}' may not publish '{name}' ({self.contract.path} does not declare it)"
            )
        kwargs.setdefault("event_callbacks", no_default_event_callbacks("publisher"))
        return super().create_publisher(msg_type, topic, *args, **kwargs)

    def create_subscription(self, msg_type: Any, topic: str, *args: Any, **kwargs: Any) -> Any:  # noqa: D102
        name = self._contract_name(topic)
        if name not in INFRASTRUCTURE_TOPICS and not self.contract.may_subscribe(self.get_name(), name):
            raise ContractError(
                f"node '{self.get_name()}' may not subscribe to '{name}' ({self.contract.path} does not declare it)"
            )
        kwargs.setdefault("event_callbacks", no_default_event_callbacks("subscription"))
        return super().create_subscription(msg_type, topic, *args, **kwargs)

    # -- contract-typed helpers --------------------------------------------------
    def contract_publisher(self, topic: str) -> Any:
        """Publisher of the contract topic ``topic`` with its type and QoS."""
        spec = self.contract.topic(topic)
        return self.create_publisher(spec.msg_class(), topic, spec.qos_profile())

    def contract_subscription(self, topic: str, callback: Callable[[Any], None], raw: bool = False) -> Any:
        """Subscription to the contract topic ``topic`` with its type and QoS."""
        spec = self.contract.topic(topic)
        return self.create_subscription(spec.msg_class(), topic, callback, spec.qos_profile(), raw=raw)

    def finish_when_recorded(self, topic: str, code: int = 0, timeout_s: float | None = None) -> None:
        """Complete ``self.finished`` with ``code`` once no recorder subscribes to ``topic``.

        A DDS reader drops the samples of a writer that leaves before they were taken, so
        a node that exited at once on ``plant/done`` could take its last messages out of
        a busy recorder's queue. The node therefore stays until the recorder (node name
        ``recorder``) has closed its bag and left, at most ``timeout_s``
        (:data:`LINGER_S`); without a recorder, or once the recorders are finished ones of
        this process (:data:`FINISHED_LOCAL_RECORDERS`), it ends at the next check.
        """
        full = self.resolve_topic_name(topic)
        limit = LINGER_S if timeout_s is None else timeout_s
        t0 = time.monotonic()

        def check() -> None:
            if self.finished.done():
                return
            recorders = [i for i in self.get_subscriptions_info_by_topic(full) if i.node_name == RECORDER_NODE
                         and (i.node_namespace, i.node_name) not in FINISHED_LOCAL_RECORDERS]
            if not recorders or time.monotonic() - t0 > limit:
                self.finished.set_result(code)

        self.create_timer(LINGER_CHECK_S, check)

    #: With a recorder in the run (parameter ``wait_for_recorder``, set by the launcher):
    #: hold the first publication until :meth:`recorder_matched` (see :meth:`recorder_gate`).
    wait_for_recorder: bool = False
    #: Node name of the recorder whose readers :meth:`recorder_matched` looks for.
    recorder_node: str = RECORDER_NODE
    _gate_open = False
    _gate_t0: float | None = None

    def recorder_gate(self) -> bool:
        """True once this node may publish its first message of the run: without
        ``wait_for_recorder`` at once, else when :meth:`recorder_matched` holds, or
        :data:`RECORDER_GATE_TIMEOUT_S` after the first ask (with a warning naming the
        topics; a reader that died without leaving the graph must not stop the run)."""
        if self._gate_open or not self.wait_for_recorder:
            return True
        now = time.monotonic()
        if self._gate_t0 is None:
            self._gate_t0 = now
        if self.recorder_matched():
            self._gate_open = True
        elif now - self._gate_t0 > RECORDER_GATE_TIMEOUT_S:
            self._gate_open = True
            unmatched = [p.topic_name for p in self.publishers if p.topic_name not in INFRASTRUCTURE_TOPICS
                         and p.get_subscription_count() < len(self.get_subscriptions_info_by_topic(p.topic_name))]
            self.get_logger().warning(f"publishing after {RECORDER_GATE_TIMEOUT_S:g} s without every reader "
                                      f"matched on: {', '.join(unmatched) or '(none; no recorder reader)'}")
        return self._gate_open

    def recorder_matched(self) -> bool:
        """Whether every contract publisher of this node has a recorder's reader and has
        matched every reader the graph shows on its topic.

        A reader sees a writer (``get_publisher_count``) before, or after, the writer sees
        the reader: the recorder's ``recorder/ready`` only says that its readers matched.
        Samples a writer publishes before it has matched a reader are not sent to it
        (volatile durability), so a node run with ``wait_for_recorder`` publishes its
        first message only once this holds (measured: the first 2 to 5 steps of 16 feed
        topics missing in one of six 12-week runs on a quiet machine).
        """
        for pub in self.publishers:
            if pub.topic_name in INFRASTRUCTURE_TOPICS:
                continue
            infos = self.get_subscriptions_info_by_topic(pub.topic_name)
            if not any(i.node_name == self.recorder_node for i in infos) or pub.get_subscription_count() < len(infos):
                return False
        return True

    def declared_topics(self) -> tuple[set[str], set[str]]:
        """Contract names of this node's actual publishers and subscriptions (infrastructure excluded)."""
        ns = self.get_namespace()

        def names(endpoints: Any) -> set[str]:
            full = {e.topic_name for e in endpoints} - INFRASTRUCTURE_TOPICS
            return {relative(ns, t) or t for t in full}

        return names(self.publishers), names(self.subscriptions)


class ArrayPublisher:
    """Publishes ``Float64MultiArray`` messages of one contract topic, reusing one message.

    Parameters
    ----------
    node : the publishing node
    topic : contract topic name
    layout_sizes : values of the layout size symbols (:func:`contract.sizes`)
    """

    def __init__(self, node: ContractNode, topic: str, layout_sizes: dict[str, int]) -> None:
        from std_msgs.msg import Float64MultiArray, MultiArrayDimension

        spec = node.contract.topic(topic)
        self.topic = topic
        self.layout: Layout = spec.layout(layout_sizes)
        self.publisher = node.contract_publisher(topic)
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


def cdr_prefix(label: str, n: int) -> bytes:
    """CDR bytes of a ``Float64MultiArray`` (one dimension ``label``, size and stride ``n``,
    data offset 0) up to its ``n`` float64 values, little endian (encapsulation CDR_LE).

    Layout (alignment counted after the 4-byte encapsulation header): dimension count;
    label length (with the terminating NUL), label, NUL, padding to 4; size; stride; data
    offset; value count; padding to 8; then the values. Equal to rclpy's serialisation
    (test/test_ros_nodes_common.py).
    """
    import struct
    import sys

    if sys.byteorder != "little":  # array.tobytes() is native: CDR_LE needs little endian
        raise RuntimeError("ready CDR bytes need a little-endian machine")
    body = bytearray(struct.pack("<I", 1))
    raw = label.encode("utf-8") + b"\0"
    body += struct.pack("<I", len(raw)) + raw
    body += b"\0" * (-len(body) % 4)
    body += struct.pack("<III", n, n, 0)
    body += struct.pack("<I", n)
    body += b"\0" * (-len(body) % 8)
    return b"\x00\x01\x00\x00" + bytes(body)


def string_cdr(text: str) -> bytes:
    """CDR bytes of a ``std_msgs/String`` holding ``text`` (encapsulation CDR_LE, length with
    the NUL, UTF-8 bytes, NUL): what rclpy serialises, without building the message object
    (test/test_ros_nodes_common.py)."""
    raw = text.encode("utf-8")
    return b"\x00\x01\x00\x00" + (len(raw) + 1).to_bytes(4, "little") + raw + b"\0"


def _array_data(raw: bytes) -> tuple[int, int]:
    """``(byte offset, count)`` of the values of a CDR ``Float64MultiArray`` (labels skipped).

    Raises
    ------
    ValueError
        For bytes that are not a little-endian ``Float64MultiArray`` or are cut short.
    """
    import struct

    if len(raw) < 8 or raw[1] != 1:
        raise ValueError("not a little-endian CDR Float64MultiArray")
    unpack = struct.unpack_from
    try:
        pos = 4
        (ndim,) = unpack("<I", raw, pos)
        pos += 4
        for _ in range(ndim):
            (n_label,) = unpack("<I", raw, pos)
            pos += 4 + n_label
            pos += -(pos - 4) % 4
            pos += 8  # size, stride
        pos += 4  # data_offset
        (n,) = unpack("<I", raw, pos)
    except struct.error:
        raise ValueError(f"Float64MultiArray cut short ({len(raw)} bytes)") from None
    pos += 4
    pos += -(pos - 4) % 8
    if pos + 8 * n > len(raw):
        raise ValueError(f"Float64MultiArray of {n} values cut short ({len(raw)} bytes)")
    return pos, n


def parse_array(raw: bytes) -> array:
    """Values of a CDR-serialised ``Float64MultiArray`` (any layout dimensions), as ``array('d')``.

    Reads the little-endian CDR directly (dimension labels skipped): about 10x cheaper
    than rclpy's conversion to a message object, which the EMS node did 10 to 20 times
    per step (docs/ros_tools.md "Profile of a step").

    Raises
    ------
    ValueError
        For bytes that are not a little-endian ``Float64MultiArray`` or are cut short.
    """
    pos, n = _array_data(raw)
    out = array("d")
    out.frombytes(raw[pos:pos + 8 * n])
    return out


def array_step(raw: bytes) -> int:
    """Element 0 (the step of every contract array topic) of a CDR ``Float64MultiArray``.

    Raises
    ------
    ValueError
        For bytes that are not such an array, or an empty one.
    """
    import struct

    pos, n = _array_data(raw)
    if n < 1:
        raise ValueError("empty Float64MultiArray: no step")
    return int(struct.unpack_from("<d", raw, pos)[0])


def layout_sizes(params: PlantParams) -> dict[str, int]:
    """Layout size symbols for ``params`` (horizon and comfort look-ahead of sim.py)."""
    from ..ems.base import BOUNDS_AHEAD, PRICE_WINDOW

    out = sizes(params, comfort_ahead=BOUNDS_AHEAD + 1)
    out["horizon"] = PRICE_WINDOW  # the loop's price window and forecast length [steps]
    return out


def param(node: Node, name: str, default: Any) -> Any:
    """Value of parameter ``name``, declared with ``default`` unless already declared.

    Nodes are created with ``automatically_declare_parameters_from_overrides=True`` (so
    every key of a ``--params-file`` becomes a parameter); a parameter given there is
    already declared and keeps its value. Array values are returned as lists.
    """
    if not node.has_parameter(name):
        node.declare_parameter(name, default)
    value = node.get_parameter(name).value
    if value is not None and not isinstance(value, (str, bytes, bool, int, float)):
        value = list(value)
    return value


def plant_params_from_node(node: Node) -> PlantParams:
    """Plant parameters of a node, from its ROS parameters.

    ``config/plant.yaml`` is merged with, in order: the files of the string-array
    parameter ``config_files`` (parameter-file form, as ``comems4build simulate
    --config``), every node parameter whose first dotted segment is a plant section
    (``battery.e_max_kwh`` and so on: what ``--ros-args --params-file config/plant.yaml``
    or ``-p battery.e_max_kwh:=10.0`` sets), and the ``overrides`` string array of
    ``section.key=value`` items (YAML scalars).

    Raises
    ------
    ConfigError
        Naming the file or override and the parameter that is invalid.
    """
    import yaml

    from ..config import PLANT_SECTIONS

    files = [str(f) for f in param(node, "config_files", [""]) if f]
    ros_overrides: dict[str, Any] = {}
    for name, p in node.get_parameters_by_prefix("").items():
        if name.split(".", 1)[0] in PLANT_SECTIONS and "." in name:
            value = p.value
            ros_overrides[name] = value if isinstance(value, (str, bool, int, float)) else list(value)
    for item in param(node, "overrides", [""]):
        if not item:
            continue
        key, sep, value = str(item).partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"node '{node.get_name()}': parameter 'overrides': '{item}' is not KEY=VALUE")
        ros_overrides[key.strip()] = yaml.safe_load(value)
    return load_plant_params(files, ros_overrides)


def command_bounds(params: PlantParams) -> dict[str, tuple[float, float]]:
    """Accepted range of each ``ems/command`` field (device limits plus tolerance).

    hp_mod [-] in [0, 1]; p_fc_w [W] in [0, P_FC,max]; p_bess_w [W] in [-P_d,max, P_ch,max],
    each widened by :data:`COMMAND_RANGE_REL_TOL` and :data:`COMMAND_RANGE_ABS_TOL_W`.
    """

    def widen(lo: float, hi: float, abs_tol: float) -> tuple[float, float]:
        span = max(abs(lo), abs(hi))
        tol = COMMAND_RANGE_REL_TOL * span + abs_tol
        return lo - tol, hi + tol

    return {
        "hp_mod": widen(0.0, 1.0, 0.0),
        "p_fc_w": widen(0.0, params.fuel_cell.p_max_w, COMMAND_RANGE_ABS_TOL_W),
        "p_bess_w": widen(-params.battery.p_d_max_w, params.battery.p_ch_max_w, COMMAND_RANGE_ABS_TOL_W),
    }


VALID_HP_MODES = (HP_OFF, HP_SH, HP_DHW)


def check_token(token: float) -> None:
    """Raise :class:`CommandError` unless ``token`` is a run token (integer in 1 .. 2^53-1)."""
    if not 0 < token < MAX_TOKEN or token != int(token):
        raise CommandError("token", f"not an integer in 1..2^53-1: {token}")


def command_to_action(
    data: Sequence[float], layout: Layout, bounds: dict[str, tuple[float, float]]
) -> tuple[int, Action]:
    """Validate one ``ems/command`` payload and return ``(step, Action)``.

    Raises
    ------
    CommandError
        For a wrong length, a non-finite value, a non-integral step, circuit or token, an
        unknown circuit, or a value outside :func:`command_bounds`; ``field`` names it.
    """
    if len(data) != layout.length:
        raise CommandError("(length)", f"{len(data)} elements, the contract layout has {layout.length}")
    for label, value in zip(layout.labels, data):
        if not math.isfinite(value):
            raise CommandError(label, f"non-finite value {value}")
    step_f = data[0]
    if step_f < 0 or step_f != int(step_f):
        raise CommandError("step", f"not a non-negative integer: {step_f}")
    check_token(data[layout.length - 1])
    values = dict(zip(ACTION_FIELDS, data[1:]))
    mode = values["hp_mode"]
    if mode not in VALID_HP_MODES:
        raise CommandError("hp_mode", f"{mode} is not one of {VALID_HP_MODES} (off, SH, DHW)")
    for name, (lo, hi) in bounds.items():
        v = values[name]
        if not lo <= v <= hi:
            raise CommandError(name, f"{v} outside the accepted range [{lo:g}, {hi:g}]")
    return int(step_f), Action(
        hp_mod=float(values["hp_mod"]),
        hp_mode=int(mode),
        p_fc_w=float(values["p_fc_w"]),
        p_bess_w=float(values["p_bess_w"]),
    )


def action_values(step: int, action: Action, token: int) -> list[float]:
    """``ems/command`` payload of ``action`` for ``step`` (layout: step, ACTION_FIELDS, token)."""
    return [float(step), *(float(getattr(action, f)) for f in ACTION_FIELDS), float(token)]


#: Environment variable choosing the executor of the node processes: ``lean`` (default,
#: :class:`comems4build_ros.ros.executor.LeanExecutor`) or ``single`` (rclpy's
#: ``SingleThreadedExecutor``, for comparison: ``comems4build bench ros`` measures both).
EXECUTOR_ENV = "COMEMS4BUILD_EXECUTOR"
EXECUTORS = ("lean", "single")


def make_executor() -> Any:
    """The executor of a node process, chosen by :data:`EXECUTOR_ENV` (default ``lean``).

    Raises
    ------
    ValueError
        For an unknown executor name.
    """
    import os

    name = os.environ.get(EXECUTOR_ENV, "lean") or "lean"
    if name == "single":
        return SingleThreadedExecutor()
    if name == "lean":
        from .executor import LeanExecutor

        return LeanExecutor()
    raise ValueError(f"environment variable {EXECUTOR_ENV}={name!r}: one of {', '.join(EXECUTORS)}")


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


def run_node(make_node: Callable[[], Node], args: list[str] | None = None, name: str = "node") -> int:
    """Create a node, spin it on :func:`make_executor`'s executor and always shut down cleanly.

    The node may expose ``finished: rclpy.task.Future``; spinning stops when it
    completes (its result is the exit code, default 0). Ctrl-C (KeyboardInterrupt) and
    SIGTERM (ExternalShutdownException, or rclpy's error on the context the signal
    handler has just shut down) end the spin with exit code 0. A
    :class:`ConfigError`, :class:`ContractError` or ``ValueError`` raised while the node
    is created is reported on stderr with exit code :data:`EXIT_BAD_INPUT`.
    Order of shutdown (as in the rclpy examples): executor shutdown, destroy node, rclpy shutdown.
    """
    rclpy.init(args=args)
    executor = make_executor()
    node: Node | None = None
    code = 0
    try:
        node = make_node()
        executor.add_node(node)
        finished: Future | None = getattr(node, "finished", None)
        if finished is not None:
            executor.spin_until_future_complete(finished)
            if finished.done():
                code = int(finished.result() or 0)
        else:
            executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # rclpy's SIGINT/SIGTERM handler shuts the context down from the signal; when that
        # falls between the executor's check and its next wait set, rclpy raises RCLError
        # (a RuntimeError: "the given context is not valid") instead of
        # ExternalShutdownException. That is the same clean external shutdown.
        if rclpy.ok():
            raise
    except (ConfigError, ContractError, ValueError, FileNotFoundError) as exc:
        label = node.get_name() if node is not None else name
        print(f"[{label}] error: {exc}", file=sys.stderr, flush=True)
        code = EXIT_BAD_INPUT
    finally:
        from .host import ignore_sigint, print_cpu

        ignore_sigint()  # a second Ctrl-C or the launcher's SIGINT must not cut the clean-up short
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        print_cpu(name)
    return code
