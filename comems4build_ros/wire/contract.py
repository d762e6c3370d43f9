"""The topic contract (``msg_defs/topics.yaml``): loading, checks and queries.

The YAML file is the single source of truth for every topic of the node set: name
(relative, so namespaces such as ``/house_3/`` work), interface type, unit, the nodes
that may publish and subscribe, QoS, and for ``Float64MultiArray`` topics the label of
each element. The nodes create their publishers and subscriptions from it (and
:mod:`comems4build_ros.ros.node` refuses any pub/sub the contract does not declare),
the recorder records every topic in it, the bag evaluation decodes the layouts, and the
docs table is generated from it (:func:`markdown_table`).

This module imports no rclpy: the message classes and QoS profiles of rclpy are built from
its specs by :mod:`comems4build_ros.ros.interfaces`.

Layout labels: ``name`` is one element; ``name[size]`` is ``size`` consecutive elements,
where ``size`` is an integer or a symbol resolved by :func:`sizes` (``horizon`` = the
MPC horizon and day-ahead window [steps], ``comfort_ahead`` = the fuzzy EMS's comfort
look-ahead [steps]); ``a.b[size]`` is entry ``b`` of the mapping ``a`` (the MPC's
``forecast``). Element 0 of every array topic is ``step``.
"""

from __future__ import annotations

import functools
import re
import sys
from array import array
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from comems4build_ros.core.config import load_yaml
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.paths import PACKAGE, SOURCE_ROOT, shared_path

#: The lock-step master's event topic: one line ``<step> <kind> <detail>`` per event.
EVENTS_TOPIC = "plant/events"
#: Kind of the ``plant/events`` line of a step whose state the master did not announce by
#: design (the MQTT bridge's safety fallback): no ``state/*`` and no ``feed/measured`` for
#: it (:func:`comems4build_ros.bags.evaluation.withheld_topics`), and no command. The
#: recorder and the bag's gap check expect none.
WITHHELD_EVENT = "withheld"


def event_step_kind(line: str) -> tuple[int, str] | None:
    """Split a ``plant/events`` line ``<step> <kind> <detail>``.

    Parameters
    ----------
    line : str
        The event line.

    Returns
    -------
    tuple of (int, str) or None
        ``(step, kind)``, or None if the line is malformed.
    """
    parts = line.split(None, 2)
    if len(parts) < 2:
        return None
    try:
        return int(parts[0]), parts[1]
    except ValueError:
        return None


CONTRACT_FILE = "topics.yaml"
#: In a topic's ``publishers``/``subscribers``: every EMS node (``ems``), or those of a level (``ems:<level>``).
EMS_GROUP = "ems"

#: Interface types the contract may use: std_msgs and rosgraph_msgs/Clock only (installable from PyPI, readable
#: by any ROS 2 tool without this package).
ALLOWED_TYPES = frozenset(
    {
        "std_msgs/msg/Float64",
        "std_msgs/msg/Float64MultiArray",
        "std_msgs/msg/UInt32",
        "std_msgs/msg/Bool",
        "std_msgs/msg/String",
        "rosgraph_msgs/msg/Clock",
    }
)
ARRAY_TYPE = "std_msgs/msg/Float64MultiArray"
NODE_ROLES = frozenset({"plant", "feed", "ems", "recorder", "replay", "bridge", "coordinator"})
QOS_KEYS = frozenset({"reliability", "history", "depth", "durability"})
TOPIC_KEYS = frozenset({"type", "unit", "publishers", "subscribers", "qos", "layout", "description", "scope"})
#: Where a topic lives (key ``scope``): ``house`` (a house's namespace, every run; the
#: default), ``community_house`` (a house's namespace in a community run only: the link
#: between the house and the coordinator) and ``coordinator`` (the coordinator's namespace).
SCOPES = ("house", "community_house", "coordinator")
_LABEL_RE = re.compile(
    r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)?)"  # name or head.key
    r"(?:\[(?P<size>[A-Za-z0-9_]+)\])?$"  # optional [size]
)
_TOPIC_RE = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*)*$")
#: The one absolute topic of the contract: the ROS 2 time source's (same in every namespace).
CLOCK_TOPIC = "/clock"

