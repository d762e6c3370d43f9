"""Run ids and authentication codes of the MQTT messages between bridge and house
(``comems4build_ros.mqtt.peer``), the house's view of the bridge's retained messages, and
the Home Assistant discovery payloads (``comems4build_ros.mqtt.discovery``). No broker here:
test/test_mqtt_bridge.py and test/test_home_assistant.py run the real ones."""

from __future__ import annotations

import json
import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from comems4build_ros.mqtt.discovery import (
    SENSORS,
    TOTAL_KEYS,
    DiscoveryError,
    check_discovery,
    discovery_messages,
)
from comems4build_ros.mqtt.peer import (
    ForeignMessageError,
    Peer,
    check_run_id,
    new_run_id,
    open_sealed,
    read_peer_key,
    seal,
    with_run,
)
from comems4build_ros.mqtt.plant_sim import BridgeView
from comems4build_ros.mqtt.topicmap import load_topic_map
from comems4build_ros.wire.tokens import write_token_file

#: The default topic map, read once (a load per example would count against hypothesis's deadline).
MAP = load_topic_map()

KEY = b"mqtt:123456789"
#: The machines are shared and loaded: no per-example deadline, no complaint about slow draws.
LOADED = {"deadline": None, "suppress_health_check": [HealthCheck.too_slow]}
run_ids = st.text(alphabet=string.ascii_letters + string.digits + "_.-", min_size=1, max_size=64)
topics = st.text(alphabet=string.ascii_lowercase + "/_", min_size=1, max_size=40)
values = st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.integers(-10**6, 10**6), st.text(max_size=20),
                   st.booleans(), st.none())
objects = st.dictionaries(st.text(alphabet=string.ascii_lowercase, min_size=1, max_size=8), values, min_size=1,
                          max_size=5).filter(lambda d: "mac" not in d and "run" not in d)


@settings(**LOADED)
@given(topic=topics, obj=objects, run=run_ids)
def test_a_sealed_payload_opens_to_itself_with_the_run_id(topic: str, obj: dict, run: str) -> None:
    peer = Peer(run, KEY)
    body = open_sealed(KEY, topic, peer.wrap(topic, json.dumps(obj).encode()))
    assert json.loads(body) == {**obj, "run": run}
    assert peer.unwrap(topic, peer.wrap(topic, json.dumps(obj).encode())) == body and peer.foreign == {}


@settings(max_examples=300, **LOADED)
@given(topic=topics, obj=objects, data=st.data())
def test_any_changed_byte_makes_a_sealed_payload_foreign(topic: str, obj: dict, data: st.DataObject) -> None:
    sealed = bytearray(seal(KEY, topic, json.dumps(obj).encode()))
    i = data.draw(st.integers(0, len(sealed) - 1))
    b = data.draw(st.integers(0, 255).filter(lambda v: v != sealed[i]))
    sealed[i] = b
    with pytest.raises(ForeignMessageError):
        open_sealed(KEY, topic, bytes(sealed))


@settings(**LOADED)
@given(topic=topics, obj=objects)
def test_the_code_binds_topic_and_key(topic: str, obj: dict) -> None:
    sealed = seal(KEY, topic, json.dumps(obj).encode())
    with pytest.raises(ForeignMessageError, match="wrong authentication code"):
        open_sealed(KEY, topic + "x", sealed)  # the same payload moved to another topic
    with pytest.raises(ForeignMessageError, match="wrong authentication code"):
        open_sealed(b"mqtt:987654321", topic, sealed)  # a code made with another key


@settings(max_examples=300, **LOADED)
@given(payload=st.binary(max_size=200), topic=topics)
def test_malformed_payloads_are_foreign_with_a_key_never_another_error(payload: bytes, topic: str) -> None:
    peer = Peer("run1", KEY)
    with pytest.raises(ForeignMessageError) as info:
        peer.unwrap(topic, payload)
    assert topic in str(info.value) and peer.foreign_total == 1


@settings(**LOADED)
@given(mine=run_ids, other=run_ids, step=st.integers(0, 10**6))
def test_a_message_of_another_run_is_foreign_even_with_a_valid_code(mine: str, other: str, step: int) -> None:
    """A message recorded in an earlier run of the same secret (a replay) names that run."""
    if mine == other:
        return
    replay = Peer(other, KEY).wrap("building/battery/power/set", f'{{"value": 0.0, "step": {step}}}'.encode())
    peer = Peer(mine, KEY)
    with pytest.raises(ForeignMessageError, match=f"message of run '{other}'"):
        peer.unwrap("building/battery/power/set", replay)
    assert peer.foreign == {"another run": 1}


