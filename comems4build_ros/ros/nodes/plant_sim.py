"""``plant_sim``: the plant simulator of a house as a ROS 2 node, master of the lock-step loop.

The node owns a :class:`comems4build_ros.core.plant.Plant` and advances it one step at a
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
   (:func:`comems4build_ros.core.ems.fallback.safe_action`), logs and counts it
   (``fallback_steps``) and moves on; the EMS takes over again as soon as it answers.
3. Step the plant, announce ``k + 1``, then publish ``plant/record`` (one timeseries row
   of the in-process loop) and ``/clock`` (end of step ``k``; the start of step 0 once its
   inputs came; only with ``publish_clock``, one clock per run).

With ``--log-level debug`` the node logs each announcement, command and step.

A house of a community (``hub:=true``, docs/community.md "Over ROS") holds its H2 store as an
account at the hub its community's coordinator keeps (:mod:`comems4build_ros.ros.hub_link`):
the plant announces step ``k`` once the coordinator's ``hub/allotment`` of ``k`` is in (the
announced ``state/loh`` is the account, ``state/el_on`` the hub's electrolysers), steps without
an electrolyser of its own (the EMS's electrolyser request is the surplus offered to the hub,
recorded as the command asked it), reports on ``hub/report`` and records the step once the
coordinator's ``hub/settlement`` of ``k`` gives the account at its end.

After the last step the node publishes ``plant/done``, waits until the record messages
are acknowledged, and exits (``exit_when_done``) with code 0. With ``wait_for_recorder`` it
starts only once the recorder has said ``recorder/ready``. With ``stall_steps`` > 0 (the
launcher sets it) a silent EMS, feed or recorder ends the run with exit code 4, naming it
(:meth:`~comems4build_ros.ros.lockstep.LockStep.check_stall`); a signal before the
last step gives exit code 3.
"""

from __future__ import annotations

import time
from array import array
from typing import Any

from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from comems4build_ros.core.community.plant import without_electrolyser
from comems4build_ros.core.community.spec import house_plant
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import ACTION_FIELDS, FLOW_FIELDS, STATE_COLUMNS, Action, Exogenous, PlantState
from comems4build_ros.ros.hub_link import HubLink
from comems4build_ros.ros.lockstep import STATE_TOPICS, LockStep
from comems4build_ros.ros.node import ArrayPublisher, ContractEndpoints
from comems4build_ros.ros.package_node import NodeParameters, debug_enabled, node_options, sim_time_logger
from comems4build_ros.ros.process import run_node
from comems4build_ros.wire.ems_command import CommandError, command_bounds, command_to_action

NODE_NAME = "plant_sim"
#: Interval of the "waiting for feed/truth" warning [s].
FEED_WARN_PERIOD_S = 10.0

