"""The run plan as a ROS 2 launch description (``ros2 launch comems4build_ros comems4build.launch.py``).

The launch file takes the arguments of ``comems4build launch`` (:data:`ARGUMENTS`), turns
them into that command's options with the command's own parser and checks
(:func:`comems4build_ros.app.commands.launch.launch_options`) and builds the very same
:class:`~comems4build_ros.run.plan.RunPlan` (:func:`~comems4build_ros.run.plans.plan_any`);
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

The file composes into a user's own launch (:class:`LaunchedRun`): it honours the
namespace an including file pushed (:func:`placed`), and each inclusion is a run of its own
(its plan, run id, tokens, bag) that ends its own processes only. The exit rule of each run is
the supervisor's (:mod:`comems4build_ros.run.supervisor`): the run is complete when every
recorder process has exited 0 (the bags are closed); any other exit while the run is in
progress (a node that fails, is stopped by a signal before the end of its run, ends a stalled
run naming the silent node, or a process that may not end by itself), the plan's time limit,
or the launch shutting down first, cuts it, with an error naming the process, its exit code
and what it means (:mod:`comems4build_ros.wire.exits`); ``ros2 launch`` then exits 1 when it
ends (:func:`fail_launch`). As with the supervisor, a process whose run was complete (its
``cleaning up: exit code 0`` line on stderr) and whose clean-up then hung until its C-level
watchdog ended it with code 1 is a completed process, with a warning. The run tokens are
written as the supervisor writes them (mode 0600 in ``<out>/.secrets``, mode 0700) and
removed, with their directory, when the run ends, the launch shuts down or ``ros2 launch``
exits (also after SIGTERM, :func:`watch_stop_signals`). Evaluate the bag afterwards with
``comems4build evaluate BAG --out DIR``.

``launch`` and ``launch_ros`` are imported inside the functions: the package itself does
not need them (they come with a ROS 2 install).
"""

from __future__ import annotations

import contextlib
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
    profile_env,
    ros_node_executables,
)
from comems4build_ros.run.plans import plan_any
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
    "namespace": ("", "namespace of the house (one house) or of the houses: absolute, or relative to the namespace "
                  "an including file pushed (empty = that namespace, else /)", "--namespace"),
    "layout": ("", "processes: node, house or role (empty = the default for the house count)", "--layout"),
    "containers": ("", "container processes of layout 'house' (empty = one per core)", "--containers"),
    "config": ("", "parameter files merged over config/plant.yaml, ';'-separated", "--config"),
    "set": ("", "plant parameter overrides KEY=VALUE, ';'-separated", "--set"),
    "ems_options": ("", "EMS options KEY=VALUE, ';'-separated", "--ems-option"),
    "forecast": ("", "forecasts of the MPC: perfect, imperfect or realistic (empty = config/forecast.yaml)",
                 "--forecast"),
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
    "out": ("", "output directory (bag, parameter and spec files; empty = comems4build_run, under a namespace an "
                "including file pushed comems4build_run/<namespace>)", "--out"),
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

    # an alternative the launch file does not offer (``or --community``: a way of comems4build
    # launch only) is left out rather than named in words no launch argument has
    offered = {option for _default, _help, option in ARGUMENTS.values() if option}
    message = re.sub(r" or (--[\w-]+)", lambda m: m.group(0) if m.group(1) in offered else "", message)
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


#: Output directory of a run whose ``out`` is empty (:func:`placed`).
DEFAULT_OUT = "comems4build_run"


def placed(values: dict[str, str], pushed: str | None) -> dict[str, str]:
    """``namespace`` and ``out`` of the launch arguments ``values`` in an including file's namespace.

    ``pushed`` is the namespace an including launch file pushed (``PushRosNamespace``, its
    ``ros_namespace`` launch configuration; None: none). As with a ``Node``, a relative
    ``namespace`` (or none) lies under it and an absolute one does not. An empty ``out`` is
    :data:`DEFAULT_OUT`, under a pushed namespace ``DEFAULT_OUT/<namespace>``, so that each
    inclusion of the file writes its own run. The plan checks the namespace
    (:func:`~comems4build_ros.run.plan.namespaces`).
    """
    given = str(values.get("namespace", "")).strip()
    base = (pushed or "").strip().strip("/")
    if given.startswith("/"):
        ns = given
    else:
        ns = "/" + "/".join(part for part in (base, given.strip("/")) if part)
    out = str(values.get("out", "")).strip()
    if not out:
        out = f"{DEFAULT_OUT}/{base}" if base else DEFAULT_OUT
    return {"namespace": ns, "out": out}


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


