"""EMS nodes: one per EMS of ``config/ems.yaml`` (``fuzzy_ems``, ``rbc_ems``, ``mpc_ems``, ...).

One module for every EMS: the node wraps the controller of the core
(:func:`comems4build_ros.core.ems.make_controller`) and is swapped by starting another node;
all publish ``ems/command``. Each node subscribes to exactly the topics its row of
``tab:level_of_information`` allows (the contract lists the node as a subscriber of
those topics only; :class:`~comems4build_ros.ros.node.ContractEndpoints` refuses anything
else). From the messages tagged with step ``k`` it rebuilds the very
:class:`~comems4build_ros.core.ems.base.Observation` the in-process loop builds with
:class:`comems4build_ros.core.loop.ObservationBuilder` (labels = observation fields, float64
values unchanged, vectors as tuples), calls the controller once per step and publishes
the command for step ``k`` (and the controller's ``step_info`` on ``ems/info``).

A repeated state announcement for a step already answered (the plant repeats while it
waits, e.g. if the first command was lost during discovery) is answered with the same
command again; the controller is never called twice for a step.

Every command carries a token (:mod:`comems4build_ros.wire.tokens`): with the run secret
of ``run_token_file`` (a file of mode 0600 the launcher writes) the command's own
authentication code, else the plain ``run_token`` (visible to every local user) or,
without either, one derived from the node's fully qualified name, so a restarted EMS
keeps it. ``plant_sim`` applies the commands of the run's EMS only and counts the others
as foreign. The node exits with code 0
on ``plant/done`` (end of the run); stopped by a signal before it, with exit code 3
(:data:`~comems4build_ros.ros.process.EXIT_INTERRUPTED`).

Parameters: ``ems`` (set by the entry point), ``ems_options`` (string array of
``key=value``, as ``comems4build simulate --ems-option``), ``run_token_file`` or
``run_token`` and the plant
parameters (:meth:`comems4build_ros.ros.package_node.NodeParameters.plant_params`), ``wait_for_recorder``
and ``recorder_node`` (the recorder whose readers its writers wait for, and whose leaving
ends the node), all read-only during the run.

Composition: ``-r __node:=NAME`` runs the node under another name (its contract role stays
its EMS's node), ``-r ems/command:=...`` sends its commands elsewhere, e.g. to run a
shadow EMS beside the one the plant applies (docs/ros_tools.md "Remapping"). With
``--log-level debug`` it logs each decision.
"""

from __future__ import annotations

import json
import sys
from array import array
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rclpy.node import Node

from comems4build_ros.core.config import parse_assignments
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.types import ACTION_FIELDS
from comems4build_ros.ros.node import (
    RECORDER_NODE,
    ArrayPublisher,
    ContractEndpoints,
    RecorderGate,
    RunEnd,
    layout_sizes,
)
from comems4build_ros.ros.package_node import NodeParameters, debug_enabled, node_options, sim_time_logger
from comems4build_ros.ros.process import run_node
from comems4build_ros.wire.cdr import parse_array, string_cdr
from comems4build_ros.wire.contract import ContractError, load_contract, nest
from comems4build_ros.wire.tokens import command_mac, default_token, read_token_file, secret_key

#: Topic whose repeated message for an answered step triggers a re-send of the command.
RESEND_TRIGGER_TOPIC = "state/t_air_c"
#: Exit code when the controller raised.
EXIT_CONTROLLER_ERROR = 1


def parse_options(items: list[str], node_name: str) -> dict[str, Any]:
    """``["solver=HiGHS", "gap=0.01"]`` -> ``{"solver": "HiGHS", "gap": 0.01}`` (YAML scalars; empty items skipped)."""
    return parse_assignments([i for i in items if i], f"node '{node_name}': parameter 'ems_options':")


