"""Tests of the topic contract (msg_defs/topics.yaml and comems4build_ros/wire/contract.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from comems4build_ros.core import kpi
from comems4build_ros.core.ems.base import FORECAST_KEYS, INFO_LEVELS
from comems4build_ros.core.loop import TIMESERIES_COLUMNS
from comems4build_ros.core.types import ACTION_FIELDS, EXOGENOUS_FIELDS, FLOW_FIELDS, STATE_FIELDS
from comems4build_ros.ros.interfaces import message_class, qos_profile
from comems4build_ros.wire.contract import (
    ALLOWED_TYPES,
    ContractError,
    load_contract,
    markdown_table,
    nest,
    parse_contract,
    relative,
    resolve,
)

SIZES = {"horizon": 24, "comfort_ahead": 6}


@pytest.fixture(scope="module")
def contract():
    return load_contract()


def test_every_topic_uses_an_allowed_type_and_has_unit_and_publisher(contract):
    assert len(contract.topics) >= 20
    for t in contract.topics.values():
        assert t.type in ALLOWED_TYPES
        assert t.unit
        assert t.publishers
        # relative for namespaces; the one absolute name is the time source's /clock
        assert not t.name.startswith("/") or t.name == "/clock", "names must be relative for namespaces"


def test_ems_nodes_receive_exactly_their_information_level(contract):
    # tab:level_of_information: an EMS node's topics carry exactly the Observation fields
    # of its level (plus the step tag), no more and no less.
    ems_nodes = [n for n in contract.nodes.values() if n.role == "ems"]
    assert {n.ems for n in ems_nodes} >= {"thermostat", "rbc", "fuzzy", "mpc"}
    for n in ems_nodes:
        got = contract.input_fields(n.name) | {"step"}
        assert got == INFO_LEVELS[n.info_level], n.name


def test_rbc_sees_no_weather_and_no_forecast(contract):
    topics = {t.name for t in contract.subscribed_by("rbc_ems")}
    assert "feed/solar" not in topics and "feed/t_amb" not in topics
    assert not any(t.startswith("forecast/") for t in topics)
    assert "state/fc_on" not in topics and "feed/h2_allowance" not in topics
    fuzzy = {t.name for t in contract.subscribed_by("fuzzy_ems")}
    assert "feed/solar" in fuzzy and "feed/t_amb" not in fuzzy
    assert not any(t.startswith("forecast/") for t in fuzzy)


def test_forecast_topics_cover_every_forecast_key_and_only_mpc_reads_them(contract):
    fc = {t.name.split("/", 1)[1]: t for t in contract.topics.values() if t.name.startswith("forecast/")}
    assert set(fc) == set(FORECAST_KEYS)
    for t in fc.values():
        assert set(t.subscribers) == {"mpc_ems", "mpc_qp_ems"}


def test_inputs_not_read_are_the_feed_topics_above_an_ems_level(contract):
    # what a feed serving one EMS leaves out: the EMS topics of the higher levels, never
    # feed/truth (the plant's) nor the topics every EMS reads
    assert contract.inputs_not_read("mpc_ems") == ()
    fuzzy = set(contract.inputs_not_read("fuzzy_ems"))
    assert fuzzy == {"feed/t_amb"} | {t.name for t in contract.topics.values() if t.name.startswith("forecast/")}
    rbc = set(contract.inputs_not_read("rbc_ems"))
    assert rbc == fuzzy | {"feed/comfort_ahead", "feed/solar", "feed/h2_allowance", "feed/season"}
    for ems in ("thermostat_ems", "rbc_ems", "fuzzy_ems", "mpc_ems"):
        read = {t.name for t in contract.subscribed_by(ems)}
        published = {t.name for t in contract.published_by("feed")}
        assert read & set(contract.inputs_not_read(ems)) == set()
        assert published - set(contract.inputs_not_read(ems)) >= read & published | {"feed/truth"}
    with pytest.raises(ContractError, match="'plant_sim' is not an EMS node"):
        contract.inputs_not_read("plant_sim")


def test_record_layout_is_the_in_process_timeseries_row(contract):
    # plant/record carries one row of sim.py's timeseries (time as unix seconds), so the
    # bag evaluation rebuilds the same table and the same KPIs.
    names = contract.topic("plant/record").field_names()
    assert names[: len(TIMESERIES_COLUMNS) - 1] == TIMESERIES_COLUMNS[1:]
    assert set(kpi.REQUIRED_COLUMNS) - {"time"} <= set(names)
    assert set(STATE_FIELDS) <= set(names) and set(FLOW_FIELDS) <= set(names)
    assert {f"cmd_{a}" for a in ACTION_FIELDS} <= set(names)
    assert names[len(TIMESERIES_COLUMNS) - 1 :] == ("time_unix_s", "fallback_steps", "rejected_commands",
                                                     "wrong_step_commands", "foreign_commands")


def test_truth_layout_carries_every_exogenous_field(contract):
    names = contract.topic("feed/truth").field_names()
    assert set(EXOGENOUS_FIELDS) <= set(names)
    assert names[:3] == ("step", "n_steps", "time_unix_s")


def test_command_layout_is_step_plus_action_fields(contract):
    assert contract.topic("ems/command").field_names() == ("step", *ACTION_FIELDS, "token")


def test_layout_expansion_pack_unpack_roundtrip(contract):
    lay = contract.topic("feed/prices").layout(SIZES)
    assert lay.length == 1 + 2 + 24
    assert lay.labels[3] == "prices_buy_24h[0]" and lay.labels[-1] == "prices_buy_24h[23]"
    assert lay.dim_label == "step,price_buy_eur_per_kwh,price_sell_eur_per_kwh,prices_buy_24h[24]"
    prices = [0.30 + 0.01 * i for i in range(24)]
    values = {"step": 7, "price_buy_eur_per_kwh": 0.3, "price_sell_eur_per_kwh": 0.0794, "prices_buy_24h": prices}
    data = lay.pack(values)
    back = lay.unpack(data)
    assert back["step"] == 7 and isinstance(back["step"], int)
    assert back["price_sell_eur_per_kwh"] == 0.0794
    assert back["prices_buy_24h"] == tuple(prices)  # float64 passes through bit for bit, as a tuple like sim.py
    with pytest.raises(ContractError, match="feed/prices.*28 elements"):
        lay.unpack([*data, 1.0])
    with pytest.raises(ContractError, match="prices_buy_24h.*23 elements"):
        lay.pack({**values, "prices_buy_24h": prices[:-1]})


def test_boolean_and_forecast_labels(contract):
    cal = contract.topic("feed/calendar").layout(SIZES).unpack([3.0, 0.0, 23.0, 6.0, 1.0])
    assert cal == {"step": 3, "day_index": 0, "hour_of_day": 23, "weekday": 6, "is_weekend": True}
    lay = contract.topic("forecast/t_amb_c").layout(SIZES)
    flat = lay.unpack([0.0, *range(24)])
    assert nest(flat)["forecast"]["t_amb_c"][5] == 5.0


def test_may_publish_and_subscribe(contract):
    assert contract.may_publish("plant_sim", "state/soc")
    assert not contract.may_publish("fuzzy_ems", "state/soc")
    assert contract.may_subscribe("mpc_ems", "forecast/p_load_w")
    assert not contract.may_subscribe("fuzzy_ems", "forecast/p_load_w")
    assert contract.may_subscribe("recorder", "forecast/p_load_w")  # records every topic
    assert contract.may_publish("replay", "feed/truth")  # replays every topic
    assert not contract.may_publish("plant_sim", "no/such/topic")
    assert contract.ems_node_name("fuzzy") == "fuzzy_ems"
    with pytest.raises(ContractError, match="no EMS node for 'nope'"):
        contract.ems_node_name("nope")


def test_namespace_helpers():
    assert resolve("/", "state/soc") == "/state/soc"
    assert resolve("/house_3", "state/soc") == "/house_3/state/soc"
    assert relative("/house_3", "/house_3/state/soc") == "state/soc"
    assert relative("/", "/clock") == "clock"
    assert relative("/house_3", "/house_4/state/soc") is None


def test_qos_profiles_build(contract):
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    for t in contract.topics.values():
        message_class(t)
        p = qos_profile(t)
        assert p.reliability == ReliabilityPolicy.RELIABLE
        assert p.depth >= 1
    assert qos_profile(contract.topic("recorder/ready")).durability == DurabilityPolicy.TRANSIENT_LOCAL


def _doc(contract_file: Path) -> dict:
    return yaml.safe_load(contract_file.read_text())


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d["topics"]["state/soc"].update(type="std_msgs/msg/Float32"), "topic 'state/soc': type must be"),
        (lambda d: d["topics"]["state/soc"].update(layout=["soc", "step"]), "first element must be 'step'"),
        (lambda d: d["topics"]["state/soc"].update(subscribers=["ghost"]), "node 'ghost' is not declared"),
        (lambda d: d["topics"]["state/soc"].pop("unit"), "topic 'state/soc': needs a 'unit'"),
        (lambda d: d["topics"]["state/soc"].update(qos={"depth": 0}), "state/soc'.qos.depth"),
        (lambda d: d["topics"].update({"/abs": d["topics"]["state/soc"]}), "the only absolute topic is /clock"),
        (lambda d: d["topics"].update({"a//b": d["topics"]["state/soc"]}), "name must be relative"),
        (lambda d: d["topics"]["plant/done"].update(layout=["step"]), "only std_msgs/msg/Float64MultiArray"),
        (lambda d: d["topics"]["state/soc"].update(layout=["step", "soc", "soc"]), "duplicate label 'soc'"),
    ],
)
def test_invalid_contract_is_rejected_naming_file_and_topic(contract, tmp_path, mutate, message):
    doc = _doc(contract.path)
    mutate(doc)
    with pytest.raises(ContractError, match=message) as err:
        parse_contract(doc, tmp_path / "bad.yaml")
    assert "bad.yaml" in str(err.value)


def test_unreadable_contract_names_the_file(tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("version: [unclosed\n")
    with pytest.raises(ContractError, match=r"broken.yaml(:\d+:\d+)?: invalid YAML"):
        load_contract(bad)


def test_markdown_table_lists_every_topic(contract):
    table = markdown_table(contract)
    for name in contract.topics:
        assert f"`{name}`" in table



def test_docs_table_lists_every_topic(contract):
    """docs/ros_nodes.md documents every topic of the contract (forecast topics as one row)."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "ros_nodes.md").read_text()
    for name in contract.topics:
        if name.startswith("forecast/"):
            assert name.split("/", 1)[1] in text, name
        else:
            assert f"`{name}`" in text, name