#: How long a stop of the launch by SIGTERM waits for the run's processes after its SIGINT
#: before it kills them [s] (:func:`_end_on_exit`); their own clean-up takes about 1 s.
STOP_GRACE_S = 2.5


class LaunchedRun:
    """One inclusion of the launch file: its run, its processes and its outcome in ``ros2 launch``.

    The launch file can be included any number of times in one launch (each inclusion builds
    its own plan: run tokens, bag, output directory); each inclusion's processes follow its own
    exit rule and end with its run, never with another's, and the launch goes on as long as
    anything else of it runs (another inclusion, the user's own nodes):

    * the run is **complete** when every recorder process (or container) has exited 0 (the
      bags are closed): the run's other processes end (``ShutdownProcess`` of its own
      actions only) and its token files are removed;
    * the run is **cut** when one of its processes exits otherwise while the run is in
      progress (a failure, a signal before the end of its run, a stalled run, or a process
      that may not end by itself), when its time limit passes, or when the launch shuts down
      before the run is complete (Ctrl-C, another action's ``Shutdown``): the error names the
      process, its exit code and what it means (:mod:`comems4build_ros.wire.exits`), the run's
      processes end, its bag is marked (:data:`~comems4build_ros.bags.evaluation.RUN_CUT_FILE`)
      once they have, and its token files are removed.

    When the launch ends, ``ros2 launch`` exits 1 if any inclusion's run was cut (one line per
    cut run), else with launch's own code (0). A stop signal ends the run's processes too: on
    SIGINT to ``ros2 launch`` alone (not its process group) each gets SIGINT at once rather than
    launch's SIGTERM 5 s later; on SIGTERM, which ends launch's loop without stopping anything
    (launch warns of orphaned processes), each gets SIGINT as ``ros2 launch`` exits and SIGKILL
    :data:`STOP_GRACE_S` later, and the token files are removed.
    """

    def __init__(self, plan: RunPlan) -> None:
        self.plan = plan
        #: None while the run is in progress, then ``"complete"`` or the cut's message
        self.outcome: str | None = None
        self.actions: dict[str, Any] = {}  # process name -> launch action
        self.running: dict[str, int] = {}  # process name -> pid, while it runs
        self.ended: set[str] = set()  # processes that exited 0 as the run asks
        self.cut_info: dict[str, Any] = {}
        self.timer: Any = None
        self.signalled: set[int] = set()  # pids sent SIGINT by stop()
        self.watches = {p.name: HangWatch() for p in plan.processes}
        self.ending = [p.name for p in plan.processes if p.role in ("recorder", "container")] or [
            p.name for p in plan.processes if p.role == "plant"]
        self.where = f"run in {plan.houses[0].namespace if len(plan.houses) == 1 else describe_houses(plan)} " \
                     f"(bag {plan.bag})"

    # ------------------------------------------------------------------ outcome
    def _end_own(self) -> list[Any]:
        """Launch events ending this run's processes that still run (its own, no other)."""
        from launch.actions import EmitEvent
        from launch.events import matches_action
        from launch.events.process import ShutdownProcess

        remove_secrets(self.plan)
        if self.timer is not None:
            self.timer.cancel()
        # every action of the run (one that has not started yet is kept from starting; one that
        # has ended is left alone), never another's
        return [EmitEvent(event=ShutdownProcess(process_matcher=matches_action(action)))
                for action in self.actions.values()]

    def complete(self) -> list[Any]:
        """Every recorder has closed its bag: end the run's remaining processes."""
        self.outcome = "complete"
        log_line("info", f"{self.where}: complete: every recorder has closed its bag")
        return self._end_own()

    def cut(self, message: str, process: str | None = None, code: int | None = None,
            nodes: tuple[str, ...] = ()) -> list[Any]:
        """The run is cut short (``message``): say so, end its processes."""
        self.outcome = message
        self.cut_info = {"cause": message, "process": process, "exit_code": code, "log": None, "nodes": list(nodes)}
        log_line("error", f"{self.where}: {message}")
        actions = self._end_own()
        self._mark_when_ended()
        return actions

    def _mark_when_ended(self) -> None:
        """Once a cut run's processes have all ended (its recorders closed their bags), mark its bag."""
        if self.outcome in (None, "complete") or self.running or not self.cut_info:
            return
        from comems4build_ros.bags.evaluation import mark_run_cut

        try:
            mark_run_cut(self.plan.bag, self.cut_info)
        except OSError as err:
            log_line("error", f"{self.where}: the cut run's bag could not be marked: {err.filename or ''} "
                              f"{err.strerror or err}")
        self.cut_info = {}

    # ------------------------------------------------------------------ launch handlers
    def on_start(self, process: Any) -> Any:
        """OnProcessStart: note the pid (a stop signal of the launch reaches it, :meth:`stop`)."""

        def started(event: Any, context: Any) -> None:
            self.running[process.name] = int(event.pid)

        return started

    def on_exit(self, process: Any) -> Any:
        """OnProcessExit of one process: the exit rule (see the class docstring)."""

        def exited(event: Any, context: Any) -> Any:
            self.running.pop(process.name, None)
            code = event.returncode
            if code == 1 and self.watches[process.name].decided() == 0:
                # its run was complete, then the clean-up hung in native code and the backstop ended it
                log_line("warning", f"process '{process.name}' had finished its run (exit code 0) but its clean-up "
                                    "hung and its watchdog ended it (the stacks are above)")
                code = 0
            if self.outcome is not None:
                self._mark_when_ended()
                return None
            if code != 0 or not process.finishes:
                nodes = tuple(node_label(n) for n in process.nodes)
                ran = f" (it ran {describe_nodes(list(nodes))})" if len(nodes) > 1 else ""
                return self.cut(f"run cut short: process '{process.name}' ({process.role}) exited with code {code} "
                                f"({exit_meaning(code)}) while the run was in progress{ran}; its 'cause:' line above "
                                "says why", process.name, code, nodes)
            self.ended.add(process.name)
            if all(name in self.ended for name in self.ending):
                return self.complete()
            return None

        return exited

    def on_stderr(self, process: Any) -> Any:
        """OnProcessIO (stderr): what the process decided before a hung clean-up (:class:`HangWatch`)."""
        watch = self.watches[process.name]

        def heard(event: Any) -> None:
            watch.feed(event.text.decode("utf-8", "replace"))

        return heard

    def time_limit(self, context: Any) -> Any:
        """The plan's time limit passed with the run in progress: it is cut."""
        if self.outcome is None:
            return self.cut(f"run not finished within the time limit of {self.plan.timeout_s:g} s "
                            "(timeout:=S sets it)")
        return None

    def on_shutdown(self, event: Any, context: Any) -> Any:
        """The launch shuts down: a run still in progress is cut; its processes get SIGINT at once
        if the launch got it (launch signals them only 5 s later when the signal did not reach
        them from the terminal); a cut run makes ``ros2 launch`` exit 1 (:func:`fail_launch`)."""
        if self.outcome is None:
            reason = getattr(event, "reason", "") or "shutdown"
            self.cut(f"run cut short: the launch was shut down ({reason}) before the run was complete")
        if getattr(event, "due_to_sigint", False):
            self.stop(signal_only=True)
        remove_secrets(self.plan)
        if self.outcome != "complete":
            fail_launch(context, f"{self.where}: {self.outcome}")
        return None

    def stop(self, signal_only: bool = False) -> None:
        """SIGINT to this run's running processes; unless ``signal_only``, wait up to
        :data:`STOP_GRACE_S` for them and SIGKILL what is left; then remove the token files."""
        import signal
        import time

        pids = list(self.running.values())
        for pid in pids:
            if pid not in self.signalled:  # once: a second SIGINT is a second Ctrl-C to the node
                self.signalled.add(pid)
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.kill(pid, signal.SIGINT)
        if not signal_only:
            deadline = time.monotonic() + STOP_GRACE_S
            while any(alive(pid) for pid in pids) and time.monotonic() < deadline:
                time.sleep(0.02)
            for pid in pids:
                if alive(pid):
                    with contextlib.suppress(ProcessLookupError, PermissionError):
                        os.kill(pid, signal.SIGKILL)
        remove_secrets(self.plan)

    def actions_of(self, global_params: list[Any], log_level: str) -> list[Any]:
        """Launch actions of the run: its processes in order (with the launch-wide parameters and
        log level, :func:`process_action`), their handlers, the time limit."""
        from launch.actions import OpaqueFunction, RegisterEventHandler, TimerAction
        from launch.event_handlers import OnProcessExit, OnProcessIO, OnProcessStart, OnShutdown

        out: list[Any] = [RegisterEventHandler(OnShutdown(on_shutdown=self.on_shutdown))]
        for p in self.plan.processes:
            action = self.actions[p.name] = process_action(self.plan, p, global_params, log_level)
            out += [RegisterEventHandler(OnProcessStart(target_action=action, on_start=self.on_start(p))),
                    RegisterEventHandler(OnProcessExit(target_action=action, on_exit=self.on_exit(p))),
                    RegisterEventHandler(OnProcessIO(target_action=action, on_stderr=self.on_stderr(p))), action]
        if self.plan.timeout_s is not None:
            self.timer = TimerAction(period=float(self.plan.timeout_s), actions=[OpaqueFunction(
                function=self.time_limit)])
            out.append(self.timer)
        return out


