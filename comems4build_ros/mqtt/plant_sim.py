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

After the last step it repeats the last record until the bridge has announced the end
on ``<base>/step`` (or ``done_timeout_s`` passed), then exits 0. SIGINT or SIGTERM
before that end the process with exit code 3 (the run was cut; see
:mod:`comems4build_ros.wire.exits`).
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
from comems4build_ros.mqtt.client import BrokerConfigError, MqttLink
from comems4build_ros.mqtt.clock import Clock, ClockError, parse_clock
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
    """

    def __init__(self, topic_map: TopicMap, params: PlantParams, scenario: Any) -> None:
        self.map = topic_map
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

    def measurement_value(self, name: str, k: int) -> float:
        """Value of measurement ``name`` at the start of step ``k`` (state) or during ``k`` (PV, load, T_amb)."""
        if name in ("p_pv_w", "p_load_w", "t_amb_c"):
            return float(getattr(self.exo[min(k, self.n_steps - 1)], name))
        if name in ("fc_on", "el_on"):
            return 1.0 if getattr(self.state, name) else 0.0
        return float(getattr(self.state, name))

    def measurement_payloads(self, k: int) -> list[tuple[str, bytes]]:
        """``(topic, payload)`` of every mapped measurement for step ``k``."""
        return [(spec.topic, spec.encode(self.measurement_value(name, k), k))
                for name, spec in self.map.measurements.items()]

    def on_setpoint(self, topic: str, payload: bytes) -> None:
        """Store a set-point (by its step tag for lock-step, as latest for the wall clock)."""
        name = self._setpoint_topics.get(topic)
        if name is None:
            return
        try:
            value, step = self.map.setpoints[name].decode(payload)
        except PayloadError as exc:
            self.bad_payloads += 1
            print(f"[mqtt_plant] warning: {exc}", file=sys.stderr, flush=True)
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

    def step(self, action: Action) -> bytes:
        """Step the plant over step ``k`` with ``action``; returns the record payload (JSON)."""
        k = self.k
        exo = self.exo[k]
        self.state, flows = self.plant.step(self.state, action, exo)
        rec = record_fields(k, self.n_steps, self.time_s[k], flows, self.state, action, exo, self.spot[k])
        self.k = k + 1
        for s in [s for s in self.pending if s <= k]:
            del self.pending[s]
        return json.dumps(rec).encode()


def _publish_all(link: MqttLink, messages: list[tuple[str, bytes]]) -> None:
    for topic, payload in messages:
        link.publish(topic, payload)


def run(house: MqttPlantSim, link: MqttLink, clock: Clock, republish_s: float = REPUBLISH_S,
        idle_timeout_s: float = IDLE_TIMEOUT_S, done_timeout_s: float = DONE_TIMEOUT_S) -> int:
    """Run the house until its last step is acknowledged; returns the exit code."""
    m = house.map
    bridge_step = -1
    run_msg: dict[str, Any] | None = None

    def handle() -> None:
        nonlocal bridge_step, run_msg
        for msg in link.drain():
            if msg.topic == m.step_topic:
                try:
                    bridge_step = int(msg.payload.decode())
                except ValueError:
                    pass
            elif msg.topic == m.run_topic:
                try:
                    run_msg = json.loads(msg.payload.decode()) if msg.payload else None
                except (ValueError, UnicodeDecodeError):
                    run_msg = None
            else:
                house.on_setpoint(msg.topic, msg.payload)

    last_record: tuple[str, bytes] | None = None
    if clock.wall:
        t_sent = -1.0
        while run_msg is None:  # the bridge starts once it has heard from the house
            if time.monotonic() - t_sent > republish_s:
                _publish_all(link, house.measurement_payloads(0))
                t_sent = time.monotonic()
            handle()
            time.sleep(0.01)
        t0, period = float(run_msg["t0_unix_s"]), float(run_msg["period_s"])
        print(f"[mqtt_plant] wall clock: step 0 at {t0:.3f}, period {period:g} s", file=sys.stderr, flush=True)
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
                action = house.action_for(house.pending[k])
            else:
                house.late_steps += 1
                action = house.action_for(house.latest)
            record = house.step(action)
            last_record = (m.sim_record_topic, record)
            if m.sim_record_topic:
                link.publish(*last_record)
    else:
        t_last_setpoint = time.monotonic()
        while house.k < house.n_steps:
            k = house.k
            out = house.measurement_payloads(k)
            if last_record is not None and m.sim_record_topic:
                out.insert(0, last_record)
            _publish_all(link, out)
            t_sent = time.monotonic()
            while not house.complete(k):
                time.sleep(POLL_S)
                handle()
                now = time.monotonic()
                if now - t_sent > republish_s and bridge_step < k:
                    _publish_all(link, out)  # the bridge has not announced k yet, or a message was lost
                    t_sent = now
                if now - t_last_setpoint > idle_timeout_s:
                    print(f"[mqtt_plant] error: no set-points for step {k} within {idle_timeout_s:g} s",
                          file=sys.stderr, flush=True)
                    return 1
            t_last_setpoint = time.monotonic()
            record = house.step(house.action_for(house.pending[k]))
            last_record = (m.sim_record_topic, record)
    # the last record: repeat until the bridge announced the end
    t_end = time.monotonic()
    t_sent = -1.0
    while bridge_step < house.n_steps and time.monotonic() - t_end < done_timeout_s:
        if last_record is not None and m.sim_record_topic and time.monotonic() - t_sent > republish_s:
            link.publish(*last_record)
            t_sent = time.monotonic()
        time.sleep(0.01)
        handle()
    ok = bridge_step >= house.n_steps
    print(f"[mqtt_plant] run done: {house.k} steps, bridge acknowledged: {ok}, "
          f"unreadable set-points: {house.bad_payloads}, steps without their own set-points: "
          f"{house.late_steps}", file=sys.stderr, flush=True)
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
    args = ap.parse_args(argv)
    try:
        from comems4build_ros.core.config import parse_assignments

        overrides = parse_assignments(args.set, "--set")
        params = load_plant_params(args.config, overrides)
        topic_map = load_topic_map(args.topic_map, args.broker)
        clock = parse_clock(args.clock, params.simulation.time_step_h)
        scenario = load_scenario(args.scenario, params, args.start, args.weeks, args.seed, args.steps)
        check_scenario(scenario, params.simulation.time_step_h)
        house = MqttPlantSim(topic_map, params, scenario)
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


