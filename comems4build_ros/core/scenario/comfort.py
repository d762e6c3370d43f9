"""Comfort bounds ``eq:T_min`` with public holidays counted as weekend days."""

from __future__ import annotations

from datetime import date
from functools import lru_cache

import numpy as np
import pandas as pd

from comems4build_ros.core.config import ComfortParams


@lru_cache(maxsize=32)
def holiday_dates(country: str, subdivision: str, years: tuple[int, ...]) -> frozenset[date]:
    """Return the public holidays of a country or subdivision in the given years.

    From the ``holidays`` library; remembered on disk per library version
    (:mod:`comems4build_ros.core.result_cache`: the library imports every country's calendar
    to look one up, in each feed and EMS process).

    Parameters
    ----------
    country : str
        ISO 3166-1 alpha-2 code (``DE``).
    subdivision : str
        A subdivision (``BW``); empty for the national holidays only.
    years : tuple of int
        Calendar years.

    Returns
    -------
    frozenset of datetime.date
        The holidays.
    """
    from comems4build_ros.core.result_cache import cached

    def library() -> tuple[np.ndarray]:
        import holidays

        cal = holidays.country_holidays(country, subdiv=subdivision or None, years=list(years))
        return (np.array(sorted(d.toordinal() for d in cal), dtype=float),)

    calendar = {"country": country, "subdivision": subdivision, "years": list(years)}
    (ordinals,) = cached("holiday-dates", calendar, [], library, dists=("holidays",))
    return frozenset(date.fromordinal(int(o)) for o in ordinals)


def _local_index(time: pd.DatetimeIndex | pd.Timestamp) -> pd.DatetimeIndex:
    """Return ``time`` as an index (one element for a single timestamp)."""
    idx = pd.DatetimeIndex([time]) if isinstance(time, pd.Timestamp) else pd.DatetimeIndex(time)
    return idx


def is_off_day(time: pd.DatetimeIndex | pd.Timestamp, comfort: ComfortParams) -> np.ndarray:
    """Mark the local dates that are a Saturday, Sunday or public holiday of ``comfort``.

    Parameters
    ----------
    time : pandas.DatetimeIndex or pandas.Timestamp
        Local times (tz-aware in the site's zone, or naive local times).
    comfort : ComfortParams
        Comfort section of the plant parameters (``holidays_country``,
        ``holidays_subdivision``).

    Returns
    -------
    numpy.ndarray of bool
        True on off days, one per time.
    """
    idx = _local_index(time)
    if len(idx) == 0:
        return np.zeros(0, dtype=bool)
    years = tuple(range(int(idx.year.min()), int(idx.year.max()) + 1))
    hol = holiday_dates(comfort.holidays_country, comfort.holidays_subdivision, years)
    weekend = np.asarray(idx.day_of_week >= 5)
    dates = idx.date
    holiday = np.fromiter((d in hol for d in dates), dtype=bool, count=len(dates))
    return weekend | holiday


def heating_season_days(
    time: pd.DatetimeIndex, start_mmdd: str, end_mmdd: str
) -> tuple[np.ndarray, np.ndarray]:
    """Return the days to the next heating season and the days left in it, for each step start.

    The season runs from the local date ``start_mmdd`` (``"12-01"``) to ``end_mmdd``
    (exclusive, ``"03-01"``), across the turn of the year when the end lies before the
    start. Inside the season the first value is 0, outside it the second.

    Parameters
    ----------
    time : pandas.DatetimeIndex
        Local step starts (tz-aware in the site's zone).
    start_mmdd, end_mmdd : str
        Season bounds as ``MM-DD``.

    Returns
    -------
    tuple of numpy.ndarray
        Days to the start of the next season, and days left in the current season [d].
    """
    idx = pd.DatetimeIndex(time)
    naive = idx.tz_localize(None) if idx.tz is not None else idx
    to_start = np.zeros(len(idx))
    left = np.zeros(len(idx))
    sm, sd = (int(x) for x in start_mmdd.split("-"))
    em, ed = (int(x) for x in end_mmdd.split("-"))
    day_s = 86400.0
    for i, t in enumerate(naive):
        y = t.year
        # the season that contains t or comes next: its start in year y-1, y or y+1
        for ys in (y - 1, y, y + 1):
            s = pd.Timestamp(ys, sm, sd)
            e = pd.Timestamp(ys + (1 if (em, ed) <= (sm, sd) else 0), em, ed)
            if s <= t < e:
                left[i] = (e - t).total_seconds() / day_s
                break
            if t < s:
                to_start[i] = (s - t).total_seconds() / day_s
                break
    return to_start, left


def _in_hours(hour: np.ndarray, pairs: list[int]) -> np.ndarray:
    """Mark where ``hour`` lies in one of the ``[start, end)`` pairs."""
    inside = np.zeros(hour.shape, dtype=bool)
    for start, end in zip(pairs[::2], pairs[1::2]):
        inside |= (hour >= start) & (hour < end)
    return inside


def comfort_bounds(
    time: pd.DatetimeIndex | pd.Timestamp, comfort: ComfortParams
) -> tuple[np.ndarray, np.ndarray]:
    """Return the lower and upper air-temperature bounds ``eq:T_min`` for each hour.

    ``T_min = t_min_home_c`` when the occupants are at home (weekdays in
    ``home_hours_weekday``, weekends and public holidays in ``home_hours_weekend``; both
    lists of ``[start, end)`` local hours, paper: 06-08 and 17-23 resp. 06-23), otherwise
    ``t_min_away_c``; ``T_max = t_max_c`` (the paper's bound), except in the months of
    ``cooling_season_months`` where ``T_max = t_max_cooling_c`` (EN 16798-1 category II,
    cooling season).

    Parameters
    ----------
    time : pandas.DatetimeIndex or pandas.Timestamp
        Start of each hourly step, local time of the site (tz-aware or naive local).
    comfort : ComfortParams
        Comfort section of the plant parameters.

    Returns
    -------
    t_min_c, t_max_c : numpy.ndarray
        Bounds T_air,min and T_air,max, of the length of ``time`` [degC].
    """
    idx = _local_index(time)
    hour = np.asarray(idx.hour)
    off = is_off_day(idx, comfort)
    home = np.where(off, _in_hours(hour, comfort.home_hours_weekend), _in_hours(hour, comfort.home_hours_weekday))
    t_min = np.where(home, comfort.t_min_home_c, comfort.t_min_away_c).astype(float)
    t_max = np.full(len(idx), float(comfort.t_max_c))
    first, last = comfort.cooling_season_months
    month = np.asarray(idx.month)
    t_max[(month >= first) & (month <= last)] = float(comfort.t_max_cooling_c)
    return t_min, t_max
