"""``plant_sim``: the building plant as a ROS 2 node, master of the lock-step loop.

The node owns a :class:`comems4build_ros.plant.Plant` and advances it one step at a
time, only when both the inputs of the step (``feed/truth``) and a valid command for the
step (``ems/command``) have arrived. Protocol (docs/ros_nodes.md):

1. Announce step ``k``: publish the state at the start of ``k`` (end of ``k-1``) on
   ``state/*``, each message tagged with ``k``, then ``plant/step`` = ``k``.
2. Wait. A command tagged with another step is ignored and counted
   (``wrong_step_commands``; an exact re-send of the command applied in the previous
   step is a retransmission, counted as ``duplicate_commands`` in the final
   statistics); a command with a wrong length, NaN/inf or an out-of-range value is
   rejected with a log line naming topic and field, counted
   (``rejected_commands``) and treated as missing. While waiting, the announcement is
   repeated every ``republish_period_s`` (a restarted EMS or a late subscriber picks it
   up). After ``step_timeout_s`` without a valid command (``startup_timeout_s`` before
   the first command or fallback of the run) the plant applies the safe fallback
   (:func:`comems4build_ros.ems.fallback.safe_action`), logs and counts it
   (``fallback_steps``) and moves on; the EMS takes over again as soon as it answers.
3. Step the plant, announce ``k + 1``, then publish ``plant/record`` (one timeseries row
   of the in-process loop) and ``clock`` (end of step ``k``).

After the last step the node publishes ``plant/done``, waits until the record messages
are acknowledged, and exits (``exit_when_done``). With ``wait_for_recorder`` it starts
only once the recorder has said ``recorder/ready``.
"""

from __future__ import annotations

import time
from array import array
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.duration import Duration
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64MultiArray, String, UInt32

from ...ems.fallback import safe_action
from ...plant import Plant
from ...types import ACTION_FIELDS, FLOW_FIELDS, STATE_COLUMNS, Action, Exogenous, PlantState
from ..common import (
    RECORDER_NODE,
    ArrayPublisher,
    CommandError,
    ContractNode,
    command_bounds,
    command_to_action,
    layout_sizes,
    param,
    plant_params_from_node,
    run_node,
)

NODE_NAME = "plant_sim"
#: Default wait for the command of a step once the EMS has answered at least once [s].
STEP_TIMEOUT_S = 5.0
#: Default wait for the first command of the run (EMS start-up, imports, solver set-up) [s].
STARTUP_TIMEOUT_S = 120.0
#: Default period of the repeated announcement while the plant waits [s].
REPUBLISH_PERIOD_S = 0.5
#: Default period of the watchdog timer (timeouts, repeats; parameter ``watchdog_period_s``) [s].
WATCHDOG_PERIOD_S = 0.02
#: Default of ``record_window_steps``: with ``wait_for_recorder`` the plant announces no
#: step more than this beyond the last step the recorder has written without a gap
#: (``recorder/progress``); the contract's keep-last depth (1000) exceeds it, so no
#: message can be overwritten before the recorder has it [steps].
RECORD_WINDOW_STEPS = 256
#: Wait for the acknowledgement of the last messages before exiting [s] ...
ACK_TIMEOUT_S = 5.0
#: ... checked this often [s].
ACK_POLL_S = 0.02
#: Interval of the "waiting for feed/truth" warning [s].
FEED_WARN_PERIOD_S = 10.0
NS_PER_S = 1_000_000_000

#: State topics: contract topic -> PlantState attributes in layout order (after step).
STATE_TOPICS: dict[str, tuple[str, ...]] = {
    "state/t_air_c": ("t_air_c",),
    "state/v_dhw_l": ("v_dhw_l",),
    "state/soc": ("soc",),
    "state/loh": ("loh",),
    "state/hp_mod": ("hp_mod",),
    "state/fc_on": ("fc_on",),
    "state/t_wall": ("t_wall_in_c", "t_wall_out_c"),
}


