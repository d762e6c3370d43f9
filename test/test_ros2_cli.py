"""Conformance with the real ROS 2 Jazzy command-line tools: ``ros2 pkg/run/param/launch``.

The tools (ros2cli, launch, launch_ros; pure Python) are not on PyPI. Where a ROS 2
install provides ``ros2`` with ``launch_ros``, the tests use it; otherwise they install
the wheels of the folder ``COMEMS4BUILD_ROS2_CLI`` (default: ``ros2-cli`` in the
``shared`` folder beside the repository) into a temporary overlay of this environment
(``pip install --target``, put first on ``PYTHONPATH``), and skip, saying why, where
neither is there. The package is found through ``AMENT_PREFIX_PATH`` = this
environment's prefix, as a ROS user sets it.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from ros2_tools import CLI, evaluate, reference, run_ros2, run_until, same_kpis
from waits import BUDGET_S, wait_exit, wait_until

pytestmark = pytest.mark.ros
#: Runs that compare KPIs or are cut by a test: the plant waits for every command within the budget
#: (a fallback, or a stall of three, on a slow step of a loaded machine would be the machine's).
STEP_TIMEOUT_BUDGET = f"step_timeout:={BUDGET_S:g}"

REPO = Path(__file__).resolve().parents[1]
EXECUTABLES = ("feed", "fuzzy_ems", "mpc_ems", "mpc_qp_ems", "mqtt_bridge", "mqtt_plant", "plant_sim", "rbc_ems",
               "recorder", "replay", "thermostat_ems")





def test_ros2_pkg_executables(ros2, domain_id, tmp_path) -> None:
    """Every executable of the package: the ROS nodes (an EMS node per row of config/ems.yaml) and mqtt_plant."""
    from comems4build_ros.run.plan import ros_node_executables

    res = run_ros2(ros2, ["pkg", "executables", "comems4build_ros"], domain_id, tmp_path)
    assert res.returncode == 0, res.stderr
    listed = sorted(line.split()[1] for line in res.stdout.splitlines())
    assert listed == sorted({*ros_node_executables(), "mqtt_plant"}) and set(EXECUTABLES) <= set(listed)


def _plan_text(stdout: str) -> str:
    """The plan printed (launch's own log lines dropped), run tokens and the run's id masked (drawn per launch)."""
    lines = stdout[stdout.index("run plan:"):].splitlines()
    text = "\n".join(line for line in lines if not line.startswith("[INFO]"))
    return re.sub(r"run_id:=(\\?\"?)[0-9a-f]+", r"run_id:=\1ID", re.sub(r"(run|ems)_token:=\d+", r"\1_token:=T", text))


@pytest.mark.parametrize("launch_args, cli_args", [
    (["ems:=rbc", "weeks:=1", "namespace:=/house_0"],
     ["--ems", "rbc", "--weeks", "1", "--namespace", "/house_0"]),
    (["ems:=fuzzy", "houses:=4", "steps:=30", "weeks:=1", "containers:=2", "set:=battery.e_max_kwh=8",
      "config:=" + str(REPO / "config" / "plant.yaml")],
     ["--ems", "fuzzy", "--houses", "4", "--steps", "30", "--weeks", "1", "--containers", "2", "--set",
      "battery.e_max_kwh=8", "--config", str(REPO / "config" / "plant.yaml")]),
    (["ems:=mpc", "houses:=2", "layout:=role", "weeks:=0.5", "ems_options:=time_limit_s=5", "namespace:=/site"],
     ["--ems", "mpc", "--houses", "2", "--layout", "role", "--weeks", "0.5", "--ems-option", "time_limit_s=5",
      "--namespace", "/site"]),
])
def test_launch_file_and_comems4build_launch_print_the_same_plan(ros2, domain_id, tmp_path, launch_args,
                                                                 cli_args) -> None:
    """Launch parity: the same nodes with the same parameters, by both paths."""
    a = run_ros2(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", *launch_args, "out:=run",
                        "domain:=9", "print_plan:=true"], domain_id, tmp_path)
    assert a.returncode == 0, a.stderr + a.stdout
    b = subprocess.run([*CLI, "launch", *cli_args, "--out", "run", "--domain-id", "9", "--print-plan"],
                       capture_output=True, text=True, cwd=tmp_path, timeout=BUDGET_S)
    assert b.returncode == 0, b.stderr
    assert _plan_text(a.stdout) == _plan_text(b.stdout)
    assert "ROS domain 9" in b.stdout


def test_ros2_launch_one_namespaced_house_gives_the_in_process_kpis(ros2, domain_id, tmp_path) -> None:
    """``namespace:=/house_0`` (the recorder's namespaces given through launch_ros) writes the bag."""
    res = run_ros2(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", "ems:=rbc", "weeks:=1",
                          "steps:=36", "namespace:=/house_0", STEP_TIMEOUT_BUDGET, f"out:={tmp_path / 'run'}"],
                   domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-3000:]
    summary = evaluate(tmp_path / "run" / "bag", tmp_path / "eval")
    got = summary["houses"]["house_0"]
    assert got["lost_messages"] == {} and got["steps"] == 36
    same_kpis(got, reference("rbc", 36))


@pytest.mark.parametrize("ems, layout", [("fuzzy", "house"), ("mpc", "node")])
def test_ros2_launch_several_houses_give_the_in_process_kpis_per_house(ros2, domain_id, tmp_path, ems,
                                                                              layout) -> None:
    from comems4build_ros.core.scenario.settings import load_scenario_settings

    steps = 24 if ems == "mpc" else 30
    res = run_ros2(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", f"ems:={ems}", "weeks:=1",
                          f"steps:={steps}", "houses:=2", f"layout:={layout}", STEP_TIMEOUT_BUDGET,
                          f"out:={tmp_path / 'run'}"], domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-3000:]
    summary = evaluate(tmp_path / "run" / "bag", tmp_path / "eval")
    seed = load_scenario_settings().seed
    for i in range(2):
        got = summary["houses"][f"house_{i}"]
        assert got["lost_messages"] == {} and got["steps"] == steps
        same_kpis(got, reference(ems, steps, seed + i))


