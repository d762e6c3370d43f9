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
DDS profile, as the supervisor gives it). Besides the launcher's arguments, the file takes
``use_sim_time`` (a launch-wide ``SetParameter``) and ``log_level`` (every node's
``--log-level``); a process of several nodes (a container) gets these and any launch-wide
parameter of an including launch file on its command line, since ``launch_ros`` gives them
to ``Node`` actions only. Errors speak of ``name:=value`` and end the launch with exit
code 2 before anything starts.

The exit rule is the supervisor's (:mod:`comems4build_ros.run.supervisor`): the run is
done when every recorder process has exited 0 (the bags are closed), and then the launch
shuts down; any other exit while the run is in progress (a node that fails, is stopped
by a signal before the end of its run, ends a stalled run naming the silent node, or a
process that may not end by itself), or the plan's time limit, ends the launch at once
with an error naming the process, its exit code and what it means
(:mod:`comems4build_ros.wire.exits`), so ``ros2 launch`` exits non-zero. As with the
supervisor, a process whose run was complete (its ``cleaning up: exit code 0`` line on
stderr) and whose clean-up then hung until its C-level watchdog ended it with code 1 is a
completed process, with a warning. The run tokens
are written as the supervisor writes them (mode 0600 in ``<out>/.secrets``, mode 0700)
and removed, with their directory, when the launch shuts down. Evaluate the bag afterwards with ``comems4build
evaluate BAG --out DIR``.

