"""The run plan of a community over ROS 2: its houses' node sets and the coordinator (``launch --community``).

:func:`plan_community` is what :func:`~comems4build_ros.run.plans.plan_any` builds for
``LaunchOptions.community``: the same supervisor starts it (docs/community.md "Over ROS").

* Every house of the community file runs its node set under ``<namespace>/<name>``:
  ``plant_sim`` with ``hub:=true`` (its plant's parameters: the house without electrolyser
  modules, its share of the hub's store as its store), the feed of its scenario
  (``community_house``), the EMS with the house's parameters as its EMS knows them, and a
  recorder of its own bag ``bag/<name>/``; in one container process per house or a few
  (layout ``house``, the default) or one process per node (layout ``node``).
* The coordinator (``coordinator`` node, the row ``coordinator`` of
  ``config/coordinators.yaml``) runs in ``<namespace>`` with its recorder of
  ``bag/coordinator/``.
* Files written before the start: the run's plant parameters (``params/plant.yaml``), a copy of
  the community file (``params/community.yaml``, which every node reads, so the run and its
  evaluation do not depend on the file staying as it was) and each house's two parameter files
  (``params/<name>/ems.yaml``, ``params/<name>/plant.yaml``); the secrets: per house the EMS's
  run secret and the hub secret its plant and the coordinator share.
* Network ``local``: every process on this host. ``netns``: one network namespace ("host")
  per house with every process of that house, one for the coordinator and its recorder, joined
  by a bridge in a namespace of its own (:func:`community_netns`), DDS over UDP.
* Clock ``sim``: lock-step; a house process that leaves fails the run as in any launch.
  ``wall``/``wall:<factor>``: the coordinator paces the steps and goes on without a house that
  left; its processes are marked ``may_leave`` (the supervisor goes on and stops what is left
  of that house at the end).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from comems4build_ros.bags.community import COORDINATOR_BAG
from comems4build_ros.run.plan import (
    CONTAINER_RECORDER_TICK_S,
    CONTAINER_STEP_TIMEOUT_S,
    CONTAINER_WATCHDOG_PERIOD_S,
    DEFAULT_STEP_TIMEOUT_S,
    FASTDDS_UDP_PROFILE,
    LOCAL_SIDE,
    PLANT_PARAMS_FILE,
    PROGRESS_PERIOD_S,
    SECRETS_DIR,
    STAGE_RECORDERS,
    STALL_STEPS,
    Commands,
    HousePlan,
    LaunchOptions,
    NetworkSide,
    NodePlan,
    PlanError,
    ProcessPlan,
    RunPlan,
    backstop_stall_s,
    container_count,
    container_process,
    ems_node_name,
    fastdds_profile,
    feed_window,
    house_params,
    node_command,
    profile_env,
    recorder_params,
    ros_args,
    run_info,
    run_time_limit,
    unread_inputs,
    with_discovery_server,
)
from comems4build_ros.wire.tokens import new_token

#: The community file as the run's nodes read it, under the output directory.
COMMUNITY_FILE = Path("params") / "community.yaml"
#: Layouts of a community run (``role`` would put several houses' nodes of one kind in one process,
#: which a network namespace per house cannot hold).
COMMUNITY_LAYOUTS = ("node", "house")


@dataclasses.dataclass(frozen=True)
class CommunityHouse:
    """One house of a community run.

    Attributes
    ----------
    name : its name in the community file
    plan : its namespace, bag and EMS run secret
    hub_token_file : the hub secret its plant and the coordinator share
    ems_file, plant_file : its parameter files (as its EMS knows the house; its plant)
    """

    name: str
    plan: HousePlan
    hub_token_file: str
    ems_file: str
    plant_file: str


def community_layout(opts: LaunchOptions) -> str:
    """The process layout of a community run: ``layout`` as given (``node`` or ``house``), else ``house``.

    Raises
    ------
    PlanError
        For layout ``role``.
    """
    layout = opts.layout or "house"
    if layout not in COMMUNITY_LAYOUTS:
        raise PlanError(f"a community runs in layout {' or '.join(COMMUNITY_LAYOUTS)}, not '{layout}'")
    return layout


def check_community_options(opts: LaunchOptions) -> None:
    """What a community run cannot take (PlanError naming the option)."""
    from comems4build_ros.mqtt.clock import parse_clock

    if opts.plant != "sim":
        raise PlanError("a community runs plant_sim for every house (plant 'sim')")
    if opts.houses != 1:
        raise PlanError("a community's houses are those of its file (no --houses)")
    if opts.building != "rc":
        raise PlanError("a community runs every house on the 4R3C (no --building)")
    if opts.inputs != "scenario":
        raise PlanError("a community runs on the scenario's inputs (no --inputs live)")
    if opts.broker_url or opts.topic_map:
        raise PlanError("a community has no house behind MQTT (no broker, no topic map)")
    if opts.network == "netns" and opts.containers is not None:
        raise PlanError("on the netns network every house has a host of its own (no --containers)")
    if opts.netem and opts.network != "netns":
        raise PlanError("netem applies to the 'netns' network only")
    parse_clock(opts.clock)
    community_layout(opts)


def check_over_ros(name: str) -> None:
    """Refuse a coordinator the coordinator node cannot run: one that reads the houses' observations.

    A coordinator of information level ``mpc`` (the central and the distributed one) reads every
    house's states and forecasts at the MPC's level each step; the coordinator node receives only
    the houses' reports (``hub/report``), so over ROS 2 only coordinators of level ``hub`` run.

    Raises
    ------
    PlanError, UnknownCoordinatorError
        Naming the coordinator and those that run over ROS 2; an unknown name.
    """
    from comems4build_ros.core.community.coordinator import coordinator_class, coordinator_names

    def level(n: str) -> str:
        return str(getattr(coordinator_class(n), "info_level", "hub"))

    if level(name) != "hub":
        runs = ", ".join(n for n in coordinator_names() if level(n) == "hub")
        raise PlanError(f"coordinator '{name}' reads every house's MPC-level observation (its states and "
                         f"forecasts), which the coordinator node does not receive over ROS 2; over ROS 2 run "
                         f"a coordinator of information level hub ({runs}); compare --community runs every "
                         "coordinator in process")


def plan_community(opts: LaunchOptions, domain_id: int, params: Any) -> RunPlan:
    """The plan of the community run of ``opts`` (module docstring); starts nothing.

    Raises
    ------
    PlanError, ConfigError
        For options a community run cannot take, a bad community file, a house variation the
        plant refuses, or a house named like the coordinator's bag.
    """
    from comems4build_ros.core.community.spec import house_plants, load_community
    from comems4build_ros.mqtt.peer import new_run_id
    from comems4build_ros.ros.parameters import plant_params_file_text

    check_community_options(opts)
    assert opts.community is not None
    check_over_ros(opts.coordinator)  # an unknown coordinator, or one the node cannot run, named before anything starts
    out = Path(opts.out)
    bag = Path(opts.bag) if opts.bag is not None else out / "bag"
    source = Path(opts.community)
    spec = load_community(source)
    if COORDINATOR_BAG in {h.name for h in spec.houses}:
        raise PlanError(f"{source}: a house may not be called '{COORDINATOR_BAG}' (the coordinator's bag)")
    if opts.network == "netns" and len(spec.houses) > NETNS_MAX_HOUSES:
        raise PlanError(f"{source}: {len(spec.houses)} houses; the netns network has hosts for "
                         f"{NETNS_MAX_HOUSES} (one /24 link)")
    base_file = str((out / PLANT_PARAMS_FILE).resolve())
    community_file = str((out / COMMUNITY_FILE).resolve())
    files: list[tuple[str, str]] = [(base_file, plant_params_file_text(params)),
                                    (community_file, source.read_text(encoding="utf-8"))]
    secret_dir = (out / SECRETS_DIR).resolve()
    root = opts.namespace.rstrip("/")
    houses: list[CommunityHouse] = []
    plants = house_plants(spec, opts.config_files, opts.overrides, params, str(source))
    for h, (ems_params, plant_params, _share) in zip(spec.houses, plants):
        ems_file = (out / "params" / h.name / "ems.yaml").resolve()
        plant_file = (out / "params" / h.name / "plant.yaml").resolve()
        files += [(str(ems_file), plant_params_file_text(ems_params)),
                  (str(plant_file), plant_params_file_text(plant_params))]
        houses.append(CommunityHouse(h.name, HousePlan(f"{root}/{h.name}", opts.seed, bag / h.name, new_token(),
                                                       str(secret_dir / f"{h.name}.token")),
                                     str(secret_dir / f"{h.name}.hub.token"), str(ems_file), str(plant_file)))
    secrets = [*((c.plan.token_file, c.plan.token) for c in houses), *((c.hub_token_file, new_token()) for c in houses)]
    info = community_run_info(opts, params, houses, new_run_id(), community_file, base_file)
    layout = community_layout(opts)
    as_houses = dataclasses.replace(opts, houses=len(houses))
    processes = [*_coordinator_processes(opts, houses, bag, info, community_file, base_file),
                 *_house_processes(as_houses, houses, layout, info, community_file, base_file, out / "containers")]
    processes, server = with_discovery_server(as_houses, layout, domain_id, processes)
    sides: dict[str, NetworkSide] = {LOCAL_SIDE: NetworkSide(LOCAL_SIDE)}
    setup: Commands = ()
    optional_setup: Commands = ()
    teardown: Commands = ()
    if opts.network == "netns":
        sides, setup, optional_setup, teardown = community_netns(domain_id, [c.name for c in houses], opts.netem)
        processes = [_on_side(p, sides, root) for p in processes]
    return RunPlan(
        ems=opts.ems,
        out=out,
        bag=bag,
        domain_id=domain_id,
        layout=layout,
        houses=tuple(c.plan for c in houses),
        sides=sides,
        setup=setup,
        optional_setup=optional_setup,
        teardown=teardown,
        processes=tuple(processes),
        run_info=info,
        timeout_s=run_time_limit(as_houses),
        stall_s=backstop_stall_s(opts, layout),
        secrets=tuple(secrets),
        files=tuple(files),
        clock=f"{houses[0].plan.namespace}/plant_sim",
        discovery_server=server,
    )


def community_run_info(opts: LaunchOptions, params: Any, houses: list[CommunityHouse], run_id: str,
                       community_file: str, base_file: str) -> dict[str, Any]:
    """The run's description in the coordinator's bag (``run_info.json``): the isolated run's
    (:func:`~comems4build_ros.run.plan.run_info`) on the run's plant file, and ``community``: the
    community file as the nodes read it, the coordinator, its options and the houses (name,
    namespace, bag); what a community evaluation of the bags needs."""
    weeks, steps = feed_window(opts.weeks, opts.steps)
    from comems4build_ros.core.scenario import is_embedded

    scenario = str(opts.scenario) if is_embedded(opts.scenario) else str(Path(opts.scenario).resolve())
    window = {"scenario": scenario, "weeks": weeks, "steps": steps, "seed": opts.seed, "start": opts.start}
    info = run_info(opts, params, [opts.seed], run_id)
    info.update(config_files=[base_file], overrides={},
                houses=[{"namespace": c.plan.namespace, "seed": opts.seed} for c in houses],
                community={"file": community_file, "source": str(Path(opts.community or "").resolve()),
                           "coordinator": opts.coordinator, "coordinator_options": list(opts.coordinator_options),
                           "clock": opts.clock, "namespace": opts.namespace, "bag": COORDINATOR_BAG,
                           "window": window,
                           "houses": [{"name": c.name, "namespace": c.plan.namespace, "bag": c.name}
                                      for c in houses]})
    return info


def house_run_info(info: dict[str, Any], house: CommunityHouse) -> dict[str, Any]:
    """``run_info.json`` of one house's bag: the run's, on the house's plant file (``comems4build
    evaluate`` of the bag alone gives the house's KPIs with its own plant), and its name."""
    return {**{k: v for k, v in info.items() if k != "community"}, "config_files": [house.plant_file],
            "overrides": {}, "houses": [{"namespace": house.plan.namespace, "seed": house.plan.seed}],
            "house": house.name}