def describe_houses(plan: RunPlan) -> str:
    """``/house_0 .. /house_3`` for a plan of several houses."""
    return f"{plan.houses[0].namespace} .. {plan.houses[-1].namespace}"


def alive(pid: int) -> bool:
    """Whether process ``pid`` still runs (not gone, not a zombie; Linux ``/proc``)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rpartition(")")[2].split()[0] != "Z"


def log_line(level: str, text: str) -> None:
    """One line of launch's log (screen and log file), as ``comems4build.launch.py``."""
    import launch.logging

    getattr(launch.logging.get_logger("comems4build.launch.py"), level)(text)


def fail_launch(context: Any, message: str) -> None:
    """Make ``ros2 launch`` exit 1, saying ``message``, without ending anything.

    launch's exit code is 1 after an error reported to its event loop's exception handler
    (``loop.call_exception_handler``, which launch's run sets to count it); an exception raised
    in an event handler instead would also shut the whole launch down at once, and leave the
    other handlers of the event unrun.
    """
    context.asyncio_loop.call_exception_handler({"message": f"comems4build.launch.py: {message}"})


#: The runs of this ``ros2 launch`` process, by output directory (one per inclusion).
RUNS: dict[Path, LaunchedRun] = {}


def _on_sigterm(signum: int, frame: Any) -> None:
    """SIGTERM to ``ros2 launch``: SIGINT to every run's processes at once (see :func:`watch_stop_signals`)."""
    log_line("warning", "SIGTERM: every run's processes get SIGINT (their runs are cut)")
    for run in RUNS.values():
        run.stop(signal_only=True)
    previous = _PREVIOUS_SIGTERM[0] if _PREVIOUS_SIGTERM else None
    if callable(previous):
        previous(signum, frame)


