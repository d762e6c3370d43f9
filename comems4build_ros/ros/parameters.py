"""ROS parameters of the nodes: type, meaning, unit, source and range of each, and the strict rules they follow.

Every parameter a node of the package reads is in :data:`PARAMETERS` (or is a plant
parameter ``<section>.<key>`` of :class:`comems4build_ros.core.config.PlantParams`, whose
field gives its type, bounds and, through its name's suffix, its unit) and is declared by
:class:`comems4build_ros.ros.package_node.NodeParameters` with a ``ParameterDescriptor`` built
here: its type (static: ``dynamic_typing`` false), a description ending with its source and
unit, a ``floating_point_range`` or ``integer_range`` for numbers, the allowed values as
``additional_constraints`` for the others, and ``read_only`` unless the node lets it change
during a run. ``ros2 param describe`` shows all of it.

:func:`coerce` is the one rule for a value given on the command line, in a parameter
file, by ``parameter_overrides`` or by ``ros2 param set``: the type must be the declared
one (``1.5`` is not an integer, ``maybe`` not a boolean, ``abc`` not a number), with one
lossless exception: an integer where a number is expected is that number (``3`` ->
``3.0``); a string array may be given as one string (``launch_ros`` hands a list of one
substitution over so), split at commas where the parameter says so. A number outside its
range is refused. Every refusal is a :class:`ParameterError` naming node and parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from comems4build_ros.files.errors import InputError

#: Unit words of plant parameter name suffixes (``e_max_kwh`` -> kWh).
SUFFIX_UNITS = {
    "kwh": "kWh", "wh": "Wh", "w": "W", "kw": "kW", "c": "degC", "k": "K", "s": "s", "h": "h", "l": "l",
    "deg": "deg", "m2": "m2", "pct": "%", "eur": "EUR", "kwh_per_day": "kWh/d", "l_per_h": "l/h",
    "eur_per_kwh": "EUR/kWh", "eur_per_mwh": "EUR/MWh", "w_per_k": "W/K", "j_per_k": "J/K", "k_per_w": "K/W",
    "w_m2": "W/m2", "weeks": "weeks",
}
#: Largest value of an integer range (``integer_range`` of a descriptor is int64).
INT64_MAX = 2**63 - 1
#: Kinds of parameter values and their ``rcl_interfaces/ParameterType`` numbers.
KIND_TYPES = {"bool": 1, "int": 2, "float": 3, "str": 4, "int[]": 7, "float[]": 8, "str[]": 9}
#: Words for each kind in error messages.
KIND_WORDS = {"bool": "true or false", "int": "an integer", "float": "a number", "str": "text",
              "int[]": "a list of integers", "float[]": "a list of numbers", "str[]": "a list of strings"}
#: Parameters rclpy declares on every node itself (not in :data:`PARAMETERS`).
RCLPY_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service"})


class ParameterError(InputError):
    """A parameter value that breaks its declared type or range, or an unknown parameter."""


@dataclass(frozen=True)
class ParamSpec:
    """Meaning of one node parameter.

    Attributes
    ----------
    kind : type of the value (:data:`KIND_TYPES`: ``bool``, ``int``, ``float``, ``str``, ``str[]``, ...)
    description : what it is (one sentence, no unit)
    unit : unit of a number (``-`` for a count or a dimensionless value, ``""`` for text)
    low, high : inclusive range of a number (None = open)
    allowed : allowed values of a text or a flag, as shown to the user
    source : where its value or default comes from (paper label, file, docs section or choice)
    split : a string array given as one string is split at this separator ("" = kept whole)
    """

    kind: str
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    allowed: str = ""
    source: str = "design choice, docs/ros_nodes.md"
    split: str = ""


_POS = (1e-9, None)  # positive
_LOCKSTEP = "design choice, docs/ros_nodes.md 'Lock-step protocol'"
_RECORDER = "design choice, docs/ros_nodes.md 'Recorder'"
_PLAN = "set by the run plan of comems4build launch (docs/ros_tools.md)"
_TOKENS = "docs/ros_nodes.md 'Run tokens and security'"
_MQTT = "docs/real_building.md"
_SCENARIO = "sec:parameters (12 winter weeks from 2022-12-01, Karlsruhe)"
_COMMUNITY = "docs/community.md 'Over ROS'"

#: Every parameter a node of the package declares itself: name -> meaning (one meaning per name).
PARAMETERS: dict[str, ParamSpec] = {
    # plant parameters (every node that models or checks the plant)
    "config_files": ParamSpec("str[]", "parameter files merged over config/plant.yaml, in order",
                              allowed="paths of ROS 2 parameter files (plant sections)", split=",",
                              source="config/plant.yaml and the files' own comments"),
    "overrides": ParamSpec("str[]", "plant parameter overrides 'section.key=value' (YAML scalars), applied last",
                           allowed="items 'section.key=value'", source="config/plant.yaml"),
    # lock-step master (plant_sim, mqtt_bridge)
    "step_timeout_s": ParamSpec("float", "wait for a valid command before the safe fallback", "s", *_POS,
                                source=_LOCKSTEP),
    "startup_timeout_s": ParamSpec("float", "wait for the first command of the run before the safe fallback",
                                   "s", *_POS, source=_LOCKSTEP),
    "republish_period_s": ParamSpec("float", "period of the repeated announcement while waiting for a command",
                                    "s", *_POS, source=_LOCKSTEP),
    "watchdog_period_s": ParamSpec("float", "period of the watchdog timer (timeouts, repeats)", "s", *_POS,
                                   source=_LOCKSTEP),
    "house_timeout_s": ParamSpec("float", "lock-step over MQTT: alarm when the house has been silent this long",
                                 "s", *_POS, source=_MQTT),
    "wait_for_recorder": ParamSpec("bool", "first message only once this node's writers matched the recorder's "
                                   "readers", allowed="true or false", source=_PLAN),
    "recorder_node": ParamSpec("str", "node name of the recorder whose readers the writers must have matched "
                               "(and whose leaving ends the node)", allowed="a node name", source=_PLAN),
    "exit_when_done": ParamSpec("bool", "exit at the end of the run (plant/done), once the recorder has left",
                                allowed="true or false"),
    "ems_token": ParamSpec("int", "the only run token whose commands are applied (0 = that of the first valid "
                           "command; visible to every local user: prefer ems_token_file)", "-", 0, 2**53 - 1,
                           source=_TOKENS),
    "ems_token_file": ParamSpec("str", "file holding the run token (readable by this user only; overrides "
                                "ems_token)", allowed="a file path or empty", source=_TOKENS),
    "stall_steps": ParamSpec("int", "end the run (exit code 4) once the EMS has sent nothing for this many step "
                             "time-outs, or no step was possible for as long (0 = never)", "steps", 0, 1_000_000,
                             source=_LOCKSTEP),
    "record_window_steps": ParamSpec("int", "with wait_for_recorder: steps the plant may run ahead of the gap-free "
                                     "recording (recorder/progress); lossless below the topics' keep-last depth "
                                     "(1000)", "steps", 1, None, source=_LOCKSTEP),
    "publish_clock": ParamSpec("bool", "publish the simulated time on /clock (one clock per run: the run plan "
                               "gives it to the first house's plant only)", allowed="true or false",
                               source="docs/ros_tools.md 'Simulated time'"),
    # plant_sim: the building's thermal model (with the feed's scenario parameters when not rc)
    "building_model": ParamSpec("str", "building model of plant_sim: rc (the paper's 4R3C), energyplus[:IDF] or "
                                "fmu:PATH (not 'building': that is the section of the 4R3C's parameters)",
                                allowed="rc, energyplus, energyplus:FILE.idf or fmu:FILE.fmu",
                                source="docs/cosimulation.md"),
    # plant_sim of a community's house
    "hub": ParamSpec("bool", "the house's H2 store is its account at a community's hub: the plant steps in lock-step "
                     "with the coordinator (hub/allotment, hub/report, hub/settlement)", allowed="true or false",
                     source=_COMMUNITY),
    "hub_token_file": ParamSpec("str", "file holding the house's hub secret (readable by this user only): every "
                                "hub/* message carries its authentication code (empty = none checked)",
                                allowed="a file path or empty", source=_TOKENS),
    # feed of a community's house, coordinator
    "community_file": ParamSpec("str", "community file: the feed builds its house's scenario from it, the "
                                "coordinator the community (empty = no community)",
                                allowed="a community file (config/community/*.yaml) or empty", source=_COMMUNITY),
    "community_house": ParamSpec("str", "the house of community_file the feed serves: its load, hot-water draws and "
                                 "parameters; feed/h2_allowance is the coordinator's (empty = no community)",
                                 allowed="a house name of the community file or empty", source=_COMMUNITY),
    # coordinator
    "coordinator": ParamSpec("str", "the coordinator the node runs", allowed="a coordinator of "
                             "config/coordinators.yaml", source="config/coordinators.yaml"),
    "coordinator_options": ParamSpec("str[]", "options of the coordinator 'key=value', over its row's",
                                     allowed="items 'key=value'", source="config/coordinators.yaml"),
    "hub_token_files": ParamSpec("str[]", "the houses' hub secret files, in the community file's order (empty = "
                                 "none checked)", allowed="file paths, a comma-separated list or a string array",
                                 split=",", source=_TOKENS),
    # feed
    "scenario": ParamSpec("str", "scenario of the run", allowed="'default', 'year', 'synthetic' or a scenario "
                          "CSV path", source=_SCENARIO),
    "start": ParamSpec("str", "ISO 8601 start time of the run's window (empty = the scenario's start)",
                       allowed="ISO 8601 time or empty", source=_SCENARIO),
    "weeks": ParamSpec("int", "run length in whole weeks (0 = the scenario's default length; at most the whole "
                       "weeks the scenario's data hold)", "weeks", 0, None, source=_SCENARIO),
    "steps": ParamSpec("int", "cut the run to its first N steps (0 = all)", "steps", 0, INT64_MAX, source=_PLAN),
    "seed": ParamSpec("int", "generator seed of the modelled radiation and load (-1 = config/scenario.yaml)", "-",
                      -1, 2**32 - 1, source="config/scenario.yaml"),
    "allow_gap_fill": ParamSpec("bool", "accept missing values the scenario loader fills by interpolation",
                                allowed="true or false", source="docs/scenario.md"),
    "forecast_mode": ParamSpec("str", "forecasts of the MPC (empty = config/forecast.yaml)",
                               allowed="perfect, imperfect, realistic or empty", source="config/forecast.yaml"),
    "lookahead_steps": ParamSpec("int", "steps published ahead of the step the plant waits for", "steps", 0, 1000,
                                 source="design choice, docs/ros_nodes.md 'Feed'"),
    "publish_measured": ParamSpec("bool", "publish feed/measured (false when mqtt_bridge publishes the house's "
                                  "meters)", allowed="true or false", source=_MQTT),
    "inputs": ParamSpec("str", "inputs of the feed", allowed="scenario or live", source=_MQTT),
    "for_ems": ParamSpec("str", "EMS node the feed (a community's coordinator: the houses' EMS) serves: only the "
                         "topics it reads are published (empty = every EMS topic)",
                         allowed="an EMS node of the contract (fuzzy_ems, ...) or empty",
                         source="tab:level_of_information"),
    "live_config": ParamSpec("str", "live-input settings file (empty = config/live_inputs.yaml)",
                             allowed="a file path or empty", source=_MQTT),
    "live_cache_dir": ParamSpec("str", "directory of the live-input cache files (empty = ~/.cache/comems4build_ros)",
                                allowed="a directory or empty", source=_MQTT),
    # EMS
    "ems_options": ParamSpec("str[]", "options of the controller 'key=value' (as simulate --ems-option)",
                             allowed="items 'key=value'", source="config/rbc.yaml, config/mpc.yaml, config/fuzzy/"),
    "run_token": ParamSpec("int", "run token in every command (0 = CRC-32 of the node's name + 1; visible to every "
                           "local user: prefer run_token_file)", "-", 0, 2**53 - 1, source=_TOKENS),
    "run_token_file": ParamSpec("str", "file holding the run token (readable by this user only; overrides "
                                "run_token)", allowed="a file path or empty", source=_TOKENS),
    # recorder
    "bag_path": ParamSpec("str", "bag directory to create (recorder) or read (replay)", allowed="a directory path",
                          source=_PLAN),
    "namespaces": ParamSpec("str[]", "namespaces to record (empty = the node's own)",
                            allowed="a namespace, a comma-separated list or a string array", split=",",
                            source=_PLAN),
    "wait_for_topics": ParamSpec("str[]", "topics whose publishers must be matched before recorder/ready "
                                 "('*' = those of plant, feed and EMS)", allowed="contract topic names or '*'",
                                 split=",", source=_RECORDER),
    "skip_topics": ParamSpec("str[]", "topics not recorded (no publisher in the run)",
                             allowed="contract topic names, a comma-separated list or a string array", split=",",
                             source=_PLAN),
    "settle_s": ParamSpec("float", "wait after every topic matched, for the other side of discovery", "s", 0.0,
                          None, source=_RECORDER),
    "ready_timeout_s": ParamSpec("float", "declare ready anyway after this wait for publishers", "s", *_POS,
                                 source=_RECORDER),
    "optional_wait_s": ParamSpec("float", "extra wait for optional topics (ems/info) before ready", "s", 0.0, None,
                                 source=_RECORDER),
    "stop_when_done": ParamSpec("bool", "close the bag and exit at the end of the run", allowed="true or false",
                                source=_RECORDER),
    "done_grace_s": ParamSpec("float", "end of run: wait this long without any message (queues drained)", "s",
                              0.0, None, source=_RECORDER),
    "done_timeout_s": ParamSpec("float", "end of run: stop this long after the last message even if steps are "
                                "missing", "s", *_POS, source=_RECORDER),
    "progress_period_s": ParamSpec("float", "period of the 'progress' lines on stdout (0 = none)", "s", 0.0, None,
                                   source=_PLAN),
    "run_info": ParamSpec("str", "JSON description of the run stored in the bag (run_info.json)",
                          allowed="a JSON object or empty", source=_PLAN),
    "tick_s": ParamSpec("float", "period of the recorder's housekeeping timer", "s", *_POS, source=_RECORDER),
    "follows": ParamSpec("str", "what the recorder follows: the houses of its namespaces (plant) or a community's "
                         "coordinator in its namespace (coordinator)", allowed="plant or coordinator",
                         source=_RECORDER),
    "chunk_period_s": ParamSpec("float", "close the pending MCAP chunk once it is this old", "s", *_POS,
                                source=_RECORDER),
    "chunk_max_bytes": ParamSpec("int", "close the pending MCAP chunk once it holds this many bytes", "byte",
                                 1, INT64_MAX, source=_RECORDER),
    # replay
    "rate": ParamSpec("float", "replay speed relative to the recording (<= 0 = as fast as possible)", "-",
                      source="as ros2 bag play --rate"),
    "inputs_only": ParamSpec("bool", "replay only the feed's topics, paced by the plant", allowed="true or false"),
    "source_namespace": ParamSpec("str", "namespace of the bag to replay (empty = own or the only one)",
                                  allowed="a namespace or empty"),
    "wait_for_subscribers_s": ParamSpec("float", "wait for a subscriber on every replayed topic", "s", 0.0, None),
    "topic_interval_s": ParamSpec("float", "full replay: shortest interval between two messages of one topic (0 = "
                                  "none): a default subscriber (ros2 topic echo, depth 5) keeps up with 0.02 s", "s",
                                  0.0, None, source="docs/ros_tools.md 'replay node'"),
    # mqtt_bridge
    "topic_map": ParamSpec("str", "MQTT topic map (empty = config/mqtt.yaml)", allowed="a file path or empty",
                           source=_MQTT),
    "broker_url": ParamSpec("str", "MQTT broker replacing the topic map's (empty = the map's)",
                            allowed="mqtt://host:port, mqtts://host:port or empty", source=_MQTT),
    "clock": ParamSpec("str", "clock of the run (mqtt_bridge; a community's coordinator and its houses' plant_sim)",
                       allowed="sim, wall or wall:<factor>", source=_MQTT),
    "measure_delay_s": ParamSpec("float", "wall clocks: announce a step this long after it starts "
                                 "(-1 = 0.2 of the period, at most 5 s)", "s", -1.0, None, source=_MQTT),
    "client_id": ParamSpec("str", "MQTT client id", allowed="a string", source=_MQTT),
    "run_id": ParamSpec("str", "the run's id: the feed names it on feed/info and the recorder in the bag's "
                        "run_info.json (evaluate refuses records of another run), mqtt_bridge on its retained MQTT "
                        "messages (empty: none, for the bridge a new random one)",
                        allowed="1 to 64 of A-Z a-z 0-9 _ . - or empty", source=_PLAN),
    "mqtt_secret_file": ParamSpec("str", "per-run secret (mode 0600): key of the authentication codes of the "
                                  "messages between bridge and house, and broker_username's password (empty = none)",
                                  allowed="a file path or empty", source=_MQTT),
    "broker_username": ParamSpec("str", "broker user replacing the topic map's, password from mqtt_secret_file "
                                 "(empty = the map's login)", allowed="a user name or empty", source=_MQTT),
}


def _unit_of(key: str) -> str:
    """Unit of a plant parameter from its name's suffix (``e_max_kwh`` -> ``kWh``), ``-`` without one."""
    parts = key.split("_")
    for n in range(min(3, len(parts) - 1), 0, -1):
        suffix = "_".join(parts[-n:])
        if suffix in SUFFIX_UNITS:
            return SUFFIX_UNITS[suffix]
    return "-"


