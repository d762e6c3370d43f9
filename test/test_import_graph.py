"""The package's import graph has no circle, counting the imports inside functions too.

Every ``import`` and ``from ... import`` statement of every module (module level, in
functions, in branches) is an edge from the module to the module it names (a name that
is a submodule, ``from . import plan``, is an edge to that submodule). A circle means two
modules that can only be understood together; the nodes' modules are leaves that only
``ros/`` itself may use.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

PACKAGE = "comems4build_ros"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE


def module_name(path: Path) -> str:
    """``comems4build_ros/ros/plan.py`` -> ``comems4build_ros.ros.plan`` (``__init__`` -> the package)."""
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    """Every module of the package by name."""
    return {module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """Modules of the package that ``name`` imports anywhere in its source."""
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[: len(base) - node.level + (1 if is_package else 0)]
                parent = ".".join(base + ([node.module] if node.module else []))
            else:
                parent = node.module or ""
            targets = [parent] + [f"{parent}.{a.name}" for a in node.names]
        else:
            continue
        out.update(t for t in targets if t in known and t != name)
    return out


def import_graph() -> nx.DiGraph:
    """Directed graph module -> imported module over the whole package."""
    mods = modules()
    known = set(mods)
    graph = nx.DiGraph()
    graph.add_nodes_from(known)
    for name, path in mods.items():
        graph.add_edges_from((name, t) for t in imports(name, path, known))
    return graph


def test_the_graph_sees_function_level_imports() -> None:
    """The graph holds the imports made inside functions (e.g. the launcher's of the bag evaluation)."""
    graph = import_graph()
    assert graph.number_of_nodes() > 50
    assert graph.has_edge(f"{PACKAGE}.ros.launcher", f"{PACKAGE}.ros.bag_eval")


def test_no_import_circle_anywhere_in_the_package() -> None:
    cycles = sorted(nx.simple_cycles(import_graph()), key=len)
    assert not cycles, "import circles:\n" + "\n".join(" -> ".join([*c, c[0]]) for c in cycles[:20])


def test_only_ros_imports_the_node_modules() -> None:
    """Shared helpers (scenario loading, codecs, checks) live outside the node modules."""
    nodes = f"{PACKAGE}.ros.nodes"
    graph = import_graph()
    offenders = sorted(f"{a} -> {b}" for a, b in graph.edges
                       if b.startswith(nodes + ".") and not a.startswith(f"{PACKAGE}.ros."))
    assert not offenders, offenders