#: The SIGTERM handler this module's replaced (called after its own).
_PREVIOUS_SIGTERM: list[Any] = []


def watch_stop_signals() -> None:
    """Make ``ros2 launch`` end the runs' processes on SIGTERM, and at its exit.

    launch handles SIGTERM through its signal wake-up descriptor only; with no Python handler
    for SIGTERM in the process (none without a ROS 2 install's rclpy signal handlers) the
    signal kills ``ros2 launch`` outright, its processes left orphaned and the token files
    behind. A Python handler (:func:`_on_sigterm`, chained to any earlier one) sends the runs'
    processes SIGINT and lets launch's own SIGTERM handling go on (it leaves its loop), and
    :func:`_end_on_exit` at the interpreter's exit waits for them and removes the token files.
    """
    import atexit
    import signal
    import threading

    atexit.register(_end_on_exit)
    if threading.current_thread() is threading.main_thread():
        _PREVIOUS_SIGTERM.append(signal.signal(signal.SIGTERM, _on_sigterm))


def _end_on_exit() -> None:
    """At the exit of ``ros2 launch``: end every run's processes still running, remove the token files.

    After SIGTERM launch leaves its loop without stopping its processes; this stops them
    (SIGINT, then SIGKILL :data:`STOP_GRACE_S` later) as the interpreter exits.
    """
    for run in RUNS.values():
        run.stop()


