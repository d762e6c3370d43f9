"""The embedded default scenario: the paper's winter from measured data (``sec:parameters``).

The paper evaluates twelve weeks from 2022-12-01 in Karlsruhe with day-ahead prices,
DWD weather of station Rheinstetten and a DHWCalc hot-water profile. This module builds
that scenario from the package data in ``comems4build_ros/data`` (provenance and licences
in its README) and the ``measured`` section of ``config/scenario.yaml``:

- spot price: ENTSO-E day-ahead prices of the bidding zone DE-LU, hourly, as measured;
- ambient temperature: DWD hourly ``TT_TU`` of station 4177 Rheinstetten, as measured; the
  record ends on 2023-02-14 23:00 UTC, later hours are filled (:func:`fill_temperature`,
  method ``repeat`` or ``synthetic``) and flagged in ``Scenario.meta["t_amb_filled"]``;
- hot-water draws: the DHWcalc file (200 l/day, single-family house); each calendar day
  takes the file day of the same weekday nearest to its day of the year
  (:func:`dhwcalc_day_of_year`), so weekday and weekend draw patterns fall on the right days;
- global and diffuse radiation: not available for the period, modelled as in the
  synthetic generator (pvlib clear-sky irradiance times a seeded daily clear-sky index,
  hourly variation, Erbs decomposition). With ``kc_from_temperature_amplitude`` the seeded
  daily indices are re-ordered so that their ranks follow the measured daily temperature
  amplitude: clear days, which have the larger diurnal swings, get the sunnier indices,
  while the distribution of the indices stays the calibrated one;
- appliance load: the synthetic generator's household load model (seeded).

Everything is deterministic for a given seed; the measured series do not depend on it.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.scenario.base import CSV_COLUMNS
from comems4build_ros.core.scenario.csvio import ScenarioError
from comems4build_ros.core.scenario.settings import HOURS_PER_DAY, MeasuredParams, ScenarioParams
from comems4build_ros.files.paths import PACKAGE_DIR

#: Days of a week.
DAYS_PER_WEEK = 7
#: Days of the (non-leap) year of a DHWcalc file.
DHWCALC_DAYS = 365


def data_dir() -> Path:
    """Return the directory of the package data files (``comems4build_ros/data``)."""
    return PACKAGE_DIR / "data"


def _data_path(name: str) -> Path:
    """Return a data file's path: ``name`` itself if absolute, else under :func:`data_dir`."""
    path = Path(name)
    return path if path.is_absolute() else data_dir() / path


def read_entsoe_prices(path: str | Path, column: str) -> pd.Series:
    """Read the hourly day-ahead spot prices of an ENTSO-E Transparency Platform export.

    Parameters
    ----------
    path : str or pathlib.Path
        CSV file with ``utc_start`` and the price column, one row per hour without gaps.
    column : str
        The price column [EUR/MWh].

    Returns
    -------
    pandas.Series
        ``spot_eur_per_mwh`` [EUR/MWh] by UTC hour start.

    Raises
    ------
    ScenarioError
        Naming the file, line and column of a missing column, a bad time or a bad number.
    """
    return read_price_csv(path, column, gapless=True)


def read_price_csv(path: str | Path, column: str, gapless: bool) -> pd.Series:
    """Read day-ahead prices from a CSV file with the columns ``utc_start`` and ``column``.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    column : str
        The price column [EUR/MWh].
    gapless : bool
        Every row one hour after the previous one (one contiguous period); else the rows
        need only follow each other in time (several winters in one file).

    Returns
    -------
    pandas.Series
        ``spot_eur_per_mwh`` [EUR/MWh] by UTC time.

    Raises
    ------
    ScenarioError
        Naming the file, line and column of a missing column, a bad time or number, or a row
        out of order.
    """
    path = Path(path)
    try:
        df = pd.read_csv(path, dtype=str)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read as CSV: {exc}") from None
    for col in ("utc_start", column):
        if col not in df.columns:
            raise ScenarioError(f"{path}: line 1 (header): column '{col}' missing (found {', '.join(df.columns)})")
    stamps = pd.to_datetime(df["utc_start"], utc=True, format="ISO8601", errors="coerce")
    if stamps.isna().any():
        i = int(np.flatnonzero(stamps.isna().to_numpy())[0])
        raise ScenarioError(f"{path}: line {i + 2}, column 'utc_start': '{df['utc_start'][i]}' is not a time")
    values = pd.to_numeric(df[column], errors="coerce").to_numpy(dtype=float)
    bad_rows = np.flatnonzero(~np.isfinite(values))
    if len(bad_rows):
        i = int(bad_rows[0])
        raise ScenarioError(f"{path}: line {i + 2}, column '{column}': '{df[column][i]}' is not a number")
    index = pd.DatetimeIndex(stamps, name="time")
    steps_h = np.asarray((index[1:] - index[:-1]) / pd.Timedelta(hours=1), dtype=float)
    wrong = np.flatnonzero(steps_h != 1.0) if gapless else np.flatnonzero(steps_h <= 0)
    if len(wrong):
        i = int(wrong[0]) + 1
        what = "not one hour after the previous row" if gapless else "not after the previous row"
        raise ScenarioError(f"{path}: line {i + 2}, column 'utc_start': {what}")
    return pd.Series(values, index=index, name="spot_eur_per_mwh")


