"""ROS parameters of the nodes: what each one means, its unit and range, declared with a descriptor.

Every parameter a node of the package reads is declared through :func:`param` with a
``ParameterDescriptor`` built from :data:`PARAMETERS` (its description ending with the
unit, a ``floating_point_range`` or ``integer_range`` for numbers, the allowed values as
``additional_constraints`` for the others), so ``ros2 param describe`` shows what it is.
The plant parameters a node takes from ``--params-file config/plant.yaml`` or ``-p
battery.e_max_kwh:=...`` (``<section>.<key>``) get theirs from the validated model
:class:`comems4build_ros.core.config.PlantParams`: the field's bounds and the unit of its
name's suffix (``_kwh``, ``_w``, ``_c``, ...).

The nodes are created with ``automatically_declare_parameters_from_overrides``, so a
parameter given on the command line is declared before the node reads it; :func:`param`
then attaches the descriptor to it (``Node.set_descriptor``) with the type of the value
given. A parameter whose default is an empty list is declared as a typed string array
without a value (rclpy cannot infer the type of ``[]``) and reads as ``[]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

#: Unit words of plant parameter name suffixes (``e_max_kwh`` -> kWh).
SUFFIX_UNITS = {
    "kwh": "kWh", "wh": "Wh", "w": "W", "kw": "kW", "c": "degC", "k": "K", "s": "s", "h": "h", "l": "l",
    "deg": "deg", "m2": "m2", "pct": "%", "eur": "EUR", "kwh_per_day": "kWh/d", "l_per_h": "l/h",
    "eur_per_kwh": "EUR/kWh", "eur_per_mwh": "EUR/MWh", "w_per_k": "W/K", "j_per_k": "J/K", "k_per_w": "K/W",
    "w_m2": "W/m2", "weeks": "weeks",
}
#: Largest value of an integer range (``integer_range`` of a descriptor is int64).
INT64_MAX = 2**63 - 1


@dataclass(frozen=True)
class ParamSpec:
    """Meaning of one node parameter.

    Attributes
    ----------
    description : what it is (one sentence, no unit)
    unit : unit of a number (``-`` for a count or a dimensionless value, ``""`` for text)
    low, high : inclusive range of a number (None = open)
    allowed : allowed values of a text or a flag, as shown to the user
    """

    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    allowed: str = ""


_POS = (1e-9, None)  # positive
_FILES = "paths of ROS 2 parameter files (plant sections)"

#: Every parameter a node of the package declares itself: name -> meaning (one meaning per name).
PARAMETERS: dict[str, ParamSpec] = {
    # plant parameters (every node that models or checks the plant)
    "config_files": ParamSpec("parameter files merged over config/plant.yaml, in order", allowed=_FILES),
    "overrides": ParamSpec("plant parameter overrides 'section.key=value' (YAML scalars), applied last",
                           allowed="items 'section.key=value'"),
    # lock-step master (plant_sim, mqtt_bridge)
    "step_timeout_s": ParamSpec("wait for a valid command before the safe fallback", "s", *_POS),
    "startup_timeout_s": ParamSpec("wait for the first command of the run before the safe fallback", "s", *_POS),
    "republish_period_s": ParamSpec("period of the repeated announcement while waiting for a command", "s", *_POS),
    "watchdog_period_s": ParamSpec("period of the watchdog timer (timeouts, repeats)", "s", *_POS),
    "house_timeout_s": ParamSpec("lock-step over MQTT: alarm when the house has been silent this long",
                                    "s", *_POS),
    "wait_for_recorder": ParamSpec("first message only once this node's writers matched the recorder's readers",
                                   allowed="true or false"),
    "recorder_node": ParamSpec("node name of the recorder whose readers the writers must have matched",
                               allowed="a node name"),
    "exit_when_done": ParamSpec("exit at the end of the run (plant/done), once the recorder has left",
                                allowed="true or false"),
    "ems_token": ParamSpec("the only run token whose commands are applied (0 = that of the first valid command; "
                           "visible to every local user: prefer ems_token_file)", "-", 0, 2**53 - 1),
    "ems_token_file": ParamSpec("file holding the run token (readable by this user only; overrides ems_token)",
                                allowed="a file path or empty"),
    "stall_steps": ParamSpec("end the run (exit code 4) once the EMS has sent nothing for this many step "
                             "time-outs, or no step was possible for as long (0 = never)", "steps", 0, 1_000_000),
    "record_window_steps": ParamSpec("with wait_for_recorder: steps the plant may run ahead of the gap-free "
                                     "recording (recorder/progress)", "steps", 1, None),
    # plant_sim: the building's thermal model (with the feed's scenario parameters when not rc)
    "building": ParamSpec("building model of plant_sim: rc (the paper's 4R3C), energyplus[:IDF] or fmu:PATH",
                          allowed="rc, energyplus, energyplus:FILE.idf or fmu:FILE.fmu"),
    # feed
    "scenario": ParamSpec("scenario of the run", allowed="'default' or a scenario CSV path"),
    "start": ParamSpec("ISO 8601 start time of the run's window (empty = the scenario's start)",
                       allowed="ISO 8601 time or empty"),
    "weeks": ParamSpec("run length in whole weeks (0 = the scenario's default length)", "weeks", 0, None),
    "steps": ParamSpec("cut the run to its first N steps (0 = all)", "steps", 0, INT64_MAX),
    "seed": ParamSpec("generator seed of the default scenario (-1 = config/scenario.yaml)", "-", -1, 2**32 - 1),
    "allow_gap_fill": ParamSpec("accept missing values the scenario loader fills by interpolation",
                                allowed="true or false"),
    "forecast_mode": ParamSpec("forecasts of the MPC (empty = config/forecast.yaml)",
                               allowed="perfect, imperfect or empty"),
    "lookahead_steps": ParamSpec("steps published ahead of the step the plant waits for", "steps", 0, 1000),
    "publish_measured": ParamSpec("publish feed/measured (false when mqtt_bridge publishes the house's meters)",
                                  allowed="true or false"),
    "inputs": ParamSpec("inputs of the feed", allowed="scenario or live"),
    "for_ems": ParamSpec("EMS node the feed serves: only the topics it reads are published (empty = every EMS topic)",
                         allowed="an EMS node of the contract (fuzzy_ems, ...) or empty"),
    "live_config": ParamSpec("live-input settings file (empty = config/live_inputs.yaml)",
                             allowed="a file path or empty"),
    "live_cache_dir": ParamSpec("directory of the live-input cache files (empty = ~/.cache/comems4build_ros)",
                                allowed="a directory or empty"),
    # EMS
    "ems_options": ParamSpec("options of the controller 'key=value' (as simulate --ems-option)",
                             allowed="items 'key=value'"),
    "run_token": ParamSpec("run token in every command (0 = CRC-32 of the node's name + 1; visible to every "
                           "local user: prefer run_token_file)", "-", 0, 2**53 - 1),
    "run_token_file": ParamSpec("file holding the run token (readable by this user only; overrides run_token)",
                                allowed="a file path or empty"),
    # recorder
    "bag_path": ParamSpec("bag directory to create (recorder) or read (replay)", allowed="a directory path"),
    "namespaces": ParamSpec("namespaces to record (empty = the node's own)",
                            allowed="a namespace, a comma-separated list or a string array"),
    "wait_for_topics": ParamSpec("topics whose publishers must be matched before recorder/ready "
                                 "('*' = those of plant, feed and EMS)", allowed="contract topic names or '*'"),
    "skip_topics": ParamSpec("topics not recorded (no publisher in the run)",
                             allowed="contract topic names, a comma-separated list or a string array"),
    "settle_s": ParamSpec("wait after every topic matched, for the other side of discovery", "s", 0.0, None),
    "ready_timeout_s": ParamSpec("declare ready anyway after this wait for publishers", "s", *_POS),
    "optional_wait_s": ParamSpec("extra wait for optional topics (ems/info) before ready", "s", 0.0, None),
    "stop_when_done": ParamSpec("close the bag and exit at the end of the run", allowed="true or false"),
    "done_grace_s": ParamSpec("end of run: wait this long without any message (queues drained)", "s", 0.0, None),
    "done_timeout_s": ParamSpec("end of run: stop this long after the last message even if steps are missing",
                                "s", *_POS),
    "progress_period_s": ParamSpec("period of the 'progress' lines on stdout (0 = none)", "s", 0.0, None),
    "run_info": ParamSpec("JSON description of the run stored in the bag (run_info.json)",
                          allowed="a JSON object or empty"),
    "tick_s": ParamSpec("period of the recorder's housekeeping timer", "s", *_POS),
    "chunk_period_s": ParamSpec("close the pending MCAP chunk once it is this old", "s", *_POS),
    "chunk_max_bytes": ParamSpec("close the pending MCAP chunk once it holds this many bytes", "byte",
                                 1, INT64_MAX),
    # replay
    "rate": ParamSpec("replay speed relative to the recording (<= 0 = as fast as possible)", "-"),
    "inputs_only": ParamSpec("replay only the feed's topics, paced by the plant", allowed="true or false"),
    "source_namespace": ParamSpec("namespace of the bag to replay (empty = own or the only one)",
                                  allowed="a namespace or empty"),
    "wait_for_subscribers_s": ParamSpec("wait for a subscriber on every replayed topic", "s", 0.0, None),
    # mqtt_bridge
    "topic_map": ParamSpec("MQTT topic map (empty = config/mqtt.yaml)", allowed="a file path or empty"),
    "broker_url": ParamSpec("MQTT broker replacing the topic map's (empty = the map's)",
                            allowed="mqtt://host:port, mqtts://host:port or empty"),
    "clock": ParamSpec("clock of the run", allowed="sim, wall or wall:<factor>"),
    "measure_delay_s": ParamSpec("wall clocks: announce a step this long after it starts "
                                 "(-1 = 0.2 of the period, at most 5 s)", "s", -1.0, None),
    "client_id": ParamSpec("MQTT client id", allowed="a string"),
    "run_id": ParamSpec("the run's id on its retained MQTT messages (empty = a new random one)",
                        allowed="1 to 64 of A-Z a-z 0-9 _ . - or empty"),
    "mqtt_secret_file": ParamSpec("per-run secret (mode 0600): key of the authentication codes of the messages "
                                  "between bridge and house, and broker_username's password (empty = none)",
                                  allowed="a file path or empty"),
    "broker_username": ParamSpec("broker user replacing the topic map's, password from mqtt_secret_file "
                                 "(empty = the map's login)", allowed="a user name or empty"),
}


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
    unit = "-"
    parts = key.split("_")
    for n in range(min(3, len(parts) - 1), 0, -1):
        suffix = "_".join(parts[-n:])
        if suffix in SUFFIX_UNITS:
            unit = SUFFIX_UNITS[suffix]
            break
    doc = (model.annotation.__doc__ or "").strip().splitlines()
    what = doc[0].rstrip(".") if doc else section
    return ParamSpec(f"plant parameter of section '{section}' ({what}); config/plant.yaml gives its source", unit,
                     low, high)


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


def descriptor(name: str, value: Any) -> Any:
    """``ParameterDescriptor`` of parameter ``name`` for a value like ``value`` (type, range, text)."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.parameter import Parameter

    spec = spec_of(name)
    unit = f" [{spec.unit}]" if spec.unit else ""
    out = ParameterDescriptor(name=name, description=f"{spec.description}{unit}")
    if value is not None:
        out.type = Parameter.Type.from_parameter_value(value).value
    numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
    if numeric and (spec.low is not None or spec.high is not None):
        if isinstance(value, int):
            lo = -INT64_MAX if spec.low is None else math.ceil(spec.low)
            hi = INT64_MAX if spec.high is None else math.floor(spec.high)
            out.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=0)]
        else:
            lo = -math.inf if spec.low is None else float(spec.low)
            hi = math.inf if spec.high is None else float(spec.high)
            out.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    elif numeric:
        out.additional_constraints = "any number"
    else:
        out.additional_constraints = spec.allowed
    return out


