"""The plan of a launch: which nodes run, in which process and on which network side, with what.

A :class:`RunPlan` is plain data, built by :func:`plan_run` from the
:class:`LaunchOptions` of ``comems4build launch`` without starting anything: the
houses (namespace, scenario seed, bag directory), the network sides (where a set of
processes runs: this machine as it is, or a network namespace with its own address), and
the processes (command line, the nodes each runs with their namespace and parameters,
the files to write before the start, environment additions, and the exit rule). The
supervisor (:mod:`comems4build_ros.run.supervisor`) starts and watches any plan; the
launcher (:mod:`comems4build_ros.run.launcher`) joins the two and evaluates the bag.

Every way to run is an option of the plan, never a branch through the supervisor:

* ``layout``: ``node`` (one OS process per node, the default for one house),
  ``house`` (``containers`` container processes, one per core by default, each
  running every node, recorder included, of its share of the houses: ROS 2
  composition; the default for more houses) or ``role`` (one process per role
  running that role's nodes of every house, recorders split by
  ``houses_per_recorder``; the default for more houses on the ``netns`` network);
  see :mod:`comems4build_ros.ros.container`;
* ``discovery_server``: a Fast DDS discovery server process and ``ROS_DISCOVERY_SERVER``
  in every other process's environment;
* ``plant``: ``sim`` (``plant_sim`` on ROS) or ``mqtt``: the house behind MQTT, i.e.
  an embedded amqtt broker process (unless ``broker_url``), ``mqtt_plant`` (the simulated
  house) and ``mqtt_bridge`` in ``plant_sim``'s place, the feed with
  ``publish_measured:=false`` (docs/real_building.md);
* ``clock``: ``sim``, ``wall`` or ``wall:<factor>`` for the bridge and the house
  (wall modes with ``plant="mqtt"`` only);
* ``inputs``: ``scenario`` or ``live`` (the feed's live prices and weather);
* ``community``: a community of houses sharing one H2 hub (:mod:`comems4build_ros.run.community`):
  every house of the community file with its node set in its namespace, plus the coordinator
  node of ``coordinator`` and its recorder;
* ``network``: ``local`` (every process on this machine as it is) or ``netns`` (separate
  network sides: plant and feed in one Linux network namespace, EMS and recorder in another,
  joined by a veth pair; UDP only, unicast discovery through ``ROS_STATIC_PEERS``;
  optionally ``netem`` delay and loss on the link). The plan carries the commands that
  set the namespaces up and tear them down; the supervisor runs them. With
  ``plant="mqtt"`` the embedded broker, the house and the bridge are on the plant's side.

``RunPlan.describe()`` prints the plan (``comems4build launch --print-plan``); the tests
check plans without processes.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.paths import shared_path
from comems4build_ros.wire.contract import CLOCK_TOPIC
from comems4build_ros.wire.tokens import new_token

#: Console script of each node and the module run with ``python -m`` when there is none.
NODE_MODULES: dict[str, str] = {
    "plant_sim": "comems4build_ros.ros.nodes.plant_sim",
    "feed": "comems4build_ros.ros.nodes.feed",
    "recorder": "comems4build_ros.ros.nodes.recorder",
    "replay": "comems4build_ros.ros.nodes.replay",
    "mqtt_bridge": "comems4build_ros.ros.nodes.mqtt_bridge",
    "mqtt_plant": "comems4build_ros.mqtt.plant_sim",
    "coordinator": "comems4build_ros.ros.nodes.coordinator",
}
#: Executables of :data:`NODE_MODULES` that are no ROS node.
NOT_ROS_NODES = frozenset({"mqtt_plant"})
#: Module of the embedded MQTT broker (``plant="mqtt"`` without a broker URL).
BROKER_MODULE = "comems4build_ros.mqtt.broker"
#: Module of every EMS node (its executable is the EMS's ``node`` of ``config/ems.yaml``).
EMS_MODULE = "comems4build_ros.ros.nodes.ems_node"
#: Module of the container processes (layouts ``house`` and ``role``).
CONTAINER_MODULE = "comems4build_ros.ros.container"
#: Recorder progress line period [s].
PROGRESS_PERIOD_S = 0.25
#: UDP port of the discovery server: this base + the (locked) domain id.
DISCOVERY_PORT_BASE = 11811
#: Houses per recorder process in layout ``role`` (one recorder process for all 16 houses
#: would hold 16 x 32 subscriptions in one executor, see the module docstring of the launcher).
ROLE_HOUSES_PER_RECORDER = 4
#: Container processes: plant_sim's step timeout [s]. One EMS process may answer every house in
#: turn, so on a loaded machine a command can come later than the 5 s meant to detect a
#: dead EMS (a dead container process stops the launch anyway). Overridden by ``plant_node_params``.
CONTAINER_STEP_TIMEOUT_S = 60.0
#: Container processes: plant_sim's watchdog and the recorder's housekeeping timer periods [s]
#: (instead of 0.02 s and 0.05 s: N nodes' timers wake one shared executor N times as often).
CONTAINER_WATCHDOG_PERIOD_S = 0.1
CONTAINER_RECORDER_TICK_S = 0.2
#: Process layouts: one process per node, one process per role for all houses, or
#: container processes each running every node of a share of the houses.
LAYOUTS = ("node", "role", "house")
#: Networks: this host as it is, or two network namespaces joined by a veth pair.
NETWORKS = ("local", "netns")
#: Network side of each role in the ``netns`` network (the others: everything in ``local``).
#: (An MQTT broker goes with the house it serves, on the plant's side.)
NETNS_SIDE_OF_ROLE = {"plant": "plant_side", "feed": "plant_side", "broker": "plant_side", "ems": "ems_side",
                       "recorder": "ems_side"}
#: Fast DDS profile given to every node unless the user sets one (see the file's comment).
FASTDDS_PROFILE = "fastdds_profile.xml"
#: Fast DDS profile of the ``netns`` network: UDPv4 only (no shared memory across hosts).
FASTDDS_UDP_PROFILE = "fastdds_profile_udp.xml"
#: Stop stages: plant, feed and EMS first, then the recorders (they close the bags),
#: then services (discovery server).
STAGE_NODES, STAGE_RECORDERS, STAGE_SERVICES = 0, 1, 2
#: Name of the network side of a plan that runs everything on this machine as it is.
LOCAL_SIDE = "local"
#: Default overall time limit of a launch: this start-up allowance plus
#: :data:`TIME_LIMIT_PER_STEP_S` per house-step (:data:`TIME_LIMIT_PER_STEP_MPC_S` for
#: an MPC; plus the step period of a wall clock) [s]. A run that needs longer (a paused or
#: hung node) is stopped with an error.
TIME_LIMIT_START_S = 300.0
TIME_LIMIT_PER_STEP_S = 0.1
TIME_LIMIT_PER_STEP_MPC_S = 1.0
#: ``stall_steps`` of every lock-step master of a launch: the run ends, naming the silent
#: node, once the EMS has sent nothing for this many steps in a row (each a fallback after
#: the step time-out) or no step was possible for as many step time-outs (feed, recorder,
#: house behind MQTT silent). Within a launch a node cannot come back (any node that
#: leaves fails the launch), so a long silence is a fault, not a restart to wait for.
STALL_STEPS = 3
#: Step time-out of the lock-step master when not given (plant_sim's and mqtt_bridge's default) [s].
DEFAULT_STEP_TIMEOUT_S = 5.0
#: The supervisor's backstop (:attr:`RunPlan.stall_s`): this many times the masters' own
#: stall window, plus :data:`STALL_MARGIN_S` (the master names the cause first when it can),
#: and at least :data:`STALL_BACKSTOP_MIN_S` (a live recorder on a loaded machine can be
#: still for seconds: the lock-step master's recorder wait, ``lockstep.RECORDER_STALL_MIN_S``).
STALL_BACKSTOP_FACTOR = 2.0
STALL_MARGIN_S = 10.0
STALL_BACKSTOP_MIN_S = 90.0
#: Directory of the run's token files under the output directory (mode 0700, removed after the run).
SECRETS_DIR = ".secrets"
#: The run's checked plant parameters, one ROS 2 parameter file every node reads
#: (``config_files``), under the output directory.
PLANT_PARAMS_FILE = Path("params") / "plant.yaml"


class PlanError(InputError):
    """Launch options that make no run plan (a layout, namespace, plant or clock that do not go together)."""


@dataclass
class LaunchOptions:
    """What :func:`comems4build_ros.run.launcher.launch` runs.

    Attributes
    ----------
    ems : EMS name (fuzzy, rbc, mpc; thermostat and mpc-qp run through ``ems_node``)
    out : output directory (``bag/``, ``log/``, ``weekly.csv``, ``summary.json``, ...)
    scenario : ``default`` or a scenario CSV path
    weeks : run length [weeks] (None = the scenario's default)
    steps : cut the run to its first ``steps`` steps (short test runs; None = all)
    start : ISO start time (CSV scenarios)
    houses : number of independent houses
    seed : scenario seed of house 0 (default scenario; None = the configured seed)
    config_files : parameter files merged over ``config/plant.yaml``
    overrides : ``section.key`` -> value overrides of the plant parameters
    ems_options : options of the EMS (``key=value`` strings)
    forecast : forecast mode of the MPC (None = ``config/forecast.yaml``)
    domain_id : ROS domain id (None = a free one)
    timeout_s : stop with an error after this wall time [s] (None = :func:`default_time_limit`;
        ``math.inf`` = no limit)
    progress : show a progress bar on stderr (:class:`comems4build_ros.run.progress.ProgressBar`)
    on_progress : called as ``on_progress(recorded steps, total steps)`` while the run goes
        (instead of the bar; e.g. a worker's reporter to a parent's bars)
    plant_node_params : extra ROS parameters of plant_sim (e.g. ``step_timeout_s``)
    discovery_server : use a Fast DDS discovery server (None = with more than one house
        in layout ``node``; never in the container layouts). It hides the graph from a
        plain ``ros2 node list``: the plan names the server's address and the super-client
        setting that shows it (:meth:`RunPlan.describe`)
    params : the plant parameters of ``config_files`` and ``overrides``, checked once by the
        command (None = checked by :func:`plan_run`); the plan hands them to every node as
        one parameter file (:data:`PLANT_PARAMS_FILE`)
    layout : process layout (:data:`LAYOUTS`, see :func:`effective_layout`): ``node`` (one
        process per node), ``house`` (container processes, each running every node of
        its share of the houses) or ``role`` (one container process per role for all
        houses, see :mod:`comems4build_ros.ros.container`); None = the default (``node``
        for one house, ``house`` for more; ``role`` for more on the ``netns``
        network, ``house`` whenever ``containers`` is given)
    houses_per_recorder : houses recorded by one recorder process in layout ``role``
    containers : container processes of layout ``house`` (recorder, EMS, feed and plant
        of house i in container i mod ``containers``; at most one container per
        house); None = one per core (:func:`container_count`)
    namespace : namespace of the run: the house's own for one house (``/`` = none),
        else the namespace under which the houses ``house_<i>`` run
    bag : bag directory to create (None = ``out/bag``)
    all_inputs : the feed publishes (and the bag records) every EMS input topic, also those
        the run's EMS does not read (so that ``replay --inputs-only`` of the bag can drive
        any EMS); default: only the topics of the EMS's information level
    plant : ``sim`` (``plant_sim`` on ROS) or ``mqtt`` (the simulated house behind MQTT,
        reached through ``mqtt_bridge``; one house, one process per node)
    clock : ``sim``, ``wall`` or ``wall:<factor>`` (wall modes need ``plant="mqtt"``)
    broker_url : broker of the MQTT plant (None = an embedded amqtt broker on a free port)
    topic_map : topic map of bridge and house (None = ``config/mqtt.yaml``)
    inputs : ``scenario`` (default) or ``live`` (the feed's live prices and weather,
        ``config/live_inputs.yaml``, cache files in ``out``)
    live_config : live-input settings file of ``inputs="live"`` (None = ``config/live_inputs.yaml``)
    network : ``local`` or ``netns`` (:data:`NETWORKS`; see the module docstring)
    netem : ``tc netem`` arguments for both ends of the veth link in the ``netns`` network,
        e.g. ``delay 5ms loss 1%`` (None = none; skipped with a message where the kernel
        lacks netem)
    building : the building model of ``plant_sim`` (``rc``, ``energyplus[:IDF]``, ``fmu:PATH``);
        a detailed model runs inside ``plant_sim``, which then loads the feed's scenario
    community : a community file (None = independent houses): its houses and a coordinator
        (:mod:`comems4build_ros.run.community`)
    coordinator : the community's coordinator (``config/coordinators.yaml``)
    coordinator_options : options of the coordinator (``key=value`` strings)
    """

    ems: str
    out: Path
    scenario: str = "default"
    weeks: float | None = None
    steps: int | None = None
    start: str | None = None
    houses: int = 1
    seed: int | None = None
    config_files: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)
    ems_options: list[str] = field(default_factory=list)
    forecast: str | None = None
    domain_id: int | None = None
    timeout_s: float | None = None
    progress: bool = False
    on_progress: Callable[[int, int], None] | None = None
    plant_node_params: dict[str, Any] = field(default_factory=dict)
    discovery_server: bool | None = None
    layout: str | None = None
    houses_per_recorder: int = ROLE_HOUSES_PER_RECORDER
    containers: int | None = None
    plant: str = "sim"
    clock: str = "sim"
    broker_url: str | None = None
    topic_map: str | None = None
    inputs: str = "scenario"
    live_config: str | None = None
    network: str = "local"
    netem: str | None = None
    namespace: str = "/"
    bag: Path | None = None
    all_inputs: bool = False
    building: str = "rc"
    params: Any = None
    community: str | None = None
    coordinator: str = "rule"
    coordinator_options: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        """An embedded scenario's plant file (``--scenario year``: ``config/year.yaml``) goes first."""
        from comems4build_ros.core.config import scenario_config_files

        self.config_files = scenario_config_files(self.scenario, self.config_files)