def dhwcalc_day_of_year(dates: pd.DatetimeIndex, day1_weekday: int) -> np.ndarray:
    """Return the file day (1..365) of a DHWcalc year for each calendar date: same weekday, nearest day of year.

    A DHWcalc year starts on a fixed weekday (``day1_weekday``, 0 = Monday) and places its
    weekend draw pattern accordingly. Day ``d`` of the calendar takes the file day
    ``doy(d) + s`` with ``s`` in -3..3 chosen so that the weekdays agree; a result outside
    1..365 moves by a week.

    Parameters
    ----------
    dates : pandas.DatetimeIndex
        Local dates (one per calendar day).
    day1_weekday : int
        Weekday of the file's day 1 (0 = Monday .. 6 = Sunday).

    Returns
    -------
    numpy.ndarray of int
        File day per date, 1..365.
    """
    doy = np.minimum(np.asarray(dates.day_of_year), DHWCALC_DAYS)
    file_weekday = (doy - 1 + day1_weekday) % DAYS_PER_WEEK
    shift = (np.asarray(dates.day_of_week) - file_weekday) % DAYS_PER_WEEK
    shift = np.where(shift > 3, shift - DAYS_PER_WEEK, shift)
    out = doy + shift
    out = np.where(out < 1, out + DAYS_PER_WEEK, out)
    return np.where(out > DHWCALC_DAYS, out - DAYS_PER_WEEK, out)


def dhwcalc_draws(path: str | Path, time: pd.DatetimeIndex, day1_weekday: int) -> np.ndarray:
    """Return the hourly hot-water draws of a 1-h DHWcalc file at the local hours ``time``.

    DHWcalc ignores daylight saving: the hour of day is taken in local standard time.

    Parameters
    ----------
    path : str or pathlib.Path
        The DHWcalc file (8760 hourly values in l/h).
    time : pandas.DatetimeIndex
        Hour starts, tz-aware.
    day1_weekday : int
        Weekday of the file's day 1 (0 = Monday).

    Returns
    -------
    numpy.ndarray
        Draws [l/h], one per hour of ``time``.

    Raises
    ------
    ScenarioError
        For a file that is not at 1 h resolution, or as :func:`read_dhwcalc`.
    """
    from comems4build_ros.core.scenario.loaders import read_dhwcalc

    series = read_dhwcalc(path, 2001, "UTC")  # the year only labels the file's rows
    if len(series) != DHWCALC_DAYS * HOURS_PER_DAY:
        raise ScenarioError(f"{path}: {len(series)} hourly values, the default scenario needs a 1 h DHWcalc file")
    table = series.to_numpy(dtype=float).reshape(DHWCALC_DAYS, HOURS_PER_DAY)
    std_offset = pd.Timestamp(time[0].year, 1, 1).tz_localize(time.tz).utcoffset()
    local_std = time.tz_convert("UTC").tz_localize(None) + std_offset
    file_day = dhwcalc_day_of_year(local_std.normalize(), day1_weekday)
    return table[file_day - 1, np.asarray(local_std.hour)]