``launch`` and ``launch_ros`` are imported inside the functions: the package itself does
not need them (they come with a ROS 2 install).
"""

from __future__ import annotations

import os
import shlex
import sys
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.run.plan import (
    LaunchOptions,
    RunPlan,
    discovery_hint,
    fastdds_profile,
    node_label,
    plan_run,
    profile_env,
    ros_node_executables,
)
from comems4build_ros.run.supervisor import LaunchError, describe_nodes, remove_secrets, write_plan_files, write_secrets
from comems4build_ros.wire.exits import HangWatch, exit_meaning

PACKAGE = "comems4build_ros"
#: Launch arguments: name -> (default, description, ``comems4build launch`` option). A list
#: option (``--config``, ``--set``, ``--ems-option``) takes ``;``-separated items; an
#: argument without an option is the launch's own (:data:`NODE_ARGUMENTS`).
ARGUMENTS: dict[str, tuple[str, str, str]] = {
    "ems": ("fuzzy", "EMS node: fuzzy, rbc, mpc (also thermostat, mpc-qp)", "--ems"),
    "scenario": ("default", "'default', 'year', 'synthetic' or a scenario CSV path", "--scenario"),
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
    "plant": ("sim", "sim: plant_sim on ROS; mqtt: the simulated house behind MQTT via mqtt_bridge", "--plant"),
    "clock": ("sim", "sim (lock-step), wall (a step per hour) or wall:<factor>; wall needs plant:=mqtt", "--clock"),
    "broker": ("", "MQTT broker mqtt[s]://host:port of plant:=mqtt (empty = an embedded one)", "--broker"),
    "topic_map": ("", "MQTT topic map of plant:=mqtt (empty = config/mqtt.yaml)", "--topic-map"),
    "inputs": ("scenario", "feed inputs: scenario or live (aWATTar prices, weather)", "--inputs"),
    "live_config": ("", "live-input settings of inputs:=live (empty = config/live_inputs.yaml)", "--live-config"),
    "network": ("local", "local only here ('netns' needs root and comems4build launch)", "--network"),
    "out": ("comems4build_run", "output directory (bag, parameter and spec files)", "--out"),
    "bag": ("", "bag directory to create (empty = <out>/bag)", "--bag"),
    "domain": ("", "ROS_DOMAIN_ID of every process (empty = the environment's, else 0)", "--domain-id"),
    "print_plan": ("false", "print the run plan and exit without starting anything", "--print-plan"),
    "use_sim_time": ("false", "every node's clock follows /clock (a launch-wide SetParameter)", ""),
    "log_level": ("info", "log level of every node: debug (the lock-step protocol), info, warn, error or fatal",
                  ""),
}
#: Arguments that are flags of ``comems4build launch`` (true/false).
FLAG_ARGUMENTS = ("all_inputs", "print_plan")
#: Arguments holding several items, separated by ``;``.
LIST_ARGUMENTS = ("config", "set", "ems_options")
#: The launch's own arguments, handed to every node (not options of ``comems4build launch``).
NODE_ARGUMENTS = ("use_sim_time", "log_level")
#: Values of ``log_level`` (rcutils' severities, as ``--ros-args --log-level`` takes them).
LOG_LEVELS = ("debug", "info", "warn", "error", "fatal")
#: Values of a true/false argument.
BOOLEAN_WORDS = {"true": True, "false": False}


class LaunchArgumentError(InputError):
    """A launch argument the launch refuses (the message speaks of ``name:=value``)."""


def command_line(values: dict[str, str]) -> list[str]:
    """The ``comems4build launch`` arguments of the launch arguments ``values`` (strings).

    Raises
    ------
    LaunchArgumentError
        For a flag that is neither ``true`` nor ``false``.
    """
    argv: list[str] = []
    for name, (default, _help, option) in ARGUMENTS.items():
        value = str(values.get(name, default)).strip()
        if not option:
            continue
        if name in FLAG_ARGUMENTS:
            if flag(name, value):
                argv.append(option)
            continue
        if name == "domain" and not value:
            value = os.environ.get("ROS_DOMAIN_ID", "")
        items = [v.strip() for v in value.split(";") if v.strip()] if name in LIST_ARGUMENTS else [value]
        for item in items:
            if item:
                argv += [option, item]
    return argv


def flag(name: str, value: str) -> bool:
    """A true/false launch argument (LaunchArgumentError for anything else)."""
    word = value.strip().lower()
    if word not in BOOLEAN_WORDS:
        raise LaunchArgumentError(f"{name}:={value}: expected true or false")
    return BOOLEAN_WORDS[word]


def in_launch_words(message: str, values: dict[str, str]) -> str:
    """``message`` of the command's parser and checks with each ``--option [VALUE]`` written as
    the launch argument ``name:=VALUE`` (``argument --weeks: ...`` -> ``weeks:=abc: ...``)."""
    import re

    words = {"and", "or", "is", "are", "need", "needs", "must", "with", "without", "not", "of", "for", "as"}

    def launch_form(m: re.Match[str], name: str) -> str:
        value = m.group(1) or ""
        if value.strip() in words:
            return f"{name}:={value}"
        return f"{name}:={value.strip()}"

    for name, (_default, _help, option) in ARGUMENTS.items():
        if not option:
            continue
        given = str(values.get(name, "")).strip()
        message = re.sub(rf"argument {re.escape(option)}(?:/\S+)?: ", f"{name}:={given}: ", message)
        message = re.sub(rf"(?<![\w-]){re.escape(option)}(?![\w-])( [\w][\w:./-]*)?",
                         lambda m, n=name: launch_form(m, n), message)
    return message


def options_of(values: dict[str, str]) -> tuple[LaunchOptions, int, bool]:
    """Launch options, domain id and ``print_plan`` of the launch arguments ``values``.

    Raises
    ------
    LaunchArgumentError
        From the command's parser and checks (:func:`comems4build_ros.app.commands.launch.launch_options`),
        in launch words: ``weeks:=abc``, not ``--weeks``.
    """
    import argparse

    from comems4build_ros.app.commands.launch import add_arguments, launch_options

    class Parser(argparse.ArgumentParser):
        def error(self, message: str) -> Any:  # noqa: D102 (argparse's: raise instead of printing the usage)
            raise LaunchArgumentError(message)

    parser = Parser(prog="comems4build.launch.py", add_help=False)
    add_arguments(parser)
    try:
        args = parser.parse_args(command_line(values))
        opts = launch_options(args)
    except (InputError, FileNotFoundError) as exc:  # only the checks' errors: a bug stays a bug
        raise LaunchArgumentError(in_launch_words(str(exc), values)) from None
    return opts, args.domain_id if args.domain_id is not None else 0, bool(args.print_plan)


def node_arguments(values: dict[str, str]) -> tuple[bool, str]:
    """``use_sim_time`` and ``log_level`` of the launch arguments ``values`` (LaunchArgumentError)."""
    sim = flag("use_sim_time", str(values.get("use_sim_time", "false")))
    level = str(values.get("log_level", "info")).strip().lower()
    if level not in LOG_LEVELS:
        raise LaunchArgumentError(f"log_level:={values.get('log_level')}: one of {', '.join(LOG_LEVELS)}")
    return sim, level


def unknown_arguments(argv: list[str]) -> list[str]:
    """A warning for each ``name:=value`` of the command line that is no argument of this launch
    file (nearest name suggested). A warning, not a refusal: a parent launch file including this
    one has arguments of its own on the same command line."""
    from comems4build_ros.ros.parameters import nearest

    names = [a.split(":=", 1)[0] for a in argv if ":=" in a]
    return [f"launch argument '{n}' is not one of comems4build.launch.py{nearest(n, list(ARGUMENTS))}; ignored "
            "(ros2 launch comems4build_ros comems4build.launch.py --show-args lists them)"
            for n in names if n not in ARGUMENTS]


def process_env(plan: RunPlan, process: Any) -> dict[str, str]:
    """Environment additions of one process: the supervisor's defaults (unbuffered output,
    the Fast DDS profile unless the user set one, the domain), then the plan's, the
    side's and the process's own."""
    env = {"PYTHONUNBUFFERED": "1", "ROS_DOMAIN_ID": str(plan.domain_id)}
    env.update(profile_env(fastdds_profile(), os.environ))
    return {**env, **plan.env, **plan.sides[process.side].env, **process.env}


def process_action(plan: RunPlan, process: Any, global_params: list[Any], log_level: str) -> Any:
    """The launch action of one process of ``plan`` (see the module docstring).

    ``global_params``: the launch-wide parameters (``SetParameter``: ``(name, value)``;
    ``SetParametersFromFile``: a path), which ``launch_ros`` gives every ``Node`` itself and
    this gives every other process of ROS nodes on its command line; ``log_level``: every
    node's ``--log-level``.
    """
    from launch.actions import ExecuteProcess
    from launch_ros.actions import Node

    env = process_env(plan, process)
    output = "log" if process.progress else "screen"  # the recorders' progress lines go to the log
    exe = Path(process.argv[0]).name
    level = ["--log-level", log_level]
    if len(process.nodes) == 1 and exe in ros_node_executables() and process.side == "local":
        node = process.nodes[0]
        params = {k: v for k, v in node.params.items() if not (isinstance(v, (list, tuple)) and not v)}
        return Node(package=PACKAGE, executable=exe, name=node.name, namespace=node.namespace,
                    parameters=[params], additional_env=env, output=output, ros_arguments=level)
    cmd = list(process.argv)
    if process.nodes:  # a process of ROS nodes (a container): the launch-wide settings as global ROS arguments
        cmd += ["--ros-args", *level]
        for item in global_params:
            cmd += ["-p", f"{item[0]}:={item[1]}"] if isinstance(item, tuple) else ["--params-file", str(item)]
    return ExecuteProcess(cmd=cmd, name=process.name.replace("/", "__"), additional_env=env, output=output)


def plan_actions(plan: RunPlan, global_params: list[Any] | None = None, log_level: str = "info") -> list[Any]:
    """Launch actions of ``plan``: its files, its processes in order (with the launch-wide
    parameters and log level, :func:`process_action`), the exit rule, the time limit."""
    from launch.actions import EmitEvent, OpaqueFunction, RegisterEventHandler, TimerAction
    from launch.event_handlers import OnProcessExit, OnProcessIO, OnShutdown
    from launch.events import Shutdown

    if plan.setup or plan.optional_setup:
        raise LaunchError("network:=netns needs 'comems4build launch --network netns' (root, ip netns); "
                          "ros2 launch runs network:=local")
    write_plan_files(plan)
    if len(plan.houses) > 1:  # the bags hold the run tokens (ems/command): this user's, never through a link
        from comems4build_ros.files.outputs import open_dir

        os.close(open_dir(plan.bag, create=True, private=True, what="the folder of the run's bags"))
    write_secrets(plan)

    state = {"over": False, "ended": set()}
    ending = [p.name for p in plan.processes if p.role in ("recorder", "container")] or [
        p.name for p in plan.processes if p.role == "plant"]

    def rule(process: Any) -> Any:
        def on_exit(event: Any, context: Any) -> Any:
            if state["over"] or context.is_shutdown:
                return None
            code = event.returncode
            if code == 1 and watches[process.name].decided() == 0:
                # its run was complete, then the clean-up hung in native code and the backstop ended it
                print(f"[WARNING] [launch]: process '{process.name}' had finished its run (exit code 0) but its "
                      "clean-up hung and its watchdog ended it (the stacks are above)", file=sys.stderr, flush=True)
                code = 0
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

    def follow(watch: HangWatch) -> Any:
        def on_stderr(event: Any) -> None:
            watch.feed(event.text.decode("utf-8", "replace"))

        return on_stderr

    watches = {p.name: HangWatch() for p in plan.processes}
    actions: list[Any] = [RegisterEventHandler(OnShutdown(on_shutdown=lambda event, context: remove_secrets(plan)))]
    for p in plan.processes:
        action = process_action(plan, p, list(global_params or []), log_level)
        actions += [action, RegisterEventHandler(OnProcessExit(target_action=action, on_exit=rule(p))),
                    RegisterEventHandler(OnProcessIO(target_action=action, on_stderr=follow(watches[p.name])))]
    if plan.timeout_s is not None:
        actions.append(TimerAction(period=float(plan.timeout_s), actions=[OpaqueFunction(function=time_limit)]))
    return actions


def launch_description() -> Any:
    """The launch description of the launch file: :data:`ARGUMENTS` and the plan they give.

    A refused argument ends ``ros2 launch`` with exit code 2 and one line naming it as
    ``name:=value``; an argument this file does not have is warned about (see
    :func:`unknown_arguments`).
    """
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import SetParameter

    def generate(context: Any) -> list[Any]:
        for warning in unknown_arguments(list(getattr(context, "argv", []) or [])):
            print(f"comems4build.launch.py: warning: {warning}", file=sys.stderr, flush=True)
        values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
        try:
            sim, log_level = node_arguments(values)
            opts, domain_id, print_plan = options_of(values)
            plan = plan_run(opts, domain_id)
            if plan.setup and not print_plan:
                raise LaunchArgumentError("network:=netns needs 'comems4build launch --network netns' (root, ip "
                                          "netns); ros2 launch runs network:=local (print_plan:=true shows the plan)")
        except LaunchArgumentError as exc:
            print(f"comems4build.launch.py: error: {exc}", file=sys.stderr, flush=True)
            raise SystemExit(2) from None
        if print_plan:
            print(plan.describe(), flush=True)
            return []
        print(f"comems4build: {len(plan.processes)} process(es), bag {plan.bag}; evaluate with: comems4build "
              f"evaluate {shlex.quote(str(plan.bag))} --out {shlex.quote(str(plan.out))}", flush=True)
        if plan.discovery_server:
            print(f"comems4build: {discovery_hint(plan.discovery_server)}", flush=True)
        before: list[Any] = [SetParameter(name="use_sim_time", value=True)] if sim else []
        global_params = [*context.launch_configurations.get("global_params", []),
                         *([("use_sim_time", True)] if sim else [])]
        return [*before, *plan_actions(plan, global_params, log_level)]

    declared = [DeclareLaunchArgument(name, default_value=default, description=text)
                for name, (default, text, _option) in ARGUMENTS.items()]
    return LaunchDescription([*declared, OpaqueFunction(function=generate)])