def param(node: Any, name: str, default: Any) -> Any:
    """Value of parameter ``name`` of ``node``, declared with ``default`` and its descriptor.

    A parameter already declared (given as an override) keeps its value and gets the
    descriptor (for the type given). Array values are returned as lists; a value outside
    the range of :data:`PARAMETERS` raises ``ValueError`` naming node and parameter.
    """
    from rclpy.exceptions import InvalidParameterValueException, ParameterUninitializedException
    from rclpy.parameter import Parameter

    if node.has_parameter(name):
        try:
            value = node.get_parameter(name).value
        except ParameterUninitializedException:  # an empty string array declared before (read a second time)
            return []
        try:
            node.set_descriptor(name, descriptor(name, value))
        except InvalidParameterValueException:
            spec = spec_of(name)
            raise ValueError(f"node '{node.get_name()}': parameter '{name}' = {value!r} outside its range "
                             f"[{spec.low}, {spec.high}] {spec.unit}") from None
    elif isinstance(default, (list, tuple)) and not default:
        node.declare_parameter(name, Parameter.Type.STRING_ARRAY, descriptor(name, None))
    else:
        node.declare_parameter(name, default, descriptor(name, default))
    try:
        value = node.get_parameter(name).value
    except ParameterUninitializedException:
        return []
    if value is not None and not isinstance(value, (str, bytes, bool, int, float)):
        value = list(value)
    return value