def fill_temperature(
    t_amb: np.ndarray, n_measured: int, method: str, reference_days: int, seam_h: int,
    synthetic: np.ndarray | None = None,
) -> np.ndarray:
    """Extend a measured hourly temperature series past its last measured hour.

    Parameters
    ----------
    t_amb : numpy.ndarray
        Hourly values [degC]; those from index ``n_measured`` on are replaced.
    n_measured : int
        Number of measured leading values.
    method : str
        ``repeat``: the values of the last ``reference_days`` measured days, repeated in
        order (whole days, so the diurnal cycle keeps its phase), plus an offset that
        closes the jump at the seam and decays linearly to zero over ``seam_h`` hours;
        ``synthetic``: the synthetic generator's temperature for the same hours
        (``synthetic``, same length as ``t_amb``), shifted by the mean difference of the
        measured and generated values over the last ``reference_days`` measured days.
    reference_days : int
        Days of measured data the fill refers to [d].
    seam_h : int
        Hours over which the seam offset of ``repeat`` decays [h].
    synthetic : numpy.ndarray, optional
        Generated temperature for ``synthetic`` [degC].

    Returns
    -------
    numpy.ndarray
        The filled series [degC] (a copy).

    Raises
    ------
    ScenarioError
        If fewer hours are measured than the fill refers to.
    ValueError
        For an unknown method, or ``synthetic`` without a generated series of the same
        length.
    """
    out = np.array(t_amb, dtype=float)
    n = len(out)
    if n_measured >= n:
        return out
    ref_h = reference_days * HOURS_PER_DAY
    if n_measured < ref_h:
        raise ScenarioError(f"temperature fill: {n_measured} measured hours, the fill refers to {ref_h}")
    fill_idx = np.arange(n_measured, n)
    if method == "repeat":
        src = n_measured - ref_h + (fill_idx - n_measured) % ref_h
        values = out[src]
        if seam_h > 0:
            jump = out[n_measured - 1] - out[n_measured - ref_h - 1]
            weight = np.clip(1.0 - (fill_idx - n_measured + 1) / (seam_h + 1), 0.0, None)
            values = values + jump * weight
    elif method == "synthetic":
        if synthetic is None or len(synthetic) != n:
            raise ValueError("synthetic fill needs the generated series of the same length")
        ref = slice(n_measured - ref_h, n_measured)
        values = synthetic[fill_idx] + float(np.mean(out[ref]) - np.mean(synthetic[ref]))
    else:
        raise ValueError(f"unknown temperature fill '{method}'")
    out[fill_idx] = values
    return out


