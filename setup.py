"""ament_python set-up for comems4build_ros.

``pip install .`` installs the Python package, the console scripts, and (through
``data_files``) the ament index marker, ``package.xml``, the ``config/`` and
``msg_defs/`` data files and the ``ros2 run`` executables under
``lib/comems4build_ros/``.
"""

from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "comems4build_ros"
HERE = Path(__file__).parent

#: ROS executables: console-script name -> module with ``main()``.
NODES = {
    "plant_sim": "comems4build_ros.ros.nodes.plant_sim",
    "feed": "comems4build_ros.ros.nodes.feed",
    "fuzzy_ems": "comems4build_ros.ros.nodes.ems_node:main_fuzzy",
    "rbc_ems": "comems4build_ros.ros.nodes.ems_node:main_rbc",
    "mpc_ems": "comems4build_ros.ros.nodes.ems_node:main_mpc",
    "recorder": "comems4build_ros.ros.nodes.recorder",
    "replay": "comems4build_ros.ros.nodes.replay",
    "mqtt_bridge": "comems4build_ros.ros.nodes.mqtt_bridge",
    "mqtt_plant": "comems4build_ros.mqtt.plant",
}


def _entry(module: str) -> str:
    return module if ":" in module else f"{module}:main"


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
        *_tree("lib_scripts", f"lib/{PACKAGE}"),
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
            *(f"{name} = {_entry(mod)}" for name, mod in NODES.items()),
        ],
    },
)
