"""The community: houses sharing one H2 hub (``core/community``).

- a community of one house whose hub is that house's own H2 system is the isolated house,
  bit for bit (the paper's winter; the year with the electrolyser at the hub);
- H2 and electricity balances close in every step over random communities;
- the community file, the coordinator table, the hub's electrolyser bank and transfers.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from comems4build_ros.core.community.coordinator import (
    CommunityInfo,
    UnknownCoordinatorError,
    coordinator_class,
    coordinator_names,
    make_coordinator,
    parse_coordinator_table,
)
from comems4build_ros.core.community.hub import CLIP_TRANSFER, ElectrolyserBank, Hub, HubState
from comems4build_ros.core.community.loop import simulate_community, write_community
from comems4build_ros.core.community.rule import water_fill
from comems4build_ros.core.community.spec import (
    CommunitySpec,
    HouseSpec,
    HubParams,
    HubSpec,
    build_community,
    load_community,
)
from comems4build_ros.core.config import ConfigError, config_dir, load_plant_params, scenario_config_files
from comems4build_ros.core.loop import TIMESERIES_COLUMNS, simulate
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.core.types import PlantState

YEAR = load_plant_params(scenario_config_files("year", []))
ONE = CommunitySpec(name="one", houses=[HouseSpec(name="h", reason="the paper's house alone")])
#: The columns of an isolated house that a community of one house moves to the connection point
#: (its grid exchange) and to the hub (its electrolyser), in the timeseries of the community's house.
MOVED = {"p_buy_w": "cp_p_buy_w", "p_sell_w": "cp_p_sell_w", "balance_residual_w": "cp_balance_residual_w",
         "p_el_w": "p_el_w", "el_on": "el_on", "el_start": "el_start", "p_h2_el_w": "p_h2_el_w",
         "q_el_rec_w": "q_el_rec_w"}


def _single_and_one(scenario: str, ems: str, hours: int, start: str | None = None):
    params = load_plant_params(scenario_config_files(scenario, []))
    single = simulate(ems, resolve_scenario(scenario, params, hours=hours, start=start), params)
    community = build_community(ONE, scenario, hours=hours, start=start)
    return single, simulate_community(community, "rule", ems)


@pytest.mark.parametrize("ems", ["fuzzy", "rbc"])
def test_one_house_with_its_own_hydrogen_system_as_hub_is_the_paper_s_house_bit_for_bit(ems: str) -> None:
    """The paper's winter (first week): every column of the timeseries and every KPI of the summary."""
    single, one = _single_and_one("default", ems, 168)
    house = one.houses["h"]
    for col in single.timeseries.columns:
        assert single.timeseries[col].equals(house.timeseries[col]), col
    keys = [k for k in single.summary if k not in ("wall_s", "ems_s", "scenario_extended")]
    assert {k: single.summary[k] for k in keys} == {k: house.summary[k] for k in keys}
    total = single.summary["cost_eur_total"] - single.summary["reimbursement_eur_total"]
    assert one.summary["cost_cp_eur"] == pytest.approx(total, abs=1e-9)
    assert one.summary["cost_eur_one_connection"] == pytest.approx(total, abs=1e-6)


@pytest.mark.parametrize("ems", ["fuzzy", "rbc"])
def test_one_house_of_the_year_is_the_house_with_its_electrolyser_at_the_hub_bit_for_bit(ems: str) -> None:
    """Three May days of the year scenario (the electrolyser runs): the house's devices, states and
    commands bit for bit; its grid exchange is the connection point's, its electrolyser the hub's; its
    clip bits split between the house and the hub."""
    single, one = _single_and_one("year", ems, 72, "2022-05-01")
    ts, house, hub = single.timeseries, one.houses["h"].timeseries, one.hub
    assert ts["p_el_w"].max() > 1000.0 and ts["p_h2_el_w"].sum() > 0.0  # the electrolyser ran
    for col in ts.columns:
        if col in MOVED:
            assert np.array_equal(ts[col].to_numpy(float), hub[MOVED[col]].to_numpy(float)), col
        elif col == "clipped":
            assert np.array_equal(ts[col].to_numpy(int), house[col].to_numpy(int) | hub[col].to_numpy(int))
        else:
            assert ts[col].equals(house[col]), col
    assert np.array_equal(ts["loh"].to_numpy(), hub["loh"].to_numpy())