#: Default comfort look-ahead of the fuzzy EMS in steps (k .. k+5, sec:information).
COMFORT_AHEAD_STEPS = 6


class ContractError(InputError):
    """The contract file is invalid, or a node breaks it."""


@dataclass(frozen=True)
class QoSSpec:
    """QoS of one topic.

    Attributes
    ----------
    reliability : str
        ``reliable`` or ``best_effort``.
    history : str
        ``keep_last`` or ``keep_all``.
    depth : int
        Queue depth [messages].
    durability : str
        ``volatile`` or ``transient_local``.
    """

    reliability: str = "reliable"
    history: str = "keep_last"
    depth: int = 100
    durability: str = "volatile"


@dataclass(frozen=True)
class Field:
    """One decoded entry of an array layout: a scalar (``size`` None) or a vector.

    Attributes
    ----------
    name : str
        Label name without size, may be dotted (``forecast.t_amb_c``); its unit is in the
        name.
    start : int
        Index of the first element.
    size : int or None
        Number of elements; None for a scalar.
    """

    name: str
    start: int
    size: int | None

    @property
    def stop(self) -> int:
        """Index after the last element."""
        return self.start + (1 if self.size is None else self.size)


@dataclass(frozen=True)
class Layout:
    """Resolved layout of a ``Float64MultiArray`` topic.

    Attributes
    ----------
    topic : str
        Contract name of the topic.
    fields : tuple of Field
        The entries in element order.
    length : int
        Number of elements.
    integer, boolean : frozenset of str
        Field names read back as int and as bool (contract ``integer_labels``,
        ``boolean_labels``).
    """

    topic: str
    fields: tuple[Field, ...]
    length: int
    integer: frozenset[str] = frozenset()
    boolean: frozenset[str] = frozenset()

    @functools.cached_property
    def labels(self) -> tuple[str, ...]:
        """One label per element (vectors as ``name[i]``)."""
        out: list[str] = []
        for f in self.fields:
            out.extend([f.name] if f.size is None else [f"{f.name}[{i}]" for i in range(f.size)])
        return tuple(out)

    @functools.cached_property
    def dim_label(self) -> str:
        """Label of the message's one ``MultiArrayDimension``.

        The field names in order, comma-separated, vectors as ``name[size]`` (what ``ros2
        topic echo`` shows).
        """
        return ",".join(f.name if f.size is None else f"{f.name}[{f.size}]" for f in self.fields)

    @functools.cached_property
    def index(self) -> dict[str, int]:
        """Label -> element index (vectors: index of the first element under the bare name)."""
        out = {label: i for i, label in enumerate(self.labels)}
        out.update({f.name: f.start for f in self.fields})
        return out

    def pack(self, values: Mapping[str, Any]) -> array:
        """Pack values by field name into the message's elements in layout order.

        Parameters
        ----------
        values : mapping of str to object
            Field name -> number, or sequence for a vector (units as in the names).

        Returns
        -------
        array.array
            ``array('d')`` of :attr:`length` elements.

        Raises
        ------
        ContractError
            If a field is missing or a vector has the wrong length.
        """
        out = array("d")
        for f in self.fields:
            try:
                value = values[f.name]
            except KeyError:
                raise ContractError(f"topic '{self.topic}': no value for field '{f.name}'") from None
            if f.size is None:
                out.append(float(value))
            else:
                seq = np.asarray(value, dtype=float).ravel()
                if seq.size != f.size:
                    raise ContractError(
                        f"topic '{self.topic}': field '{f.name}' has {seq.size} elements, layout says {f.size}"
                    )
                out.extend(seq.tolist())
        return out

    def unpack(self, data: Sequence[float]) -> dict[str, Any]:
        """Unpack a message's elements into field name -> value.

        Dotted names are returned flat (``"forecast.t_amb_c"``); see :func:`nest`.

        Parameters
        ----------
        data : sequence of float
            The elements.

        Returns
        -------
        dict of str to object
            Field name -> float, int or bool (per :attr:`integer` and :attr:`boolean`), or a
            tuple of floats for a vector.

        Raises
        ------
        ContractError
            If the length differs from the layout.
        """
        if len(data) != self.length:
            raise ContractError(f"topic '{self.topic}': {len(data)} elements, layout has {self.length}")
        out: dict[str, Any] = {}
        for f in self.fields:
            if f.size is None:
                v = data[f.start]
                if f.name in self.boolean:
                    out[f.name] = bool(v > 0.5)
                elif f.name in self.integer:
                    out[f.name] = int(v)
                else:
                    out[f.name] = float(v)
            else:
                out[f.name] = tuple(float(x) for x in data[f.start : f.stop])
        return out


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Nest dotted keys one level: ``{"forecast.t_amb_c": x}`` -> ``{"forecast": {"t_amb_c": x}}``.

    Parameters
    ----------
    flat : mapping of str to object
        Output of :meth:`Layout.unpack`.

    Returns
    -------
    dict
        Undotted keys as they are, dotted ones grouped under their head.
    """
    out: dict[str, Any] = {}
    for key, value in flat.items():
        head, dot, tail = key.partition(".")
        if dot:
            out.setdefault(head, {})[tail] = value
        else:
            out[key] = value
    return out


@dataclass(frozen=True)
class TopicSpec:
    """One topic of the contract.

    Attributes
    ----------
    name : str
        Contract name (relative, or ``/clock``).
    type : str
        Interface type (one of :data:`ALLOWED_TYPES`).
    unit : str
        Unit of the values.
    publishers, subscribers : tuple of str
        Nodes that may publish and subscribe (groups resolved).
    qos : QoSSpec
        The topic's QoS.
    layout_labels : tuple of str
        Layout labels of an array topic (``name``, ``name[size]``).
    description : str
        What the topic carries.
    contract : Contract or None
        The contract it belongs to (its integer and boolean labels).
    """

    name: str
    type: str
    unit: str
    publishers: tuple[str, ...]
    subscribers: tuple[str, ...]
    qos: QoSSpec
    layout_labels: tuple[str, ...] = ()
    description: str = ""
    scope: str = "house"
    contract: Contract | None = field(default=None, repr=False, compare=False)

    @property
    def is_array(self) -> bool:
        """True for ``Float64MultiArray`` topics."""
        return self.type == ARRAY_TYPE

    def layout(self, sizes: Mapping[str, int]) -> Layout:
        """Resolve the topic's array layout.

        Parameters
        ----------
        sizes : mapping of str to int
            Values of the size symbols in ``name[symbol]`` (:func:`sizes`) [steps].

        Returns
        -------
        Layout
            The resolved layout.

        Raises
        ------
        ContractError
            For a non-array topic or an unknown size symbol.
        """
        if not self.is_array:
            raise ContractError(f"topic '{self.name}' ({self.type}) has no array layout")
        fields_: list[Field] = []
        pos = 0
        for raw in self.layout_labels:
            m = _LABEL_RE.match(raw)
            assert m is not None  # checked at load
            size_s = m.group("size")
            if size_s is None:
                size = None
            elif size_s.isdigit():
                size = int(size_s)
            else:
                try:
                    size = int(sizes[size_s])
                except KeyError:
                    raise ContractError(f"topic '{self.name}': unknown layout size symbol '{size_s}'") from None
            fields_.append(Field(m.group("name"), pos, size))
            pos += 1 if size is None else size
        integer = self.contract.integer_labels if self.contract else frozenset()
        boolean = self.contract.boolean_labels if self.contract else frozenset()
        return Layout(self.name, tuple(fields_), pos, integer, boolean)

    def field_names(self) -> tuple[str, ...]:
        """Return the field names of the layout without sizes (``step`` included).

        Returns
        -------
        tuple of str
            The names in layout order.
        """
        return tuple(_LABEL_RE.match(raw).group("name") for raw in self.layout_labels)  # type: ignore[union-attr]


@dataclass(frozen=True)
class NodeSpec:
    """One node of the contract.

    Attributes
    ----------
    name : str
        Node name.
    role : str
        One of :data:`NODE_ROLES`.
    ems : str or None
        EMS name of an EMS node (``config/ems.yaml``).
    info_level : str or None
        Information level of an EMS node (``tab:level_of_information``).
    subscribes_all, publishes_all : bool
        The node may subscribe to / publish every topic.
    """

    name: str
    role: str
    ems: str | None = None
    info_level: str | None = None
    subscribes_all: bool = False
    publishes_all: bool = False


@dataclass
class Contract:
    """All topics and nodes of ``msg_defs/topics.yaml``.

    Attributes
    ----------
    path : pathlib.Path
        The contract file.
    version : int
        Format version (1).
    topics : dict of str to TopicSpec
        Contract name -> topic.
    nodes : dict of str to NodeSpec
        Node name -> node (the EMS nodes of ``config/ems.yaml`` included).
    integer_labels, boolean_labels : frozenset of str
        Layout fields read back as int and as bool.
    """

    path: Path
    version: int
    topics: dict[str, TopicSpec]
    nodes: dict[str, NodeSpec]
    integer_labels: frozenset[str]
    boolean_labels: frozenset[str]

    def topic(self, name: str) -> TopicSpec:
        """Look up a topic by contract name (relative, or ``/clock``; no namespace).

        Parameters
        ----------
        name : str
            Contract name of the topic.

        Returns
        -------
        TopicSpec
            Its type, unit, publishers, subscribers, QoS and layout labels.

        Raises
        ------
        ContractError
            If the topic is not in the contract.
        """
        try:
            return self.topics[name]
        except KeyError:
            raise ContractError(f"topic '{name}' is not in the contract {self.path}") from None

    def node(self, name: str) -> NodeSpec:
        """Look up a node by name.

        Parameters
        ----------
        name : str
            Name of a declared node or an EMS node.

        Returns
        -------
        NodeSpec
            Its role (and EMS and information level for an EMS node).

        Raises
        ------
        ContractError
            If the node is not in the contract.
        """
        try:
            return self.nodes[name]
        except KeyError:
            raise ContractError(f"node '{name}' is not in the contract {self.path}") from None

    def may_publish(self, node: str, topic: str) -> bool:
        """Tell whether ``node`` may publish ``topic``.

        Parameters
        ----------
        node : str
            The publishing node's name.
        topic : str
            Contract name of the topic it would publish.

        Returns
        -------
        bool
            True if the topic lists the node among its publishers or the node publishes
            all; False for an unknown node or topic.
        """
        spec = self.topics.get(topic)
        nspec = self.nodes.get(node)
        if spec is None or nspec is None:
            return False
        return nspec.publishes_all or node in spec.publishers

    def may_subscribe(self, node: str, topic: str) -> bool:
        """Tell whether ``node`` may subscribe to ``topic`` (the reading side of :meth:`may_publish`).

        Parameters
        ----------
        node, topic : str
            The subscribing node's name and the contract name of the topic it would read.

        Returns
        -------
        bool
            True if the topic lists the node among its subscribers or the node subscribes
            to all; False for an unknown node or topic.
        """
        spec = self.topics.get(topic)
        nspec = self.nodes.get(node)
        if spec is None or nspec is None:
            return False
        return nspec.subscribes_all or node in spec.subscribers

    def published_by(self, node: str) -> tuple[TopicSpec, ...]:
        """List the topics ``node`` is declared to publish (explicitly, not via ``publishes_all``).

        Parameters
        ----------
        node : str
            A publisher's name.

        Returns
        -------
        tuple of TopicSpec
            The topics whose ``publishers`` name it, in contract order.
        """
        return tuple(t for t in self.topics.values() if node in t.publishers)

    def subscribed_by(self, node: str) -> tuple[TopicSpec, ...]:
        """List the topics ``node`` is declared to subscribe to (explicitly).

        Parameters
        ----------
        node : str
            A subscriber's name.

        Returns
        -------
        tuple of TopicSpec
            The topics whose ``subscribers`` name it, in contract order.
        """
        return tuple(t for t in self.topics.values() if node in t.subscribers)

    def in_scope(self, *scopes: str) -> tuple[TopicSpec, ...]:
        """Return the topics of the given scopes (:data:`SCOPES`)."""
        return tuple(t for t in self.topics.values() if t.scope in scopes)

    def ems_node_name(self, ems: str) -> str:
        """Return the node name of an EMS (e.g. ``fuzzy`` -> ``fuzzy_ems``).

        Parameters
        ----------
        ems : str
            EMS name.

        Returns
        -------
        str
            The node name.

        Raises
        ------
        ContractError
            If no EMS node has that EMS, naming the known ones.
        """
        for spec in self.nodes.values():
            if spec.role == "ems" and spec.ems == ems:
                return spec.name
        known = sorted(s.ems for s in self.nodes.values() if s.role == "ems" and s.ems)
        raise ContractError(f"no EMS node for '{ems}' in {self.path} (known: {', '.join(known)})")

    def inputs_not_read(self, ems_node: str) -> tuple[str, ...]:
        """List the feed topics only EMS nodes read and ``ems_node`` does not.

        That follows from its information level (``tab:level_of_information``): what a run
        of that EMS needs no feed to publish.

        Parameters
        ----------
        ems_node : str
            Node name of an EMS.

        Returns
        -------
        tuple of str
            Contract names of those topics.

        Raises
        ------
        ContractError
            If ``ems_node`` is not an EMS node of the contract.
        """
        if self.node(ems_node).role != "ems":
            raise ContractError(f"node '{ems_node}' is not an EMS node of {self.path}")
        roles = {n.name: n.role for n in self.nodes.values()}
        return tuple(
            t.name for t in self.published_by("feed")
            if t.subscribers and all(roles.get(s) == "ems" for s in t.subscribers) and ems_node not in t.subscribers
        )

    def input_fields(self, node: str) -> frozenset[str]:
        """Return the observation field names the subscribed array topics of ``node`` deliver.

        Dotted labels count as their head (``forecast.t_amb_c`` -> ``forecast``); ``step`` is
        left out.

        Parameters
        ----------
        node : str
            Node name.

        Returns
        -------
        frozenset of str
            The field names.
        """
        names: set[str] = set()
        for t in self.subscribed_by(node):
            if t.is_array:
                names.update(n.partition(".")[0] for n in t.field_names())
        names.discard("step")
        return frozenset(names)


def contract_path() -> Path:
    """Return the path of ``topics.yaml``: source tree first, then the installed share directory.

    Returns
    -------
    pathlib.Path
        The contract file.

    Raises
    ------
    ContractError
        If neither exists.
    """
    found = shared_path("msg_defs", "msg_defs", CONTRACT_FILE)
    if found is None:
        raise ContractError(f"cannot find the topic contract ({SOURCE_ROOT / 'msg_defs' / CONTRACT_FILE} or "
                            f"{Path(sys.prefix) / 'share' / PACKAGE / 'msg_defs' / CONTRACT_FILE})")
    return found


def sizes(params: Any = None, comfort_ahead: int | None = None) -> dict[str, int]:
    """Return the values of the layout size symbols.

    Parameters
    ----------
    params : PlantParams, optional
        ``simulation.horizon_h`` [h] / ``time_step_h`` [h] gives ``horizon`` in steps; None
        uses the defaults of ``config/plant.yaml``.
    comfort_ahead : int, optional
        Comfort look-ahead [steps]; default :data:`COMFORT_AHEAD_STEPS`.

    Returns
    -------
    dict of str to int
        ``horizon`` and ``comfort_ahead`` [steps].
    """
    if params is None:
        from comems4build_ros.core.config import load_plant_params

        params = load_plant_params()
    sim = params.simulation
    horizon = int(round(sim.horizon_h / sim.time_step_h))
    return {"horizon": horizon, "comfort_ahead": int(comfort_ahead or COMFORT_AHEAD_STEPS)}


def _err(path: Path, where: str, msg: str) -> ContractError:
    """Return a ContractError naming the file and the place."""
    return ContractError(f"{path}: {where}: {msg}")


def _names(path: Path, where: str, value: Any) -> tuple[str, ...]:
    """Return a list of node names as a tuple (empty for None); refuse anything else."""
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise _err(path, where, "must be a list of names")
    return tuple(value)


def _ems_groups(ems_nodes: Mapping[str, tuple[str, str]]) -> dict[str, tuple[str, ...]]:
    """Map ``ems`` and ``ems:<level>`` to the EMS nodes they stand for (levels of ``tab:level_of_information``)."""
    from comems4build_ros.core.ems.base import INFO_LEVELS

    groups = {EMS_GROUP: tuple(ems_nodes)}
    for level, fields in INFO_LEVELS.items():
        groups[f"{EMS_GROUP}:{level}"] = tuple(n for n, (_, lv) in ems_nodes.items() if fields <= INFO_LEVELS[lv])
    return groups


def _parse_nodes(doc: Mapping[str, Any], path: Path, ems_nodes: Mapping[str, tuple[str, str]]) -> dict[str, NodeSpec]:
    """Parse the ``nodes`` of the contract and add the EMS nodes (name -> (EMS, information level))."""
    nodes: dict[str, NodeSpec] = {}
    for name, raw in (doc.get("nodes") or {}).items():
        where = f"node '{name}'"
        raw = raw or {}
        if not isinstance(raw, Mapping):
            raise _err(path, where, "must be a mapping")
        extra = set(raw) - {"role", "subscribes_all", "publishes_all"}
        if extra:
            raise _err(path, where, f"unknown key(s): {', '.join(sorted(extra))}")
        role = raw.get("role")
        if role not in NODE_ROLES or role == "ems":
            raise _err(path, where, f"role must be one of {', '.join(sorted(NODE_ROLES - {'ems'}))} (the EMS nodes "
                                    f"are those of config/ems.yaml), got {role!r}")
        nodes[name] = NodeSpec(name=name, role=role, subscribes_all=bool(raw.get("subscribes_all", False)),
                               publishes_all=bool(raw.get("publishes_all", False)))
    for name, (ems, level) in ems_nodes.items():
        if name in nodes:
            raise _err(path, f"node '{name}'", "is also the node of an EMS in config/ems.yaml")
        nodes[name] = NodeSpec(name=name, role="ems", ems=ems, info_level=level)
    if not nodes:
        raise _err(path, "nodes", "no nodes declared")
    return nodes


def _parse_qos(raw: Mapping[str, Any], default_qos: Mapping[str, Any], path: Path, where: str) -> QoSSpec:
    """Parse a topic's QoS over the contract's defaults."""
    qos_raw = {**default_qos, **(raw.get("qos") or {})}
    if set(qos_raw) - QOS_KEYS:
        raise _err(path, f"{where}.qos", f"unknown key(s): {', '.join(sorted(set(qos_raw) - QOS_KEYS))}")
    qos = QoSSpec(**qos_raw)
    if qos.reliability not in ("reliable", "best_effort"):
        raise _err(path, f"{where}.qos.reliability", f"'reliable' or 'best_effort', got {qos.reliability!r}")
    if qos.history not in ("keep_last", "keep_all"):
        raise _err(path, f"{where}.qos.history", f"'keep_last' or 'keep_all', got {qos.history!r}")
    if qos.durability not in ("volatile", "transient_local"):
        raise _err(path, f"{where}.qos.durability", f"'volatile' or 'transient_local', got {qos.durability!r}")
    if not isinstance(qos.depth, int) or qos.depth < 1:
        raise _err(path, f"{where}.qos.depth", f"positive integer needed, got {qos.depth!r}")
    return qos


def _check_layout(layout: Any, type_name: str, path: Path, where: str) -> None:
    """Refuse a layout that is missing, malformed or on a topic that is not an array."""
    if type_name == ARRAY_TYPE:
        if not isinstance(layout, list) or not layout:
            raise _err(path, f"{where}.layout", "a Float64MultiArray topic needs a non-empty label list")
        if layout[0] != "step":
            raise _err(path, f"{where}.layout", "the first element must be 'step'")
        seen: set[str] = set()
        for label in layout:
            m = _LABEL_RE.match(str(label))
            if not m:
                raise _err(path, f"{where}.layout", f"invalid label {label!r}")
            if m.group("name") in seen:
                raise _err(path, f"{where}.layout", f"duplicate label '{m.group('name')}'")
            seen.add(m.group("name"))
    elif layout is not None:
        raise _err(path, f"{where}.layout", f"only {ARRAY_TYPE} topics have a layout")


def _parse_topic(name: Any, raw: Any, contract: Contract, groups: Mapping[str, tuple[str, ...]],
                 default_qos: Mapping[str, Any]) -> TopicSpec:
    """Parse and check one topic of the contract."""
    path, where = contract.path, f"topic '{name}'"
    if not isinstance(name, str) or not _TOPIC_RE.match(name):
        raise _err(path, where, "name must be relative ('a/b', letters, digits, '_') or /clock")
    if name.startswith("/") and name != CLOCK_TOPIC:
        raise _err(path, where, f"the only absolute topic is {CLOCK_TOPIC} (the time source's); others are relative")
    if not isinstance(raw, Mapping):
        raise _err(path, where, "must be a mapping")
    extra = set(raw) - TOPIC_KEYS
    if extra:
        raise _err(path, where, f"unknown key(s): {', '.join(sorted(extra))}")
    type_name = raw.get("type")
    if type_name not in ALLOWED_TYPES:
        raise _err(path, where, f"type must be one of {', '.join(sorted(ALLOWED_TYPES))}, got {type_name!r}")
    if not raw.get("unit"):
        raise _err(path, where, "needs a 'unit'")
    pubs, subs = (tuple(n for item in _names(path, f"{where}.{key}", raw.get(key)) for n in groups.get(item, (item,)))
                  for key in ("publishers", "subscribers"))
    if not pubs:
        raise _err(path, f"{where}.publishers", "at least one publisher needed")
    for n in (*pubs, *subs):
        if n not in contract.nodes:
            raise _err(path, where, f"node '{n}' is not declared under 'nodes' (nor an EMS node of config/ems.yaml)")
    layout = raw.get("layout")
    _check_layout(layout, type_name, path, where)
    scope = raw.get("scope", "house")
    if scope not in SCOPES:
        raise _err(path, f"{where}.scope", f"one of {', '.join(SCOPES)}, got {scope!r}")
    return TopicSpec(name=name, type=type_name, unit=str(raw["unit"]), publishers=pubs, subscribers=subs,
                     qos=_parse_qos(raw, default_qos, path, where), layout_labels=tuple(str(x) for x in (layout or ())),
                     description=str(raw.get("description", "")), scope=scope, contract=contract)


def parse_contract(doc: Any, path: Path, ems_nodes: Mapping[str, tuple[str, str]] | None = None) -> Contract:
    """Validate a loaded YAML document and build the :class:`Contract`.

    Parameters
    ----------
    doc : object
        The YAML document.
    path : pathlib.Path
        Its file (named in errors).
    ems_nodes : mapping of str to tuple of (str, str), optional
        EMS node name -> (EMS name, information level); default the rows of
        ``config/ems.yaml`` (:func:`comems4build_ros.core.ems.ems_table`).

    Returns
    -------
    Contract
        The contract.

    Raises
    ------
    ContractError
        Naming the file, the topic or node and the rule broken.
    """
    if not isinstance(doc, Mapping):
        raise _err(path, "top level", "expected a mapping with 'version', 'nodes' and 'topics'")
    unknown = set(doc) - {"version", "defaults", "integer_labels", "boolean_labels", "nodes", "topics"}
    if unknown:
        raise _err(path, "top level", f"unknown key(s): {', '.join(sorted(unknown))}")
    version = doc.get("version")
    if version != 1:
        raise _err(path, "version", f"expected 1, got {version!r}")
    if ems_nodes is None:
        from comems4build_ros.core.ems import ems_table

        ems_nodes = {e.node: (e.name, e.info_level) for e in ems_table().values()}
    nodes = _parse_nodes(doc, path, ems_nodes)
    raw_topics = doc.get("topics")
    if not isinstance(raw_topics, Mapping) or not raw_topics:
        raise _err(path, "topics", "must be a non-empty mapping")
    contract = Contract(path=path, version=int(version), topics={}, nodes=nodes,
                        integer_labels=frozenset(doc.get("integer_labels") or ()),
                        boolean_labels=frozenset(doc.get("boolean_labels") or ()))
    groups = _ems_groups(ems_nodes)
    default_qos = dict((doc.get("defaults") or {}).get("qos") or {})
    for name, raw in raw_topics.items():
        contract.topics[name] = _parse_topic(name, raw, contract, groups, default_qos)
    return contract


@functools.lru_cache(maxsize=4)
def _load_cached(path: str) -> Contract:
    """Load and parse the contract file ``path`` (cached)."""
    p = Path(path)
    return parse_contract(load_yaml(p, "the topic contract", ContractError), p)


def load_contract(path: str | Path | None = None) -> Contract:
    """Load (and cache) the topic contract.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The contract file; None = the package's ``msg_defs/topics.yaml``.

    Returns
    -------
    Contract
        The parsed contract (the same object again for the same path).

    Raises
    ------
    ContractError
        For an unreadable file, or as :func:`parse_contract`.
    """
    return _load_cached(str(Path(path) if path is not None else contract_path()))


def resolve(namespace: str, topic: str) -> str:
    """Return the absolute topic name of a contract name under a namespace.

    Parameters
    ----------
    namespace : str
        The namespace (``/`` = root).
    topic : str
        Contract name; an absolute one (``/clock``) stays as it is.

    Returns
    -------
    str
        The absolute name.
    """
    if topic.startswith("/"):
        return topic
    ns = namespace.rstrip("/")
    return f"{ns}/{topic}" if ns else f"/{topic}"


def relative(namespace: str, full_name: str) -> str | None:
    """Return the contract name of an absolute topic under a namespace.

    Parameters
    ----------
    namespace : str
        The namespace.
    full_name : str
        Absolute topic name.

    Returns
    -------
    str or None
        The name relative to ``namespace``, or None if the topic lies outside it.
    """
    ns = namespace.rstrip("/") + "/"
    if full_name.startswith(ns):
        return full_name[len(ns) :]
    return None


def markdown_table(contract: Contract | None = None, topics: Iterable[str] | None = None) -> str:
    """Format the topics as a Markdown table (name, type, unit, publishers, subscribers, layout).

    Parameters
    ----------
    contract : Contract, optional
        The contract (default: the package's).
    topics : iterable of str, optional
        Contract names of the rows (default: every topic).

    Returns
    -------
    str
        The table.
    """
    c = contract or load_contract()
    rows = [
        "| topic | type | unit | publishers | subscribers (+ recorder) | layout |",
        "|---|---|---|---|---|---|",
    ]
    for name in topics or c.topics:
        t = c.topic(name)
        layout = ", ".join(t.layout_labels) if t.layout_labels else ""
        rows.append(
            f"| `{t.name}` | {t.type.replace('/msg/', '/')} | {t.unit} | {', '.join(t.publishers)} | "
            f"{', '.join(t.subscribers) or '-'} | {layout} |"
        )
    return "\n".join(rows)