def effective_layout(opts: LaunchOptions) -> str:
    """The process layout of ``opts`` (:data:`LAYOUTS`): ``layout`` as given, else ``house``
    when ``containers`` is given, else ``node`` for one house and ``house`` (network
    ``local``) or ``role`` (``netns``: containers cannot span two network sides) for more.

    Raises
    ------
    ValueError
        For an unknown layout, or ``containers`` with a layout other than ``house``.
    """
    if opts.layout is not None and opts.layout not in LAYOUTS:
        raise PlanError(f"layout '{opts.layout}': one of {', '.join(LAYOUTS)}")
    if opts.containers is not None and opts.layout not in (None, "house"):
        raise PlanError(f"containers need layout 'house', not '{opts.layout}'")
    if opts.layout is not None:
        return opts.layout
    if opts.containers is not None:
        return "house"
    if opts.houses == 1:
        return "node"
    return "house" if opts.network == "local" else "role"


def container_count(opts: LaunchOptions) -> int:
    """Container processes of layout ``house``: ``containers``, or one per core, at most
    one per building."""
    import os

    n = opts.containers if opts.containers is not None else (os.cpu_count() or 1)
    return max(1, min(n, opts.houses))


# ---------------------------------------------------------------------- plan records
@dataclass(frozen=True)
class NodePlan:
    """One ROS node of the plan.

    Attributes
    ----------
    role : plant, feed, ems or recorder
    name : node name (``plant_sim``, ``feed``, ``fuzzy_ems``, ``recorder``)
    namespace : ``/`` or ``/house_<i>``
    params : ROS parameters of the node
    """

    role: str
    name: str
    namespace: str
    params: dict[str, Any] = field(default_factory=dict)


