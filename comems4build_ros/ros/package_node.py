"""What every node of the package composes: its parameters, steady timers and the simulated time in its log.

A node of the package is an ``rclpy.node.Node`` of its own (the node file holds the node, as in
ros2/examples), created with :func:`node_options`; it composes these helpers rather than
inheriting them:

* **Parameters** (:class:`NodeParameters`, :mod:`comems4build_ros.ros.parameters`).
  :meth:`NodeParameters.param` declares a parameter with its static type, its description
  (source and unit), its range and, unless the node passes ``on_change``, as read-only: a
  ``ros2 param set`` of it is refused ("Trying to set a read-only parameter"), as the value is
  fixed when the node starts. A parameter with ``on_change`` may change during a run and takes
  effect at once (``on_change`` gets the new value; the node logs it). Every value given, at
  start or by ``ros2 param set``, follows :func:`~comems4build_ros.ros.parameters.coerce`; an
  integer set where a number is declared becomes that number (a pre-set callback), every other
  type is refused. :meth:`NodeParameters.plant_params` reads, validates and declares every
  plant parameter (``battery.e_max_kwh`` ...), so ``ros2 param dump`` shows the plant the node
  models. :meth:`NodeParameters.refuse_undeclared` (called once the node is built, by
  :func:`~comems4build_ros.ros.process.run_node` and the container, through
  :func:`refuse_undeclared`) refuses a parameter given to the node that it does not have (a
  typo), naming the nearest known name.
* **Timers on the steady clock** (:func:`steady_timer`). Every timer of the package's nodes is
  a protocol time-out or period in wall time; with ``use_sim_time`` a node's own clock jumps an
  hour per step (and stands still before the first ``/clock``).
* **The simulated time in the log** (:func:`sim_time_logger`,
  :class:`~comems4build_ros.ros.log.SimTimeLogger`): a node returns it from ``get_logger``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.logging import LoggingSeverity
from rclpy.node import Node
from rclpy.parameter import Parameter

from comems4build_ros.ros.log import SimTimeLogger
from comems4build_ros.ros.parameters import (
    RCLPY_PARAMETERS,
    ParameterError,
    ParamSpec,
    coerce,
    descriptor,
    flat_plant_params,
    nearest,
    plant_param_spec,
    spec_of,
)

_UNSET = object()


def node_options(kwargs: dict[str, Any]) -> dict[str, Any]:
    """``rclpy.node.Node`` keyword arguments of a node of the package: ``kwargs`` (``namespace``,
    ``parameter_overrides``, ``context``, ...) with every parameter given kept for
    :class:`NodeParameters` to declare."""
    return {**kwargs, "automatically_declare_parameters_from_overrides": True}


def sim_time_logger(node: Node) -> SimTimeLogger:
    """The node's logger, stamped with the simulated time (:class:`~comems4build_ros.ros.log.SimTimeLogger`)."""
    return SimTimeLogger(Node.get_logger(node).name, node.get_clock())


def debug_enabled(logger: Any) -> bool:
    """Whether ``logger`` logs at debug level (``--log-level debug``, read once at start): the per-step lines."""
    return bool(logger.is_enabled_for(LoggingSeverity.DEBUG))


def steady_timer(node: Node, period_s: float, callback: Callable[[], Any]) -> Any:
    """``node.create_timer`` on the steady clock (see the module docstring) [s]."""
    return node.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


def refuse_undeclared(node: Any) -> None:
    """:meth:`NodeParameters.refuse_undeclared` of a node of the package (nothing for another node)."""
    parameters = getattr(node, "parameters", None)
    if isinstance(parameters, NodeParameters):
        parameters.refuse_undeclared()


