"""A ROS run that is cut short fails fast and names the cause; counts mean what they say; no secret leaks.

Real processes throughout: ``comems4build launch`` as a user runs it, its node, container
and broker processes over DDS and MQTT, an amqtt broker of the test, and an rclpy node of
the test that spoofs commands. One case per row of each class:

* a node that leaves during a run (SIGTERM to plant_sim, to the EMS, SIGINT to feed, a
  container of layout ``house``, the EMS process of layout ``role``, SIGTERM to the
  simulated house behind MQTT, the embedded MQTT broker killed, an external broker
  killed and not restarted): the launch exits 1 within
  10 s of the departure, the console's first line says the run was cut and names the
  node (or the broker's URL), the bag is kept and marked incomplete (``run_cut.json``,
  ``run_cut`` in summary.json);
* a stall (the EMS or the feed paused: alive but silent) is named with the silent node;
* the MQTT bridge's safety fallback steps (no state by design) are no lost messages: no
  warning, ``lost_messages`` empty, ``evaluate`` accepts the bag without ``--accept-gaps``;
* SIGKILL of one container of a 2-house run: the launcher names the nodes that died with
  it (house_0's), and each house's summary lists the damage of its own bag only and
  which of its own nodes left (``nodes_here``: none for the intact house);
* live inputs that cannot be fetched: the launch (exit 2, before anything starts) and the
  feed node (exit 2) refuse, naming the source URL; steps of a live run beyond the known
  prices, and the scenario's weather, are stated on the console, in summary.json and in the bag;
* a command built from anything another local user can read (every process's command
  line, every world-readable file of the run) is not applied; the run token (read here
  from its private file, as only the run's user can) is, which shows the spoof reached the plant.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from array import array
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from launch_probe import pid_of, records_on_disk, run_held
from waits import BUDGET_S, wait_exit, wait_until

from comems4build_ros.mqtt.broker import free_port
from comems4build_ros.ros.interfaces import qos_profile
from comems4build_ros.run.supervisor import processes_with_env

pytestmark = pytest.mark.ros
#: ``comems4build`` of this tree.
CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
#: Step time-out of the runs [s]: with the launcher's 3 stall steps a silent node is named after 6 s.
STEP_TIMEOUT = "2"
#: A node's departure must fail the launch within this [s] (what the launcher promises).
DEPARTURE_LIMIT_S = 10.0
#: A silent node must be named within this [s]: 3 step time-outs of 2 s plus the same margin.
STALL_LIMIT_S = 6.0 + DEPARTURE_LIMIT_S


class Run:
    """``comems4build launch`` in a subprocess; its stderr lines are kept with their arrival times."""

    def __init__(self, out: Path, *args: str) -> None:
        self.out = out
        self.proc = subprocess.Popen([*CLI, "launch", "--out", str(out), "--no-progress", *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.lines: list[tuple[float, str]] = []
        self.stdout: list[str] = []
        self._readers = [threading.Thread(target=self._read, daemon=True),
                         threading.Thread(target=self._read_stdout, daemon=True)]
        for r in self._readers:
            r.start()

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    def _read_stdout(self) -> None:
        assert self.proc.stdout is not None
        self.stdout.extend(self.proc.stdout)

    def started(self, log: str) -> bool:
        """The lock-step master (logging to ``log/<log>.log``) has started the run."""
        path = self.out / "log" / f"{log}.log"
        return path.is_file() and "starting the run" in path.read_text(errors="replace")

    def recording(self) -> bool:
        """Steps are being recorded: a plant/record message can be read from the bag."""
        return records_on_disk(self.out / "bag")

    def wait_running(self, master: str) -> None:
        """Until the run has started and steps are on disk (the EMS has answered)."""
        wait_until(lambda: (self.started(master) and self.recording()) or self.proc.poll() is not None,
                   "recorded steps")
        assert self.proc.poll() is None, "the run ended before the fault"

    def first(self, text: str) -> float | None:
        """Arrival time of the first stderr line containing ``text``."""
        return next((t for t, line in list(self.lines) if text in line), None)

    def finish(self) -> tuple[int, str]:
        """Exit code and stderr; nothing of the launch may be left running."""
        try:
            wait_exit(self.proc, "the launch to end")
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
        wait_until(lambda: not any(r.is_alive() for r in self._readers), "the launch's output read to its end")
        marker = str(self.out / "log" / "ros")
        try:  # the launcher's processes end with it; a /proc entry may outlive its exit for a moment
            wait_until(lambda: not processes_with_env("ROS_LOG_DIR", marker), "no process of the launch left")
        finally:
            for pid in processes_with_env("ROS_LOG_DIR", marker):
                os.kill(pid, signal.SIGKILL)
        return self.proc.returncode, "\n".join(line for _, line in self.lines)




class Broker:
    """An amqtt broker process of the test (outside the launch: a broker given by URL)."""

    def __init__(self, tmp: Path) -> None:
        self.port = free_port()
        self.url = f"mqtt://127.0.0.1:{self.port}"
        with open(tmp / "broker.log", "w") as log:
            self.proc = subprocess.Popen([sys.executable, "-m", "comems4build_ros.mqtt.broker", "--port",
                                          str(self.port)], stdout=subprocess.PIPE, stderr=log, text=True,
                                         start_new_session=True)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.startswith("broker ready"), line

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        wait_exit(self.proc, "the broker killed")


@pytest.fixture()
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    yield b
    b.close()


# ---------------------------------------------------------------------- a node leaves, a node falls silent
# id: (launch arguments, log of the lock-step master, process to signal, signal, texts the error names,
#      time limit from the signal to the launcher's first line [s])
FAULTS = {
    "plant_sim SIGTERM": ([], "plant_sim", "plant_sim", signal.SIGTERM,
                          ["node 'plant_sim' exited with code 3", "stopped by a signal"], DEPARTURE_LIMIT_S),
    "EMS SIGTERM": ([], "plant_sim", "fuzzy_ems", signal.SIGTERM,
                    ["node 'fuzzy_ems' exited with code 3", "stopped by a signal"], DEPARTURE_LIMIT_S),
    "feed SIGINT": ([], "plant_sim", "feed", signal.SIGINT,
                    ["node 'feed' exited with code 3", "stopped by a signal"], DEPARTURE_LIMIT_S),
    "container SIGTERM": (["--houses", "2", "--containers", "2"], "container_0", "container_1", signal.SIGTERM,
                          ["node 'container_1' exited with code 3",
                           "(it ran recorder, fuzzy_ems, feed, plant_sim of /house_1)"],
                          DEPARTURE_LIMIT_S),
    "role EMS SIGTERM": (["--houses", "2", "--layout", "role"], "role_plant", "role_ems", signal.SIGTERM,
                         ["node 'role_ems' exited with code 3", "(it ran fuzzy_ems of /house_0, /house_1)"],
                         DEPARTURE_LIMIT_S),
    "mqtt_plant SIGTERM": (["--plant", "mqtt", "--weeks", "2"], "mqtt_bridge", "mqtt_plant", signal.SIGTERM,
                           ["node 'mqtt_plant' exited with code 3", "stopped by a signal"], DEPARTURE_LIMIT_S),
    "embedded MQTT broker SIGKILL": (["--plant", "mqtt", "--weeks", "2"], "mqtt_bridge", "broker", signal.SIGKILL,
                                     ["node 'broker' exited with code -9", "killed by SIGKILL"], DEPARTURE_LIMIT_S),
    "EMS paused (stall)": ([], "plant_sim", "fuzzy_ems", signal.SIGSTOP,
                           ["run stalled", "the EMS is silent", "publisher: /fuzzy_ems"], STALL_LIMIT_S),
    "feed paused (stall)": ([], "plant_sim", "feed", signal.SIGSTOP,
                            ["run stalled", "waiting for the feed's inputs", "publisher: /feed"], STALL_LIMIT_S),
}


@pytest.mark.parametrize("case", list(FAULTS), ids=list(FAULTS))
def test_a_node_that_leaves_or_falls_silent_fails_the_launch_naming_it(tmp_path: Path, case: str) -> None:
    args, master, target, sig, texts, limit_s = FAULTS[case]
    out = tmp_path / "run"
    # a stall is named after three step time-outs: short ones where a stall is the fault, the budget
    # where a node leaves (a stall on a slow step of a loaded machine would be the machine's)
    step_timeout = STEP_TIMEOUT if sig == signal.SIGSTOP else f"{BUDGET_S:g}"
    run = Run(out, "--ems", "fuzzy", "--weeks", "12", "--step-timeout", step_timeout, *args)
    run.wait_running(master)
    with run_held(out, master):  # the run cannot end before the fault (its master paused)
        t_signal = time.monotonic()
        os.kill(pid_of(out, target), sig)
    code, err = run.finish()
    assert code == 1, err
    # said first, at once (after the supervisor's warning that a process is paused, SIGSTOP)
    first = next(ln for ln in err.splitlines() if not ln.startswith("launcher: warning:"))
    assert first.startswith(("launcher: run cut short", "launcher: run stalled")), err
    for text in texts:
        assert text in err, (text, err)
    t_named = run.first("launcher: run")
    assert t_named is not None and t_named - t_signal < limit_s, f"named {t_named - t_signal:.1f} s after the signal"
    print(f"{case}: named {t_named - t_signal:.2f} s after the signal: {first}")
    # the bag is kept and marked incomplete; the summary of what was recorded says the run was cut
    cut_files = sorted((out / "bag").rglob("run_cut.json"))
    assert cut_files, "no bag marked"
    assert json.loads(cut_files[0].read_text())["cause"] in first
    assert (out / "summary.json").is_file(), err  # the launcher says why the cut bag could not be evaluated
    summary = json.loads((out / "summary.json").read_text())
    for s in summary.get("houses", {"/": summary}).values():
        assert s["run_cut"] and s["bag_incomplete"]["run_cut"]["cause"] in first
        assert s["bag_incomplete"]["steps_recorded"] < s["bag_incomplete"]["steps_expected"]


def test_an_external_broker_killed_and_not_restarted_is_named(tmp_path: Path, broker: Broker) -> None:
    out = tmp_path / "run"
    run = Run(out, "--ems", "fuzzy", "--weeks", "2", "--step-timeout", STEP_TIMEOUT, "--plant", "mqtt",
              "--broker", broker.url)
    run.wait_running("mqtt_bridge")
    with run_held(out, "mqtt_bridge"):  # the run cannot end before the fault
        t_kill = time.monotonic()
        broker.close()  # SIGKILL, not restarted
    code, err = run.finish()
    assert code == 1, err
    first = err.splitlines()[0]
    assert first.startswith("launcher: run cut short") and "run stalled" in first, err
    assert "node 'mqtt_bridge' exited with code 4" in first and f"broker {broker.url}: not connected" in first, err
    t_named = run.first("launcher: run")
    assert t_named is not None and t_named - t_kill < STALL_LIMIT_S, f"named {t_named - t_kill:.1f} s after the kill"
    print(f"external broker killed: named {t_named - t_kill:.2f} s after the kill: {first}")


# ---------------------------------------------------------------------- counts that mean what they say
def test_mqtt_fallback_steps_without_state_are_no_lost_messages(tmp_path: Path, broker: Broker) -> None:
    """Home Assistant's fallback switch on for a while: the bridge announces no state for those
    steps, by design; the run reports no lost message and evaluate takes the bag as complete."""
    from comems4build_ros.mqtt.client import MqttLink
    from comems4build_ros.mqtt.topicmap import load_topic_map

    out = tmp_path / "run"
    tmap = load_topic_map(broker_url=broker.url)
    link = MqttLink(tmap.broker, "test_switch", [tmap.state_topic])
    assert link.start(wait_s=10)
    run = Run(out, "--ems", "rbc", "--weeks", "2", "--plant", "mqtt", "--broker", broker.url)
    reported: list[int] = []

    def bridge_reports_fallback() -> bool:
        # the bridge's state (a fresh broker: nothing retained from another run) counts the
        # fallback steps; the switch stays on until one has been taken (a fixed time was not
        # enough under load: the run can wait that long for the EMS's first command)
        reported.extend(json.loads(m.payload)["fallback_steps"] for m in link.drain())
        return any((n or 0) >= 1 for n in reported) or run.proc.poll() is not None

    try:
        wait_until(lambda: run.started("mqtt_bridge") or run.proc.poll() is not None, "the start of the run")
        link.publish(tmap.switch_topics("fallback")[0], "ON")
        wait_until(bridge_reports_fallback, "a fallback step reported by the bridge")
        link.publish(tmap.switch_topics("fallback")[0], "OFF")
        code, err = run.finish()
    finally:
        link.stop()
    assert code == 0, err
    assert "misses messages" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 336 and summary["fallback_steps"] >= 1, summary["fallback_steps"]
    assert summary["lost_messages"] == {} and "bag_incomplete" not in summary
    res = subprocess.run([*CLI, "evaluate", str(out / "bag"), "--out", str(tmp_path / "eval")],
                         capture_output=True, text=True, timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr  # no --accept-gaps needed
    assert "complete" in res.stdout
    print(f"fallback steps without state (withheld): {summary['fallback_steps']}")


def test_container_killed_damage_attributed_to_its_own_house(tmp_path: Path) -> None:
    out = tmp_path / "run"
    # fuzzy (the slower EMS per step): each house's 12 weeks take some seconds in its container,
    # and the kill comes as soon as both bags have records in closed chunks on disk (1 s chunk
    # period; house_1's first step can come later than house_0's: once, it had none yet)
    run = Run(out, "--ems", "fuzzy", "--weeks", "12", "--houses", "2", "--containers", "2",
              "--step-timeout", f"{BUDGET_S:g}")
    run.wait_running("container_0")
    wait_until(lambda: all(records_on_disk(out / "bag" / b) for b in ("house_0", "house_1"))
               or run.proc.poll() is not None, "both houses' records on disk")
    assert run.proc.poll() is None, "the run ended before the fault"
    with run_held(out, "container_0") as container:  # house_0's run cannot end before the fault
        assert not (out / "bag" / "house_0" / "metadata.yaml").exists(), "house_0's run ended before the fault"
        os.kill(container, signal.SIGKILL)
    code, err = run.finish()
    assert code == 1 and "node 'container_0' exited with code -9 (killed by SIGKILL)" in err, err
    first = err.splitlines()[0]  # the nodes that died with the container: house_0's, none of house_1's
    assert "(it ran recorder, fuzzy_ems, feed, plant_sim of /house_0)" in first and "/house_1" not in first, first
    b0 = json.loads((out / "house_0" / "summary.json").read_text())["bag_incomplete"]
    b1 = json.loads((out / "house_1" / "summary.json").read_text())["bag_incomplete"]
    assert sorted(b0["run_cut"]["nodes_here"]) == [f"/house_0/{n}" for n in ("feed", "fuzzy_ems", "plant_sim",
                                                                                 "recorder")]
    assert b1["run_cut"]["nodes_here"] == []  # cut by the other house's loss: its own nodes all ran on
    assert b0["metadata_yaml"] is False  # its recorder was killed with its container
    assert b1["metadata_yaml"] is True and b1["damage"] == [] and b1["truncated_mcap"] is False
    assert all("house_1" not in d for d in b0["damage"]) and all("house_0" not in d for d in b1["damage"])
    print("house_0:", b0, "\nhouse_1:", b1)


# ---------------------------------------------------------------------- live inputs that cannot be fetched
def _live_config(tmp_path: Path, url: str) -> Path:
    import yaml

    from comems4build_ros.core.config import config_dir

    doc = yaml.safe_load((config_dir() / "live_inputs.yaml").read_text())
    doc["/**"]["ros__parameters"]["live_inputs"]["prices"].update(url=url, retries=1, timeout_s=2.0, retry_delay_s=0.0)
    path = tmp_path / "live.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("where", ["launch", "feed node"])
def test_live_inputs_that_cannot_be_fetched_are_refused_naming_the_source(tmp_path: Path, where: str) -> None:
    """Nothing listens at the source's port (as with no network): no run on stand-in prices."""
    url = f"http://127.0.0.1:{free_port()}/v1/marketdata"
    cfg = _live_config(tmp_path, url)
    out = tmp_path / "run"
    if where == "launch":
        res = subprocess.run([*CLI, "launch", "--ems", "rbc", "--weeks", "1", "--inputs", "live", "--live-config",
                              str(cfg), "--out", str(out), "--no-progress"],
                             capture_output=True, text=True, timeout=BUDGET_S)
        assert not out.exists()  # refused before anything started or was written
    else:
        from comems4build_ros.run.plan import node_command, ros_args

        env = {**os.environ, "ROS_LOG_DIR": str(tmp_path / "ros_log"), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
        res = subprocess.run([*node_command("feed"), *ros_args("", {"weeks": 1, "inputs": "live", "live_config":
                                                                    str(cfg), "live_cache_dir": str(tmp_path)})],
                             capture_output=True, text=True, timeout=BUDGET_S, env=env)
    assert res.returncode == 2, res.stderr
    assert url in res.stderr and "no day-ahead price for the run's first hour" in res.stderr, res.stderr
    assert "Traceback" not in res.stderr


def test_live_run_states_its_stand_in_prices_on_the_console_in_the_summary_and_the_bag(tmp_path: Path) -> None:
    """Live prices known for 30 hours from the last hour, no weather source (the default): a
    one-week run goes, and the steps beyond the known prices (the same hour of the latest
    day standing in) and the scenario's weather are stated, not hidden."""
    from test_live_inputs import Server, awattar_answer

    from comems4build_ros.bags.bag import decode, iter_messages

    first = pd.Timestamp.now(tz="Europe/Berlin").floor("h") - pd.Timedelta(hours=1)
    server = Server()
    server.responses = [(200, awattar_answer(first, 30, 80.0), 0.0)]
    try:
        out = tmp_path / "run"
        res = subprocess.run([*CLI, "launch", "--ems", "rbc", "--weeks", "1", "--inputs", "live", "--live-config",
                              str(_live_config(tmp_path, server.url)), "--out", str(out), "--no-progress"],
                             capture_output=True, text=True, timeout=BUDGET_S)
    finally:
        server.close()
    assert res.returncode == 0, res.stderr
    summary = json.loads((out / "summary.json").read_text())
    ts = pd.read_csv(out / "timeseries.csv")
    end = first + pd.Timedelta(hours=30)  # the first hour without a live price
    beyond = int((pd.to_datetime(ts["time"], utc=True) >= end.tz_convert("UTC")).sum())
    assert summary["steps"] == 168 and 130 <= beyond <= 140, beyond
    assert summary["scenario"] == "default+live"
    assert summary["live_inputs"] == {"stand_in_price_steps": beyond, "stand_in_weather_steps": 168}
    warning = f"live inputs: {beyond} of 168 steps ran on stand-in prices"
    assert warning in res.stderr and "168 on the scenario's weather" in res.stderr, res.stderr
    lines = [decode(m, raw).data for topic, m, _, raw in iter_messages(out / "bag") if topic == "/feed/events"]
    stated = [ln for ln in lines if ln.split()[1] == "stand_in"]
    assert [ln.split(":")[0] for ln in stated] == ["0 stand_in weather", f"{168 - beyond} stand_in prices+weather"]
    print(f"live run: {res.stderr.strip().splitlines()[-1]}")
    ev = subprocess.run([*CLI, "evaluate", str(out / "bag"), "--out", str(tmp_path / "eval")],
                        capture_output=True, text=True, timeout=BUDGET_S)
    assert ev.returncode == 0 and f'"stand_in_price_steps": {beyond}' in ev.stdout, ev.stdout + ev.stderr


# ---------------------------------------------------------------------- secrets
def _world_readable(path: Path, top: Path) -> bool:
    """Whether a user other than the owner can read ``path`` (mode bits of it and of every
    directory from it up to ``top``, the run's output directory, whose parents are the
    user's choice (pytest's own are private); this test may run as root, so access() cannot tell)."""
    p = path
    if not path.stat().st_mode & 0o004:
        return False
    while p != top:
        p = p.parent
        if not p.stat().st_mode & 0o001:
            return False
    return True


def _readable_by_others(out: Path) -> tuple[set[int], int]:
    """Every integer of 7 to 16 digits that another local user can read while the run goes: in the
    command line of every process (``ps``) and in every world-readable file of the run; and
    how many files were read. (The launcher's tokens are drawn from 1 .. 2^48: below 10^6
    with a probability of 4e-9.)"""
    text = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                text.append((d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"))
            except OSError:
                continue
    files = [f for f in out.rglob("*") if f.is_file() and _world_readable(f, out)]
    for f in files:
        text.append(f.read_text(errors="replace"))
    found = re.findall(r"(?<![\d.])\d{7,16}(?![\d])", "\n".join(text))
    return {int(m) for m in found if 0 < int(m) < 2**53}, len(files)


def test_a_command_spoofed_from_what_other_users_can_read_is_not_applied(tmp_path: Path) -> None:
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray, UInt32

    from comems4build_ros.run.supervisor import acquire_domain_id
    from comems4build_ros.wire.contract import load_contract
    from comems4build_ros.wire.tokens import command_mac, secret_key

    with acquire_domain_id() as did:
        pass  # a free domain id for the run, joined below by the spoofer
    out = tmp_path / "run"
    # a step time-out of 20 s: the EMS is paused for a fallback step and the spoofing, which a loaded
    # machine can stretch; 3 silent steps end the run as stalled (by design) before it is over. With 5 s,
    # 500 candidates (5 batches, each waiting for its acknowledgements) reached the plant over 14 s, the
    # plant fell back 3 times in a row and ended the run (once in a fresh clone's suite)
    run = Run(out, "--ems", "fuzzy", "--weeks", "12", "--step-timeout", "20", "--domain-id", str(did))
    contract = load_contract()
    # DHW at 37 %, the rest idle: hp_mod, hp_mode, p_fc_w, p_bess_w, p_el_w (in range, distinctive)
    spoof = [0.37, 2.0, 0.0, 0.0, 0.0]
    assert contract.topic("ems/command").layout_labels == ("step", "hp_mod", "hp_mode", "p_fc_w", "p_bess_w", "p_el_w",
                                                           "token")
    steps: list[int] = []
    ems = None
    ctx = Context()
    try:
        run.wait_running("plant_sim")  # the EMS has answered: from now on a missing command means a fallback
        candidates, n_files = _readable_by_others(out)
        token = int((out / ".secrets" / "root.token").read_text())  # readable by the run's user only
        assert oct((out / ".secrets" / "root.token").stat().st_mode & 0o777) == "0o600"
        assert oct((out / ".secrets").stat().st_mode & 0o777) == "0o700"
        assert token not in candidates, "the run token is readable by other users"
        # the run's logs, lock and plan files are private to its user (docs/security.md), so what another
        # user reads is the process list and the run's results (umask); the codes of the EMS's commands
        # sniffed on the wire are added below
        # the spoofer joins the run's domain (as any local user can) once the run goes
        rclpy.init(context=ctx, domain_id=did)
        node = Node("spoofer", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        node.create_subscription(UInt32, "/plant/step", lambda m: steps.append(int(m.data)),
                                 qos_profile(contract.topic("plant/step")))
        sniffed: list[float] = []  # the tokens of the EMS's commands as DDS carries them (in clear)
        node.create_subscription(Float64MultiArray, "/ems/command", lambda m: sniffed.append(float(m.data[-1])),
                                 qos_profile(contract.topic("ems/command")))
        cmd = node.create_publisher(Float64MultiArray, "/ems/command", qos_profile(contract.topic("ems/command")))

        def spin(seconds: float) -> bool:
            t_end = time.monotonic() + seconds
            while time.monotonic() < t_end:
                ex.spin_once(timeout_sec=0.02)
            return False

        def joined() -> bool:
            assert run.proc.poll() is None, "the run ended before the spoofer had joined"
            return (bool(steps) and bool(sniffed) and cmd.get_subscription_count() >= 2) or spin(0.05)

        wait_until(joined, "the plant's announcements, the EMS's commands and the readers of ems/command matched")
        ems = pid_of(out, "fuzzy_ems")
        os.kill(ems, signal.SIGSTOP)  # the plant now waits for a command: the spoof has the field to itself
        # the step it waits for is the one it announces again (its republish period): a command the EMS
        # sent just before the stop can still move it on, so wait for a step announced twice after the stop
        after = len(steps)
        wait_until(lambda: (len(steps) - after >= 2 and steps[-1] == steps[-2]) or spin(0.05),
                   "the plant announcing the step it waits for again")
        k = steps[-1]
        assert token not in sniffed  # the secret itself is never on the wire ...
        candidates |= {int(t) for t in sniffed}  # ... its codes are, and are tried as well
        ordered = sorted(candidates)
        for i in range(0, len(ordered), 100):  # every readable candidate, for the step the plant waits for
            for t in ordered[i:i + 100]:
                cmd.publish(Float64MultiArray(data=[float(k), *spoof, float(t)]))
            assert cmd.wait_for_all_acked(Duration(seconds=BUDGET_S))  # within the writer's history depth (1000)
        # the plant falls back for k after its step time-out and announces k + 1
        wait_until(lambda: steps[-1] > k or spin(0.02), "the announcement of the next step")
        k1 = steps[-1]
        values = array("d", [float(k1), *spoof])  # with the run's secret, as only the run's user can:
        cmd.publish(Float64MultiArray(data=[*values, command_mac(secret_key(token), values.tobytes())]))
        wait_until(lambda: steps[-1] > k1 or spin(0.02), "the plant taking that command (the next step announced)")
        os.kill(ems, signal.SIGCONT)
        ems = None
        code, err = run.finish()
    finally:
        if ems is not None:
            os.kill(ems, signal.SIGCONT)
        if run.proc.poll() is None:
            run.proc.send_signal(signal.SIGINT)
        rclpy.try_shutdown(context=ctx)
    assert code == 0, err
    ts = pd.read_csv(out / "timeseries.csv")
    summary = json.loads((out / "summary.json").read_text())
    print(f"{len(candidates)} candidate tokens from {n_files} world-readable files, the process list and the wire; "
          f"foreign commands counted: {summary.get('ros_faults', {}).get('foreign_commands')}")
    assert summary["ros_faults"]["foreign_commands"] == len(candidates)  # every spoof reached the plant ...
    assert ts["fallback"][k] == 1 and ts["cmd_hp_mod"][k] != 0.37  # ... and none was applied
    assert (ts["cmd_hp_mode"][k1], ts["cmd_hp_mod"][k1]) == (2, 0.37)  # the channel works: the true token is
    assert ((ts["cmd_hp_mod"] == 0.37) & (ts["cmd_hp_mode"] == 2)).sum() == 1
    assert not (out / ".secrets").exists()  # removed after the run


def test_dds_security_plugins_are_missing_from_the_installed_fast_dds(tmp_path: Path) -> None:
    """What docs/ros_nodes.md states as measured: the ROS wheels' Fast DDS has no DDS-Security
    plugins, so an enforced SROS2 enclave cannot be used here. The day a wheel brings them this
    fails: then DDS-Security gets a real test (keystore, enclaves, a spoofer without permissions)."""
    enclave = tmp_path / "keystore" / "enclaves" / "probe"
    enclave.mkdir(parents=True)
    for name in ("identity_ca.cert.pem", "cert.pem", "key.pem", "governance.p7s", "permissions.p7s",
                 "permissions_ca.cert.pem"):
        (enclave / name).write_text("not a certificate\n")
    env = {**os.environ, "ROS_SECURITY_KEYSTORE": str(tmp_path / "keystore"), "ROS_SECURITY_ENABLE": "true",
           "ROS_SECURITY_STRATEGY": "Enforce", "ROS_SECURITY_ENCLAVE_OVERRIDE": "/probe",
           "ROS_LOG_DIR": str(tmp_path / "ros_log"), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    res = subprocess.run([sys.executable, "-c", "import rclpy; rclpy.init(); rclpy.create_node('probe')"],
                         capture_output=True, text=True, timeout=BUDGET_S, env=env)
    assert res.returncode != 0, "a node was created with an enforced enclave: test DDS-Security for real"
    assert "doesn't have the security libraries" in res.stderr and "-DSECURITY=ON" in res.stderr, res.stderr
