"""The fuzzy, central and distributed coordinators: short runs with closed balances, the distributed
ADMM against the central optimum, the central limit, FLC_hub's rule file refused by name."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from comems4build_ros.app.cli import main
from comems4build_ros.core.community.coordinator import (
    CommunityInfo,
    CommunityView,
    HouseReport,
    HubReport,
    Request,
    make_coordinator,
)
from comems4build_ros.core.community.hubrun import community_info
from comems4build_ros.core.community.loop import simulate_community
from comems4build_ros.core.community.optimal import transfers_from
from comems4build_ros.core.community.plant import CommunityPlant
from comems4build_ros.core.community.spec import build_community, load_community
from comems4build_ros.core.config import ConfigError, config_dir

THREE = """community:
  name: three
  houses:
    - {name: a, reason: "the paper's house"}
    - {name: b, reason: "a 2-person neighbour with an east roof", load_scale: 0.71, load_seed: 5, dhw_scale: 0.5,
       dhw_shift_days: 7, pv_azimuth_deg: 90, pv_n_modules: 24, building_scale: 0.85}
    - {name: c, reason: "a single person under a west roof", load_scale: 0.47, load_seed: 6, dhw_scale: 0.25,
       dhw_shift_days: 14, pv_azimuth_deg: 270, pv_n_modules: 16}
"""
OPTIMISING = ("central", "distributed")


def _community(tmp_path: Path, houses: int = 3, scenario: str = "default", start: str | None = None,
               hours: int = 3):
    path = tmp_path / "three.yaml"
    path.write_text(THREE, encoding="utf-8")
    spec = load_community(path)
    spec = spec.model_copy(update={"houses": spec.houses[:houses]})
    return build_community(spec, scenario, source=str(path), start=start, hours=hours)


def _views(community, steps: int = 1) -> list[CommunityView]:
    """The views of the first steps of a rule-coordinated run, with the houses' MPC-level observations."""
    info = community_info(community, CommunityPlant(community).hub)
    views: list[CommunityView] = []

    class Grab:
        name = "rule"
        info_level = "mpc"
        step_info: dict[str, float] = {}

        def __init__(self) -> None:
            self.rule = make_coordinator("rule", info)

        def reset(self) -> None:
            self.rule.reset()

        def allot(self, view):
            views.append(view)
            return self.rule.allot(view)

        def dispatch(self, view, requests):
            return self.rule.dispatch(view, requests)

    simulate_community(community, Grab(), "fuzzy")
    return views[:steps]


@pytest.mark.parametrize("coordinator", ["fuzzy", *OPTIMISING])
@pytest.mark.parametrize("window", ["winter", "may"])
def test_each_coordinator_runs_a_small_community_with_closed_balances(tmp_path: Path, coordinator: str,
                                                                     window: str) -> None:
    # the paper's winter (no electrolysers) and a May morning of the year (the hub's electrolysers run)
    community = (_community(tmp_path, 2, hours=3) if window == "winter" else
                 _community(tmp_path, 2, "year", "2022-05-02T09:00", hours=3))
    result = simulate_community(community, coordinator, "fuzzy")
    s, hub = result.summary, result.hub
    assert s["coordinator"] == coordinator and s["steps"] == 3
    assert s["h2_balance_max_rel"] <= 1e-6
    # the store's change is production - use - loss in every step, the connection point's balance closes
    store_wh = hub["store_kwh"].to_numpy() * 1000.0
    before = np.concatenate([[store_wh[0] - (hub["p_h2_el_w"][0] - hub["p_h2_fc_w"][0] - hub["p_h2_loss_w"][0])],
                             store_wh[:-1]])
    flow = (hub["p_h2_el_w"] - hub["p_h2_fc_w"] - hub["p_h2_loss_w"]).to_numpy()
    assert np.allclose(store_wh - before, flow, atol=1e-6 * max(1.0, float(np.abs(flow).max())))
    assert np.abs(hub["cp_balance_residual_w"]).max() <= 1e-6 * max(1.0, float(hub["cp_p_buy_w"].abs().max()))
    if window == "may":
        assert s["h2_produced_kwh"] > 0.0
    if coordinator == "central":
        assert hub["coord_solve_s"].gt(0).all() and not hub["coord_fallback"].any()
    if coordinator == "distributed":  # prices and totals per iteration and house, 2N + 1 per step besides
        assert (hub["coord_messages"] == 2 * 2 * hub["coord_iterations"] + 2 * 2 + 1).all()
        assert hub["coord_converged"].all()


