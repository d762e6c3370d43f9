"""``mqtt_plant``: the simulated house with its I/O over MQTT instead of ROS.

The same :class:`comems4build_ros.core.plant.Plant`, scenario and initial state as
``plant_sim`` and the in-process loop, but it talks to the world like a real house
behind Home Assistant: it publishes its measurements on the topics of the topic map
(``config/mqtt.yaml``, same units and scaling as a real install) and applies the
set-points it reads there. The ``mqtt_bridge`` node connects it to the EMS, so the loop
EMS -> bridge -> MQTT -> house -> MQTT -> bridge -> EMS closes over a real broker.

Clock (:mod:`comems4build_ros.mqtt.clock`):

* ``sim``: lock-step. The house publishes the measurements of step ``k`` (the state
  at the start of ``k``, the PV output and load of ``k``), each tagged with ``k`` (the
  map's ``step_key``), waits for a complete set of set-points tagged ``k``, steps the
  plant and publishes the step's timeseries row on ``sim_record_topic``. While it waits
  it repeats its last messages every ``republish_s`` (a message lost while the broker
  restarts is sent again; the tags make repeats harmless).
* ``wall``/``wall:<f>``: it waits for the bridge's retained run message (start time and
  step period), publishes the measurements of step ``k`` at ``t0 + k * period`` and, at
  ``t0 + (k + 1) * period``, steps the plant with the latest set-points it holds (the
  EMS acts on the latest measurements; no handshake).

Records are kept until the bridge acknowledges them (``records`` of its ``<base>/step``
message: the records it has forwarded) and repeated every ``republish_s`` until then, in
step order: a broker outage loses no record in either clock mode. After the last step
the house repeats the records not yet acknowledged until the bridge has announced the
end on ``<base>/step`` (or ``done_timeout_s`` passed), then exits 0. SIGINT or SIGTERM
before that end the process with exit code 3 (the run was cut; see
:mod:`comems4build_ros.wire.exits`).

Run and peer (:mod:`comems4build_ros.mqtt.peer`): with ``--run-id`` the house reads only
the step and run messages of that run (a retained message of an earlier run, cut or not,
is ignored and named once on stderr); without it, it takes the id of the first live run
message (a retained one may be a cut run's). With ``--mqtt-secret-file`` (the launcher's
per-run secret) every message it sends carries the run id and an authentication code,
and it applies only set-points whose code is valid: others are counted as foreign
(``foreign_messages`` in every record, which the bridge reports) and not applied. The
same file holds the password of ``--username`` on the launcher's embedded broker.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams, load_plant_params
from comems4build_ros.core.loop import STATE_COLUMNS, exogenous_series
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import ACTION_FIELDS, FLOW_FIELDS, Action, Exogenous, Flows, PlantState
from comems4build_ros.files.errors import InputError
from comems4build_ros.mqtt.client import BrokerConfigError, MqttLink
from comems4build_ros.mqtt.clock import Clock, ClockError, parse_clock
from comems4build_ros.mqtt.peer import ForeignMessageError, Peer, check_run_id, parse_run_json, read_peer_key
from comems4build_ros.mqtt.topicmap import SETPOINTS, PayloadError, TopicMap, load_topic_map

#: Default repeat period of the last messages while waiting [s].
REPUBLISH_S = 0.5
#: Default wait for the bridge's acknowledgement of the last step [s].
DONE_TIMEOUT_S = 30.0
#: Default wait without any set-point before giving up (lock-step) [s].
IDLE_TIMEOUT_S = 600.0
#: Poll period of the main loop [s].
POLL_S = 0.002
#: Wall clock: wait for the step's set-points up to this share of the period past the end
#: of the step before applying the latest ones (tagged set-points only).
WALL_SETPOINT_WAIT_SHARE = 0.3
#: Record fields the bridge fills in (not known to the house).
BRIDGE_RECORD_FIELDS = ("fallback", "fallback_steps", "rejected_commands", "wrong_step_commands",
                        "foreign_commands")


def record_fields(k: int, n_steps: int, t0_unix_s: float, flows: Flows, state: PlantState, action: Action,
                  exo: Exogenous, spot: float) -> dict[str, float]:
    """One step's timeseries row by plant/record label (without the bridge's fields)."""
    out: dict[str, float] = {"step": float(k), "n_steps": float(n_steps)}
    out.update({f: float(getattr(flows, f)) for f in FLOW_FIELDS})
    out.update({f: float(getattr(state, f)) for f in STATE_COLUMNS})
    out.update({f"cmd_{f}": float(getattr(action, f)) for f in ACTION_FIELDS})
    out.update(t_amb_c=exo.t_amb_c, ghi_w_m2=exo.ghi_w_m2, dhw_l_per_h=exo.dhw_l_per_h, t_min_c=exo.t_min_c,
               t_max_c=exo.t_max_c, spot_eur_per_mwh=float(spot), time_unix_s=float(t0_unix_s))
    return out


class MqttPlantSim:
    """The plant and its scenario, with MQTT payloads in and out (see the module docstring).

    Parameters
    ----------
    topic_map : the topic map (the house publishes measurements, reads set-points)
    params : plant parameters
    scenario : the run's scenario (the same window as the feed's)
    peer : run id and peer key (default: no run id, no key)
    """

    def __init__(self, topic_map: TopicMap, params: PlantParams, scenario: Any, peer: Peer | None = None) -> None:
        self.map = topic_map
        self.peer = peer if peer is not None else Peer(None, None)
        self.params = params
        self.plant = Plant(params)
        self.state = self.plant.initial_state()
        self.exo = exogenous_series(scenario, params)
        self.n_steps = int(scenario.n_steps)
        self.time_s = [t.timestamp() for t in scenario.time]
        self.spot = scenario.spot_eur_per_mwh.tolist()
        self.k = 0
        self._setpoint_topics = {spec.topic: name for name, spec in topic_map.setpoints.items()}
        self.pending: dict[int, dict[str, float]] = {}  # step -> set-point values (lock-step)
        self.latest: dict[str, float] = {}  # latest set-point values (wall clock)
        self.latest_step: dict[str, int | None] = {}
        self.bad_payloads = 0
        self.late_steps = 0  # wall clock: steps stepped without their own set-points
        self.unacked: dict[int, bytes] = {}  # step -> record payload not yet acknowledged by the bridge
        self.acked = 0  # records the bridge has acknowledged (it forwarded steps 0 .. acked - 1)

    def measurement_value(self, name: str, k: int) -> float:
        """Value of measurement ``name`` at the start of step ``k`` (state) or during ``k`` (PV, load, T_amb)."""
        if name in ("p_pv_w", "p_load_w", "t_amb_c"):
            return float(getattr(self.exo[min(k, self.n_steps - 1)], name))
        if name in ("fc_on", "el_on"):
            return 1.0 if getattr(self.state, name) else 0.0
        return float(getattr(self.state, name))

    def measurement_payloads(self, k: int) -> list[tuple[str, bytes]]:
        """``(topic, payload)`` of every mapped measurement for step ``k``."""
        return [(spec.topic, self.peer.wrap(spec.topic, spec.encode(self.measurement_value(name, k), k)))
                for name, spec in self.map.measurements.items()]

    def on_setpoint(self, topic: str, payload: bytes) -> None:
        """Store a set-point (by its step tag for lock-step, as latest for the wall clock).

        A foreign set-point (no valid code, another run) is counted and not applied; one
        tagged with a step already made is not applied either (a repeat of the bridge's,
        or a replay: it may not steer a later step)."""
        name = self._setpoint_topics.get(topic)
        if name is None:
            return
        try:
            value, step = self.map.setpoints[name].decode(self.peer.unwrap(topic, payload))
        except ForeignMessageError as exc:
            if self.peer.foreign_total <= 3 or self.peer.foreign_total % 100 == 0:
                print(f"[mqtt_plant] warning: foreign message not applied ({self.peer.foreign_total} so far): {exc}",
                      file=sys.stderr, flush=True)
            return
        except PayloadError as exc:
            self.bad_payloads += 1
            print(f"[mqtt_plant] warning: {exc}", file=sys.stderr, flush=True)
            return
        if step is not None and step < self.k:
            return
        self.latest[name] = value
        self.latest_step[name] = step
        if step is not None:
            self.pending.setdefault(step, {})[name] = value

    def complete(self, k: int) -> bool:
        """True when every set-point tagged ``k`` has arrived."""
        return len(self.pending.get(k, {})) == len(SETPOINTS)

    def action_for(self, values: dict[str, float]) -> Action:
        """The action of set-point values (missing ones: device idle)."""
        return Action(hp_mod=values.get("hp_mod", 0.0), hp_mode=int(values.get("hp_mode", 0)),
                      p_fc_w=values.get("p_fc_w", 0.0), p_bess_w=values.get("p_bess_w", 0.0))

    def step(self, action: Action, setpoints_of: int | None = None) -> bytes:
        """Step the plant over step ``k`` with ``action`` (the set-points tagged ``setpoints_of``,
        default ``k``); returns the record payload (JSON, tagged and sealed), kept in
        :attr:`unacked` until the bridge acknowledges it."""
        k = self.k
        exo = self.exo[k]
        self.state, flows = self.plant.step(self.state, action, exo)
        rec: dict[str, Any] = dict(record_fields(k, self.n_steps, self.time_s[k], flows, self.state, action, exo,
                                                 self.spot[k]))
        rec["setpoints_of_step"] = k if setpoints_of is None else setpoints_of
        rec["foreign_messages"] = self.peer.foreign_total
        self.k = k + 1
        for s in [s for s in self.pending if s <= k]:
            del self.pending[s]
        payload = self.peer.wrap(self.map.sim_record_topic or "record", json.dumps(rec).encode())
        if self.map.sim_record_topic:
            self.unacked[k] = payload
        return payload

    def acknowledge(self, records: int) -> None:
        """The bridge has forwarded the records of steps ``0 .. records - 1``: forget them."""
        if records > self.acked:
            self.acked = records
            for s in [s for s in self.unacked if s < records]:
                del self.unacked[s]

    def repeat_records(self, limit: int = 32) -> list[tuple[str, bytes]]:
        """The oldest records not yet acknowledged (at most ``limit``), in step order."""
        return [(self.map.sim_record_topic, self.unacked[s]) for s in sorted(self.unacked)[:limit]]


def _publish_all(link: MqttLink, messages: list[tuple[str, bytes]]) -> None:
    for topic, payload in messages:
        link.publish(topic, payload)


class BridgeView:
    """What the house knows of the bridge: its step and run messages of this run only."""

    def __init__(self, house: MqttPlantSim) -> None:
        self.house = house
        self.step = -1  # the step the bridge announced last
        self.run_msg: dict[str, Any] | None = None
        self.ignored: set[tuple[str, str]] = set()  # (topic, run) of other runs' messages, named once

    def on_message(self, topic: str, payload: bytes, retained: bool) -> None:
        """A message on the bridge's step or run topic."""
        m, peer = self.house.map, self.house.peer
        if not payload:  # a cleared retained message (the end of a run)
            if topic == m.run_topic:
                self.run_msg = None
            return
        try:
            msg = parse_run_json(topic, payload)
        except ValueError:
            msg = None
        if msg is not None and peer.run_id is None and topic == m.run_topic and not retained and msg.run:
            peer.adopt(msg.run)  # the first live run message names the run (a retained one may be a cut run's)
        if msg is None or msg.run is None or (peer.run_id is not None and msg.run != peer.run_id) \
                or peer.run_id is None:
            key = (topic, str(msg.run if msg is not None else None))
            if key not in self.ignored and peer.run_id is not None:
                self.ignored.add(key)
                print(f"[mqtt_plant] note: ignored {'retained ' if retained else ''}'{topic}' of "
                      f"{'run ' + repr(msg.run) if msg is not None and msg.run else 'no run'} "
                      f"(this run: '{peer.run_id}')", file=sys.stderr, flush=True)
            return
        try:
            body = parse_run_json(topic, peer.unwrap(topic, payload)).body
        except (ForeignMessageError, ValueError) as exc:
            print(f"[mqtt_plant] warning: foreign message not applied: {exc}", file=sys.stderr, flush=True)
            return
        if topic == m.step_topic:
            try:
                self.step = int(body["step"])  # type: ignore[call-overload]
                self.house.acknowledge(int(body.get("records", 0)))  # type: ignore[call-overload]
            except (KeyError, TypeError, ValueError):
                pass
        else:
            self.run_msg = body


