"""``mqtt_bridge``: the topic contract on one side, a house behind MQTT on the other.

The bridge stands in for ``plant_sim``: it publishes the plant's topics (``state/*``,
``plant/step``, ``plant/record``, ``/clock``, ``plant/done``, ``plant/events``) from the
house's MQTT measurements and forwards each ``ems/command`` as MQTT set-points
(heat-pump mode and modulation, fuel-cell power, battery power) with the topics, units
and scaling of the topic map (``config/mqtt.yaml``). With the map's PV and load meters it
also publishes ``feed/measured`` (the feed then runs with ``publish_measured:=false``).
The EMS nodes and the step protocol are those of the ROS-only loop, with plant_sim's
run contract: commands of one run token only (``ems_token``, else the first valid
command's; others counted as ``foreign_commands``), in lock-step no step announced more
than ``record_window_steps`` beyond ``recorder/progress`` (with ``wait_for_recorder``),
and the end of the run through :meth:`~comems4build_ros.ros.lockstep.LockStep.finish_run`
(transient-local ``plant/done``, then the bridge stays until the recorder has left). With
``stall_steps`` > 0 (the launcher sets it) the run ends with exit code 4 naming the silent
party: the EMS (no command for ``stall_steps`` steps), the recorder, or the house and
the broker (nothing from the house for ``stall_steps`` step time-outs, or periods of a
wall clock: a broker that is down and does not come back is named with its URL).

Clock (parameter ``clock``; :mod:`comems4build_ros.mqtt.clock`):

* ``sim``: lock-step over MQTT. The bridge announces step ``k`` once every measurement
  tagged ``k`` (and the house's record of ``k - 1``) has arrived, forwards the EMS's
  command tagged ``k``, and repeats whatever the other side may have lost every
  ``republish_period_s``, so a broker restart loses no step.
* ``wall`` / ``wall:<factor>``: step ``k`` starts at ``t0 + k * period`` (``t0`` a
  multiple of the period; ``wall`` steps start on the full hour). ``measure_delay_s``
  later the bridge announces ``k`` with the latest measurements; the EMS's command is
  forwarded as soon as it comes; without one by ``t0 + (k + 0.9) * period`` the bridge
  sends the fallback. The run's ``t0`` and period go out retained on ``<base>/run``.

Safety (:mod:`comems4build_ros.mqtt.safety`): before announcing a step the watchdog
checks every measurement (missing, older than ``max_age_s`` of simulated time in the
wall modes, outside its range, unreadable). On any finding, or while the EMS switch is
off or the fallback switch on, the bridge does not hand the measurements to the EMS (no
``state/*`` and no ``feed/measured`` for that step, by design: the step is named by a
``withheld`` event on ``plant/events``, so the recorder and the bag's gap check expect no
such message), it sends :func:`comems4build_ros.core.ems.fallback.safe_action` as the
set-points of that very step and publishes an alarm on ``bridge/alarm`` (ROS) and ``<base>/alarm`` (MQTT). Every
command is clamped to the device limits and ramp limits and rate-limited
(``min_interval_s``); changes are logged on ``plant/events`` and counted. An EMS silent
past ``step_timeout_s`` also gets the fallback, as with ``plant_sim``.

Home Assistant: retained discovery configs (:mod:`comems4build_ros.mqtt.discovery`) and
availability ``online`` on every (re)connect, ``offline`` as the last will; a retained
JSON state per step (what the EMS sees, its set-points, who is in charge, the run totals
with the arithmetic of ``summary.json``, counters, alarm) and once more at the end with the
last step's record; switches ``ems`` and ``fallback``, whose retained commands (the
user's choice) are applied when the bridge (re)connects.

Run and peer (:mod:`comems4build_ros.mqtt.peer`): the bridge's retained messages name its
run (``run_id``, a new random one if not given); a retained ``<base>/step`` or
``<base>/run`` of another run is cleared and named on ``plant/events`` (``retained_cleared``).
With ``mqtt_secret_file`` (the launcher's per-run secret) it applies only measurements
and records of the house whose authentication code is valid and whose run is its own,
and seals its set-points, step and run messages the same way; every other message is
counted and named (``foreign_mqtt``), as are the messages the house refused (the
``foreign_messages`` of its records). ``broker_username`` logs in with the password of
that file (the launcher's embedded broker).

Records: the house repeats each record until the bridge acknowledges it (``records`` in
``<base>/step``), and the bridge forwards them in step order, so a broker outage loses no
record in either clock mode. A step whose own set-points did not reach the house before
it stepped (a wall clock during an outage) ran on the last set-points the house held: the
bridge names it (``setpoints_held`` on ``plant/events``, ``setpoints_held`` in its final
line).
"""

from __future__ import annotations

import json
import math
import time
from array import array
from datetime import UTC, datetime
from typing import Any

from rclpy.node import Node
from std_msgs.msg import Float64MultiArray, String