def coordinator_params(opts: LaunchOptions, houses: list[CommunityHouse], community_file: str,
                       base_file: str) -> dict[str, Any]:
    """Parameters of the coordinator node (the scenario's as the feeds', the houses' hub secrets)."""
    weeks, steps = feed_window(opts.weeks, opts.steps)
    step_timeout = float(opts.plant_node_params.get("step_timeout_s", CONTAINER_STEP_TIMEOUT_S
                                                    if community_layout(opts) == "house" else DEFAULT_STEP_TIMEOUT_S))
    params: dict[str, Any] = {
        "config_files": [base_file], "community_file": community_file, "coordinator": opts.coordinator,
        "coordinator_options": list(opts.coordinator_options), "scenario": str(opts.scenario), "weeks": weeks,
        "steps": steps, "hub_token_files": [c.hub_token_file for c in houses], "clock": opts.clock,
        "wait_for_recorder": True, "stall_steps": STALL_STEPS, "for_ems": ems_node_name(opts.ems),
        # a house falls back after its plant's step time-out: the coordinator waits for that first
        "step_timeout_s": 2.0 * step_timeout,
    }
    if opts.seed is not None:
        params["seed"] = int(opts.seed)
    if opts.start:
        params["start"] = opts.start
    return params


def _coordinator_processes(opts: LaunchOptions, houses: list[CommunityHouse], bag: Path, info: dict[str, Any],
                           community_file: str, base_file: str) -> list[ProcessPlan]:
    """The coordinator's recorder (``follows:=coordinator``, its bag ``bag/coordinator``) and the coordinator."""
    ns = opts.namespace
    rec = dict(recorder_params(ns, bag / COORDINATOR_BAG, info, 0.0, (), clock=False), follows="coordinator")
    params = coordinator_params(opts, houses, community_file, base_file)
    prefix = ns.strip("/") + "/" if ns.strip("/") else ""
    return [
        ProcessPlan(f"{prefix}coordinator_recorder", "recorder", (*node_command("recorder"), *ros_args(ns, rec)),
                    nodes=(NodePlan("recorder", "recorder", ns, rec),), finishes=True, stop_stage=STAGE_RECORDERS),
        ProcessPlan(f"{prefix}coordinator", "coordinator", (*node_command("coordinator"), *ros_args(ns, params)),
                    nodes=(NodePlan("coordinator", "coordinator", ns, params),), finishes=True),
    ]