def run(house: MqttPlantSim, link: MqttLink, clock: Clock, republish_s: float = REPUBLISH_S,
        idle_timeout_s: float = IDLE_TIMEOUT_S, done_timeout_s: float = DONE_TIMEOUT_S) -> int:
    """Run the house until its last step is acknowledged; returns the exit code."""
    m = house.map
    bridge = BridgeView(house)
    t_records = -1.0

    def publish_record(record: bytes) -> None:
        nonlocal t_records
        if m.sim_record_topic:
            link.publish(m.sim_record_topic, record)
            t_records = time.monotonic()

    def handle() -> None:
        nonlocal t_records
        for msg in link.drain():
            if msg.topic in (m.step_topic, m.run_topic):
                bridge.on_message(msg.topic, msg.payload, msg.retain)
            else:
                house.on_setpoint(msg.topic, msg.payload)
        now = time.monotonic()
        if house.unacked and now - t_records > republish_s:  # records the bridge may have lost (broker outage)
            t_records = now
            _publish_all(link, house.repeat_records())

    if clock.wall:
        _run_wall_clock(house, link, bridge, handle, publish_record, republish_s)
    elif _run_sim_clock(house, link, bridge, handle, publish_record, republish_s, idle_timeout_s) != 0:
        return 1
    # the records not yet acknowledged: repeat until the bridge announced the end
    t_end = time.monotonic()
    while bridge.step < house.n_steps and time.monotonic() - t_end < done_timeout_s:
        time.sleep(0.01)
        handle()
    ok = bridge.step >= house.n_steps
    print(f"[mqtt_plant] run done: {house.k} steps, bridge acknowledged: {ok}, "
          f"unreadable set-points: {house.bad_payloads}, steps without their own set-points: "
          f"{house.late_steps}, foreign messages not applied: {house.peer.foreign_total} {house.peer.foreign}",
          file=sys.stderr, flush=True)
    return 0


