"""``ros2 run``'s executable lookup through ament_index_python with AMENT_PREFIX_PATH = the venv prefix."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from comems4build_ros.run.supervisor import ProcessGroup, acquire_domain_id, child_env

PACKAGE = "comems4build_ros"
#: Every executable ``ros2 run comems4build_ros <exe>`` must find (setup.py NODES).
EXECUTABLES = ("plant_sim", "feed", "fuzzy_ems", "rbc_ems", "mpc_ems", "recorder", "replay", "mqtt_bridge",
               "mqtt_plant")


@pytest.fixture
def ament_prefix(monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setenv("AMENT_PREFIX_PATH", sys.prefix)
    return sys.prefix


def _lookup(exe: str) -> Path:
    """What ``ros2 run`` does: package prefix from the ament index, then lib/<package>/<exe>."""
    from ament_index_python.packages import get_package_prefix

    return Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE / exe


def test_package_is_registered_in_the_ament_index(ament_prefix: str) -> None:
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    assert Path(get_package_prefix(PACKAGE)) == Path(ament_prefix)
    share = Path(get_package_share_directory(PACKAGE))
    assert (share / "package.xml").is_file()
    assert (share / "msg_defs" / "topics.yaml").is_file()


@pytest.mark.parametrize("exe", EXECUTABLES)
def test_ros2_run_finds_every_executable(ament_prefix: str, exe: str) -> None:
    path = _lookup(exe)
    assert path.is_file(), f"{path} missing (run tools/setup.sh to reinstall the package)"
    assert os.access(path, os.X_OK), f"{path} is not executable"


@pytest.mark.ros
def test_installed_recorder_smoke_run(ament_prefix: str, tmp_path: Path) -> None:
    """Start ``lib/comems4build_ros/recorder`` as ``ros2 run`` would, stop it with SIGINT: a closed bag."""
    exe = _lookup("recorder")
    bag = tmp_path / "bag"
    with acquire_domain_id() as did, ProcessGroup(child_env(did, tmp_path / "ros_log"), tmp_path / "log") as group:
        rec = group.start("recorder", "recorder", [str(exe), "--ros-args", "-p", f"bag_path:={bag}",
                                                   "-p", "wait_for_topics:=['']", "-p", "stop_when_done:=false"])
        t0 = time.monotonic()
        log = tmp_path / "log" / "recorder.log"
        while time.monotonic() - t0 < 60 and not (log.exists() and "ready" in log.read_text()):
            assert rec.proc.poll() is None, rec.tail()
            time.sleep(0.1)
        rec.proc.send_signal(signal.SIGINT)
        assert rec.proc.wait(timeout=20) == 0, rec.tail()
    assert (bag / "metadata.yaml").is_file() and (bag / "bag.mcap").is_file()