def _kind_of(annotation: Any) -> tuple[str, str]:
    """Kind and allowed values of a plant parameter from its field's annotation."""
    from typing import Literal, get_args, get_origin

    if annotation is bool:
        return "bool", "true or false"
    if annotation is int:
        return "int", ""
    if annotation is float:
        return "float", ""
    if get_origin(annotation) is Literal:
        return "str", ", ".join(str(a) for a in get_args(annotation))
    if get_origin(annotation) is list:
        (item,) = get_args(annotation)
        return ("int[]" if item is int else "float[]"), ""
    return "str", "text"


def plant_param_spec(name: str) -> ParamSpec | None:
    """Meaning of the plant parameter ``<section>.<key>`` (None if ``name`` is not one)."""
    from comems4build_ros.core.config import PlantParams

    section, dot, key = name.partition(".")
    model = PlantParams.model_fields.get(section)
    if not dot or model is None or model.annotation is None:
        return None
    field = getattr(model.annotation, "model_fields", {}).get(key)
    if field is None:
        return None
    low = high = None
    for rule in field.metadata:
        for attr in ("ge", "gt"):
            if getattr(rule, attr, None) is not None:
                low = float(getattr(rule, attr))
        for attr in ("le", "lt"):
            if getattr(rule, attr, None) is not None:
                high = float(getattr(rule, attr))
    kind, allowed = _kind_of(field.annotation)
    doc = (model.annotation.__doc__ or "").strip().splitlines()
    what = doc[0].rstrip(".") if doc else section
    return ParamSpec(kind, f"plant parameter of section '{section}' ({what})",
                     "" if kind in ("str", "bool") else _unit_of(key), low, high, allowed,
                     source="config/plant.yaml, whose comment gives the paper's or an outside source")


