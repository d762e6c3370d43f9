"""The run plan as a ROS 2 launch description (``ros2 launch comems4build_ros comems4build.launch.py``).

The launch file takes the arguments of ``comems4build launch`` (:data:`ARGUMENTS`), turns
them into that command's options with the command's own parser and checks
(:func:`comems4build_ros.app.commands.launch.launch_options`) and builds the very same
:class:`~comems4build_ros.run.plan.RunPlan` (:func:`~comems4build_ros.run.plan.plan_run`);
``print_plan:=true`` prints it, as ``comems4build launch --print-plan`` does. Each process
of the plan becomes a launch action: a process running one node of a ``ros2 run``
executable is a ``launch_ros`` ``Node`` (its namespace, name and parameters as the plan
has them, so ``ros2 node`` and ``ros2 param`` see it as usual), any other process
(container processes, the MQTT broker, a discovery server) an ``ExecuteProcess`` of the
plan's command line. Every process gets the plan's environment additions (and the Fast
DDS profile, as the supervisor gives it).

The exit rule is the supervisor's (:mod:`comems4build_ros.run.supervisor`): the run is
done when every recorder process has exited 0 (the bags are closed), and then the launch
shuts down; any other exit while the run is in progress (a node that fails, is stopped
by a signal before the end of its run, ends a stalled run naming the silent node, or a
process that may not end by itself), or the plan's time limit, ends the launch at once
with an error naming the process, its exit code and what it means
(:mod:`comems4build_ros.wire.exits`), so ``ros2 launch`` exits non-zero. The run tokens
are written as the supervisor writes them (mode 0600 in ``<out>/.secrets``, mode 0700)
and removed when the launch shuts down. Evaluate the bag afterwards with ``comems4build
evaluate BAG --out DIR``.

``launch`` and ``launch_ros`` are imported inside the functions: the package itself does
not need them (they come with a ROS 2 install).
"""

from __future__ import annotations

import os
import shlex
from pathlib import Path
from typing import Any

from comems4build_ros.run.plan import (
    LaunchOptions,
    RunPlan,
    fastdds_profile,
    node_label,
    plan_run,
    profile_env,
    ros_node_executables,
)
from comems4build_ros.run.supervisor import LaunchError, describe_nodes
from comems4build_ros.wire.exits import exit_meaning
from comems4build_ros.wire.tokens import write_token_file

PACKAGE = "comems4build_ros"
#: Launch arguments: name -> (default, description, ``comems4build launch`` option). A list
#: option (``--config``, ``--set``, ``--ems-option``) takes ``;``-separated items.
ARGUMENTS: dict[str, tuple[str, str, str]] = {
    "ems": ("fuzzy", "EMS node: fuzzy, rbc, mpc (also thermostat, mpc-qp)", "--ems"),
    "scenario": ("default", "'default', 'synthetic' or a scenario CSV path", "--scenario"),
    "start": ("", "ISO 8601 start of the run's window (CSV scenarios)", "--start"),
    "weeks": ("", "run length [weeks] (empty = the scenario's default)", "--weeks"),
    "steps": ("", "cut the run to its first N steps (empty = all)", "--steps"),
    "houses": ("1", "independent houses under <namespace>/house_<i>", "--houses"),
    "seed": ("", "scenario seed of house 0 (default scenario)", "--seed"),
    "namespace": ("/", "namespace of the house (one house) or of the houses", "--namespace"),
    "layout": ("", "processes: node, house or role (empty = the default for the house count)", "--layout"),
    "containers": ("", "container processes of layout 'house' (empty = one per core)", "--containers"),
    "config": ("", "parameter files merged over config/plant.yaml, ';'-separated", "--config"),
    "set": ("", "plant parameter overrides KEY=VALUE, ';'-separated", "--set"),
    "ems_options": ("", "EMS options KEY=VALUE, ';'-separated", "--ems-option"),
    "forecast": ("", "forecasts of the MPC: perfect or imperfect (empty = config/forecast.yaml)", "--forecast"),
    "building": ("rc", "building model of plant_sim: rc, energyplus, energyplus:FILE.idf or fmu:FILE.fmu",
                 "--building"),
    "all_inputs": ("false", "publish and record every EMS input, also what this EMS does not read", "--all-inputs"),
    "step_timeout": ("", "plant_sim's wait for a command before its safe fallback [s]", "--step-timeout"),
    "timeout": ("", "end the launch with an error after this wall time [s] (empty = the plan's limit)",
                "--timeout"),
    "out": ("comems4build_run", "output directory (bag, spec files)", "--out"),
    "bag": ("", "bag directory to create (empty = <out>/bag)", "--bag"),
    "domain": ("", "ROS_DOMAIN_ID of every process (empty = the environment's, else 0)", "--domain-id"),
    "print_plan": ("false", "print the run plan and exit without starting anything", "--print-plan"),
}
#: Arguments that are flags of ``comems4build launch`` (true/false).
FLAG_ARGUMENTS = ("all_inputs", "print_plan")
#: Arguments holding several items, separated by ``;``.
LIST_ARGUMENTS = ("config", "set", "ems_options")


def command_line(values: dict[str, str]) -> list[str]:
    """The ``comems4build launch`` arguments of the launch arguments ``values`` (strings)."""
    argv: list[str] = []
    for name, (_default, _help, option) in ARGUMENTS.items():
        value = str(values.get(name, ARGUMENTS[name][0])).strip()
        if name in FLAG_ARGUMENTS:
            if value.lower() in ("true", "1", "yes"):
                argv.append(option)
            continue
        if name == "domain" and not value:
            value = os.environ.get("ROS_DOMAIN_ID", "")
        items = [v.strip() for v in value.split(";") if v.strip()] if name in LIST_ARGUMENTS else [value]
        for item in items:
            if item:
                argv += [option, item]
    return argv


