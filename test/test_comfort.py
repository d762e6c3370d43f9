"""Comfort bounds eq:T_min with German public holidays counted as weekend days."""

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.scenario import comfort_bounds, is_off_day

TZ = "Europe/Berlin"


@pytest.fixture(scope="module")
def comfort():
    return load_plant_params().comfort


@pytest.mark.parametrize(
    ("local_time", "expected_min"),
    [
        ("2022-12-01 07:00", 21.0),  # Thursday, home 06-08
        ("2022-12-01 10:00", 18.0),  # Thursday, away
        ("2022-12-01 05:00", 18.0),  # before 06
        ("2022-12-01 06:00", 21.0),  # start of the morning slot
        ("2022-12-01 08:00", 18.0),  # end of the slot is exclusive
        ("2022-12-01 17:00", 21.0),  # evening slot 17-23
        ("2022-12-01 22:00", 21.0),
        ("2022-12-01 23:00", 18.0),  # 23 is exclusive
        ("2022-12-03 10:00", 21.0),  # Saturday, home 06-23
        ("2022-12-04 23:00", 18.0),  # Sunday 23:00
        ("2022-12-26 10:00", 21.0),  # Monday, Second Day of Christmas (holiday)
        ("2023-01-06 10:00", 21.0),  # Friday, Epiphany (holiday in BW)
        ("2022-12-27 10:00", 18.0),  # Tuesday, no holiday
        ("2022-12-24 10:00", 21.0),  # Saturday (Christmas Eve is no public holiday, but a Saturday)
    ],
)
def test_comfort_bounds_hand_picked(comfort, local_time, expected_min):
    t = pd.DatetimeIndex([pd.Timestamp(local_time).tz_localize(TZ)])
    t_min, t_max = comfort_bounds(t, comfort)
    assert t_min[0] == expected_min
    assert t_max[0] == 24.0


def test_comfort_bounds_scalar_timestamp(comfort):
    t_min, t_max = comfort_bounds(pd.Timestamp("2022-12-01 07:00", tz=TZ), comfort)
    assert t_min.shape == (1,) and t_min[0] == 21.0 and t_max[0] == 24.0


def test_off_days_in_window(comfort):
    days = pd.date_range("2022-12-19", "2023-01-08", freq="D", tz=TZ)
    off = is_off_day(days, comfort)
    expected = {"2022-12-24", "2022-12-25", "2022-12-26", "2022-12-31", "2023-01-01", "2023-01-06",
                "2023-01-07", "2023-01-08"}
    got = {d.strftime("%Y-%m-%d") for d, o in zip(days, off) if o}
    assert got == expected


def test_home_hours_per_day_type(comfort):
    """Hours at 21 degC: 2 + 6 = 8 on a workday, 17 on an off day."""
    workday = pd.date_range("2022-12-01", periods=24, freq="h", tz=TZ)
    offday = pd.date_range("2022-12-26", periods=24, freq="h", tz=TZ)
    assert np.sum(comfort_bounds(workday, comfort)[0] == 21.0) == 8
    assert np.sum(comfort_bounds(offday, comfort)[0] == 21.0) == 17


def test_other_home_hours_from_parameters():
    params = load_plant_params(overrides={"comfort.home_hours_weekday": [0, 24], "comfort.t_min_home_c": 20.0})
    t = pd.date_range("2022-12-01 10:00", periods=3, freq="h", tz=TZ)
    assert list(comfort_bounds(t, params.comfort)[0]) == [20.0, 20.0, 20.0]