def rank_matched(values: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Re-order values so that their ranks follow the ranks of ``key`` (ties by position).

    Parameters
    ----------
    values : numpy.ndarray
        Values to re-order, any unit.
    key : numpy.ndarray
        Key of the same length.

    Returns
    -------
    numpy.ndarray
        The sorted ``values`` placed at the rank of each key.
    """
    order = np.argsort(np.argsort(key, kind="stable"), kind="stable")
    return np.sort(values)[order]


def measured_hours(params: PlantParams, measured: MeasuredParams) -> pd.DatetimeIndex:
    """Return the hours the package data of ``measured`` cover from its start, without building the frame.

    Those are the hours of the price file; :func:`measured_frame` has one row per hour of it.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (time zone).
    measured : MeasuredParams
        The ``measured`` settings (price file and start).

    Returns
    -------
    pandas.DatetimeIndex
        Hour starts in UTC.
    """
    tz = params.site.timezone
    spot = read_entsoe_prices(_data_path(measured.prices_file), measured.prices_column)
    start = pd.Timestamp(measured.start).tz_localize(tz).tz_convert("UTC")
    return spot.index[spot.index >= start]


def measured_frame(
    params: PlantParams, measured: MeasuredParams, generator: ScenarioParams, seed: int | None = None,
    fill: str | None = None,
) -> tuple[pd.DataFrame, dict]:
    """Build a scenario frame of all hours the package data cover, from ``measured.start``.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (site, holidays).
    measured : MeasuredParams
        The ``measured`` settings.
    generator : ScenarioParams
        The synthetic generator's settings (its ``solar`` and ``load`` models).
    seed : int, optional
        Seed of the modelled radiation and load (default ``measured.seed``).
    fill : str, optional
        Temperature fill method (default ``measured.temperature.fill``).

    Returns
    -------
    frame : pandas.DataFrame
        UTC-indexed, the scenario CSV columns (units in the names).
    meta : dict
        Provenance of each series (ENTSO-E, DWD, DHWcalc, modelled), the seed and the
        temperature fill (``t_amb_filled``).

    Raises
    ------
    ScenarioError
        For a data file that does not cover the scenario's start.
    """
    tz = params.site.timezone
    seed = measured.seed if seed is None else int(seed)
    fill = fill or measured.temperature.fill
    prices_path = _data_path(measured.prices_file)
    spot = read_entsoe_prices(prices_path, measured.prices_column)
    start = pd.Timestamp(measured.start).tz_localize(tz).tz_convert("UTC")
    spot = spot[spot.index >= start]
    if len(spot) == 0 or spot.index[0] != start:
        raise ScenarioError(f"{prices_path}: no price for the scenario start {start.tz_convert(tz).isoformat()}")
    index = spot.index
    time = index.tz_convert(tz)
    temp_path = _data_path(measured.temperature.file)
    t_amb, n_measured = _temperature(temp_path, index, time, params, measured, generator, seed, fill)
    ghi, dhi, load = _modelled_radiation_and_load(time, t_amb, params, measured, generator, seed)
    dhw_path = _data_path(measured.dhw_file)
    dhw = dhwcalc_draws(dhw_path, time, measured.dhw_day1_weekday)
    frame = pd.DataFrame(
        {
            "t_amb_c": t_amb,
            "ghi_w_m2": ghi,
            "dhi_w_m2": dhi,
            "spot_eur_per_mwh": spot.to_numpy(),
            "p_load_w": load,
            "dhw_l_per_h": dhw,
        },
        index=index,
    )[list(CSV_COLUMNS[1:])]
    filled_from = time[n_measured].isoformat() if n_measured < len(time) else None
    meta = {
        "source": "measured",
        "spot_eur_per_mwh": f"ENTSO-E Transparency Platform, day-ahead DE-LU ({prices_path.name})",
        "t_amb_c": f"Deutscher Wetterdienst, station 4177 Rheinstetten, hourly TT_TU ({temp_path.name})",
        "dhw_l_per_h": f"DHWcalc via OpenDHW ({dhw_path.name})",
        "ghi_w_m2": f"modelled: pvlib clear-sky x seeded daily clear-sky index (seed {seed})",
        "p_load_w": f"modelled: household load model (seed {seed})",
        "seed": seed,
        "t_amb_filled": {"method": fill, "from": filled_from, "hours": int(len(time) - n_measured)},
    }
    return frame, meta


def _temperature(path: Path, index: pd.DatetimeIndex, time: pd.DatetimeIndex, params: PlantParams,
                 measured: MeasuredParams, generator: ScenarioParams, seed: int, fill: str) -> tuple[np.ndarray, int]:
    """Return the measured ambient temperature on ``index``, its missing end filled [degC]; and the measured hours."""
    from comems4build_ros.core.scenario.generator import generate
    from comems4build_ros.core.scenario.loaders import read_dwd_temperature

    t_meas = read_dwd_temperature(path).reindex(index)
    valid = np.isfinite(t_meas.to_numpy())
    n_measured = int(np.argmin(valid)) if not valid.all() else len(valid)
    if n_measured == 0 or valid[n_measured:].any():
        raise ScenarioError(
            f"{path}: the temperature must cover the scenario from its start without gaps "
            f"({int(valid.sum())} of {len(valid)} hours present)"
        )
    synthetic = None
    if fill == "synthetic":
        g = generate(generator, params.site, params.comfort.holidays_country, params.comfort.holidays_subdivision,
                     len(time), seed, start=time[0])
        synthetic = g.t_amb_c
    t_ref = measured.temperature
    t_amb = fill_temperature(t_meas.to_numpy(), n_measured, fill, t_ref.fill_reference_days, t_ref.fill_seam_h,
                             synthetic)
    return t_amb, n_measured


def _modelled_radiation_and_load(time: pd.DatetimeIndex, t_amb: np.ndarray, params: PlantParams,
                                 measured: MeasuredParams, generator: ScenarioParams, seed: int
                                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Model GHI and DHI [W/m2] and the appliance load [W]: the generator's models on the measured calendar."""
    from comems4build_ros.core.scenario.comfort import is_off_day
    from comems4build_ros.core.scenario.generator import _daily_kc, _load, _solar, _streams

    local_dates = time.normalize().tz_localize(None)
    day = ((local_dates - local_dates[0]).days).to_numpy()
    n_days = int(day.max()) + 1
    rng = _streams(seed)
    kc = _daily_kc(rng["solar"], n_days, np.zeros(n_days), generator)
    if measured.kc_from_temperature_amplitude:
        daily = pd.Series(t_amb).groupby(day)
        amplitude = (daily.max() - daily.min()).to_numpy()
        kc = rank_matched(kc, amplitude)
    ghi, dhi = _solar(rng["solar"], time, day, kc, generator, params.site)
    load = _load(rng["load"], time, day, is_off_day(time, params.comfort), generator)
    return ghi, dhi, load


def filled_mask(time: pd.DatetimeIndex, meta: dict) -> np.ndarray:
    """Mark the hours whose temperature was filled.

    Parameters
    ----------
    time : pandas.DatetimeIndex
        Hour starts, tz-aware.
    meta : dict
        A scenario's ``meta`` (its ``t_amb_filled`` entry).

    Returns
    -------
    numpy.ndarray of bool
        True from the first filled hour on.
    """
    info = (meta or {}).get("t_amb_filled") or {}
    start = info.get("from")
    if not start:
        return np.zeros(len(time), dtype=bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(time >= pd.Timestamp(start))