# ----------------------------------------------------------------- balances
houses_st = st.builds(
    HouseSpec,
    name=st.just("x"),
    reason=st.just("random neighbour"),
    load_scale=st.floats(0.3, 2.0),
    load_seed=st.one_of(st.none(), st.integers(0, 10_000)),
    dhw_scale=st.floats(0.0, 2.0),
    dhw_shift_days=st.integers(-30, 30),
    pv_n_modules=st.one_of(st.none(), st.integers(0, 60)),
    pv_azimuth_deg=st.one_of(st.none(), st.floats(0, 360)),
    building_scale=st.floats(0.7, 1.3),
    h2_weight=st.floats(0.2, 3.0),
)


@st.composite
def communities(draw):
    """A random community of 1..6 houses, its hub, scenario window and coordinator options."""
    houses = draw(st.lists(houses_st, min_size=1, max_size=6))
    houses = [h.model_copy(update={"name": f"h{i}"}) for i, h in enumerate(houses)]
    hub = HubSpec(store_kwh=draw(st.one_of(st.none(), st.floats(50.0, 20_000.0))),
                  electrolyser_modules=draw(st.one_of(st.none(), st.integers(0, 8))),
                  standing_loss_per_h=draw(st.sampled_from([0.0, 1e-4, 0.01])))
    scenario, start = draw(st.sampled_from([("year", "2022-04-20"), ("year", "2022-07-01"), ("default", None)]))
    loh_init = draw(st.sampled_from([None, 0.0, 0.5, 0.98]))
    options = {"h2_split": draw(st.sampled_from(["equal", "need"])), "need_days": draw(st.integers(1, 3))}
    return CommunitySpec(name="random", houses=houses, hub=hub), scenario, start, loh_init, options


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(communities(), st.integers(24, 60))
def test_hydrogen_and_electricity_balances_close_in_every_step(case, hours) -> None:
    """Over random communities: the hub's store changes by production - fuel cells' use - losses and equals
    the accounts plus the pool, every house's and the connection point's power balance closes, the
    connection point exchanges the net of the meters and the hub, each to 1e-6 of its throughput."""
    spec, scenario, start, loh_init, options = case
    overrides = {} if loh_init is None else {"simulation.loh_init": loh_init}
    community = build_community(spec, scenario, overrides=overrides, hours=hours, start=start)
    result = simulate_community(community, "rule", "rbc", coordinator_options=options)
    hub = result.hub
    e0 = result.summary["hub_loh_init"] * community.hub.e_max_wh
    flows = (hub["p_h2_el_w"] + hub["p_h2_fc_w"] + hub["p_h2_loss_w"]).to_numpy(float)
    throughput = e0 + np.cumsum(flows)  # Wh at 1 h steps
    store = hub["store_kwh"].to_numpy(float) * 1000.0
    assert np.all(np.abs(hub["h2_residual_wh"].to_numpy(float)) <= 1e-6 * throughput + 1e-9)
    change = np.diff(np.concatenate(([e0], store)))
    made = (hub["p_h2_el_w"] - hub["p_h2_fc_w"] - hub["p_h2_loss_w"]).to_numpy(float)
    assert np.all(np.abs(change - made) <= 1e-6 * throughput + 1e-9)
    assert np.all(hub["pool_kwh"].to_numpy(float) >= 0.0)
    cp_through = (hub["cp_p_pv_w"] + hub["cp_p_buy_w"] + hub["cp_p_fc_w"] + hub["cp_p_dis_w"]).to_numpy(float)
    assert np.all(np.abs(hub["cp_balance_residual_w"].to_numpy(float)) <= 1e-6 * cp_through + 1e-9)
    net_meters = sum((r.timeseries["p_buy_w"] - r.timeseries["p_sell_w"]).to_numpy(float)
                     for r in result.houses.values())
    net_cp = (hub["cp_p_buy_w"] - hub["cp_p_sell_w"]).to_numpy(float)
    assert np.all(np.abs(net_cp - (net_meters + hub["p_el_w"].to_numpy(float))) <= 1e-6 * cp_through + 1e-9)
    for r in result.houses.values():
        ts = r.timeseries
        through = (ts["p_pv_w"] + ts["p_buy_w"] + ts["p_fc_w"] + ts["p_dis_w"]).to_numpy(float)
        assert np.all(np.abs(ts["balance_residual_w"].to_numpy(float)) <= 1e-6 * through + 1e-9)
    credited = sum(r.timeseries["hub_credited_wh"].to_numpy(float) for r in result.houses.values())
    assert np.allclose(credited, hub["h2_credited_wh"].to_numpy(float), rtol=1e-12, atol=1e-9)
    assert result.summary["h2_balance_max_rel"] <= 1e-6