def spec_of(name: str) -> ParamSpec:
    """Meaning of parameter ``name`` (:data:`PARAMETERS`, else a plant parameter).

    Raises
    ------
    KeyError
        For a parameter of neither kind (a node must not read an undocumented parameter).
    """
    spec = PARAMETERS.get(name) or plant_param_spec(name)
    if spec is None:
        raise KeyError(f"parameter '{name}' has no entry in comems4build_ros.ros.parameters.PARAMETERS")
    return spec


def _range_text(spec: ParamSpec) -> str:
    lo = "-inf" if spec.low is None else f"{spec.low:g}"
    hi = "inf" if spec.high is None else f"{spec.high:g}"
    unit = f" {spec.unit}" if spec.unit and spec.unit != "-" else ""
    return f"{lo} .. {hi}{unit}"


def coerce(spec: ParamSpec, value: Any, where: str) -> Any:
    """``value`` as a value of ``spec`` (see the module docstring), or :class:`ParameterError`.

    Parameters
    ----------
    spec : the parameter's meaning
    value : the value given (as rclpy holds it: bool, int, float, str or a sequence)
    where : ``node 'feed': parameter 'weeks'``, the start of every message
    """
    kind = spec.kind
    given = f"{where} = {value!r}" if not isinstance(value, (list, tuple)) else f"{where} = {list(value)!r}"
    if kind.endswith("[]"):
        if isinstance(value, str):
            items: list[Any] = ([s.strip() for s in value.split(spec.split) if s.strip()] if spec.split
                                else [value] if value else [])
        elif isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
            items = list(value.tolist() if hasattr(value, "tolist") else value)
        else:
            raise ParameterError(f"{given}: expected {KIND_WORDS[kind]}")
        item_spec = ParamSpec(kind[:-2], spec.description, spec.unit, spec.low, spec.high)
        out = [coerce(item_spec, v, f"{where}[{i}]") for i, v in enumerate(items)]
        return [s for s in out if s] if kind == "str[]" else out
    if kind == "bool":
        if not isinstance(value, bool):
            raise ParameterError(f"{given}: expected true or false")
        return value
    if kind == "str":
        if not isinstance(value, str):
            raise ParameterError(f"{given}: expected text ({spec.allowed or 'a string'}); quote a value that reads "
                                 f"as a number or a flag: '\"{value}\"'")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError(f"{given}: expected {KIND_WORDS[kind]} ({_range_text(spec)})")
    if kind == "int":
        if not isinstance(value, int):
            raise ParameterError(f"{given}: expected an integer ({_range_text(spec)}), got a fractional number")
    else:
        value = float(value)
        if not math.isfinite(value):
            raise ParameterError(f"{given}: expected a finite number ({_range_text(spec)})")
    if (spec.low is not None and value < spec.low) or (spec.high is not None and value > spec.high):
        raise ParameterError(f"{given}: outside its range {_range_text(spec)}")
    return value


