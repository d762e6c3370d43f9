"""The scenario's weather as an EnergyPlus weather file (EPW), and the check that one covers a run.

The EPW (EnergyPlus Auxiliary Programs, "Weather Converter Program", file format) holds one
record per hour in local *standard* time; the record of hour ``h`` (1..24) holds the
temperature at the end of the hour and the radiation summed over it. Written here from the
same series the plant and the PV model use:

- dry-bulb temperature: the scenario's ``t_amb_c`` (DWD station 4177 Rheinstetten for the
  measured scenarios), the step's value at the end of its hour;
- global and diffuse horizontal irradiance: the scenario's modelled ``ghi_w_m2`` and
  ``dhi_w_m2`` (the radiation the PV model sees), direct normal irradiance
  DNI = (GHI - DHI) / cos(zenith) at the middle of the hour (pvlib's solar position; 0 when
  the sun is less than :data:`MIN_ELEVATION_DEG` above the horizon);
- choices for the fields the scenario does not carry (:data:`CHOICES`): relative humidity,
  pressure, wind, sky cover (EnergyPlus derives the sky's long-wave radiation from them),
  ground albedo.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from comems4build_ros.core.config import SiteParams
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import parse_decimal, parse_integer, text_lines

#: Fields of an EPW data record that the scenario does not give (choices, written in the header).
CHOICES = {
    "relative_humidity_pct": 85.0,  # winter mean of the Upper Rhine valley, about (DWD RF_TU is not in the scenario)
    "pressure_pa": 100500.0,        # 115 m above sea level
    "wind_direction_deg": 225.0,    # south-west, the prevailing direction
    "wind_speed_m_s": 3.0,
    "total_sky_cover_tenths": 8.0,
    "opaque_sky_cover_tenths": 6.0,
    "albedo": 0.2,
}
#: Below this solar elevation the direct normal irradiance is written as 0 [deg].
MIN_ELEVATION_DEG = 3.0
#: Number of header lines of an EPW file.
HEADER_LINES = 8
#: Missing-value codes of the EPW fields written as missing.
_MISSING = {"ext_horiz": 9999, "ext_dni": 9999, "hor_ir": 9999, "illum": 999999, "zenith_lum": 9999,
            "visibility": 9999, "ceiling": 99999, "weather_codes": 999999999, "precip_water": 999,
            "aod": 0.999, "snow": 999, "days_since_snow": 99}
_FLAGS = "?9?9?9?9E0?9?9?9?9?9?9?9?9?9?9?9?9?9?9?9*9*9?9?9?9"


@dataclass(frozen=True)
class Weather:
    """Hourly weather of a run (the step's mean values, ``time`` = start of each step, local time).

    Attributes
    ----------
    time : pandas.DatetimeIndex
        Start of each hourly step, tz-aware.
    t_amb_c : numpy.ndarray
        Ambient temperature [degC].
    ghi_w_m2, dhi_w_m2 : numpy.ndarray
        Global and diffuse horizontal irradiance [W/m2].
    """

    time: pd.DatetimeIndex
    t_amb_c: np.ndarray
    ghi_w_m2: np.ndarray
    dhi_w_m2: np.ndarray


def standard_offset_h(site: SiteParams, time: pd.DatetimeIndex) -> float:
    """Return the site's standard-time offset from UTC (its offset outside daylight saving).

    Parameters
    ----------
    site : SiteParams
        ``timezone`` (IANA name).
    time : pandas.DatetimeIndex
        The run's steps (the year of the first one is used).

    Returns
    -------
    float
        Offset [h], the smaller of the January and July offsets.
    """
    import zoneinfo

    tz = zoneinfo.ZoneInfo(site.timezone)
    jan = pd.Timestamp(year=int(time[0].year), month=1, day=15, hour=12).tz_localize(tz)
    jul = pd.Timestamp(year=int(time[0].year), month=7, day=15, hour=12).tz_localize(tz)
    return min(jan.utcoffset().total_seconds(), jul.utcoffset().total_seconds()) / 3600.0


def standard_times(time: pd.DatetimeIndex, offset_h: float) -> pd.DatetimeIndex:
    """Convert the steps' starts to the site's standard time, naive (as EPW records count hours).

    Parameters
    ----------
    time : pandas.DatetimeIndex
        Step starts, tz-aware.
    offset_h : float
        Standard-time offset from UTC [h] (:func:`standard_offset_h`).

    Returns
    -------
    pandas.DatetimeIndex
        Naive local standard times.
    """
    return (time.tz_convert("UTC") + pd.Timedelta(hours=offset_h)).tz_localize(None)


def direct_normal_w_m2(weather: Weather, site: SiteParams) -> np.ndarray:
    """Compute DNI = (GHI - DHI) / cos(zenith) at the middle of each hour (0 with the sun below 3 deg).

    Parameters
    ----------
    weather : Weather
        Hourly GHI and DHI [W/m2].
    site : SiteParams
        Latitude, longitude [deg] and altitude [m] (solar position by pvlib).

    Returns
    -------
    numpy.ndarray
        Direct normal irradiance [W/m2].
    """
    import pvlib

    mid = weather.time + pd.Timedelta(minutes=30)
    pos = pvlib.solarposition.get_solarposition(mid, site.latitude_deg, site.longitude_deg, site.altitude_m)
    elev = pos["apparent_elevation"].to_numpy()
    cosz = np.sin(np.radians(np.clip(elev, MIN_ELEVATION_DEG, 90.0)))
    beam_h = np.clip(np.asarray(weather.ghi_w_m2, float) - np.asarray(weather.dhi_w_m2, float), 0.0, None)
    return np.where(elev >= MIN_ELEVATION_DEG, beam_h / cosz, 0.0)


def write_epw(path: str | Path, weather: Weather, site: SiteParams, source: str = "comems4build scenario") -> Path:
    """Write ``weather`` as an EPW file (one record per step, local standard time).

    The format is EnergyPlus's EPW (EnergyPlus "Auxiliary Programs", Weather Converter:
    8 header lines, then 35 fields per hourly record); fields the scenario does not hold are
    the format's "missing" values or the documented choices of :data:`CHOICES`.

    Parameters
    ----------
    path : str or Path
        Output file.
    weather : Weather
        Hourly series of the run (steps of 1 h, consecutive).
    site : SiteParams
        Location (latitude, longitude, altitude, time zone).
    source : str
        Text of the LOCATION line's source field.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    offset = standard_offset_h(site, weather.time)
    std = standard_times(weather.time, offset)
    dni = direct_normal_w_m2(weather, site)
    c = CHOICES
    first, last = std[0], std[-1]
    dow = first.day_name()
    choices = "; ".join(f"{k}={v:g}" for k, v in c.items())
    header = [
        f"LOCATION,Karlsruhe,BW,DEU,{source},4177,{site.latitude_deg:.4f},{site.longitude_deg:.4f},"
        f"{offset:.1f},{site.altitude_m:.1f}",
        "DESIGN CONDITIONS,0",
        "TYPICAL/EXTREME PERIODS,0",
        "GROUND TEMPERATURES,0",
        "HOLIDAYS/DAYLIGHT SAVINGS,No,0,0,0",
        "COMMENTS 1,dry bulb = scenario t_amb_c (DWD 4177 Rheinstetten where measured); GHI and DHI = the "
        "scenario's modelled radiation; DNI = (GHI-DHI)/cos(zenith) at mid-hour",
        f"COMMENTS 2,choices: {choices}",
        f"DATA PERIODS,1,1,Data,{dow},{first.month}/{first.day}/{first.year},{last.month}/{last.day}/{last.year}",
    ]
    rh = c["relative_humidity_pct"]
    rows = []
    m = _MISSING
    for t, temp, ghi, dhi, bn in zip(std, weather.t_amb_c, weather.ghi_w_m2, weather.dhi_w_m2, dni):
        dew = dew_point_c(float(temp), rh)
        rows.append(",".join(str(v) for v in (
            t.year, t.month, t.day, t.hour + 1, 60, _FLAGS, f"{float(temp):.3f}", f"{dew:.3f}", f"{rh:g}",
            f"{c['pressure_pa']:g}", m["ext_horiz"], m["ext_dni"], m["hor_ir"], f"{float(ghi):.3f}",
            f"{float(bn):.3f}", f"{float(dhi):.3f}", m["illum"], m["illum"], m["illum"], m["zenith_lum"],
            f"{c['wind_direction_deg']:g}", f"{c['wind_speed_m_s']:g}", f"{c['total_sky_cover_tenths']:g}",
            f"{c['opaque_sky_cover_tenths']:g}", m["visibility"], m["ceiling"], 9, m["weather_codes"],
            m["precip_water"], m["aod"], m["snow"], m["days_since_snow"], f"{c['albedo']:g}", 0, 1)))
    path.write_text("\n".join(header + rows) + "\n", encoding="utf-8")
    return path


