"""``comems4build launch``: the ROS 2 node set as separate processes, evaluated from the bag."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import (
    COUNT,
    DOMAIN_ID,
    HOUSES,
    MAX_HOUSES,
    SECONDS,
    SEED,
    add_building_options,
    add_forecast_option,
    add_scenario_options,
    ems_help,
)
from comems4build_ros.files.errors import InputError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``launch``."""
    parser.add_argument("--ems", metavar="NAME", required=True,
                        help=ems_help())
    add_scenario_options(parser, hours=False, seed=False, extend=False)
    parser.add_argument("--steps", metavar="N", type=COUNT, default=None,
                        help="cut the run to its first N steps, integer >= 1 (short runs)")
    parser.add_argument("--houses", metavar="N", type=HOUSES, default=1,
                        help="independent houses under /house_<i>/, scenario seed + i, integer 1 .. "
                             f"{MAX_HOUSES} (default 1)")
    parser.add_argument("--seed", metavar="N", type=SEED, default=None,
                        help="scenario seed of house 0 (default scenario; 0 .. 2^32-1)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="parameter file merged over config/plant.yaml (repeatable)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one plant parameter, e.g. --set battery.e_max_kwh=10 (repeatable)")
    parser.add_argument("--ems-option", action="append", default=[], metavar="KEY=VALUE",
                        help="option passed to the EMS (repeatable)")
    add_forecast_option(parser)
    add_building_options(parser)
    parser.add_argument("--all-inputs", action="store_true",
                        help="the feed publishes every EMS input (tab:level_of_information), also what this EMS does "
                             "not read, so that the bag can drive any EMS with 'replay --inputs-only'")
    parser.add_argument("--domain-id", metavar="ID", type=DOMAIN_ID, default=None,
                        help="ROS_DOMAIN_ID of the run, 0 .. 232 (default: a free id, locked for the run)")
    parser.add_argument("--step-timeout", metavar="S", type=SECONDS, default=None,
                        help="plant_sim's wait for a command before its safe fallback [s], 0.01 .. a year")
    parser.add_argument("--timeout", metavar="S", type=SECONDS, default=None,
                        help="give up after this wall time [s], 0.01 .. a year")
    parser.add_argument("--plant", choices=("sim", "mqtt"), default="sim",
                        help="sim: plant_sim on ROS; mqtt: the simulated house behind MQTT via mqtt_bridge")
    parser.add_argument("--clock", metavar="sim|wall|wall:F", type=_clock, default="sim",
                        help="sim (lock-step), wall (a step per hour), wall:<factor> (faster); wall needs --plant mqtt "
                             "or --community (whose coordinator then goes on without a house that leaves)")
    parser.add_argument("--broker", metavar="URL", type=_broker_url, default=None,
                        help="MQTT broker, mqtt://host:port or mqtts://host:port (default: an embedded amqtt broker)")
    parser.add_argument("--topic-map", metavar="FILE", default=None, help="MQTT topic map (default config/mqtt.yaml)")
    parser.add_argument("--inputs", choices=("scenario", "live"), default="scenario",
                        help="feed inputs: the scenario (default) or live aWATTar prices and weather (real houses; "
                             "refused with exit code 2 when no live price for the current hour can be had)")
    parser.add_argument("--live-config", metavar="FILE", default=None,
                        help="live-input settings for --inputs live (default config/live_inputs.yaml)")
    parser.add_argument("--out", metavar="DIR", required=True,
                        help="output directory (bag/, log/, weekly.csv, summary.json)")
    parser.add_argument("--bag", metavar="DIR", default=None,
                        help="bag directory to create (default DIR/bag of --out)")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--network", choices=("local", "netns"), default="local",
                        help="local (default) or netns: plant+feed and EMS+recorder in two network namespaces "
                             "joined by a veth pair, DDS over UDP with unicast discovery (root, 'ip netns')")
    parser.add_argument("--netem", default=None, metavar="ARGS", type=_netem,
                        help="with --network netns: 'tc netem' arguments of the link, e.g. 'delay 5ms loss 1%%' "
                             "(skipped with a note where the kernel lacks netem)")
    parser.add_argument("--layout", choices=("node", "house", "role"), default=None,
                        help="processes: node = one per node (default for 1 house), house = container "
                             "processes each running every node of some houses (default for more), role = one "
                             "per role for all houses")
    parser.add_argument("--containers", metavar="N", type=COUNT, default=None,
                        help="container processes of --layout house (implies it), house i in container "
                             "i mod N (default: one per core)")
    parser.add_argument("--namespace", metavar="NS", type=_namespace, default="/",
                        help="ROS namespace of the house (one house) or of the houses' namespaces "
                             "house_<i> (default /)")
    parser.add_argument("--community", metavar="FILE", default=None,
                        help="run the community of FILE (e.g. config/community/default.yaml): every house's node set "
                             "under <namespace>/<house>, sharing one H2 hub that the coordinator node keeps; "
                             "evaluated into community.json, hub.csv, houses.csv and houses/<house>/ "
                             "(docs/community.md 'Over ROS')")
    parser.add_argument("--coordinator", metavar="NAME", default=None,
                        help="with --community: the coordinator of config/coordinators.yaml (default rule)")
    parser.add_argument("--coordinator-option", action="append", default=[], metavar="KEY=VALUE",
                        help="with --community: an option of the coordinator over its row's, e.g. h2_split=need "
                             "(repeatable)")
    parser.add_argument("--print-plan", action="store_true",
                        help="print the run plan (processes, nodes, parameters) and exit without starting anything")