# -------------------------------------------------------------- the community file
def _write(tmp_path, text: str):
    path = tmp_path / "t1" / "community.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


HOUSE = "{name: a, reason: r}"


@pytest.mark.parametrize("text, field", [
    ("- a list\n", "needs a mapping 'community'"),
    (f"community: {{name: c, houses: [{HOUSE}]}}\nextra: 1\n", "unknown top-level key(s) extra"),
    ("community: {name: c, houses: [{name: a, reason: r, load_scal: 2}]}\n", "houses.0.load_scal"),
    ("community: {name: c, houses: [{name: a, reason: r, load_scale: 0}]}\n", "houses.0.load_scale"),
    ("community: {name: c, houses: [{name: a, reason: r, load_scale: true}]}\n", "houses.0.load_scale"),
    ("community: {name: c, houses: [{name: a}]}\n", "houses.0.reason"),
    (f"community: {{name: c, houses: [{HOUSE}, {HOUSE}]}}\n", "the name 'a' is given twice"),
    ("community: {name: c, houses: []}\n", "houses"),
    ("community: {name: c, houses: [{name: 'a b', reason: r}]}\n", "houses.0.name"),
    (f"community: {{name: c, hub: {{store_kwh: -5}}, houses: [{HOUSE}]}}\n", "hub.store_kwh"),
    (f"community: {{name: c, hub: {{standing_loss_per_h: 0.5}}, houses: [{HOUSE}]}}\n", "hub.standing_loss_per_h"),
    ("community: {name: c, houses: [{name: a, reason: r, set: {hydrogen.e_max_kwh: 9}}]}\n", "houses.0.set"),
    ("community: {name: c, houses: [{name: a, reason: r, pv_tilt_deg: 95}]}\n", "houses.0.pv_tilt_deg"),
])
def test_a_bad_community_file_is_refused_naming_the_file_and_field(tmp_path, text: str, field: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match="community.yaml") as info:
        load_community(path)
    assert field in str(info.value)


def test_a_house_variation_a_plant_refuses_is_named_with_its_house(tmp_path) -> None:
    path = _write(tmp_path, "community: {name: c, houses: [{name: a, reason: r}, {name: b, reason: r, "
                            "set: {battery.soc_min: 0.95}}]}\n")
    spec = load_community(path)
    with pytest.raises(ConfigError, match=r"community.yaml: house 'b': .*battery") as info:
        build_community(spec, "default", hours=24, source=str(path))
    assert "soc_min" in str(info.value)


def test_a_missing_community_file_is_named(tmp_path) -> None:
    with pytest.raises(ConfigError, match="community file .*nope.yaml"):
        load_community(tmp_path / "nope.yaml")


