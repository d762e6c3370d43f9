"""The node set over real DDS: separate processes for plant_sim, feed and the EMS.

* Closed loop over ROS gives exactly the timeseries and KPIs of the in-process loop
  (``comems4build_ros.sim.simulate``) for thermostat, RBC, fuzzy and MPC over 2 days.
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
import time
from array import array
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402

from comems4build_ros.config import load_plant_params  # noqa: E402
from comems4build_ros.ros.common import layout_sizes  # noqa: E402
from comems4build_ros.ros.contract import load_contract, relative  # noqa: E402
from comems4build_ros.sim import TIMESERIES_COLUMNS  # noqa: E402

pytestmark = pytest.mark.ros

STEPS = 48  # 2 days
#: Wall-clock limit of one closed-loop run including process start-up [s].
RUN_TIMEOUT_S = 150.0
IGNORED_SUMMARY_KEYS = ("wall_s", "ems_s")
#: Controller step_info columns that hold wall-clock measurements (differ run to run).
TIMING_COLUMNS = ("ems_solve_s",)


# ---------------------------------------------------------------------- harness
@pytest.fixture()
def domain_id() -> Iterator[int]:
    """A ROS domain id nobody else uses during the test (same lock files as the launcher)."""
    from comems4build_ros.ros.launcher import acquire_domain_id

    with acquire_domain_id() as did:
        yield did


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
        self.node = Node("test_observer", context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.contract = load_contract()
        self.params = load_plant_params()
        self.sizes = layout_sizes(self.params)
        self.records: dict[int, array] = {}
        self.infos: dict[int, dict[str, float]] = {}
        self.states: dict[int, float] = {}
        self.done = False

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

    def start_plant(self, **params: Any) -> subprocess.Popen:
        return self.start("plant_sim", ["-m", "comems4build_ros.ros.nodes.plant_sim", *_ros_args(params)])

    def start_feed(self, **params: Any) -> subprocess.Popen:
        params = {"weeks": 1, "steps": STEPS, **params}
        return self.start("feed", ["-m", "comems4build_ros.ros.nodes.feed", *_ros_args(params)])

    def start_ems(self, ems: str, **params: Any) -> subprocess.Popen:
        return self.start("ems", ["-m", "comems4build_ros.ros.nodes.ems_node", "--ems", ems, *_ros_args(params)])

    def log(self, name: str) -> str:
        return self.logs[name].read_text(errors="replace")

    def stop(self, name: str, sig: int = signal.SIGINT, timeout: float = 15.0) -> int:
        """Signal a process and wait; SIGKILL after ``timeout``. Returns its exit code."""
        proc = self.procs[name]
        if proc.poll() is None:
            proc.send_signal(sig)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
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
            self.states[int(msg.data[0])] = msg.data[1]

        self.subs = {}
        for topic, typ, cb in (
            ("plant/record", Float64MultiArray, on_record),
            ("ems/info", String, on_info),
            ("plant/done", Bool, on_done),
            ("state/t_air_c", Float64MultiArray, on_state),
        ):
            self.subs[topic] = self.node.create_subscription(typ, topic, cb, c.topic(topic).qos_profile())
        self._ready_pub = self.node.create_publisher(Bool, "recorder/ready", c.topic("recorder/ready").qos_profile())

    def ready(self, topics: tuple[str, ...] = ("plant/record", "plant/done", "state/t_air_c"), timeout: float = 60.0):
        """Wait until the observer is matched with the publishers of ``topics``, then say
        ``recorder/ready`` (the plant runs with ``wait_for_recorder``, as under the launcher)."""
        from std_msgs.msg import Bool

        self.spin_until(
            lambda: all(self.subs[t].get_publisher_count() > 0 for t in topics), timeout, f"publishers of {topics}"
        )
        self._ready_pub.publish(Bool(data=True))

    def spin_until(self, cond: Callable[[], bool], timeout: float, what: str) -> None:
        """Spin the observer until ``cond()`` or fail after ``timeout`` with the logs."""
        t_end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > t_end:
                logs = "\n".join(f"--- {n}\n{self.log(n)[-3000:]}" for n in self.logs)
                pytest.fail(f"timeout waiting for {what}\n{logs}")
            for name, proc in self.procs.items():
                if proc.poll() not in (None, 0):
                    pytest.fail(f"{name} exited with {proc.returncode} while waiting for {what}:\n{self.log(name)}")
            self.executor.spin_once(timeout_sec=0.05)

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
                                                              "wrong_step_commands")}
        return ts

    def graph_topics(self, node: str, ns: str = "/") -> tuple[set[str], set[str]]:
        """Contract names of a remote node's publishers and subscriptions (graph API)."""
        pubs = self.node.get_publisher_names_and_types_by_node(node, ns)
        subs = self.node.get_subscriber_names_and_types_by_node(node, ns)

        def names(items: list) -> set[str]:
            return {relative(ns, t) for t, _ in items if t not in ("/parameter_events", "/rosout")}

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
    from comems4build_ros.scenario import resolve_scenario
    from comems4build_ros.sim import simulate

    params = load_plant_params()
    scen = dataclasses.replace(resolve_scenario("default", params, weeks=1), n_steps=steps)
    return simulate(ems, scen, params)


def assert_same_run(ros_ts: pd.DataFrame, ref) -> None:
    """Every column and every summary figure equal (bit for bit where numeric)."""
    from comems4build_ros.sim import evaluate_timeseries

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
EMS_CASES = ["thermostat", "rbc", "fuzzy", "mpc"]


@pytest.mark.parametrize("ems", EMS_CASES)
def test_closed_loop_over_ros_equals_in_process(graph: Graph, ems: str) -> None:
    from comems4build_ros.ems import UnknownEMSError, controller_class

    try:
        level = controller_class(ems).info_level
    except UnknownEMSError as exc:
        pytest.skip(str(exc))
    graph.collect()
    graph.start_ems(ems)
    graph.start_feed()
    graph.start_plant(exit_when_done=False, wait_for_recorder=True)
    graph.ready(("plant/record", "plant/done", "ems/info"))
    ref = in_process(ems)
    n_info = STEPS if any(c.startswith("ems_") for c in ref.timeseries.columns) else 0
    graph.spin_until(
        lambda: graph.done and len(graph.records) == STEPS and len(graph.infos) >= n_info,
        RUN_TIMEOUT_S,
        f"{STEPS} records and {n_info} step infos",
    )

    # The real DDS endpoints of every node are exactly what the contract declares.
    c = graph.contract
    ems_node = c.ems_node_name(ems)
    for node in ("plant_sim", "feed", ems_node):
        want_pub = {t.name for t in c.published_by(node)}
        want_sub = {t.name for t in c.subscribed_by(node)}
        got_pub, got_sub = graph.graph_topics(node)
        assert got_pub == want_pub, f"{node} publishes {got_pub ^ want_pub} against the contract"
        assert got_sub == want_sub, f"{node} subscribes {got_sub ^ want_sub} against the contract"
    if level == "basic":
        assert not any(t.startswith(("forecast/", "feed/solar", "feed/t_amb")) for t in want_sub)

    ts = graph.timeseries()
    assert ts.attrs["counters"] == {"fallback_steps": 0, "rejected_commands": 0, "wrong_step_commands": 0}
    assert_same_run(ts, ref)
    for name in ("ems", "feed", "plant_sim"):
        assert graph.stop(name) == 0, graph.log(name)
        assert "Traceback" not in graph.log(name), graph.log(name)
