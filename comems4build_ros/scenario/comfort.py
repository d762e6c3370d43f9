"""Comfort bounds ``eq:T_min`` with public holidays counted as weekend days."""

from __future__ import annotations

from functools import lru_cache

import holidays as holidays_lib
import numpy as np
import pandas as pd

from ..config import ComfortParams


@lru_cache(maxsize=32)
def _holiday_dates(country: str, subdivision: str, years: tuple[int, ...]) -> frozenset:
    """Public holidays (``datetime.date``) of a country/subdivision in the given years."""
    cal = holidays_lib.country_holidays(country, subdiv=subdivision or None, years=list(years))
    return frozenset(cal.keys())


def _local_index(time: pd.DatetimeIndex | pd.Timestamp) -> pd.DatetimeIndex:
    idx = pd.DatetimeIndex([time]) if isinstance(time, pd.Timestamp) else pd.DatetimeIndex(time)
    return idx


def is_off_day(time: pd.DatetimeIndex | pd.Timestamp, comfort: ComfortParams) -> np.ndarray:
    """True where the local date is a Saturday, Sunday or public holidays of ``comfort``.

    Parameters
    ----------
    time : local times (tz-aware in the site's zone, or naive local times)
    comfort : comfort section of the plant parameters (holidays_country, holidays_subdivision)
    """
    idx = _local_index(time)
    if len(idx) == 0:
        return np.zeros(0, dtype=bool)
    years = tuple(range(int(idx.year.min()), int(idx.year.max()) + 1))
    hol = _holiday_dates(comfort.holidays_country, comfort.holidays_subdivision, years)
    weekend = np.asarray(idx.day_of_week >= 5)
    dates = idx.date
    holiday = np.fromiter((d in hol for d in dates), dtype=bool, count=len(dates))
    return weekend | holiday


def _in_hours(hour: np.ndarray, pairs: list[int]) -> np.ndarray:
    """True where ``hour`` lies in one of the ``[start, end)`` pairs."""
    inside = np.zeros(hour.shape, dtype=bool)
    for start, end in zip(pairs[::2], pairs[1::2]):
        inside |= (hour >= start) & (hour < end)
    return inside


def comfort_bounds(
    time: pd.DatetimeIndex | pd.Timestamp, comfort: ComfortParams
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper air-temperature bounds ``eq:T_min`` [degC] for each hour.

    ``T_min = t_min_home_c`` when the occupants are at home (weekdays in
    ``home_hours_weekday``, weekends and public holidays in ``home_hours_weekend``; both
    lists of ``[start, end)`` local hours, paper: 06-08 and 17-23 resp. 06-23), otherwise
    ``t_min_away_c``; ``T_max = t_max_c`` always.

    Parameters
    ----------
    time : start of each hourly step, local time of the site (tz-aware or naive local)
    comfort : :class:`~comems4build_ros.config.ComfortParams`

    Returns
    -------
    t_min_c, t_max_c : arrays [degC] of the length of ``time``
    """
    idx = _local_index(time)
    hour = np.asarray(idx.hour)
    off = is_off_day(idx, comfort)
    home = np.where(off, _in_hours(hour, comfort.home_hours_weekend), _in_hours(hour, comfort.home_hours_weekday))
    t_min = np.where(home, comfort.t_min_home_c, comfort.t_min_away_c).astype(float)
    t_max = np.full(len(idx), float(comfort.t_max_c))
    return t_min, t_max
