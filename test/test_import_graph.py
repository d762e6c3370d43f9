"""The package's layers: each imports only the layers below it, with no circle anywhere.

Every ``import`` and ``from ... import`` statement of every module (module level, in
functions, in branches) is an edge from the module to the module it names (a name that
is a submodule, ``from comems4build_ros.run import plan``, is an edge to that submodule).

The layers, bottom up (docs/architecture.md): ``files`` (reading and writing the
package's files), ``core`` (parameters, device models, plant, scenarios, EMS, KPIs, the
in-process loop), ``wire`` (the topic contract, CDR, run tokens, exit codes), ``bags``,
``mqtt``, ``ros`` (the only layer that uses rclpy), ``run`` (the run plan, its supervisor,
the launcher), ``study``, ``report`` and ``app`` (the commands). Inside the core, the same
rule holds for its parts (:data:`CORE_LAYERS`). The layers below ``ros``
import no ROS client library: no rclpy, launch, ROS message packages; the core and the
wire contract no bag library either.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

PACKAGE = "comems4build_ros"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE

#: The layers, bottom up: a module may import its own layer and the layers before it.
LAYERS = ("files", "core", "wire", "bags", "mqtt", "ros", "run", "study", "report", "app")
#: The core's own order, bottom up: records and arithmetic, the parameters, the device models,
#: what is built from them (plant, scenarios, KPIs, economics, EMS), and the in-process loop.
CORE_LAYERS = (
    ("types", "numerics", "result_cache", "psychrometrics"),
    ("config",),
    ("models",),
    ("plant", "scenario", "kpi", "economics", "ems"),
    ("loop",),
)
#: Top-level distributions of the ROS client libraries and message packages.
ROS_CLIENT = frozenset({"rclpy", "launch", "launch_ros", "ros2launch", "std_msgs", "rosgraph_msgs",
                        "builtin_interfaces", "rcl_interfaces", "rosidl_runtime_py", "ament_index_python"})
#: Top-level distributions of the bag libraries.
BAG_LIBRARIES = frozenset({"rosbags", "mcap", "mcap_ros2"})
#: External packages each layer may not import.
FORBIDDEN: dict[str, frozenset[str]] = {
    "files": ROS_CLIENT | BAG_LIBRARIES,
    "core": ROS_CLIENT | BAG_LIBRARIES,
    "wire": ROS_CLIENT | BAG_LIBRARIES,
    "bags": ROS_CLIENT,
    "mqtt": ROS_CLIENT | BAG_LIBRARIES,
}


def module_name(path: Path, root: Path = ROOT) -> str:
    """``comems4build_ros/run/plan.py`` -> ``comems4build_ros.run.plan`` (``__init__`` -> the package)."""
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the package by name."""
    return {module_name(p, root): p for p in sorted(root.rglob("*.py"))}


def imported_names(name: str, path: Path) -> set[str]:
    """Every module name ``name`` imports anywhere in its source, in and outside the package."""
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[: len(base) - node.level + (1 if is_package else 0)]
                parent = ".".join(base + ([node.module] if node.module else []))
            else:
                parent = node.module or ""
            out.add(parent)
            out.update(f"{parent}.{a.name}" for a in node.names)
    return out


def import_graph(root: Path = ROOT) -> nx.DiGraph:
    """Directed graph module -> imported module of the package (its own modules only)."""
    mods = modules(root)
    known = set(mods)
    graph = nx.DiGraph()
    graph.add_nodes_from(known)
    for name, path in mods.items():
        graph.add_edges_from((name, t) for t in imported_names(name, path) if t in known and t != name)
    return graph


def layer_of(module: str) -> str | None:
    """The layer of a module (``comems4build_ros.run.plan`` -> ``run``); None for the package's face."""
    parts = module.split(".")
    if len(parts) < 2:
        return None
    if parts[1] not in LAYERS:
        raise AssertionError(f"{module} lies outside every layer ({', '.join(LAYERS)})")
    return parts[1]


def core_layer_of(module: str) -> tuple[int, str] | None:
    """Rank and name of a core module's part (``comems4build_ros.core.models.pv`` -> (2, "models"))."""
    parts = module.split(".")
    if len(parts) < 3 or parts[1] != "core":
        return None
    for rank, names in enumerate(CORE_LAYERS):
        if parts[2] in names:
            return rank, parts[2]
    raise AssertionError(f"{module} lies outside every part of the core ({CORE_LAYERS})")


