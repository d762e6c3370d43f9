"""Topic map and codec (comems4build_ros.mqtt.topicmap), watchdog and limiter (mqtt.safety),
Home Assistant discovery (mqtt.discovery), clock parsing (mqtt.clock)."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from comems4build_ros.core.config import ConfigError, load_plant_params
from comems4build_ros.core.types import HP_DHW, Action
from comems4build_ros.mqtt.clock import ClockError, parse_clock
from comems4build_ros.mqtt.discovery import (
    DISCOVERY_SCHEMA,
    DiscoveryError,
    check_discovery,
    discovery_messages,
)
from comems4build_ros.mqtt.safety import CommandLimiter, MeasurementWatchdog
from comems4build_ros.mqtt.topicmap import MeasurementSpec, PayloadError, SetpointSpec, load_topic_map


@pytest.fixture(scope="module")
def tmap():
    return load_topic_map()


# ---------------------------------------------------------------------- codec
@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False))
def test_percent_and_kilowatt_scaling_round_trip_to_the_last_bit(x):
    for scale, offset in ((0.01, 0.0), (1000.0, 0.0), (1.0, -273.15), (0.1, 5.0)):
        spec = MeasurementSpec(topic="a/b", scale=scale, offset=offset, range=(-1e9, 1e9), json_key="value",
                               step_key="step")
        value, step = spec.decode(spec.encode(x, 7))
        assert value == x and step == 7


def test_scaling_by_hand():
    soc = MeasurementSpec(topic="bat/soc", unit="%", scale=0.01, range=(0, 1))
    assert soc.encode(0.5) == b"50"
    assert soc.decode(b"42.5") == (0.425, None)
    kelvin = MeasurementSpec(topic="t", scale=1.0, offset=-273.15, range=(-50, 50))
    assert kelvin.decode(b"293.15") == (20.0, None)
    kw = SetpointSpec(topic="bat/p/set", unit="kW", scale=1000.0)
    assert kw.encode(-750.0) == b"-0.75"


def test_payload_forms_and_errors_name_the_topic():
    plain = MeasurementSpec(topic="fc/on", range=(0, 1))
    assert plain.decode(b"ON")[0] == 1.0 and plain.decode(b"off")[0] == 0.0
    js = MeasurementSpec(topic="zone/t", range=(0, 40), json_key="value", step_key="step")
    assert js.decode(b'{"value": 21.5, "step": 3, "linkquality": 80}') == (21.5, 3)
    assert js.decode(b'{"value": 21.5}') == (21.5, None)
    with pytest.raises(PayloadError, match="topic 'zone/t': payload is not JSON"):
        js.decode(b"21.5}")
    with pytest.raises(PayloadError, match="topic 'zone/t': JSON payload has no key 'value'"):
        js.decode(b'{"temperature": 21.5}')
    with pytest.raises(PayloadError, match="topic 'fc/on': 'abc' is not a number"):
        plain.decode(b"abc")
    mode = SetpointSpec(topic="hp/mode/set", values={"0": "off", "1": "heating", "2": "dhw"})
    assert mode.encode(2) == b"dhw" and mode.decode(b"heating") == (1.0, None)
    with pytest.raises(PayloadError, match="'cool' is not one of"):
        mode.decode(b"cool")


def test_default_map_loads_with_plant_limits(tmap):
    params = load_plant_params()
    limits = tmap.device_limits(params)
    assert limits == {"hp_mod": (0.0, 1.0), "p_fc_w": (0.0, params.fuel_cell.p_max_w),
                      "p_bess_w": (-params.battery.p_d_max_w, params.battery.p_ch_max_w)}
    assert tmap.broker.host == "127.0.0.1" and tmap.broker.port == 1883 and not tmap.broker.tls
    assert load_topic_map(broker_url="mqtts://broker.example:8884").broker.port == 8884


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda m: m["measurements"].pop("soc"), "measurement(s) ['soc'] missing"),
        (lambda m: m["measurements"].update(humidity=dict(m["measurements"]["soc"])), "unknown measurement"),
        (lambda m: m["setpoints"]["hp_mod"].update(topic=m["setpoints"]["p_fc_w"]["topic"]), "topic(s) used twice"),
        (lambda m: m["measurements"]["soc"].update(scale=0), "parameter 'measurements.soc.scale'"),
        (lambda m: m["measurements"]["t_air_c"].update(range=[40, 0]), "parameter 'measurements.t_air_c.range'"),
        (lambda m: m["broker"].update(url="tcp://x"), "parameter 'broker.url'"),
        (lambda m: m["measurements"]["soc"].update(topic="bat/+/soc"), "not a plain MQTT topic"),
    ],
)
def test_invalid_map_is_refused_naming_file_and_parameter(tmp_path, edit, message):
    import yaml

    from comems4build_ros.mqtt.topicmap import default_map_file

    doc = yaml.safe_load(default_map_file().read_text())
    edit(doc["/**"]["ros__parameters"]["mqtt"])
    bad = tmp_path / "map.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match="map.yaml") as info:
        load_topic_map(bad)
    assert message in str(info.value)


# ---------------------------------------------------------------------- watchdog and limiter
def test_watchdog_flags_missing_stale_out_of_range_and_nan(tmap):
    w = MeasurementWatchdog(tmap)
    assert {p.measurement for p in w.check(0.0)} == {"t_air_c", "v_dhw_l", "soc", "loh", "hp_mod", "fc_on"}
    for name in tmap.measurements:
        lo, hi = tmap.measurements[name].range
        w.update(name, (lo + hi) / 2, 4, t_recv=100.0)
    assert w.check(100.0) == [] and w.complete_for(4) and not w.complete_for(5)
    w.update("t_air_c", 80.0, 5, t_recv=101.0)
    w.update("soc", math.nan, 5, t_recv=101.0)
    kinds = {(p.measurement, p.kind) for p in w.check(101.0)}
    assert kinds == {("t_air_c", "out_of_range"), ("soc", "out_of_range")}
    stale = w.check(100.0 + tmap.max_age_s + 1.0, check_age=True)
    assert ("v_dhw_l", "stale") in {(p.measurement, p.kind) for p in stale}
    assert all(p.kind != "stale" for p in w.check(100.0 + tmap.max_age_s + 1.0, check_age=False))


def test_limiter_clamps_counts_ramps_and_rate_limits():
    lim = CommandLimiter({"hp_mod": (0.0, 1.0), "p_fc_w": (0.0, 2000.0), "p_bess_w": (-1000.0, 1000.0)},
                         {"hp_mod": 0.0, "p_fc_w": 500.0, "p_bess_w": 0.0}, min_interval_s=10.0)
    out, notes = lim.limit(Action(hp_mod=1.2, hp_mode=HP_DHW, p_fc_w=0.0, p_bess_w=-5000.0))
    assert out == Action(hp_mod=1.0, hp_mode=HP_DHW, p_fc_w=0.0, p_bess_w=-1000.0)
    assert len(notes) == 2 and lim.counters.clamped == {"hp_mod": 1, "p_bess_w": 1}
    assert lim.counters.clamped_commands == 1
    out, notes = lim.limit(Action(hp_mod=0.5, hp_mode=7, p_fc_w=1800.0, p_bess_w=math.nan))
    assert out == Action(hp_mod=0.5, hp_mode=0, p_fc_w=500.0, p_bess_w=0.0)  # ramp 0 -> 500 W
    assert lim.counters.ramped == {"p_fc_w": 1} and lim.counters.invalid_mode == 1
    out, notes = lim.limit(Action(hp_mod=0.5, hp_mode=1, p_fc_w=600.0, p_bess_w=0.0))
    assert notes == [] and lim.counters.clamped_commands == 2
    assert lim.may_send(0.0)
    lim.sent(0.0)
    assert not lim.may_send(5.0) and lim.counters.rate_limited == 1 and lim.may_send(10.0)


# ---------------------------------------------------------------------- Home Assistant discovery
def test_every_discovery_payload_matches_the_documented_schema(tmap):
    limits = tmap.device_limits(load_plant_params())
    msgs = [(t, p) for t, p in discovery_messages(tmap, limits) if p is not None]  # None: deleted (not this map's)
    components = {check_discovery(t, json.dumps(p)) for t, p in msgs}
    assert components == set(DISCOVERY_SCHEMA)
    ids = [p["unique_id"] for _, p in msgs]
    assert len(ids) == len(set(ids)) and len({p["object_id"] for _, p in msgs}) == len(ids)
    for topic, p in msgs:
        assert topic.startswith(f"homeassistant/{topic.split('/')[1]}/{tmap.node_id}/")
        # live values go unavailable with the bridge; run totals and counters keep the last run's
        lasting = p.get("state_class") == "total" or topic.endswith("/step/config")
        assert p.get("availability_topic") == (None if lasting else tmap.availability_topic)
        assert p["device"]["identifiers"] == [tmap.node_id]
        if p.get("device_class") in ("power", "energy", "monetary"):
            assert p["unit_of_measurement"]
    power = dict(msgs)["homeassistant/sensor/comems4build/p_bess_w/config"]
    assert power["unit_of_measurement"] == "W" and power["state_topic"] == "comems4build/state"


@pytest.mark.parametrize(
    ("topic", "edit", "message"),
    [
        ("homeassistant/sensor/comems4build/p_bess_w/config", lambda p: p.pop("unique_id"), "field 'unique_id'"),
        ("homeassistant/sensor/comems4build/p_bess_w/config", lambda p: p.pop("state_topic"), "field 'state_topic'"),
        ("homeassistant/sensor/comems4build/p_bess_w/config", lambda p: p.update(unit_of_measurement="kWh"),
         "does not fit device class 'power'"),
        ("homeassistant/sensor/comems4build/p_bess_w/config", lambda p: p["device"].pop("identifiers"),
         "field 'device'"),
        ("homeassistant/switch/comems4build/ems/config", lambda p: p.pop("command_topic"), "field 'command_topic'"),
        ("homeassistant/sensor/comems4build/p_bess_w/config", lambda p: p.update(state_topic="a/#"), "plain topic"),
    ],
)
def test_broken_discovery_payloads_are_refused(tmap, topic, edit, message):
    payload = json.loads(json.dumps(dict(discovery_messages(tmap))[topic]))
    edit(payload)
    with pytest.raises(DiscoveryError, match=message):
        check_discovery(topic, payload)
    with pytest.raises(DiscoveryError, match="unknown component 'light'"):
        check_discovery("homeassistant/light/comems4build/x/config", payload)


# ---------------------------------------------------------------------- clock
def test_clock_specs():
    assert parse_clock("sim").wall is False
    wall = parse_clock("wall")
    assert wall.period_s == 3600.0 and wall.first_boundary(7201.0) == 10800.0
    fast = parse_clock("wall:3600")
    assert fast.period_s == 1.0 and fast.spec() == "wall:3600" and fast.first_boundary(10.2, lead_s=1.0) == 12.0
    for bad in ("wall:0", "wall:x", "fast", "wall:-2"):
        with pytest.raises(ClockError, match="expected 'sim', 'wall' or 'wall:<factor>'"):
            parse_clock(bad)