def test_ros2_launch_fails_when_the_recorder_fails(ros2, domain_id, tmp_path) -> None:
    """A recorder that cannot create its bag (the directory exists) fails the launch."""
    (tmp_path / "run" / "bag").mkdir(parents=True)
    res = run_ros2(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", "ems:=rbc", "weeks:=1",
                          "steps:=24", f"out:={tmp_path / 'run'}"], domain_id, tmp_path)
    assert res.returncode != 0
    assert "'recorder' (recorder) exited with code 2" in res.stdout + res.stderr
    assert "bag directory already exists" in res.stdout + res.stderr


def _describe(ros2: dict, node: str, domain: int, tmp_path: Path) -> dict[str, str]:
    """``ros2 param describe`` of every parameter of ``node``: name -> its text."""
    # a node just listed can miss a query on a loaded machine: asked again until it answers
    listed = run_until(ros2, ["param", "list", node], domain, tmp_path, lambda r: "use_sim_time" in r.stdout)
    names = listed.stdout.split()
    own = [n for n in names if not n.endswith(":") and n not in ("use_sim_time", "start_type_description_service")]
    assert own, f"no parameters of {node}"
    res = run_until(ros2, ["param", "describe", node, *own], domain, tmp_path, lambda r: r.returncode == 0)
    assert res.returncode == 0, res.stderr
    blocks = res.stdout.split("Parameter name: ")[1:]
    return {b.splitlines()[0].strip(): b for b in blocks}