from comems4build_ros.core import kpi
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.types import ACTION_FIELDS, Action
from comems4build_ros.mqtt.client import MqttLink
from comems4build_ros.mqtt.clock import parse_clock
from comems4build_ros.mqtt.discovery import (
    AVAILABLE,
    FROM_BRIDGE,
    FROM_RECORDS,
    NOT_AVAILABLE,
    PAYLOAD_OFF,
    PAYLOAD_ON,
    SENSORS,
    SETTINGS,
    TOTAL_KEYS,
    announced,
    discovery_messages,
    setting_max,
)
from comems4build_ros.mqtt.peer import (
    ForeignMessageError,
    Peer,
    check_run_id,
    new_run_id,
    parse_run_json,
    read_peer_key,
)
from comems4build_ros.mqtt.plant_sim import BRIDGE_RECORD_FIELDS
from comems4build_ros.mqtt.safety import CommandLimiter, MeasurementWatchdog, Problem, SettingError, parse_setting
from comems4build_ros.mqtt.topicmap import PayloadError, load_topic_map
from comems4build_ros.ros.lockstep import STATE_TOPICS, LockStep
from comems4build_ros.ros.node import ArrayPublisher, ContractEndpoints
from comems4build_ros.ros.package_node import NodeParameters, node_options, sim_time_logger
from comems4build_ros.ros.process import run_node
from comems4build_ros.wire.contract import WITHHELD_EVENT
from comems4build_ros.wire.ems_command import CommandError, check_token

NODE_NAME = "mqtt_bridge"
#: Lock-step: alarm when the house has sent nothing for this long [s].
HOUSE_TIMEOUT_S = 10.0
#: Wall modes: announce a step this share of the period after its start (at most
#: MEASURE_DELAY_MAX_S), so that measurements taken at the start of the step are in.
MEASURE_DELAY_SHARE = 0.2
MEASURE_DELAY_MAX_S = 5.0
#: Wall modes: the EMS's command must arrive before this share of the period has passed.
COMMAND_DEADLINE_SHARE = 0.9
ACK_TIMEOUT_S = 5.0
#: Wall modes with step-tagged measurements (the simulated house): wait for the
#: measurements of step k up to this share of the period before announcing k with the
#: latest ones. At wall:3600 a 0.1 s scheduling delay of a loaded machine is 6 simulated
#: minutes; a real house sends no tags and is read at the announcement time.
WALL_TAG_WAIT_SHARE = 0.5
HP_MODE_WORDS = {0: "off", 1: "heating", 2: "dhw"}
#: After every subscription of a (re)connect was acknowledged, wait this long for the
#: retained switch commands and states (the user's choice: the broker sends them right
#: after each acknowledgement) before publishing the switch states and starting a run [s].
SWITCH_SETTLE_S = 0.3
#: Fallback kinds (``plant/events`` ``fallback <kind>:``) -> the ``in_charge`` value.
IN_CHARGE_OF_KIND = {"missing": "fallback_watchdog", "stale": "fallback_watchdog",
                     "out_of_range": "fallback_watchdog", "forced": "fallback_switch",
                     "ems_silent": "fallback_late_command"}
#: Measurements shown in percent in Home Assistant's state (state key -> measurement).
PERCENT_KEYS = {"soc_pct": "soc", "loh_pct": "loh"}


