"""Rule-based controller (sec:RBC) on hand-made observations and a short run."""

import pytest
from observations import observation_data

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import COMMON_FIELDS, InformationError, Observation
from comems4build_ros.core.ems.rbc import RuleBasedController
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH

DAY = tuple(0.20 + 0.01 * i for i in range(24))  # 24 distinct prices 0.20 .. 0.43



def basic(**changes):
    d = observation_data(step=10, hour_of_day=10, price_buy_eur_per_kwh=0.30, prices_buy_24h=DAY)
    d.update(changes)
    return Observation("basic", {k: d[k] for k in COMMON_FIELDS})


def test_registry_and_level(params):
    rbc = make_controller("rbc", params)
    assert isinstance(rbc, RuleBasedController)
    assert (rbc.name, rbc.info_level) == ("rbc", "basic")


def test_basic_observation_has_no_h2_allowance():
    with pytest.raises(InformationError):
        _ = basic().dloh_per_day
    with pytest.raises(InformationError):
        _ = basic().t_min_5h_c


def test_hysteresis_between_bounds(params):
    rbc = RuleBasedController(params, {})
    assert rbc.act(basic(t_air_c=22.0)).hp_mode == HP_OFF  # inside the band, never switched on
    on = rbc.act(basic(t_air_c=21.0))  # reaches T_min -> on
    assert (on.hp_mode, on.hp_mod) == (HP_SH, 1.0)
    assert rbc.act(basic(t_air_c=23.0)).hp_mode == HP_SH  # keeps heating up to T_max
    assert rbc.act(basic(t_air_c=24.0)).hp_mode == HP_OFF  # off at T_max
    assert rbc.act(basic(t_air_c=22.0)).hp_mode == HP_OFF  # stays off while cooling


def test_no_lookahead_of_comfort_bounds(params):
    rbc = RuleBasedController(params, {})
    # 19 degC at night with T_min = 18: no heating, although 21 degC is due at 06:00
    assert rbc.act(basic(t_air_c=19.0, t_min_c=18.0)).hp_mode == HP_OFF


def test_dhw_before_space_heating(params):
    rbc = RuleBasedController(params, {})
    a = rbc.act(basic(t_air_c=20.5, v_dhw_l=150.0))  # fill (150-40)/260 = 0.42 -> chi 0.18 < 0.25
    assert a.hp_mode == HP_DHW
    a = rbc.act(basic(t_air_c=20.5, v_dhw_l=200.0))  # tank still heating (hysteresis) -> DHW
    assert a.hp_mode == HP_DHW
    a = rbc.act(basic(t_air_c=20.5, v_dhw_l=299.0))  # tank full -> room
    assert a.hp_mode == HP_SH


def test_fuel_cell_in_upper_quartile_only(params):
    rbc = RuleBasedController(params, {})
    p_fc = params.fuel_cell.zeta * params.fuel_cell.p_max_w
    # price 0.43 = highest of DAY -> EDF 1.0 > 0.75, demand 500 W -> FC at zeta * P_max
    assert rbc.act(basic(price_buy_eur_per_kwh=0.43)).p_fc_w == pytest.approx(p_fc)
    # 0.38 -> EDF 19/24 = 0.79 > 0.75: still upper quartile
    assert rbc.act(basic(price_buy_eur_per_kwh=0.38)).p_fc_w == pytest.approx(p_fc)
    # 0.37 -> EDF 18/24 = 0.75: not above the quartile
    assert rbc.act(basic(price_buy_eur_per_kwh=0.37)).p_fc_w == 0.0
    # surplus -> no FC even at the highest price
    assert rbc.act(basic(price_buy_eur_per_kwh=0.43, p_pv_w=3000.0)).p_fc_w == 0.0
    # empty store -> no request
    assert rbc.act(basic(price_buy_eur_per_kwh=0.43, loh=0.0)).p_fc_w == 0.0


def test_battery_rules(params):
    rbc = RuleBasedController(params, {})
    b = params.battery
    # lowest quartile (0.21 -> EDF 2/24): charge at full power although there is demand
    assert rbc.act(basic(price_buy_eur_per_kwh=0.21, p_load_w=800.0)).p_bess_w == pytest.approx(b.p_ch_max_w)
    # middle price, 500 W demand -> discharge 500 W
    assert rbc.act(basic(price_buy_eur_per_kwh=0.30, p_load_w=500.0)).p_bess_w == pytest.approx(-500.0)
    # upper quartile: FC 1953 W over 500 W demand -> surplus charges the battery at its limit
    a = rbc.act(basic(price_buy_eur_per_kwh=0.43, p_load_w=500.0))
    assert a.p_bess_w == pytest.approx(min(b.p_ch_max_w, a.p_fc_w - 500.0))
    # empty battery cannot discharge; full battery cannot charge
    assert rbc.act(basic(soc=b.soc_min, p_load_w=500.0)).p_bess_w == 0.0
    assert rbc.act(basic(soc=b.soc_max, price_buy_eur_per_kwh=0.21)).p_bess_w == 0.0


def test_bad_option_named(params):
    with pytest.raises(ConfigError, match=r"rbc.yaml \[rbc\] \+ options: parameter 'hp_mod_on'"):
        RuleBasedController(params, {"hp_mod_on": 1.5})
    with pytest.raises(ConfigError, match="parameter 'hp_power': unknown parameter .known: sh_on_chi, .*hp_mod_on"):
        RuleBasedController(params, {"hp_power": 1.0})


def test_short_closed_loop_run(params):
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import default_scenario
    from comems4build_ros.core.types import CLIP_FC_RANGE, CLIP_HP_MOD, CLIP_HP_MODE

    ts = simulate("rbc", default_scenario(params, weeks=1), params).timeseries
    assert len(ts) == 168
    bad = CLIP_HP_MODE | CLIP_HP_MOD | CLIP_FC_RANGE
    assert not ((ts["clipped"] & bad) != 0).any()
    fc_on = ts["p_fc_w"] > 0
    assert fc_on.any()
    # the RBC asks for the FC only at zeta * P_max
    p_fc = params.fuel_cell.zeta * params.fuel_cell.p_max_w
    assert (ts.loc[fc_on, "cmd_p_fc_w"] - p_fc).abs().max() < 1e-9
