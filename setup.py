"""ament_python set-up for comems4build_ros.

``pip install .`` installs the Python package, the console scripts, and (through
``data_files``) the ament index marker, ``package.xml``, the ``config/``, ``msg_defs/`` and
launch files and the ``ros2 run`` executables under ``lib/comems4build_ros/``. The
executables are the nodes of :data:`NODES` and one per EMS of ``config/ems.yaml`` (named
after its node); their ``ros2 run`` wrappers are written into ``build/lib_scripts/`` here.
"""

from pathlib import Path

import yaml
from setuptools import find_packages, setup

PACKAGE = "comems4build_ros"
HERE = Path(__file__).parent

#: ROS executables other than the EMS: executable -> (module with ``main()``, what it is).
NODES = {
    "plant_sim": ("comems4build_ros.ros.nodes.plant_sim", "the plant simulator, master of the lock-step loop"),
    "feed": ("comems4build_ros.ros.nodes.feed", "the scenario feed (prices, weather, comfort bounds, forecasts)"),
    "recorder": ("comems4build_ros.ros.nodes.recorder", "the recorder of every topic into a rosbag2/MCAP bag"),
    "replay": ("comems4build_ros.ros.nodes.replay", "the replay of a recorded bag"),
    "mqtt_bridge": ("comems4build_ros.ros.nodes.mqtt_bridge", "the bridge to a house behind MQTT"),
    "mqtt_plant": ("comems4build_ros.mqtt.plant_sim", "the plant simulator behind MQTT"),
    "coordinator": ("comems4build_ros.ros.nodes.coordinator", "the coordinator of a community's hydrogen hub"),
}
#: The module of every EMS node (its ``main()`` finds the EMS by the executable's name).
EMS_NODE_MODULE = "comems4build_ros.ros.nodes.ems_node"

#: The ``ros2 run`` wrapper. Its second line is both shell and Python: run by /bin/sh it runs
#: the file again with ``<prefix>/bin/python`` (the virtual environment's interpreter when
#: installed into one) or else ``python3`` (a ROS 2 install); Python reads it as a string.
WRAPPER = (
    "#!/bin/sh\n"
    "''''true; py=\"$(dirname \"$0\")/../../bin/python\"; [ -x \"$py\" ] || py=python3; "
    "exec \"$py\" \"$0\" \"$@\" # '''\n"
    '"""``ros2 run comems4build_ros {name}``: {summary}."""\n'
    "\n"
    "import sys\n"
    "\n"
    "from {module} import main\n"
    "\n"
    "sys.exit(main())\n"
)


def executables() -> dict[str, tuple[str, str]]:
    """Every ``ros2 run`` executable: :data:`NODES` and the ``node`` of each EMS of ``config/ems.yaml``."""
    table = yaml.safe_load((HERE / "config" / "ems.yaml").read_text(encoding="utf-8"))["ems"]
    return {**NODES, **{row["node"]: (EMS_NODE_MODULE, row["summary"]) for row in table.values()}}


def lib_scripts() -> list[str]:
    """Write the ``ros2 run`` executables into ``build/lib_scripts/``; their paths (relative)."""
    out = HERE / "build" / "lib_scripts"
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (module, summary) in executables().items():
        path = out / name
        path.write_text(WRAPPER.format(name=name, summary=summary, module=module), encoding="utf-8")
        path.chmod(0o755)
        paths.append(str(path.relative_to(HERE)))
    return paths


def _tree(src: str, dest: str) -> list[tuple[str, list[str]]]:
    """``data_files`` entries for every file below ``src`` (relative paths)."""
    out: dict[str, list[str]] = {}
    for path in sorted((HERE / src).rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            rel = path.relative_to(HERE)
            sub = rel.parent.relative_to(src)
            out.setdefault(str(Path(dest) / sub), []).append(str(rel))
    return sorted(out.items())


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    package_data={PACKAGE: ["report/*.yaml", "data/*"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        *_tree("config", f"share/{PACKAGE}/config"),
        *_tree("msg_defs", f"share/{PACKAGE}/msg_defs"),
        *_tree("launch_scripts", f"share/{PACKAGE}/launch"),
        (f"lib/{PACKAGE}", lib_scripts()),
    ],
    install_requires=["setuptools"],
    # Optional MILP solver for the MPC (``solver: gurobi``, config/mpc.yaml): ``pip install .[gurobi]``.
    # The wheel's bundled restricted licence covers models up to 2000 variables / constraints.
    extras_require={"gurobi": ["gurobipy==13.0.3"]},
    zip_safe=False,
    maintainer="comems4build_ros developers",
    maintainer_email="dev@comems4build.invalid",
    description="ComEMS4Build energy management (fuzzy, RBC, MILP MPC) as ROS 2 Jazzy nodes",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "comems4build = comems4build_ros.app.cli:main",
            *(f"{name} = {module}:main" for name, (module, _) in executables().items()),
        ],
    },
)