def test_distributed_reaches_the_central_optimum_on_three_houses(tmp_path: Path) -> None:
    community = _community(tmp_path, 3, hours=2)
    info = community_info(community, CommunityPlant(community).hub)
    view = _views(community)[0]
    central = make_coordinator("central", info, {"mip_rel_gap": 1e-4}).solve(view)
    relaxed = make_coordinator("central", info, {"relaxed": True}).solve(view)
    distributed = make_coordinator("distributed", info)
    admm = distributed.solve(view)
    assert central["optimal"] and admm["converged"] and admm["residual_kw"] <= 0.01
    assert relaxed["objective"] <= central["objective"] + 1e-6
    # the ADMM's fixed point is the LP relaxation's optimum
    assert abs(admm["objective"] - relaxed["objective"]) <= 5e-3 * abs(relaxed["objective"])
    # the houses' integer plan at its prices costs within 1 % of the central MILP's optimum
    prices = distributed.u
    integer = distributed.recover(view)
    assert integer["converged"] and integer["residual_kw"] <= 0.01
    assert abs(integer["objective"] - central["objective"]) <= 1e-2 * abs(central["objective"])
    # and leaves the agents relaxed and the decision's prices as they were
    assert all(v.lowBound == 0 and v.upBound == 1 for h in distributed.houses for v in h.model.v["s_fc"])
    assert all(np.array_equal(a, b) for a, b in zip(prices, distributed.u))


def test_central_refuses_above_its_limit(tmp_path: Path, capsys) -> None:
    community = _community(tmp_path, 3, hours=1)
    info = community_info(community, CommunityPlant(community).hub)
    with pytest.raises(ConfigError, match="3 houses exceed its limit of 2 .option max_houses."):
        make_coordinator("central", info, {"max_houses": 2})
    many = dataclasses.replace(info, names=tuple(f"h{i}" for i in range(17)),
                               shares_wh=(1.0,) * 17, house_params=info.house_params * 6)
    with pytest.raises(ConfigError, match="17 houses exceed its limit of 16"):
        make_coordinator("central", many)
    assert main(["compare", "--community", str(tmp_path / "three.yaml"), "--weeks", "0.25", "--coordinator",
                 "central", "--coordinator-option", "central.max_houses=1", "--out", str(tmp_path / "c")]) == 2
    assert "max_houses" in capsys.readouterr().err


def _rules(tmp_path: Path, old: str, new: str) -> Path:
    text = (config_dir() / "fuzzy" / "hub.yaml").read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "hub_bad.yaml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


@pytest.mark.parametrize("old, new, message", [
    ('"surplus=small -> off"', '"surplus=tiny -> off"', "'surplus' has no term 'tiny'"),
    ('        - "surplus=small -> off"\n', "", "incomplete rule base: no rule covers surplus=small"),
    ('"surplus=small -> off"', '"surplus=small -> full"\n        - "surplus=small, loh=full -> off"',
     "conflicting rules"),
    ("order: [surplus, loh, need, price, winter]", "order: [loh, surplus, need, price, winter]",
     "inputs.order must be"),
    ('small: ["0.0", "0.0", "0.5*el_min", "el_min"]', 'small: ["0.0", "0.0", "0.5*el_low", "el_min"]',
     "term 'surplus.small': cannot read point '0.5\\*el_low'"),
    ("flc_hub:", "flc_other:", "no section 'flc_hub'"),
    ("low: [0.0, 0.0, 0.25, 0.5]", "low: [0.0, 0.3, 0.25, 0.5]", "term 'need.low': points must not decrease"),
])
def test_bad_hub_rules_are_refused_naming_file_and_culprit(tmp_path: Path, capsys, old: str, new: str,
                                                           message: str) -> None:
    path = _rules(tmp_path, old, new)
    community = _community(tmp_path, 2, hours=1)
    info = community_info(community, CommunityPlant(community).hub)
    with pytest.raises(ConfigError, match=message) as exc:
        make_coordinator("fuzzy", info, {"rules": str(path)})
    assert str(path) in str(exc.value)
    assert main(["compare", "--community", str(tmp_path / "three.yaml"), "--weeks", "0.25", "--coordinator", "fuzzy",
                 "--coordinator-option", f"fuzzy.rules={path}", "--out", str(tmp_path / "c")]) == 2
    assert str(path) in capsys.readouterr().err


