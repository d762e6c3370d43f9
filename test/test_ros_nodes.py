"""The node set over real DDS: separate processes for plant_sim, feed and the EMS.

* Closed loop over ROS gives exactly the timeseries and KPIs of the in-process loop
  (``comems4build_ros.core.loop.simulate``) for thermostat, RBC, fuzzy and MPC over 2 days.
* Each node's actual DDS endpoints (graph API) are exactly those the contract declares.
* Faults: an EMS killed mid-run (fallback after the timeout, resume after restart), invalid
  and wrong-step commands (rejected, counted, logged with topic and field), a scenario with
  NaN or a gap (the feed refuses to start).

Every test gets its own ROS_DOMAIN_ID (locked like the launcher does) and ROS_LOG_DIR, and
stops every process it started (SIGINT, then SIGKILL if needed).
"""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import subprocess
import sys
from array import array
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from waits import BUDGET_S, Deadline, log_has, wait_exit

rclpy = pytest.importorskip("rclpy")

from rclpy._rclpy_pybind11 import NodeNameNonExistentError  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from comems4build_ros.core.config import load_plant_params  # noqa: E402
from comems4build_ros.core.loop import TIMESERIES_COLUMNS  # noqa: E402
from comems4build_ros.ros.interfaces import message_class, qos_profile  # noqa: E402
from comems4build_ros.ros.node import layout_sizes  # noqa: E402
from comems4build_ros.wire.contract import load_contract, relative  # noqa: E402

pytestmark = pytest.mark.ros

STEPS = 48  # 2 days
#: Node name of the observer. It plays the recorder's part (collect() reads every topic): a node
#: started with wait_for_recorder gets it as ``recorder_node`` and publishes its first message only
#: once its writers matched the observer's readers.
OBSERVER = "test_observer"
#: What such a node logs when its writers matched the recorder's readers (ros/node.py).
GATE_OPEN_LINE = "every writer matched the recorder's readers"
IGNORED_SUMMARY_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")
#: Controller step_info columns that hold wall-clock measurements (differ run to run).
TIMING_COLUMNS = ("ems_solve_s",)


