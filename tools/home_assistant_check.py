"""A building owner's Home Assistant around ``launch --plant mqtt``, headless, and what it shows.

Starts Debian's Mosquitto (persistence on, a login per client, as Home Assistant's
Mosquitto add-on runs it) and Home Assistant (``tools/home_assistant.sh install``: 2025.4.4
in its own Python 3.13 venv) with the MQTT integration set up headless (its config entry,
discovery on, written into ``.storage`` before the start, as the integration's config flow
would write it), runs ``comems4build launch --plant mqtt`` against that broker, and reads
every entity of the EMS's device through Home Assistant's REST API (``GET /api/states``,
with a long-lived access token written into ``.storage/auth``). After each run it checks
that the entities exist with the classes of the discovery configs and that their final
states equal the run's ``summary.json``.

    .venv/bin/python tools/home_assistant_check.py --runs 10 --steps 24 --broker-restart --out /tmp/ha
    .venv/bin/python tools/home_assistant_check.py --runs 1 --show --screenshot docs/figures/ha_device.png

``test/test_home_assistant.py`` drives the same classes. Sources: Home Assistant's MQTT
integration documentation ("MQTT Discovery", "Sensor", "Switch"), its REST API
documentation (``/api/states``, ``/api/services``), Mosquitto's ``mosquitto.conf(5)``
(``listener``, ``persistence``, ``password_file``) and ``mosquitto_passwd(1)``.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import hashlib
import hmac
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
import uuid
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: Home Assistant and its MQTT client's user names on the test broker.
HA_USER, EMS_USER = "homeassistant", "ems"
#: Wait for Home Assistant's API after the start [s] (measured: 20..60 s on a loaded 2-core machine).
HA_START_TIMEOUT_S = 240.0


def free_port() -> int:
    """A TCP port on 127.0.0.1 that is free right now."""
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def ha_python() -> Path | None:
    """The Home Assistant venv's python (``tools/home_assistant.sh path``), None if not installed."""
    proc = subprocess.run(["bash", str(ROOT / "tools" / "home_assistant.sh"), "path"], capture_output=True, text=True)
    return Path(proc.stdout.strip()) if proc.returncode == 0 and proc.stdout.strip() else None


def mosquitto_binary() -> str | None:
    """Debian's ``mosquitto`` (``/usr/sbin`` is not on every PATH)."""
    return shutil.which("mosquitto") or next((p for p in ("/usr/sbin/mosquitto",) if os.access(p, os.X_OK)), None)