def node_label(node: NodePlan) -> str:
    """The node's full name under the namespace of the house it serves (``/house_0/plant_sim``,
    ``/feed``): what the launcher names when the node's process leaves the run. A recorder
    started at ``/`` for one house's bag (layout ``node``) is ``/house_0/recorder``."""
    ns = node.namespace
    recorded = node.params.get("namespaces") if node.role == "recorder" else None
    if ns == "/" and isinstance(recorded, list) and len(recorded) == 1:
        ns = str(recorded[0])
    return f"{ns.rstrip('/')}/{node.name}"


@dataclass(frozen=True)
class ProcessPlan:
    """One OS process of the plan.

    Attributes
    ----------
    name : name in messages and of the log file (``plant_sim``, ``house_3/feed``, ``role_ems``)
    role : plant, feed, ems, recorder or discovery (what the exit rule looks at)
    argv : command line
    nodes : the ROS nodes the process runs (empty for a service such as the discovery server)
    side : network side (:class:`NetworkSide`) the process runs on
    files : ``(path, text)`` written before the start (container spec files)
    env : environment additions of this process (over the side's and the plan's)
    finishes : exit code 0 means its part of the run is complete (every node process: a
        node exits 0 only then, :mod:`comems4build_ros.wire.exits`); any other exit while
        the run is in progress fails the launch, as does any exit of a process that does
        not finish (a broker, a discovery server)
    progress : the process prints ``progress <recorded> <total>`` lines on stdout
    stop_stage : order of stopping (:data:`STAGE_NODES`, :data:`STAGE_RECORDERS`,
        :data:`STAGE_SERVICES`)
    may_leave : the run goes on when the process leaves (the houses of a community on a wall
        clock: the community goes on without them, docs/community.md "Over ROS")
    """

    name: str
    role: str
    argv: tuple[str, ...]
    nodes: tuple[NodePlan, ...] = ()
    side: str = LOCAL_SIDE
    files: tuple[tuple[str, str], ...] = ()
    env: dict[str, str] = field(default_factory=dict)
    finishes: bool = False
    progress: bool = False
    stop_stage: int = STAGE_NODES
    may_leave: bool = False


@dataclass(frozen=True)
class NetworkSide:
    """Where a set of processes runs.

    Attributes
    ----------
    name : side name (``local`` = this machine as it is)
    env : environment additions of every process of the side
    netns : Linux network namespace the side's processes run in (None = the launcher's)
    address : the side's IPv4 address on the link to the other side (None = local)
    """

    name: str
    env: dict[str, str] = field(default_factory=dict)
    netns: str | None = None
    address: str | None = None


@dataclass(frozen=True)
class HousePlan:
    """One house: namespace, scenario seed (None = configured), bag directory and the
    run token its EMS puts in every command (plant_sim applies no other token's commands)."""

    namespace: str
    seed: int | None
    bag: Path
    token: int = 0
    token_file: str = ""  # where the supervisor writes the token for the run (mode 0600)


