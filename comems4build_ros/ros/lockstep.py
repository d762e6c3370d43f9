"""The master of the lock-step loop: the protocol that ``plant_sim`` and ``mqtt_bridge`` share.

A lock-step master announces step ``k`` (the state at its start on ``state/*``, then
``plant/step`` = ``k``), waits for the EMS's command for ``k``, applies it (the plant
model, or the house behind MQTT), publishes the step's ``plant/record`` and ``/clock``,
and goes on to ``k + 1`` (docs/ros_nodes.md "Lock-step protocol"). :class:`LockStep`, which
each master composes, owns what does not depend on what is stepped:

* the loop's timing parameters (:data:`LOOP_PARAMS`, each positive) and ``stall_steps``,
  which may change during a run (``ros2 param set``: from the next watchdog tick), and
  the read-only flags (``wait_for_recorder``, ``recorder_node``, ``exit_when_done``,
  ``ems_token`` or ``ems_token_file``, ``record_window_steps``, ``publish_clock``);
* run tokens (:meth:`accept_token`): the commands of one EMS only, ``ems_token`` or the
  token of the run's first valid command; any other is counted as foreign;
* the start gate (:meth:`recorder_ready`): with ``wait_for_recorder``, the recorder's
  ``recorder/ready`` and this node's writers matched to the recorder's readers;
* back-pressure (:meth:`behind`): no step announced more than ``record_window_steps``
  beyond ``recorder/progress``, the time held counted; a warning when the recorder leaves
  before the end of the run (:meth:`_check_recorder_stays`);
* the run's fault counters and statistics (:meth:`stats`), fault events on
  ``plant/events`` (:meth:`event`), ``/clock`` (:meth:`publish_clock`: one clock per run,
  parameter ``publish_clock``);
* stalls (:meth:`check_stall`, with ``stall_steps`` > 0): the run ends with exit code
  :data:`~comems4build_ros.wire.exits.EXIT_STALLED`, naming the silent party, once the
  EMS has sent nothing for ``stall_steps`` step time-outs in a row (every one of them a
  fallback step), or once no step was possible for ``stall_steps`` step time-outs while
  the master waited for anything else than the EMS (the feed's inputs, the recorder's
  progress, the house behind MQTT: :meth:`waiting_for`);
* the end of the run (:meth:`finish_run`): the statistics line, ``plant/done``, the
  acknowledgement of the last messages, and the exit once the recorder has left.

The master node creates its own publishers of ``state/*`` and its subscriptions of
``ems/command`` and ``feed/truth``, and tells the lock-step what to do when the recording
caught up (``on_progress``) and what it waits for (``waiting_for``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future
from std_msgs.msg import Bool, String, UInt32

from comems4build_ros.ros.node import RECORDER_NODE, ArrayPublisher, ContractEndpoints, RecorderGate, layout_sizes
from comems4build_ros.ros.package_node import NodeParameters, steady_timer
from comems4build_ros.ros.process import report_cause
from comems4build_ros.wire.cdr import clock_cdr, uint32_cdr
from comems4build_ros.wire.contract import CLOCK_TOPIC
from comems4build_ros.wire.exits import EXIT_STALLED
from comems4build_ros.wire.tokens import authentic, read_token_file, secret_key

#: Default wait for the command of a step once the EMS has answered at least once [s].
STEP_TIMEOUT_S = 5.0
#: Default wait for the first command of the run (EMS start-up, imports, solver set-up) [s].
STARTUP_TIMEOUT_S = 120.0
#: Default period of the repeated announcement while the master waits [s].
REPUBLISH_PERIOD_S = 0.5
#: Default period of the watchdog timer (timeouts, repeats; parameter ``watchdog_period_s``) [s].
WATCHDOG_PERIOD_S = 0.02
#: A gap between two watchdog ticks longer than this (and than 50 periods) means this node itself
#: did not run (paused with SIGSTOP, or starved of CPU): its time-outs restart instead of blaming
#: the EMS or the feed for the time it could not see [s].
OWN_PAUSE_S = 2.0
#: Timing parameters of the loop [s] and their defaults.
LOOP_PARAMS = {
    "step_timeout_s": STEP_TIMEOUT_S,
    "startup_timeout_s": STARTUP_TIMEOUT_S,
    "republish_period_s": REPUBLISH_PERIOD_S,
    "watchdog_period_s": WATCHDOG_PERIOD_S,
}
#: Default of ``record_window_steps``: with ``wait_for_recorder`` no step is announced more
#: than this beyond the last step the recorder has written without a gap
#: (``recorder/progress``); the contract's keep-last depth (1000) exceeds it, so no
#: message can be overwritten before the recorder has it [steps].
RECORD_WINDOW_STEPS = 256
#: Wait for the acknowledgement of the last messages before exiting [s] ...
ACK_TIMEOUT_S = 5.0
#: ... checked this often [s].
ACK_POLL_S = 0.02
NS_PER_S = 1_000_000_000
#: State topics: contract topic -> PlantState attributes in layout order (after step).
STATE_TOPICS: dict[str, tuple[str, ...]] = {
    "state/t_air_c": ("t_air_c",),
    "state/v_dhw_l": ("v_dhw_l",),
    "state/soc": ("soc",),
    "state/loh": ("loh",),
    "state/hp_mod": ("hp_mod",),
    "state/fc_on": ("fc_on",),
    "state/el_on": ("el_on",),
    "state/t_wall": ("t_wall_in_c", "t_wall_out_c"),
}
#: Shortest wait for the recorder's progress before a held run counts as stalled [s]: on a
#: loaded machine a reliable writer's retransmission waits for its next heartbeat (seconds),
#: so a live recorder can be still for a while (measured: 6 s at a load average of 9 on 2 cores).
RECORDER_STALL_MIN_S = 60.0
#: Period of the check that the recorder is still in the run (with ``wait_for_recorder``) [s].
RECORDER_CHECK_S = 1.0
#: Names of the fault counters, in the order of ``plant/record`` and of the statistics.
FAULT_COUNTERS = ("fallback_steps", "rejected_commands", "wrong_step_commands", "duplicate_commands",
                  "foreign_commands")


class LockStep:
    """The master's side of the lock-step loop, composed by ``plant_sim`` and ``mqtt_bridge`` (see
    the module docstring): its parameters, the run's state and counters, the recorder's
    back-pressure and gate, stalls, the fault events and the end of the run.

    Parameters
    ----------
    node : the master node (``plant_sim``, ``mqtt_bridge``), whose endpoints and timers these are
    parameters : the node's parameters (the loop's are declared here)
    endpoints : the node's contract endpoints
    on_progress : called when ``recorder/progress`` grew: a held announcement may go out now
    waiting_for : what the master waits for now, ``(words naming the node or device, contract
        topic whose publishers to name or None)``; None while it waits for the EMS's command
        (the step time-out and :attr:`silent_fallbacks` cover that). Called at every watchdog
        tick: no graph queries there. A wait for ``recorder/progress`` is a stall only after
        :data:`RECORDER_STALL_MIN_S` at least.
    silent_ems_cause : words appended to the "EMS is silent" stall when the master sees why (a
        silent EMS may itself wait for another node), given ``time.monotonic()`` [s]; none by default
    extra_timing : further positive timing parameters [s] of the master and their defaults

    Attributes
    ----------
    step_period_s : a wall clock's step period [s] (0 in lock-step): the stall window is at
        least ``stall_steps`` of them (:meth:`stall_window_s`)
    """

    def __init__(self, node: Node, parameters: NodeParameters, endpoints: ContractEndpoints,
                 on_progress: Callable[[], None], waiting_for: Callable[[], tuple[str, str | None] | None],
                 silent_ems_cause: Callable[[float], str] | None = None,
                 extra_timing: dict[str, float] | None = None) -> None:
        self.node = node
        self.endpoints = endpoints
        self._on_progress = on_progress
        self._waiting_for = waiting_for
        self._silent_ems_cause = silent_ems_cause or (lambda now: "")
        self.step_period_s = 0.0
        self.params = parameters.plant_params()
        # The loop's timing may change during a run (ros2 param set): each takes effect at the
        # next watchdog tick; the watchdog's own period changes the timer's.
        for name, default in {**LOOP_PARAMS, **(extra_timing or {})}.items():
            setattr(self, name, parameters.param(name, default, on_change=self._timing_setter(name)))
        self.wait_for_recorder = parameters.param("wait_for_recorder", False)
        self.recorder_node = parameters.param("recorder_node", RECORDER_NODE)
        self.gate = RecorderGate(node, self.wait_for_recorder, self.recorder_node)
        self.exit_when_done = parameters.param("exit_when_done", True)
        token_file = parameters.param("ems_token_file", "")
        # a run secret (file): every command authenticated; else a plain token (parameter) or none
        self._key = secret_key(read_token_file(token_file)) if token_file else None
        ems_token = parameters.param("ems_token", 0)
        self.ems_token = 0 if token_file else ems_token
        self.stall_steps = parameters.param("stall_steps", 0, on_change=lambda v: setattr(self, "stall_steps", v))
        self.record_window_steps = parameters.param("record_window_steps", RECORD_WINDOW_STEPS)
        self.publish_clock_on = parameters.param("publish_clock", True)
        self.sizes = layout_sizes(self.params)
        self.dt_ns = int(round(self.params.simulation.time_step_h * 3600.0 * NS_PER_S))
        # the run
        self.k = 0  # the step announced or waited for
        self.n_steps: int | None = None
        self.started = False
        self.done = False
        self.stalled = False
        self.finished = Future()
        self.silent_fallbacks = 0  # fallback steps in a row without any command of the run's EMS
        self._t_moved = time.monotonic()  # last step, recorder progress, or wait for the EMS (check_stall)
        self._t_tick = time.monotonic()  # last watchdog tick (own_pause)
        self.paused_s = 0.0  # time this node itself did not run in the run [s]
        for name in FAULT_COUNTERS:
            setattr(self, name, 0)
        self.held_s = 0.0  # time announcements waited for the recorder (back-pressure) [s]
        self._t_held: float | None = None
        self._token = float(self.ems_token) if self.ems_token > 0 else None  # run token of applied commands
        self._recorder_ready = False
        self._recorded = 0  # steps the recorder has written without a gap (recorder/progress)
        self._clock_ns = -1  # the simulated time last published on /clock [ns]
        self._watchdog_timer: Any = None
        # what every master publishes and reads besides its state and commands
        self.record = ArrayPublisher(self.endpoints, "plant/record", self.sizes)
        self._step_pub = self.endpoints.publisher("plant/step")
        self._clock_pub = self.endpoints.publisher(CLOCK_TOPIC) if self.publish_clock_on else None
        self._done_pub = self.endpoints.publisher("plant/done")
        self._events_pub = self.endpoints.publisher("plant/events")
        self.endpoints.subscription("recorder/ready", self._on_recorder_ready)
        self.endpoints.subscription("recorder/progress", self._on_recorder_progress)
        self._recorder_left = False
        if self.wait_for_recorder:
            steady_timer(self.node, RECORDER_CHECK_S, self._check_recorder_stays)

    @property
    def recorded(self) -> int:
        """Steps the recorder has written without a gap (``recorder/progress``)."""
        return self._recorded

    def _timing_setter(self, name: str) -> Any:
        """``on_change`` of a timing parameter: the new value is used from the next watchdog tick."""

        def apply(value: float) -> None:
            setattr(self, name, float(value))
            if name == "watchdog_period_s" and self._watchdog_timer is not None:
                self._watchdog_timer.timer_period_ns = int(float(value) * NS_PER_S)

        return apply

    def start_watchdog(self, callback: Any) -> None:
        """The watchdog timer (period ``watchdog_period_s``, changeable during the run)."""
        self._watchdog_timer = steady_timer(self.node, self.watchdog_period_s, callback)

    # ------------------------------------------------------------------ recorder
    def _on_recorder_ready(self, msg: Bool) -> None:
        self._recorder_ready = bool(msg.data)

    def _on_recorder_progress(self, msg: UInt32) -> None:
        if int(msg.data) > self._recorded:
            self._recorded = int(msg.data)
            self._t_moved = time.monotonic()
        self._on_progress()

    def _check_recorder_stays(self) -> None:
        """With ``wait_for_recorder``: warn once (a ``recorder_left`` event on ``plant/events`` and
        in the log) when the recorder has left the graph while the run is in progress.

        The run goes on: the recording of its remaining steps is lost, and back-pressure holds
        the run ``record_window_steps`` beyond the last step recorded (with ``stall_steps`` the
        run then ends as stalled, naming the recorder). A recorder killed outright leaves the
        graph when DDS notices (the participant's lease), a stopped one at once."""
        if not self.started or self.done or self._recorder_left:
            return
        infos = self.node.get_subscriptions_info_by_topic(self.record.publisher.topic_name)
        if any(i.node_name == self.recorder_node for i in infos):
            return
        self._recorder_left = True
        self.event("recorder_left", f"the recorder '{self.recorder_node}' left the run before its end (step "
                                    f"{self.k}, recorded: {self._recorded}): the steps from here on are not "
                                    f"recorded, and the run holds {self.record_window_steps} steps beyond the "
                                    "last one recorded")

    def recorder_ready(self) -> bool:
        """Whether the run may start as far as the recorder is concerned: without
        ``wait_for_recorder`` at once; else once the recorder said ``recorder/ready`` (its
        readers matched) and this node's writers matched its readers too (the first
        messages could otherwise go unsent, :meth:`~comems4build_ros.ros.node.RecorderGate.is_open`)."""
        return not self.wait_for_recorder or (self._recorder_ready and self.gate.is_open())

    def behind(self, k: int) -> bool:
        """With ``wait_for_recorder``: announcing step ``k`` would run more than
        ``record_window_steps`` beyond the gap-free recording (back-pressure). The time
        from the first ``True`` to the next ``False`` is added to ``held_s``."""
        behind = self.wait_for_recorder and k - self._recorded > self.record_window_steps
        now = time.monotonic()
        if behind and self._t_held is None:
            self._t_held = now
        elif not behind and self._t_held is not None:
            self.held_s += now - self._t_held
            self._t_held = None
        return behind

    # ------------------------------------------------------------------ commands
    def accept_token(self, data: Any, step: int) -> bool:
        """Whether the valid command ``data`` (float64 array, the token last) comes from
        the run's EMS (:mod:`comems4build_ros.wire.tokens`): with a run secret its token is
        the authentication code of its other elements; else the token is ``ems_token``, or
        else that of the run's first valid command. Any other command is counted in
        ``foreign_commands``, logged on plant/events and ignored."""
        token = data[-1]
        if self._key is not None:
            if not authentic(self._key, data):
                self.foreign_commands += 1
                self.event("foreign", f"topic 'ems/command': command for step {step} with token {int(token)} "
                                      "ignored (not authenticated by the run's secret)")
                return False
        elif self._token is None:
            self._token = token  # the first valid command names the run's EMS
            self.node.get_logger().info(f"commands of token {int(token)} accepted from now on")
        elif token != self._token:
            self.foreign_commands += 1
            self.event("foreign", f"topic 'ems/command': command for step {step} with token {int(token)} ignored "
                                  f"(the run's EMS has token {int(self._token)})")
            return False
        self.silent_fallbacks = 0  # the run's EMS is there (even if this command comes too late)
        return True

    # ------------------------------------------------------------------ stalls
    @property
    def complete(self) -> bool:
        """A signal from now on is a normal end (exit code 0): the last step is done and,
        with ``exit_when_done``, the recorder has left (while it has not, a node leaving
        would take its last messages out of the recorder's queues: the run is cut)."""
        return self.done and not self.stalled and (not self.exit_when_done or self.finished.done())

    @property
    def over(self) -> bool:
        """The last step is done (the node may still wait for the recorder to leave)."""
        return self.done and not self.stalled

    def note_fallback(self, ems_silent: bool) -> None:
        """Count a fallback step: ``ems_silent`` if the EMS's command did not come in time
        (a fallback for another reason, e.g. a bad measurement, says nothing about the EMS)."""
        self.silent_fallbacks = self.silent_fallbacks + 1 if ems_silent else 0

    def note_step(self) -> None:
        """A step was made (:meth:`check_stall`)."""
        self._t_moved = time.monotonic()

    def stall_window_s(self) -> float:
        """How long a wait may last before it is a stall: ``stall_steps`` step time-outs, or step
        periods of a wall clock (:attr:`step_period_s`) if longer [s]."""
        return self.stall_steps * max(self.step_timeout_s, self.step_period_s)

    def publishers_of(self, topic: str) -> str:
        """The nodes publishing contract topic ``topic`` now, in words (for stall messages)."""
        infos = self.node.get_publishers_info_by_topic(self.node.resolve_topic_name(topic))
        names = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos})
        return f"publisher: {', '.join(names)}" if names else "no publisher left"

    def own_pause(self, now: float) -> float:
        """The time [s] this node did not run before this watchdog tick (0 for a normal tick).

        A master that was paused (SIGSTOP) or starved of CPU for longer than
        :data:`OWN_PAUSE_S` finds, when it runs again, its step time-out long passed while the
        EMS's command may already wait in its queue: the pause is its own, so the stall clock
        restarts (the master restarts its step wait) and an event names it, instead of a
        fallback counted as a late command of the EMS. ``now``: ``time.monotonic()`` [s].
        """
        gap = now - self._t_tick
        self._t_tick = now
        if gap <= max(OWN_PAUSE_S, 50 * self.watchdog_period_s):
            return 0.0
        self.paused_s += gap
        self._t_moved += gap
        self.event("paused", f"node '{self.node.get_name()}' itself did not run for {gap:.1f} s (paused, e.g. by "
                             "SIGSTOP, or starved of CPU): the wait for the step's command restarts; no fallback is "
                             "counted against the EMS for that time")
        return gap

    def check_stall(self, now: float) -> bool:
        """End the run as stalled (:meth:`stall`) if, with ``stall_steps`` > 0, the EMS has
        been silent for ``stall_steps`` fallback steps in a row, or no step was possible for
        :meth:`stall_window_s` while the master waited for something else (:meth:`waiting_for`).
        Called by the master's watchdog; returns whether the run stalled."""
        if not self.stall_steps or not self.started or self.done:
            return self.stalled
        if self.silent_fallbacks >= self.stall_steps:
            self.stall(f"the EMS is silent: no command on 'ems/command' for {self.silent_fallbacks} steps in a row "
                       f"(step time-out {self.step_timeout_s:g} s; {self.publishers_of('ems/command')})"
                       f"{self._silent_ems_cause(now)}")
            return True
        waiting = self._waiting_for()
        if waiting is None:
            self._t_moved = now
        elif now - self._t_moved > (self.stall_window_s() if waiting[1] != "recorder/progress"
                                    else max(self.stall_window_s(), RECORDER_STALL_MIN_S)):
            what, topic = waiting
            who = f" ({self.publishers_of(topic)})" if topic else ""
            self.stall(f"no step for {now - self._t_moved:.1f} s at step {self.k} (limit: {self.stall_steps} step "
                       f"time-outs of {self.step_timeout_s:g} s): waiting for {what}{who}")
            return True
        return False

    def stall(self, cause: str) -> None:
        """End the run early: log ``cause`` (naming the silent party), publish it on
        plant/events (kind ``stall``, in the bag) and on stderr as the process's cause line,
        and finish with exit code :data:`~comems4build_ros.wire.exits.EXIT_STALLED`."""
        if self.stalled or self.finished.done():
            return
        self.stalled = True
        self.done = True  # no further step: every handler of the masters checks done
        self.event("stall", cause)
        report_cause(self.node.get_fully_qualified_name(), f"run stalled: {cause}", self.node.get_logger())
        self.finished.set_result(EXIT_STALLED)

    # ------------------------------------------------------------------ output
    def event(self, kind: str, detail: str, step: int | None = None) -> None:
        """Log a fault event and publish it on plant/events (``<step> <kind> <detail>``; the
        step the event concerns, default the current one)."""
        line = f"{self.k if step is None else step} {kind} {detail}"
        self.node.get_logger().warning(line)
        self._events_pub.publish(String(data=line))

    def publish_step(self, k: int) -> None:
        """``plant/step`` = ``k``."""
        self._step_pub.publish(uint32_cdr(k))  # ready CDR bytes, as the arrays

    def publish_clock(self, start_unix_s: float, end: bool = True) -> None:
        """``/clock``: the end of the step that started at ``start_unix_s`` [s since the epoch]
        (``end`` false: its start, the run's first time); nothing without ``publish_clock``
        or for a time already published."""
        t_ns = int(round(start_unix_s * NS_PER_S)) + (self.dt_ns if end else 0)
        if self._clock_pub is None or t_ns <= self._clock_ns:
            return
        self._clock_ns = t_ns
        self._clock_pub.publish(clock_cdr(t_ns))

    def stats(self) -> dict[str, float]:
        """Run statistics: steps, fault counters and the time held by the recorder [s]."""
        return {"steps": float(self.k), **{name: float(getattr(self, name)) for name in FAULT_COUNTERS},
                "held_for_recorder_s": self.held_s}

    # ------------------------------------------------------------------ end of run
    def finish_run(self, stats: dict[str, float], before_done: Any = None) -> None:
        """End of the run: log the statistics line, publish plant/done and the line on
        plant/events, wait (at most :data:`ACK_TIMEOUT_S`) for their acknowledgement, then,
        if ``exit_when_done``, finish once the recorder has left (a writer that left at once
        could take its last messages out of a busy recorder's queue).

        The acknowledgements are polled by a timer (:data:`ACK_POLL_S`), not awaited in the
        callback: a container process spins every house's plant on one executor, and a
        blocking wait (DDS acknowledges on the writer's heartbeat period, seconds) would stall
        the other houses' steps at every end of run. The line is logged first: whoever
        sees plant/done can rely on it being in the log: ``stats``, the master's statistics
        (:meth:`stats` and its own). ``before_done`` (optional) is called between the log line
        and plant/done.
        """
        self.done = True
        line = " ".join(f"{k}={v:.6g}" for k, v in stats.items())
        self.node.get_logger().info(f"run done: {line}")
        if before_done is not None:
            before_done()
        self._done_pub.publish(Bool(data=True))
        self._events_pub.publish(String(data=f"{self.k} stats {line}"))
        pubs = (self.record.publisher, self._done_pub, self._events_pub)
        t0 = time.monotonic()
        now_only = Duration(nanoseconds=0)
        timer: Any = None

        def poll() -> None:
            if not all(p.wait_for_all_acked(now_only) for p in pubs) and time.monotonic() - t0 < ACK_TIMEOUT_S:
                return
            timer.cancel()
            if self.exit_when_done:
                self.gate.finish_when_recorded(self.finished, "plant/record")

        timer = steady_timer(self.node, ACK_POLL_S, poll)