def _wait_port(port: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.closing(socket.socket()) as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return True
        time.sleep(0.05)
    return False


class Mosquitto:
    """Debian's Mosquitto on 127.0.0.1:``port`` with persistence and a password file (restartable)."""

    def __init__(self, work: Path, users: dict[str, str], port: int | None = None) -> None:
        self.work = work
        self.port = port or free_port()
        self.url = f"mqtt://127.0.0.1:{self.port}"
        work.mkdir(parents=True, exist_ok=True)
        passwd = work / "passwd"
        passwd.write_text("")
        for user, password in users.items():  # mosquitto_passwd hashes them (PBKDF2-SHA512)
            subprocess.run(["mosquitto_passwd", "-b", str(passwd), user, password], check=True, capture_output=True)
        self.conf = work / "mosquitto.conf"
        self.conf.write_text(
            f"listener {self.port} 127.0.0.1\n"
            "allow_anonymous false\n"
            f"password_file {passwd}\n"
            "persistence true\n"  # retained messages survive a restart, as with Home Assistant's add-on
            f"persistence_location {work}/\n"
            "autosave_interval 1\n"
            f"log_dest file {work}/mosquitto.log\n"
            + ("user root\n" if os.geteuid() == 0 else "")  # keep access to this private folder
        )
        self.proc: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        """Start and wait until it listens."""
        binary = mosquitto_binary()
        if binary is None:
            raise RuntimeError("mosquitto not installed (bash tools/home_assistant.sh install)")
        self.proc = subprocess.Popen([binary, "-c", str(self.conf)], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL, start_new_session=True)
        if not _wait_port(self.port, 20.0):
            raise RuntimeError(f"mosquitto did not listen on {self.port}: {(self.work / 'mosquitto.log').read_text()}")

    def kill(self) -> None:
        """SIGKILL: no goodbye, as a crash or a power cut."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)

    def stop(self) -> None:
        """SIGTERM (Mosquitto saves its persistence file) and wait."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(15)
            except subprocess.TimeoutExpired:
                self.kill()


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def hs256_jwt(claims: dict[str, Any], key: str) -> str:
    """A JSON Web Token signed with HMAC-SHA256 (RFC 7519), as Home Assistant issues access tokens."""
    head = _b64(json.dumps({"alg": "HS256", "typ": "JWT"}, separators=(",", ":")).encode())
    body = _b64(json.dumps(claims, separators=(",", ":")).encode())
    sig = hmac.new(key.encode(), f"{head}.{body}".encode(), hashlib.sha256).digest()
    return f"{head}.{body}.{_b64(sig)}"


class HomeAssistant:
    """Home Assistant in its own venv with a headless configuration (see the module docstring)."""

    def __init__(self, python: Path, config: Path, broker_port: int, mqtt_password: str, port: int | None = None):
        self.python = python
        self.config = config
        self.port = port or free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.proc: subprocess.Popen[bytes] | None = None
        self.token = self._write_config(broker_port, mqtt_password)

    def _write_config(self, broker_port: int, mqtt_password: str) -> str:
        storage = self.config / ".storage"
        storage.mkdir(parents=True, exist_ok=True)
        (self.config / "configuration.yaml").write_text(
            "homeassistant:\n  name: ComEMS4Build test house\n  latitude: 48.97\n  longitude: 8.33\n"
            "  elevation: 116\n  unit_system: metric\n  currency: EUR\n  time_zone: UTC\n  country: DE\n"
            f"http:\n  server_host: 127.0.0.1\n  server_port: {self.port}\n"
            "logger:\n  default: warning\n"
        )
        now = datetime.now(UTC)
        stamp = now.isoformat()

        def store(key: str, data: dict[str, Any], version: int = 1, minor: int = 1) -> None:
            (storage / key).write_text(json.dumps({"version": version, "minor_version": minor, "key": key,
                                                   "data": data}))

        store("onboarding", {"done": ["user", "core_config", "analytics", "integration"]}, version=4)
        store("core.config_entries", {"entries": [{
            "entry_id": uuid.uuid4().hex, "version": 1, "minor_version": 2, "domain": "mqtt",
            "title": f"127.0.0.1:{broker_port}", "source": "user", "unique_id": None, "disabled_by": None,
            "data": {"broker": "127.0.0.1", "port": broker_port, "username": HA_USER, "password": mqtt_password},
            "options": {"discovery": True, "discovery_prefix": "homeassistant"},
            "pref_disable_new_entities": False, "pref_disable_polling": False, "created_at": stamp,
            "modified_at": stamp, "discovery_keys": {}, "subentries": []}]}, minor=5)
        user_id, token_id, jwt_key = uuid.uuid4().hex, uuid.uuid4().hex, secrets.token_hex(64)
        store("auth", {
            "users": [{"id": user_id, "group_ids": ["system-admin"], "is_owner": True, "is_active": True,
                       "name": "Building owner", "system_generated": False, "local_only": False}],
            "groups": [{"id": "system-admin", "name": "Administrators"}, {"id": "system-users", "name": "Users"},
                       {"id": "system-read-only", "name": "Read Only"}],
            "credentials": [],
            "refresh_tokens": [{
                "id": token_id, "user_id": user_id, "client_id": None, "client_name": "comems4build check",
                "client_icon": None, "token_type": "long_lived_access_token", "created_at": stamp,
                "access_token_expiration": 3650 * 86400.0, "token": secrets.token_hex(64), "jwt_key": jwt_key,
                "last_used_at": None, "last_used_ip": None, "expire_at": None, "credential_id": None,
                "version": "2025.4.4"}],
        })
        iat = int(now.timestamp())
        return hs256_jwt({"iss": token_id, "iat": iat, "exp": iat + 3650 * 86400}, jwt_key)

    def start(self, timeout_s: float = HA_START_TIMEOUT_S) -> float:
        """Start and wait until the REST API answers and the MQTT integration is loaded; returns the seconds taken."""
        t0 = time.monotonic()
        log = open(self.config / "stdout.log", "ab")  # noqa: SIM115 (handed to the child)
        self.proc = subprocess.Popen([str(self.python), "-m", "homeassistant", "-c", str(self.config), "--skip-pip",
                                      "--log-file", str(self.config / "home-assistant.log")],
                                     stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        log.close()
        deadline = t0 + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"Home Assistant exited with {self.proc.returncode}: {self.log_tail()}")
            try:
                entries = self.get("/api/config")
                if "mqtt" in entries.get("components", []):
                    return time.monotonic() - t0
            except OSError:
                pass
            time.sleep(1.0)
        raise RuntimeError(f"Home Assistant not up with MQTT within {timeout_s:g} s: {self.log_tail()}")

    def log_tail(self, n: int = 3000) -> str:
        f = self.config / "home-assistant.log"
        return f.read_text(errors="replace")[-n:] if f.exists() else ""

    def get(self, path: str) -> Any:
        req = urllib.request.Request(self.url + path, headers={"Authorization": f"Bearer {self.token}"})
        with urllib.request.urlopen(req, timeout=10) as r:
            return json.loads(r.read())

    def post(self, path: str, body: dict[str, Any]) -> Any:
        req = urllib.request.Request(self.url + path, data=json.dumps(body).encode(), method="POST",
                                     headers={"Authorization": f"Bearer {self.token}",
                                              "Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=20) as r:
            return json.loads(r.read())

    def states(self, prefix: str = "comems4build_") -> dict[str, dict[str, Any]]:
        """Entity id -> state object of the EMS's entities."""
        return {s["entity_id"]: s for s in self.get("/api/states")
                if s["entity_id"].split(".", 1)[1].startswith(prefix)}

    def switch(self, object_id: str, on: bool) -> None:
        """The user flips a switch in the dashboard (``switch.turn_on``/``turn_off``)."""
        self.post(f"/api/services/switch/turn_{'on' if on else 'off'}", {"entity_id": f"switch.{object_id}"})

    def problems_in_log(self) -> list[str]:
        """Warnings and errors of Home Assistant's log that concern MQTT or the EMS's entities."""
        out = []
        for line in (self.config / "home-assistant.log").read_text(errors="replace").splitlines():
            if (" WARNING " in line or " ERROR " in line) and ("mqtt" in line.lower() or "comems4build" in line):
                out.append(line)
        return out

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)


def ems_topic_map(work: Path, password: str) -> Path:
    """``config/mqtt.yaml`` with the broker login of the EMS's user (password in a file of mode 0600)."""
    import yaml

    from comems4build_ros.mqtt.topicmap import default_map_file

    pw = work / "ems.password"
    pw.write_text(password + "\n")
    pw.chmod(0o600)
    doc = yaml.safe_load(default_map_file().read_text())
    doc["/**"]["ros__parameters"]["mqtt"]["broker"].update(username=EMS_USER, password_file=str(pw))
    f = work / "mqtt.yaml"
    f.write_text(yaml.safe_dump(doc, allow_unicode=True))
    return f


def launch_cmd(out: Path, broker_url: str, topic_map: Path, steps: int, clock: str = "sim") -> list[str]:
    """``comems4build launch --plant mqtt`` against the broker (the project's venv)."""
    return [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())",
            "launch", "--ems", "fuzzy", "--plant", "mqtt", "--weeks", "1", "--steps", str(steps), "--clock", clock,
            "--broker", broker_url, "--topic-map", str(topic_map), "--out", str(out), "--no-progress"]


def expected_entities() -> dict[str, dict[str, Any]]:
    """Entity id -> the discovery config's classes, for the simulated house and the default map."""
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.mqtt.discovery import discovery_messages
    from comems4build_ros.mqtt.topicmap import load_topic_map

    out = {}
    tmap = load_topic_map()
    for topic, p in discovery_messages(tmap, tmap.device_limits(load_plant_params())):
        if p is not None:
            out[f"{topic.split('/')[1]}.{p['object_id']}"] = p
    return out


def check_entities(states: dict[str, dict[str, Any]], summary: dict[str, Any],
                   run_start: str | None = None) -> list[str]:
    """What differs between Home Assistant's entities and the discovery configs and the run's summary."""
    from comems4build_ros.mqtt.discovery import TOTAL_KEYS

    problems = []
    for entity, cfg in expected_entities().items():
        st = states.get(entity)
        if st is None:
            problems.append(f"{entity}: missing")
            continue
        attrs = st["attributes"]
        for key in ("device_class", "state_class", "unit_of_measurement", "options", "min", "max", "step"):
            if key in cfg and attrs.get(key) != cfg[key]:
                problems.append(f"{entity}: {key} {attrs.get(key)!r}, the config says {cfg[key]!r}")
    for key, summary_key in TOTAL_KEYS.items():
        st = states.get(f"sensor.comems4build_{key}")
        if st is None:
            continue
        try:
            value = float(st["state"])
        except ValueError:
            problems.append(f"sensor.comems4build_{key}: state {st['state']!r}, summary {summary[summary_key]!r}")
            continue
        if value != summary[summary_key]:
            problems.append(f"sensor.comems4build_{key}: {value!r}, summary.json's {summary_key} "
                            f"{summary[summary_key]!r}")
        if run_start is not None and not str(st["attributes"].get("last_reset", "")).startswith(run_start[:19]):
            problems.append(f"sensor.comems4build_{key}: last_reset {st['attributes'].get('last_reset')!r}, "
                            f"the run started {run_start}")
    for key, summary_key in (("step", "steps"), ("fallback_steps", "fallback_steps")):
        st = states.get(f"sensor.comems4build_{key}")
        if st is not None and st["state"] != str(summary[summary_key]):
            problems.append(f"sensor.comems4build_{key}: {st['state']!r}, summary.json's {summary_key} "
                            f"{summary[summary_key]!r}")
    return problems


def wait_for(cond: Any, timeout_s: float, period_s: float = 0.5) -> bool:
    """Poll ``cond()`` until it is true or ``timeout_s`` passed."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(period_s)
    return bool(cond())


def dashboard_table(states: dict[str, dict[str, Any]]) -> str:
    """The EMS's entities as Home Assistant shows them (name, state with unit and its suggested
    precision, entity id, category), as a Markdown table."""
    from comems4build_ros.mqtt.discovery import discovery_messages
    from comems4build_ros.mqtt.topicmap import load_topic_map

    precision = {f"{t.split('/')[1]}.{p['object_id']}": p.get("suggested_display_precision")
                 for t, p in discovery_messages(load_topic_map()) if p is not None}
    rows = ["| entity | state | entity id | |", "|---|---|---|---|"]
    for entity in sorted(states, key=lambda e: (e.split(".")[0] != "sensor", e)):
        st = states[entity]
        attrs = st["attributes"]
        value = st["state"]
        digits = precision.get(entity)
        if digits is not None:
            with contextlib.suppress(ValueError):
                value = f"{float(value):.{digits}f}"
        unit = (attrs.get("unit_of_measurement") or "") if value not in ("unavailable", "unknown") else ""
        cat = "diagnostic" if entity.endswith(("_step", "_fallback_steps", "_clamped_commands", "_foreign_messages",
                                               "_fallback_reason")) else ""
        rows.append(f"| {attrs.get('friendly_name', entity)} | {value} {unit}".rstrip() + f" | `{entity}` | {cat} |")
    return "\n".join(rows)


def screenshot(ha: HomeAssistant, path: Path, work: Path, wait_s: float = 12.0) -> Path:
    """The EMS's device page in Home Assistant's frontend, taken by Debian's headless Chromium
    (``apt-get install chromium``) through its DevTools protocol: the page is opened on Home
    Assistant's origin, the long-lived token put where the frontend keeps its tokens
    (``hassTokens`` in local storage), then the device page is loaded and captured."""
    from websockets.sync.client import connect

    chromium = shutil.which("chromium")
    if chromium is None:
        raise RuntimeError("chromium is not installed (apt-get install chromium)")
    req = urllib.request.Request(ha.url + "/api/template", method="POST",
                                 data=json.dumps({"template": "{{ device_id('sensor.comems4build_step') }}"}).encode(),
                                 headers={"Authorization": f"Bearer {ha.token}", "Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=10) as r:
        device = r.read().decode().strip()
    port = free_port()
    proc = subprocess.Popen([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                             "--no-first-run", "--disable-background-networking", "--disable-component-update",
                             "--disable-sync",
                             f"--user-data-dir={work / 'chromium'}", f"--remote-debugging-port={port}",
                             "--window-size=1280,1500", "about:blank"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        targets: list[dict[str, Any]] = []

        def page_target() -> bool:
            nonlocal targets
            with contextlib.suppress(OSError, ValueError):
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=2) as r:
                    targets = [t for t in json.loads(r.read()) if t.get("type") == "page"]
            return bool(targets)

        if not wait_for(page_target, 30.0):
            raise RuntimeError("chromium's DevTools endpoint did not come up")
        with connect(targets[0]["webSocketDebuggerUrl"], max_size=2**26, open_timeout=20) as ws:
            ids = iter(range(1, 10**6))

            def call(method: str, **params: Any) -> dict[str, Any]:
                i = next(ids)
                ws.send(json.dumps({"id": i, "method": method, "params": params}))
                while True:
                    msg = json.loads(ws.recv(timeout=60))
                    if msg.get("id") == i:
                        return msg.get("result", {})

            call("Page.enable")
            call("Page.navigate", url=ha.url + "/")
            time.sleep(3.0)
            tokens = {"hassUrl": ha.url, "clientId": ha.url + "/", "expires": int(time.time() * 1000) + 10**10,
                      "refresh_token": "", "access_token": ha.token, "expires_in": 10**8, "token_type": "Bearer"}
            call("Runtime.evaluate", expression=f"localStorage.setItem('hassTokens', {json.dumps(json.dumps(tokens))})")
            call("Page.navigate", url=f"{ha.url}/config/devices/device/{device}")
            time.sleep(wait_s)
            shot = call("Page.captureScreenshot", format="png")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(shot["data"]))
        return path
    finally:
        proc.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(10)


#: The run during which --show and --screenshot read Home Assistant: its length and the step from which [steps].
SHOWCASE_STEPS, SHOWCASE_AT_STEP = 60, 12


def live_step(ha: HomeAssistant) -> int:
    """The step of the run going on now, -1 while the EMS's live entities are unavailable."""
    try:
        states = ha.states()
        if states["sensor.comems4build_in_charge"]["state"] in ("unavailable", "unknown"):
            return -1
        return int(states["sensor.comems4build_step"]["state"])
    except (KeyError, TypeError, ValueError, OSError):
        return -1


