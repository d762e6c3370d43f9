"""Mamdani engine and the rule-base files of ComEMS4Build (config/fuzzy/*.yaml)."""

import itertools
import warnings

import numpy as np
import pytest

from comems4build_ros.core.config import ConfigError, load_plant_params
from comems4build_ros.core.ems.fuzzy import build_system, device_quantities, load_flcs

FLCS = ("flex", "fc", "battery")



@pytest.fixture(scope="module")
def flcs(params):
    return {k: system for k, (system, _) in load_flcs(params).items()}


def test_device_quantities_hand_computed(params):
    q = device_quantities(
        load_plant_params(
            overrides={"fuel_cell.p_max_w": 2500.0, "fuel_cell.zeta": 0.8, "battery.p_d_max_w": 1500.0,
                       "battery.p_ch_max_w": 1200.0, "battery.soc_min": 0.1, "battery.soc_max": 0.9}
        ),
        10_000.0,
    )
    assert q["dp_fc"] == pytest.approx(0.2)  # 0.8 * 2500 W / 10 kW
    assert q["dp_fc_bess"] == pytest.approx(0.35)  # (2000 + 1500) W / 10 kW
    assert q["p_ch"] == pytest.approx(0.12)
    assert q["p_d"] == pytest.approx(0.15)
    assert q["soc_mid"] == pytest.approx(0.5)


def test_membership_peaks_follow_device_sizes(params):
    base = {k: s for k, (s, _) in load_flcs(params).items()}
    # sec:appendix: dP "medium negative" at zeta * P_FC,max, "big negative" core starts at FC + BESS
    p_fc = params.fuel_cell.zeta * params.fuel_cell.p_max_w
    assert base["fc"].peak("dp", "mn") == pytest.approx(-p_fc / 10_000.0)
    bn = base["fc"].variable("dp").points[base["fc"].variable("dp").term_names.index("bn")]
    assert bn[2] == pytest.approx(-(p_fc + params.battery.p_d_max_w) / 10_000.0)
    # dP_new: medium at half, big at full battery power
    assert base["battery"].peak("dp_new", "mp") == pytest.approx(0.5 * params.battery.p_ch_max_w / 10_000.0)
    assert base["battery"].peak("dp_new", "mn") == pytest.approx(-0.5 * params.battery.p_d_max_w / 10_000.0)

    bigger = load_plant_params(
        overrides={"fuel_cell.p_max_w": 3000.0, "battery.p_ch_max_w": 3000.0, "battery.p_d_max_w": 2000.0,
                   "battery.soc_min": 0.2}
    )
    moved = {k: s for k, (s, _) in load_flcs(bigger).items()}
    assert moved["fc"].peak("dp", "mn") == pytest.approx(-0.8 * 3000.0 / 10_000.0)  # -0.24
    bn = moved["fc"].variable("dp").points[moved["fc"].variable("dp").term_names.index("bn")]
    assert bn[2] == pytest.approx(-(2400.0 + 2000.0) / 10_000.0)  # -0.44
    bp = moved["battery"].variable("dp_new").points[moved["battery"].variable("dp_new").term_names.index("bp")]
    assert bp[1] == pytest.approx(0.3)  # full charging power 3 kW / 10 kW
    assert moved["battery"].peak("dp_new", "mn") == pytest.approx(-0.1)  # half of 2 kW
    soc = moved["flex"].variable("soc")
    assert soc.points[soc.term_names.index("average")][1] == pytest.approx(0.55)  # (0.2 + 0.9) / 2


@pytest.mark.parametrize("flc", FLCS)
def test_rule_base_complete_on_dense_grid(flcs, flc):
    system = flcs[flc]
    axes = []
    for v in system.inputs:
        n = 2 if v.name == "s_onoff" else 9
        axes.append(np.union1d(np.linspace(v.lo, v.hi, n), v.points.ravel()))
    grid = np.array(list(itertools.product(*axes)))
    assert len(grid) > 1000
    fire = system.firing(grid)
    assert fire.max(axis=1).min() > 0.0, "some input combination fires no rule"
    out = system.evaluate(grid)
    assert np.all(np.isfinite(out))
    assert np.all((out >= system.output.lo) & (out <= system.output.hi))