def string_list(node: Any, name: str) -> list[str]:
    """A parameter that may be given as a string array or as one comma-separated string
    (``launch_ros`` passes a list of one substitution as a string), empty items dropped."""
    value = param(node, name, [])
    items = value.split(",") if isinstance(value, str) else [str(v) for v in value]
    return [s.strip() for s in items if s.strip()]


def plant_params_from_node(node: Any) -> Any:
    """Plant parameters of a node, from its ROS parameters.

    ``config/plant.yaml`` is merged with, in order: the files of the string-array
    parameter ``config_files`` (parameter-file form, as ``comems4build simulate
    --config``), every node parameter whose first dotted segment is a plant section
    (``battery.e_max_kwh`` and so on: what ``--ros-args --params-file config/plant.yaml``
    or ``-p battery.e_max_kwh:=10.0`` sets), and the ``overrides`` string array of
    ``section.key=value`` items (YAML scalars).

    Raises
    ------
    ConfigError
        Naming the file or override and the parameter that is invalid.
    """
    from comems4build_ros.core.config import PLANT_SECTIONS, load_plant_params, parse_assignments

    files = string_list(node, "config_files")
    ros_overrides: dict[str, Any] = {}
    for name, p in node.get_parameters_by_prefix("").items():
        if name.split(".", 1)[0] in PLANT_SECTIONS and "." in name:
            ros_overrides[name] = param(node, name, p.value)
    ros_overrides.update(parse_assignments(string_list(node, "overrides"),
                                           f"node '{node.get_name()}': parameter 'overrides':"))
    return load_plant_params(files, ros_overrides)