@dataclass(frozen=True)
class RunPlan:
    """Everything a launch runs (see the module docstring).

    Attributes
    ----------
    ems : EMS name
    out : output directory; ``bag`` the bag directory (or set of per-house bags)
    domain_id : ROS domain id of every process
    layout : ``node`` or ``role`` (:data:`LAYOUTS`)
    houses : the houses, in namespace order
    sides : network sides by name
    processes : processes in start order
    env : environment additions of every process (besides the isolation variables the
        supervisor sets: domain id, discovery range, log directory)
    run_info : the run's description stored in every bag (``run_info.json``)
    timeout_s : overall wall-time limit [s] (None = none)
    stall_s : the supervisor ends the run when no step was recorded for this long [s]
        (None = never; the backstop behind the masters' ``stall_steps``)
    secrets : ``(path, token)`` of the token files to write before the start (mode 0600 in
        a directory of mode 0700) and to remove after the run; the processes get the paths
    setup : commands run before the first process (network namespaces, link)
    optional_setup : commands whose failure only prints a note (``tc netem``)
    teardown : commands run after the last process stopped
    files : ``(path, text)`` written before the first process (the plant parameter file)
    clock : the node publishing ``/clock`` (one clock per run; None = none)
    discovery_server : ``host:port`` of the run's Fast DDS discovery server (None = simple discovery)
    """

    ems: str
    out: Path
    bag: Path
    domain_id: int
    layout: str
    houses: tuple[HousePlan, ...]
    sides: dict[str, NetworkSide]
    processes: tuple[ProcessPlan, ...]
    env: dict[str, str] = field(default_factory=dict)
    run_info: dict[str, Any] = field(default_factory=dict)
    timeout_s: float | None = None
    stall_s: float | None = None
    secrets: tuple[tuple[str, int], ...] = ()
    setup: tuple[tuple[str, ...], ...] = ()
    optional_setup: tuple[tuple[str, ...], ...] = ()
    teardown: tuple[tuple[str, ...], ...] = ()
    files: tuple[tuple[str, str], ...] = ()
    clock: str | None = None
    discovery_server: str | None = None

    def process(self, name: str) -> ProcessPlan:
        """The process called ``name`` (KeyError naming the known ones)."""
        for p in self.processes:
            if p.name == name:
                return p
        raise KeyError(f"no process '{name}' in the plan (processes: {', '.join(p.name for p in self.processes)})")

    def nodes(self, role: str | None = None) -> list[tuple[ProcessPlan, NodePlan]]:
        """``(process, node)`` of every node (of ``role``), in start order."""
        return self.nodes_of(self.processes, role)

    @staticmethod
    def nodes_of(processes: Sequence[ProcessPlan], role: str | None = None) -> list[tuple[ProcessPlan, NodePlan]]:
        """``(process, node)`` of every node of ``processes`` (of ``role``), in start order."""
        return [(p, n) for p in processes for n in p.nodes if role is None or n.role == role]

    def describe(self) -> str:
        """Human-readable plan: network sides, processes and the nodes each runs."""
        lines = [
            f"run plan: EMS {self.ems}, {len(self.houses)} house(s), layout '{self.layout}', "
            f"ROS domain {self.domain_id}, {len(self.processes)} process(es), "
            f"time limit {'none' if self.timeout_s is None else f'{self.timeout_s:g} s'}",
            f"bag: {self.bag}",
        ]
        for path, _text in self.files:
            lines.append(f"file: {path}")
        if self.clock:
            lines.append(f"clock: /clock from {self.clock} (one clock per run; a node of another house with "
                         "use_sim_time follows it)" if len(self.houses) > 1 else f"clock: /clock from {self.clock}")
        if self.discovery_server:
            lines.append(discovery_hint(self.discovery_server))
        for cmd in (*self.setup, *self.optional_setup):
            lines.append(f"setup $ {' '.join(cmd)}")
        for g in self.sides.values():
            env = " ".join(f"{k}={v}" for k, v in sorted(g.env.items()))
            where = f" (network namespace {g.netns}, {g.address})" if g.netns else ""
            lines.append(f"side {g.name}{where}" + (f": {env}" if env else ""))
            for p in self.processes:
                if p.side != g.name:
                    continue
                nodes = ", ".join(f"{n.namespace.rstrip('/')}/{n.name}" for n in p.nodes) or "-"
                lines.append(f"  process {p.name} [{p.role}, stop stage {p.stop_stage}]: {nodes}")
                lines.append(f"    $ {' '.join(p.argv)}")
        for cmd in self.teardown:
            lines.append(f"teardown $ {' '.join(cmd)}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form of the plan."""

        def node(n: NodePlan) -> dict[str, Any]:
            return {"role": n.role, "name": n.name, "namespace": n.namespace, "params": n.params}

        return {
            "ems": self.ems,
            "out": str(self.out),
            "bag": str(self.bag),
            "domain_id": self.domain_id,
            "layout": self.layout,
            "timeout_s": self.timeout_s,
            "env": self.env,
            "files": [f for f, _ in self.files],
            "clock": self.clock,
            "discovery_server": self.discovery_server,
            "houses": [{"namespace": b.namespace, "seed": b.seed, "bag": str(b.bag)} for b in self.houses],
            "sides": [{"name": g.name, "env": g.env, "netns": g.netns, "address": g.address}
                       for g in self.sides.values()],
            "setup": [list(c) for c in (*self.setup, *self.optional_setup)],
            "teardown": [list(c) for c in self.teardown],
            "processes": [
                {"name": p.name, "role": p.role, "side": p.side, "argv": list(p.argv),
                 "nodes": [node(n) for n in p.nodes], "files": [f for f, _ in p.files], "env": p.env,
                 "finishes": p.finishes, "progress": p.progress, "stop_stage": p.stop_stage,
                 "may_leave": p.may_leave}
                for p in self.processes
            ],
        }


# ---------------------------------------------------------------------- command lines
def python_module(module: str) -> list[str]:
    """``python -m module`` with this interpreter, without the working directory on
    ``sys.path`` (``-P``, Python >= 3.11): a launch started inside another checkout of the
    package must not run that checkout's code in its children."""
    return [sys.executable, *(("-P",) if sys.version_info >= (3, 11) else ()), "-m", module]


def node_command(executable: str, ems: str | None = None) -> list[str]:
    """Command line of a node: the venv's console script if installed, else ``python -m``.

    ``executable`` is a key of :data:`NODE_MODULES` or ``"ems"`` (then ``ems`` names it and
    its executable is its ``node`` of ``config/ems.yaml``).
    """
    bindir = Path(sys.executable).parent
    if executable == "ems":
        if ems is None:
            raise ValueError("node_command('ems') needs the EMS name")
        script = ems_node_name(ems)
        if (bindir / script).is_file():
            return [str(bindir / script)]
        return [*python_module(EMS_MODULE), "--ems", ems]
    module = NODE_MODULES[executable]
    if (bindir / executable).is_file():
        return [str(bindir / executable)]
    return python_module(module)


def ros_args(namespace: str = "", params: dict[str, Any] | None = None, params_files: Sequence[str] = ()) -> list[str]:
    """``--ros-args`` part of a command line: namespace, ``-p name:=value``, params files.

    Values are written as YAML (lists and strings as JSON, which YAML reads); empty
    lists are left out (their type cannot be inferred).
    """
    out = ["--ros-args"]
    if namespace and namespace != "/":
        out += ["-r", f"__ns:={namespace}"]
    for f in params_files:
        out += ["--params-file", str(f)]
    for name, value in (params or {}).items():
        if isinstance(value, (list, tuple)):
            if not value:
                continue
            text = json.dumps([str(v) for v in value] if all(isinstance(v, str) for v in value) else list(value))
        elif isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, str):
            text = json.dumps(value)
        else:
            text = repr(value)
        out += ["-p", f"{name}:={text}"]
    return out


def container_command(role: str, spec_path: Path) -> list[str]:
    """Command line of a container process (``python -m comems4build_ros.ros.container``)."""
    return [*python_module(CONTAINER_MODULE), "--role", role, "--spec", str(spec_path)]


def discovery_hint(address: str) -> str:
    """How to see the graph of a run behind the discovery server at ``address`` (``host:port``):
    ``ros2`` must join as a super client (ROS 2 docs, "Using Fast DDS Discovery Server")."""
    return (f"discovery server {address}: the graph shows to 'ROS_DISCOVERY_SERVER={address} "
            f"ROS_SUPER_CLIENT=TRUE ros2 node list' (ros2 daemon stop first, or --no-daemon)")


def discovery_server_command(port: int) -> list[str] | None:
    """``fast-discovery-server`` on 127.0.0.1:``port`` (None when the ROS wheels lack it)."""
    exe = Path(sys.executable).parent / "fast-discovery-server"
    if not exe.is_file():
        return None
    return [str(exe), "-i", "0", "-l", "127.0.0.1", "-p", str(port)]


#: Environment variables naming a Fast DDS XML profiles file: ``FASTRTPS_DEFAULT_PROFILES_FILE``
#: is the one Fast DDS 2.x reads (Jazzy ships 2.14), ``FASTDDS_DEFAULT_PROFILES_FILE`` the one of
#: Fast DDS 3.x. A process gets both; a user who set either keeps it.
FASTDDS_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def profile_env(profile: Path | None, env: Mapping[str, str] | None = None) -> dict[str, str]:
    """The variables that make Fast DDS 2.x and 3.x load ``profile``; empty when there is no
    profile or ``env`` (default: none) already names one (the user's choice stands)."""
    if profile is None or (env is not None and any(v in env for v in FASTDDS_PROFILE_VARS)):
        return {}
    return dict.fromkeys(FASTDDS_PROFILE_VARS, str(profile))


def fastdds_profile(name: str = FASTDDS_PROFILE) -> Path | None:
    """A Fast DDS profile of ``launch_scripts/`` (default ``fastdds_profile.xml``: deep
    shared-memory port queues): source tree, then installed share."""
    return shared_path("launch_scripts", "launch", name)


# ---------------------------------------------------------------------- the planner
def bag_dir(bag: Path, ns: str, houses: int) -> Path:
    """Bag of the house in namespace ``ns``: ``bag`` itself for one house, else
    ``bag/house_<i>`` (the namespace's last segment)."""
    return bag if houses == 1 else bag / ns.rstrip("/").rsplit("/", 1)[-1]