def _clock(text: str) -> str:
    """``--clock`` value, checked by :func:`comems4build_ros.mqtt.clock.parse_clock`."""
    from comems4build_ros.mqtt.clock import ClockError, parse_clock

    try:
        return parse_clock(text).spec()
    except ClockError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def check_clock(text: str, step_h: float) -> None:
    """``--clock`` with the run's time step: the wall time of a step in its range
    (:func:`comems4build_ros.mqtt.clock.check_period`), a usage error naming ``--clock`` otherwise."""
    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.mqtt.clock import ClockError, parse_clock

    try:
        parse_clock(text, step_h)
    except ClockError as exc:
        raise UsageError(f"--clock: {exc}") from None


def _namespace(text: str) -> str:
    """``--namespace`` value: an absolute ROS namespace (:func:`comems4build_ros.run.plan.namespaces`)."""
    from comems4build_ros.run.plan import namespaces

    try:
        return namespaces(1, text)[0]
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _netem(text: str) -> str:
    """``--netem`` value, checked by :func:`comems4build_ros.app.commands.netem.check_netem` (tc-netem(8))."""
    from comems4build_ros.app.commands.netem import NetemError, check_netem

    try:
        return check_netem(text)
    except NetemError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _broker_url(text: str) -> str:
    """``--broker`` value, checked by :func:`comems4build_ros.mqtt.topicmap.check_broker_url`."""
    from comems4build_ros.mqtt.topicmap import check_broker_url

    try:
        return check_broker_url(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def check_plant_options(args: argparse.Namespace) -> None:
    """``--plant``, ``--clock``, ``--broker``, ``--topic-map``, ``--netem`` and their combinations.

    A bad combination raises :class:`UsageError` naming the options; with ``--plant mqtt``
    the topic map is read and checked whole (:class:`~comems4build_ros.core.config.ConfigError`
    naming the file and the parameter).
    """
    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.core.config import check_input_file

    if args.topic_map is not None:
        check_input_file(args.topic_map, "--topic-map")
    community = getattr(args, "community", None) is not None
    if args.plant != "mqtt" and ((args.clock != "sim" and not community) or args.broker or args.topic_map):
        raise UsageError("--clock wall needs --plant mqtt or --community; --broker and --topic-map need --plant mqtt")
    if args.plant == "mqtt" and args.houses != 1:
        raise UsageError("--plant mqtt runs one house (--houses 1)")
    if args.netem is not None and args.network != "netns":
        raise UsageError("--netem needs --network netns")
    layout = getattr(args, "layout", None)
    if layout in ("node", "role") and getattr(args, "containers", None) is not None:
        raise UsageError(f"--containers needs --layout house, not --layout {layout}")
    if (layout == "house" or getattr(args, "containers", None) is not None) and (
            args.plant != "sim" or args.network != "local"):
        raise UsageError("--layout house and --containers need --plant sim and --network local")
    if args.broker and args.network != "local":
        raise UsageError("--broker needs --network local (the netns namespaces reach no other host)")
    if args.plant == "mqtt":  # the whole topic map, as bridge and house will read it, before they start
        from comems4build_ros.mqtt.topicmap import load_topic_map

        load_topic_map(args.topic_map, args.broker)


def _building(args: argparse.Namespace) -> str:
    """``--building``: checked before anything starts; a detailed model needs plant_sim (``--plant sim``)."""
    from comems4build_ros.app.commands.options import UsageError, building_choice

    choice = building_choice(args)
    if choice.kind == "rc":
        return "rc"
    if getattr(args, "plant", "sim") != "sim":
        raise UsageError(f"--building {choice.text} needs --plant sim (the building model runs inside plant_sim)")
    if choice.map_path is not None and getattr(args, "building_map", None):
        raise UsageError("--building-map: over ROS put the map beside the FMU as FILE.map.yaml")
    if choice.epw is not None:
        raise UsageError("--epw: over ROS plant_sim writes the weather file from the feed's scenario")
    return choice.text


def launch_options(args: argparse.Namespace) -> Any:
    """Check every input of ``launch`` (before anything starts) and return its
    :class:`~comems4build_ros.run.plan.LaunchOptions`; the ROS 2 launch file builds its
    plan through this same function (:mod:`comems4build_ros.app.ros2_launch`).

    Raises
    ------
    UsageError
        Naming the option, file or parameter that is invalid.
    """
    from comems4build_ros.app.commands.options import UsageError, add_scenario_config, ems_controller, load_params
    from comems4build_ros.app.commands.simulate import parse_assignments
    from comems4build_ros.core.ems import UnknownEMSError, controller_class
    from comems4build_ros.run.plan import LaunchOptions

    add_scenario_config(args)  # --scenario year: its plant file first (the params below are the run's)
    try:
        controller_class(args.ems)
    except UnknownEMSError as exc:
        raise UsageError(str(exc)) from None
    check_plant_options(args)
    overrides = parse_assignments(args.set, "--set")
    params = load_params(args.config, overrides)
    check_clock(args.clock, params.simulation.time_step_h)
    ems_controller(args.ems, params, args.ems_option)  # the EMS node's own checks, before any node starts
    check_feed_scenario(args, params)
    check_live_inputs(args, params)
    args.building_text = _building(args)
    coordinator = check_community(args, overrides)
    return LaunchOptions(
        ems=args.ems,
        out=Path(args.out),
        scenario=args.scenario,
        weeks=args.weeks,
        steps=args.steps,
        start=args.start,
        houses=args.houses,
        seed=args.seed,
        config_files=list(args.config),
        overrides=overrides,
        ems_options=list(args.ems_option),
        forecast=args.forecast,
        domain_id=args.domain_id,
        timeout_s=args.timeout,
        progress=not args.no_progress and sys.stderr.isatty(),
        plant_node_params={} if args.step_timeout is None else {"step_timeout_s": float(args.step_timeout)},
        plant=args.plant,
        clock=args.clock,
        broker_url=args.broker,
        topic_map=args.topic_map,
        inputs=args.inputs,
        live_config=getattr(args, "live_config", None),
        network=args.network,
        netem=args.netem,
        containers=args.containers,
        layout=args.layout,
        namespace=args.namespace,
        bag=Path(args.bag) if args.bag else None,
        all_inputs=bool(args.all_inputs),
        building=getattr(args, "building_text", "rc"),
        params=params,  # checked once here; the plan hands them to every node as one file
        community=getattr(args, "community", None),
        coordinator=coordinator,
        coordinator_options=list(getattr(args, "coordinator_option", [])),
    )


def check_community(args: argparse.Namespace, overrides: dict[str, Any]) -> str:
    """``--community``, ``--coordinator`` and ``--coordinator-option``: the community file, its houses'
    plants, the run's window for every house and the coordinator with its options, built as the
    nodes will build them, before anything starts; the coordinator's name.

    Raises
    ------
    UsageError, ConfigError
        Naming the option, the file, the house or the option that is invalid.
    """
    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.core.community.coordinator import make_coordinator
    from comems4build_ros.core.community.hub import community_hub
    from comems4build_ros.core.community.hubrun import community_info
    from comems4build_ros.core.community.spec import build_community, load_community
    from comems4build_ros.core.config import parse_assignments
    from comems4build_ros.run.community import check_over_ros
    from comems4build_ros.run.plan import feed_window

    community = getattr(args, "community", None)
    name = getattr(args, "coordinator", None)
    options = list(getattr(args, "coordinator_option", []))
    if community is None:
        if name is not None or options:
            raise UsageError("--coordinator and --coordinator-option apply with --community")
        return "rule"
    if args.houses != 1:
        raise UsageError("--community runs the houses of its file (no --houses)")
    if args.plant != "sim" or args.inputs != "scenario" or getattr(args, "building_text", "rc") != "rc":
        raise UsageError("--community runs plant_sim on the scenario and the 4R3C for every house (no --plant mqtt, "
                         "--inputs live, --building)")
    if args.layout == "role":
        raise UsageError("--community runs in --layout house or node (a netns host per house)")
    name = name or "rule"
    try:
        check_over_ros(name)  # an unknown coordinator, or one that reads the houses' observations
    except ValueError as exc:
        raise UsageError(f"--coordinator {name}: {exc}") from None
    spec = load_community(community)
    weeks, steps = feed_window(args.weeks, args.steps)
    built = build_community(spec, args.scenario, args.config, overrides, source=str(community), start=args.start,
                            weeks=weeks or None, seed=args.seed, steps=steps or None)
    try:
        make_coordinator(name, community_info(built, community_hub(built)),
                         parse_assignments(options, "--coordinator-option"))
    except (ValueError, TypeError) as exc:
        raise UsageError(f"--coordinator {name} --coordinator-option: {exc}") from None
    args.run_steps = int(built.scenario.n_steps) * len(built.houses)  # the bags' size against the free space
    return name


def run(args: argparse.Namespace) -> int:
    """Validate every input, then launch, wait, evaluate; print the main figures."""
    from comems4build_ros.app.commands.options import add_scenario_config

    add_scenario_config(args)
    from comems4build_ros.app.commands.options import output_dir
    from comems4build_ros.app.commands.simulate import warn_run
    from comems4build_ros.files.outputs import BAG_BYTES_PER_STEP, check_free_space
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.supervisor import LaunchError

    opts = launch_options(args)
    if args.print_plan:
        from comems4build_ros.run.plans import plan_any

        print(plan_any(opts, args.domain_id if args.domain_id is not None else 0).describe())
        return 0
    output = output_dir(args, "launch", in_place=True)
    output.check()
    own_bag = check_bag_dir(args, output.path)
    check_free_space(own_bag or output.path / "bag", getattr(args, "run_steps", 0) * args.houses * BAG_BYTES_PER_STEP,
                     "--bag" if own_bag else "--out", f"the bag of {args.houses} house(s) x "
                     f"{getattr(args, 'run_steps', 0)} steps")
    keys = ("weeks", "cost_eur_week_median", "discomfort_kh_week_median", "discomfort_weeks_nonzero",
            "buy_kwh_week_median", "sell_kwh_week_median", "loh_end", "fallback_steps")
    # the run writes into --out itself (its logs and bag can be watched there), an earlier run's results kept
    # aside until it ends: an interrupted run leaves them as they were, a finished or cut run replaces them
    with output:
        out = output.path
        for cache in output.previous_entries("live_*.json"):  # the live inputs' caches (config/live_inputs.yaml)
            shutil.copy2(cache, out / cache.name)
        try:
            result = launch(opts)
        except LaunchError as exc:
            # first: that the run was cut and why (the message names the node, its exit code and log)
            print(f"comems4build launch: {exc}", file=sys.stderr)
            for ns, s in exc.summaries.items():
                inc = s.get("bag_incomplete", {})
                print(json.dumps({"house": ns, "run_cut": True, "steps_recorded": inc.get("steps_recorded"),
                                  "steps_expected": inc.get("steps_expected"), **{k: s.get(k) for k in keys}}))
            bag = own_bag or out / "bag"
            if exc.summaries:
                print(f"comems4build launch: the run was cut short: the figures above cover only the steps recorded; "
                      f"{bag} is kept and marked incomplete (run_cut.json), summaries in {out}", file=sys.stderr)
            output.commit()
            return 1
        except BaseException:
            if own_bag is not None:  # all or nothing: the bag this run started goes with it
                shutil.rmtree(own_bag, ignore_errors=True)
            raise
    for ns, s in result.summaries.items():
        print(json.dumps({"house": ns, **{k: s.get(k) for k in keys}}))
    print(f"ROS domain {result.domain_id}: {len(result.summaries)} house(s), wall {result.wall_s:.1f} s "
          f"(run {result.run_s:.1f} s after the first record)")
    if result.community is not None:
        from comems4build_ros.bags.community import community_summary_line

        print(community_summary_line(result.community))
        print(f"wrote {own_bag or out / 'bag'}, {out / 'community.json'}, {out / 'hub.csv'}, {out / 'houses.csv'}, "
              f"{out / 'houses'}/")
    else:
        print(f"wrote {own_bag or out / 'bag'}, {out / 'weekly.csv'}, {out / 'summary.json'}")
    return max([warn_run(s, "launch") for s in result.summaries.values()], default=0)


def check_bag_dir(args: argparse.Namespace, out: Path) -> Path | None:
    """``--bag DIR`` (None without): not yet there, not an input, in a directory the recorder can write.

    Checked before any node starts: a recorder that cannot create its bag would fail only
    after every node started. Without ``--bag`` the bag goes to ``bag/`` of the run's stage
    in ``--out`` (checked with it).

    Raises
    ------
    OutputPathError
        Naming ``--bag`` and the reason.
    """
    from comems4build_ros.app.commands.options import command_inputs
    from comems4build_ros.files.outputs import OutputPathError, check_not_input, check_out_dir, check_out_text

    if not args.bag:
        return None
    bag = check_out_text(args.bag, "--bag")
    if bag.exists() or bag.is_symlink():
        raise OutputPathError(f"--bag {bag}: exists (a bag is never written over: choose another --bag or remove it)")
    check_out_dir(bag, "--bag")
    check_not_input(bag, command_inputs(args), "--bag")
    return bag


def check_live_inputs(args: argparse.Namespace, params: Any) -> None:
    """``--live-config`` (needs ``--inputs live``) and, for a run on live inputs, a live
    price for the current hour, fetched as the feed will fetch it (or cached): without it
    the run is refused (:class:`UsageError` naming the source URL), before any node starts.
    ``--print-plan`` fetches nothing."""
    import shutil
    import tempfile
    import time

    from comems4build_ros.app.commands.options import UsageError
    from comems4build_ros.core.config import check_input_file
    from comems4build_ros.core.scenario.live import LiveInputsError, PriceSource, load_live_settings

    live_config = getattr(args, "live_config", None)
    if live_config is not None:
        if args.inputs != "live":
            raise UsageError("--live-config needs --inputs live")
        check_input_file(live_config, "--live-config")
    if args.inputs != "live":
        return
    settings = load_live_settings(live_config).prices
    if args.print_plan:
        return
    cache = Path(settings.cache_file) if settings.cache_file else Path(args.out) / "live_prices.json"
    with tempfile.TemporaryDirectory(prefix="comems4build_live_") as tmp:
        probe = cache
        if not settings.cache_file or not cache.parent.is_dir():  # nothing goes into --out before the run
            probe = Path(tmp) / cache.name
            if cache.is_file():
                shutil.copy(cache, probe)
        prices = PriceSource(settings, params.site.timezone, probe, lambda text: None)
        prices.refresh(force=True)
        try:
            prices.require(time.time())
        except LiveInputsError as exc:
            raise UsageError(f"--inputs live: {exc}") from None


def check_feed_scenario(args: argparse.Namespace, params: Any) -> None:
    """Build house 0's scenario exactly as its ``feed`` node will, before any node starts.

    The feed's own loader and checks run here (a bad file, a window outside the data, a
    run longer than the scenario, missing values the feed refuses), so that a bad
    scenario ends the launch with exit code 2 instead of a feed exiting after start-up.
    """
    from comems4build_ros.app.commands.options import check_start
    from comems4build_ros.core.scenario.run import check_scenario, load_scenario
    from comems4build_ros.run.plan import feed_window

    check_start(args.start, params)
    weeks, steps = feed_window(args.weeks, args.steps)
    scenario = load_scenario(args.scenario, params, args.start, weeks or None, args.seed, steps or None)
    check_scenario(scenario, params.simulation.time_step_h)
    args.run_steps = int(scenario.n_steps)  # the bag's size is checked against the free space with it