def _run_wall_clock(house: MqttPlantSim, link: MqttLink, bridge: BridgeView, handle: Any, publish_record: Any,
                    republish_s: float) -> None:
    """The steps on the wall clock the bridge's run message sets: measurements at each step's
    start, the set-points applied at its end (an earlier step's held when they are late)."""
    t_sent = -1.0
    while bridge.run_msg is None:  # the bridge starts once it has heard from the house
        if time.monotonic() - t_sent > republish_s:
            _publish_all(link, house.measurement_payloads(0))
            t_sent = time.monotonic()
        handle()
        time.sleep(0.01)
    t0, period = float(bridge.run_msg["t0_unix_s"]), float(bridge.run_msg["period_s"])
    print(f"[mqtt_plant] wall clock: step 0 at {t0:.3f}, period {period:g} s (run '{house.peer.run_id}')",
          file=sys.stderr, flush=True)
    while house.k < house.n_steps:
        k = house.k
        _sleep_until(t0 + k * period, handle)
        _publish_all(link, house.measurement_payloads(k))
        _sleep_until(t0 + (k + 1) * period, handle)
        handle()
        # the set-points of step k may be a moment late on a loaded machine (machine
        # jitter is multiplied by the clock's factor): wait up to WALL_SETPOINT_WAIT_SHARE
        limit = t0 + (k + 1 + WALL_SETPOINT_WAIT_SHARE) * period
        while not house.complete(k) and time.time() < limit:
            time.sleep(POLL_S)
            handle()
        if house.complete(k):
            action, of = house.action_for(house.pending[k]), k
        else:  # the device holds its last set-points (lost in a broker outage, or late)
            house.late_steps += 1
            held = [s for s in house.latest_step.values() if s is not None]
            action, of = house.action_for(house.latest), (min(held) if held else -1)
        record = house.step(action, of)
        publish_record(record)


