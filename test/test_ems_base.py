"""Observation restriction (tab:level_of_information), registry, fallback and thermostat."""

from __future__ import annotations

import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.ems import UnknownEMSError, make_controller
from comems4build_ros.core.ems.base import COMMON_FIELDS, FUZZY_FIELDS, MPC_FIELDS, InformationError, Observation
from comems4build_ros.core.ems.fallback import safe_action
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH


def full_data() -> dict:
    """Every field of every level with plausible values."""
    data = {name: 0.0 for name in MPC_FIELDS}
    data.update(t_air_c=20.0, v_dhw_l=200.0, soc=0.5, loh=1.0, t_min_c=21.0, t_max_c=24.0,
                prices_buy_24h=tuple([0.3] * 24), forecast={}, is_weekend=False, fc_on_prev=False)
    return data


def test_levels_nest_as_in_the_paper() -> None:
    assert COMMON_FIELDS < FUZZY_FIELDS < MPC_FIELDS
    # tab:level_of_information: only the MPC sees T_amb and forecasts; RBC sees no radiation,
    # no bounds ahead, no dLOH and no FC state
    assert {"t_amb_c", "forecast"} <= MPC_FIELDS - FUZZY_FIELDS
    assert {"ghi_w_m2", "t_min_5h_c", "dloh_per_day", "fc_on_prev"} <= FUZZY_FIELDS - COMMON_FIELDS


@pytest.mark.parametrize(("level", "forbidden"), [("basic", "ghi_w_m2"), ("basic", "dloh_per_day"),
                                                  ("fuzzy", "t_amb_c"), ("fuzzy", "forecast")])
def test_reading_a_field_outside_the_level_fails_loudly(level: str, forbidden: str) -> None:
    obs = Observation(level, full_data())
    assert obs.t_air_c == 20.0
    with pytest.raises(InformationError, match=f"'{forbidden}'.*'{level}'"):
        getattr(obs, forbidden)
    assert forbidden not in obs.as_dict()


def test_observation_requires_all_fields_and_is_read_only() -> None:
    data = full_data()
    del data["soc"]
    with pytest.raises(ValueError, match="soc"):
        Observation("basic", data)
    obs = Observation("basic", full_data())
    with pytest.raises(AttributeError):
        obs.soc = 0.2
    with pytest.raises(ValueError, match="unknown information level"):
        Observation("oracle", full_data())


def test_registry_unknown_name() -> None:
    with pytest.raises(UnknownEMSError, match="unknown EMS 'magic'"):
        make_controller("magic", load_plant_params())


def test_safe_action_priorities() -> None:
    p = load_plant_params()
    # tank at V_min -> DHW first, whatever the room
    assert safe_action(15.0, 40.0, 21.0, p).hp_mode == HP_DHW
    # tank fine, room below T_min + margin -> space heating at full modulation
    a = safe_action(20.9, 250.0, 21.0, p)
    assert (a.hp_mode, a.hp_mod, a.p_fc_w, a.p_bess_w) == (HP_SH, 1.0, 0.0, 0.0)
    # both fine -> off
    assert safe_action(22.0, 250.0, 21.0, p).hp_mode == HP_OFF
    # NaN measurements -> heat rather than risk
    assert safe_action(float("nan"), 250.0, 21.0, p).hp_mode == HP_SH


def test_thermostat_hysteresis_and_dhw_priority() -> None:
    p = load_plant_params()
    th = make_controller("thermostat", p)
    d = full_data()

    def act(t_air: float, v: float):
        d.update(t_air_c=t_air, v_dhw_l=v)
        return th.act(Observation("basic", d))

    assert act(20.0, 250.0).hp_mode == HP_SH  # below T_min + 0.3 -> on
    assert act(21.8, 250.0).hp_mode == HP_SH  # inside hysteresis band -> stays on
    assert act(22.1, 250.0).hp_mode == HP_OFF  # above T_min + 1.0 -> off
    assert act(21.8, 250.0).hp_mode == HP_OFF  # inside band -> stays off
    assert act(20.0, 100.0).hp_mode == HP_DHW  # tank below half -> DHW first