def test_a_missing_rule_file_is_named(tmp_path: Path) -> None:
    community = _community(tmp_path, 1, hours=1)
    info = community_info(community, CommunityPlant(community).hub)
    with pytest.raises(ConfigError, match="nosuch.yaml"):
        make_coordinator("fuzzy", info, {"rules": str(tmp_path / "nosuch.yaml")})


def _info(n_houses: int, n_modules: int) -> CommunityInfo:
    return CommunityInfo(tuple(f"h{i}" for i in range(n_houses)), (1800e3,) * n_houses, 1.0, 24, 1800e3 * n_houses,
                         n_modules, 1454.0, 2400.0, 0.0, 1.0, 0.62)


def _view(houses: list[tuple[float, float]], store: float, pool: float, price: float, prices: list[float],
          days: float) -> CommunityView:
    reports = tuple(HouseReport(f"h{i}", 1800e3, acc, floor, 0.01, 0.0, 0.0, 0.0)
                    for i, (acc, floor) in enumerate(houses))
    hub = HubReport(1800e3 * len(houses), store, pool, False, 0, 1, 1454.0, 2400.0)
    return CommunityView(0, "2022-05-02T12:00:00+02:00", 0, True, 24, hub, reports, price, tuple(prices), 0.08, days)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 5), modules=st.integers(0, 6),
       offers=st.lists(st.floats(-500.0, 6000.0, allow_nan=False), min_size=5, max_size=5),
       fill=st.floats(0.0, 1.0), price=st.floats(0.05, 0.8), days=st.floats(0.0, 300.0))
def test_fuzzy_hub_stays_within_the_offered_surplus_and_its_modules(n: int, modules: int, offers: list[float],
                                                                     fill: float, price: float, days: float) -> None:
    coord = make_coordinator("fuzzy", _info(n, modules))
    houses = [(fill * 1800e3, 0.0)] * n
    view = _view(houses, fill * 1800e3 * n, 0.0, price, [0.05 * i for i in range(24)], days)
    d = coord.dispatch(view, tuple(Request(p, 0.0, 0.0) for p in offers[:n]))
    total = sum(max(p, 0.0) for p in offers[:n])
    assert d.p_el_w == 0.0 or 1454.0 <= d.p_el_w <= min(total, modules * 2400.0) + 1e-9
    assert modules or d.p_el_w == 0.0
    assert sum(d.production_split) == pytest.approx(1.0 if total > 0 else 0.0)
    assert all(s >= 0.0 for s in d.production_split)


@settings(max_examples=100, deadline=None)
@given(data=st.data(), n=st.integers(1, 6))
def test_planned_transfers_never_overdraw_the_pool_or_an_account(data, n: int) -> None:
    moves = data.draw(st.lists(st.floats(-5e4, 5e4, allow_nan=False), min_size=n, max_size=n))
    accounts = data.draw(st.lists(st.floats(0.0, 1800e3), min_size=n, max_size=n))
    pool = data.draw(st.floats(0.0, 1e5))
    plans = [{"h2_in": np.array([max(m, 0.0)]), "h2_out": np.array([max(-m, 0.0)])} for m in moves]
    view = _view([(a, 0.05 * 1800e3) for a in accounts], sum(accounts) + pool, pool, 0.3, [0.3] * 24, 0.0)
    out = transfers_from(plans, view, 1.0)
    for t, a in zip(out, accounts):
        assert t >= -max(a - 0.05 * 1800e3, 0.0) - 1e-9
    assert sum(t for t in out if t > 0) <= pool - sum(t for t in out if t < 0) + 1e-6
    assert all(math.isfinite(t) for t in out)