def _run_sim_clock(house: MqttPlantSim, link: MqttLink, bridge: BridgeView, handle: Any, publish_record: Any,
                   republish_s: float, idle_timeout_s: float) -> int:
    """The steps in lock-step with the bridge: each waits for its set-points (measurements
    repeated while the bridge has not announced it); 1 after ``idle_timeout_s`` without any."""
    t_last_setpoint = time.monotonic()
    while house.k < house.n_steps:
        k = house.k
        out = house.measurement_payloads(k)
        _publish_all(link, out)
        t_sent = time.monotonic()
        while not house.complete(k):
            time.sleep(POLL_S)
            handle()
            now = time.monotonic()
            if now - t_sent > republish_s and bridge.step < k:
                _publish_all(link, out)  # the bridge has not announced k yet, or a message was lost
                t_sent = now
            if now - t_last_setpoint > idle_timeout_s:
                print(f"[mqtt_plant] error: no set-points for step {k} within {idle_timeout_s:g} s",
                      file=sys.stderr, flush=True)
                return 1
        t_last_setpoint = time.monotonic()
        record = house.step(house.action_for(house.pending[k]))
        publish_record(record)
    return 0


def _sleep_until(t_unix_s: float, handle: Any) -> None:
    while True:
        left = t_unix_s - time.time()
        if left <= 0:
            return
        time.sleep(min(left, 0.005))
        handle()


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``mqtt_plant``; exit code 2 for bad options or files."""
    from comems4build_ros.core.scenario.run import check_scenario, load_scenario

    ap = argparse.ArgumentParser(prog="mqtt_plant", description="simulated house with its I/O over MQTT")
    ap.add_argument("--topic-map", default=None, help="topic map (default config/mqtt.yaml)")
    ap.add_argument("--broker", default=None, help="broker URL (default: the topic map's)")
    ap.add_argument("--clock", default="sim", help="sim, wall or wall:<factor>")
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--start", default=None)
    ap.add_argument("--weeks", type=int, default=None)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--config", action="append", default=[])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--republish-s", type=float, default=REPUBLISH_S)
    ap.add_argument("--client-id", default="comems4build_plant_sim")
    ap.add_argument("--run-id", default=None, help="the run's id (default: the first live run message's)")
    ap.add_argument("--mqtt-secret-file", default=None,
                    help="per-run secret (mode 0600): peer key of the authentication codes, and the password of "
                         "--username on the launcher's embedded broker")
    ap.add_argument("--username", default=None, help="broker user (password from --mqtt-secret-file)")
    args = ap.parse_args(argv)
    try:
        from comems4build_ros.core.config import parse_assignments

        overrides = parse_assignments(args.set, "--set")
        params = load_plant_params(args.config, overrides)
        if args.username and not args.mqtt_secret_file:
            raise InputError("--username needs --mqtt-secret-file (the password's file)")
        if args.mqtt_secret_file and not args.run_id:
            raise InputError("--mqtt-secret-file needs --run-id (the codes bind each message to its run)")
        topic_map = load_topic_map(args.topic_map, args.broker, args.username,
                                   args.mqtt_secret_file if args.username else None)
        clock = parse_clock(args.clock, params.simulation.time_step_h)
        peer = Peer(check_run_id(args.run_id) if args.run_id else None,
                    read_peer_key(args.mqtt_secret_file) if args.mqtt_secret_file else None)
        scenario = load_scenario(args.scenario, params, args.start, args.weeks, args.seed, args.steps)
        check_scenario(scenario, params.simulation.time_step_h)
        house = MqttPlantSim(topic_map, params, scenario, peer)
        subs = [s.topic for s in topic_map.setpoints.values()] + [topic_map.step_topic, topic_map.run_topic]
        link = MqttLink(topic_map.broker, args.client_id, subs,
                        will=(topic_map.topic("building", "availability"), "offline"))
    except (ConfigError, ClockError, BrokerConfigError, ValueError, FileNotFoundError) as exc:
        print(f"[mqtt_plant] error: {exc}", file=sys.stderr, flush=True)
        return 2
    if not link.start(wait_s=30.0):
        print(f"[mqtt_plant] error: no connection to {topic_map.broker.url} within 30 s ({link.last_error})",
              file=sys.stderr, flush=True)
        link.stop()
        return 1
    link.publish(topic_map.topic("building", "availability"), "online", retain=True)
    print(f"[mqtt_plant] scenario '{scenario.name}': {house.n_steps} steps, clock {clock.spec()}, broker "
          f"{topic_map.broker.url}", file=sys.stderr, flush=True)
    import signal

    from comems4build_ros.wire.exits import CAUSE_TAG, EXIT_INTERRUPTED

    def on_sigterm(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, on_sigterm)  # as Ctrl-C: say goodbye on MQTT, exit with the code below
    try:
        code = run(house, link, clock, args.republish_s)
    except KeyboardInterrupt:  # before the last step was acknowledged: the run was cut
        print(f"[mqtt_plant] {CAUSE_TAG} stopped by a signal before the end of its run", file=sys.stderr, flush=True)
        code = EXIT_INTERRUPTED
    link.stop(final=(topic_map.topic("building", "availability"), "offline"))
    return code


if __name__ == "__main__":
    raise SystemExit(main())


