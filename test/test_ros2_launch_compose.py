"""The launch file inside a user's own launch, with the real ``ros2 launch`` (test/ros2_tools.py).

A user's launch file includes ``comems4build.launch.py`` twice, each inclusion in a
``GroupAction`` with ``PushRosNamespace``, beside a node of its own: each inclusion is a run of
its own (its namespace, tokens and bag), ends its own processes only, and the launch's exit
code says whether every run completed. Stop signals to ``ros2 launch`` end every process of a
run and remove its token files. Every wait is for a condition, with a generous deadline.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ros2_tools import evaluate, reference, ros2_env, same_kpis, wait_for

from comems4build_ros.app.ros2_launch import DEFAULT_OUT, placed

#: The user's launch file: ours twice under pushed namespaces, and a node of the user's own.
USER_LAUNCH = '''
import os
import sys

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import ExecuteProcess, GroupAction, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch_ros.actions import PushRosNamespace

BYSTANDER = """
import rclpy
rclpy.init()
node = rclpy.create_node("bystander")
node.create_timer(0.5, lambda: None)
print("bystander up", flush=True)
rclpy.spin(node)
"""


def generate_launch_description():
    ours = os.path.join(get_package_share_directory("comems4build_ros"), "launch", "comems4build.launch.py")

    def house(ns, args):
        return GroupAction([PushRosNamespace(ns), IncludeLaunchDescription(
            PythonLaunchDescriptionSource(ours), launch_arguments=args.items())])

    return LaunchDescription([
        house("house_a", {HOUSE_A}),
        house("house_b", {HOUSE_B}),
        *([ExecuteProcess(cmd=[sys.executable, "-c", BYSTANDER], name="bystander", output="screen")]
          if {BYSTANDER_ON} else []),
    ])
'''
#: Wall-time budget of one launch in these tests [s] (generous: a loaded 2-core machine).
LAUNCH_BUDGET_S = 150.0
#: A stop signal must end every process of the run within this [s] (the requirement).
STOP_WITHIN_S = 3.0


def _user_launch(tmp_path: Path, house_a: dict[str, str], house_b: dict[str, str], bystander: bool) -> Path:
    path = tmp_path / "user.launch.py"
    path.write_text(USER_LAUNCH.replace("{HOUSE_A}", repr(house_a)).replace("{HOUSE_B}", repr(house_b))
                    .replace("{BYSTANDER_ON}", repr(bystander)), encoding="utf-8")
    return path


def _start(ros2: dict, args: list[str], domain: int, tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    """``ros2 <args>`` in its own session (a signal reaches it alone), output into a file."""
    log = tmp_path / "launch.out"
    with open(log, "wb") as out:
        proc = subprocess.Popen([*ros2["argv"], *args], env=ros2_env(ros2, domain, tmp_path), cwd=tmp_path,
                                stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    return proc, log


def _ours(tmp_path: Path) -> list[int]:
    """Processes of this test's launch (its ``ROS_LOG_DIR``), ``ros2 launch`` itself aside."""
    from comems4build_ros.run.supervisor import processes_with_env

    return [pid for pid in processes_with_env("ROS_LOG_DIR", str(tmp_path / "ros_log")) if not _is_launch(pid)]


def _is_launch(pid: int) -> bool:
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return False
    return any(Path(a.decode(errors="replace")).name == "ros2" for a in argv[:2]) and b"launch" in argv


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0] != "Z"
    except OSError:
        return False


def _clean_up(proc: subprocess.Popen, tmp_path: Path) -> None:
    """Whatever a failed test left: the launch's process group, then any process of its log dir."""
    from comems4build_ros.run.supervisor import processes_with_env

    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    for pid in processes_with_env("ROS_LOG_DIR", str(tmp_path / "ros_log")):
        os.kill(pid, signal.SIGKILL)