def namespaces(houses: int, namespace: str = "/") -> list[str]:
    """Namespaces of the houses: ``[namespace]`` for one house, else
    ``[<namespace>/house_0, ...]`` (``/house_<i>`` under the root namespace).

    Raises
    ------
    ValueError
        For fewer than one house or a namespace that is not absolute.
    """
    if houses < 1:
        raise PlanError(f"--houses must be >= 1, got {houses}")
    if not namespace.startswith("/") or "//" in namespace or not all(
            part.replace("_", "a").isalnum() and not part[0].isdigit() for part in namespace.strip("/").split("/")
            if namespace.strip("/")):
        raise PlanError(f"namespace '{namespace}': an absolute ROS namespace such as / or /site_3 is expected")
    root = "/" + namespace.strip("/") if namespace.strip("/") else "/"
    if houses == 1:
        return [root]
    return [f"{root.rstrip('/')}/house_{i}" for i in range(houses)]


def feed_window(weeks: float | None, steps: int | None) -> tuple[int, int]:
    """``weeks`` and ``steps`` parameters of the feed (integer weeks, fractions via steps)."""
    from comems4build_ros.core.scenario import HOURS_PER_WEEK

    if weeks is None:
        return 0, int(steps or 0)
    whole = math.ceil(weeks - 1e-9)
    n = int(round(weeks * HOURS_PER_WEEK))
    if steps is not None:
        n = min(n, steps)
    return whole, (0 if n == whole * HOURS_PER_WEEK else n)


def house_seeds(opts: LaunchOptions) -> list[int | None]:
    """Scenario seed of each house: ``seed + i`` for several houses on the default scenario."""
    from comems4build_ros.core.scenario.settings import load_scenario_settings

    if opts.houses > 1 and opts.scenario == "default":
        base = opts.seed if opts.seed is not None else load_scenario_settings().seed
        return [base + i for i in range(opts.houses)]
    return [opts.seed] * opts.houses


def run_info(opts: LaunchOptions, params: Any, seeds: list[int | None], run_id: str | None = None) -> dict[str, Any]:
    """The run's description stored in the bag (``run_info.json``): what evaluate needs, and the
    run's id (``run_id``, which every feed of the run also names on ``feed/info``: a record of
    another run in the bag is told apart by it)."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.core.loop import load_forecast_settings

    level = ems_entry(opts.ems).info_level
    forecast = load_forecast_settings(**({"mode": opts.forecast} if opts.forecast else {})).mode
    name = opts.scenario if opts.scenario in ("default", "year") else Path(opts.scenario).name
    if opts.inputs == "live":  # the scenario's steps laid on the wall-clock hours, live prices and weather in
        name += "+live"
    return {
        "ems": opts.ems,
        "scenario": name,
        "inputs": opts.inputs,
        "forecast": forecast if level == "mpc" else None,
        "weeks": opts.weeks,
        "steps": opts.steps,
        "start": opts.start,
        "houses": [{"namespace": ns, "seed": s} for ns, s in zip(namespaces(opts.houses, opts.namespace), seeds)],
        "config_files": [str(Path(f).resolve()) for f in opts.config_files],
        "overrides": opts.overrides,
        "ems_options": opts.ems_options,
        "timezone": params.site.timezone,
        "run_id": run_id,
    }


def house_params(
    opts: LaunchOptions, seed: int | None, common: dict[str, Any], token_file: str = "", clock: bool = True,
    run_id: str = "",
) -> dict[str, dict[str, Any]]:
    """Parameters of the EMS, feed and plant of one house (role -> parameters).

    ``run_id``: the run's id, which the feed names on ``feed/info`` (:func:`run_info`).

    ``token_file``: the house's run token file (EMS ``run_token_file``, plant
    ``ems_token_file``); the token itself is never a parameter value (any local user sees
    command lines, and any DDS participant reads parameters with ``ros2 param get``).
    ``clock``: the house's plant publishes ``/clock`` (the first house of a run only: one
    clock per run, and the houses step independently).
    """
    weeks, steps = feed_window(opts.weeks, opts.steps)
    ems_params = dict(common, wait_for_recorder=True)  # first command once its writers matched the recorder
    if token_file:
        ems_params["run_token_file"] = token_file
    if opts.ems_options:
        ems_params["ems_options"] = list(opts.ems_options)
    feed_params = dict(common, scenario=str(opts.scenario), weeks=weeks, steps=steps, wait_for_recorder=True)
    if run_id:
        feed_params["run_id"] = run_id
    if not opts.all_inputs:
        feed_params["for_ems"] = ems_node_name(opts.ems)
    if seed is not None:
        feed_params["seed"] = int(seed)
    if opts.start:
        feed_params["start"] = opts.start
    if opts.forecast:
        feed_params["forecast_mode"] = opts.forecast
    if opts.inputs != "scenario":
        feed_params.update(inputs=opts.inputs, live_cache_dir=str(Path(opts.out).resolve()))
        if opts.live_config:
            feed_params["live_config"] = str(Path(opts.live_config).resolve())
    plant = dict(common, wait_for_recorder=True, stall_steps=STALL_STEPS,
                 **({"ems_token_file": token_file} if token_file else {}), **opts.plant_node_params)
    if opts.building != "rc":  # a detailed building model: plant_sim loads the feed's scenario for its weather
        plant["building_model"] = opts.building
        plant.update({k: v for k, v in feed_params.items() if k in ("scenario", "weeks", "steps", "seed", "start")})
    if not clock:
        plant["publish_clock"] = False
    return {"ems": ems_params, "feed": feed_params, "plant": plant}


def run_steps(opts: LaunchOptions) -> int:
    """Steps per house of the run (12 weeks when the length is not given)."""
    from comems4build_ros.core.scenario import HOURS_PER_WEEK

    weeks, steps = feed_window(opts.weeks, opts.steps)
    return steps or (weeks or 12) * HOURS_PER_WEEK


def default_time_limit(opts: LaunchOptions) -> float:
    """Overall time limit of a launch without ``timeout_s`` [s] (see :data:`TIME_LIMIT_START_S`)."""
    from comems4build_ros.core.ems import ems_entry
    from comems4build_ros.mqtt.clock import parse_clock

    planning = ems_entry(opts.ems).info_level == "mpc"  # an optimiser over the horizon's forecasts
    per = TIME_LIMIT_PER_STEP_MPC_S if planning else TIME_LIMIT_PER_STEP_S
    clock = parse_clock(opts.clock)
    if clock.wall:  # a wall clock paces the steps (hourly steps of the default time step)
        per += clock.period_s
    return TIME_LIMIT_START_S + per * run_steps(opts) * opts.houses


def run_time_limit(opts: LaunchOptions) -> float | None:
    """The supervisor's overall time limit of a run (:attr:`RunPlan.timeout_s`) [s]: ``timeout_s``,
    :func:`default_time_limit` where it is None, and None (no limit) where it is infinite."""
    if opts.timeout_s == math.inf:
        return None
    return opts.timeout_s if opts.timeout_s is not None else default_time_limit(opts)


def backstop_stall_s(opts: LaunchOptions, layout: str) -> float | None:
    """The supervisor's stall limit of a run (:attr:`RunPlan.stall_s`) [s]: :data:`STALL_BACKSTOP_FACTOR`
    times the masters' window (``stall_steps`` x the step time-out, plus a wall clock's step
    period) plus :data:`STALL_MARGIN_S`, at least :data:`STALL_BACKSTOP_MIN_S`; None when the
    masters' stall rule is off."""
    from comems4build_ros.mqtt.clock import parse_clock

    steps = int(opts.plant_node_params.get("stall_steps", STALL_STEPS))
    if steps <= 0:
        return None
    default = CONTAINER_STEP_TIMEOUT_S if layout in ("role", "house") else DEFAULT_STEP_TIMEOUT_S
    step_timeout = float(opts.plant_node_params.get("step_timeout_s", default))
    clock = parse_clock(opts.clock)
    window = steps * (step_timeout + (clock.period_s if clock.wall else 0.0))
    return max(STALL_BACKSTOP_FACTOR * window + STALL_MARGIN_S, STALL_BACKSTOP_MIN_S)


