"""How fast a cut run ends: a node killed mid-run, the time until the launch has exited.

``comems4build bench cut`` starts the 12-week run (``--ems``, one process per node) with
``comems4build launch`` and with ``ros2 launch comems4build_ros comems4build.launch.py``,
waits until the bag holds records, kills ``--node`` (default ``plant_sim``) with
``--signal`` (default SIGKILL) and measures the time from the signal until the launch
process has exited. Each run prints that time, the launch's exit code, the processes of
the run still alive after it (none expected) and whether its run-token directory
``OUT/.secrets`` is gone; the end, the median and the largest time and how many runs
ended within the target (:data:`TARGET_S`). ``--ros2 CMD`` names the ``ros2`` command
(default: ``ros2`` on PATH; without one the ``ros2 launch`` runs are skipped, saying so).
Figures depend on the load of the machine: the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from comems4build_ros.app.commands.options import COUNT

#: The launch should end within this time after a node was killed [s].
TARGET_S = 3.0
#: Longest wait for the run to be under way (records on disk) [s].
START_TIMEOUT_S = 180.0
#: Longest wait for the launch to end after the signal [s].
END_TIMEOUT_S = 120.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench cut``."""
    parser.add_argument("--runs", metavar="N", type=COUNT, default=20, help="runs per launcher, >= 1 (default 20)")
    parser.add_argument("--via", choices=("launch", "ros2", "both"), default="both",
                        help="comems4build launch, ros2 launch or both (default)")
    parser.add_argument("--node", default="plant_sim", choices=("plant_sim", "feed", "recorder"),
                        help="the node to kill (default plant_sim; the EMS is the one of --ems)")
    parser.add_argument("--signal", choices=("KILL", "TERM", "INT"), default="KILL", help="signal (default KILL)")
    parser.add_argument("--ems", default="fuzzy", help="EMS of the runs (default fuzzy)")
    parser.add_argument("--ros2", metavar="CMD", default=None,
                        help="the ros2 command, e.g. 'python /opt/ros2cli/bin/ros2' (default: ros2 on PATH)")
    parser.add_argument("--out", metavar="DIR", default=None, help="keep the runs here (default: a temporary one)")


def _records_on_disk(bag: Path) -> bool:
    """Whether the bag being written holds 100 kB of closed chunks (the run is under way)."""
    return sum(f.stat().st_size for f in bag.rglob("*.mcap")) > 100_000 if bag.exists() else False


def _pid_of(log_dir: Path, name: str) -> int | None:
    """The process of the run (its children carry ``ROS_LOG_DIR=log_dir``) running ``name``."""
    from comems4build_ros.run.supervisor import processes_with_env

    for pid in processes_with_env("ROS_LOG_DIR", str(log_dir)):
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")
        except OSError:
            continue
        if any(Path(a).name == name or a.endswith(f".{name}") for a in argv[:4]):
            return pid
    return None


def _one_run(argv: list[str], env: dict[str, str], out: Path, log_dir: Path, node: str, sig: int,
             cwd: Path) -> tuple[float | None, int | None, int, str]:
    """Start, kill ``node`` mid-run, wait: (seconds to the launch's end or None, its exit code,
    processes left, what went wrong or "")."""
    from comems4build_ros.run.supervisor import processes_with_env

    with open(out / "launch.out", "wb") as sink:
        launch = subprocess.Popen(argv, env=env, cwd=cwd, stdout=sink, stderr=subprocess.STDOUT,
                                  start_new_session=True)
    try:
        t_end = time.monotonic() + START_TIMEOUT_S
        while not _records_on_disk(out / "run" / "bag") and launch.poll() is None and time.monotonic() < t_end:
            time.sleep(0.05)
        pid = _pid_of(log_dir, node)
        if launch.poll() is not None or pid is None:
            return None, launch.poll(), 0, f"the run was not under way ({node} not found or the launch ended)"
        t0 = time.monotonic()
        os.kill(pid, sig)
        try:
            code = launch.wait(timeout=END_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            return None, None, 0, f"the launch had not ended {END_TIMEOUT_S:g} s after the signal"
        took = time.monotonic() - t0
        time.sleep(0.2)
        left = processes_with_env("ROS_LOG_DIR", str(log_dir))
        return took, code, len(left), ""
    finally:
        if launch.poll() is None:
            os.killpg(launch.pid, signal.SIGKILL)
            launch.wait()
        for pid in processes_with_env("ROS_LOG_DIR", str(log_dir)):
            os.kill(pid, signal.SIGKILL)


def run(args: argparse.Namespace) -> int:
    """Run the benchmark and print its figures."""
    sig = getattr(signal, f"SIG{args.signal}")
    ros2 = shlex.split(args.ros2) if args.ros2 else ([shutil.which("ros2")] if shutil.which("ros2") else None)
    vias = ["launch", "ros2"] if args.via == "both" else [args.via]
    base = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="comems4build_bench_cut_"))
    base.mkdir(parents=True, exist_ok=True)
    print(f"bench cut: {args.runs} run(s) each, EMS {args.ems}, SIG{args.signal} to {args.node} mid-run; load "
          f"average {os.getloadavg()[0]:.2f} (1 min); runs in {base}", flush=True)
    failed = False
    for via in vias:
        if via == "ros2" and not ros2:
            print("ros2 launch: skipped (no ros2 on PATH; --ros2 CMD names one)", flush=True)
            continue
        times: list[float] = []
        for i in range(args.runs):
            out = base / f"{via}_{i}"
            shutil.rmtree(out, ignore_errors=True)
            out.mkdir(parents=True)
            env = dict(os.environ, PYTHONUNBUFFERED="1")
            if via == "launch":
                argv = [sys.executable, "-m", "comems4build_ros.app.cli", "launch", "--ems", args.ems, "--weeks",
                        "12", "--step-timeout", "2", "--no-progress", "--out", str(out / "run")]
                log_dir = out / "run" / "log" / "ros"
            else:
                assert ros2 is not None
                from comems4build_ros.run.supervisor import acquire_domain_id

                log_dir = out / "ros_log"
                argv = [*ros2, "launch", "comems4build_ros", "comems4build.launch.py", f"ems:={args.ems}",
                        "weeks:=12", "step_timeout:=2", f"out:={out / 'run'}"]
                env.update(AMENT_PREFIX_PATH=sys.prefix, ROS_LOG_DIR=str(log_dir),
                           ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
            if via == "ros2":
                with acquire_domain_id() as domain:
                    env["ROS_DOMAIN_ID"] = str(domain)
                    took, code, left, problem = _one_run(argv, env, out, log_dir, args.node, sig, out)
            else:
                took, code, left, problem = _one_run(argv, env, out, log_dir, args.node, sig, out)
            secrets = "left" if (out / "run" / ".secrets").exists() else "gone"
            if took is None:
                failed = True
                print(f"{via} run {i}: {problem} (exit code {code})", flush=True)
                continue
            times.append(took)
            print(f"{via} run {i}: ended {took:.2f} s after the signal, exit code {code}, {left} process(es) left, "
                  f".secrets {secrets}", flush=True)
            failed |= left > 0 or secrets == "left" or code == 0
        if times:
            within = sum(t <= TARGET_S for t in times)
            print(f"{via}: {len(times)} run(s), median {statistics.median(times):.2f} s, max {max(times):.2f} s, "
                  f"{within} of {len(times)} within {TARGET_S:g} s", flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f} (1 min)", flush=True)
    return 1 if failed else 0
