"""The MQTT bridge with real brokers (amqtt processes) and real rclpy nodes in processes.

* ``launch --plant mqtt`` (embedded broker): EMS -> mqtt_bridge -> MQTT -> simulated
  house -> MQTT -> mqtt_bridge -> EMS gives the in-process KPIs exactly over 2 weeks;
  a 1-week ``wall:3600`` run gives them within 1 %.
* The broker is killed and restarted mid-run: the bridge and the house reconnect and
  the run completes with no step lost, equal to in-process.
* Safety, with a scripted house (MQTT client in this test) and a scripted EMS (rclpy
  node in this test) around a real bridge process: an out-of-range measurement gets the
  fallback set-points and an alarm (MQTT and ROS) in the same step, a command beyond the
  device limits is clamped and counted, a measurement that stops updating is flagged
  stale and gets the fallback within one step; the retained Home Assistant discovery
  messages on the broker match the documented schema.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from waits import BUDGET_S, Deadline, wait_exit, wait_until

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from std_msgs.msg import Float64MultiArray, String, UInt32  # noqa: E402

from comems4build_ros.core.config import load_plant_params  # noqa: E402
from comems4build_ros.core.loop import simulate  # noqa: E402
from comems4build_ros.mqtt.broker import free_port  # noqa: E402
from comems4build_ros.mqtt.client import MqttLink  # noqa: E402
from comems4build_ros.mqtt.discovery import DISCOVERY_SCHEMA, check_discovery, discovery_messages  # noqa: E402
from comems4build_ros.mqtt.topicmap import SETPOINTS, load_topic_map  # noqa: E402
from comems4build_ros.ros.interfaces import qos_profile  # noqa: E402
from comems4build_ros.run.launcher import launch  # noqa: E402
from comems4build_ros.run.plan import LaunchOptions, ros_args  # noqa: E402
from comems4build_ros.wire.contract import load_contract  # noqa: E402

pytestmark = pytest.mark.ros
#: Only in summaries from a bag (timings), or from a house behind MQTT (its MQTT counts).
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages", "mqtt")
#: KPIs compared for the wall-clock run (summary keys).
KPI_KEYS = ("cost_eur_week_median", "discomfort_kh_week_median", "buy_kwh_week_median", "sell_kwh_week_median",
            "loh_end")


def _reference(weeks: int, steps: int | None = None) -> dict:
    from comems4build_ros.core.scenario.run import load_scenario

    params = load_plant_params()
    scenario = load_scenario("default", params, None, weeks, None, steps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate("fuzzy", scenario, params).summary


def _same(a: dict, b: dict) -> None:
    keys = set(a) - set(TIMING_KEYS)
    assert keys == set(b) - set(TIMING_KEYS)
    for k in sorted(keys):
        if isinstance(a[k], float) and math.isnan(a[k]):
            assert math.isnan(b[k]), k
        else:
            assert a[k] == b[k], k


class Broker:
    """An amqtt broker process on a fixed port (restartable)."""

    def __init__(self, tmp: Path, port: int | None = None) -> None:
        self.port = port or free_port()
        self.url = f"mqtt://127.0.0.1:{self.port}"
        self.tmp = tmp
        self.proc: subprocess.Popen | None = None
        self.starts = 0

    def start(self) -> None:
        self.starts += 1
        log = open(self.tmp / f"broker.{self.starts}.log", "w")  # noqa: SIM115
        self.proc = subprocess.Popen([sys.executable, "-m", "comems4build_ros.mqtt.broker", "--port", str(self.port)],
                                     stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True)
        log.close()
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.startswith("broker ready"), line

    def kill(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            wait_exit(self.proc, "the broker killed")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(BUDGET_S)
            except subprocess.TimeoutExpired:
                self.kill()


@pytest.fixture()
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    b.start()
    yield b
    b.stop()


# ---------------------------------------------------------------------- launcher runs
def test_launch_mqtt_plant_two_weeks_equals_in_process(tmp_path: Path) -> None:
    out = tmp_path / "run"
    launch(LaunchOptions(ems="fuzzy", out=out, weeks=2, plant="mqtt", timeout_s=BUDGET_S))
    summary = json.loads((out / "summary.json").read_text())
    _same(summary, _reference(2))
    assert summary["steps"] == 336 and summary["fallback_steps"] == 0 and summary["lost_messages"] == {}
    log = (out / "log" / "mqtt_bridge.log").read_text()
    assert "run done: steps=336 fallback_steps=0" in log and "clamped_commands=0" in log


def test_launch_wall_clock_one_week_within_one_percent(tmp_path: Path) -> None:
    out = tmp_path / "run"
    launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, plant="mqtt", clock="wall:3600", timeout_s=BUDGET_S))
    summary = json.loads((out / "summary.json").read_text())
    ref = _reference(1)
    for name in ("mqtt_bridge", "mqtt_plant"):
        print([line for line in (out / "log" / f"{name}.log").read_text().splitlines() if "run done" in line])
    assert summary["steps"] == 168
    for k in KPI_KEYS:
        assert summary[k] == pytest.approx(ref[k], rel=0.01, abs=1e-9), k
    print("wall:3600 fallback steps:", summary["fallback_steps"], {k: (summary[k], ref[k]) for k in KPI_KEYS})


def test_broker_restart_mid_run_loses_no_step(tmp_path: Path, broker: Broker) -> None:
    out = tmp_path / "run"
    steps_seen: list[int] = []
    watch = MqttLink(load_topic_map(broker_url=broker.url).broker, "test_watch", ["comems4build/step"])
    assert watch.start(wait_s=BUDGET_S)
    result: dict[str, Any] = {}

    def run() -> None:
        try:
            result["res"] = launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=96, plant="mqtt",
                                                 broker_url=broker.url, timeout_s=BUDGET_S))
        except BaseException as exc:  # reported below
            result["error"] = exc

    th = threading.Thread(target=run)
    th.start()
    try:
        def thirty_steps() -> bool:
            steps_seen.extend(json.loads(m.payload)["step"] for m in watch.drain() if m.payload)
            return bool(steps_seen) and steps_seen[-1] >= 30

        wait_until(thirty_steps, "the run at step 30")
        broker.kill()  # mid-run, no goodbye
        time.sleep(1.0)  # the fault: the broker down for a second
        broker.start()
    finally:
        wait_until(lambda: not th.is_alive(), "the launch to end")
        watch.stop()
    assert "error" not in result, result.get("error")
    summary = json.loads((out / "summary.json").read_text())
    _same(summary, _reference(1, 96))
    assert summary["steps"] == 96 and summary["lost_messages"] == {}
    log = (out / "log" / "mqtt_bridge.log").read_text()
    connects = int(float(log.split("mqtt_connects=")[1].split()[0]))
    assert connects >= 2, "the bridge did not reconnect"


# ---------------------------------------------------------------------- scripted house and EMS
class Rig:
    """A real bridge process between a scripted house (MQTT) and a scripted EMS (rclpy)."""

    def __init__(self, tmp: Path, domain_id: int, broker: Broker, clock: str, command: Callable[[int], list[float]],
                 tagged: bool = True):
        import yaml

        from comems4build_ros.mqtt.topicmap import default_map_file

        # a real house: no simulator record topic
        doc = yaml.safe_load(default_map_file().read_text())
        doc["/**"]["ros__parameters"]["mqtt"]["sim_record_topic"] = ""
        if not tagged:  # measurements without step tags, as from real devices
            for spec in doc["/**"]["ros__parameters"]["mqtt"]["measurements"].values():
                spec["step_key"] = ""
        map_file = tmp / "map.yaml"
        map_file.write_text(yaml.safe_dump(doc))
        self.map = load_topic_map(map_file, broker_url=broker.url)
        self.contract = load_contract()
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain_id), "ROS_LOG_DIR": str(tmp / "ros_log"),
               "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "PYTHONUNBUFFERED": "1"}
        self.log = tmp / "bridge.log"
        with open(self.log, "w") as fh:
            # a step of simulated time waits for its command (the budget as its time-out): its
            # fallbacks are the ones the test makes; on wall-clock time the period decides
            wait_s = BUDGET_S if clock == "sim" else 5.0
            params = {"broker_url": broker.url, "clock": clock, "startup_timeout_s": wait_s, "step_timeout_s": wait_s,
                      "topic_map": str(map_file)}
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "comems4build_ros.ros.nodes.mqtt_bridge", *ros_args("", params)],
                env=env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = Node("test_ems", context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        c = self.contract
        self.announced: list[int] = []  # steps whose state reached the EMS
        self.ros_alarms: list[dict] = []
        self.events: list[str] = []
        self.plant_steps: list[int] = []
        self.command = command
        self.cmd_pub = self.node.create_publisher(Float64MultiArray, "ems/command",
                                                  qos_profile(c.topic("ems/command")))

        def on_state(msg: Float64MultiArray) -> None:
            k = int(msg.data[0])
            if k not in self.announced:
                self.announced.append(k)
                if k == 3:  # another EMS on the topic first: its token is not the run's
                    self.cmd_pub.publish(Float64MultiArray(data=[float(k), 0.0, 0.0, 0.0, 0.0, 0.0, RIG_TOKEN + 1]))
                self.cmd_pub.publish(Float64MultiArray(data=[float(k), *self.command(k), RIG_TOKEN]))

        self.node.create_subscription(Float64MultiArray, "state/t_air_c", on_state,
                                      qos_profile(c.topic("state/t_air_c")))
        self.node.create_subscription(String, "bridge/alarm", lambda m: self.ros_alarms.append(json.loads(m.data)),
                                      qos_profile(c.topic("bridge/alarm")))
        self.node.create_subscription(String, "plant/events", lambda m: self.events.append(m.data),
                                      qos_profile(c.topic("plant/events")))
        self.node.create_subscription(UInt32, "plant/step", lambda m: self.plant_steps.append(int(m.data)),
                                      qos_profile(c.topic("plant/step")))
        sp = [s.topic for s in self.map.setpoints.values()]
        self.link = MqttLink(self.map.broker, "test_building", [*sp, self.map.alarm_topic, self.map.run_topic,
                                                                 "homeassistant/#", self.map.state_topic,
                                                                 self.map.availability_topic])
        self.availability: list[bytes] = []
        assert self.link.start(wait_s=BUDGET_S)
        self.setpoints: dict[int, dict[str, float]] = {}
        self.latest_setpoints: dict[str, float] = {}
        self.mqtt_alarms: list[dict] = []
        self.discovery: dict[str, bytes] = {}
        self.ha_states: list[dict] = []
        self.run_msg: dict | None = None

    def pump(self, seconds: float = 0.01) -> None:
        self.executor.spin_once(timeout_sec=seconds)
        by_topic = {s.topic: n for n, s in self.map.setpoints.items()}
        for m in self.link.drain():
            if m.topic in by_topic:
                name = by_topic[m.topic]
                value, step = self.map.setpoints[name].decode(m.payload)
                self.latest_setpoints[name] = value
                if step is not None:
                    self.setpoints.setdefault(step, {})[name] = value
            elif m.topic == self.map.alarm_topic:
                self.mqtt_alarms.append(json.loads(m.payload))
            elif m.topic == self.map.state_topic:
                self.ha_states.append(json.loads(m.payload))
            elif m.topic == self.map.run_topic:
                self.run_msg = json.loads(m.payload) if m.payload else None
            elif m.topic == self.map.availability_topic:
                self.availability.append(m.payload)
            elif m.topic.startswith("homeassistant/") and m.payload:  # empty: a deleted config
                self.discovery[m.topic] = m.payload

    def measure(self, values: dict[str, float], step: int | None, skip: tuple[str, ...] = ()) -> None:
        for name, spec in self.map.measurements.items():
            if name not in skip:
                self.link.publish(spec.topic, spec.encode(values[name], step))

    def close(self) -> None:
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(BUDGET_S)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self.link.stop()
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


GOOD = {"t_air_c": 20.5, "v_dhw_l": 200.0, "soc": 0.5, "loh": 0.9, "hp_mod": 0.0, "fc_on": 0.0,
        "t_wall_in_c": 19.0, "t_wall_out_c": 5.0, "p_pv_w": 0.0, "p_load_w": 400.0, "t_amb_c": 2.0}
#: Run token of the scripted EMS's commands (the last element of ems/command).
RIG_TOKEN = 7.0
#: The scripted EMS: hp_mod, hp_mode, p_fc_w, p_bess_w; step 1 asks the battery for 5 kW.
NORMAL = [0.6, 1.0, 0.0, 200.0, 0.0]  # hp_mod, hp_mode, p_fc_w, p_bess_w, p_el_w



def test_out_of_range_gets_fallback_and_alarm_in_the_same_step_commands_clamped_switch_and_last_will(
        tmp_path: Path, domain_id: int, broker: Broker) -> None:
    rig = Rig(tmp_path, domain_id, broker, "sim", lambda k: [0.6, 1.0, 0.0, 5000.0, 0.0] if k == 1 else NORMAL)
    try:
        k, t_pub = 0, 0.0

        def said(text: str) -> bool:  # the bridge took a setting or a switch (its event)
            rig.pump(0.01)
            return any(text in e for e in rig.events)

        deadline = Deadline("five steps")
        while k < 5 and not deadline.passed():
            rig.pump()
            if len(rig.setpoints.get(k, {})) == len(SETPOINTS):
                k += 1
                t_pub = 0.0
                if k == 3:  # Home Assistant's setting: at most 150 W of battery power, either way
                    rig.link.publish(rig.map.setting_topics("battery_power_limit")[0], "150")
                    wait_until(lambda: said("setting battery_power_limit 150"), "the bridge taking the setting")
                if k == 4:  # Home Assistant's switch: EMS off
                    rig.link.publish(rig.map.switch_topics("ems")[0], "OFF")
                    wait_until(lambda: said("switch ems OFF"), "the bridge taking the switch")
            elif time.monotonic() - t_pub > 0.5:  # (re)send the measurements of step k
                rig.measure(dict(GOOD, t_air_c=80.0) if k == 2 else GOOD, k)
                t_pub = time.monotonic()
        assert k == 5, f"stuck at step {k}: {rig.proc.poll()} {(tmp_path / 'bridge.log').read_text()[-2000:]}"

        def step_4_reported() -> bool:  # what the bridge says about the last step, on MQTT and ROS
            rig.pump()
            return (4, "forced") in [(a["step"], a["kind"]) for a in rig.mqtt_alarms] and any(
                s["step"] == 4 and s["in_charge"] == "fallback_switch" for s in rig.ha_states)

        wait_until(step_4_reported, "the alarm and the state of step 4")
        # step 0: the EMS's command as sent
        assert rig.setpoints[0] == {"hp_mod": 0.6, "hp_mode": 1.0, "p_fc_w": 0.0, "p_bess_w": 200.0}
        # step 1: 5 kW battery power clamped to the device limit (battery.p_ch_max_w), counted, logged
        p_ch_max = load_plant_params().battery.p_ch_max_w
        assert rig.setpoints[1]["p_bess_w"] == p_ch_max
        assert any("clamped" in e and "p_bess_w 5000 clamped to 1000" in e for e in rig.events)
        # step 2: T_air 80 degC out of range -> no state to the EMS, the safe action (rooms at
        # full power: the room temperature is unknown), alarm on MQTT and ROS for step 2
        assert 2 not in rig.announced and 2 in rig.plant_steps
        assert rig.setpoints[2] == {"hp_mod": 1.0, "hp_mode": 1.0, "p_fc_w": 0.0, "p_bess_w": 0.0}
        assert [(a["step"], a["kind"]) for a in rig.mqtt_alarms][:1] == [(2, "out_of_range")]
        assert [(a["step"], a["kind"]) for a in rig.ros_alarms][:1] == [(2, "out_of_range")]
        assert "t_air_c" in rig.mqtt_alarms[0]["detail"] and rig.mqtt_alarms[0]["action"]["hp_mode"] == 1
        assert any(s["step"] == 2 and s["alarm"] == "ON" and s["in_charge"] == "fallback_watchdog"
                   for s in rig.ha_states)
        # the first state of the run is this run's, every value unknown (not the last run's)
        assert rig.ha_states[0]["step"] is None and rig.ha_states[0]["soc_pct"] is None
        assert len({s["run"] for s in rig.ha_states}) == 1
        # step 3: back to the EMS; the other token's command of step 3 is ignored and counted;
        # the user's battery power limit (150 W) clamps the EMS's 200 W
        assert 3 in rig.announced and rig.setpoints[3]["hp_mod"] == 0.6 and rig.setpoints[3]["p_bess_w"] == 150.0
        assert any("p_bess_w 200 clamped to 150 (the user's limits [-150, 150])" in e for e in rig.events)
        assert any("setting battery_power_limit 150" in e for e in rig.events)
        assert any("foreign" in e and "token 8 ignored" in e for e in rig.events)
        last = [s for s in rig.ha_states if s["step"] == 3][-1]
        assert last["clamped_commands"] == 2 and last["fallback_steps"] == 1 and last["alarm"] == "OFF"
        assert last["in_charge"] == "ems" and last["soc_pct"] == 50.0 and last["t_air_c"] == GOOD["t_air_c"]
        # step 4: EMS switched off in Home Assistant -> the safe action (here: rooms within
        # 0.5 K of an unknown bound -> heat), a 'forced' alarm, no state to the EMS
        assert 4 not in rig.announced and rig.setpoints[4]["hp_mode"] == 1.0 and rig.setpoints[4]["hp_mod"] == 1.0
        assert (4, "forced") in [(a["step"], a["kind"]) for a in rig.mqtt_alarms]
        assert [s["in_charge"] for s in rig.ha_states if s["step"] == 4][-1] == "fallback_switch"
        # Home Assistant discovery: retained configs on the broker, valid against the schema;
        # a real building (no record topic) has no run totals: those are not announced
        comps = {check_discovery(t, p) for t, p in rig.discovery.items()}
        limits = rig.map.device_limits(load_plant_params())
        wanted = {t for t, p in discovery_messages(rig.map, limits) if p is not None}
        assert comps == set(DISCOVERY_SCHEMA) and set(rig.discovery) == wanted
        assert not any("grid_cost_eur" in t for t in rig.discovery)
        # availability: online while running; the last will says offline when the bridge dies
        assert rig.availability[-1] == b"online"
        rig.proc.kill()
        deadline = Deadline("the last will: offline")
        while not deadline.passed() and rig.availability[-1] != b"offline":
            rig.pump(0.05)
        assert rig.availability[-1] == b"offline"
    finally:
        rig.close()


def test_stale_measurement_gets_fallback_within_one_step_wall_clock(
        tmp_path: Path, domain_id: int, broker: Broker) -> None:
    rig = Rig(tmp_path, domain_id, broker, "wall:3600", lambda k: NORMAL, tagged=False)
    try:
        max_age_wall = rig.map.max_age("soc") / 3600.0  # 2 s at one simulated hour per second
        t_last_soc = None
        t_next = 0.0
        deadline = Deadline("12 s of the wall-clock run")
        while not deadline.passed():
            rig.pump()
            now = time.time()
            if rig.run_msg is not None:
                t0 = rig.run_msg["t0_unix_s"]
                if now > t0 + 12:
                    break
                stop_soc = now > t0 + 3.0
            else:
                stop_soc = False
            if now >= t_next:  # a real house: plain values every 0.5 s, no step tags
                rig.measure(GOOD, None, skip=("soc",) if stop_soc else ())
                if not stop_soc:
                    t_last_soc = now
                t_next = now + 0.5
        assert rig.run_msg is not None and t_last_soc is not None
        t0, period = rig.run_msg["t0_unix_s"], rig.run_msg["period_s"]
        delay = 0.2 * period
        # first step whose announcement (t0 + k*period + delay) sees soc older than its limit
        expected = math.ceil((t_last_soc + max_age_wall - t0 - delay) / period)
        stale = [a for a in rig.mqtt_alarms if a["kind"] == "stale"]
        assert stale and expected <= stale[0]["step"] <= expected + 1, (expected, stale[:2])
        k = stale[0]["step"]
        assert "soc" in stale[0]["detail"] and any(a["step"] == k and a["kind"] == "stale" for a in rig.ros_alarms)
        # the safe action; without a feed the comfort bound is unknown, so it heats the rooms
        assert rig.setpoints[k] == {"hp_mod": 1.0, "hp_mode": 1.0, "p_fc_w": 0.0, "p_bess_w": 0.0}
        assert k not in rig.announced and all(s in rig.announced for s in range(k))
        assert all(rig.setpoints[s]["hp_mod"] == 0.6 for s in range(k))  # the EMS before
    finally:
        rig.close()


# ---------------------------------------------------------------------- TLS and credentials
def _self_signed(tmp: Path) -> tuple[Path, Path]:
    import shutil

    if shutil.which("openssl") is None:
        pytest.skip("openssl not installed (needed to make a test certificate)")
    cert, key = tmp / "cert.pem", tmp / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(cert),
                    "-days", "2", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"],
                   check=True, capture_output=True)
    return cert, key


def test_tls_broker_with_password_from_file_or_env_never_logged(tmp_path: Path, domain_id: int,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    import yaml

    from comems4build_ros.mqtt.broker import write_password_file
    from comems4build_ros.mqtt.client import BrokerConfigError, read_password
    from comems4build_ros.mqtt.topicmap import default_map_file

    secret = "s3cret-Pa55-for-the-test"
    cert, key = _self_signed(tmp_path)
    users = write_password_file(tmp_path / "users", {"ems": secret})
    port = free_port()
    log = open(tmp_path / "broker.log", "w")  # noqa: SIM115
    proc = subprocess.Popen([sys.executable, "-m", "comems4build_ros.mqtt.broker", "--port", str(port), "--users",
                             str(users), "--cert", str(cert), "--key", str(key)], stdout=subprocess.PIPE,
                            stderr=log, text=True, start_new_session=True)
    log.close()
    bridge = None
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("broker ready")
        pw_file = tmp_path / "pw"
        pw_file.write_text(secret + "\n")
        doc = yaml.safe_load(default_map_file().read_text())
        doc["/**"]["ros__parameters"]["mqtt"]["broker"].update(
            url=f"mqtts://127.0.0.1:{port}", username="ems", password_file=str(pw_file), ca_file=str(cert))
        map_file = tmp_path / "map.yaml"
        map_file.write_text(yaml.safe_dump(doc))
        tmap = load_topic_map(map_file)
        # the test's own client: password from an environment variable
        env_settings = tmap.broker.model_copy(update={"password_file": "", "password_env": "TEST_MQTT_PW"})
        monkeypatch.setenv("TEST_MQTT_PW", secret)
        monkeypatch.setenv("TEST_MQTT_WRONG", "not-the-password")
        watch = MqttLink(env_settings, "test_watch", [tmap.availability_topic])
        assert watch.start(wait_s=BUDGET_S), watch.last_error
        wrong = MqttLink(env_settings.model_copy(update={"password_env": "TEST_MQTT_WRONG"}), "test_wrong")
        assert not wrong.start(wait_s=3)  # a window for what must not happen
        wrong.stop()
        with pytest.raises(BrokerConfigError, match="TEST_MQTT_UNSET is not set") as info:
            read_password(env_settings.model_copy(update={"password_env": "TEST_MQTT_UNSET"}), environ={})
        assert secret not in str(info.value)
        # the bridge: password from the file, TLS with the test CA
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain_id), "ROS_LOG_DIR": str(tmp_path / "ros_log"),
               "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "PYTHONUNBUFFERED": "1"}
        with open(tmp_path / "bridge.log", "w") as fh:
            bridge = subprocess.Popen([sys.executable, "-m", "comems4build_ros.ros.nodes.mqtt_bridge",
                                       *ros_args("", {"topic_map": str(map_file)})],
                                      env=env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)
        deadline = Deadline("the bridge online")
        online = False
        while not deadline.passed() and not online:
            online = any(m.payload == b"online" for m in watch.drain())
            time.sleep(0.05)
        assert online, (tmp_path / "bridge.log").read_text()[-2000:]
        watch.stop()
    finally:
        if bridge is not None:
            bridge.send_signal(signal.SIGINT)
            wait_exit(bridge, "the bridge to stop")
        proc.send_signal(signal.SIGINT)
        wait_exit(proc, "the broker to stop")
    logs = [tmp_path / "bridge.log", *(tmp_path / "ros_log").rglob("*")]
    text = "".join(p.read_text(errors="replace") for p in logs if p.is_file())
    assert "user: ems, TLS: True" in text and secret not in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--clock", "wall"], "--clock wall needs --plant mqtt or --community"),
        (["--plant", "mqtt", "--clock", "wall:0"], "--clock: clock 'wall:0'"),
        (["--plant", "mqtt", "--houses", "2"], "--plant mqtt runs one house"),
        (["--plant", "mqtt", "--topic-map", "/nonexistent/m.yaml"], "--topic-map /nonexistent/m.yaml: no such file"),
    ],
)
def test_launch_refuses_bad_plant_options_with_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    cli = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
    proc = subprocess.run([*cli, "launch", "--ems", "fuzzy", *args, "--out", str(tmp_path / "x")],
                          capture_output=True, text=True, timeout=BUDGET_S)
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert not (tmp_path / "x").exists()


def test_plan_options_plant_mqtt_and_clock(tmp_path: Path) -> None:
    from comems4build_ros.run.plan import plan_run

    plan = plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, weeks=1, plant="mqtt", clock="wall:3600"), 7)
    names = [p.name for p in plan.processes]
    assert names == ["recorder", "fuzzy_ems", "feed", "broker", "mqtt_plant", "mqtt_bridge"]
    assert plan.process("feed").nodes[0].params["publish_measured"] is False
    bridge = plan.process("mqtt_bridge")
    assert bridge.finishes and plan.process("mqtt_plant").finishes and not plan.process("broker").finishes
    assert plan.process("broker").stop_stage > plan.process("recorder").stop_stage
    url = bridge.nodes[0].params["broker_url"]
    assert bridge.nodes[0].params["clock"] == "wall:3600" and url in plan.process("mqtt_plant").argv
    argv = plan.process("broker").argv
    assert url.endswith(":" + argv[argv.index("--port") + 1])
    own = plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, weeks=1, plant="mqtt", broker_url="mqtts://h:8883"), 7)
    assert "broker" not in [p.name for p in own.processes]
    live = plan_run(LaunchOptions(ems="rbc", out=tmp_path, weeks=1, inputs="live"), 7)
    assert live.process("feed").nodes[0].params["inputs"] == "live"
    assert "plant_sim" in [p.name for p in live.processes]
    for bad, message in ((dict(clock="wall"), "need plant 'mqtt'"), (dict(plant="mqtt", houses=2), "one house"),
                         (dict(plant="ros"), "expected 'sim' or 'mqtt'"), (dict(plant="mqtt", clock="wall:-1"),
                                                                           "wall:<factor>")):
        with pytest.raises(ValueError, match=message):
            plan_run(LaunchOptions(ems="fuzzy", out=tmp_path, weeks=1, **bad), 7)


# ---------------------------------------------------------------------- no one else at the controls
def test_the_embedded_broker_lets_in_only_the_runs_two_users(tmp_path: Path) -> None:
    """A foreign local client with no or wrong credentials is refused by the launcher's
    broker; the run's users get in with the per-run secret, which is on no command line."""
    from comems4build_ros.mqtt.topicmap import BrokerParams
    from comems4build_ros.run.plan import MQTT_BRIDGE_USER, MQTT_HOUSE_USER, plan_run
    from comems4build_ros.wire.tokens import new_token, write_token_file

    secret = new_token()
    login = write_token_file(tmp_path / ".secrets" / "mqtt.token", secret)
    port = free_port()
    log = open(tmp_path / "broker.log", "w")  # noqa: SIM115
    proc = subprocess.Popen([sys.executable, "-m", "comems4build_ros.mqtt.broker", "--port", str(port), "--login-file",
                             str(login), "--user", MQTT_HOUSE_USER, "--user", MQTT_BRIDGE_USER],
                            stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True)
    log.close()
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("broker ready")
        url = f"mqtt://127.0.0.1:{port}"
        wrong = tmp_path / "wrong"
        wrong.write_text(f"{secret + 1}\n")
        for user, pw_file in ((None, None), (MQTT_HOUSE_USER, str(wrong)), ("intruder", str(login))):
            settings = BrokerParams(url=url, username=user or "", password_file=pw_file or "")
            link = MqttLink(settings, f"foreign_{user}")
            assert not link.start(wait_s=3), f"{user} got in"  # a window for what must not happen
            link.stop()
        for user in (MQTT_HOUSE_USER, MQTT_BRIDGE_USER):
            link = MqttLink(BrokerParams(url=url, username=user, password_file=str(login)), f"peer_{user}")
            assert link.start(wait_s=BUDGET_S), link.last_error
            link.stop()
    finally:
        proc.send_signal(signal.SIGINT)
        wait_exit(proc, "the broker to stop")
    plan = plan_run(LaunchOptions(ems="fuzzy", out=tmp_path / "run", weeks=1, plant="mqtt"), 7)
    secret_file, token = next((f, t) for f, t in plan.secrets if f.endswith("mqtt.token"))
    argv = " ".join(" ".join(p.argv) for p in plan.processes)
    assert str(token) not in argv and "--login-file" in argv and secret_file in argv
    assert plan.process("mqtt_bridge").nodes[0].params["mqtt_secret_file"] == secret_file