def unread_inputs(opts: LaunchOptions) -> list[str]:
    """Feed topics the run's EMS does not read (its information level,
    ``tab:level_of_information``), which its feed leaves out (feed ``for_ems``) and its
    recorder does not record (``skip_topics``); none with ``all_inputs``."""
    from comems4build_ros.wire.contract import load_contract

    return [] if opts.all_inputs else list(load_contract().inputs_not_read(ems_node_name(opts.ems)))


def not_recorded(opts: LaunchOptions) -> list[str]:
    """Topics the recorder of an independent house leaves out: the inputs its EMS does not read
    (:func:`unread_inputs`) and the link to a community's coordinator, which it has not."""
    from comems4build_ros.wire.contract import load_contract

    return [*unread_inputs(opts), *(t.name for t in load_contract().in_scope("community_house"))]


def recorder_params(ns: str, bag: Path, info: dict[str, Any], progress_period_s: float,
                    skip_topics: Sequence[str] = (), clock: bool = True) -> dict[str, Any]:
    """Parameters of the recorder of namespace ``ns`` writing the bag directory ``bag``
    (``skip_topics``: topics no node of the run publishes, see :func:`unread_inputs`;
    ``clock``: the house's plant publishes ``/clock``, which its bag records, else none does).
    The run's id goes as the parameter ``run_id`` (the recorder adds it to ``run_info.json``)."""
    if not clock:
        skip_topics = [*skip_topics, CLOCK_TOPIC]
    params: dict[str, Any] = {
        "bag_path": str(bag.resolve()),
        "namespaces": [ns],
        "run_info": json.dumps({k: v for k, v in info.items() if k != "run_id"}),
        "progress_period_s": progress_period_s,
    }
    if info.get("run_id"):
        params["run_id"] = info["run_id"]
    if skip_topics:
        params["skip_topics"] = list(skip_topics)
    return params


def ros_node_executables() -> frozenset[str]:
    """The package's executables that run one ROS node (``ros2 run comems4build_ros X``): the
    node executables of :data:`NODE_MODULES` and the node of each EMS of ``config/ems.yaml``."""
    from comems4build_ros.core.ems import ems_table

    return frozenset(set(NODE_MODULES) - NOT_ROS_NODES | {e.node for e in ems_table().values()})


def ems_node_name(ems: str) -> str:
    """Node name and executable of the EMS ``ems`` (``fuzzy_ems``, ``mpc_qp_ems``, ...; ``config/ems.yaml``)."""
    from comems4build_ros.core.ems import ems_entry

    return ems_entry(ems).node


def check_plant_options(opts: LaunchOptions) -> None:
    """The ``plant``, ``clock`` and ``inputs`` combinations a plan can run (ValueError names them)."""
    from comems4build_ros.mqtt.clock import parse_clock

    if opts.plant not in ("sim", "mqtt"):
        raise PlanError(f"plant {opts.plant!r}: expected 'sim' or 'mqtt'")
    if opts.inputs not in ("scenario", "live"):
        raise PlanError(f"inputs {opts.inputs!r}: expected 'scenario' or 'live'")
    clock = parse_clock(opts.clock)
    if opts.plant != "mqtt" and (clock.wall or opts.broker_url or opts.topic_map):
        raise PlanError("clock 'wall', a broker URL and a topic map need plant 'mqtt' (plant_sim runs lock-step)")
    if opts.plant == "mqtt" and (opts.houses > 1 or effective_layout(opts) != "node"):
        raise PlanError("plant 'mqtt' runs one house, one process per node")
    if opts.plant == "mqtt" and opts.broker_url and opts.network != "local":
        raise PlanError("a broker URL needs network 'local' (the 'netns' namespaces reach no other host)")


#: Broker users of the run's two MQTT peers on the embedded broker (password: the run's MQTT secret).
MQTT_HOUSE_USER, MQTT_BRIDGE_USER = "comems4build_house", "comems4build_bridge"
#: The run's MQTT secret under :data:`SECRETS_DIR` (``plant="mqtt"``).
MQTT_SECRET_FILE = "mqtt.token"


def mqtt_plant_processes(opts: LaunchOptions, params: dict[str, dict[str, Any]], secret_file: str,
                         run_id: str) -> list[ProcessPlan]:
    """``plant="mqtt"``: the embedded broker (unless ``broker_url``; a free port now), the
    simulated house with the feed's scenario window, and ``mqtt_bridge`` in plant_sim's
    place. Bridge and house finish (exit 0 at the end); the broker stops last.

    Bridge and house share the run id ``run_id`` and the per-run secret in ``secret_file``
    (written by the supervisor, mode 0600): the key of their messages' authentication codes
    (:mod:`comems4build_ros.mqtt.peer`) and, on the embedded broker, the password of their
    two users (no anonymous access). Only paths and user names stand on the command lines."""
    from comems4build_ros.mqtt.broker import free_port

    out: list[ProcessPlan] = []
    url = opts.broker_url
    login: dict[str, str] = {}
    house_login: list[str] = []
    if url is None:
        port = free_port()
        url = f"mqtt://127.0.0.1:{port}"
        out.append(ProcessPlan("broker", "broker", (*python_module(BROKER_MODULE), "--port", str(port),
                                                    "--login-file", secret_file, "--user", MQTT_HOUSE_USER,
                                                    "--user", MQTT_BRIDGE_USER),
                               stop_stage=STAGE_SERVICES))
        login = {"broker_username": MQTT_BRIDGE_USER}
        house_login = ["--username", MQTT_HOUSE_USER]
    feed = params["feed"]
    argv = [*node_command("mqtt_plant"), "--broker", url, "--clock", opts.clock, "--scenario", str(feed["scenario"]),
            "--run-id", run_id, "--mqtt-secret-file", secret_file, *house_login]
    for key in ("weeks", "steps", "seed", "start"):
        if feed.get(key):
            argv += [f"--{key}", str(feed[key])]
    for f in feed.get("config_files", []):  # the run's plant parameter file
        argv += ["--config", f]
    bridge = dict(params["plant"], broker_url=url, clock=opts.clock, run_id=run_id, mqtt_secret_file=secret_file,
                  **login)
    if opts.topic_map:
        topic_map = str(Path(opts.topic_map).resolve())
        argv += ["--topic-map", topic_map]
        bridge["topic_map"] = topic_map
    out.append(ProcessPlan("mqtt_plant", "plant", tuple(argv), finishes=True))
    out.append(ProcessPlan("mqtt_bridge", "plant", (*node_command("mqtt_bridge"), *ros_args("/", bridge)),
                           nodes=(NodePlan("plant", "mqtt_bridge", "/", bridge),), finishes=True))
    return out