@settings(**LOADED)
@given(value=st.floats(allow_nan=False, allow_infinity=False), other=run_ids)
def test_without_a_key_plain_values_pass_and_other_runs_do_not(value: float, other: str) -> None:
    peer = Peer("this-run", None)
    assert peer.unwrap("building/zone/air_temperature", repr(value).encode()) == repr(value).encode()
    assert peer.unwrap("t", b'{"value": 1}') == b'{"value": 1}'  # a real device's JSON without a run id
    if other != "this-run":
        with pytest.raises(ForeignMessageError):
            peer.unwrap("t", with_run(b'{"value": 1}', other))
    with pytest.raises(ForeignMessageError, match="no run id"):
        Peer("this-run", KEY).unwrap("t", seal(KEY, "t", b'{"value": 1}'))  # a code but no run id


def test_run_ids_and_peer_key_file(tmp_path: Path) -> None:
    assert check_run_id(new_run_id()) and len(new_run_id()) == 12 and new_run_id() != new_run_id()
    for bad in ("", "a b", "x" * 65, "ü", "a/b"):
        with pytest.raises(ValueError, match="run id"):
            check_run_id(bad)
    f = write_token_file(tmp_path / "s" / "mqtt.token", 4242)
    assert read_peer_key(f) == b"mqtt:4242"
    f.chmod(0o644)
    with pytest.raises(ValueError, match="lets other users read"):
        read_peer_key(f)
    with pytest.raises(ValueError, match="non-empty JSON object"):
        seal(KEY, "t", b"21.5")


# ---------------------------------------------------------------------- the house's view of the bridge
class _House:
    """The parts of MqttPlantSim that BridgeView reads (no scenario needed)."""

    def __init__(self, run: str | None, key: bytes | None) -> None:
        self.map = MAP
        self.peer = Peer(run, key)
        self.acked = 0

    def acknowledge(self, records: int) -> None:
        self.acked = max(self.acked, records)


@settings(**LOADED)
@given(other=run_ids, step=st.integers(0, 10**5), records=st.integers(0, 10**5), retained=st.booleans(),
       key=st.sampled_from([None, KEY]))
def test_the_house_takes_no_step_or_run_message_of_another_run(other: str, step: int, records: int, retained: bool,
                                                               key: bytes | None) -> None:
    house = _House("mine", key)
    view = BridgeView(house)  # type: ignore[arg-type]
    m = house.map
    if other != "mine":
        bad = Peer(other, key)
        view.on_message(m.step_topic, bad.wrap(m.step_topic, json.dumps({"step": step, "records": records}).encode()),
                        retained)
        view.on_message(m.run_topic, bad.wrap(m.run_topic, b'{"t0_unix_s": 1.0, "period_s": 1.0}'), retained)
        view.on_message(m.step_topic, str(step).encode(), retained)  # an older release's plain step number
        assert view.step == -1 and view.run_msg is None and house.acked == 0
    good = Peer("mine", key)
    view.on_message(m.step_topic, good.wrap(m.step_topic, json.dumps({"step": step, "records": records}).encode()),
                    retained)
    assert view.step == step and house.acked == records
    view.on_message(m.run_topic, good.wrap(m.run_topic, b'{"t0_unix_s": 5.0, "period_s": 1.0}'), retained)
    assert view.run_msg is not None and view.run_msg["t0_unix_s"] == 5.0


def test_a_house_without_run_id_adopts_only_a_live_run_message() -> None:
    house = _House(None, None)
    view = BridgeView(house)  # type: ignore[arg-type]
    m = house.map
    cut = with_run(b'{"t0_unix_s": 1.0, "period_s": 1.0}', "cut-run")
    view.on_message(m.run_topic, cut, retained=True)  # a cut run's retained message
    assert house.peer.run_id is None and view.run_msg is None
    view.on_message(m.run_topic, with_run(b'{"t0_unix_s": 9.0, "period_s": 1.0}', "live-run"), retained=False)
    assert house.peer.run_id == "live-run" and view.run_msg is not None and view.run_msg["t0_unix_s"] == 9.0


# ---------------------------------------------------------------------- discovery
def _real_building_map(tmp_path: Path) -> Path:
    import yaml

    from comems4build_ros.mqtt.topicmap import default_map_file

    doc = yaml.safe_load(default_map_file().read_text())
    mq = doc["/**"]["ros__parameters"]["mqtt"]
    mq["sim_record_topic"] = ""
    for name in ("p_pv_w", "t_amb_c", "t_wall_in_c", "t_wall_out_c"):
        del mq["measurements"][name]
    f = tmp_path / "real.yaml"
    f.write_text(yaml.safe_dump(doc))
    return f


