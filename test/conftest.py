"""Fixtures shared by the test modules.

``tmp_path`` is a fresh folder named ``t<N>`` (not after the test). ``mounted_tmpfs`` mounts
a real small file system for a test (root; skipped where refused). ``params`` is the
default plant (``config/plant.yaml``), built once per module; a module that tests another
plant defines its own ``params``. ``ros2`` is the ROS 2 command-line tools
(``test/ros2_tools.py``). ``domain_id`` is a ROS 2 domain id locked for
one test with the launcher's own lock files, so tests that start nodes never meet.
"""

from __future__ import annotations

import contextlib
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from comems4build_ros.core.config import PlantParams, load_plant_params


def pytest_configure(config: pytest.Config) -> None:
    """Let the processes the tests start be interrupted (Ctrl-C, SIGINT) whatever started the suite.

    A shell without job control starts a background command (``bash tools/test.sh &``, nohup)
    with SIGINT ignored, and an ignored signal stays ignored in every child: a launcher or
    ``ros2 launch`` a test interrupts would not see it. Python's own handler in this process
    is reset to the default in each child it starts, so the children react to SIGINT again.
    """
    import signal

    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def tmp_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh folder per test named ``t<N>``, not after the test as pytest's own: an error
    message names the file, and a folder such as ``test_time_backwards0`` would answer for the
    word ``backwards`` a test expects of the message."""
    return tmp_path_factory.mktemp("t", numbered=True)


@contextlib.contextmanager
def mounted_tmpfs(mount: Path, size: str) -> Iterator[Path]:
    """A tmpfs of ``size`` (``24m``) mounted on the new folder ``mount`` for the block, unmounted after;
    the test is skipped where mounting is refused (it needs root)."""
    mount.mkdir()
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mount)], capture_output=True,
                         text=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {res.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


@pytest.fixture(scope="module")
def params() -> PlantParams:
    """The default plant parameters."""
    return load_plant_params()


@pytest.fixture(scope="session")
def ros2(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The ``ros2`` command (with ``launch_ros``) and its environment (test/ros2_tools.py; skips without one)."""
    from ros2_tools import ros2_command

    return ros2_command(tmp_path_factory)


@pytest.fixture()
def domain_id() -> Iterator[int]:
    """A ROS domain id nobody else uses during the test (the launcher's lock files)."""
    from comems4build_ros.run.supervisor import acquire_domain_id

    with acquire_domain_id() as did:
        yield did


@pytest.fixture()
def rclpy_context(tmp_path, monkeypatch: pytest.MonkeyPatch, domain_id: int) -> Iterator[object]:
    """A private rclpy context (own domain id, discovery on this machine, logs in tmp)."""
    import rclpy

    monkeypatch.setenv("ROS_LOG_DIR", str(tmp_path / "log"))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    yield ctx
    rclpy.try_shutdown(context=ctx)


# ---------------------------------------------------------------------- the fast lane
#: Tests measured at 3 s or more on the 2-core machine (``tools/test_durations.py`` writes
#: the list from a full run's JUnit file); they are marked ``slow`` at collection, so
#: ``tools/test.sh --quick`` (``-m "(not ros and not slow) or quick"``) leaves them out.
SLOW_LIST = Path(__file__).with_name("slow_tests.txt")


def _slow_ids() -> set[str]:
    if not SLOW_LIST.is_file():
        return set()
    lines = SLOW_LIST.read_text(encoding="utf-8").splitlines()
    return {line.split("#", 1)[0].strip() for line in lines if line.split("#", 1)[0].strip()}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the tests named in ``slow_tests.txt`` as ``slow`` (the fast lane leaves them out)."""
    slow = _slow_ids()
    for item in items:
        if item.nodeid in slow or item.nodeid.split("::", 1)[0] in slow:
            item.add_marker(pytest.mark.slow)
