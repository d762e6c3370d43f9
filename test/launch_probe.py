"""Probes of a running ``comems4build launch`` for the fault and interruption tests: which
process runs a node, and whether steps are on disk yet (not a test module)."""

from __future__ import annotations

from pathlib import Path

from comems4build_ros.run.supervisor import processes_with_env


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