def test_the_default_community_has_eight_different_houses_and_a_hub_of_their_own_h2_systems() -> None:
    spec = load_community(config_dir() / "community" / "default.yaml")
    winter = build_community(spec, "default", hours=48)
    year = build_community(spec, "year", hours=48, start="2022-06-01")
    assert len(winter.houses) == 8 and winter.houses[0].spec.load_seed is None
    assert winter.hub.e_max_wh == 8 * 1800e3 and winter.hub.electrolyser.n_modules == 0
    assert year.hub.electrolyser.n_modules == 8
    assert all(h.share_wh == 1800e3 for h in winter.houses)
    loads = {round(float(h.scenario.p_load_w.sum())) for h in winter.houses}
    pv = {(h.params.pv.n_modules, h.params.pv.azimuth_deg) for h in winter.houses}
    dhw = {round(float(h.scenario.dhw_l_per_h[:48].sum())) for h in winter.houses}
    assert len(loads) == 8 and len(pv) >= 6 and len(dhw) >= 4
    assert all(h.plant_params.electrolyser.n_modules == 0 for h in year.houses)
    assert all(h.params.electrolyser.n_modules == 1 for h in year.houses)
    assert all(h.spec.reason for h in winter.houses)
    c_air = [h.params.building.c_air_j_per_k for h in winter.houses]
    assert max(c_air) / min(c_air) == pytest.approx(1.15 / 0.85)


# --------------------------------------------------------------- coordinators
def test_the_coordinator_table_names_the_four_coordinators() -> None:
    assert coordinator_names() == ("rule", "fuzzy", "central", "distributed")
    for name in coordinator_names():
        assert coordinator_class(name).name == name
    with pytest.raises(UnknownCoordinatorError, match="known: central, distributed, fuzzy, rule"):
        coordinator_class("auction")


@pytest.mark.parametrize("doc, problem", [
    ({"coordinators": {}}, "needs a mapping"),
    ({"coordinators": {"a": {"coordinator": "m:C", "label": "A", "colour": "#000000", "summary": "s"}}},
     "missing options"),
    ({"coordinators": {"a": {"coordinator": "m.C", "label": "A", "colour": "#000000", "options": {},
                             "summary": "s"}}}, "module:Class"),
    ({"coordinators": {"a": {"coordinator": "m:C", "label": "", "colour": "#000000", "options": {},
                             "summary": "s"}}}, "label"),
    ({"coordinators": {"a": {"coordinator": "m:C", "label": "A", "colour": "#000000", "options": [],
                             "summary": "s", "x": 1}}}, "unknown x"),
])
def test_a_bad_coordinator_table_is_refused_naming_the_row(doc, problem) -> None:
    with pytest.raises(ConfigError, match="coordinators.yaml: ") as info:
        parse_coordinator_table(doc, "coordinators.yaml")
    assert problem in str(info.value)


def _info(n: int = 2) -> CommunityInfo:
    return CommunityInfo(tuple(f"h{i}" for i in range(n)), (1800e3,) * n, 1.0, 24, n * 1800e3, n, 1493.0, 2465.0)


def test_coordinator_options_are_checked_by_the_coordinator() -> None:
    assert make_coordinator("rule", _info(), {"h2_split": "need"}).options.h2_split == "need"
    with pytest.raises(ConfigError, match="coordinator 'rule' options: parameter 'h2_splt'"):
        make_coordinator("rule", _info(), {"h2_splt": "need"})
    with pytest.raises(ConfigError, match="h2_split"):
        make_coordinator("rule", _info(), {"h2_split": "fair"})


@settings(max_examples=200, deadline=None)
@given(st.floats(0, 1e6), st.lists(st.tuples(st.floats(0.0, 10.0), st.floats(0, 1e5)), min_size=1, max_size=8))
def test_water_fill_shares_in_proportion_within_the_caps(total, pairs) -> None:
    weights, caps = [p[0] for p in pairs], [p[1] for p in pairs]
    out = water_fill(total, weights, caps)
    assert all(-1e-9 <= o <= c + 1e-6 for o, c in zip(out, caps))
    assert sum(out) == pytest.approx(min(total, sum(caps)), rel=1e-9, abs=1e-6)