#: Timing parameters of the step loop [s] and their defaults (also used by mqtt_bridge).
LOOP_PARAMS = {
    "step_timeout_s": STEP_TIMEOUT_S,
    "startup_timeout_s": STARTUP_TIMEOUT_S,
    "republish_period_s": REPUBLISH_PERIOD_S,
    "watchdog_period_s": WATCHDOG_PERIOD_S,
}


def set_loop_params(node: ContractNode, node_name: str, extra: dict[str, float] | None = None) -> None:
    """Read the loop's timing parameters (:data:`LOOP_PARAMS` plus ``extra``), each positive,
    ``wait_for_recorder``, ``recorder_node`` (the recorder's node name, see
    :meth:`~comems4build_ros.ros.common.ContractNode.recorder_matched`), ``exit_when_done``,
    ``ems_token`` (0 = the token of the run's
    first valid command) and ``record_window_steps`` (>= 1) into attributes of ``node``, and
    set the run's counters to zero (the lock-step masters plant_sim and mqtt_bridge share them)."""
    for name, default in {**LOOP_PARAMS, **(extra or {})}.items():
        value = float(param(node, name, default))
        if not value > 0:
            raise ValueError(f"node '{node_name}': parameter '{name}' must be positive")
        setattr(node, name, value)
    node.wait_for_recorder = bool(param(node, "wait_for_recorder", False))
    node.recorder_node = str(param(node, "recorder_node", RECORDER_NODE))
    node.exit_when_done = bool(param(node, "exit_when_done", True))
    node.ems_token = int(param(node, "ems_token", 0))
    node.record_window_steps = int(param(node, "record_window_steps", RECORD_WINDOW_STEPS))
    if node.record_window_steps < 1:
        raise ValueError(f"node '{node_name}': parameter 'record_window_steps' must be >= 1")
    # the run's counters (plant/record, the final "run done" line) and the recorder's state
    node.fallback_steps = 0
    node.rejected_commands = 0
    node.wrong_step_commands = 0
    node.duplicate_commands = 0
    node.foreign_commands = 0
    node._token = float(node.ems_token) if node.ems_token > 0 else None  # run token of accepted commands
    node._recorder_ready = False
    node._recorded = 0  # steps the recorder has written without a gap (recorder/progress)
    node.held_s = 0.0  # lock-step: time the next announcement waited for the recorder (back-pressure) [s]


def finish_run(node: Any, before_done: Any = None) -> None:
    """End of a run (plant_sim, mqtt_bridge): log the statistics line, publish plant/done and
    the line on plant/events, wait (at most :data:`ACK_TIMEOUT_S`) for their acknowledgement,
    then, if ``exit_when_done``, finish once the recorder has left (``finish_when_recorded``:
    a writer that left at once could take its last messages out of a busy recorder's queue).

    The acknowledgements are polled by a timer (:data:`ACK_POLL_S`), not awaited in the
    callback: a host process spins every building's plant on one executor, and a blocking
    wait (DDS acknowledges on the writer's heartbeat period, seconds) would stall the other
    buildings' steps at every end of run.

    The line is logged first: whoever sees plant/done can rely on it being in the log.
    ``before_done`` (optional) is called between the log line and plant/done.
    """
    line = " ".join(f"{k}={v:.6g}" for k, v in node.stats().items())
    node.get_logger().info(f"run done: {line}")
    if before_done is not None:
        before_done()
    node._done_pub.publish(Bool(data=True))
    node._events_pub.publish(String(data=f"{node.k} stats {line}"))
    pubs = (node._record.publisher, node._done_pub, node._events_pub)
    t0 = time.monotonic()
    now_only = Duration(nanoseconds=0)
    timer: Any = None

    def poll() -> None:
        if not all(p.wait_for_all_acked(now_only) for p in pubs) and time.monotonic() - t0 < ACK_TIMEOUT_S:
            return
        timer.cancel()
        if node.exit_when_done:
            node.finish_when_recorded("plant/record")

    timer = node.create_timer(ACK_POLL_S, poll)