def options_of(values: dict[str, str]) -> tuple[LaunchOptions, int, bool]:
    """Launch options, domain id and ``print_plan`` of the launch arguments ``values``.

    Raises
    ------
    SystemExit, UsageError
        From the command's parser and checks, naming the option (``--weeks`` for ``weeks``).
    """
    import argparse

    from comems4build_ros.app.commands.launch import add_arguments, launch_options

    parser = argparse.ArgumentParser(prog="comems4build.launch.py", add_help=False)
    add_arguments(parser)
    args = parser.parse_args(command_line(values))
    return launch_options(args), args.domain_id if args.domain_id is not None else 0, bool(args.print_plan)


def process_env(plan: RunPlan, process: Any) -> dict[str, str]:
    """Environment additions of one process: the supervisor's defaults (unbuffered output,
    the Fast DDS profile unless the user set one, the domain), then the plan's, the
    side's and the process's own."""
    env = {"PYTHONUNBUFFERED": "1", "ROS_DOMAIN_ID": str(plan.domain_id)}
    env.update(profile_env(fastdds_profile(), os.environ))
    return {**env, **plan.env, **plan.sides[process.side].env, **process.env}


def process_action(plan: RunPlan, process: Any) -> Any:
    """The launch action of one process of ``plan`` (see the module docstring)."""
    from launch.actions import ExecuteProcess
    from launch_ros.actions import Node

    env = process_env(plan, process)
    output = "log" if process.progress else "screen"  # the recorders' progress lines go to the log
    exe = Path(process.argv[0]).name
    if len(process.nodes) == 1 and exe in ros_node_executables() and process.side == "local":
        node = process.nodes[0]
        params = {k: v for k, v in node.params.items() if not (isinstance(v, (list, tuple)) and not v)}
        return Node(package=PACKAGE, executable=exe, name=node.name, namespace=node.namespace,
                    parameters=[params], additional_env=env, output=output)
    return ExecuteProcess(cmd=list(process.argv), name=process.name.replace("/", "__"), additional_env=env,
                          output=output)


def plan_actions(plan: RunPlan) -> list[Any]:
    """Launch actions of ``plan``: its files, its processes in order, the exit rule, the time limit."""
    from launch.actions import EmitEvent, OpaqueFunction, RegisterEventHandler, TimerAction
    from launch.event_handlers import OnProcessExit, OnShutdown
    from launch.events import Shutdown

    if plan.setup or plan.optional_setup:
        raise LaunchError("the 'netns' network needs 'comems4build launch' (root, ip netns); "
                            "ros2 launch runs network 'local'")
    for p in plan.processes:
        for path, text in p.files:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            Path(path).write_text(text, encoding="utf-8")
    if len(plan.houses) > 1:
        plan.bag.mkdir(parents=True, exist_ok=True)
    for path, token in plan.secrets:
        write_token_file(path, token)

    def remove_secrets(event: Any, context: Any) -> None:
        for path, _token in plan.secrets:
            Path(path).unlink(missing_ok=True)

    state = {"over": False, "ended": set()}
    ending = [p.name for p in plan.processes if p.role in ("recorder", "container")] or [
        p.name for p in plan.processes if p.role == "plant"]

    def rule(process: Any) -> Any:
        def on_exit(event: Any, context: Any) -> Any:
            if state["over"] or context.is_shutdown:
                return None
            code = event.returncode
            if code != 0 or not process.finishes:
                state["over"] = True
                nodes = [node_label(n) for n in process.nodes]
                ran = f" (it ran {describe_nodes(nodes)})" if len(nodes) > 1 else ""
                raise LaunchError(f"run cut short: process '{process.name}' ({process.role}) exited with code {code} "
                                  f"({exit_meaning(code)}) while the run was in progress{ran}; the launch fails (its "
                                  "'cause:' line above says why)", process=process.name, code=code, nodes=nodes)
            state["ended"].add(process.name)
            if all(name in state["ended"] for name in ending):
                state["over"] = True
                return [EmitEvent(event=Shutdown(reason="run complete: every recorder has closed its bag"))]
            return None

        return on_exit

    def time_limit(context: Any) -> None:
        if not state["over"] and not context.is_shutdown:
            state["over"] = True
            raise LaunchError(f"run not finished within the time limit of {plan.timeout_s:g} s (timeout:=S sets it)")

    actions: list[Any] = [RegisterEventHandler(OnShutdown(on_shutdown=remove_secrets))]
    for p in plan.processes:
        action = process_action(plan, p)
        actions += [action, RegisterEventHandler(OnProcessExit(target_action=action, on_exit=rule(p)))]
    if plan.timeout_s is not None:
        actions.append(TimerAction(period=float(plan.timeout_s), actions=[OpaqueFunction(function=time_limit)]))
    return actions


def launch_description() -> Any:
    """The launch description of the launch file: :data:`ARGUMENTS` and the plan they give."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration

    def generate(context: Any) -> list[Any]:
        values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
        opts, domain_id, print_plan = options_of(values)
        plan = plan_run(opts, domain_id)
        if print_plan:
            print(plan.describe(), flush=True)
            return []
        print(f"comems4build: {len(plan.processes)} process(es), bag {plan.bag}; evaluate with: comems4build "
              f"evaluate {shlex.quote(str(plan.bag))} --out {shlex.quote(str(plan.out))}", flush=True)
        return plan_actions(plan)

    declared = [DeclareLaunchArgument(name, default_value=default, description=text)
                for name, (default, text, _option) in ARGUMENTS.items()]
    return LaunchDescription([*declared, OpaqueFunction(function=generate)])
