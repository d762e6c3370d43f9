"""A plausible observation of one winter evening step, for the EMS unit tests.

``observation_data`` gives every field of the richest (fuzzy) information level; a test
changes what it examines and cuts the dict to its EMS's level.
"""

from __future__ import annotations

from typing import Any


def observation_data(**changes: Any) -> dict[str, Any]:
    """Fields of an observation at 18:00 on a Tuesday: room 22 degC in a 21..24 degC band,
    tank 250 l, SOC 0.5, LOH 0.8, no PV, 500 W load, buy price 0.40 EUR/kWh (the day's
    highest), ``changes`` applied last."""
    d: dict[str, Any] = {
        "step": 18,
        "day_index": 0,
        "hour_of_day": 18,
        "weekday": 1,
        "is_weekend": False,
        "t_air_c": 22.0,
        "v_dhw_l": 250.0,
        "soc": 0.5,
        "loh": 0.8,
        "hp_mod_prev": 0.0,
        "p_pv_w": 0.0,
        "p_load_w": 500.0,
        "t_min_c": 21.0,
        "t_max_c": 24.0,
        "price_buy_eur_per_kwh": 0.40,
        "price_sell_eur_per_kwh": 0.0794,
        "prices_buy_24h": tuple([0.40] + [0.30] * 23),  # current price is the day's highest
        "t_min_5h_c": (21.0,) * 6,
        "ghi_w_m2": 0.0,
        "dloh_per_day": 1.0 / 84.0,
        "fc_on_prev": False,
        "el_on_prev": False,
        "days_to_heating_season": 0.0,
        "heating_season_days_left": 84.0,
    }
    d.update(changes)
    return d