def _cli_launch(out: Path, broker_url: str, steps: int) -> subprocess.Popen[str]:
    cli = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
    return subprocess.Popen([*cli, "launch", "--ems", "fuzzy", "--plant", "mqtt", "--weeks", "1", "--steps",
                             str(steps), "--broker", broker_url, "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_foreign_publishers_on_a_shared_broker_are_counted_and_not_applied(tmp_path: Path, broker: Broker) -> None:
    """On a broker others can reach (anonymous here, as a shared Mosquitto): set-points and
    measurements on the right topics without the run's code, and a sealed set-point of an
    earlier run replayed, are counted, reported and not applied: the run equals in-process."""
    tmap = load_topic_map(broker_url=broker.url)
    bess = tmap.setpoints["p_bess_w"].topic
    spy = MqttLink(tmap.broker, "test_spy", [bess, tmap.step_topic])
    assert spy.start(wait_s=BUDGET_S)
    _, text = _cli_launch(tmp_path / "first", broker.url, 12).communicate(timeout=BUDGET_S)
    recorded = [m.payload for m in spy.drain() if m.topic == bess and b'"mac"' in m.payload]
    assert recorded, text[-2000:]
    proc = _cli_launch(tmp_path / "second", broker.url, 48)
    sent = 0
    try:
        deadline = Deadline("the second run at step 40")
        steps: list[int] = []
        while not deadline.passed() and not (steps and steps[-1] >= 40):
            for m in spy.drain():
                if m.topic == tmap.step_topic and m.payload and not m.retain:
                    steps.append(json.loads(m.payload)["step"])
            if steps and steps[-1] >= 2 and sent < 60:
                k = steps[-1]
                for topic, payload in (
                        (bess, json.dumps({"value": -1000.0, "step": k + 1}).encode()),  # no code
                        (bess, recorded[-1]),  # a sealed message of the first run, replayed
                        (tmap.measurements["t_air_c"].topic, json.dumps({"value": 80.0, "step": k + 1}).encode())):
                    spy.publish(topic, payload)
                    sent += 1
            time.sleep(0.05)
        out, _ = proc.communicate(timeout=BUDGET_S)
    finally:
        if proc.poll() is None:
            proc.kill()
        spy.stop()
    assert proc.returncode == 0 and sent >= 30, out[-3000:]
    summary = json.loads((tmp_path / "second" / "summary.json").read_text())
    _same(summary, _reference(1, 48))  # nothing foreign was applied
    assert summary["fallback_steps"] == 0 and summary["mqtt"]["foreign_messages"] >= sent // 2
    assert "MQTT message(s) from someone else than the run's house or bridge were not applied" in out
    events = (tmp_path / "second" / "log" / "mqtt_bridge.log").read_text()
    assert "foreign_mqtt topic 'building/zone/air_temperature': no authentication code" in events
    assert "the house did not apply" in events
    house = (tmp_path / "second" / "log" / "mqtt_plant.log").read_text()
    # the replay carries the first run's code: each launch has its own secret, so it is wrong here
    assert "'no authentication code': " in house and "'wrong authentication code': " in house