def test_ros2_run_every_node_and_describe_every_parameter(ros2, domain_id, tmp_path) -> None:
    """Every ROS executable started by ``ros2 run`` with ``--ros-args -p`` (each in a namespace of
    its own, so they wait instead of running a loop); ``ros2 param describe`` shows a
    description, the unit and the range (or the allowed values) of each parameter."""
    runs = {
        "plant_sim": ["-r", "__ns:=/b0", "-p", "step_timeout_s:=3.0", "-p", "battery.e_max_kwh:=8.0"],
        "feed": ["-r", "__ns:=/b4", "-p", "weeks:=1", "-p", "steps:=24"],
        "fuzzy_ems": ["-p", "run_token:=7"],
        "rbc_ems": ["-r", "__ns:=/b1", "-p", "ems_options:=['sh_on_chi=0.1']"],
        "mpc_ems": ["-r", "__ns:=/b2", "-p", "ems_options:=['time_limit_s=5']"],
        "recorder": ["-p", f"bag_path:={tmp_path / 'bag'}", "-p", "namespaces:=/b3"],
        "mqtt_bridge": ["-p", "broker_url:=mqtt://127.0.0.1:9", "-p", "startup_timeout_s:=3600.0"],  # never here
    }
    env = dict(ros2["env"], ROS_DOMAIN_ID=str(domain_id), ROS_LOG_DIR=str(tmp_path / "ros_log"),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    procs = {exe: subprocess.Popen([*ros2["argv"], "run", "comems4build_ros", exe, "--ros-args", *args], env=env,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path,
                                   start_new_session=True)
             for exe, args in runs.items()}
    try:
        nodes = {"plant_sim": "/b0/plant_sim", "feed": "/b4/feed", "fuzzy_ems": "/fuzzy_ems", "rbc_ems": "/b1/rbc_ems",
                 "mpc_ems": "/b2/mpc_ems", "recorder": "/recorder", "mqtt_bridge": "/mqtt_bridge"}

        def all_listed() -> bool:
            assert all(p.poll() is None for p in procs.values()), {e: p.poll() for e, p in procs.items()}
            return set(nodes.values()) <= set(run_ros2(ros2, ["node", "list"], domain_id, tmp_path).stdout.split())

        wait_until(all_listed, f"every node listed: {sorted(nodes.values())}")
        for node in nodes.values():
            described = _describe(ros2, node, domain_id, tmp_path)
            for name, text in described.items():
                desc = re.search(r"Description: (.*)", text)
                assert desc and desc.group(1).strip(), (node, name, text)
                if re.search(r"Type: (integer|double)\b", text):
                    assert desc.group(1).rstrip().endswith("]"), (node, name, text)  # the unit
                    assert "Min value" in text or "Additional constraints" in text, (node, name, text)
                else:
                    assert "Additional constraints" in text, (node, name, text)
        plant = _describe(ros2, "/b0/plant_sim", domain_id, tmp_path)
        assert "[kWh]" in plant["battery.e_max_kwh"] and "Min value: 0.1" in plant["battery.e_max_kwh"]
        assert "[s]" in plant["step_timeout_s"]
        got = run_ros2(ros2, ["param", "get", "/fuzzy_ems", "run_token"], domain_id, tmp_path)
        assert "7" in got.stdout
    finally:
        run_ros2(ros2, ["daemon", "stop"], domain_id, tmp_path)  # started by the first 'node list'
        for p in procs.values():
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
        codes = {exe: wait_exit(p, f"{exe} to stop on SIGINT") for exe, p in procs.items()}
    # a clean shutdown on Ctrl-C, with the exit code of a node whose run never ended (exits.py: 3)
    outputs = {e: p.stdout.read() for e, p in procs.items()}
    assert codes == dict.fromkeys(runs, 3), {e: (c, outputs[e][-800:]) for e, c in codes.items() if c != 3}
    assert all("Traceback" not in text and "cause: stopped by a signal before the end of its run" in text
               for text in outputs.values()), outputs


def test_ros2_run_replay_and_mqtt_plant(ros2, domain_id, tmp_path) -> None:
    """The two other executables: ``replay`` of a recorded bag, ``mqtt_plant`` (no ROS node) with --help."""
    res = run_ros2(ros2, ["launch", "comems4build_ros", "comems4build.launch.py", "ems:=rbc", "weeks:=1",
                          "steps:=12", f"out:={tmp_path / 'run'}"], domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-2000:]
    rep = run_ros2(ros2, ["run", "comems4build_ros", "replay", "--ros-args", "-p", f"bag_path:={tmp_path / 'run/bag'}",
                          "-p", "rate:=0.0", "-p", "wait_for_subscribers_s:=0.5"], domain_id, tmp_path)
    assert rep.returncode == 0, rep.stderr[-2000:]
    helped = run_ros2(ros2, ["run", "comems4build_ros", "mqtt_plant", "--help"], domain_id, tmp_path)
    assert helped.returncode == 0 and "--broker" in helped.stdout


def test_ros2_launch_fails_at_once_when_a_node_leaves(ros2, domain_id, tmp_path) -> None:
    """The launch file's exit rule is the supervisor's: plant_sim stopped by SIGTERM mid-run
    (exit code 3) fails the launch at once, naming it, its exit code and what it means."""
    import signal
    import threading

    from comems4build_ros.run.supervisor import processes_with_env

    out = tmp_path / "run"
    env = dict(ros2["env"], ROS_DOMAIN_ID=str(domain_id), ROS_LOG_DIR=str(tmp_path / "ros_log"),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([*ros2["argv"], "launch", "comems4build_ros", "comems4build.launch.py", "ems:=fuzzy",
                             "weeks:=12", STEP_TIMEOUT_BUDGET, f"out:={out}"], env=env, cwd=tmp_path, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    lines: list[tuple[float, str]] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append((time.monotonic(), line.rstrip("\n")))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        wait_until(lambda: proc.poll() is not None or sum(f.stat().st_size for f in (out / "bag").rglob("*.mcap"))
                   >= 100_000, "100 kB of the bag written")
        assert proc.poll() is None, "\n".join(line for _, line in lines)[-3000:]
        plant = [pid for pid in processes_with_env("ROS_LOG_DIR", str(tmp_path / "ros_log"))
                 if any(Path(a.decode()).name == "plant_sim"
                        for a in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[:3])]
        assert len(plant) == 1
        t_signal = time.monotonic()
        os.kill(plant[0], signal.SIGTERM)
        wait_exit(proc, "the launch to end")
    finally:
        if proc.poll() is None:
            proc.kill()
        wait_until(lambda: not reader.is_alive(), "the launch's output read to its end")
        for pid in processes_with_env("ROS_LOG_DIR", str(tmp_path / "ros_log")):
            os.kill(pid, signal.SIGKILL)
    text = "\n".join(line for _, line in lines)
    assert proc.returncode != 0, text[-3000:]
    named = [t for t, line in lines if "process 'plant_sim' (plant) exited with code 3 (stopped by a signal" in line]
    assert named and named[0] - t_signal < 10.0, text[-3000:]
    print(f"ros2 launch named plant_sim {named[0] - t_signal:.2f} s after SIGTERM")