def against_the_order(graph: nx.DiGraph) -> list[str]:
    """Every import of a module from a higher layer (or part of the core), as ``a -> b (why)``."""
    rank = {layer: i for i, layer in enumerate(LAYERS)}
    out = []
    for a, b in sorted(graph.edges):
        la, lb = layer_of(a), layer_of(b)
        if la is not None and lb is not None and rank[lb] > rank[la]:
            out.append(f"{a} -> {b} ({la} may not import {lb})")
        ca, cb = core_layer_of(a), core_layer_of(b)
        if ca is not None and cb is not None and cb[0] > ca[0]:
            out.append(f"{a} -> {b} (core.{ca[1]} may not import core.{cb[1]})")
    return out


def forbidden_imports(root: Path = ROOT) -> list[str]:
    """Every import of a ROS client or bag library in a layer that may not use it."""
    out = []
    for name, path in modules(root).items():
        layer = layer_of(name)
        banned = FORBIDDEN.get(layer or "", frozenset())
        for target in sorted(imported_names(name, path)):
            if target.split(".")[0] in banned:
                out.append(f"{name} imports {target} ({layer} may not use {target.split('.')[0]})")
    return out


def test_every_module_lies_in_a_layer() -> None:
    """The package's folders are its layers; nothing lies beside them but the package's face."""
    loose = sorted(n for n in modules() if len(n.split(".")) == 2 and n.split(".")[1] not in LAYERS)
    assert not loose, loose
    assert {n.split(".")[1] for n in modules() if "." in n} == set(LAYERS)
    for name in modules():
        core_layer_of(name)  # raises for a core module outside the core's parts


def test_the_graph_sees_function_level_imports() -> None:
    """The graph holds the imports made inside functions (e.g. the launcher's of the bag evaluation)."""
    graph = import_graph()
    assert graph.number_of_nodes() > 50
    assert graph.has_edge(f"{PACKAGE}.run.launcher", f"{PACKAGE}.bags.evaluation")


def test_no_import_circle_anywhere_in_the_package() -> None:
    cycles = sorted(nx.simple_cycles(import_graph()), key=len)
    assert not cycles, "import circles:\n" + "\n".join(" -> ".join([*c, c[0]]) for c in cycles[:20])


def test_each_layer_imports_only_the_layers_below_it() -> None:
    offenders = against_the_order(import_graph())
    assert not offenders, "imports against the layer order:\n" + "\n".join(offenders)


def test_no_ros_client_below_the_ros_layer_and_no_bag_library_in_the_core() -> None:
    offenders = forbidden_imports()
    assert not offenders, "\n".join(offenders)


def test_only_ros_imports_the_node_modules() -> None:
    """Shared helpers (scenario loading, codecs, checks) live outside the node modules."""
    nodes = f"{PACKAGE}.ros.nodes"
    graph = import_graph()
    offenders = sorted(f"{a} -> {b}" for a, b in graph.edges
                       if b.startswith(nodes + ".") and not a.startswith(f"{PACKAGE}.ros."))
    assert not offenders, offenders


@pytest.mark.parametrize(("layer", "statement", "expected"), [
    ("core/scenario", "from comems4build_ros.run.plan import RunPlan\n", "core may not import run"),
    ("core/models", "from comems4build_ros.core.loop import simulate\n", "core.models may not import core.loop"),
    ("wire", "def f():\n    from comems4build_ros.ros import node\n", "wire may not import ros"),
    ("core/ems", "import rclpy\n", "core may not use rclpy"),
    ("core/ems/mpc", "def f():\n    from rosbags.highlevel import AnyReader\n", "core may not use rosbags"),
    ("bags", "from launch import LaunchDescription\n", "bags may not use launch"),
])
def test_the_checks_fail_on_an_import_against_the_order(tmp_path: Path, layer: str, statement: str,
                                                         expected: str) -> None:
    """A copy of the package with one added import breaks the rules, and the checks name it."""
    import shutil

    copy = tmp_path / PACKAGE
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns("__pycache__", "data"))
    (copy / layer / "zz_scratch.py").write_text(statement, encoding="utf-8")
    found = against_the_order(import_graph(copy)) + forbidden_imports(copy)
    assert any(expected in line and "zz_scratch" in line for line in found), found