def house_nodes(opts: LaunchOptions, house: CommunityHouse, info: dict[str, Any], community_file: str,
                base_file: str, clock: bool, contained: bool) -> list[NodePlan]:
    """Recorder, EMS, feed and plant of one house of the community (``clock``: its plant publishes
    ``/clock``; ``contained``: as nodes of a container process, timers slower, step time-out longer)."""
    b = house.plan
    roles = house_params(opts, b.seed, {"config_files": [base_file]}, b.token_file, clock, info["run_id"])
    roles["ems"]["config_files"] = [house.ems_file]
    roles["feed"].update(community_file=community_file, community_house=house.name)
    # plant_sim checks the EMS's commands against the house as its EMS knows it, and builds its plant
    # without the electrolyser modules (core.community.spec.house_plant)
    roles["plant"].update(config_files=[house.ems_file], hub=True, hub_token_file=house.hub_token_file,
                          clock=opts.clock)
    rec = recorder_params(b.namespace, b.bag, house_run_info(info, house), 0.0 if contained else PROGRESS_PERIOD_S,
                          unread_inputs(opts), clock)
    if contained:
        rec["tick_s"] = CONTAINER_RECORDER_TICK_S
        roles["plant"] = {"step_timeout_s": CONTAINER_STEP_TIMEOUT_S,
                          "watchdog_period_s": CONTAINER_WATCHDOG_PERIOD_S, **roles["plant"]}
    names = {"ems": ems_node_name(opts.ems), "feed": "feed", "plant": "plant_sim"}
    return [NodePlan("recorder", "recorder", b.namespace, rec),
            *(NodePlan(role, names[role], b.namespace, p) for role, p in roles.items())]


