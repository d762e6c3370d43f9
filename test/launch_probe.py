"""Probes of a running ``comems4build launch`` for the fault and interruption tests: which
process runs a node, whether steps are on disk yet, and a run held in progress (not a test module)."""

from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Iterator
from pathlib import Path

from waits import log_has, wait_until

from comems4build_ros.run.supervisor import processes_with_env

#: What the lock-step master logs when its last step is done (ros/lockstep.py), before plant/done.
RUN_DONE_LINE = "run done:"


def pid_of(out: Path, name: str) -> int:
    """The process of the launch in ``out`` running ``name`` (console script, module or container spec)."""
    for pid in processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")):
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")
        except OSError:
            continue
        if any(Path(a).name in (name, f"{name}.json") or a.endswith(f".{name}") for a in argv[:8]):
            return pid
    raise AssertionError(f"no process {name}")


def records_on_disk(bag: Path) -> bool:
    """Whether a plant/record message (of any namespace) can be read now from the closed chunks
    of the bag being written; a size alone is not enough, the first chunks may hold only the
    feed's inputs."""
    from comems4build_ros.bags.bag import iter_messages

    if not any(bag.rglob("*.mcap")):
        return False
    try:
        return any(topic.endswith("plant/record") for topic, *_ in iter_messages(bag))
    except (OSError, ValueError):
        return False


def process_state(pid: int) -> str | None:
    """The state letter of process ``pid`` (``/proc/<pid>/stat``: R, S, T for stopped ...), None once it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[0]


@contextlib.contextmanager
def run_held(out: Path, master: str = "plant_sim") -> Iterator[int]:
    """The run of the launch in ``out`` held in progress while the block runs: its lock-step
    master paused (SIGSTOP) before its last step, so the run cannot end by itself (nothing
    steps); continued (SIGCONT) afterwards, as a launcher that stops its nodes also does.

    Yields the master's process id.

    Raises
    ------
    AssertionError
        When the master had already done its last step (``run done:`` in its log) or exited:
        then the run could end anyway and the caller's test would prove nothing.
    """
    pid = pid_of(out, master)
    os.kill(pid, signal.SIGSTOP)
    try:
        wait_until(lambda: process_state(pid) in ("T", "t", None), f"{master} paused (SIGSTOP)")
        assert process_state(pid) in ("T", "t"), f"{master} exited before it was paused"
        assert not log_has(out / "log" / f"{master}.log", RUN_DONE_LINE), f"{master} had done its last step"
        yield pid
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGCONT)


def netns_available() -> str | None:
    """None if network namespaces can be made here, else the reason."""
    import shutil
    import subprocess

    if shutil.which("ip") is None:
        return "no 'ip' command (iproute2)"
    if os.geteuid() != 0:
        return "'ip netns' needs root"
    name = f"c4bprobe{os.getpid() % 10000}"
    res = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True)
    if res.returncode != 0:
        return f"'ip netns add' failed: {res.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", name], capture_output=True)
    return None