class EMSNode(Node):
    """Wraps one controller; see the module docstring.

    Parameters
    ----------
    ems : EMS name of ``config/ems.yaml`` (``fuzzy``, ``rbc``, ``mpc``, ``mpc-qp``, ``thermostat``)
    node_kwargs : passed to ``rclpy.node.Node`` (e.g. ``namespace``, ``parameter_overrides``)
    """

    def __init__(self, ems: str, **node_kwargs: Any) -> None:
        contract = load_contract()
        node_name = contract.ems_node_name(ems)
        super().__init__(node_name, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.debug = debug_enabled(self.log)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, node_name, contract)
        spec = contract.node(node_name)
        params = self.parameters.plant_params()
        options = parse_options(self.parameters.param("ems_options", []), node_name)
        self.controller = make_controller(ems, params, options)
        self.controller.reset()
        self.level = self.controller.info_level
        if self.level != spec.info_level:
            raise ContractError(
                f"node '{node_name}': controller '{ems}' has information level '{self.level}', "
                f"the contract says '{spec.info_level}'"
            )
        sizes = layout_sizes(params)
        token_file = self.parameters.param("run_token_file", "")
        self._key = secret_key(read_token_file(token_file)) if token_file else None  # authenticate each command
        run_token = self.parameters.param("run_token", 0)
        token = 0 if token_file else run_token
        self.token = float(token if token > 0 else default_token(self.get_fully_qualified_name()))
        self._cmd = ArrayPublisher(self.endpoints, "ems/command", sizes)
        self._info_pub = self.endpoints.publisher("ems/info")
        self.ems = ems
        self._inputs = [t for t in contract.subscribed_by(node_name) if t.is_array]
        self._full = (1 << len(self._inputs)) - 1
        self._pending: dict[int, list[Any]] = {}  # step -> [fields, bitmask of topics received]
        self._answered = -1
        self._last_cmd: array | None = None
        self.steps = 0
        for i, topic in enumerate(self._inputs):
            self.endpoints.subscription(topic.name, self._callback(i, topic.layout(sizes), topic.name), raw=True)
        self.run_end = RunEnd(self.parameters.param("exit_when_done", True))  # process.run_complete reads it
        self.finished = self.run_end.finished
        self.gate = RecorderGate(self, self.parameters.param("wait_for_recorder", False),
                                 self.parameters.param("recorder_node", RECORDER_NODE))
        self.endpoints.subscription("plant/done", self._on_done)
        self._done = False
        self.get_logger().info(
            f"EMS '{ems}' (level '{self.level}') listening to {len(self._inputs)} topics: "
            + ", ".join(t.name for t in self._inputs)
        )

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def _callback(self, index: int, layout: Any, topic: str) -> Callable[[bytes], None]:
        bit = 1 << index
        resend = topic == RESEND_TRIGGER_TOPIC

        def on_msg(raw: bytes) -> None:
            try:
                data = parse_array(raw)
            except ValueError as exc:
                self.get_logger().error(f"topic '{topic}': {exc}; message dropped")
                return
            step = int(data[0]) if len(data) else -1
            if step <= self._answered:
                if resend and step == self._answered and self._last_cmd is not None:
                    self._cmd.publish(self._last_cmd)
                return
            try:
                values = layout.unpack(data)
            except ContractError as exc:
                self.get_logger().error(f"topic '{topic}': {exc}; message dropped")
                return
            entry = self._pending.get(step)
            if entry is None:
                entry = self._pending[step] = [{}, 0]
            entry[0].update(values)
            entry[1] |= bit
            if entry[1] == self._full:
                self._decide(step, entry[0])

        return on_msg

    def _on_done(self, msg: Any) -> None:
        """End of the run (``plant/done``): the node exits with code 0."""
        if msg.data:
            self.run_end.saw_done = True
        if msg.data and self.run_end.exit_when_done and not self._done:
            self._done = True
            self.get_logger().info(f"run done after {self.steps} decisions: exiting once the recorder has left")
            self.gate.finish_when_recorded(self.finished, "ems/command")

    def _decide_pending(self, step: int) -> None:
        """Decide ``step`` if all its inputs are still pending (not answered meanwhile)."""
        entry = self._pending.get(step)
        if entry is not None and entry[1] == self._full and step > self._answered:
            self._decide(step, entry[0])

    def _decide(self, step: int, fields: dict[str, Any]) -> None:
        if not self.gate.is_open():  # not yet: decided once the gate opens (or at a repeated announcement)
            self.gate.when_open(lambda: self._decide_pending(step))
            return
        for s in [s for s in self._pending if s <= step]:
            del self._pending[s]
        data = nest(fields)
        data["step"] = step
        try:
            action = self.controller.act(Observation(self.level, data))
        except Exception as exc:  # a failing controller ends the node; the plant falls back
            self.get_logger().error(f"controller failed at step {step}: {type(exc).__name__}: {exc}")
            self.finished.set_result(EXIT_CONTROLLER_ERROR)
            return
        info = getattr(self.controller, "step_info", None) or {}
        # before the command, so it is out before the plant records the step
        payload_info = {"step": step, "ems": self.ems, "info": {k: float(v) for k, v in info.items()}}
        self._info_pub.publish(string_cdr(json.dumps(payload_info)))  # ready CDR bytes, as the arrays
        payload = array("d", [float(step), *(float(getattr(action, f)) for f in ACTION_FIELDS), self.token])
        if self._key is not None:  # the run secret: this command's own authentication code as its token
            payload[-1] = command_mac(self._key, payload[:-1].tobytes())
        self._cmd.publish(payload)
        self._answered = step
        self._last_cmd = payload
        self.steps += 1
        if self.debug:
            self.get_logger().debug(f"step {step}: decided and sent: " + ", ".join(
                f"{f}={getattr(action, f):g}" for f in ACTION_FIELDS))


def ems_of_program(program: str) -> str | None:
    """The EMS whose executable ``program`` is (``.../fuzzy_ems`` -> ``fuzzy``; ``config/ems.yaml``), else None."""
    from comems4build_ros.core.ems import ems_table

    name = Path(program).name
    return next((e.name for e in ems_table().values() if e.node == name), None)


def main(args: list[str] | None = None, ems: str | None = None) -> int:
    """Run the EMS node ``ems``; without it, the EMS whose executable this is, or the one after ``--ems``.

    Every EMS of ``config/ems.yaml`` has an executable named after its node (``fuzzy_ems``,
    ``ros2 run comems4build_ros fuzzy_ems``); ``python -m comems4build_ros.ros.nodes.ems_node
    --ems NAME --ros-args ...`` runs any of them.
    """
    argv = list(sys.argv[1:] if args is None else args)
    if ems is None:
        ems = ems_of_program(sys.argv[0])
    if ems is None:
        if "--ems" not in argv or argv.index("--ems") + 1 >= len(argv):
            from comems4build_ros.ros.log import process_logger

            process_logger("ems_node").error("refused to start: give the EMS as '--ems NAME'")
            return 2
        ems = argv[argv.index("--ems") + 1]
    return run_node(lambda: EMSNode(ems), args, f"{ems}_ems")


if __name__ == "__main__":
    raise SystemExit(main())
