"""The sharing rule sets of a community (``config/sharing.yaml``) and their settlement."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from comems4build_ros.core.community.sharing import (
    charge_parts,
    load_sharing_rules,
    settle,
    share_prices,
)
from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.scenario.csvio import ScenarioError

RULES = load_sharing_rules()
TZ = "Europe/Berlin"


def test_the_rule_sets_are_the_three_legal_cases_and_the_reference() -> None:
    assert list(RULES.rule_sets) == ["none", "enwg_42c", "one_connection", "at_local"]
    enwg, one, at = RULES.rule_sets["enwg_42c"], RULES.rule_sets["one_connection"], RULES.rule_sets["at_local"]
    assert (enwg.network_share, enwg.levies_share, enwg.electricity_tax_share) == (1.0, 1.0, 1.0)
    assert (one.network_share, one.levies_share, one.concession_share) == (0.0, 0.0, 0.0)
    assert at.network_share == pytest.approx(1 - 0.57)
    assert "precarious" in one.legal_status and "C-293/23" in one.legal_status
    assert not RULES.rule_sets["none"].shares_energy


def test_the_charges_come_from_the_tariff_data_of_the_hour_s_year() -> None:
    """The network charge of 2022 and 2023 and the EEG surcharge abolished from July 2022 (config/tariffs.yaml)."""
    time = pd.DatetimeIndex(["2022-06-30 12:00", "2022-07-01 12:00", "2023-01-15 12:00"]).tz_localize(TZ)
    parts = charge_parts(time, TZ)
    assert parts.levies[0] > parts.levies[1] + 0.03  # the EEG surcharge of the first half of 2022
    assert parts.network[2] > parts.network[1]
    assert np.all(parts.vat_share == 0.19) and np.all(parts.electricity_tax == 0.0205)


def test_a_year_the_tariff_data_lacks_is_refused_naming_the_file_and_year() -> None:
    time = pd.DatetimeIndex(["2031-01-15 12:00"]).tz_localize(TZ)
    with pytest.raises(ScenarioError, match=r"tariffs\.yaml: no tariff for 2031"):
        charge_parts(time, TZ)


@pytest.mark.parametrize("text, field", [
    ("sharing: {sources: {a: x}, rule_sets: {r: {label: L, legal_status: s, shares_energy: true, network_share: 1.5, "
     "concession_share: 1, levies_share: 1, electricity_tax_share: 1, price_position: 0.5, sources: [a]}}}",
     "rule_sets.r.network_share"),
    ("sharing: {sources: {a: x}, rule_sets: {r: {label: L, legal_status: s, shares_energy: true, network_share: 1, "
     "concession_share: 1, levies_share: 1, electricity_tax_share: 1, price_position: 0.5, sources: [b]}}}",
     "'b' is not among the sources"),
    ("sharing: {sources: {a: x}, rule_sets: {r: {label: L, legal_status: s, shares_energy: true, network_share: 1, "
     "concession_share: 1, levies_share: 1, electricity_tax_share: 1, price_position: 0.5, sources: [a], vat: 0}}}",
     "rule_sets.r.vat"),
    ("rules: {}", "needs a mapping 'sharing'"),
])
def test_a_bad_rule_file_is_refused_naming_the_file_and_field(tmp_path, text: str, field: str) -> None:
    path = tmp_path / "t1" / "sharing.yaml"
    path.parent.mkdir()
    path.write_text(text + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="sharing.yaml") as info:
        load_sharing_rules(path)
    assert field in str(info.value)


@st.composite
def meters(draw):
    """Random meter readings of 1..6 houses and a hub over 1..30 steps [W], with 2022/2023 tariff hours."""
    n, t = draw(st.integers(1, 6)), draw(st.integers(1, 30))
    power = st.floats(0, 8000, allow_subnormal=False)
    buy = np.array(draw(st.lists(st.lists(power, min_size=t, max_size=t), min_size=n, max_size=n)))
    sell = np.array(draw(st.lists(st.lists(power, min_size=t, max_size=t), min_size=n, max_size=n)))
    sell = np.where(draw(st.booleans()), sell, np.where(buy > 0, 0.0, sell))  # a meter buys or sells
    hub = np.array(draw(st.lists(st.floats(0, 20000, allow_subnormal=False), min_size=t, max_size=t)))
    weights = np.array(draw(st.lists(st.lists(st.floats(0.01, 1), min_size=t, max_size=t), min_size=n, max_size=n)))
    start = draw(st.sampled_from(["2022-03-01", "2022-07-15", "2022-12-01", "2023-02-20"]))
    time = pd.date_range(start, periods=t, freq="h", tz=TZ)
    spot = np.array(draw(st.lists(st.floats(-0.05, 0.7), min_size=t, max_size=t)))
    return buy, sell, hub, weights / weights.sum(axis=0), time, 0.105 + 1.64 * spot, np.full(t, 0.0794)


@settings(max_examples=150, deadline=None)
@given(meters())
def test_the_settlement_conserves_energy_and_orders_the_rule_sets(m) -> None:
    """Shared energy leaves the exporters and reaches the importers whole; the grid covers the rest; the
    rule sets that keep fewer charges never cost the community more; without charges (one connection
    point) the community pays what its connection point exchanges."""
    buy, sell, hub, weights, time, p_buy, p_sell = m
    parts = charge_parts(time, TZ)
    names = [f"h{i}" for i in range(len(buy))]
    out = {name: settle(name, rule, buy, sell, hub, weights, p_buy, p_sell, parts, 1.0, names)
           for name, rule in RULES.rule_sets.items()}
    demand = (buy.sum(axis=0) + hub) / 1000.0
    supply = sell.sum(axis=0) / 1000.0
    shared = np.minimum(demand, supply).sum()
    tol = 1e-9 * max(1.0, demand.sum() + supply.sum())
    for name, s in out.items():
        h = s.houses
        expect = shared if RULES.rule_sets[name].shares_energy else 0.0
        assert s.totals["shared_kwh"] == pytest.approx(expect, abs=tol)
        assert h["shared_out_kwh"].sum() == pytest.approx(expect, abs=tol)
        assert h["shared_in_kwh"].sum() <= expect + tol
        assert s.totals["grid_buy_kwh"] == pytest.approx(demand.sum() - expect, abs=tol)
        assert s.totals["grid_sell_kwh"] == pytest.approx(supply.sum() - expect, abs=tol)
        assert (h["grid_buy_kwh"] >= -tol).all() and (h["grid_sell_kwh"] >= -tol).all()
        assert h["hub_kwh"].sum() == pytest.approx(hub.sum() / 1000.0, rel=1e-9, abs=tol)
        assert s.totals["cost_eur"] == pytest.approx(h["cost_eur"].sum(), rel=1e-9, abs=1e-9)
    net = (buy.sum(axis=0) + hub - sell.sum(axis=0)) / 1000.0
    cp = float(np.sum(np.maximum(net, 0) * p_buy) - np.sum(np.maximum(-net, 0) * p_sell))
    assert out["one_connection"].totals["cost_eur"] == pytest.approx(cp, rel=1e-9, abs=1e-9)
    cost = {name: s.totals["cost_eur"] for name, s in out.items()}
    assert cost["one_connection"] <= cost["at_local"] + 1e-9 <= cost["enwg_42c"] + 2e-9


@settings(max_examples=100, deadline=None)
@given(st.floats(-0.05, 0.9), st.floats(0.0, 0.3), st.sampled_from(list(RULES.rule_sets)))
def test_the_share_price_lies_between_the_feed_in_value_and_the_retail_energy_component(spot, feed_in, name) -> None:
    time = pd.date_range("2022-12-01", periods=1, freq="h", tz=TZ)
    parts = charge_parts(time, TZ)
    p_buy = np.array([0.105 + 1.64 * spot])
    p_s, p_c = share_prices(RULES.rule_sets[name], p_buy, np.array([feed_in]), parts)
    energy = p_buy / (1 + parts.vat_share) - parts.total
    assert feed_in - 1e-12 <= p_s[0] <= max(energy[0], feed_in) + 1e-12
    assert p_c[0] >= p_s[0] - 1e-12
