"""ComEMS4Build controller (FLC_flex -> FLC_FC -> FLC_B) on hand-made observations and a short run."""

import pytest
from observations import observation_data

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import COMMON_FIELDS, FUZZY_FIELDS, InformationError, Observation
from comems4build_ros.core.ems.fuzzy import FuzzyEMS
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH


def obs_data(**changes):
    return observation_data(**changes)


def fuzzy_obs(**changes):
    return Observation("fuzzy", obs_data(**changes))


def test_registry_builds_fuzzy(params):
    ems = make_controller("fuzzy", params)
    assert isinstance(ems, FuzzyEMS)
    assert (ems.name, ems.info_level) == ("fuzzy", "fuzzy")


def test_basic_observation_fails_loudly(params):
    ems = FuzzyEMS(params, {})
    basic = Observation("basic", {k: v for k, v in obs_data().items() if k in COMMON_FIELDS})
    with pytest.raises(InformationError, match="not available to a controller of information level 'basic'"):
        ems.act(basic)


def test_reads_only_fuzzy_fields(params):
    # an observation holding exactly the fuzzy fields is enough (nothing of the MPC level)
    assert set(fuzzy_obs().as_dict()) == set(FUZZY_FIELDS)
    FuzzyEMS(params, {}).act(fuzzy_obs())


def test_cold_room_starts_heat_pump_from_zero(params):
    ems = FuzzyEMS(params, {})
    a = ems.act(fuzzy_obs(t_air_c=20.5, hp_mod_prev=0.0, prices_buy_24h=tuple([0.40] * 24)))
    # chi_SH = 0, tank full enough -> space heating, modulation left zero into [0.2, 1]
    assert a.hp_mode == HP_SH
    assert 0.2 <= a.hp_mod <= 1.0


def test_warm_room_at_high_price_lowers_modulation(params):
    ems = FuzzyEMS(params, {})
    a = ems.act(fuzzy_obs(t_air_c=23.9, v_dhw_l=300.0, hp_mod_prev=0.8))
    assert a.hp_mod < 0.8
    assert a.hp_mod == 0.0 or a.hp_mod >= 0.2


def test_dhw_priority(params):
    ems = FuzzyEMS(params, {})
    # tank below half (chi_DHW < 0.25) wins even though the room is cooler in chi terms
    a = ems.act(fuzzy_obs(t_air_c=21.3, v_dhw_l=120.0, hp_mod_prev=0.5))
    assert a.hp_mode == HP_DHW
    # tank more than half full and the room lower -> the room
    a = ems.act(fuzzy_obs(t_air_c=21.05, v_dhw_l=200.0, hp_mod_prev=0.5))
    assert a.hp_mode == HP_SH
    # equal states -> the tank (DHW priority)
    a = ems.act(fuzzy_obs(t_air_c=21.0, t_min_5h_c=(21.0,) * 6, v_dhw_l=40.0, hp_mod_prev=0.5))
    assert a.hp_mode == HP_DHW


def test_preheats_before_home_period(params):
    ems = FuzzyEMS(params, {})
    away = dict(t_air_c=19.0, t_min_c=18.0, hp_mod_prev=0.0, prices_buy_24h=tuple([0.30] * 24))
    a_far = ems.act(fuzzy_obs(**away, t_min_5h_c=(18.0,) * 6))
    a_near = ems.act(fuzzy_obs(**away, t_min_5h_c=(18.0,) * 4 + (21.0,) * 2))
    assert a_near.hp_mod > a_far.hp_mod


def test_fuel_cell_only_with_demand_and_within_limits(params):
    ems = FuzzyEMS(params, {})
    fc, b = params.fuel_cell, params.battery
    surplus = ems.act(fuzzy_obs(p_pv_w=4000.0, p_load_w=300.0, soc=b.soc_min))
    assert surplus.p_fc_w == 0.0
    # 1.6 kW demand at the day's highest price, empty battery, allowance untouched -> FC on within range
    a = ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, hp_mod_prev=0.0, soc=b.soc_min))
    assert a.hp_mod == 0.0 and a.hp_mode == HP_OFF
    assert fc.p_min_w <= a.p_fc_w <= fc.zeta * fc.p_max_w
    # low price -> grid, no FC
    cheap = ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, soc=b.soc_min,
                              prices_buy_24h=tuple([0.40] + [0.50] * 23)))
    assert cheap.p_fc_w == 0.0