@pytest.mark.parametrize("flc", FLCS)
def test_paper_snapshot_rules_fire_as_published(flcs, flc):
    system = flcs[flc]
    paper = [(i, r) for i, r in enumerate(system.rules) if r.source == "paper"]
    assert len(paper) == 7  # tab:FLCflex_rules, tab:FLCfc_rules, tab:FLCb_rules: 7 rows each
    for i, rule in paper:
        x = [system.peak(v.name, v.term_names[sel[0]]) for v, sel in zip(system.inputs, rule.antecedent)]
        fire = system.firing(np.array([x]))[0]
        assert fire[i] == pytest.approx(1.0), rule.text
        cons = system.output.term_names[rule.consequent]
        # only rules with the same conclusion fire at all -> output = that term's centroid
        others = [j for j, r in enumerate(system.rules) if r.consequent != rule.consequent]
        assert np.all(fire[others] == 0.0), rule.text
        assert system(*x) == pytest.approx(system.term_centroid(cons), abs=1e-9), rule.text


def test_paper_rules_verbatim(flcs):
    texts = [r.text for r in flcs["fc"].rules if r.source == "paper"]
    assert texts[4] == "dp=mn, dloh=average, soc=empty, price=high, s_onoff=off -> bp"  # tab:FLCfc_rules row 5
    texts = [r.text for r in flcs["flex"].rules if r.source == "paper"]
    assert texts[6] == "chi=high, loh=empty, soc=average, price=high, qs=low -> bn"  # tab:FLCflex_rules row 7
    texts = [r.text for r in flcs["battery"].rules if r.source == "paper"]
    assert texts[0] == "dp_new=sn, soc=empty, price=low -> bp"  # tab:FLCb_rules row 1


def test_paper_examples_in_prose(flcs):
    fc, b = flcs["fc"], flcs["battery"]
    # sec:appendix: same situation, FC on in k-1 -> "medium positive", off -> stays "off"
    x = [fc.peak("dp", "sn"), 0.5, fc.peak("soc", "empty"), 0.5]
    assert fc(*x, 1.0) == pytest.approx(fc.term_centroid("mp"))
    assert fc(*x, 0.0) == pytest.approx(fc.term_centroid("off"))
    # FLC_B: small demand, empty battery, low price -> charge "big positive"
    assert b(b.peak("dp_new", "sn"), b.peak("soc", "empty"), 0.0) > 0.9


@pytest.mark.parametrize("flc", FLCS)
def test_numpy_engine_agrees_with_skfuzzy_control(flcs, flc):
    from skfuzzy import control as ctrl

    system = flcs[flc]
    sim = ctrl.ControlSystemSimulation(system.to_skfuzzy())
    rng = np.random.default_rng(20221201)
    lo = np.array([v.lo for v in system.inputs])
    hi = np.array([v.hi for v in system.inputs])
    x = rng.uniform(lo, hi, size=(1000, len(lo)))
    if "s_onoff" in system.input_names:
        j = system.input_names.index("s_onoff")
        x[:, j] = rng.integers(0, 2, size=len(x))
    ours = system.evaluate(x)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        # all 1000 inputs through skfuzzy's array path ...
        for v, column in zip(system.inputs, x.T):
            sim.input[v.name] = column
        sim.compute()
        theirs = np.asarray(sim.output[system.output.name])
        # ... and the first 50 one at a time (the per-step path the benchmark times)
        single = np.empty(50)
        sim = ctrl.ControlSystemSimulation(system.to_skfuzzy())
        for n, row in enumerate(x[:50]):
            for v, value in zip(system.inputs, row):
                sim.input[v.name] = value
            sim.compute()
            single[n] = sim.output[system.output.name]
    assert theirs.shape == (1000,)
    assert np.max(np.abs(ours - theirs)) < 1e-3
    assert np.max(np.abs(ours[:50] - single)) < 1e-3