def plan_actions(plan: RunPlan, global_params: list[Any] | None = None, log_level: str = "info") -> list[Any]:
    """Launch actions of ``plan``: its files, its processes in order (with the launch-wide
    parameters and log level, :func:`process_action`), its exit rule and time limit
    (:class:`LaunchedRun`).

    Raises
    ------
    LaunchError
        For a plan ``ros2 launch`` cannot run (``network:=netns``).
    LaunchArgumentError
        For a plan whose output directory another inclusion of the same launch writes.
    """
    if plan.setup or plan.optional_setup:
        raise LaunchError("network:=netns needs 'comems4build launch --network netns' (root, ip netns); "
                          "ros2 launch runs network:=local")
    out = Path(plan.out).resolve()
    if out in RUNS:
        raise LaunchArgumentError(f"out:={plan.out}: another inclusion of comems4build.launch.py in this launch "
                                  "writes there; give each inclusion its own out:= (or namespace)")
    write_plan_files(plan)
    if len(plan.houses) > 1:  # the bags hold the run tokens (ems/command): this user's, never through a link
        from comems4build_ros.files.outputs import open_dir

        os.close(open_dir(plan.bag, create=True, private=True, what="the folder of the run's bags"))
    write_secrets(plan)
    if not RUNS:
        watch_stop_signals()
    run = RUNS[out] = LaunchedRun(plan)
    return run.actions_of(list(global_params or []), log_level)


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
        pushed = context.launch_configurations.get("ros_namespace")
        try:
            values.update(placed(values, pushed))
            sim, log_level = node_arguments(values)
            opts, domain_id, print_plan = options_of(values)
            plan = plan_any(opts, domain_id)
            if plan.setup and not print_plan:
                raise LaunchArgumentError("network:=netns needs 'comems4build launch --network netns' (root, ip "
                                          "netns); ros2 launch runs network:=local (print_plan:=true shows the plan)")
            if print_plan:
                print(plan.describe(), flush=True)
                return []
            global_params = [*context.launch_configurations.get("global_params", []),
                             *([("use_sim_time", True)] if sim else [])]
            actions = plan_actions(plan, global_params, log_level)
        except LaunchArgumentError as exc:
            print(f"comems4build.launch.py: error: {exc}", file=sys.stderr, flush=True)
            raise SystemExit(2) from None
        print(f"comems4build: {len(plan.processes)} process(es), bag {plan.bag}; evaluate with: comems4build "
              f"evaluate {shlex.quote(str(plan.bag))} --out {shlex.quote(str(plan.out))}", flush=True)
        if plan.discovery_server:
            print(f"comems4build: {discovery_hint(plan.discovery_server)}", flush=True)
        before: list[Any] = [SetParameter(name="use_sim_time", value=True)] if sim else []
        return [*before, *actions]

    declared = [DeclareLaunchArgument(name, default_value=default, description=text)
                for name, (default, text, _option) in ARGUMENTS.items()]
    return LaunchDescription([*declared, OpaqueFunction(function=generate)])