def test_battery_first_then_the_fuel_cell_holds(params):
    """tab:FLCfc_rules: an off FC starts for a medium load only with an empty battery; a running FC holds."""
    ems = FuzzyEMS(params, {})
    b = params.battery
    charged = ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, soc=0.8))
    assert charged.p_fc_w == 0.0 and charged.p_bess_w < 0.0  # the battery covers the load
    running = ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, soc=0.8, fc_on_prev=True))
    assert running.p_fc_w >= params.fuel_cell.p_min_w  # an FC already on stays on
    # at an average price an off FC stays off, a running one holds (rows 2 and 3)
    avg = tuple([0.35] + [0.30] * 11 + [0.40] * 12)  # EDF 0.5: "average" only
    assert ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, soc=b.soc_min, price_buy_eur_per_kwh=0.35,
                             prices_buy_24h=avg)).p_fc_w == 0.0
    assert ems.act(fuzzy_obs(p_load_w=1600.0, t_air_c=22.5, soc=b.soc_min, price_buy_eur_per_kwh=0.35,
                             prices_buy_24h=avg, fc_on_prev=True)).p_fc_w > 0.0


def test_fuel_cell_stops_when_daily_allowance_used(params):
    ems = FuzzyEMS(params, {})
    dloh = 1.0 / 84.0
    empty = params.battery.soc_min
    ems.act(fuzzy_obs(step=0, day_index=3, loh=0.8, p_load_w=1600.0, t_air_c=22.5, soc=empty))
    a = ems.act(fuzzy_obs(step=1, day_index=3, loh=0.8 - 1.01 * dloh, p_load_w=1600.0, t_air_c=22.5, soc=empty))
    assert ems.step_info["dloh_share"] == 0.0
    assert a.p_fc_w == 0.0
    # next day: renewed
    b = ems.act(fuzzy_obs(step=2, day_index=4, loh=0.8 - 1.01 * dloh, p_load_w=1600.0, t_air_c=22.5, soc=empty))
    assert ems.step_info["dloh_share"] == pytest.approx(1.0)
    assert b.p_fc_w > 0.0


def test_battery_limits_and_signs(params):
    ems = FuzzyEMS(params, {})
    b = params.battery
    # empty battery never discharges
    a = ems.act(fuzzy_obs(soc=b.soc_min, p_load_w=3000.0, loh=0.0))
    assert a.p_bess_w >= 0.0
    # full battery with PV surplus does not charge
    a = ems.act(fuzzy_obs(soc=b.soc_max, p_pv_w=5000.0, p_load_w=300.0))
    assert a.p_bess_w <= 0.0
    # half-full battery, demand at the highest price, no H2 -> discharges within P_d,max
    a = ems.act(fuzzy_obs(soc=0.6, p_load_w=800.0, loh=0.0, t_air_c=22.5))
    assert -b.p_d_max_w <= a.p_bess_w < 0.0
    # low price, empty battery -> charges from the grid
    a = ems.act(fuzzy_obs(soc=b.soc_min, p_load_w=800.0, prices_buy_24h=tuple([0.40] + [0.50] * 23)))
    assert 0.0 < a.p_bess_w <= b.p_ch_max_w


def test_options_override_and_errors(params):
    ems = FuzzyEMS(params, {"fc.fc.cap_to_demand": True})
    a = ems.act(fuzzy_obs(p_load_w=600.0, t_air_c=22.5, soc=params.battery.soc_min, fc_on_prev=True))
    assert a.p_fc_w == pytest.approx(600.0)  # capped at the demand
    b = FuzzyEMS(params, {}).act(fuzzy_obs(p_load_w=600.0, t_air_c=22.5, soc=params.battery.soc_min,
                                           fc_on_prev=True))
    assert b.p_fc_w > 600.0  # the default: alpha_FC * zeta * P_max, above the demand
    with pytest.raises(ConfigError, match="unknown option"):
        FuzzyEMS(params, {"fcc": {}})
    with pytest.raises(ConfigError, match="parameter .fc.fc.cap_to_demand.: expected true or false, got .maybe."):
        FuzzyEMS(params, {"fc.fc.cap_to_demand": "maybe"})


def test_short_closed_loop_run(params):
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import default_scenario
    from comems4build_ros.core.types import CLIP_FC_RANGE, CLIP_HP_MOD, CLIP_HP_MODE

    result = simulate("fuzzy", default_scenario(params, weeks=1), params)
    ts = result.timeseries
    assert len(ts) == 168
    bad = CLIP_HP_MODE | CLIP_HP_MOD | CLIP_FC_RANGE
    assert not ((ts["clipped"] & bad) != 0).any()  # set-points are physically sensible
    assert {"ems_alpha_hp", "ems_alpha_fc", "ems_alpha_b", "ems_edf"} <= set(ts.columns)
    assert ts["cmd_hp_mod"].between(0.0, 1.0).all()
