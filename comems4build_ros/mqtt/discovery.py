"""Home Assistant MQTT discovery for what the EMS sees and decides.

Home Assistant creates an entity for every retained config message on
``<discovery_prefix>/<component>/<node_id>/<object_id>/config`` and deletes it on an empty
one (Home Assistant MQTT integration documentation, "MQTT Discovery"). The bridge
publishes one per entity on every (re)connect, all pointing at one retained JSON state
topic (``<base>/state``, read with a ``value_template``) and at the availability topic
``<base>/availability`` whose last will is ``offline``. Entities (:data:`SENSORS`):

* what the EMS sees: battery SOC, hydrogen level (LOH), room temperature, usable hot
  water, PV and appliance power, outdoor temperature (each only where the topic map has
  the measurement);
* what it decides and who decides: the heat-pump mode (``enum``) and modulation, the
  fuel-cell and battery set-points, and *in charge* (``enum``: the EMS, or the safe
  fallback and why: the watchdog, the user's switch, a late command);
* run totals of the simulated house's records (grid purchase cost, feed-in
  reimbursement, grid import and export, discomfort ``eq:discomfort``) with
  ``state_class: total`` and ``last_reset`` at the run's start, so that Home Assistant's
  statistics take a new run as a new meter cycle, not as a negative change; the same
  arithmetic as ``summary.json`` (:func:`comems4build_ros.core.kpi.run_totals`). A real
  building (no ``sim_record_topic``) has no such records: these sensors are not
  announced, and a retained config of an earlier run is deleted;
* diagnostics (``entity_category: diagnostic``): the step, fallback steps, clamped
  commands, foreign messages, the last fallback's reason;
* binary sensor ``alarm`` (device class ``problem``);
* switches ``ems`` (off: the bridge sends the safe fallback action instead of the EMS's
  commands) and ``fallback`` (on: the same, forced). Both with ``retain: true``: Home
  Assistant's commands stay on the broker, so a command sent while the bridge is offline
  is applied when it returns, and a restarted bridge keeps the user's choice;
* the setting ``battery_power_limit`` (a ``number``, W, retained as the switches): the
  largest battery power either way that the bridge lets through, within the device
  limits (commands beyond it are clamped and counted as ``clamped_commands``).

Every config has ``object_id`` (entity ids such as ``switch.comems4build_ems_control``),
``origin`` and a ``device`` block with ``sw_version`` (and ``configuration_url`` when the
topic map gives one). :data:`DISCOVERY_SCHEMA` lists the fields each component's payload
must have, and :func:`check_discovery` checks a payload against it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from comems4build_ros import __version__
from comems4build_ros.files.errors import InputError
from comems4build_ros.mqtt.topicmap import TopicMap

#: Required payload fields per component (HA MQTT discovery); ``unit_of_measurement``
#: is required, and checked, for sensors with a device class of :data:`DEVICE_CLASS_UNITS`.
DISCOVERY_SCHEMA: dict[str, tuple[str, ...]] = {
    "sensor": ("name", "unique_id", "object_id", "state_topic", "value_template", "device", "origin"),
    "binary_sensor": ("name", "unique_id", "object_id", "state_topic", "value_template", "device", "origin",
                      "availability_topic", "payload_on", "payload_off"),
    "switch": ("name", "unique_id", "object_id", "state_topic", "command_topic", "device", "origin",
               "availability_topic", "payload_on", "payload_off"),
    "number": ("name", "unique_id", "object_id", "state_topic", "command_topic", "device", "origin",
               "availability_topic", "min", "max", "step"),
}
#: Units Home Assistant accepts for the device classes used here (empty: any ISO 4217 currency code).
DEVICE_CLASS_UNITS: dict[str, tuple[str, ...]] = {
    "power": ("W", "kW"),
    "energy": ("Wh", "kWh", "MWh"),
    "monetary": (),
    "temperature": ("°C", "K"),
    "battery": ("%",),
    "volume_storage": ("L", "m³"),
}
#: State classes Home Assistant allows per device class (others: any).
DEVICE_CLASS_STATE_CLASSES: dict[str, tuple[str | None, ...]] = {
    "monetary": ("total",),
    "energy": ("total", "total_increasing"),
    "enum": (None,),
}
#: Required fields of the ``device`` and ``origin`` blocks.
DEVICE_FIELDS = ("identifiers", "name", "sw_version")
ORIGIN_FIELDS = ("name", "sw_version")
PAYLOAD_ON, PAYLOAD_OFF = "ON", "OFF"
AVAILABLE, NOT_AVAILABLE = "online", "offline"
#: Values of the ``in_charge`` sensor: who decided the set-points of the current step.
IN_CHARGE = ("ems", "fallback_watchdog", "fallback_switch", "fallback_late_command")
#: Heat-pump modes as the ``hp_mode`` sensor shows them (``types.HP_OFF``, ``HP_SH``, ``HP_DHW``).
HP_MODES = ("off", "heating", "dhw")
#: Where a sensor's value comes from: a measurement of the topic map (shown only when the
#: map has it), the simulated house's records (only with ``sim_record_topic``), or the bridge.
FROM_BRIDGE, FROM_RECORDS = "bridge", "records"


@dataclass(frozen=True)
class SensorDef:
    """One sensor of the state JSON.

    ``source``: :data:`FROM_BRIDGE`, :data:`FROM_RECORDS` or the name of a measurement of
    the topic map. A sensor with ``state_class: total`` is a run total (with ``last_reset``
    at the run's start); ``lasting``: no availability topic, so the value stays when the
    bridge goes offline (the totals and counters of the last run, which stay true after
    its end; a live value such as the SOC shows "unavailable" instead).
    """

    key: str  # key in the state JSON (and the object id's suffix)
    name: str
    unit: str | None  # None: text or enum sensor
    device_class: str | None = None
    state_class: str | None = "measurement"
    precision: int | None = None
    diagnostic: bool = False
    source: str = FROM_BRIDGE
    options: tuple[str, ...] = ()
    lasting: bool = False


#: Sensors of the state JSON (units as Home Assistant shows them).
SENSORS: tuple[SensorDef, ...] = (
    # what the EMS sees
    SensorDef("soc_pct", "Battery state of charge", "%", "battery", precision=1, source="soc"),
    SensorDef("loh_pct", "Hydrogen level", "%", None, precision=1, source="loh"),
    SensorDef("t_air_c", "Room temperature", "°C", "temperature", precision=2, source="t_air_c"),
    SensorDef("v_dhw_l", "Usable hot water", "L", "volume_storage", precision=0, source="v_dhw_l"),
    SensorDef("p_pv_w", "PV power", "W", "power", precision=0, source="p_pv_w"),
    SensorDef("p_load_w", "Appliance load", "W", "power", precision=0, source="p_load_w"),
    SensorDef("t_amb_c", "Outdoor temperature", "°C", "temperature", precision=1, source="t_amb_c"),
    # what it decides, and who decides
    SensorDef("in_charge", "In charge", None, "enum", None, options=IN_CHARGE),
    SensorDef("hp_mode", "Heat-pump mode", None, "enum", None, options=HP_MODES),
    SensorDef("hp_mod_pct", "Heat-pump modulation set-point", "%", None, precision=0),
    SensorDef("p_fc_set_w", "Fuel-cell power set-point", "W", "power", precision=0),
    SensorDef("p_bess_set_w", "Battery power set-point", "W", "power", precision=0),
    # what the simulated house did (its records)
    SensorDef("p_hp_el_w", "Heat-pump electric power", "W", "power", precision=0, source=FROM_RECORDS),
    SensorDef("p_fc_w", "Fuel-cell power", "W", "power", precision=0, source=FROM_RECORDS),
    SensorDef("p_bess_w", "Battery power", "W", "power", precision=0, source=FROM_RECORDS),
    SensorDef("p_grid_w", "Grid power", "W", "power", precision=0, source=FROM_RECORDS),
    # run totals (summary.json's cost_eur_total, reimbursement_eur_total, buy/sell_kwh_total, discomfort_kh_total)
    SensorDef("grid_cost_eur", "Grid purchase cost", "EUR", "monetary", "total", 2, source=FROM_RECORDS, lasting=True),
    SensorDef("feed_in_eur", "Feed-in reimbursement", "EUR", "monetary", "total", 2, source=FROM_RECORDS, lasting=True),
    SensorDef("grid_import_kwh", "Grid import", "kWh", "energy", "total", 2, source=FROM_RECORDS, lasting=True),
    SensorDef("grid_export_kwh", "Grid export", "kWh", "energy", "total", 2, source=FROM_RECORDS, lasting=True),
    SensorDef("discomfort_kh", "Thermal discomfort", "K·h", None, "total", 2, source=FROM_RECORDS, lasting=True),
    # diagnostics
    SensorDef("step", "EMS step", None, None, None, diagnostic=True, lasting=True),
    SensorDef("fallback_steps", "Fallback steps", None, None, "total", diagnostic=True, lasting=True),
    SensorDef("clamped_commands", "Clamped commands", None, None, "total", diagnostic=True, lasting=True),
    SensorDef("foreign_messages", "Foreign messages", None, None, "total", diagnostic=True, lasting=True),
    SensorDef("fallback_reason", "Last fallback reason", None, None, None, diagnostic=True),
)
#: Keys of the run totals in the state JSON -> summary.json keys (:func:`comems4build_ros.core.kpi.run_totals`).
TOTAL_KEYS: dict[str, str] = {
    "grid_cost_eur": "cost_eur_total",
    "feed_in_eur": "reimbursement_eur_total",
    "grid_import_kwh": "buy_kwh_total",
    "grid_export_kwh": "sell_kwh_total",
    "discomfort_kh": "discomfort_kh_total",
}
#: Switches: name -> (entity name, object id suffix).
SWITCHES: dict[str, tuple[str, str]] = {
    "ems": ("EMS control", "ems_control"),
    "fallback": ("Forced fallback", "forced_fallback"),
}
#: Settings (``number`` entities): name -> (entity name, object id suffix, set-point it limits, step [W]).
SETTINGS: dict[str, tuple[str, str, str, float]] = {
    "battery_power_limit": ("Battery power limit", "battery_power_limit", "p_bess_w", 50.0),
}
#: Object ids of entities of earlier releases, deleted on connect (empty retained config).
RETIRED: tuple[tuple[str, str], ...] = (("sensor", "cost_eur"),)


def config_topic(topic_map: TopicMap, component: str, object_id: str) -> str:
    """``<discovery_prefix>/<component>/<node_id>/<object_id>/config``."""
    return f"{topic_map.discovery_prefix}/{component}/{topic_map.node_id}/{object_id}/config"


def device_block(topic_map: TopicMap) -> dict[str, Any]:
    """The ``device`` block shared by every entity."""
    d = topic_map.device
    out: dict[str, Any] = {"identifiers": [topic_map.node_id], "name": d.name, "sw_version": __version__}
    if d.manufacturer:
        out["manufacturer"] = d.manufacturer
    if d.model:
        out["model"] = d.model
    if d.configuration_url:
        out["configuration_url"] = d.configuration_url
    return out


def origin_block() -> dict[str, Any]:
    """The ``origin`` block: the software that publishes the configs."""
    return {"name": "comems4build_ros", "sw_version": __version__}


def announced(topic_map: TopicMap, s: SensorDef) -> bool:
    """Whether sensor ``s`` has a value with this topic map (see :class:`SensorDef`)."""
    if s.source == FROM_BRIDGE:
        return True
    if s.source == FROM_RECORDS:
        return bool(topic_map.sim_record_topic)
    return s.source in topic_map.measurements


def sensor_config(topic_map: TopicMap, s: SensorDef, common: dict[str, Any]) -> dict[str, Any]:
    """The discovery payload of sensor ``s``."""
    p: dict[str, Any] = {
        "name": s.name,
        "unique_id": f"{topic_map.node_id}_{s.key}",
        "object_id": f"{topic_map.node_id}_{s.key}",
        "state_topic": topic_map.state_topic,
        "value_template": f"{{{{ value_json.{s.key} }}}}",
        **common,
    }
    if s.unit is not None:
        p["unit_of_measurement"] = s.unit
    if s.device_class:
        p["device_class"] = s.device_class
    if s.state_class:
        p["state_class"] = s.state_class
    if s.state_class == "total":  # a run total restarts with every run: a new meter cycle
        p["last_reset_value_template"] = "{{ value_json.run_start or '' }}"  # '': no run yet (ignored)
    if s.precision is not None:
        p["suggested_display_precision"] = s.precision
    if s.options:
        p["options"] = list(s.options)
    if s.diagnostic:
        p["entity_category"] = "diagnostic"
    return p


def setting_max(limits: dict[str, tuple[float, float]], name: str) -> float:
    """The largest value of setting ``name``: the larger magnitude of its set-point's device limits."""
    lo, hi = limits[SETTINGS[name][2]]
    return max(abs(lo), abs(hi))


def discovery_messages(topic_map: TopicMap, limits: dict[str, tuple[float, float]] | None = None
                       ) -> list[tuple[str, dict[str, Any] | None]]:
    """Every ``(config topic, payload)`` of the EMS's entities (published retained); payload
    None for an entity this topic map does not have (published empty: Home Assistant
    deletes a retained config of an earlier run). ``limits``: the device limits
    (``TopicMap.device_limits``), the range of the settings (none without)."""
    blocks = {"device": device_block(topic_map), "origin": origin_block()}
    common = {
        "availability_topic": topic_map.availability_topic,
        "payload_available": AVAILABLE,
        "payload_not_available": NOT_AVAILABLE,
        **blocks,
    }
    out: list[tuple[str, dict[str, Any] | None]] = []
    for s in SENSORS:
        out.append((config_topic(topic_map, "sensor", s.key),
                    sensor_config(topic_map, s, blocks if s.lasting else common) if announced(topic_map, s) else None))
    out.append((config_topic(topic_map, "binary_sensor", "alarm"), {
        "name": "EMS alarm",
        "unique_id": f"{topic_map.node_id}_alarm",
        "object_id": f"{topic_map.node_id}_alarm",
        "state_topic": topic_map.state_topic,
        "value_template": "{{ value_json.alarm }}",
        "payload_on": PAYLOAD_ON,
        "payload_off": PAYLOAD_OFF,
        "device_class": "problem",
        **common,
    }))
    def commanded(title: str, name: str, object_id: str, topics: tuple[str, str]) -> dict[str, Any]:
        """Fields of an entity the user commands (a switch, a number); the command is retained on
        the broker, so a bridge that (re)connects applies the user's last one."""
        return {"name": title, "unique_id": f"{topic_map.node_id}_{name}",
                "object_id": f"{topic_map.node_id}_{object_id}", "command_topic": topics[0],
                "state_topic": topics[1], "retain": True, **common}

    for name, (title, object_id) in SWITCHES.items():
        out.append((config_topic(topic_map, "switch", name), {
            **commanded(title, name, object_id, topic_map.switch_topics(name)),
            "payload_on": PAYLOAD_ON, "payload_off": PAYLOAD_OFF,
        }))
    for name, (title, object_id, _setpoint, step) in SETTINGS.items():
        if limits is None:
            continue
        out.append((config_topic(topic_map, "number", name), {
            **commanded(title, name, object_id, topic_map.setting_topics(name)),
            "min": 0.0, "max": setting_max(limits, name), "step": step, "mode": "box",
            "unit_of_measurement": "W", "device_class": "power",
        }))
    out.extend((config_topic(topic_map, comp, obj), None) for comp, obj in RETIRED)
    return out


class DiscoveryError(InputError):
    """A discovery message breaks :data:`DISCOVERY_SCHEMA`; the message names topic and field."""


def check_discovery(
    topic: str, payload: dict[str, Any] | bytes | str, discovery_prefix: str = "homeassistant"
) -> str:
    """Check one discovery message; returns its component.

    Checks: the topic is ``<prefix>/<component>/<node_id>/<object_id>/config`` with a
    known component; the payload is a JSON object with every field of the component's
    schema, string topics without wildcards, ``device`` and ``origin`` blocks with their
    fields, ``unique_id`` ending in the object id, a ``unit_of_measurement`` that fits
    the device class, a state class the device class allows, ``options`` for an ``enum``.

    Raises
    ------
    DiscoveryError
        Naming the topic and the field.
    """
    parts = topic.split("/")
    if len(parts) != 5 or parts[0] != discovery_prefix or parts[4] != "config":
        raise DiscoveryError(f"topic '{topic}': not '{discovery_prefix}/<component>/<node_id>/<object_id>/config'")
    component = parts[1]
    if component not in DISCOVERY_SCHEMA:
        raise DiscoveryError(f"topic '{topic}': unknown component '{component}'")
    if isinstance(payload, (bytes, str)):
        try:
            payload = json.loads(payload)
        except json.JSONDecodeError as exc:
            raise DiscoveryError(f"topic '{topic}': payload is not JSON: {exc.msg}") from None
    if not isinstance(payload, dict):
        raise DiscoveryError(f"topic '{topic}': payload is not a JSON object")
    for key in DISCOVERY_SCHEMA[component]:
        if key not in payload or payload[key] in ("", None):
            raise DiscoveryError(f"topic '{topic}': field '{key}' missing")
    for key, value in payload.items():
        if key.endswith("_topic") and (not isinstance(value, str) or any(c in value for c in "+#")):
            raise DiscoveryError(f"topic '{topic}': field '{key}' is not a plain topic: {value!r}")
    for block, fields in (("device", DEVICE_FIELDS), ("origin", ORIGIN_FIELDS)):
        value = payload[block]
        if not isinstance(value, dict) or any(not value.get(k) for k in fields):
            raise DiscoveryError(f"topic '{topic}': field '{block}' needs {list(fields)}")
    if not str(payload["unique_id"]).endswith(parts[3]):
        raise DiscoveryError(f"topic '{topic}': field 'unique_id' {payload['unique_id']!r} does not name object "
                             f"'{parts[3]}'")
    dc = payload.get("device_class")
    if component == "number" and not (isinstance(payload["min"], (int, float)) and
                                      isinstance(payload["max"], (int, float)) and payload["min"] < payload["max"]):
        raise DiscoveryError(f"topic '{topic}': fields 'min' and 'max' must be numbers with min < max")
    if component in ("sensor", "number") and dc in DEVICE_CLASS_UNITS:
        units = DEVICE_CLASS_UNITS[dc]
        unit = payload.get("unit_of_measurement")
        currency = dc == "monetary" and isinstance(unit, str) and len(unit) == 3 and unit.isalpha() and unit.isupper()
        if not unit or (units and unit not in units) or (dc == "monetary" and not currency):
            raise DiscoveryError(f"topic '{topic}': field 'unit_of_measurement' {unit!r} does not fit device class "
                                 f"'{dc}' (expected one of {list(units) or 'an ISO 4217 currency code'})")
    if component == "sensor" and dc in DEVICE_CLASS_STATE_CLASSES and \
            payload.get("state_class") not in DEVICE_CLASS_STATE_CLASSES[dc]:
        raise DiscoveryError(f"topic '{topic}': field 'state_class' {payload.get('state_class')!r} does not fit "
                             f"device class '{dc}' (allowed: {list(DEVICE_CLASS_STATE_CLASSES[dc])})")
    if component == "sensor" and dc == "enum" and (not payload.get("options") or "unit_of_measurement" in payload):
        raise DiscoveryError(f"topic '{topic}': field 'options' missing (an enum sensor has options and no unit)")
    if payload.get("last_reset_value_template") and payload.get("state_class") != "total":
        raise DiscoveryError(f"topic '{topic}': field 'last_reset_value_template' needs state_class 'total'")
    return component