def descriptor(name: str, spec: ParamSpec, read_only: bool = True) -> Any:
    """``ParameterDescriptor`` of parameter ``name``: static type, description with source and unit,
    range or allowed values, and whether it is read-only."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    unit = f" [{spec.unit}]" if spec.unit else ""
    source = f" (source: {spec.source})" if spec.source else ""
    out = ParameterDescriptor(name=name, type=KIND_TYPES[spec.kind], description=f"{spec.description}{source}{unit}",
                              read_only=read_only, dynamic_typing=False)
    numeric = spec.kind.removesuffix("[]") in ("int", "float")
    if numeric and (spec.low is not None or spec.high is not None):
        if spec.kind == "int":
            lo = -INT64_MAX if spec.low is None else math.ceil(spec.low)
            hi = INT64_MAX if spec.high is None else math.floor(spec.high)
            out.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
        elif spec.kind == "float":
            lo = -math.inf if spec.low is None else float(spec.low)
            hi = math.inf if spec.high is None else float(spec.high)
            out.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
        else:
            out.additional_constraints = f"each item {_range_text(spec)}"
    elif numeric:
        out.additional_constraints = "any number"
    else:
        out.additional_constraints = spec.allowed or "any text"
    return out


def nearest(name: str, known: list[str]) -> str:
    """``" (did you mean 'x'?)"`` for the known name closest to ``name``, else ``""``."""
    import difflib

    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


def flat_plant_params(params: Any) -> dict[str, Any]:
    """``{"battery.e_max_kwh": 6.5, ...}``: every plant parameter of a checked ``PlantParams``."""
    from comems4build_ros.core.config import PLANT_SECTIONS

    dumped = params.model_dump()
    return {f"{section}.{key}": value for section in PLANT_SECTIONS for key, value in dumped[section].items()}


def plant_params_file_text(params: Any) -> str:
    """A ROS 2 parameter file (``/**: ros__parameters:``) holding every value of the checked
    ``params``: what the run plan hands its nodes (``config_files``), parsed once by each.
    ``load_plant_params([file])`` gives ``params`` back exactly."""
    import yaml

    from comems4build_ros.core.config import PLANT_SECTIONS

    dumped = params.model_dump()
    doc = {"/**": {"ros__parameters": {section: dumped[section] for section in PLANT_SECTIONS}}}
    head = ("# The checked plant parameters of this run, written by the run plan (comems4build launch);\n"
            "# each value's source: config/plant.yaml and the files and overrides named in bag/run_info.json.\n")
    return head + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120)