class MqttBridge(Node):
    """The bridge node (see the module docstring): the house behind MQTT stepped by the lock-step
    loop it composes (:class:`~comems4build_ros.ros.lockstep.LockStep`).

    Parameters
    ----------
    node_kwargs : passed to ``rclpy.node.Node`` (e.g. ``namespace``, ``parameter_overrides``)
    """

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, NODE_NAME)
        self.loop = LockStep(self, self.parameters, self.endpoints, on_progress=self.on_recorder_progress,
                             waiting_for=self.waiting_for, extra_timing={"house_timeout_s": HOUSE_TIMEOUT_S})
        self.run_end = self.loop  # how the run ends (comems4build_ros.ros.process.run_complete)
        self.finished = self.loop.finished
        client_id = self._read_parameters()
        self.dt_h = self.loop.params.simulation.time_step_h
        sizes = self.loop.sizes
        m = self.map.measurements
        self._state_pubs = [(ArrayPublisher(self.endpoints, t, sizes), attrs) for t, attrs in STATE_TOPICS.items()
                            if t != "state/t_wall" or ("t_wall_in_c" in m and "t_wall_out_c" in m)]
        self._measured = (ArrayPublisher(self.endpoints, "feed/measured", sizes)
                          if "p_pv_w" in m and "p_load_w" in m else None)
        self._record_labels = self.loop.record.layout.labels
        self._alarm_pub = self.endpoints.publisher("bridge/alarm")
        self._cmd_layout = self.endpoints.contract.topic("ems/command").layout(sizes)
        self._truth_index = self.endpoints.contract.topic("feed/truth").layout(sizes).index
        self._cmd_sub = self.endpoints.subscription("ems/command", self._on_command)
        self.endpoints.subscription("feed/truth", self._on_truth)

        self.watchdog = MeasurementWatchdog(self.map)
        self.limiter = CommandLimiter.from_map(self.map, self.loop.params)
        self._topic_measurement = {spec.topic: name for name, spec in m.items()}
        self._switch_topics = {self.map.switch_topics(n)[0]: n for n in ("ems", "fallback")}
        self._switch_states = {self.map.switch_topics(n)[1]: n for n in ("ems", "fallback")}
        self.switches = {"ems": True, "fallback": False}
        self._setting_topics = {self.map.setting_topics(n)[0]: n for n in SETTINGS}
        self._setting_states = {self.map.setting_topics(n)[1]: n for n in SETTINGS}
        self.settings = {n: setting_max(self.limiter.device_limits, n) for n in SETTINGS}  # the user's, default: none
        self._switch_by_command: set[str] = set()  # switches and settings set by a command since the start
        self._switches_published = -1  # the connect count whose switch states were published

        self._reset_run_state()
        self._wake = self.create_guard_condition(self._on_mqtt)
        subs = [*self._topic_measurement, *self._switch_topics, *self._switch_states, *self._setting_topics,
                *self._setting_states, self.map.step_topic, self.map.run_topic]
        if self.map.sim_record_topic:
            subs.append(self.map.sim_record_topic)
        self.link = MqttLink(self.map.broker, client_id, subs,
                             will=(self.map.availability_topic, NOT_AVAILABLE),
                             on_connect=self._on_connect, wake=self._wake.trigger)
        self.link.start()
        self.loop.start_watchdog(self._watchdog)
        self.get_logger().info(
            f"bridge to {self.map.broker.url} (user: {self.map.broker.username or 'anonymous'}, "
            f"TLS: {self.map.broker.tls}), run '{self.peer.run_id}' (authentication codes: "
            f"{'on' if self.peer.key else 'off'}), clock {self.clock.spec()}, {len(m)} measurements, "
            f"device limits {self.limiter.limits}"
        )

    def _read_parameters(self) -> str:
        """The broker login, topic map, run id and key, clock and measurement delay from the
        node's parameters (each checked); returns the MQTT client id."""
        secret_file = self.parameters.param("mqtt_secret_file", "")
        username = self.parameters.param("broker_username", "")
        if username and not secret_file:
            raise ValueError(f"node '{NODE_NAME}': parameter 'broker_username' needs 'mqtt_secret_file' (its password)")
        topic_map, broker_url = self.parameters.param("topic_map", ""), self.parameters.param("broker_url", "")
        self.map = load_topic_map(topic_map or None, broker_url or None, username or None,
                                  secret_file if username else None)
        self.peer = Peer(check_run_id(self.parameters.param("run_id", "") or new_run_id()),
                         read_peer_key(secret_file) if secret_file else None)
        self.clock = parse_clock(self.parameters.param("clock", "sim"), self.loop.params.simulation.time_step_h)
        self.loop.step_period_s = self.clock.period_s if self.clock.wall else 0.0  # the stall window
        delay = self.parameters.param("measure_delay_s", -1.0)
        self.measure_delay_s = delay if delay >= 0 else min(MEASURE_DELAY_SHARE * self.clock.period_s,
                                                            MEASURE_DELAY_MAX_S)
        client_id = self.parameters.param("client_id", "comems4build_bridge")
        if self.clock.wall and self.measure_delay_s >= COMMAND_DEADLINE_SHARE * self.clock.period_s:
            raise ValueError(f"node '{NODE_NAME}': parameter 'measure_delay_s' must be below "
                             f"{COMMAND_DEADLINE_SHARE:g} of the step period ({self.clock.period_s:g} s)")
        return client_id

    def _reset_run_state(self) -> None:
        """The state of a run before its first step: lock-step phase, records, totals, fallbacks."""
        self.phase = "measure"  # measure -> command -> sent (lock-step); command/sent per wall step
        self.t0_unix_s: float | None = None
        self._truth: dict[int, tuple[float, float]] = {}  # step -> (time_unix_s, t_min_c)
        self._records: dict[int, dict[str, float]] = {}
        self.next_record = 0
        self.fallback_for: dict[int, bool] = {}
        self.bad_measurements = 0
        self.untagged_announcements = 0  # wall modes: steps announced without measurements tagged for them
        self._tagged = all(spec.step_key for spec in self.map.measurements.values())
        self.alarms = 0
        self._ever_commanded = False
        self._last_cmd: list[float] | None = None
        self._last_action = Action()
        self._sent: list[tuple[str, bytes]] = []
        self._held: tuple[int, Action, bool] | None = None
        self._announced = -1  # the step announced last (<base>/step)
        self._alarm_step = -1
        self._house_alarmed = -1
        self._t_created = time.monotonic()
        self._t_phase = self._t_created
        self._t_announce = 0.0
        self._t_sent = 0.0
        self._t_house = self._t_created
        self._columns: dict[str, list[float]] = {c: [] for c in kpi.REQUIRED_COLUMNS if c != "time"}  # run totals
        self._last_row: dict[str, float] | None = None  # the last forwarded record
        self.totals: dict[str, float] = {}  # state key -> run total so far (TOTAL_KEYS)
        self.run_start: str | None = None  # ISO time of the run's start (last_reset of the totals)
        self.in_charge: str | None = None
        self.fallback_reason = ""
        self.fallback_kinds: dict[str, int] = {}  # fallback kind -> steps
        self.setpoints_held = 0  # steps the house ran on an earlier step's set-points
        self.retained_cleared = 0
        self.replayed_measurements = 0
        self._house_foreign = 0  # foreign messages the house reported (its records)
        self._foreign_reported = 0
        self._ha_state_text = json.dumps(self._ha_state(None))


    # ------------------------------------------------------------------ MQTT side
    def _on_connect(self) -> None:
        """(paho thread) The state, discovery, availability and the run message again.

        The state goes first: a client that sees ``online`` sees this run's state, never
        the previous run's retained one. The switch states follow from the ROS thread once
        the retained commands have arrived (:meth:`_settle_switches`).
        """
        link = self.link
        link.publish(self.map.state_topic, self._ha_state_text, retain=True)
        if self.map.discovery:
            for topic, payload in discovery_messages(self.map, self.limiter.device_limits):
                link.publish(topic, json.dumps(payload) if payload is not None else "", retain=True)
        link.publish(self.map.availability_topic, AVAILABLE, retain=True)
        if self.t0_unix_s is not None:
            link.publish(self.map.run_topic, self._run_payload(), retain=True)

    def _run_payload(self) -> bytes:
        body = json.dumps({"clock": self.clock.spec(), "t0_unix_s": self.t0_unix_s, "period_s": self.clock.period_s})
        return self.peer.wrap(self.map.run_topic, body.encode())

    def _settle_switches(self, now: float) -> bool:
        """Whether the switches are settled after the last connect (every subscription
        acknowledged :data:`SWITCH_SETTLE_S` ago, and the retained messages that came with
        them taken in); publishes their states once per connect."""
        t = self.link.t_subscribed
        if t is None or now - t < SWITCH_SETTLE_S:
            return False
        if self._switches_published != self.link.connects:
            self._on_mqtt()  # the retained commands queued by now: applied before any step
            self._switches_published = self.link.connects
            for name, on in self.switches.items():
                self.link.publish(self.map.switch_topics(name)[1], PAYLOAD_ON if on else PAYLOAD_OFF, retain=True)
            for name, value in self.settings.items():
                self.link.publish(self.map.setting_topics(name)[1], f"{value:g}", retain=True)
        return True

    def _on_mqtt(self) -> None:
        m = self.map
        for msg in self.link.drain():
            name = self._topic_measurement.get(msg.topic)
            if name is not None:
                self._on_measurement(name, msg.payload, msg.t_recv)
            elif msg.topic == m.sim_record_topic:
                try:
                    self._on_record(self.peer.unwrap(msg.topic, msg.payload))
                    self._t_house = msg.t_recv
                except ForeignMessageError as exc:
                    self._foreign(exc)
            elif msg.topic in self._switch_topics:
                self._on_switch(self._switch_topics[msg.topic], msg.payload, command=True)
            elif msg.topic in self._switch_states:
                if msg.retain:  # the state this bridge (or an earlier one) confirmed: the user's last choice
                    self._on_switch(self._switch_states[msg.topic], msg.payload, command=False)
            elif msg.topic in self._setting_topics:
                self._on_setting(self._setting_topics[msg.topic], msg.topic, msg.payload, command=True)
            elif msg.topic in self._setting_states:
                if msg.retain:
                    self._on_setting(self._setting_states[msg.topic], msg.topic, msg.payload, command=False)
            elif msg.topic in (m.step_topic, m.run_topic):
                self._on_own_retained(msg.topic, msg.payload)
        self._advance()

    def _on_measurement(self, name: str, payload: bytes, t_recv: float) -> None:
        try:
            value, step = self.map.measurements[name].decode(self.peer.unwrap(self.map.measurements[name].topic,
                                                                              payload))
        except ForeignMessageError as exc:
            self._foreign(exc)
            return
        except PayloadError as exc:
            self.bad_measurements += 1
            self.loop.event("rejected", f"measurement '{name}': {exc}")
            # lock-step: the house sends only the step the bridge waits for, so
            # the unreadable value stands for it (and gets the fallback)
            value, step = math.nan, (self.loop.k if self.phase == "measure" and not self.clock.wall else None)
        last = self.watchdog.latest.get(name)
        if step is not None and last is not None and last.step is not None and step < last.step:
            self.replayed_measurements += 1  # a repeat or replay of an earlier step: not for a later one
            return
        self.watchdog.update(name, value, step, t_recv)
        self._t_house = t_recv

    def _foreign(self, exc: ForeignMessageError) -> None:
        """A message not from the run's peer: counted (:attr:`peer`), named on plant/events (the
        first ones, then every hundredth), not applied."""
        n = self.peer.foreign_total
        if n <= 3 or n % 100 == 0:
            self.loop.event("foreign_mqtt", f"{exc} (not applied; {n} foreign message(s) so far)")

    def _on_own_retained(self, topic: str, payload: bytes) -> None:
        """A message on this bridge's step or run topic: its own (ignored), or a retained one
        of another run, which is cleared (an empty retained message) and named."""
        if not payload:
            return
        try:
            run = parse_run_json(topic, payload).run
        except ValueError:
            run = None
        if run == self.peer.run_id:
            return
        self.retained_cleared += 1
        self.link.publish(topic, b"", retain=True)
        self.loop.event("retained_cleared", f"retained '{topic}' of {('run ' + repr(run)) if run else 'no run'} "
                                       f"({payload[:60]!r}) cleared: not this run's ('{self.peer.run_id}')")
        if self.loop.started and topic == self.map.run_topic and self.t0_unix_s is not None and not self.loop.done:
            self.link.publish(topic, self._run_payload(), retain=True)  # in case the clear overtook ours
        elif self.loop.started and topic == self.map.step_topic:
            self._publish_step_msg()

    def _on_record(self, payload: bytes) -> None:
        try:
            rec = json.loads(payload)
            step = int(rec["step"])
        except (ValueError, KeyError, TypeError):
            self.loop.event("rejected", f"topic '{self.map.sim_record_topic}': unreadable record")
            return
        if step >= self.next_record:
            self._records[step] = rec

    def _on_switch(self, name: str, payload: bytes, command: bool) -> None:
        text = payload.decode("utf-8", errors="replace").strip().upper()
        if not text:
            return  # a cleared retained command
        if text not in (PAYLOAD_ON, PAYLOAD_OFF):
            self.loop.event("rejected", f"switch '{name}': payload {text[:20]!r} is not ON/OFF")
            return
        if not command and name in self._switch_by_command:
            return  # a command (the newer word) already set it
        if command:
            self._switch_by_command.add(name)
        changed = self.switches[name] != (text == PAYLOAD_ON)
        self.switches[name] = text == PAYLOAD_ON
        if command:
            self.link.publish(self.map.switch_topics(name)[1], text, retain=True)
        if changed or command:
            self.loop.event("switch", f"{name} {text}{'' if command else ' (kept from before the restart)'}")

    def _on_setting(self, name: str, topic: str, payload: bytes, command: bool) -> None:
        """A user's setting (Home Assistant ``number``): applied from the next command on."""
        if not payload:
            return  # a cleared retained message
        key = f"setting:{name}"
        if not command and key in self._switch_by_command:
            return
        try:
            value = parse_setting(topic, payload, 0.0, setting_max(self.limiter.device_limits, name))
        except SettingError as exc:
            self.loop.event("rejected", f"setting '{name}': {exc}")
            return
        if command:
            self._switch_by_command.add(key)
        changed = value != self.settings[name]
        self.settings[name] = value
        lo, hi = self.limiter.set_power_limit(SETTINGS[name][2], value)
        if command:
            self.link.publish(self.map.setting_topics(name)[1], f"{value:g}", retain=True)
        if changed or command:
            self.loop.event("setting", f"{name} {value:g} ({SETTINGS[name][2]} within [{lo:g}, {hi:g}])"
                                  f"{'' if command else ' (kept from before the restart)'}")

    def _send_setpoints(self, k: int, action: Action, fallback: bool) -> None:
        """Set-points of ``action`` tagged ``k`` (held back while the rate limit is in force)."""
        now = time.monotonic()
        if self.clock.wall and not self.limiter.may_send(now):
            self._held = (k, action, fallback)
            return
        self._held = None
        self._sent = [(spec.topic, self.peer.wrap(spec.topic, spec.encode(float(getattr(action, name)), k)))
                      for name, spec in self.map.setpoints.items()]
        for topic, payload in self._sent:
            self.link.publish(topic, payload)
        self.limiter.sent(now)
        self._t_sent = now
        self.fallback_for[k] = fallback
        if not fallback:
            self.in_charge = "ems"
        self._last_action = action
        self.phase = "sent"
        self._publish_ha_state(k)

    def _ha_state(self, k: int | None, final: dict[str, float] | None = None) -> dict[str, Any]:
        """Home Assistant's state JSON (:data:`~comems4build_ros.mqtt.discovery.SENSORS`);
        ``k`` None: the run has not started (every value unknown). ``final``: the last
        record, whose end-of-step state stands for the measurements after the last step."""
        state: dict[str, Any] = {"run": self.peer.run_id, "run_start": self.run_start, "step": k,
                                 "alarm": PAYLOAD_ON if k is not None and self._alarm_step == k else PAYLOAD_OFF}
        started = k is not None
        a = self._last_action
        last = self._last_row
        for s in SENSORS:
            if s.key in state or not announced(self.map, s):
                continue
            value: Any = None
            if not started:
                pass
            elif s.key in TOTAL_KEYS:
                value = self.totals.get(s.key, 0.0)
            elif s.source == FROM_RECORDS:
                value = _record_power(s.key, last) if last is not None else None
            elif s.source != FROM_BRIDGE:  # a measurement: what the EMS sees
                name = s.source
                v = final[name] if final is not None and name in final else self.watchdog.value(name)
                value = None if not math.isfinite(v) else round(100.0 * v if s.key in PERCENT_KEYS else v, 4)
            else:
                value = {
                    "in_charge": self.in_charge,
                    "fallback_reason": self.fallback_reason or None,
                    "hp_mode": HP_MODE_WORDS.get(a.hp_mode, str(a.hp_mode)),
                    "hp_mod_pct": round(100.0 * a.hp_mod, 3),
                    "p_fc_set_w": round(a.p_fc_w, 3),
                    "p_bess_set_w": round(a.p_bess_w, 3),
                    "fallback_steps": self.loop.fallback_steps,
                    "clamped_commands": self.limiter.counters.clamped_commands,
                    "foreign_messages": self.peer.foreign_total + self._house_foreign,
                }.get(s.key)
            state[s.key] = value
        return state

    def _publish_ha_state(self, k: int | None, final: dict[str, float] | None = None) -> None:
        self._ha_state_text = json.dumps(self._ha_state(k, final))
        self.link.publish(self.map.state_topic, self._ha_state_text, retain=True)

    # ------------------------------------------------------------------ ROS side
    def _alarm(self, k: int, kind: str, detail: str, action: Action | None) -> None:
        payload = {"step": k, "kind": kind, "detail": detail, "time_unix_s": time.time()}
        if action is not None:
            payload["action"] = {f: getattr(action, f) for f in ACTION_FIELDS}
        text = json.dumps(payload)
        self.alarms += 1
        self._alarm_step = k
        self._alarm_pub.publish(String(data=text))
        self.link.publish(self.map.alarm_topic, text)
        self.get_logger().error(f"alarm at step {k}: {kind}: {detail}")

    def on_recorder_progress(self) -> None:
        """The recording caught up: the next step may be due."""
        self._advance()

    def _on_truth(self, msg: Float64MultiArray) -> None:
        d = msg.data
        ti = self._truth_index
        if len(d) <= max(ti.values()):
            return
        step = int(d[0])
        self._truth[step] = (d[ti["time_unix_s"]], d[ti["t_min_c"]])
        if self.loop.n_steps is None:
            self.loop.n_steps = int(d[ti["n_steps"]])
        for s in [s for s in self._truth if s < self.loop.k - 1]:
            del self._truth[s]
        self._advance()

    def _on_command(self, msg: Float64MultiArray) -> None:
        data = list(msg.data)
        if len(data) != self._cmd_layout.length or not all(math.isfinite(v) for v in data) \
                or data[0] != int(data[0]) or data[2] != int(data[2]):
            self.loop.rejected_commands += 1
            self.loop.event("rejected", f"topic 'ems/command': malformed command {data[:6]}")
            return
        try:
            check_token(data[-1])
        except CommandError as exc:
            self.loop.rejected_commands += 1
            self.loop.event("rejected", f"topic 'ems/command' {exc}")
            return
        step = int(data[0])
        if not self.loop.accept_token(data, step):
            return
        if step == self.loop.k - 1 and data == self._last_cmd:
            self.loop.duplicate_commands += 1
            return
        if not self.loop.started or self.loop.done or step != self.loop.k or self.phase != "command":
            if not (self.phase == "sent" and step == self.loop.k):  # an answer to a repeated announcement
                self.loop.wrong_step_commands += 1
                self.loop.event("wrong_step", f"topic 'ems/command': command for step {step} ignored")
            return
        raw = Action(hp_mod=data[1], hp_mode=int(data[2]), p_fc_w=data[3], p_bess_w=data[4], p_el_w=data[5])
        action, notes = self.limiter.limit(raw)
        if notes:
            self.loop.event("clamped", "; ".join(notes))
        self._last_cmd = data
        self._ever_commanded = True
        self._send_setpoints(step, action, fallback=False)
        self._advance()

    def _announce(self, k: int) -> None:
        w = self.watchdog
        kf = float(k)
        for pub, attrs in self._state_pubs:
            values = []
            for a in attrs:
                if a in self.map.measurements:
                    values.append(w.value(a))
                elif a == "hp_mod":  # not metered: the modulation the bridge last sent
                    values.append(float(self._last_action.hp_mod) if k else 0.0)
                elif a == "el_on":  # not metered: the electrolyser was asked to run
                    values.append(1.0 if k and self._last_action.p_el_w > 0 else 0.0)
                else:  # fc_on not metered: the fuel cell was asked to run
                    values.append(1.0 if k and self._last_action.p_fc_w > 0 else 0.0)
            pub.publish(array("d", [kf, *values]))
        if self._measured is not None:
            self._measured.publish(array("d", [kf, w.value("p_pv_w"), w.value("p_load_w")]))
        self._publish_step(k)
        self._t_announce = time.monotonic()

    def _publish_step(self, k: int) -> None:
        self.loop.publish_step(k)
        self._announced = k
        self._publish_step_msg()

    def _publish_step_msg(self) -> None:
        """``<base>/step`` (retained, sealed): the step announced last and the records forwarded
        (the house's acknowledgement of both)."""
        body = json.dumps({"step": self._announced, "records": self.next_record})
        self.link.publish(self.map.step_topic, self.peer.wrap(self.map.step_topic, body.encode()), retain=True)

    def _fallback(self, k: int, kind: str, detail: str) -> None:
        w = self.watchdog
        bad = {p.measurement for p in w.check(time.monotonic(), check_age=False)}
        t_air = math.nan if "t_air_c" in bad else w.value("t_air_c")
        v_dhw = math.nan if "v_dhw_l" in bad else w.value("v_dhw_l")
        t_min = self._truth.get(k, (0.0, math.nan))[1]
        if math.isnan(t_min) and self._truth:
            t_min = self._truth[max(self._truth)][1]
        action = safe_action(t_air, v_dhw, t_min, self.loop.params)
        self.loop.fallback_steps += 1
        self.fallback_kinds[kind] = self.fallback_kinds.get(kind, 0) + 1
        self.in_charge = IN_CHARGE_OF_KIND.get(kind, "fallback_watchdog")
        self.fallback_reason = f"step {k}: {kind}: {detail}"
        self.loop.note_fallback(ems_silent=kind == "ems_silent")
        self.loop.event("fallback", f"{kind}: {detail}: safe action hp_mode={action.hp_mode} hp_mod={action.hp_mod} "
                                f"(fallback steps: {self.loop.fallback_steps})")
        self._alarm(k, kind, detail, action)
        self._send_setpoints(k, action, fallback=True)

    def _begin_step(self, k: int, problems: list[Problem]) -> None:
        """Announce step ``k`` to the EMS, or send the fallback at once (problem or switch)."""
        self.phase = "command"
        self._t_phase = time.monotonic()
        if problems:
            self._publish_step(k)  # the feed keeps pace; the EMS gets no state for k
            self.loop.event(WITHHELD_EVENT, "no state announced (safety fallback)")
            self._fallback(k, problems[0].kind, "; ".join(str(p) for p in problems))
        elif not self.switches["ems"] or self.switches["fallback"]:
            self._publish_step(k)
            self.loop.event(WITHHELD_EVENT, "no state announced (fallback forced)")
            self._fallback(k, "forced", "EMS switched off" if not self.switches["ems"] else "fallback switched on")
        else:
            self._announce(k)

    # ------------------------------------------------------------------ stepping
    def _forward_records(self) -> None:
        forwarded = False
        while self.next_record in self._records:
            k = self.next_record
            rec = self._records.pop(k)
            fb = self.fallback_for.pop(k, False)
            extra = {f: float(getattr(self.loop, f)) for f in BRIDGE_RECORD_FIELDS if f != "fallback"}  # counters
            extra["fallback"] = 1.0 if fb else 0.0
            try:
                row = array("d", [float(extra[lab]) if lab in extra else float(rec[lab])
                                  for lab in self._record_labels])
            except (KeyError, TypeError, ValueError) as exc:
                self.loop.event("rejected", f"topic '{self.map.sim_record_topic}': record {k} lacks {exc}")
                row = None
            if row is not None:
                self.loop.record.publish(row)
                self._last_row = dict(zip(self._record_labels, row))
                for c, values in self._columns.items():
                    values.append(self._last_row[c])
                self.loop.publish_clock(float(rec["time_unix_s"]))
                self._check_record(k, rec)
            self.next_record = k + 1
            if self.loop.n_steps is None and "n_steps" in rec:
                self.loop.n_steps = int(rec["n_steps"])
            forwarded = True
        if forwarded:
            self._update_totals()
            self._publish_step_msg()  # the house may forget these records

    def _check_record(self, k: int, rec: dict[str, Any]) -> None:
        """Name what the house's record of step ``k`` says went wrong on its side."""
        of = rec.get("setpoints_of_step", k)
        if isinstance(of, (int, float)) and int(of) != k:
            self.setpoints_held += 1
            held = f"those of step {int(of)}" if of >= 0 else "none (the devices idle)"
            self.loop.event("setpoints_held", f"ran on the set-points the house held, {held}: the step's own did not "
                                         "reach it before the step's end (a broker outage, or late)", step=k)
        foreign = rec.get("foreign_messages", 0)
        if isinstance(foreign, (int, float)) and foreign > self._house_foreign:
            self.loop.event("foreign_mqtt", f"the house did not apply {int(foreign - self._house_foreign)} foreign "
                                       f"message(s) ({int(foreign)} so far)")
            self._house_foreign = int(foreign)

    def _update_totals(self) -> None:
        """The run totals over every record so far (:func:`comems4build_ros.core.kpi.run_totals`:
        the arithmetic of summary.json, which reads the same records from the bag)."""
        import numpy as np
        import pandas as pd

        ts = pd.DataFrame({c: np.asarray(v, dtype=float) for c, v in self._columns.items()})  # columns: fast
        c = self.loop.params.comfort
        t_comfort = kpi.comfort_sample_c(ts, c.discomfort_sample, self.loop.params.simulation.t_air_init_c)
        totals = kpi.run_totals(ts, self.dt_h, t_comfort)
        self.totals = {key: totals[name] for key, name in TOTAL_KEYS.items()}

    def _advance(self) -> None:
        if not self.loop.started or self.loop.done:
            return
        self._forward_records()
        records = bool(self.map.sim_record_topic)
        n = self.loop.n_steps
        if n is not None and ((records and self.next_record >= n)
                              or (not records and self.loop.k >= n and self.phase == "sent")):
            self._finish()
            return
        if self.clock.wall:
            return  # the wall clock drives the steps (watchdog timer)
        if self.phase == "sent" and (not records or self.next_record > self.loop.k):
            if self.loop.n_steps is not None and self.loop.k + 1 >= self.loop.n_steps:
                return  # the last record completes the run
            if self.loop.behind(self.loop.k + 1):
                return  # back-pressure: the recorder catches up first (recorder/progress)
            if self.watchdog.complete_for(self.loop.k + 1):
                self.loop.k += 1
                self.loop.note_step()
                self.phase = "measure"
                self._t_phase = time.monotonic()
        if self.phase == "measure" and self.watchdog.complete_for(self.loop.k):
            self._begin_step(self.loop.k, self.watchdog.check(time.monotonic(), check_age=False))

    def _start(self) -> None:
        self.loop.started = True
        if self.clock.wall:
            self.t0_unix_s = self.clock.first_boundary(time.time(), lead_s=min(1.0, self.clock.period_s))
        else:
            self.t0_unix_s = time.time()
        self.run_start = datetime.fromtimestamp(time.time(), UTC).isoformat(timespec="seconds")
        self.link.publish(self.map.run_topic, self._run_payload(), retain=True)
        self._t_phase = time.monotonic()
        self.get_logger().info(f"starting the run (clock {self.clock.spec()}, t0 {self.t0_unix_s:.3f})")
        self._advance()

    def _wall_tick(self, now: float) -> None:
        """Wall modes: the command deadline of the current step; begin the next step when due."""
        period = self.clock.period_s
        t0 = self.t0_unix_s if self.t0_unix_s is not None else 0.0
        unix = time.time()
        if self.phase == "command" and unix > t0 + (self.loop.k + COMMAND_DEADLINE_SHARE) * period:
            self._fallback(self.loop.k, "ems_silent",
                           f"no valid command on 'ems/command' for step {self.loop.k} in time")
        due = math.floor((unix - t0 - self.measure_delay_s) / period)
        nk = self.loop.k if self.phase == "measure" else self.loop.k + 1
        if due < nk or self.phase == "command" or (self.loop.n_steps is not None and nk >= self.loop.n_steps):
            return
        if self._tagged and not self.watchdog.complete_for(nk) \
                and unix < t0 + (nk + WALL_TAG_WAIT_SHARE) * period:
            return  # the house tags its measurements: give a late one a moment (machine jitter)
        if self._tagged and not self.watchdog.complete_for(nk):
            self.untagged_announcements += 1
        self.loop.k = nk
        self.loop.note_step()
        problems = self.watchdog.check(now, check_age=False)
        for name in self.map.measurements:  # max_age_s is simulated time: scale wall ages by the factor
            r = self.watchdog.latest.get(name)
            age = (now - r.t_recv) * self.clock.factor if r is not None else 0.0
            if age > self.map.max_age(name):
                problems.append(Problem(name, "stale", f"last value {age:.0f} s (simulated time) old, limit "
                                                       f"{self.map.max_age(name):g} s"))
        self._begin_step(nk, problems)

    def waiting_for(self) -> tuple[str, str | None] | None:
        """The recorder (back-pressure), the house over MQTT (its measurements or its
        record of the step), or None (the EMS's command; a wall clock steps anyway)."""
        if self.clock.wall or self.phase == "command":
            return None
        if self.phase == "sent" and self.loop.wait_for_recorder and \
                self.loop.k + 1 - self.loop.recorded > self.loop.record_window_steps:
            return f"the recorder '{self.loop.recorder_node}' (written: {self.loop.recorded})", "recorder/progress"
        what = "measurements" if self.phase == "measure" else "record"
        return f"the house's {what} of step {self.loop.k} over MQTT ({self.link.describe()})", None

    def _watchdog(self) -> None:
        now = time.monotonic()
        if self.loop.done or self.loop.check_stall(now):
            return
        if self.loop.stall_steps and self.loop.started and now - self._t_house > self.loop.stall_window_s():
            self.loop.stall(f"nothing from the house for {now - self._t_house:.1f} s at step {self.loop.k} "
                       f"({self.link.describe()})")
            return
        if not self.loop.started:
            late = now - self._t_created > self.loop.startup_timeout_s
            heard = all(m in self.watchdog.latest for m in self.map.measurements if self.map.measurements[m].required)
            ready = self.link.connected.is_set() and self._settle_switches(now) and self.loop.recorder_ready() and (
                self._cmd_sub.get_publisher_count() > 0 or late) and (heard or late)
            if ready:
                self._start()
            return
        self._settle_switches(now)
        if self._held is not None and self.limiter.may_send(now):
            self._send_setpoints(*self._held)
        if self.clock.wall:
            self._wall_tick(now)
        elif self.phase == "command":
            first = not self._ever_commanded and self.loop.fallback_steps == 0
            if now - self._t_phase > (self.loop.startup_timeout_s if first else self.loop.step_timeout_s):
                self._fallback(self.loop.k, "ems_silent", "no valid command on 'ems/command' within the timeout")
        if self.phase == "command" and now - self._t_announce > self.loop.republish_period_s and self._t_announce:
            self._announce(self.loop.k)
        elif self.phase == "sent" and not self.clock.wall and now - self._t_sent > self.loop.republish_period_s:
            for topic, payload in self._sent:  # the house may have lost them (broker restart)
                self.link.publish(topic, payload)
            self._t_sent = now
        # before the house's first message the start-up timeout applies (scenario, imports)
        silent_limit = self.loop.house_timeout_s if self.watchdog.latest else self.loop.startup_timeout_s
        if not self.clock.wall and now - self._t_house > silent_limit and self._house_alarmed != self.loop.k:
            self._house_alarmed = self.loop.k
            self._alarm(self.loop.k, "house_silent", f"nothing from the house for {now - self._t_house:.1f} s "
                                                   f"(broker {self.map.broker.url}, connected: "
                                                   f"{self.link.connected.is_set()})", None)
        self._advance()

    def stats(self) -> dict[str, float]:
        """Run statistics (fault and limiter counters, MQTT reconnects)."""
        c = self.limiter.counters
        return {
            **self.loop.stats(),
            "steps": float(self.next_record if self.map.sim_record_topic else self.loop.k),
            "clamped_commands": float(c.clamped_commands),
            "rate_limited": float(c.rate_limited),
            "bad_measurements": float(self.bad_measurements),
            "untagged_announcements": float(self.untagged_announcements),
            "alarms": float(self.alarms),
            "mqtt_connects": float(self.link.connects),
            "mqtt_reconnects": float(max(self.link.connects - 1, 0)),
            "setpoints_held": float(self.setpoints_held),
            "foreign_mqtt": float(self.peer.foreign_total),
            "house_foreign_mqtt": float(self._house_foreign),
            "retained_cleared": float(self.retained_cleared),
            "replayed_measurements": float(self.replayed_measurements),
            **{f"fallback_{kind}": float(n) for kind, n in sorted(self.fallback_kinds.items())},
        }

    def _finish(self) -> None:
        def tell_house() -> None:
            self._publish_step(self.loop.n_steps or self.loop.k)  # the house's acknowledgement
            self.link.publish(self.map.run_topic, "", retain=True)
            last = self._last_row
            final = {name: float(last[name]) for name in ("soc", "loh", "t_air_c", "v_dhw_l") if name in last} \
                if last is not None else None
            self._publish_ha_state(self.loop.n_steps or self.loop.k, final)  # with the last step's record

        self.loop.finish_run(self.stats(), tell_house)

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def destroy_node(self) -> None:  # noqa: D102
        self.link.stop(final=(self.map.availability_topic, NOT_AVAILABLE))
        super().destroy_node()


def _record_power(key: str, rec: dict[str, float]) -> float | None:
    """A power of the house's last record for Home Assistant [W]: battery charging minus
    discharging (``p_bess_w``), grid purchase minus feed-in (``p_grid_w``), else the record's."""
    if key == "p_bess_w":
        return round(rec["p_ch_w"] - rec["p_dis_w"], 3)
    if key == "p_grid_w":
        return round(rec["p_buy_w"] - rec["p_sell_w"], 3)
    return round(rec[key], 3) if key in rec else None


def main(args: list[str] | None = None) -> int:
    """Entry point of ``mqtt_bridge`` (``ros2 run comems4build_ros mqtt_bridge``)."""
    return run_node(MqttBridge, args, NODE_NAME)


if __name__ == "__main__":
    raise SystemExit(main())