SECTION = {
    "inputs": {
        "order": ["a", "b"],
        "a": {"universe": [0.0, 1.0], "terms": {"lo": [0.0, 0.0, 1.0], "hi": [0.0, 1.0, 1.0]}},
        "b": {"universe": [0.0, 1.0], "terms": {"lo": [0.0, 0.0, 1.0], "hi": [0.0, 1.0, 1.0]}},
    },
    "output": {
        "name": "y",
        "universe": [0.0, 1.0],
        "points": 101,
        "terms": {"off": [0.0, 0.0, 0.5], "on": [0.5, 1.0, 1.0]},
    },
}


def _section(rules, **changes):
    import copy

    s = copy.deepcopy(SECTION)
    s["rules_design"] = rules
    s.update(changes)
    return s


def test_small_system_hand_computed():
    system = build_system("t", _section(["a=lo -> off", "a=hi, b=lo|hi -> on"]), {}, "mem.yaml")
    # a = 0.25: "lo" 0.75, "hi" 0.25 (b any). Output: off clipped at 0.75, on clipped at 0.25.
    act = system.activation(np.array([[0.25, 0.9]]))[0]
    assert act == pytest.approx([0.75, 0.25])
    # Only "off" fully: centroid of the right triangle on [0, 0.5] = 0.5 / 3
    assert system(0.0, 0.3) == pytest.approx(0.5 / 3.0)
    assert system(1.0, 1.0) == pytest.approx(1.0 - 0.5 / 3.0)
    # Out-of-universe inputs are clipped
    assert system(-5.0, 7.0) == pytest.approx(system(0.0, 1.0))


def test_incomplete_rule_base_rejected():
    with pytest.raises(ConfigError, match=r"mem.yaml: t: incomplete rule base: no rule covers a=hi, b=hi"):
        build_system("t", _section(["a=lo -> off", "a=hi, b=lo -> on"]), {}, "mem.yaml")


def test_conflicting_rules_rejected():
    with pytest.raises(ConfigError, match="conflicting rules for a=lo, b=lo"):
        build_system("t", _section(["a=lo -> off", "a=hi -> on", "b=lo, a=lo -> on"]), {}, "mem.yaml")


@pytest.mark.parametrize(
    ("rules", "message"),
    [
        (["a=mid -> off", "a=hi -> on"], "'a' has no term 'mid'"),
        (["c=lo -> off"], "unknown input 'c'"),
        (["a=lo -> maybe", "a=hi -> on"], "output 'y' has no term 'maybe'"),
        (["a=lo off"], "cannot read rule"),
        (["a=lo, a=hi -> off"], "input 'a' given twice"),
    ],
)
def test_bad_rules_named(rules, message):
    with pytest.raises(ConfigError, match=message) as err:
        build_system("t", _section(rules), {}, "mem.yaml")
    assert "mem.yaml: t.rules_design[0]" in str(err.value)


def test_bad_points_named():
    s = _section(["a=lo -> off", "a=hi -> on"])
    s["inputs"]["a"]["terms"]["lo"] = [0.0, "0.5*unknown_size", 1.0]
    with pytest.raises(ConfigError, match=r"term 'a.lo': cannot read point '0.5\*unknown_size'"):
        build_system("t", s, {"p_ch": 0.1}, "mem.yaml")
    s["inputs"]["a"]["terms"]["lo"] = [0.0, 0.8, 0.4]
    with pytest.raises(ConfigError, match="points must not decrease"):
        build_system("t", s, {}, "mem.yaml")
    s["inputs"]["a"]["terms"]["lo"] = [0.2, 0.2, 1.0]
    with pytest.raises(ConfigError, match="left shoulder"):
        build_system("t", s, {}, "mem.yaml")


def test_yaml_booleans_do_not_break_term_names(flcs):
    # "on"/"off" are YAML 1.1 booleans unless quoted: the files quote them
    assert flcs["fc"].variable("s_onoff").term_names == ("off", "on")
    assert "off" in flcs["battery"].output.term_names