class PlantSimNode(Node):
    """Plant simulator node (see the module docstring): the plant model stepped by the lock-step
    loop it composes (:class:`~comems4build_ros.ros.lockstep.LockStep`).

    Parameters
    ----------
    node_kwargs : passed to ``rclpy.node.Node`` (e.g. ``namespace``, ``parameter_overrides``)
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.debug = debug_enabled(self.log)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, NODE_NAME)
        self.loop = LockStep(self, self.parameters, self.endpoints, on_progress=self.on_recorder_progress,
                             waiting_for=self.waiting_for, silent_ems_cause=self.silent_ems_cause)
        self.run_end = self.loop  # how the run ends (comems4build_ros.ros.process.run_complete)
        self.finished = self.loop.finished
        # a house of a community: its parameters are the house as its EMS knows it (its commands are
        # checked against them); its plant has no electrolyser modules (they are at the hub)
        hub_mode = self.parameters.param("hub", False)
        self.plant = Plant(house_plant(self.loop.params) if hub_mode else self.loop.params, self._building_model())
        self.state: PlantState = self.plant.initial_state()
        sizes = self.loop.sizes
        self._bounds = command_bounds(self.loop.params)

        self._state_pubs = [(ArrayPublisher(self.endpoints, t, sizes), attrs) for t, attrs in STATE_TOPICS.items()]
        self._el_pub = next(pub for pub, attrs in self._state_pubs if attrs == ("el_on",))
        if hub_mode:
            self._state_pubs = [(pub, attrs) for pub, attrs in self._state_pubs if pub is not self._el_pub]
        self._cmd_layout = self.endpoints.contract.topic("ems/command").layout(sizes)
        self._truth_layout = self.endpoints.contract.topic("feed/truth").layout(sizes)
        self._ti = self._truth_layout.index
        self._cmd_sub = self.endpoints.subscription("ems/command", self._on_command)
        self.endpoints.subscription("feed/truth", self._on_truth)
        # a house of a community: the H2 store is an account at the coordinator's hub
        self.hub = HubLink(self.parameters, self.endpoints, self.loop, self._on_hub) if hub_mode else None
        self._pending: tuple[int, Action, Any, Exogenous, Any, bool] | None = None  # stepped, not yet recorded
        self._hub_el_on = 0.0  # the hub's electrolysers in step k-1 (state/el_on of a community's house)
        self._t_report = 0.0

        self._truth: dict[int, Any] = {}
        self._cmd: Action | None = None
        self._ever_commanded = False
        self._held = False  # announcement of step k held back until the recorder catches up
        self._cmd_data: list[float] | None = None  # payload of the pending command
        self._last_cmd: list[float] | None = None  # payload of the command applied in step k-1
        self._t_created = time.monotonic()
        self._t_wait = 0.0
        self._t_announce = 0.0
        self._t_feed_warn = 0.0
        self._t_truth = time.monotonic()  # last feed/truth message [s, monotonic]
        self._t_run0 = 0.0
        self._t_first_cmd = 0.0
        self._t_step_announced = 0.0
        self._announced = -1
        self._rtt = array("d")  # announce -> command round trips [s]
        self.loop.start_watchdog(self._watchdog)
        self.get_logger().info(
            f"plant ready: step timeout {self.loop.step_timeout_s} s, "
            f"start-up timeout {self.loop.startup_timeout_s} s, "
            f"wait for recorder: {self.loop.wait_for_recorder}"
        )

    def _building_model(self) -> Any:
        """The building model of parameter ``building`` (None: the 4R3C of the plant parameters).

        A detailed model (EnergyPlus, an FMU) runs in this process as part of the plant's step;
        EnergyPlus writes its weather from the scenario, which plant_sim loads with the feed's
        scenario parameters (the launcher gives it the same ones).
        """
        building = self.parameters.param("building_model", "rc")
        if building == "rc":
            return None
        from comems4build_ros.core.loop import building_model
        from comems4build_ros.ros.nodes.feed import SCENARIO_PARAMS, load_scenario, scenario_args

        values = {name: self.parameters.param(name, default) for name, default in SCENARIO_PARAMS.items()}
        scenario = load_scenario(*scenario_args(values, self.loop.params))
        model = building_model(building, self.loop.params, scenario)
        self.get_logger().info(f"building model: {model.name} ({building})")
        return model

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def destroy_node(self) -> None:
        """End the building model's own simulator (EnergyPlus's thread, an FMU instance), then the node."""
        self.plant.building.close()
        super().destroy_node()

    # ------------------------------------------------------------------ events
    def on_recorder_progress(self) -> None:
        """The recording caught up: announce the held step."""
        if self._held:
            self._next_step()

    def _on_hub(self) -> None:
        """An allotment or settlement of the coordinator came: end the step waiting for its
        settlement, or announce the step waiting for its allotment."""
        hub, loop = self.hub, self.loop
        assert hub is not None
        if not loop.started or loop.done:
            return
        if self._pending is not None:
            if self._pending[0] in hub.settlements:
                self._end_step()
        elif self._announced != loop.k and not self._held:
            self._next_step()

    def _next_step(self) -> None:
        """Announce step k if it may go out now: not held back by the recording (back-pressure)
        and, for a community's house, with the coordinator's allotment of k in (its account
        and the hub's electrolysers become the announced state)."""
        k = self.loop.k
        if self.loop.behind(k):
            self._held = True
            return
        self._held = False
        if self.hub is not None:
            allotment = self.hub.allotments.get(k)
            if allotment is None:
                return  # announced when it comes (_on_hub)
            self.state.loh = allotment.loh
            self._hub_el_on = 1.0 if allotment.el_on_prev else 0.0
        self._t_wait = time.monotonic()
        self._announce()

    def _on_truth(self, msg: Float64MultiArray) -> None:
        data = msg.data
        if len(data) != self._truth_layout.length:
            self.loop.event("rejected",
                            f"topic 'feed/truth': {len(data)} elements, layout has {self._truth_layout.length}")
            return
        self._t_truth = time.monotonic()  # the feed answers (every announcement, even a repeated one)
        step = int(data[0])
        if step < self.loop.k:
            return
        self._truth[step] = data
        if self.loop.n_steps is None:
            self.loop.n_steps = int(data[1])
        if step == 0:  # the run's first time: the start of step 0 (later ones come with each step's end)
            self.loop.publish_clock(data[self._ti["time_unix_s"]], end=False)
        self._try_advance()

    def _on_command(self, msg: Float64MultiArray) -> None:
        try:
            step, action = command_to_action(msg.data, self._cmd_layout, self._bounds)
        except CommandError as exc:
            self.loop.rejected_commands += 1
            self.loop.event("rejected", f"topic 'ems/command' {exc}")
            return
        if not self.loop.accept_token(msg.data, step):
            return
        if step == self.loop.k - 1 and self._last_cmd is not None and list(msg.data) == self._last_cmd:
            # the EMS re-sent the command just applied (answer to a repeated announcement
            # that crossed its first answer): a retransmission, not a wrong step
            self.loop.duplicate_commands += 1
            return
        if not self.loop.started or self.loop.done or step != self.loop.k:
            self.loop.wrong_step_commands += 1
            self.loop.event("wrong_step", f"topic 'ems/command': command for step {step} ignored")
            return
        self._cmd = action
        self._cmd_data = list(msg.data)
        now = time.monotonic()
        if self.debug:
            waited_ms = 1e3 * (now - self._t_step_announced)
            self.get_logger().debug(f"step {step}: command accepted {waited_ms:.2f} ms after the announcement")
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
        kf = float(self.loop.k)
        for pub, attrs in self._state_pubs:
            pub.publish(array("d", [kf, *(float(getattr(s, a)) for a in attrs)]))
        if self.hub is not None:  # a community's house: the hub's electrolysers, not its own
            self._el_pub.publish(array("d", (kf, self._hub_el_on)))
        self.loop.publish_step(self.loop.k)
        self._t_announce = time.monotonic()
        if self._announced != self.loop.k:
            self._announced = self.loop.k
            self._t_step_announced = self._t_announce
            if self.debug:
                self.get_logger().debug(f"step {self.loop.k}: announced (state/*, plant/step)")
        elif self.debug:
            self.get_logger().debug(f"step {self.loop.k}: announced again "
                                    f"(waiting {self._t_announce - self._t_wait:.2f} s)")

    def _start(self) -> None:
        self.loop.started = True
        self._t_run0 = time.monotonic()
        self._t_wait = self._t_run0
        self.get_logger().info("starting the run")
        self._next_step()

    def _try_advance(self) -> None:
        if (self.loop.started and not self.loop.done and self._cmd is not None and self.loop.k in self._truth
                and self._pending is None and self._announced == self.loop.k):
            action, self._cmd = self._cmd, None
            self._last_cmd = self._cmd_data
            self._step(action, fallback=False)

    def _step(self, action: Action, fallback: bool) -> None:
        k = self.loop.k
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
        hub = self.hub
        self.state, flows = self.plant.step(self.state, action if hub is None else without_electrolyser(action), exo)
        self._pending = (k, action, flows, exo, t, fallback)
        if hub is not None:  # the step ends with the coordinator's settlement (_on_hub)
            hub.report(k, self.state.loh, flows, action.p_el_w)
            self._t_report = time.monotonic()
            if k in hub.settlements:
                self._end_step()
            return
        self._end_step()

    def _end_step(self) -> None:
        """Record the step just made (a community's house: its account as the settlement gives
        it), announce the next one and, after the last, end the run."""
        assert self._pending is not None
        k, action, flows, exo, t, fallback = self._pending
        self._pending = None
        if self.hub is not None:
            self.state.loh = self.hub.settlements[k]
            self.hub.forget(k)
        ti = self._ti
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
        loop = self.loop
        row.extend((t0, float(loop.fallback_steps), float(loop.rejected_commands), float(loop.wrong_step_commands),
                    float(loop.foreign_commands)))
        self.loop.k = k + 1
        self._t_wait = self.loop._t_moved = time.monotonic()
        last = self.loop.n_steps is not None and self.loop.k >= self.loop.n_steps
        if not last:
            self._next_step()  # first, so the EMS works on k + 1 while the record goes out
        self.loop.record.publish(row)
        self.loop.publish_clock(t0)
        if self.debug:
            self.get_logger().debug(f"step {k}: stepped ({'fallback' if fallback else 'command'}), plant/record and "
                                    "/clock published")
        if last:
            self.loop.finish_run(self.stats())

    def _fallback(self) -> None:
        t = self._truth[self.loop.k]
        action = safe_action(self.state.t_air_c, self.state.v_dhw_l, t[self._ti["t_min_c"]], self.loop.params)
        self.loop.fallback_steps += 1
        self.loop.note_fallback(ems_silent=True)
        self._last_cmd = None
        self.loop.event(
            "fallback",
            f"no valid command on 'ems/command' within the timeout: safe action hp_mode={action.hp_mode} "
            f"hp_mod={action.hp_mod} (fallback steps: {self.loop.fallback_steps})",
        )
        self._step(action, fallback=True)

    def stats(self) -> dict[str, float]:
        """Run statistics: steps, wall times [s], round trip announce -> command [ms], fault counters."""
        now = time.monotonic()
        rtt = sorted(self._rtt)
        n = len(rtt)
        return {
            "wall_s": now - self._t_run0 if self.loop.started else 0.0,
            "wall_from_first_command_s": now - self._t_first_cmd if self._ever_commanded else 0.0,
            "rtt_median_ms": 1e3 * rtt[n // 2] if n else float("nan"),
            "rtt_p99_ms": 1e3 * rtt[min(n - 1, int(0.99 * n))] if n else float("nan"),
            **self.loop.stats(),
        }

    # ------------------------------------------------------------------ watchdog
    def waiting_for(self) -> tuple[str, str | None] | None:
        """The recorder while an announcement is held back, the feed while ``feed/truth`` of
        the step is missing, else None (the EMS)."""
        if self._held:
            loop = self.loop
            return (f"the recorder '{loop.recorder_node}' (step {loop.k} held back until it has written step "
                    f"{loop.k - loop.record_window_steps}; written: {loop.recorded})", "recorder/progress")
        k = self.loop.k
        if self.hub is not None and self._pending is not None:
            return f"the coordinator's settlement of step {k} on 'hub/settlement'", "hub/settlement"
        if self.hub is not None and self._announced != k:
            if k == 0 and time.monotonic() - self._t_run0 < self.loop.startup_timeout_s:
                return None  # the coordinator's start-up (its community, its recorder) as the EMS's: no stall
            return f"the coordinator's allotment of step {k} on 'hub/allotment'", "hub/allotment"
        if k not in self._truth:
            return "the feed's inputs on 'feed/truth'", "feed/truth"
        return None

    def silent_ems_cause(self, now: float) -> str:
        """A healthy feed answers every announcement (repeated every ``republish_period_s``)
        with the inputs of the next steps; when it has not for a step time-out, the EMS is
        silent because its inputs stopped: name the feed (the plant itself still had inputs
        of the steps published ahead)."""
        quiet = now - self._t_truth
        if quiet <= max(self.loop.step_timeout_s, 4 * self.loop.republish_period_s):
            return ""
        return (f"; the feed has not answered the step announcements for {quiet:.1f} s, so the EMS lacks its "
                f"inputs: waiting for the feed's inputs on 'feed/truth' ({self.loop.publishers_of('feed/truth')})")

    def _watchdog(self) -> None:
        now = time.monotonic()
        if self.loop.own_pause(now):
            self._t_wait = now  # the EMS's command may wait in the queue: take it before any time-out
            self._t_announce = now
            return
        if self.loop.done or self.loop.check_stall(now) or self._held:
            return
        if not self.loop.started:
            ready = self.loop.recorder_ready() and (
                self._cmd_sub.get_publisher_count() > 0 or now - self._t_created > self.loop.startup_timeout_s
            )
            if ready:
                self._start()
            return
        if self._pending is not None:  # a community's house waits for the settlement: report again
            if self.hub is not None and now - self._t_report > self.loop.republish_period_s:
                self._t_report = now
                self.hub.resend()
            return
        if self._announced != self.loop.k:  # waiting for the coordinator's allotment
            return
        have_truth = self.loop.k in self._truth
        if have_truth and self._cmd is None:
            # The start-up timeout covers the EMS's first answer only; once the run fell
            # back or had a command, every step waits step_timeout_s.
            first = not self._ever_commanded and self.loop.fallback_steps == 0
            timeout = self.loop.startup_timeout_s if first else self.loop.step_timeout_s
            if now - self._t_wait > timeout:
                self._fallback()
                return
        elif not have_truth and min(now - self._t_wait, now - self._t_feed_warn) > FEED_WARN_PERIOD_S:
            self._t_feed_warn = now
            self.get_logger().warning(f"step {self.loop.k}: still waiting for 'feed/truth'")
        if now - self._t_announce > self.loop.republish_period_s:
            self._announce()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``plant_sim`` (``ros2 run comems4build_ros plant_sim``)."""
    return run_node(PlantSimNode, args, NODE_NAME)


if __name__ == "__main__":
    raise SystemExit(main())