# ---------------------------------------------------------------------- harness
class Graph:
    """Node processes of one test plus an observer node in the test process.

    Parameters
    ----------
    tmp : directory for logs (ROS_LOG_DIR and each process's stdout/stderr)
    domain_id : ROS_DOMAIN_ID of this test
    """

    def __init__(self, tmp: Path, domain_id: int) -> None:
        self.tmp = tmp
        self.domain_id = domain_id
        self.env = {
            **os.environ,
            "ROS_DOMAIN_ID": str(domain_id),
            "ROS_LOG_DIR": str(tmp / "ros_log"),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "PYTHONUNBUFFERED": "1",
        }
        self.procs: dict[str, subprocess.Popen] = {}
        self.logs: dict[str, Path] = {}
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id)
        self.node = Node(OBSERVER, context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.contract = load_contract()
        self.params = load_plant_params()
        self.sizes = layout_sizes(self.params)
        self.records: dict[int, array] = {}
        self.infos: dict[int, dict[str, float]] = {}
        self.states: dict[int, float] = {}
        self.done = False
        self.on_state: Callable[[int], None] | None = None  # hook called for each state/t_air_c message
        self.subs: dict[str, Any] = {}
        self._extra: list[Any] = []
        self.may_fail: set[str] = set()  # processes a test kills or expects to fail
        self.gated: set[str] = set()  # processes started with wait_for_recorder, the observer as recorder

    # -- processes
    def start(self, name: str, argv: list[str]) -> subprocess.Popen:
        """Start ``python -m <module> argv`` with the full environment, output to files."""
        log = self.tmp / f"{name}.{len(self.logs)}.log"
        self.logs[name] = log
        fh = open(log, "w")  # noqa: SIM115 - closed when the process is reaped
        proc = subprocess.Popen(
            [sys.executable, *argv], env=self.env, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True
        )
        fh.close()
        self.procs[name] = proc
        return proc

    def _gate(self, name: str, params: dict[str, Any]) -> dict[str, Any]:
        """With wait_for_recorder while the observer collects: the observer is the recorder."""
        if params.get("wait_for_recorder") and self.subs:
            self.gated.add(name)
            return {"recorder_node": OBSERVER, **params}
        return params

    def start_plant(self, **params: Any) -> subprocess.Popen:
        params = self._gate("plant_sim", params)
        return self.start("plant_sim", ["-m", "comems4build_ros.ros.nodes.plant_sim", *_ros_args(params)])

    def start_feed(self, **params: Any) -> subprocess.Popen:
        params = self._gate("feed", {"weeks": 1, "steps": STEPS, **params})
        return self.start("feed", ["-m", "comems4build_ros.ros.nodes.feed", *_ros_args(params)])

    def start_ems(self, ems: str, **params: Any) -> subprocess.Popen:
        params = self._gate("ems", params)
        return self.start("ems", ["-m", "comems4build_ros.ros.nodes.ems_node", "--ems", ems, *_ros_args(params)])

    def log(self, name: str) -> str:
        return self.logs[name].read_text(errors="replace")

    def stop(self, name: str, sig: int = signal.SIGINT) -> int:
        """Signal a process and wait for its exit; SIGKILL after the budget. Returns its exit code."""
        proc = self.procs[name]
        if proc.poll() is None:
            proc.send_signal(sig)
            try:
                proc.wait(BUDGET_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        return proc.returncode

    def close(self) -> None:
        for name in list(self.procs):
            self.stop(name)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    # -- observation
    def collect(self) -> None:
        """Subscribe to plant/record, ems/info, plant/done and state/t_air_c."""
        import json

        from std_msgs.msg import Bool, Float64MultiArray, String

        c = self.contract

        def on_record(msg: Float64MultiArray) -> None:
            self.records.setdefault(int(msg.data[0]), array("d", msg.data))

        def on_info(msg: String) -> None:
            d = json.loads(msg.data)
            self.infos[int(d["step"])] = d["info"]

        def on_done(msg: Bool) -> None:
            self.done = bool(msg.data)

        def on_state(msg: Float64MultiArray) -> None:
            step = int(msg.data[0])
            self.states[step] = msg.data[1]
            if self.on_state is not None:
                self.on_state(step)

        self.subs = {}
        for topic, typ, cb in (
            ("plant/record", Float64MultiArray, on_record),
            ("ems/info", String, on_info),
            ("plant/done", Bool, on_done),
            ("state/t_air_c", Float64MultiArray, on_state),
        ):
            self.subs[topic] = self.node.create_subscription(typ, topic, cb, qos_profile(c.topic(topic)))
        # The rest, as the recorder reads them, until every node started with wait_for_recorder
        # has matched them (:meth:`gates_open`; its first message waits for that); dropped then,
        # once the run has started, so that the observer keeps up with the plant.
        self._extra = [self.node.create_subscription(message_class(spec), spec.name, lambda _raw: None,
                                                     qos_profile(spec), raw=True)
                       for spec in c.topics.values() if spec.name not in self.subs and spec.publishers]
        self._ready_pub = self.node.create_publisher(Bool, "recorder/ready", qos_profile(c.topic("recorder/ready")))

    def leave(self) -> None:
        """The observer, the plant's ``recorder_node``, closes its run as a recorder does: its
        reader of plant/record leaves (the plant waits for that before it exits)."""
        self.node.destroy_subscription(self.subs.pop("plant/record"))
        self.executor.spin_once(timeout_sec=0.1)

    def gates_open(self) -> bool:
        """Whether every node started with wait_for_recorder has said that its writers matched
        the observer's readers (it publishes from then on, and no message of it is lost to us)."""
        return all(log_has(self.logs[name], GATE_OPEN_LINE) for name in self.gated)

    def ready(self, topics: tuple[str, ...] = ("plant/record", "plant/done", "state/t_air_c")) -> None:
        """Wait until the observer is matched with the publishers of ``topics``, then say
        ``recorder/ready`` (the plant runs with ``wait_for_recorder``, as under the launcher).

        Our readers seeing the writers does not mean the writers see our readers (a message
        published before that is not sent to us): the nodes started with wait_for_recorder
        wait for that side themselves before their first message (:meth:`gates_open`)."""
        from std_msgs.msg import Bool

        self.spin_until(lambda: all(self.subs[t].get_publisher_count() > 0 for t in topics), f"publishers of {topics}")
        self._ready_pub.publish(Bool(data=True))

    def spin_until(self, cond: Callable[[], bool], what: str) -> None:
        """Spin the observer until ``cond()``; fail with the logs when the budget (test/waits.py) passes."""
        deadline = Deadline(what)
        while not cond():
            if deadline.passed():
                logs = "\n".join(f"--- {n}\n{self.log(n)[-3000:]}" for n in self.logs)
                got = f"got {len(self.records)} records, {len(self.infos)} step infos, done={self.done}"
                pytest.fail(f"{deadline.fail(got)}\n{logs}")
            for name, proc in self.procs.items():
                if name not in self.may_fail and proc.poll() not in (None, 0):
                    pytest.fail(f"{name} exited with {proc.returncode} while waiting for {what}:\n{self.log(name)}")
            self.executor.spin_once(timeout_sec=0.05)
            if self._extra and self.states and self.gates_open():
                for sub in self._extra:
                    self.node.destroy_subscription(sub)
                self._extra = []

    def timeseries(self) -> pd.DataFrame:
        """The recorded per-step table in sim.py's column order (time from time_unix_s)."""
        layout = self.contract.topic("plant/record").layout(self.sizes)
        steps = sorted(self.records)
        assert steps == list(range(len(steps))), f"steps missing: {steps}"
        rows = [layout.unpack(self.records[k]) for k in steps]
        cols = [c for c in TIMESERIES_COLUMNS if c != "time"]
        ts = pd.DataFrame({c: [r[c] for r in rows] for c in cols})
        tz = self.params.site.timezone
        times = pd.to_datetime([r["time_unix_s"] for r in rows], unit="s", utc=True).tz_convert(tz)
        ts.insert(0, "time", [t.isoformat() for t in times])
        if self.infos and all(k in self.infos for k in steps):
            ts = pd.concat([ts, pd.DataFrame([self.infos[k] for k in steps]).add_prefix("ems_")], axis=1)
        ts.attrs["counters"] = {c: int(rows[-1][c]) for c in ("fallback_steps", "rejected_commands",
                                                              "wrong_step_commands", "foreign_commands")}
        return ts

    def graph_topics(self, node: str, ns: str = "/") -> tuple[set[str], set[str]]:
        """Contract names of a remote node's publishers and subscriptions (graph API)."""
        try:
            pubs = self.node.get_publisher_names_and_types_by_node(node, ns)
            subs = self.node.get_subscriber_names_and_types_by_node(node, ns)
        except NodeNameNonExistentError:  # node discovery is asynchronous: not (yet) known
            return set(), set()

        def names(items: list) -> set[str]:  # contract names: relative to ns, /clock absolute
            return {t if t in self.contract.topics else relative(ns, t) for t, _ in items
                    if t not in ("/parameter_events", "/rosout")}

        return names(pubs), names(subs)


def _ros_args(params: dict[str, Any]) -> list[str]:
    if not params:
        return []
    out = ["--ros-args"]
    for k, v in params.items():
        text = ("true" if v else "false") if isinstance(v, bool) else (f'"{v}"' if isinstance(v, str) else repr(v))
        out += ["-p", f"{k}:={text}"]
    return out


@pytest.fixture()
def graph(tmp_path: Path, domain_id: int) -> Iterator[Graph]:
    g = Graph(tmp_path, domain_id)
    try:
        yield g
    finally:
        g.close()


def in_process(ems: str, steps: int = STEPS):
    """The in-process run of ``ems`` on the first ``steps`` steps of the default scenario."""
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_plant_params()
    scen = dataclasses.replace(resolve_scenario("default", params, weeks=1), n_steps=steps)
    return simulate(ems, scen, params)


def assert_same_run(ros_ts: pd.DataFrame, ref) -> None:
    """Every column and every summary figure equal (bit for bit where numeric)."""
    from comems4build_ros.core.loop import evaluate_timeseries

    ref_ts = ref.timeseries
    assert list(ros_ts.columns) == list(ref_ts.columns)
    assert (ros_ts["time"] == ref_ts["time"]).all()
    for col in ref_ts.columns[1:]:
        if col in TIMING_COLUMNS:
            continue
        a = ros_ts[col].to_numpy(dtype=float)
        b = ref_ts[col].to_numpy(dtype=float)
        assert np.array_equal(a, b, equal_nan=True), f"column {col}: first difference at step " \
            f"{int(np.flatnonzero(~((a == b) | (np.isnan(a) & np.isnan(b))))[0])}"
    ros = evaluate_timeseries(ros_ts, load_plant_params()).summary
    for key, value in ref.summary.items():
        if key in IGNORED_SUMMARY_KEYS or key not in ros:
            continue
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(ros[key]), key
        else:
            assert ros[key] == value, key
    pd.testing.assert_frame_equal(evaluate_timeseries(ros_ts, load_plant_params()).weekly, ref.weekly)


# ---------------------------------------------------------------------- closed loop
#: ComEMS4Build's run is the fast lane's one ROS run (``tools/test.sh --quick``).
EMS_CASES = ["thermostat", "rbc", pytest.param("fuzzy", marks=pytest.mark.quick), "mpc"]


@pytest.mark.parametrize("ems", EMS_CASES)
def test_closed_loop_over_ros_equals_in_process(graph: Graph, ems: str) -> None:
    from comems4build_ros.core.ems import UnknownEMSError, controller_class

    try:
        level = controller_class(ems).info_level
    except UnknownEMSError as exc:
        pytest.skip(str(exc))
    graph.collect()
    # the EMS and the plant kept alive to check their endpoints after the run; both publish
    # what the observer must get from the first step on (ems/info, plant/record)
    graph.start_ems(ems, exit_when_done=False, wait_for_recorder=True)
    graph.start_feed(exit_when_done=False)
    # the plant waits for every command (the budget as its time-outs): a fallback on a slow step of
    # a loaded machine (an MPC solve) would be the machine's, and this compares runs
    graph.start_plant(exit_when_done=False, wait_for_recorder=True, step_timeout_s=BUDGET_S,
                      startup_timeout_s=BUDGET_S)
    graph.ready(("plant/record", "plant/done", "ems/info"))
    ref = in_process(ems)
    n_info = STEPS if any(c.startswith("ems_") for c in ref.timeseries.columns) else 0
    graph.spin_until(
        lambda: graph.done and len(graph.records) == STEPS and len(graph.infos) >= n_info,
        f"{STEPS} records and {n_info} step infos",
    )

    # The real DDS endpoints of every node are exactly what the contract declares. Discovery
    # is asynchronous: wait for the node, then for its endpoints (each within the budget).
    c = graph.contract
    ems_node = c.ems_node_name(ems)
    for node in ("plant_sim", "feed", ems_node):
        # an independent house: no link to a community's coordinator (scope community_house)
        want_pub = {t.name for t in c.published_by(node) if t.scope == "house"}
        # /clock: the contract lets ROS 2's time source read it; it does with use_sim_time only
        want_sub = {t.name for t in c.subscribed_by(node) if t.scope == "house"} - {"/clock"}
        graph.spin_until(lambda n=node: (n, "/") in graph.node.get_node_names_and_namespaces(), f"node {node} "
                         "in the observer's graph")
        deadline = Deadline(f"every endpoint of {node} in the observer's graph")
        while graph.graph_topics(node) != (want_pub, want_sub) and not deadline.passed():
            graph.executor.spin_once(timeout_sec=0.05)
        got_pub, got_sub = graph.graph_topics(node)
        assert got_pub == want_pub, f"{node} publishes {got_pub ^ want_pub} against the contract"
        assert got_sub == want_sub, f"{node} subscribes {got_sub ^ want_sub} against the contract"
    if level == "basic":
        assert not any(t.startswith(("forecast/", "feed/solar", "feed/t_amb")) for t in want_sub)

    ts = graph.timeseries()
    assert ts.attrs["counters"] == {"fallback_steps": 0, "rejected_commands": 0, "wrong_step_commands": 0,
                                    "foreign_commands": 0}
    assert_same_run(ts, ref)
    for name, sig in (("ems", signal.SIGINT), ("feed", signal.SIGTERM), ("plant_sim", signal.SIGINT)):
        assert graph.stop(name, sig) == 0, graph.log(name)  # clean shutdown on Ctrl-C and on SIGTERM
        assert "Traceback" not in graph.log(name), graph.log(name)


# ---------------------------------------------------------------------- faults
def _fallback_rule(t_air_c: float, v_dhw_l: float, t_min_c: float, params) -> tuple[int, float]:
    """(hp_mode, hp_mod) of the safe fallback, written out by hand from ems/fallback.py's
    documented rule: DHW at full power if the tank is within 25 % of its usable range above
    V_min, else SH at full power if the room is within 0.5 K of T_min, else off."""
    d = params.dhw
    if v_dhw_l <= d.v_min_l + 0.25 * (d.v_max_l - d.v_min_l):
        return 2, 1.0
    if t_air_c <= t_min_c + 0.5:
        return 1, 1.0
    return 0, 0.0


def test_ems_killed_mid_run_plant_falls_back_and_resumes_after_restart(graph: Graph) -> None:
    from std_msgs.msg import UInt32

    killed_at: list[int] = []
    graph.collect()
    # The observer stands in for the recorder's back-pressure: with recorder/progress at 0 and
    # a window of 12 steps the plant announces no step beyond 12 until the EMS is dead (a
    # fast EMS would otherwise answer all 48 steps before the kill lands).
    progress = graph.node.create_publisher(UInt32, "recorder/progress",
                                           qos_profile(graph.contract.topic("recorder/progress")))

    def kill_on_step(step: int) -> None:  # SIGKILL the EMS the moment the plant announces step 12
        if step == 12 and not killed_at:
            killed_at.append(step)
            graph.may_fail.add("ems")
            os.kill(graph.procs["ems"].pid, signal.SIGKILL)
            wait_exit(graph.procs["ems"], "the EMS to die of SIGKILL")
            progress.publish(UInt32(data=STEPS))  # the plant may go on

    graph.on_state = kill_on_step
    graph.start_ems("thermostat", exit_when_done=False)
    graph.start_feed(exit_when_done=False)
    # the step time-out is what the test is about: 5 s, far longer than an EMS on a loaded machine
    # takes to answer (a fallback before the kill would be the machine's, not the EMS's death)
    graph.start_plant(exit_when_done=False, wait_for_recorder=True, step_timeout_s=5.0, republish_period_s=0.2,
                      record_window_steps=12)
    graph.ready()

    def n_fallback() -> int:
        lay = graph.contract.topic("plant/record").layout(graph.sizes)
        return sum(1 for r in graph.records.values() if r[lay.index["fallback"]] > 0.5)

    graph.spin_until(lambda: n_fallback() >= 2, "2 fallback steps after the EMS was killed")
    assert graph.procs["ems"].returncode == -signal.SIGKILL
    graph.start_ems("thermostat")  # restart: the plant must hand control back to it
    graph.may_fail.discard("ems")
    graph.spin_until(lambda: graph.done and len(graph.records) == STEPS, "the end of the run")

    ts = graph.timeseries()
    fb = ts["fallback"].to_numpy(dtype=bool)
    first, last = int(np.argmax(fb)), int(len(fb) - 1 - np.argmax(fb[::-1]))
    assert first >= 12, "no fallback before the EMS died"
    assert fb[first : last + 1].all(), "fallback steps are contiguous while the EMS is down"
    assert last < STEPS - 1 and not fb[last + 1 :].any(), "the restarted EMS took over again"
    assert ts.attrs["counters"]["fallback_steps"] == int(fb.sum()) >= 2
    p = graph.params
    for k in np.flatnonzero(fb):  # the fallback is the documented safe action for the state at the start of k
        mode, mod = _fallback_rule(ts["t_air_c"][k - 1], ts["v_dhw_l"][k - 1], ts["t_min_c"][k], p)
        assert (ts["cmd_hp_mode"][k], ts["cmd_hp_mod"][k], ts["cmd_p_fc_w"][k], ts["cmd_p_bess_w"][k]) == (
            mode, mod, 0.0, 0.0), f"step {k}"
        # comfort: a room that started the step inside the band stays within 0.3 K of it
        if ts["t_air_c"][k - 1] >= ts["t_min_c"][k]:
            assert ts["t_air_c"][k] >= ts["t_min_c"][k] - 0.3, f"step {k}"
    # storage bounds hold throughout
    assert ts["soc"].between(p.battery.soc_min - 1e-9, p.battery.soc_max + 1e-9).all()
    assert ts["loh"].between(p.hydrogen.loh_min - 1e-9, p.hydrogen.loh_max + 1e-9).all()
    assert ts["v_dhw_l"].between(p.dhw.v_min_l - 1e-9, p.dhw.v_max_l + 1e-9).all()
    assert graph.stop("plant_sim") == 0
    plant_log = graph.log("plant_sim")
    assert plant_log.count(" fallback no valid command on 'ems/command'") == int(fb.sum())
    assert f"fallback_steps={int(fb.sum())}" in plant_log


def test_invalid_and_wrong_step_commands_are_rejected_counted_and_logged(graph: Graph) -> None:
    from std_msgs.msg import Float64MultiArray

    graph.collect()
    cmd_pub = graph.node.create_publisher(
        Float64MultiArray, "ems/command", qos_profile(graph.contract.topic("ems/command"))
    )
    graph.start_feed(steps=3)
    # step 0 falls back after the start-up time-out (every command of it is invalid); the
    # valid answers to steps 1 and 2 must never be late, however slow this process is
    graph.start_plant(wait_for_recorder=True, step_timeout_s=BUDGET_S, startup_timeout_s=2.0)
    graph.ready()
    graph.spin_until(lambda: cmd_pub.get_subscription_count() > 0 and 0 in graph.states, "step 0")

    def send(*values: float, token: float = 5.0) -> None:
        cmd_pub.publish(Float64MultiArray(data=[*values, token]))

    nan, inf = float("nan"), float("inf")
    send(0.0, 1.0, 1.0, 0.0, 0.0)  # wrong length
    send(0.0, nan, 1.0, 0.0, 0.0, 0.0)  # NaN
    send(0.0, 1.0, 1.0, inf, 0.0, 0.0)  # inf
    send(0.0, 1.0, 1.0, 0.0, 5.0e5, 0.0)  # battery power far beyond its 1 kW
    send(0.0, 1.0, 7.0, 0.0, 0.0, 0.0)  # unknown circuit
    send(5.0, 1.0, 1.0, 0.0, 0.0, 0.0)  # valid, but for step 5 while the plant waits for step 0
    graph.spin_until(lambda: 0 in graph.records, "step 0 (after the timeout)")
    lay = graph.contract.topic("plant/record").layout(graph.sizes)
    r0 = lay.unpack(graph.records[0])
    assert r0["fallback"] is True, "invalid commands count as missing: the plant fell back"
    assert (r0["rejected_commands"], r0["wrong_step_commands"]) == (5, 1)

    graph.spin_until(lambda: 1 in graph.states, "step 1")
    send(1.0, 0.0, 2.0, 0.0, 0.0, 0.0, token=99.0)  # in range, right step, but another EMS's token: foreign
    send(1.0, 1.0, 1.0, 0.0, 0.0, 0.0)  # valid: space heating at full power
    graph.spin_until(lambda: 2 in graph.states, "step 2")
    send(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    graph.spin_until(lambda: len(graph.records) == 3, "the end of the run")
    r1, r2 = lay.unpack(graph.records[1]), lay.unpack(graph.records[2])
    assert r1["fallback"] is False and (r1["cmd_hp_mode"], r1["cmd_hp_mod"]) == (1, 1.0)
    assert r1["hp_mode"] == 1 and r1["q_hp_sh_w"] > 0
    assert r2["fallback"] is False and r2["cmd_hp_mode"] == 0
    assert r2["foreign_commands"] == 1 and r2["rejected_commands"] == 5
    graph.leave()  # the recorder's stand-in leaves: the plant, waiting for that, ends
    assert wait_exit(graph.procs["plant_sim"], "the plant's exit after the observer left") == 0
    log = graph.log("plant_sim")
    for expected in (
        "rejected topic 'ems/command' field '(length)': 6 elements",
        "rejected topic 'ems/command' field 'hp_mod': non-finite value nan",
        "rejected topic 'ems/command' field 'p_fc_w': non-finite value inf",
        "rejected topic 'ems/command' field 'p_bess_w': 500000.0 outside the accepted range",
        "rejected topic 'ems/command' field 'hp_mode': 7.0 is not one of",
        "wrong_step topic 'ems/command': command for step 5 ignored",
        "rejected_commands=5 wrong_step_commands=1",
        "foreign topic 'ems/command': command for step 1 with token 99 ignored (the run's EMS has token 5)",
        "foreign_commands=1",
    ):
        assert expected in log, expected


@pytest.fixture(scope="module")
def scenario_csv(tmp_path_factory) -> Path:
    """One week (plus look-ahead) of the default scenario written as a scenario CSV."""
    from comems4build_ros.core.scenario import resolve_scenario, write_scenario_csv

    path = tmp_path_factory.mktemp("scen") / "week.csv"
    write_scenario_csv(resolve_scenario("default", load_plant_params(), weeks=1), path)
    return path


def test_feed_refuses_a_scenario_with_nan_or_gap(graph: Graph, scenario_csv: Path) -> None:
    lines = scenario_csv.read_text().splitlines(keepends=True)
    header = lines[0].strip().split(",")
    col = header.index("t_amb_c")
    nan_row = lines[11].split(",")
    nan_row[col] = "NaN"
    with_nan = graph.tmp / "with_nan.csv"
    with_nan.write_text("".join([*lines[:11], ",".join(nan_row), *lines[12:]]))  # line 12 of the file
    with_gap = graph.tmp / "with_gap.csv"
    with_gap.write_text("".join([*lines[:30], *lines[31:]]))  # the hour of line 31 is missing

    graph.may_fail.update({"feed_nan", "feed_gap"})
    graph.start("feed_nan", ["-m", "comems4build_ros.ros.nodes.feed", *_ros_args({"scenario": str(with_nan)})])
    graph.start("feed_gap", ["-m", "comems4build_ros.ros.nodes.feed", *_ros_args({"scenario": str(with_gap)})])
    assert wait_exit(graph.procs["feed_nan"], "the feed refusing the NaN") == 2
    assert wait_exit(graph.procs["feed_gap"], "the feed refusing the gap") == 2
    nan_log, gap_log = graph.log("feed_nan"), graph.log("feed_gap")
    assert "[feed]: refused to start:" in nan_log and "with_nan.csv" in nan_log and "line 12" in nan_log
    assert "column 't_amb_c'" in nan_log and "refuses a scenario with missing values" in nan_log
    assert "[feed]: refused to start:" in gap_log and "with_gap.csv" in gap_log and "gap" in gap_log
    assert "Traceback" not in nan_log + gap_log


def test_feed_check_refuses_non_finite_series_and_irregular_steps() -> None:
    """The feed's own check on a Scenario object (whatever loader produced it)."""
    from comems4build_ros.core.scenario import resolve_scenario
    from comems4build_ros.core.scenario.run import ScenarioInputError, check_scenario

    scen = resolve_scenario("default", load_plant_params(), weeks=1)
    bad = dataclasses.replace(scen, p_load_w=scen.p_load_w.copy())
    bad.p_load_w[7] = np.nan
    with pytest.raises(ScenarioInputError, match=r"series 'p_load_w' has 1 non-finite value\(s\), first at "
                       r"2022-12-01T07:00:00\+01:00 \(row 7\)"):
        check_scenario(bad, 1.0)
    keep = np.r_[0:20, 21 : len(scen.time)]
    gap = dataclasses.replace(
        scen, time=scen.time[keep], **{k: getattr(scen, k)[keep] for k in _series_names()}
    )
    with pytest.raises(ScenarioInputError, match=r"time step 7200 s instead of 3600 s between 2022-12-01T19:00"):
        check_scenario(gap, 1.0)
    check_scenario(scen, 1.0)  # the default scenario passes


def _series_names() -> tuple[str, ...]:
    from comems4build_ros.core.scenario.base import SERIES

    return SERIES


def test_nodes_started_by_hand_exit_at_the_end_and_the_bag_knows_ems_and_scenario(graph: Graph) -> None:
    """Recorder, EMS, feed and plant with their default parameters all exit 0 by themselves after the
    run (end-of-run signal plant/done), and the bag, recorded without the launcher's run_info, names
    the EMS and the scenario."""
    from comems4build_ros.bags.evaluation import evaluate_bag

    bag = graph.tmp / "bag"
    graph.start("recorder", ["-m", "comems4build_ros.ros.nodes.recorder", *_ros_args({"bag_path": str(bag)})])
    graph.start_ems("rbc")
    graph.start_feed(steps=24)
    graph.start_plant(wait_for_recorder=True)
    for name in ("plant_sim", "recorder", "feed", "ems"):
        assert wait_exit(graph.procs[name], f"{name} to exit by itself after the run") == 0, graph.log(name)
    assert "run done: exiting once the recorder has left" in graph.log("feed")
    summary = evaluate_bag(bag, graph.tmp / "eval")["/"]
    assert summary["ems"] == "rbc" and summary["scenario"] == in_process_scenario_name()
    assert summary["steps"] == 24 and summary["lost_messages"] == {}


def in_process_scenario_name() -> str:
    """Name of the default scenario as the in-process summary reports it."""
    from comems4build_ros.core.scenario.run import load_scenario

    return load_scenario("default", load_plant_params(), None, 1, None, 24).name
