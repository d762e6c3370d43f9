"""``ros2 run``'s executable lookup through ament_index_python with AMENT_PREFIX_PATH = the venv prefix."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest
from waits import log_has, wait_exit, wait_until

from comems4build_ros.run.supervisor import ProcessGroup, acquire_domain_id, child_env

PACKAGE = "comems4build_ros"
#: Every executable ``ros2 run comems4build_ros <exe>`` must find (setup.py NODES).
EXECUTABLES = ("plant_sim", "feed", "fuzzy_ems", "rbc_ems", "mpc_ems", "recorder", "replay", "mqtt_bridge",
               "mqtt_plant", "coordinator")


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
        log = tmp_path / "log" / "recorder.log"
        wait_until(lambda: rec.proc.poll() is not None or log_has(log, "ready"), "the recorder ready")
        assert rec.proc.poll() is None, rec.tail()
        rec.proc.send_signal(signal.SIGINT)
        assert wait_exit(rec.proc, "the recorder closing its bag on SIGINT") == 0, rec.tail()
    assert (bag / "metadata.yaml").is_file() and (bag / "bag.mcap").is_file()


#: The package.xml key of each distribution the package imports (rosdep keys; see package.xml);
#: None where rosdep has no key: pip installs it (:data:`PIP_ONLY`, docs/ros_tools.md).
IMPORT_KEYS = {
    "rclpy": "rclpy", "std_msgs": "std_msgs", "rcl_interfaces": "rcl_interfaces", "launch": "launch",
    "launch_ros": "launch_ros", "numpy": "python3-numpy", "scipy": "python3-scipy", "pandas": "python3-pandas",
    "yaml": "python3-yaml", "pydantic": "python3-pydantic", "matplotlib": "python3-matplotlib", "PIL": "python3-pil",
    "tqdm": "python3-tqdm", "paho": "python3-paho-mqtt", "psutil": "python3-psutil", "rosbags": "python3-rosbags-pip",
    "pulp": None, "holidays": None, "distributed": None, "mcap": None, "skfuzzy": None, "highspy": None, "osqp": None,
    "pvlib": None, "OpenDHW": None, "amqtt": None, "pwdlib": None, "pyenergyplus": None, "fmpy": None,
    "pythonfmu": None,
}
#: The PyPI distribution of each import without a rosdep key: what docs/ros_tools.md has a ROS
#: user install with pip ...
PIP_ONLY = {"pulp": "PuLP", "holidays": "holidays", "distributed": "distributed", "mcap": "mcap",
            "skfuzzy": "scikit-fuzzy", "highspy": "highspy", "osqp": "osqp", "pvlib": "pvlib", "OpenDHW": "OpenDHW",
            "amqtt": "amqtt", "pwdlib": "pwdlib", "pyenergyplus": "pyenergyplus-lbnl", "fmpy": "fmpy",
            "pythonfmu": "pythonfmu"}
#: ... with those needed without an import by name (dask, the scheduler under distributed).
PIP_INDIRECT = ("dask",)
#: Imported only when present (an optional comparison solver, docs/mpc.md), no dependency.
OPTIONAL_IMPORTS = frozenset({"gurobipy"})
#: Dependencies no module imports by name: the contract's message packages (loaded by type
#: name), the launch front end, what scikit-fuzzy needs without declaring it (networkx) and
#: what serves the Dask scheduler's dashboard (bokeh).
INDIRECT_KEYS = ("rosgraph_msgs", "builtin_interfaces", "ros2launch", "python3-networkx", "python3-bokeh-pip")


def test_package_xml_lists_every_run_dependency() -> None:
    """Every distribution any module of the package imports (anywhere, also inside functions) has
    its exec_depend in package.xml, as have the indirect ones; a new import needs its key here."""
    import ast
    import xml.etree.ElementTree as ET

    root = Path(__file__).resolve().parents[1]
    imported: set[str] = set()
    for path in (root / PACKAGE).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                imported.add(node.module.split(".")[0])
    imported -= set(sys.stdlib_module_names) | {PACKAGE, "__future__"} | OPTIONAL_IMPORTS
    assert imported <= set(IMPORT_KEYS), f"no package.xml key known for {sorted(imported - set(IMPORT_KEYS))}"
    declared = {e.text for e in ET.parse(root / "package.xml").getroot().iter("exec_depend")}
    missing = sorted(({IMPORT_KEYS[m] for m in imported if IMPORT_KEYS[m]} | set(INDIRECT_KEYS)) - declared)
    assert not missing, f"package.xml lacks exec_depend {missing}"
    assert {m for m in imported if IMPORT_KEYS[m] is None} <= set(PIP_ONLY)


def test_the_docs_say_how_to_install_what_rosdep_cannot() -> None:
    """docs/ros_tools.md's pip command names every distribution without a rosdep key, and only
    distributions of requirements.txt (whose versions were tested)."""
    import re

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "ros_tools.md").read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if re.match(r"\s*python3 -m pip install --user ", ln)]
    assert len(lines) == 1, "one pip command for what rosdep cannot install"
    named = {w for w in lines[0].split()[5:] if not w.startswith("-")}
    pinned = {re.split(r"[=<>\[ ]", ln, maxsplit=1)[0].lower()
              for ln in (root / "requirements.txt").read_text(encoding="utf-8").splitlines()
              if ln and not ln.startswith("#")}
    want = {*PIP_ONLY.values(), *PIP_INDIRECT}
    assert named == want, sorted(named ^ want)
    assert {n.lower() for n in named} <= pinned