def _house_processes(opts: LaunchOptions, houses: list[CommunityHouse], layout: str, info: dict[str, Any],
                     community_file: str, base_file: str, spec_dir: Path) -> list[ProcessPlan]:
    """The houses' processes: one container per house or per few houses (layout ``house``; one per
    house on the netns network) or one process per node (layout ``node``). On a wall clock every
    one may leave (the community goes on without its houses)."""
    from comems4build_ros.mqtt.clock import parse_clock

    may_leave = parse_clock(opts.clock).wall
    out: list[ProcessPlan] = []
    if layout == "house":
        n = len(houses) if opts.network == "netns" else container_count(opts)
        for j in range(n):
            nodes = [node for c in houses[j::n]
                     for node in house_nodes(opts, c, info, community_file, base_file, c is houses[0], True)]
            out.append(dataclasses.replace(container_process(f"container_{j}", "container", nodes, spec_dir,
                                                             opts.ems, True), may_leave=may_leave))
        return out
    exe = {"recorder": ("recorder", None), "ems": ("ems", opts.ems), "feed": ("feed", None),
           "plant": ("plant_sim", None)}
    for c in houses:
        for node in house_nodes(opts, c, info, community_file, base_file, c is houses[0], False):
            name, ems = exe[node.role]
            out.append(ProcessPlan(
                f"{c.plan.namespace.strip('/')}/{node.name}", node.role,
                (*node_command(name, ems), *ros_args(node.namespace, node.params)), nodes=(node,), finishes=True,
                progress=node.role == "recorder", stop_stage=STAGE_RECORDERS if node.role == "recorder" else 0,
                may_leave=may_leave))
    return out