def plan_run(opts: LaunchOptions, domain_id: int, params: Any = None) -> RunPlan:
    """The plan of ``opts`` on ``domain_id``; starts nothing (see the module docstring).

    A run of independent houses; a community's plan is
    :func:`comems4build_ros.run.plans.plan_any`'s (:mod:`comems4build_ros.run.community`).

    Parameters
    ----------
    opts : launch options
    domain_id : ROS domain id of the run (the launcher locks a free one first)
    params : checked plant parameters (default ``opts.params``, else loaded from
        ``opts.config_files`` and ``opts.overrides``): written once into the run's plant
        parameter file (:data:`PLANT_PARAMS_FILE`), the one thing every node parses

    Raises
    ------
    ValueError
        For an invalid house count, layout or ``houses_per_recorder``, or a community.
    """
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.ros.parameters import plant_params_file_text

    out = Path(opts.out)
    bag = Path(opts.bag) if opts.bag is not None else out / "bag"
    params = params or opts.params or load_plant_params(opts.config_files, opts.overrides)
    if opts.community is not None:  # planned by run.community (which builds on this module)
        raise ValueError("a community run is planned by comems4build_ros.run.plans.plan_any")
    layout = check_layout(opts)
    seeds = house_seeds(opts)
    from comems4build_ros.mqtt.peer import new_run_id

    info = run_info(opts, params, seeds, new_run_id())
    params_file = (out / PLANT_PARAMS_FILE).resolve()
    common: dict[str, Any] = {"config_files": [str(params_file)]}
    secret_dir = (out / SECRETS_DIR).resolve()
    houses = tuple(HousePlan(ns, seed, bag_dir(bag, ns, opts.houses), new_token(),
                             str(secret_dir / f"{ns.strip('/').replace('/', '__') or 'root'}.token"))
                   for ns, seed in zip(namespaces(opts.houses, opts.namespace), seeds))
    secrets = [(b.token_file, b.token) for b in houses]
    mqtt_secret: tuple[str, str] | None = None
    if opts.plant == "mqtt":  # the run's MQTT secret and id (mqtt_plant_processes)
        mqtt_secret = (str(secret_dir / MQTT_SECRET_FILE), info["run_id"])
        secrets.append((mqtt_secret[0], new_token()))
    if layout in ("role", "house"):
        processes = _container_processes(opts, houses, common, bag, info, out / "containers")
    else:
        processes = _node_processes(opts, houses, common, bag, info, mqtt_secret)
    processes, server = with_discovery_server(opts, layout, domain_id, processes)
    sides, setup, optional_setup, teardown, processes = network_sides(opts, domain_id, processes)
    masters = [n for _p, n in RunPlan.nodes_of(processes, "plant") if n.params.get("publish_clock", True)]
    return RunPlan(
        ems=opts.ems,
        out=out,
        bag=bag,
        domain_id=domain_id,
        layout=layout,
        houses=houses,
        sides=sides,
        setup=setup,
        optional_setup=optional_setup,
        teardown=teardown,
        processes=tuple(processes),
        run_info=info,
        timeout_s=run_time_limit(opts),
        stall_s=backstop_stall_s(opts, layout),
        secrets=tuple(secrets),
        files=((str(params_file), plant_params_file_text(params)),),
        clock=f"{masters[0].namespace.rstrip('/')}/{masters[0].name}" if masters else None,
        discovery_server=server,
    )


def check_layout(opts: LaunchOptions) -> str:
    """The effective layout of ``opts`` after the checks of its house count, plant, network and
    layout options (ValueError names the option)."""
    namespaces(opts.houses, opts.namespace)
    check_plant_options(opts)
    layout = effective_layout(opts)
    if opts.network not in NETWORKS:
        raise PlanError(f"network '{opts.network}': one of {', '.join(NETWORKS)}")
    if layout == "role" and opts.houses_per_recorder < 1:
        raise PlanError(f"houses_per_recorder must be >= 1, got {opts.houses_per_recorder}")
    if layout == "house" and opts.containers is not None and opts.containers < 1:
        raise PlanError(f"containers must be >= 1, got {opts.containers}")
    if layout == "house" and opts.network != "local":
        raise PlanError("containers run on this host (network 'local'): 'netns' splits plant and EMS between hosts")
    if opts.netem and opts.network != "netns":
        raise PlanError("netem applies to the 'netns' network only")
    return layout


def with_discovery_server(opts: LaunchOptions, layout: str, domain_id: int,
                          processes: list[ProcessPlan]) -> tuple[list[ProcessPlan], str | None]:
    """``processes`` with a discovery server in front when the plan uses one (``discovery_server``,
    default: several houses in layout ``node``) and its address, else unchanged and None."""
    use_server = opts.discovery_server
    if use_server is None:
        use_server = opts.houses > 1 and layout == "node" and opts.network == "local"
    if use_server and opts.network != "local":
        raise PlanError("a discovery server is not planned for the 'netns' network (unicast peers are used)")
    if not use_server:
        return processes, None
    port = DISCOVERY_PORT_BASE + domain_id
    argv = discovery_server_command(port)
    if argv is None:
        print("launcher: fast-discovery-server not found, using simple discovery", file=sys.stderr)
        return processes, None
    address = f"127.0.0.1:{port}"
    server = {"ROS_DISCOVERY_SERVER": address}
    return [ProcessPlan("discovery_server", "discovery", tuple(argv), stop_stage=STAGE_SERVICES),
            *(dataclasses.replace(p, env={**p.env, **server}) for p in processes)], address


def network_sides(opts: LaunchOptions, domain_id: int, processes: list[ProcessPlan]) -> tuple[
        dict[str, NetworkSide], Commands, Commands, Commands, list[ProcessPlan]]:
    """The network sides of the plan, their set-up, optional set-up and tear-down commands, and
    ``processes`` placed on them (``local``: every process on this machine as it is)."""
    if opts.network != "netns":
        return {LOCAL_SIDE: NetworkSide(LOCAL_SIDE)}, (), (), (), processes
    sides, setup, optional_setup, teardown = netns_network(domain_id, opts.netem)
    placed = [dataclasses.replace(p, side=NETNS_SIDE_OF_ROLE[p.role],
                                  argv=("ip", "netns", "exec", str(sides[NETNS_SIDE_OF_ROLE[p.role]].netns), *p.argv))
              for p in processes]
    return sides, setup, optional_setup, teardown, placed