def accept_token(node: Any, token: float, step: int) -> bool:
    """Whether a valid command with run token ``token`` comes from the run's EMS
    (plant_sim, mqtt_bridge): ``node._token`` is ``ems_token``, or else the token of the
    run's first valid command; any other token is counted in ``node.foreign_commands``,
    logged on plant/events and its command ignored."""
    if node._token is None:
        node._token = token  # the first valid command names the run's EMS
        node.get_logger().info(f"commands of token {int(token)} accepted from now on")
    elif token != node._token:
        node.foreign_commands += 1
        node._event("foreign", f"topic 'ems/command': command for step {step} with token {int(token)} ignored "
                               f"(the run's EMS has token {int(node._token)})")
        return False
    return True


class PlantSim(ContractNode):
    """Plant simulator node (see the module docstring)."""

    def __init__(self, **node_kwargs: Any) -> None:
        """``node_kwargs`` (e.g. ``namespace``, ``parameter_overrides``) go to ``rclpy.node.Node``."""
        super().__init__(NODE_NAME, automatically_declare_parameters_from_overrides=True, **node_kwargs)
        self.params = plant_params_from_node(self)
        set_loop_params(self, NODE_NAME)

        self.plant = Plant(self.params)
        self.state: PlantState = self.plant.initial_state()
        self.dt_ns = int(round(self.params.simulation.time_step_h * 3600.0 * NS_PER_S))
        sizes = layout_sizes(self.params)
        self._bounds = command_bounds(self.params)

        self._state_pubs = [(ArrayPublisher(self, t, sizes), attrs) for t, attrs in STATE_TOPICS.items()]
        self._record = ArrayPublisher(self, "plant/record", sizes)
        self._step_pub = self.contract_publisher("plant/step")
        self._clock_pub = self.contract_publisher("clock")
        self._done_pub = self.contract_publisher("plant/done")
        self._events_pub = self.contract_publisher("plant/events")
        self._cmd_layout = self.contract.topic("ems/command").layout(sizes)
        self._truth_layout = self.contract.topic("feed/truth").layout(sizes)
        self._ti = self._truth_layout.index
        self._cmd_sub = self.contract_subscription("ems/command", self._on_command)
        self.contract_subscription("feed/truth", self._on_truth)
        self.contract_subscription("recorder/ready", self._on_recorder_ready)
        self.contract_subscription("recorder/progress", self._on_recorder_progress)

        self.k = 0
        self.n_steps: int | None = None
        self._truth: dict[int, Any] = {}
        self._cmd: Action | None = None
        self._ever_commanded = False
        self.started = False
        self.done = False
        self._held = False  # announcement of step k held back until the recorder catches up
        self._t_held = 0.0
        self._cmd_data: list[float] | None = None  # payload of the pending command
        self._last_cmd: list[float] | None = None  # payload of the command applied in step k-1
        self._t_created = time.monotonic()
        self._t_wait = 0.0
        self._t_announce = 0.0
        self._t_feed_warn = 0.0
        self._t_run0 = 0.0
        self._t_first_cmd = 0.0
        self._t_step_announced = 0.0
        self._announced = -1
        self._rtt = array("d")  # announce -> command round trips [s]
        self._step_msg = UInt32()
        self._clock_msg = Clock()
        self.finished = Future()
        self.create_timer(self.watchdog_period_s, self._watchdog)
        self.get_logger().info(
            f"plant ready: step timeout {self.step_timeout_s} s, start-up timeout {self.startup_timeout_s} s, "
            f"wait for recorder: {self.wait_for_recorder}"
        )

    # ------------------------------------------------------------------ events
    def _event(self, kind: str, detail: str) -> None:
        """Log a fault event and publish it on plant/events."""
        line = f"{self.k} {kind} {detail}"
        self.get_logger().warning(line)
        self._events_pub.publish(String(data=line))

    def _on_recorder_ready(self, msg: Bool) -> None:
        self._recorder_ready = bool(msg.data)

    def _on_recorder_progress(self, msg: UInt32) -> None:
        self._recorded = max(self._recorded, int(msg.data))
        if self._held and not self._behind():
            self._held = False
            self.held_s += time.monotonic() - self._t_held
            self._t_wait = time.monotonic()
            self._announce()

    def _behind(self) -> bool:
        """The recorder is more than ``record_window_steps`` steps behind step k (back-pressure)."""
        return self.wait_for_recorder and self.k - self._recorded > self.record_window_steps

    def _on_truth(self, msg: Float64MultiArray) -> None:
        data = msg.data
        if len(data) != self._truth_layout.length:
            self._event("rejected", f"topic 'feed/truth': {len(data)} elements, layout has {self._truth_layout.length}")
            return
        step = int(data[0])
        if step < self.k:
            return
        self._truth[step] = data
        if self.n_steps is None:
            self.n_steps = int(data[1])
        self._try_advance()

    def _on_command(self, msg: Float64MultiArray) -> None:
        try:
            step, action = command_to_action(msg.data, self._cmd_layout, self._bounds)
        except CommandError as exc:
            self.rejected_commands += 1
            self._event("rejected", f"topic 'ems/command' {exc}")
            return
        if not accept_token(self, msg.data[-1], step):
            return
        if step == self.k - 1 and self._last_cmd is not None and list(msg.data) == self._last_cmd:
            # the EMS re-sent the command just applied (answer to a repeated announcement
            # that crossed its first answer): a retransmission, not a wrong step
            self.duplicate_commands += 1
            return
        if not self.started or self.done or step != self.k:
            self.wrong_step_commands += 1
            self._event("wrong_step", f"topic 'ems/command': command for step {step} ignored")
            return
        self._cmd = action
        self._cmd_data = list(msg.data)
        now = time.monotonic()
        if self._ever_commanded:  # the first round trip includes the EMS start-up
            self._rtt.append(now - self._t_step_announced)
        else:
            self._t_first_cmd = now
        self._ever_commanded = True
        self._try_advance()

    # ------------------------------------------------------------------ stepping
    def _announce(self) -> None:
        """Publish the state at the start of step k on state/* and plant/step = k."""
        s = self.state
        kf = float(self.k)
        for pub, attrs in self._state_pubs:
            pub.publish(array("d", [kf, *(float(getattr(s, a)) for a in attrs)]))
        self._step_msg.data = self.k
        self._step_pub.publish(self._step_msg)
        self._t_announce = time.monotonic()
        if self._announced != self.k:
            self._announced = self.k
            self._t_step_announced = self._t_announce

    def _start(self) -> None:
        self.started = True
        self._t_run0 = time.monotonic()
        self._t_wait = self._t_run0
        self.get_logger().info("starting the run")
        self._announce()

    def _try_advance(self) -> None:
        if self.started and not self.done and self._cmd is not None and self.k in self._truth:
            action, self._cmd = self._cmd, None
            self._last_cmd = self._cmd_data
            self._step(action, fallback=False)

    def _step(self, action: Action, fallback: bool) -> None:
        k = self.k
        t = self._truth.pop(k)
        ti = self._ti
        exo = Exogenous(
            t_amb_c=t[ti["t_amb_c"]],
            ghi_w_m2=t[ti["ghi_w_m2"]],
            p_pv_w=t[ti["p_pv_w"]],
            p_load_w=t[ti["p_load_w"]],
            dhw_l_per_h=t[ti["dhw_l_per_h"]],
            price_buy_eur_per_kwh=t[ti["price_buy_eur_per_kwh"]],
            price_sell_eur_per_kwh=t[ti["price_sell_eur_per_kwh"]],
            t_min_c=t[ti["t_min_c"]],
            t_max_c=t[ti["t_max_c"]],
        )
        self.state, flows = self.plant.step(self.state, action, exo)
        s = self.state
        row = array("d", [float(k)])
        row.extend(float(getattr(flows, f)) for f in FLOW_FIELDS)
        row.extend(float(getattr(s, f)) for f in STATE_COLUMNS)
        row.extend(float(getattr(action, f)) for f in ACTION_FIELDS)
        row.extend(
            (exo.t_amb_c, exo.ghi_w_m2, exo.dhw_l_per_h, exo.t_min_c, exo.t_max_c, t[ti["spot_eur_per_mwh"]])
        )
        row.append(1.0 if fallback else 0.0)
        t0 = t[ti["time_unix_s"]]
        row.extend((t0, float(self.fallback_steps), float(self.rejected_commands), float(self.wrong_step_commands),
                    float(self.foreign_commands)))
        self.k = k + 1
        self._t_wait = time.monotonic()
        last = self.n_steps is not None and self.k >= self.n_steps
        if not last:
            if self._behind():
                self._held = True
                self._t_held = self._t_wait
            else:
                self._announce()  # first, so the EMS works on k + 1 while the record goes out
        self._record.publish(row)
        end_ns = int(round(t0 * NS_PER_S)) + self.dt_ns
        self._clock_msg.clock = Time(sec=end_ns // NS_PER_S, nanosec=end_ns % NS_PER_S)
        self._clock_pub.publish(self._clock_msg)
        if last:
            self._finish()

    def _fallback(self) -> None:
        t = self._truth[self.k]
        action = safe_action(self.state.t_air_c, self.state.v_dhw_l, t[self._ti["t_min_c"]], self.params)
        self.fallback_steps += 1
        self._last_cmd = None
        self._event(
            "fallback",
            f"no valid command on 'ems/command' within the timeout: safe action hp_mode={action.hp_mode} "
            f"hp_mod={action.hp_mod} (fallback steps: {self.fallback_steps})",
        )
        self._step(action, fallback=True)

    def stats(self) -> dict[str, float]:
        """Run statistics: steps, wall times [s], round trip announce -> command [ms], fault counters."""
        now = time.monotonic()
        rtt = sorted(self._rtt)
        n = len(rtt)
        return {
            "steps": float(self.k),
            "wall_s": now - self._t_run0 if self.started else 0.0,
            "wall_from_first_command_s": now - self._t_first_cmd if self._ever_commanded else 0.0,
            "rtt_median_ms": 1e3 * rtt[n // 2] if n else float("nan"),
            "rtt_p99_ms": 1e3 * rtt[min(n - 1, int(0.99 * n))] if n else float("nan"),
            "fallback_steps": float(self.fallback_steps),
            "rejected_commands": float(self.rejected_commands),
            "wrong_step_commands": float(self.wrong_step_commands),
            "duplicate_commands": float(self.duplicate_commands),
            "foreign_commands": float(self.foreign_commands),
            "held_for_recorder_s": self.held_s,
        }

    def _finish(self) -> None:
        self.done = True
        finish_run(self)

    # ------------------------------------------------------------------ watchdog
    def _watchdog(self) -> None:
        now = time.monotonic()
        if self.done or self._held:
            return
        if not self.started:
            # The recorder's ready says its readers matched our writers; our writers must
            # have matched its readers too, or the first messages could go unsent.
            recorder = self._recorder_ready and self.recorder_gate()
            ready = (not self.wait_for_recorder or recorder) and (
                self._cmd_sub.get_publisher_count() > 0 or now - self._t_created > self.startup_timeout_s
            )
            if ready:
                self._start()
            return
        have_truth = self.k in self._truth
        if have_truth and self._cmd is None:
            # The start-up timeout covers the EMS's first answer only; once the run fell
            # back or had a command, every step waits step_timeout_s.
            first = not self._ever_commanded and self.fallback_steps == 0
            timeout = self.startup_timeout_s if first else self.step_timeout_s
            if now - self._t_wait > timeout:
                self._fallback()
                return
        elif not have_truth and min(now - self._t_wait, now - self._t_feed_warn) > FEED_WARN_PERIOD_S:
            self._t_feed_warn = now
            self.get_logger().warning(f"step {self.k}: still waiting for 'feed/truth'")
        if now - self._t_announce > self.republish_period_s:
            self._announce()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``plant_sim`` (``ros2 run comems4build_ros plant_sim``)."""
    return run_node(PlantSim, args, NODE_NAME)


if __name__ == "__main__":
    raise SystemExit(main())
