"""Home Assistant MQTT discovery for the EMS's sensors and switches.

Home Assistant creates an entity for every retained config message on
``<discovery_prefix>/<component>/<node_id>/<object_id>/config`` (Home Assistant MQTT
integration documentation, "MQTT Discovery"). The bridge publishes one per entity on
every (re)connect, all pointing at one JSON state topic (``<base>/state``, read with a
``value_template``) and at the availability topic ``<base>/availability`` whose last will
is ``offline``. Entities:

* sensors: run KPIs so far (cost, discomfort ``eq:discomfort``, grid import and export),
  the current step, fallback steps and clamped commands, the heat-pump mode and the next
  set-points (modulation, fuel-cell power, battery power);
* binary sensor ``alarm`` (device class ``problem``);
* switches ``ems`` (off: the bridge sends the safe fallback action instead of the EMS's
  commands) and ``fallback`` (on: the same, forced; its state also shows a fallback the
  watchdog started).

:data:`DISCOVERY_SCHEMA` lists the fields each component's payload must have, and
:func:`validate_discovery` checks a payload against it (used by the tests and by the bridge
before it publishes).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from comems4build_ros.mqtt.topicmap import TopicMap

#: Required payload fields per component (HA MQTT discovery); ``unit_of_measurement``
#: is required, and checked, for sensors with a device class of :data:`DEVICE_CLASS_UNITS`.
DISCOVERY_SCHEMA: dict[str, tuple[str, ...]] = {
    "sensor": ("name", "unique_id", "state_topic", "value_template", "device", "availability_topic"),
    "binary_sensor": ("name", "unique_id", "state_topic", "value_template", "device", "availability_topic",
                      "payload_on", "payload_off"),
    "switch": ("name", "unique_id", "state_topic", "command_topic", "device", "availability_topic",
               "payload_on", "payload_off"),
}
#: Units Home Assistant accepts for the device classes used here (empty: any currency).
DEVICE_CLASS_UNITS: dict[str, tuple[str, ...]] = {
    "power": ("W", "kW"),
    "energy": ("Wh", "kWh", "MWh"),
    "monetary": (),
    "temperature": ("°C", "K"),
}
#: Required fields of the ``device`` block.
DEVICE_FIELDS = ("identifiers", "name")
PAYLOAD_ON, PAYLOAD_OFF = "ON", "OFF"
AVAILABLE, NOT_AVAILABLE = "online", "offline"


@dataclass(frozen=True)
class SensorDef:
    """One numeric or text sensor of the state JSON."""

    key: str  # key in the state JSON
    name: str
    unit: str | None  # None: text sensor
    device_class: str | None = None
    state_class: str | None = "measurement"


#: Sensors of the state JSON (units as Home Assistant shows them).
SENSORS: tuple[SensorDef, ...] = (
    SensorDef("cost_eur", "Energy cost of the run", "EUR", "monetary", "total"),
    SensorDef("discomfort_kh", "Thermal discomfort of the run", "K·h", None, "total_increasing"),
    SensorDef("grid_import_kwh", "Grid import of the run", "kWh", "energy", "total_increasing"),
    SensorDef("grid_export_kwh", "Grid export of the run", "kWh", "energy", "total_increasing"),
    SensorDef("step", "EMS step", None, None, None),
    SensorDef("fallback_steps", "Fallback steps", None, None, "total_increasing"),
    SensorDef("clamped_commands", "Clamped commands", None, None, "total_increasing"),
    SensorDef("hp_mode", "Heat-pump mode", None, None, None),
    SensorDef("hp_mod_pct", "Heat-pump modulation set-point", "%", None, "measurement"),
    SensorDef("p_fc_w", "Fuel-cell power set-point", "W", "power", "measurement"),
    SensorDef("p_bess_w", "Battery power set-point", "W", "power", "measurement"),
)
#: Switches: name -> description.
SWITCHES: dict[str, str] = {
    "ems": "EMS control (off: safe fallback action)",
    "fallback": "Forced fallback",
}


def config_topic(topic_map: TopicMap, component: str, object_id: str) -> str:
    """``<discovery_prefix>/<component>/<node_id>/<object_id>/config``."""
    return f"{topic_map.discovery_prefix}/{component}/{topic_map.node_id}/{object_id}/config"


def device_block(topic_map: TopicMap) -> dict[str, Any]:
    """The ``device`` block shared by every entity."""
    d = topic_map.device
    out: dict[str, Any] = {"identifiers": [topic_map.node_id], "name": d.name}
    if d.manufacturer:
        out["manufacturer"] = d.manufacturer
    if d.model:
        out["model"] = d.model
    return out


def discovery_messages(topic_map: TopicMap) -> list[tuple[str, dict[str, Any]]]:
    """Every ``(config topic, payload)`` of the EMS's entities (published retained)."""
    dev = device_block(topic_map)
    common = {
        "availability_topic": topic_map.availability_topic,
        "payload_available": AVAILABLE,
        "payload_not_available": NOT_AVAILABLE,
        "device": dev,
    }
    out: list[tuple[str, dict[str, Any]]] = []
    for s in SENSORS:
        p: dict[str, Any] = {
            "name": s.name,
            "unique_id": f"{topic_map.node_id}_{s.key}",
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
        out.append((config_topic(topic_map, "sensor", s.key), p))
    out.append((config_topic(topic_map, "binary_sensor", "alarm"), {
        "name": "EMS alarm",
        "unique_id": f"{topic_map.node_id}_alarm",
        "state_topic": topic_map.state_topic,
        "value_template": "{{ value_json.alarm }}",
        "payload_on": PAYLOAD_ON,
        "payload_off": PAYLOAD_OFF,
        "device_class": "problem",
        **common,
    }))
    for name, title in SWITCHES.items():
        cmd, state = topic_map.switch_topics(name)
        out.append((config_topic(topic_map, "switch", name), {
            "name": title,
            "unique_id": f"{topic_map.node_id}_{name}",
            "command_topic": cmd,
            "state_topic": state,
            "payload_on": PAYLOAD_ON,
            "payload_off": PAYLOAD_OFF,
            **common,
        }))
    return out


class DiscoveryError(ValueError):
    """A discovery message breaks :data:`DISCOVERY_SCHEMA`; the message names topic and field."""


def validate_discovery(
    topic: str, payload: dict[str, Any] | bytes | str, discovery_prefix: str = "homeassistant"
) -> str:
    """Check one discovery message; returns its component.

    Checks: the topic is ``<prefix>/<component>/<node_id>/<object_id>/config`` with a
    known component; the payload is a JSON object with every field of the component's
    schema, string topics without wildcards, a ``device`` block with identifiers and
    name, ``unique_id`` ending in the object id, and a ``unit_of_measurement`` for
    every sensor with a ``state_class`` (numeric sensors).

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
    dev = payload["device"]
    if not isinstance(dev, dict) or any(not dev.get(k) for k in DEVICE_FIELDS):
        raise DiscoveryError(f"topic '{topic}': field 'device' needs {list(DEVICE_FIELDS)}")
    if not str(payload["unique_id"]).endswith(parts[3]):
        raise DiscoveryError(f"topic '{topic}': field 'unique_id' {payload['unique_id']!r} does not name object "
                             f"'{parts[3]}'")
    if component == "sensor" and payload.get("device_class") in DEVICE_CLASS_UNITS:
        units = DEVICE_CLASS_UNITS[payload["device_class"]]
        unit = payload.get("unit_of_measurement")
        if not unit or (units and unit not in units):
            raise DiscoveryError(f"topic '{topic}': field 'unit_of_measurement' {unit!r} does not fit device class "
                                 f"'{payload['device_class']}' (expected one of {list(units) or 'a currency'})")
    return component
