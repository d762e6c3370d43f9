"""Operating the nodes with the real ROS 2 tools (test/ros2_tools.py): a plant whose recorder
leaves mid-run says so; ``replay`` paces itself so that a default ``ros2 topic echo`` gets
every message. Every wait is for a condition, with a generous deadline."""

from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from ros2_tools import run_ros2, start_ros2, stop, wait_for

pytestmark = pytest.mark.ros

#: Wall-time budget of one condition on a loaded 2-core machine [s].
BUDGET_S = 120.0


def _bag_bytes(bag: Path) -> int:
    return sum(f.stat().st_size for f in bag.glob("*.mcap"))


def test_a_plant_whose_recorder_leaves_mid_run_warns(ros2, domain_id, tmp_path) -> None:
    """plant_sim started by hand with wait_for_recorder; its recorder stopped (SIGINT) while the
    run goes on: a ``recorder_left`` warning on plant/events and in the plant's log, naming the
    recorder and the step; the rest of the house runs on."""
    bag = tmp_path / "bag"
    logs = tmp_path / "out"
    logs.mkdir()
    run = {"recorder": ["-p", f"bag_path:={bag}"], "plant_sim": ["-p", "wait_for_recorder:=true"],
           "feed": ["-p", "wait_for_recorder:=true", "-p", "weeks:=12"], "rbc_ems": ["-p", "wait_for_recorder:=true"]}
    procs = {name: start_ros2(ros2, ["run", "comems4build_ros", name, "--ros-args", *args], domain_id, tmp_path,
                              logs / f"{name}.log") for name, args in run.items()}
    plant_log = logs / "plant_sim.log"
    try:
        def recording() -> bool:
            assert all(p.poll() is None for p in procs.values()), {n: (logs / f"{n}.log").read_text()[-2000:]
                                                                   for n in procs}
            return _bag_bytes(bag) > 50_000

        wait_for(recording, BUDGET_S, "the run under way, recorded", period=0.1)
        os.killpg(procs["recorder"].pid, signal.SIGINT)
        assert procs["recorder"].wait(timeout=60) == 3  # stopped before the end of its run
        wait_for(lambda: "recorder_left" in plant_log.read_text(), 30, "the plant's recorder_left warning")
        assert procs["plant_sim"].poll() is None
    finally:
        stop(list(procs.values()))
    line = next(ln for ln in plant_log.read_text().splitlines() if "recorder_left" in ln)
    assert "[WARN]" in line and "the recorder 'recorder' left the run before its end (step" in line, line


def test_replay_paces_itself_for_a_default_ros2_topic_echo(ros2, domain_id, tmp_path) -> None:
    """A bag of 48 state/soc messages recorded within 50 ms, replayed as fast as replay goes into a
    ``ros2 topic echo`` with its default QoS (keep-last depth 5): every message arrives."""
    from comems4build_ros.bags.bag import BagWriter, typestore

    n = 48
    store = typestore()
    msgtype = "std_msgs/msg/Float64MultiArray"
    layout = store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        w.add_topic("/state/soc", msgtype)
        for k in range(n):
            msg = store.types[msgtype](layout=layout, data=np.array([float(k), 0.5]))
            w.write("/state/soc", 1_700_000_000 * 10**9 + k * 1_000_000, bytes(store.serialize_cdr(msg, msgtype)))
    echo_log = tmp_path / "echo.log"
    echo = start_ros2(ros2, ["topic", "echo", "/state/soc", msgtype, "--field", "data"], domain_id, tmp_path,
                      echo_log)
    try:
        def echo_listens() -> bool:
            res = run_ros2(ros2, ["topic", "info", "/state/soc", "--no-daemon"], domain_id, tmp_path, timeout=60)
            return "Subscription count: 1" in res.stdout

        wait_for(echo_listens, BUDGET_S, "ros2 topic echo subscribed", period=1.0)
        res = run_ros2(ros2, ["run", "comems4build_ros", "replay", str(bag), "--rate", "0", "--ros-args", "-p",
                              f"wait_for_subscribers_s:={BUDGET_S}"], domain_id, tmp_path, timeout=BUDGET_S + 60)
        assert res.returncode == 0, res.stderr[-3000:]
        assert "at most one message per topic every 0.02 s" in res.stderr, res.stderr[-3000:]

        def all_echoed() -> bool:
            return echo_log.read_text().count("---") >= n

        wait_for(all_echoed, 30, f"ros2 topic echo printed {n} messages")
    finally:
        stop([echo])
    steps = [float(v) for v in re.findall(r"array\('d', \[([-0-9.e]+),", echo_log.read_text())]
    assert steps == [float(k) for k in range(n)], echo_log.read_text()[-2000:]  # every one, in order