def test_discovery_for_the_simulated_house_and_for_a_real_building(tmp_path: Path) -> None:
    sim = dict(discovery_messages(load_topic_map()))
    real = dict(discovery_messages(load_topic_map(_real_building_map(tmp_path))))
    for msgs in (sim, real):
        for topic, payload in msgs.items():
            if payload is not None:
                check_discovery(topic, payload)
    prefix = "homeassistant/sensor/comems4build/"
    # the simulated house: every sensor; the run totals with last_reset, lasting after the run
    assert all(sim[f"{prefix}{s.key}/config"] is not None for s in SENSORS)
    cost = sim[f"{prefix}grid_cost_eur/config"]
    assert cost["state_class"] == "total" and cost["device_class"] == "monetary" and \
        cost["last_reset_value_template"] == "{{ value_json.run_start or '' }}" and "availability_topic" not in cost
    assert cost["suggested_display_precision"] == 2 and cost["object_id"] == "comems4build_grid_cost_eur"
    mode = sim[f"{prefix}hp_mode/config"]
    assert mode["device_class"] == "enum" and mode["options"] == ["off", "heating", "dhw"]
    assert sim[f"{prefix}fallback_steps/config"]["entity_category"] == "diagnostic"
    switch = sim["homeassistant/switch/comems4build/ems/config"]
    assert switch["retain"] is True and switch["object_id"] == "comems4build_ems_control"
    assert switch["device"]["sw_version"] and switch["origin"]["name"] == "comems4build_ros"
    # a real building: no record, no totals and no record powers (deleted: empty config); no PV meter here
    gone = [k for k, p in real.items() if p is None and k.startswith(prefix)]
    assert sorted(gone) == sorted(f"{prefix}{k}/config" for k in
                                  (*TOTAL_KEYS, "p_hp_el_w", "p_fc_w", "p_bess_w", "p_grid_w", "p_pv_w", "t_amb_c",
                                   "cost_eur"))
    assert real[f"{prefix}p_load_w/config"] is not None and real[f"{prefix}soc_pct/config"] is not None


@pytest.mark.parametrize(("change", "message"), [
    (lambda p: p.update(state_class="total_increasing"), "does not fit device class 'monetary'"),
    (lambda p: p.update(unit_of_measurement="W"), "does not fit device class 'monetary'"),
    (lambda p: p.pop("origin"), "field 'origin' missing"),
    (lambda p: p["device"].pop("sw_version"), "field 'device' needs"),
    (lambda p: p.update(state_class="measurement"), "does not fit device class"),
])
def test_discovery_check_names_the_field(change, message: str) -> None:
    topic, payload = next((t, p) for t, p in discovery_messages(load_topic_map()) if t.endswith("grid_cost_eur/config"))
    payload = json.loads(json.dumps(payload))
    change(payload)
    with pytest.raises(DiscoveryError, match=message):
        check_discovery(topic, payload)


@settings(max_examples=300, **LOADED)
@given(payload=st.one_of(st.binary(max_size=40), st.floats().map(lambda v: repr(v).encode()),
                         st.integers(-5000, 5000).map(lambda v: str(v).encode())))
def test_a_setting_is_a_number_within_its_range_or_refused_naming_the_topic(payload: bytes) -> None:
    from comems4build_ros.mqtt.safety import SettingError, parse_setting

    topic = "comems4build/setting/battery_power_limit/set"
    try:
        value = parse_setting(topic, payload, 0.0, 1000.0)
    except SettingError as exc:
        assert topic in str(exc)
    else:
        assert 0.0 <= value <= 1000.0 and value == float(payload.decode())


def test_the_battery_power_limit_narrows_the_device_limits() -> None:
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.types import Action
    from comems4build_ros.mqtt.safety import CommandLimiter

    limiter = CommandLimiter.from_map(MAP, load_plant_params())
    assert limiter.set_power_limit("p_bess_w", 300.0) == (-300.0, 300.0)
    out, notes = limiter.limit(Action(hp_mod=0.5, hp_mode=1, p_fc_w=0.0, p_bess_w=-800.0))
    assert out.p_bess_w == -300.0 and "the user's limits [-300, 300]" in notes[0]
    assert limiter.set_power_limit("p_bess_w", 5000.0) == limiter.device_limits["p_bess_w"]  # never beyond the device
    sim = dict(discovery_messages(MAP, MAP.device_limits(load_plant_params())))
    number = sim["homeassistant/number/comems4build/battery_power_limit/config"]
    assert check_discovery("homeassistant/number/comems4build/battery_power_limit/config", number) == "number"
    assert number["max"] == 1000.0 and number["retain"] is True and number["device_class"] == "power"