def dew_point_c(t_c: float, rh_pct: float) -> float:
    """Compute the dew point by the Magnus formula (a = 17.62, b = 243.12 degC; WMO, over water).

    Parameters
    ----------
    t_c : float
        Air temperature [degC].
    rh_pct : float
        Relative humidity [%].

    Returns
    -------
    float
        Dew point [degC].
    """
    a, b = 17.62, 243.12
    g = np.log(rh_pct / 100.0) + a * t_c / (b + t_c)
    return float(b * g / (a - g))


class EPWError(InputError):
    """An EPW file that cannot serve a run; the message names the file, the line and the field."""


def epw_hours(path: str | Path) -> pd.DatetimeIndex:
    """Read the start of each record's hour of an EPW file.

    Parameters
    ----------
    path : str or Path
        EPW file.

    Returns
    -------
    pandas.DatetimeIndex
        Naive local standard time of each record's start (EPW hour h covers h-1 .. h).

    Raises
    ------
    EPWError
        If the file is missing, has fewer than :data:`HEADER_LINES` lines, or a record whose
        year, month, day or hour field is not a valid date.
    """
    path = Path(path)
    if not path.is_file():
        raise EPWError(f"{path}: EPW file not found")
    lines = text_lines(path.read_text(encoding="utf-8", errors="replace"))
    if len(lines) <= HEADER_LINES or not lines[0].startswith("LOCATION"):
        raise EPWError(f"{path}: line 1: field LOCATION: not an EPW file (8 header lines, then hourly records)")
    starts = []
    for i, line in enumerate(lines[HEADER_LINES:], start=HEADER_LINES + 1):
        parts = line.split(",")
        if len(parts) < 22:
            raise EPWError(f"{path}: line {i}: {len(parts)} fields, an EPW record has 35")
        try:
            y, mo, d, h = (parse_integer(parts[j]) for j in range(4))
            starts.append(pd.Timestamp(year=y, month=mo, day=d) + pd.Timedelta(hours=h - 1))
            parse_decimal(parts[6])
        except ValueError:
            raise EPWError(f"{path}: line {i}: field year/month/day/hour or dry bulb is not valid: {line[:60]!r}") \
                from None
    return pd.DatetimeIndex(starts)


def check_epw_covers(path: str | Path, first_std: pd.Timestamp, hours: int) -> None:
    """Raise :class:`EPWError` unless the EPW holds every hour from ``first_std`` for ``hours`` hours.

    Parameters
    ----------
    path : str or Path
        EPW file.
    first_std : pandas.Timestamp
        Start of the run's first hour (naive local standard time).
    hours : int
        Hours of the run (whole days are simulated: rounded up to a day).

    Raises
    ------
    EPWError
        Naming the file, the hours missing and the first of them.
    """
    have = epw_hours(path)
    need = pd.date_range(first_std.normalize(), periods=int(np.ceil((hours + first_std.hour) / 24.0)) * 24,
                         freq="h")
    missing = need.difference(have)
    if len(missing):
        raise EPWError(f"{path}: field date: the weather file does not cover the run: {len(missing)} of its "
                       f"{len(need)} hours are missing, the first {missing[0]} (records {have[0]} .. {have[-1]})")