def main(argv: list[str] | None = None) -> int:
    """The command of the module docstring; exit 0 when every check passed."""
    ap = argparse.ArgumentParser(prog="home_assistant_check", description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=2, help="launch --plant mqtt runs back to back")
    ap.add_argument("--steps", type=int, default=24)
    ap.add_argument("--broker-restart", action="store_true",
                    help="one more run with --clock wall:3600 whose broker is killed for 1.4 s mid-run")
    ap.add_argument("--ha-restart", action="store_true", help="restart Home Assistant during the last run")
    ap.add_argument("--show", action="store_true",
                    help="print the entities as Home Assistant shows them during one more (wall-clock) run")
    ap.add_argument("--screenshot", type=Path, default=None,
                    help="PNG of the EMS's device page during one more (wall-clock) run (headless chromium)")
    ap.add_argument("--out", type=Path, default=Path("runs/home_assistant"))
    args = ap.parse_args(argv)
    python = ha_python()
    if python is None:
        print("home_assistant_check: Home Assistant is not installed: bash tools/home_assistant.sh install",
              file=sys.stderr)
        return 2
    work = args.out.resolve()
    shutil.rmtree(work, ignore_errors=True)
    pw = {HA_USER: secrets.token_hex(12), EMS_USER: secrets.token_hex(12)}
    broker = Mosquitto(work / "mosquitto", pw)
    broker.start()
    ha = HomeAssistant(python, work / "ha_config", broker.port, pw[HA_USER])
    failures = 0
    try:
        print(f"Home Assistant up with MQTT in {ha.start():.1f} s ({ha.url})", flush=True)
        topic_map = ems_topic_map(work, pw[EMS_USER])
        plan = [("sim", False)] * args.runs + ([("wall:3600", True)] if args.broker_restart else [])
        for i, (clock, restart) in enumerate(plan):
            out = work / f"run_{i}"
            t0 = time.monotonic()
            proc = subprocess.Popen(launch_cmd(out, broker.url, topic_map, args.steps, clock), cwd=ROOT,
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            if restart:
                time.sleep(25.0)  # start-up, then a few wall-clock steps
                broker.kill()
                time.sleep(1.4)
                broker.start()
            if args.ha_restart and i == len(plan) - 1:
                time.sleep(15.0)
                ha.stop()
                ha.start()
            text, _ = proc.communicate()
            wall = time.monotonic() - t0
            if proc.returncode != 0:
                print(f"run {i} ({clock}): exit {proc.returncode} after {wall:.1f} s\n{text[-3000:]}", flush=True)
                failures += 1
                continue
            summary = json.loads((out / "summary.json").read_text())
            ok = wait_for(lambda s=summary: not check_entities(ha.states(), s), 30.0)
            problems = check_entities(ha.states(), summary)
            warnings = [line for line in text.splitlines() if "warning" in line]
            print(f"run {i} ({clock}): exit 0, {wall:.1f} s, {summary['steps']} steps, fallback steps "
                  f"{summary['fallback_steps']}, mqtt {summary.get('mqtt')}, Home Assistant "
                  f"{'equal to summary.json' if ok else 'DIFFERENT: ' + '; '.join(problems)}", flush=True)
            for line in warnings:
                print(f"  {line}", flush=True)
            failures += 0 if ok else 1
        if args.show or args.screenshot is not None:  # during a wall-clock run, what a user sees live
            proc = subprocess.Popen(launch_cmd(work / "showcase", broker.url, topic_map, SHOWCASE_STEPS, "wall:3600"),
                                    cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            if not wait_for(lambda: live_step(ha) >= SHOWCASE_AT_STEP, 180.0, 0.2):
                print("showcase run: no live step in 180 s", flush=True)
                failures += 1
            else:
                if args.show:
                    print(dashboard_table(ha.states()), flush=True)
                if args.screenshot is not None:
                    print(f"screenshot: {screenshot(ha, args.screenshot.resolve(), work)}", flush=True)
            text, _ = proc.communicate()
            print(f"showcase run ({SHOWCASE_STEPS} steps, wall:3600): exit {proc.returncode}", flush=True)
            failures += 1 if proc.returncode else 0
        log_problems = ha.problems_in_log()
        print(f"Home Assistant log: {len(log_problems)} MQTT warning(s) or error(s)", flush=True)
        for line in log_problems[:20]:
            print(f"  {line}", flush=True)
    finally:
        ha.stop()
        broker.stop()
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
