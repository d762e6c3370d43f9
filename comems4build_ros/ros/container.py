"""Container processes: one OS process runs several nodes (ROS 2 composition, for rclpy).

``python -m comems4build_ros.ros.container --role plant|feed|ems|recorder|container --spec FILE.json``

rclpy has no component container, so this module is one: it creates the very node
classes of ``comems4build_ros.ros.nodes`` (:class:`PlantSimNode`, :class:`Feed`,
:class:`EMSNode`, :class:`Recorder`), one ``rclpy`` node per entry of its spec file, each
under its own namespace with its parameters as ``parameter_overrides``, and spins them
all on one executor. The nodes still talk over DDS (one participant per process, rclpy's
default), so the topics, the lock-step protocol, the contract checks and the bags are
those of separate processes. Two layouts of the run plan use it
(:mod:`comems4build_ros.run.plan`):

* ``house`` (role ``container``): one process runs every node of a few houses
  (recorder, EMS, feed and plant), each spec entry naming its node role (``"role":
  "plant"``): one process wake-up per step of a house instead of one in each of four
  processes;
* ``role`` (roles ``plant``, ``feed``, ``ems``, ``recorder``): one process per role runs
  that role's node of every house (and one recorder process per few houses); with
  16 houses one process per node meant ~65 DDS participants, whose discovery did not
  finish in minutes on 2 cores (docs/ros_tools.md).

Spec file (JSON, written by the launcher)::

    {"ems": "fuzzy",                       # EMS name (role ems only)
     "progress_period_s": 0.25,            # recorder only: one summed progress line per period
     "nodes": [{"namespace": "/house_0", "params": {"config_files": [...], ...},
                "role": "plant"},      # container processes only
               ...]}

The recorders' own progress lines are replaced by one line ``progress <recorded>
<total>`` summed over the process's recorders (give them ``progress_period_s`` 0).
Parameter values: bool, int, float, str or a non-empty list of one of them (empty lists
are left out: their type cannot be inferred, as with ``-p``).

Exit codes: a container process exits 0 once every node's ``finished`` future completed with
0 (plants after their last step, recorders once their bags are complete, feed and EMS
nodes on ``plant/done``); the first non-zero result is the exit code (an EMS node whose
controller failed, a plant whose run stalled). SIGINT or SIGTERM give 0 only when every
node's part of the run is complete, else exit code 3
(:data:`~comems4build_ros.ros.process.EXIT_INTERRUPTED`). A bad parameter or scenario gives exit code 2 and a message
naming the namespace; so does a parameter a node does not have. Parameter services are not
started for contained nodes (fewer entities in the shared executor); ``ros2 param`` does not
reach them. Options for every node of the process (``--log-level``, ``-p use_sim_time:=true``)
follow ``--ros-args`` on the container's command line.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import load_json_file
from comems4build_ros.ros.log import process_logger
from comems4build_ros.wire.exits import EXIT_BAD_INPUT

#: Roles of the nodes a container runs.
NODE_ROLES = ("plant", "feed", "ems", "recorder")
#: Role of a container process: every entry of its spec names its own node role.
CONTAINER = "container"
#: Roles a container process can run.
ROLES = (*NODE_ROLES, CONTAINER)
#: Roles whose process ends once all its nodes' ``finished`` futures are done (every node
#: finishes at the end of the run: feed and EMS on ``plant/done``).
FINISHING_ROLES = ROLES


class ContainerSpecError(InputError):
    """The spec file is unreadable or malformed."""


def load_spec(path: str | Path) -> dict[str, Any]:
    """Read and check a container spec file (see the module docstring).

    Raises
    ------
    ContainerSpecError
        Naming the file and the offending entry.
    """
    p = Path(path)
    try:
        spec = load_json_file(p, "a container spec")
    except ValueError as exc:
        raise ContainerSpecError(f"container spec '{p}': {exc}") from None
    nodes = spec.get("nodes") if isinstance(spec, dict) else None
    if not isinstance(nodes, list) or not nodes:
        raise ContainerSpecError(f"container spec '{p}': 'nodes' must be a non-empty list")
    seen: set[tuple[Any, str]] = set()
    for i, entry in enumerate(nodes):
        if not isinstance(entry, dict) or not isinstance(entry.get("namespace"), str):
            raise ContainerSpecError(f"container spec '{p}': nodes[{i}] needs a string 'namespace'")
        key = (entry.get("role"), entry["namespace"])  # a container has one node per role and namespace
        if key in seen:
            raise ContainerSpecError(f"container spec '{p}': nodes[{i}]: namespace '{entry['namespace']}' given twice")
        seen.add(key)
        if not isinstance(entry.get("params", {}), dict):
            raise ContainerSpecError(f"container spec '{p}': nodes[{i}].params must be an object")
        if "role" in entry and entry["role"] not in NODE_ROLES:
            raise ContainerSpecError(f"container spec '{p}': nodes[{i}].role '{entry['role']}': "
                                     f"one of {', '.join(NODE_ROLES)}")
    return spec


def process_label(role: str) -> str:
    """The logger name of a container process of ``role`` (``container``, ``container_plant``, ...)."""
    return CONTAINER if role == CONTAINER else f"container_{role}"


def entry_role(entry: dict[str, Any], role: str) -> str:
    """Node role of one spec entry in a process of ``role`` (a container's entries name their own)."""
    if role != CONTAINER:
        return role
    if "role" not in entry:
        raise ContainerSpecError(f"container spec: node '{entry.get('namespace')}' of a container needs a 'role'")
    return str(entry["role"])


def to_parameters(params: dict[str, Any]) -> list[Any]:
    """``rclpy.parameter.Parameter`` list of ``params`` (empty lists left out)."""
    from rclpy.parameter import Parameter

    out = []
    for name, value in params.items():
        if isinstance(value, (list, tuple)):
            if not value:
                continue
            value = list(value)
        out.append(Parameter(name, value=value))
    return out


def node_factory(role: str, spec: dict[str, Any]) -> Any:
    """``make(namespace, parameter_overrides) -> Node`` for ``role``."""
    if role == "plant":
        from comems4build_ros.ros.nodes.plant_sim import PlantSimNode

        return lambda **kw: PlantSimNode(**kw)
    if role == "feed":
        from comems4build_ros.ros.nodes.feed import Feed

        return lambda **kw: Feed(**kw)  # may get scenario= (prepare_feed_scenarios)
    if role == "recorder":
        from comems4build_ros.ros.nodes.recorder import Recorder

        return lambda **kw: Recorder(**kw)
    if role == "ems":
        from comems4build_ros.ros.nodes.ems_node import EMSNode

        ems = spec.get("ems")
        if not isinstance(ems, str) or not ems:
            raise ContainerSpecError("container spec: role 'ems' needs the EMS name as 'ems'")
        return lambda **kw: EMSNode(ems, **kw)
    raise ContainerSpecError(f"unknown role '{role}' (one of {', '.join(ROLES)})")


def run_container(role: str, spec: dict[str, Any], args: list[str] | None = None, end_process: bool = True) -> int:
    """Create every node of ``spec`` and spin them on one executor (:func:`~.process.make_executor`)
    until all are done (:func:`all_finished`); the clean-up and the exit code are those of
    :func:`comems4build_ros.ros.process.run_node` (:func:`~comems4build_ros.ros.process.clean_up`).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from comems4build_ros.core.config import ConfigError
    from comems4build_ros.ros.package_node import steady_timer
    from comems4build_ros.ros.process import (
        REFUSED_TAG,
        clean_up,
        init_rclpy,
        interrupted_code,
        log_crash,
        make_executor,
        spin_until_done,
        stop_signalled,
    )
    from comems4build_ros.wire.contract import ContractError

    label = process_label(role)
    roles = [entry_role(e, role) for e in spec["nodes"]]
    makers = {r: node_factory(r, spec) for r in dict.fromkeys(roles)}
    prepared = prepare_feed_scenarios(spec, role)
    init_rclpy(args, label)
    executor = make_executor()
    nodes: list[Any] = []
    code = 0
    current = "?"
    try:
        for entry, r in zip(spec["nodes"], roles):
            current = entry["namespace"]
            nodes.append(create_node(makers[r], entry, prepared.get(current) if r == "feed" else None))
            executor.add_node(nodes[-1])
        progress_nodes = [n for n, r in zip(nodes, roles) if r == "recorder"]
        period = float(spec.get("progress_period_s", 0.0))
        if progress_nodes and period > 0:
            steady_timer(progress_nodes[0], period, lambda: print_progress(progress_nodes))
        done = all_finished(nodes, role)
        spin_until_done(executor, done)
        # the spin ended with every node done, or because the context was shut down (no exception)
        code = int(done.result() or 0) if done.done() else interrupted_code(nodes, label)
        if progress_nodes:
            print_progress(progress_nodes)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = interrupted_code(nodes, label)
    except RuntimeError:
        if rclpy.ok() and not stop_signalled():  # see run_node: a context shut down from elsewhere, a signal
            raise
        code = interrupted_code(nodes, label)
    except (ConfigError, ContractError, ValueError, FileNotFoundError, FileExistsError) as exc:
        process_logger(label).error(f"{REFUSED_TAG} node of namespace {current}: {exc}")
        code = EXIT_BAD_INPUT
    except Exception:  # a bug: its traceback in the log, exit code 1 (the process ends in clean_up)
        code = log_crash(label)
    finally:
        clean_up(executor, nodes, label, code, end_process)
    return code


def create_node(make: Any, entry: dict[str, Any], prepared: tuple[Any, Any] | None) -> Any:
    """One node of a spec entry (namespace, parameters; a feed's prepared scenario), its
    parameters checked whole (:meth:`~comems4build_ros.ros.package_node.NodeParameters.refuse_undeclared`)."""
    from comems4build_ros.ros.package_node import refuse_undeclared

    extra = {} if prepared is None else {"scenario": prepared[0], "weeks_bound": prepared[1]}
    node = make(namespace=entry["namespace"], parameter_overrides=to_parameters(dict(entry.get("params", {}))),
                start_parameter_services=False, **extra)
    refuse_undeclared(node)
    return node


def all_finished(nodes: list[Any], role: str) -> Any:
    """A future done once every node's ``finished`` future is (result 0), or with the first
    non-zero result (an EMS whose controller failed, a stalled plant) as soon as it comes."""
    from rclpy.task import Future

    done = Future()
    futures = [f for f in (getattr(n, "finished", None) for n in nodes) if f is not None]

    def check(_: Any = None) -> None:
        if done.done():
            return
        failed = [int(f.result() or 0) for f in futures if f.done() and int(f.result() or 0) != 0]
        if failed:
            done.set_result(failed[0])
        elif role in FINISHING_ROLES and all(f.done() for f in futures):
            done.set_result(0)

    for f in futures:
        f.add_done_callback(check)
    return done


def prepare_feed_scenarios(spec: dict[str, Any], role: str = "feed") -> dict[str, tuple[Any, Any]]:
    """Scenario and ``weeks`` bound of every feed node of ``spec`` (of a process of ``role``), built
    in parallel worker processes.

    Generating one default scenario takes about 1.5 s of CPU; a feed container with 16
    houses would spend 16 x that before the first step. The workers are forked before
    rclpy is initialised (one per core, at most one per node). A node whose scenario
    fails here is left to its own constructor, which reports the error as usual.
    """
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    from comems4build_ros.ros.nodes.feed import prepare_scenario

    nodes = [e for e in spec["nodes"] if entry_role(e, role) == "feed"]
    workers = min(len(nodes), os.cpu_count() or 1)
    if len(nodes) < 2 or workers < 2:
        return {}
    out: dict[str, Any] = {}
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork")) as pool:
        futures = {e["namespace"]: pool.submit(prepare_scenario, dict(e.get("params", {}))) for e in nodes}
        for ns, fut in futures.items():
            try:
                scenario, notes, weeks_bound = fut.result()
            except Exception:  # noqa: BLE001 - the node's constructor reports it with its namespace
                continue
            if not notes:  # loader notes are logged by the node itself: let it load
                out[ns] = (scenario, weeks_bound)
    return out


def print_progress(recorders: list[Any]) -> None:
    """One ``progress <recorded> <total>`` line for all recorders of the process (total 0 until every one knows)."""
    recorded = sum(sum(r.records.values()) for r in recorders)
    known = all(len(r.n_steps) == len(r.namespaces) for r in recorders)
    total = sum(sum(r.n_steps.values()) for r in recorders) if known else 0
    print(f"progress {recorded} {total}", flush=True)


def main(argv: list[str] | None = None) -> int:
    """Entry point: ``python -m comems4build_ros.ros.container --role ROLE --spec FILE``."""
    parser = argparse.ArgumentParser(prog="comems4build_ros.ros.container", description=__doc__.splitlines()[0])
    parser.add_argument("--role", required=True, choices=ROLES)
    parser.add_argument("--spec", required=True, help="JSON spec file (namespaces and parameters of the nodes)")
    ns, rest = parser.parse_known_args(argv)
    try:
        spec = load_spec(ns.spec)
        for entry in spec["nodes"]:
            entry_role(entry, ns.role)
    except ContainerSpecError as exc:
        process_logger(process_label(ns.role)).error(f"refused to start: {exc}")
        return EXIT_BAD_INPUT
    return run_container(ns.role, spec, rest or None)


if __name__ == "__main__":
    raise SystemExit(main())