#: Most houses on the netns network (hosts .2 .. .254 of one /24 link; .1 is the coordinator's).
NETNS_MAX_HOUSES = 250


def community_netns(domain_id: int, names: list[str], netem: str | None) -> tuple[
        dict[str, NetworkSide], Commands, Commands, Commands]:
    """One network namespace ("host") per house and one for the coordinator, joined by a bridge.

    Names carry the (locked) domain id: hosts ``c4b<id>h0`` (the coordinator) and ``c4b<id>h<i+1>``
    (house ``i``), the bridge ``br0`` in a namespace ``c4b<id>b`` of its own (nothing of the run
    is left in the host's own network namespace), one veth pair per host; link
    ``10.231.<id>.0/24``, host ``j`` at ``.j+1``. Every process gets UDP-only Fast DDS
    (:data:`~comems4build_ros.run.plan.FASTDDS_UDP_PROFILE`), ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``
    and as ``ROS_STATIC_PEERS`` the hosts it talks to: a house the coordinator's, the coordinator
    every house's. ``netem`` arguments go on every host's end of its link (optional).
    """
    profile = fastdds_profile(FASTDDS_UDP_PROFILE)
    bridge = f"c4b{domain_id}b"
    hosts = ["coordinator", *(f"house_{n}" for n in names)]
    addr = {h: f"10.231.{domain_id}.{j + 1}" for j, h in enumerate(hosts)}
    setup: list[tuple[str, ...]] = [("ip", "netns", "add", bridge),
                                    ("ip", "-n", bridge, "link", "add", "br0", "type", "bridge"),
                                    ("ip", "-n", bridge, "link", "set", "br0", "up")]
    optional: list[tuple[str, ...]] = []
    teardown: list[tuple[str, ...]] = []
    sides: dict[str, NetworkSide] = {}
    for j, h in enumerate(hosts):
        ns, dev, peer = f"c4b{domain_id}h{j}", f"c4b{domain_id}v{j}", f"c4b{domain_id}p{j}"
        peers = ";".join(addr[o] for o in hosts if o != h) if h == "coordinator" else addr["coordinator"]
        env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": peers, **profile_env(profile)}
        sides[h] = NetworkSide(h, env, netns=ns, address=addr[h])
        setup += [("ip", "netns", "add", ns), ("ip", "link", "add", dev, "type", "veth", "peer", "name", peer),
                  ("ip", "link", "set", dev, "netns", ns), ("ip", "link", "set", peer, "netns", bridge),
                  ("ip", "-n", bridge, "link", "set", peer, "master", "br0"),
                  ("ip", "-n", bridge, "link", "set", peer, "up"),
                  ("ip", "-n", ns, "addr", "add", f"{addr[h]}/24", "dev", dev),
                  ("ip", "-n", ns, "link", "set", "lo", "up"), ("ip", "-n", ns, "link", "set", dev, "up")]
        if netem:
            optional.append(("ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", dev, "root", "netem",
                             *netem.split()))
        teardown.append(("ip", "netns", "del", ns))
    teardown.append(("ip", "netns", "del", bridge))
    return sides, tuple(setup), tuple(optional), tuple(teardown)


def _on_side(p: ProcessPlan, sides: dict[str, NetworkSide], root: str) -> ProcessPlan:
    """``p`` on its host of the netns network: the coordinator's, or that of the house whose nodes it runs."""
    if any(n.role == "coordinator" or n.params.get("follows") == "coordinator" for n in p.nodes):
        side = "coordinator"
    else:
        names = {n.namespace[len(root) + 1:] for n in p.nodes}
        if len(names) != 1:
            raise ValueError(f"process '{p.name}' runs nodes of {len(names)} houses: on the netns network each "
                             "house has a host of its own")
        side = f"house_{names.pop()}"
    netns = sides[side].netns
    assert netns is not None
    return dataclasses.replace(p, side=side, argv=("ip", "netns", "exec", netns, *p.argv))
