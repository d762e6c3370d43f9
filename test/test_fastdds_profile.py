"""The Fast DDS profiles of ``launch_scripts/`` are valid and really in effect in a node process.

Fast DDS 2.14 (Jazzy) reads only ``FASTRTPS_DEFAULT_PROFILES_FILE``; a process given only
``FASTDDS_DEFAULT_PROFILES_FILE`` (the name of Fast DDS 3) runs on the defaults. The check
here is what the middleware did, not what the environment says: the size of the
participant's shared-memory segment (16 MiB in ``fastdds_profile.xml``, 0.5 MiB by default)
and, with the UDP-only profile, no segment at all.
"""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from waits import BUDGET_S

from comems4build_ros.run.plan import (
    FASTDDS_PROFILE,
    FASTDDS_PROFILE_VARS,
    FASTDDS_UDP_PROFILE,
    fastdds_profile,
    profile_env,
)
from comems4build_ros.run.supervisor import acquire_domain_id, child_env

#: Prints the sizes [bytes] of the Fast DDS shared-memory segments (not ports) this process maps.
PROBE = """
import re, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("profile_probe")  # its participant maps its segments while it is created
node.create_publisher(String, "probe", 10)
sizes = {}
for line in open("/proc/self/maps"):
    name = line.split()[-1]
    if re.fullmatch(r"/dev/shm/fastrtps_[0-9a-f]{16}", name):
        lo, hi = (int(x, 16) for x in line.split()[0].split("-"))
        sizes[name] = sizes.get(name, 0) + hi - lo
print(sum(sizes.values()))
rclpy.shutdown()
"""


def _segment_bytes(env: dict[str, str]) -> int:
    res = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr
    return int(res.stdout.strip().splitlines()[-1])


def _base_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in FASTDDS_PROFILE_VARS}


@pytest.mark.parametrize("name", [FASTDDS_PROFILE, FASTDDS_UDP_PROFILE])
def test_profiles_are_valid_xml(name: str) -> None:
    path = fastdds_profile(name)
    assert path is not None
    root = ET.parse(path).getroot()  # a comment with "--" or a stray tag fails here
    assert root.tag.endswith("dds")


def test_both_variables_set_unless_the_user_chose(tmp_path: Path) -> None:
    env = child_env(0, tmp_path, base=_base_env())
    assert {env[v] for v in FASTDDS_PROFILE_VARS} == {str(fastdds_profile())}
    mine = {**_base_env(), "FASTDDS_DEFAULT_PROFILES_FILE": "/my/profile.xml"}
    env = child_env(0, tmp_path, base=mine)
    assert env["FASTDDS_DEFAULT_PROFILES_FILE"] == "/my/profile.xml" and "FASTRTPS_DEFAULT_PROFILES_FILE" not in env
    assert profile_env(None) == {}


@pytest.mark.ros
@pytest.mark.skipif(not Path("/proc/self/maps").is_file(), reason="needs /proc/<pid>/maps (Linux)")
def test_profile_in_effect_in_a_node_process(tmp_path: Path) -> None:
    with acquire_domain_id() as did:
        launcher_env = child_env(did, tmp_path / "ros_log", base=_base_env())
        with_profile = _segment_bytes(launcher_env)
        # as a side of the netns network runs: discovery range SUBNET, the UDP-only profile
        udp_only = _segment_bytes({**launcher_env, "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                                   **dict.fromkeys(FASTDDS_PROFILE_VARS, str(fastdds_profile(FASTDDS_UDP_PROFILE)))})
        fast_dds_3_name_only = _segment_bytes({**_base_env(), "ROS_DOMAIN_ID": str(did),
                                               "ROS_LOG_DIR": str(tmp_path / "ros_log"),
                                               "FASTDDS_DEFAULT_PROFILES_FILE": str(fastdds_profile())})
    assert with_profile >= 16 * 2**20, with_profile  # segment_size of fastdds_profile.xml
    assert udp_only == 0  # no shared memory: the UDP-only profile applies
    # what the launcher set before: Fast DDS 2.14 ignores this name and keeps its 0.5 MiB default
    assert fast_dds_3_name_only < 2**20, fast_dds_3_name_only