# -------------------------------------------------------------------- the hub
@settings(max_examples=300, deadline=None)
@given(st.floats(-500, 4000), st.floats(0.0, 1.0), st.booleans(), st.sampled_from([1.0, 0.5]))
def test_a_bank_of_one_module_is_the_house_s_electrolyser(p, loh, was_on, dt_h) -> None:
    el = YEAR.electrolyser
    table, bank = ElectrolyserTable(el), ElectrolyserBank(el.model_copy(update={"n_modules": 1}))
    p_el, h2, on, q, loh_t, clip = table.run(p, loh, was_on, dt_h, 1.0, 1.8e6)
    b_el, b_h2, b_on, b_q, b_loh, b_clip, started = bank.run(p, loh, int(was_on), dt_h, 1.0, 1.8e6)
    assert (p_el, h2, on, q, loh_t, clip) == (b_el, b_h2, b_on > 0, b_q, b_loh, b_clip)
    assert started == (on and not was_on)


@settings(max_examples=300, deadline=None)
@given(st.floats(0, 30000), st.integers(1, 8), st.integers(0, 8))
def test_a_bank_runs_as_many_modules_as_a_set_point_needs(p, n, warm) -> None:
    bank = ElectrolyserBank(YEAR.electrolyser.model_copy(update={"n_modules": n}))
    p_el, h2, on, _, loh, _, _ = bank.run(p, 0.2, min(warm, n), 1.0, 1.0, 1.0e9)
    assert 0 <= on <= n
    if on:
        assert bank.p_module_min_w * on <= p_el - (n - on) * bank.p_standby_module_w + 1e-6
        assert p_el - (n - on) * bank.p_standby_module_w <= max(p, on * bank.p_module_min_w) + 1e-6
        assert h2 > 0.0 and loh > 0.2
    else:
        assert h2 == 0.0 and p_el == pytest.approx(n * bank.p_standby_module_w)


def test_transfers_are_cut_to_the_pool_and_the_accounts() -> None:
    params = HubParams(3600e3, 0.0, 1.0, YEAR.electrolyser, 0.0, 1.0)
    hub = Hub(params, [1800e3, 1800e3], [0.0, 0.0], [1.0, 1.0])
    states = [PlantState(0.5, loh, 21.0, 21.0, 10.0, 200.0) for loh in (0.5, 0.99)]
    state = HubState(loh=(0.5 * 1800e3 + 0.99 * 1800e3 + 1000.0) / 3600e3, pool_wh=1000.0)
    moved, clip = hub.transfer(states, state, [5000.0, 50_000.0])
    assert moved == [1000.0, 0.0] and clip & CLIP_TRANSFER and state.pool_wh == 0.0
    moved, clip = hub.transfer(states, state, [-2e6, 0.0])
    assert moved[0] == pytest.approx(-(0.5 * 1800e3 + 1000.0)) and clip & CLIP_TRANSFER
    assert abs(hub.balance_residual_wh(states, state)) < 1e-6
    with pytest.raises(ValueError, match="not finite"):
        hub.transfer(states, state, [math.nan, 0.0])


def test_need_shares_move_hydrogen_to_the_houses_that_buy_more(tmp_path) -> None:
    """Two houses, one buying much more: with ``need`` its account ends fuller than with ``equal``."""
    spec = CommunitySpec(name="two", houses=[HouseSpec(name="big", reason="r", load_scale=2.5, building_scale=1.2),
                                             HouseSpec(name="small", reason="r", load_scale=0.4,
                                                       building_scale=0.8)])
    community = build_community(spec, "default", hours=72)
    equal = simulate_community(community, "rule", "rbc")
    need = simulate_community(community, "rule", "rbc", coordinator_options={"h2_split": "need"})
    big_equal = equal.houses["big"].timeseries["loh"].iloc[-1]
    big_need = need.houses["big"].timeseries["loh"].iloc[-1]
    small_need = need.houses["small"].timeseries["loh"].iloc[-1]
    assert big_need > big_equal and small_need < big_need
    assert need.houses["big"].timeseries["hub_transfer_wh"].sum() > 0.0
    out = write_community(need, tmp_path / "t1")
    summary = json.loads((out / "community.json").read_text(encoding="utf-8"))
    assert summary["coordinator"] == "rule" and summary["houses"] == 2
    assert (out / "houses" / "big" / "timeseries.csv").is_file() and (out / "hub.csv").is_file()
    assert set(TIMESERIES_COLUMNS) <= set(need.houses["big"].timeseries.columns)