class NodeParameters:
    """The parameters of one node: declared with their descriptors, checked, plant parameters included.

    Parameters
    ----------
    node : the node, created with :func:`node_options` (every parameter given to it is collected
        here and declared by :meth:`param`)

    Attributes
    ----------
    sim_time : ``use_sim_time`` now (kept current when it is set): the node's clock follows ``/clock``
    """

    def __init__(self, node: Node) -> None:
        self.node = node
        #: values given to the node (command line, parameter files, overrides), by name
        self._given: dict[str, Any] = {
            name: node.get_parameter(name).value for name in node.list_parameters([], 0).names
            if name not in RCLPY_PARAMETERS and not name.startswith("qos_overrides.")}
        self._declared: set[str] = set()
        self._on_change: dict[str, Any] = {}
        self._float_params: set[str] = set()
        self._specs: dict[str, ParamSpec] = {}
        sim = node.get_parameter("use_sim_time").value
        if not isinstance(sim, bool):
            raise ParameterError(f"{self._where('use_sim_time')} = {sim!r}: expected true or false")
        self.sim_time = sim
        node.add_pre_set_parameters_callback(self._numbers_as_floats)
        node.add_on_set_parameters_callback(self._check_set)
        node.add_post_set_parameters_callback(self._after_set)

    def _where(self, name: str) -> str:
        return f"node '{self.node.get_fully_qualified_name()}': parameter '{name}'"

    def param(self, name: str, default: Any, on_change: Any = None, spec: ParamSpec | None = None) -> Any:
        """Value of parameter ``name``: the one given to the node, else ``default``; declared
        with its descriptor (:mod:`comems4build_ros.ros.parameters`, or ``spec``, e.g. with a
        range known only now), read-only unless ``on_change`` is given (then called with each
        new value set during the run).

        Raises
        ------
        ParameterError
            For a value of the wrong type or outside the range, naming node and parameter.
        """
        spec = spec or spec_of(name)
        self._specs[name] = spec
        given = self._given.get(name, _UNSET)
        value = coerce(spec, default if given is _UNSET else given, self._where(name))
        self._declare(name, value, descriptor(name, spec, read_only=on_change is None))
        if spec.kind == "float":
            self._float_params.add(name)
        if on_change is not None:
            self._on_change[name] = on_change
        return value

    def string_list(self, name: str) -> list[str]:
        """A string-array parameter (default empty), empty items dropped."""
        return [str(v) for v in self.param(name, [])]

    def _declare(self, name: str, value: Any, desc: Any) -> None:
        """Declare ``name`` with ``value`` (replacing the declaration its given value made)."""
        node = self.node
        if node.has_parameter(name):
            node.undeclare_parameter(name)
        self._declared.add(name)
        if isinstance(value, list) and not value:
            # rclpy infers the type of [] as a byte array: declare the typed array, then set it
            # empty, then make it read-only (rclpy keeps the descriptor object it is given)
            import copy

            writable = copy.copy(desc)
            writable.read_only = False
            node.declare_parameter(name, Parameter.Type(desc.type), writable, ignore_override=True)
            node.set_parameters([Parameter(name, Parameter.Type(desc.type), [])])
            if desc.read_only:
                node.set_descriptor(name, desc)
            return
        node.declare_parameter(name, value, desc, ignore_override=True)

    def plant_params(self) -> Any:
        """The plant parameters of the node, checked once, every one of them declared (read-only).

        ``config/plant.yaml`` is merged with, in order: the files of ``config_files``
        (parameter-file form, as ``comems4build simulate --config``; the run plan gives one
        file with every checked value), every parameter given to the node whose first
        dotted segment is a plant section (``-p battery.e_max_kwh:=10.0``, or a
        ``--params-file`` with a ``battery`` section), and the ``overrides`` items
        ``section.key=value``.

        Raises
        ------
        ConfigError, ParameterError
            Naming the file, override or parameter that is invalid.
        """
        from comems4build_ros.core.config import load_plant_params, parse_assignments

        files = self.string_list("config_files")
        items = self.param("overrides", [])
        given: dict[str, Any] = {}
        for name, value in self._given.items():
            spec = plant_param_spec(name)
            if spec is not None:
                given[name] = coerce(spec, value, self._where(name))
        given.update(parse_assignments(items, f"{self._where('overrides')}:"))
        #: what the plant parameters were loaded from: the files and the dotted overrides
        self.plant_sources: tuple[list[str], dict[str, Any]] = (files, given)
        params = load_plant_params(files, given)
        for name, value in flat_plant_params(params).items():
            spec = plant_param_spec(name)
            assert spec is not None
            self._declare(name, value, descriptor(name, spec, read_only=True))
        return params

    def refuse_undeclared(self) -> None:
        """Refuse every parameter given to the node that it has not declared (a typo).

        Raises
        ------
        ParameterError
            Naming the first such parameter and the nearest name the node knows.
        """
        unknown = sorted(set(self._given) - self._declared)
        if not unknown:
            return
        known = sorted(self._declared | RCLPY_PARAMETERS)
        name = unknown[0]
        more = f" (and {len(unknown) - 1} more: {', '.join(unknown[1:])})" if len(unknown) > 1 else ""
        raise ParameterError(f"{self._where(name)}: not a parameter of this node{nearest(name, known)}{more}; "
                             "'ros2 param list' or 'ros2 param describe' shows its parameters")

    def _numbers_as_floats(self, parameters: list[Any]) -> list[Any]:
        """Pre-set callback: an integer set on a parameter declared as a number becomes that number."""
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.name in self._float_params and p.type_ == Parameter.Type.INTEGER else p for p in parameters]

    def _check_set(self, parameters: list[Any]) -> Any:
        """On-set callback: every value set follows :func:`~comems4build_ros.ros.parameters.coerce`
        (the descriptor checks type and range; this also refuses NaN and names the node)."""
        from rcl_interfaces.msg import SetParametersResult

        for p in parameters:
            if p.name not in self._declared or p.type_ == Parameter.Type.NOT_SET:
                continue
            try:
                coerce(self._specs.get(p.name) or spec_of(p.name), p.value, self._where(p.name))
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _after_set(self, parameters: list[Any]) -> None:
        """Post-set callback: hand each new value of a run-time parameter to its node and say so."""
        for p in parameters:
            action = self._on_change.get(p.name)
            if action is not None:
                action(p.value)
                self.node.get_logger().info(f"parameter '{p.name}' = {p.value!r} from now on")
            elif p.name == "use_sim_time" and self._declared:
                self.sim_time = bool(p.value)
                self.node.get_logger().info(f"use_sim_time = {p.value}: this node's clock "
                                            f"{'follows /clock' if p.value else 'is the system clock'} from now on")