def _node_processes(
    opts: LaunchOptions, houses: Sequence[HousePlan], common: dict[str, Any], bag: Path, info: dict[str, Any],
    mqtt_secret: tuple[str, str] | None = None,
) -> list[ProcessPlan]:
    """Layout ``node``: one recorder per house (in the house's namespace, as in the container
    layouts: no two nodes of a run share a name), then EMS, feed and plant of each house
    (``mqtt_secret``: the secret file and run id of a house behind MQTT)."""
    out: list[ProcessPlan] = []
    for b in houses:
        prefix = "" if b.namespace == "/" else b.namespace.strip("/") + "/"
        params = recorder_params(b.namespace, b.bag, info, PROGRESS_PERIOD_S, not_recorded(opts), b is houses[0])
        out.append(ProcessPlan(
            f"{prefix}recorder", "recorder", (*node_command("recorder"), *ros_args(b.namespace, params)),
            nodes=(NodePlan("recorder", "recorder", b.namespace, params),), finishes=True, progress=True,
            stop_stage=STAGE_RECORDERS,
        ))
    ems_name = ems_node_name(opts.ems)
    for b in houses:
        prefix = "" if b.namespace == "/" else b.namespace.strip("/") + "/"
        params = house_params(opts, b.seed, common, b.token_file, b is houses[0], info["run_id"])
        ns = b.namespace
        out.append(ProcessPlan(f"{prefix}{opts.ems}_ems", "ems",
                               (*node_command("ems", opts.ems), *ros_args(ns, params["ems"])),
                               nodes=(NodePlan("ems", ems_name, ns, params["ems"]),), finishes=True))
        if opts.plant == "mqtt":  # the house's meters give PV and load (mqtt_bridge)
            params["feed"]["publish_measured"] = False
        out.append(ProcessPlan(f"{prefix}feed", "feed", (*node_command("feed"), *ros_args(ns, params["feed"])),
                               nodes=(NodePlan("feed", "feed", ns, params["feed"]),), finishes=True))
        if opts.plant == "mqtt":
            assert mqtt_secret is not None
            out.extend(mqtt_plant_processes(opts, params, *mqtt_secret))
            continue
        out.append(ProcessPlan(f"{prefix}plant_sim", "plant",
                               (*node_command("plant_sim"), *ros_args(ns, params["plant"])),
                               nodes=(NodePlan("plant", "plant_sim", ns, params["plant"]),), finishes=True))
    return out


def _contained_nodes(
    opts: LaunchOptions, b: HousePlan, common: dict[str, Any], bag: Path, info: dict[str, Any], clock: bool
) -> list[NodePlan]:
    """Recorder, EMS, feed and plant of house ``b`` as nodes of a container
    process: the recorder's and the plant's timers slower, the plant's step timeout longer)."""
    names = {"ems": ems_node_name(opts.ems), "feed": "feed", "plant": "plant_sim"}
    nodes = [NodePlan("recorder", "recorder", b.namespace,
                      dict(recorder_params(b.namespace, b.bag, info, 0.0, not_recorded(opts), clock),
                           tick_s=CONTAINER_RECORDER_TICK_S))]
    for role, params in house_params(opts, b.seed, common, b.token_file, clock, info["run_id"]).items():
        if role == "plant":
            params = {"step_timeout_s": CONTAINER_STEP_TIMEOUT_S, "watchdog_period_s": CONTAINER_WATCHDOG_PERIOD_S,
                      **params}
        nodes.append(NodePlan(role, names[role], b.namespace, params))
    return nodes


def container_process(name: str, role: str, nodes: Sequence[NodePlan], spec_dir: Path, ems: str,
                  progress: bool) -> ProcessPlan:
    """A process of :mod:`comems4build_ros.ros.container` running ``nodes`` (its spec file written first)."""
    path = spec_dir / f"{name}.json"
    spec: dict[str, Any] = {"ems": ems, "nodes": [
        {"namespace": n.namespace, "params": n.params, **({"role": n.role} if role == "container" else {})}
        for n in nodes]}
    if progress:
        spec["progress_period_s"] = PROGRESS_PERIOD_S
    return ProcessPlan(name, role, tuple(container_command(role, path)), nodes=tuple(nodes),
                       files=((str(path), json.dumps(spec, indent=1) + "\n"),), finishes=True, progress=progress,
                       stop_stage=STAGE_RECORDERS if progress else STAGE_NODES)


def _container_processes(
    opts: LaunchOptions,
    houses: Sequence[HousePlan],
    common: dict[str, Any],
    bag: Path,
    info: dict[str, Any],
    spec_dir: Path,
) -> list[ProcessPlan]:
    """Processes of :mod:`comems4build_ros.ros.container` for the layouts ``role`` and ``house``.

    ``role``: recorder processes (one per ``houses_per_recorder``), then one
    EMS, one feed and one plant process for all houses. ``house``: container process
    j runs recorder, EMS, feed and plant of every house i with i mod n = j (n =
    ``containers``, at most the number of houses).
    """
    if effective_layout(opts) == "house":
        n = container_count(opts)
        return [container_process(f"container_{j}", "container",
                              [node for b in houses[j::n]
                               for node in _contained_nodes(opts, b, common, bag, info, b is houses[0])],
                              spec_dir, opts.ems, True)
                for j in range(n)]
    by_role: dict[str, list[NodePlan]] = {"recorder": [], "ems": [], "feed": [], "plant": []}
    for b in houses:
        for node in _contained_nodes(opts, b, common, bag, info, b is houses[0]):
            by_role[node.role].append(node)
    per = opts.houses_per_recorder
    recorders = by_role["recorder"]
    out = [container_process(f"role_recorder_{j // per}", "recorder", recorders[j:j + per], spec_dir, opts.ems, True)
           for j in range(0, len(recorders), per)]
    out += [container_process(f"role_{role}", role, by_role[role], spec_dir, opts.ems, False)
            for role in ("ems", "feed", "plant")]
    return out


Commands = tuple[tuple[str, ...], ...]


def netns_network(domain_id: int, netem: str | None) -> tuple[dict[str, NetworkSide], Commands, Commands, Commands]:
    """Two network namespaces joined by a veth pair: network sides and set-up/tear-down commands.

    Names carry the (locked) domain id, so concurrent launches do not collide: namespaces
    ``c4b<id>p`` (the plant's side) and ``c4b<id>e`` (the EMS's side), link ``10.231.<id>.0/24`` with
    ``.1`` on the plant side and ``.2`` on the EMS side. Each side's processes get UDP-only
    Fast DDS (:data:`FASTDDS_UDP_PROFILE`), ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` and the
    other side as ``ROS_STATIC_PEERS`` (unicast discovery, no multicast needed).
    """
    profile = fastdds_profile(FASTDDS_UDP_PROFILE)
    tags = {"plant_side": ("p", 1), "ems_side": ("e", 2)}
    sides: dict[str, NetworkSide] = {}
    setup: list[tuple[str, ...]] = []
    optional: list[tuple[str, ...]] = []
    teardown: list[tuple[str, ...]] = []
    addr = {g: f"10.231.{domain_id}.{n}" for g, (_, n) in tags.items()}
    for g, (tag, _n) in tags.items():
        other = next(o for o in tags if o != g)
        env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": addr[other], **profile_env(profile)}
        sides[g] = NetworkSide(g, env, netns=f"c4b{domain_id}{tag}", address=addr[g])
    ns_p, ns_e = sides["plant_side"].netns, sides["ems_side"].netns
    dev_p, dev_e = f"{ns_p}0", f"{ns_e}0"
    assert ns_p is not None and ns_e is not None
    setup += [("ip", "netns", "add", ns_p), ("ip", "netns", "add", ns_e),
              ("ip", "link", "add", dev_p, "type", "veth", "peer", "name", dev_e),
              ("ip", "link", "set", dev_p, "netns", ns_p), ("ip", "link", "set", dev_e, "netns", ns_e)]
    for ns, dev, g in ((ns_p, dev_p, "plant_side"), (ns_e, dev_e, "ems_side")):
        setup += [("ip", "-n", ns, "addr", "add", f"{addr[g]}/24", "dev", dev),
                  ("ip", "-n", ns, "link", "set", "lo", "up"), ("ip", "-n", ns, "link", "set", dev, "up")]
        if netem:
            optional.append(("ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", dev, "root", "netem",
                             *netem.split()))
    teardown += [("ip", "netns", "del", ns_p), ("ip", "netns", "del", ns_e)]
    return sides, tuple(setup), tuple(optional), tuple(teardown)