def _plant_of(tmp_path: Path, namespace: str) -> list[int]:
    """The plant_sim process of ``namespace`` (launch_ros gives it ``-r __ns:=<namespace>``)."""
    out = []
    for pid in _ours(tmp_path):
        try:
            argv = [a.decode() for a in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")]
        except OSError:
            continue
        if any(Path(a).name == "plant_sim" for a in argv[:3]) and f"__ns:={namespace}" in argv:
            out.append(pid)
    return out


@pytest.mark.ros
def test_two_inclusions_under_pushed_namespaces_beside_a_node_of_the_user(ros2, domain_id, tmp_path) -> None:
    """Both runs complete in their own namespaces with their own bags, each bag evaluates to its own
    in-process run bit for bit, and the user's node still runs when they have ended; the launch,
    stopped then, exits 0 and leaves no process and no token file. Each node's log file is named
    after the node and its namespace."""
    steps = 12
    launch_file = _user_launch(tmp_path, {"ems": "rbc", "weeks": "1", "steps": str(steps)},
                               {"ems": "fuzzy", "weeks": "1", "steps": str(steps), "seed": "7"}, bystander=True)
    proc, log = _start(ros2, ["launch", str(launch_file)], domain_id, tmp_path)
    try:
        def both_complete() -> bool:
            assert proc.poll() is None, log.read_text()[-4000:]
            text = log.read_text()
            return all(f"run in /house_{x} (bag comems4build_run/house_{x}/bag): complete" in text for x in "ab")

        wait_for(both_complete, LAUNCH_BUDGET_S, "both runs complete")
        users = [p for p in _ours(tmp_path) if b"bystander" in Path(f"/proc/{p}/cmdline").read_bytes()]
        wait_for(lambda: not [p for p in _ours(tmp_path) if p not in users], 30, "the runs' processes ended")
        assert proc.poll() is None and users and all(_alive(p) for p in users), "the user's node ended with the runs"
        text = log.read_text()
        assert "bystander up" in text and " foreign topic " not in text, text[-4000:]  # no cross-talk
        os.kill(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=60) == 0, log.read_text()[-4000:]
        wait_for(lambda: not _ours(tmp_path), 10, "no process of the launch left")
    finally:
        _clean_up(proc, tmp_path)
    logs = {p.name.rsplit("_", 2)[0] for p in (tmp_path / "ros_log").rglob("*.log")}  # <name>_<pid>_<time>.log
    assert {"house_a_plant_sim", "house_b_fuzzy_ems", "house_b_recorder"} <= logs, sorted(logs)
    from comems4build_ros.core.scenario.settings import load_scenario_settings

    for ns, ems, seed in (("house_a", "rbc", load_scenario_settings().seed), ("house_b", "fuzzy", 7)):
        out = tmp_path / "comems4build_run" / ns
        assert not (out / ".secrets").exists()
        summary = evaluate(out / "bag", tmp_path / "eval" / ns)
        got = summary["houses"][ns]
        assert got["ems"] == ems and got["lost_messages"] == {} and got["steps"] == steps
        same_kpis(got, reference(ems, steps, seed))


@pytest.mark.ros
def test_a_killed_node_in_one_inclusion_fails_the_launch_and_not_the_other_run(ros2, domain_id, tmp_path) -> None:
    """house_b's plant_sim SIGKILLed mid-run: house_b's run is cut (its processes end, its bag is
    marked), house_a's runs to its end and evaluates to its in-process run, and ``ros2 launch``
    exits non-zero, naming the cut run."""
    steps = 48
    launch_file = _user_launch(tmp_path, {"ems": "rbc", "weeks": "1", "steps": str(steps)},
                               {"ems": "fuzzy", "weeks": "12"}, bystander=False)
    proc, log = _start(ros2, ["launch", str(launch_file)], domain_id, tmp_path)
    try:
        bag_b = tmp_path / "comems4build_run" / "house_b" / "bag"

        def b_under_way() -> bool:
            assert proc.poll() is None, log.read_text()[-4000:]
            return sum(f.stat().st_size for f in bag_b.glob("*.mcap")) > 50_000

        wait_for(b_under_way, LAUNCH_BUDGET_S, "house_b's run under way", period=0.1)
        plant = _plant_of(tmp_path, "/house_b")
        assert len(plant) == 1, plant
        os.kill(plant[0], signal.SIGKILL)
        code = proc.wait(timeout=LAUNCH_BUDGET_S)
    finally:
        _clean_up(proc, tmp_path)
    text = log.read_text()
    assert code != 0, text[-4000:]
    assert "run in /house_b (bag comems4build_run/house_b/bag): run cut short: process 'house_b/plant_sim'" in text, \
        text[-4000:]
    assert "run in /house_a (bag comems4build_run/house_a/bag): complete" in text, text[-4000:]
    assert (bag_b / "run_cut.json").is_file()
    summary = evaluate(tmp_path / "comems4build_run" / "house_a" / "bag", tmp_path / "eval")
    got = summary["houses"]["house_a"]
    assert got["lost_messages"] == {} and got["steps"] == steps and "bag_incomplete" not in got
    same_kpis(got, reference("rbc", steps))
    assert not list((tmp_path / "comems4build_run").glob("*/.secrets"))


@pytest.mark.ros
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_to_ros2_launch_ends_every_process_of_the_run(ros2, domain_id, tmp_path, sig) -> None:
    """SIGINT or SIGTERM to ``ros2 launch`` alone (not its process group) mid-run: every process
    of the run ends within 3 s, the token files are removed, the bag is closed, and the launch
    exits non-zero (the run was cut)."""
    out = tmp_path / "run"
    proc, log = _start(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", "ems:=fuzzy", "weeks:=12",
                              f"out:={out}"], domain_id, tmp_path)
    try:
        def under_way() -> bool:
            assert proc.poll() is None, log.read_text()[-4000:]
            return sum(f.stat().st_size for f in (out / "bag").glob("*.mcap")) > 50_000

        wait_for(under_way, LAUNCH_BUDGET_S, "the run under way", period=0.1)
        nodes = _ours(tmp_path)
        assert len(nodes) == 4 and (out / ".secrets").is_dir(), nodes
        t0 = time.monotonic()
        os.kill(proc.pid, sig)
        while any(_alive(p) for p in nodes) and time.monotonic() - t0 < 30:
            time.sleep(0.02)
        took = time.monotonic() - t0
        code = proc.wait(timeout=30)
    finally:
        _clean_up(proc, tmp_path)
    print(f"{signal.Signals(sig).name}: every process of the run ended {took:.2f} s after the signal", file=sys.stderr)
    assert took < STOP_WITHIN_S, log.read_text()[-4000:]
    assert code != 0
    assert not (out / ".secrets").exists()
    assert (out / "bag" / "metadata.yaml").is_file()


SEGMENT = st.from_regex(r"[a-z][a-z0-9_]{0,6}", fullmatch=True)
NAMESPACE = st.lists(SEGMENT, min_size=0, max_size=3).map(lambda parts: "/".join(parts))


@settings(deadline=None)
@given(pushed=st.none() | NAMESPACE.map(lambda ns: "/" + ns), given_ns=NAMESPACE, absolute=st.booleans(),
       out=st.sampled_from(["", "mine", "/tmp/o"]))
def test_the_run_lies_in_the_namespace_an_including_file_pushed(pushed, given_ns, absolute, out) -> None:
    """As a ``Node``'s: a relative ``namespace`` (or none) under the pushed one, an absolute one as
    given; an empty ``out`` is the run's own directory under a pushed namespace."""
    given_value = ("/" + given_ns) if absolute else given_ns
    got = placed({"namespace": given_value, "out": out}, pushed)
    base = (pushed or "/").strip("/")
    if absolute:
        assert got["namespace"] == "/" + given_ns
    else:
        assert got["namespace"] == "/" + "/".join(p for p in (base, given_ns) if p)
    if out:
        assert got["out"] == out
    else:
        assert got["out"] == (f"{DEFAULT_OUT}/{base}" if base else DEFAULT_OUT)
