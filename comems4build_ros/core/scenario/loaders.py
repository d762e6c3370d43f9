"""Loaders for real data sources, resampled to 1 h, and the builder of a scenario CSV.

Sources and their formats:

- aWATTar market data API JSON (day-ahead price, EUR/MWh, net of taxes);
  :func:`fetch_awattar` downloads it (``comems4build data fetch-prices``).
- DWD open data, 10-minute air temperature (``TT_10``) and solar radiation (``GS_10``
  global, ``DS_10`` diffuse, J/cm2 per 10 min), and the hourly temperature product (``TT_TU``).
- DHWCalc output: one column of draws in l/h, one row per time step of a whole year.
- A household load CSV: a ``time`` column (ISO 8601 with UTC offset) and a power column.

Time conventions (documented choices):

- Every hourly value belongs to the step that *starts* at its time stamp (UTC inside this
  module; the scenario CSV is written in the site's local time with its offset).
- DWD ``MESS_DATUM`` is UTC. Radiation sums are taken to cover the 10 minutes *ending* at
  the stamp, so the hour ``[h, h+1)`` averages the stamps ``h:10 .. h+1:00``; temperatures are
  instantaneous, so the hour averages the stamps ``h:00 .. h:50``. An hour needs at least
  :data:`MIN_VALID_10MIN` valid 10-minute values, otherwise it is missing. The hourly
  product's value at ``HH`` is used for the step starting at ``HH``.
- Missing hours in a built scenario are filled by linear interpolation when a run is at
  most :data:`~.csvio.MAX_FILL_H` hours long (with a warning), otherwise the build fails
  naming the source file, the time and the column.
"""

from __future__ import annotations

import json
import re
import urllib.parse
import urllib.request
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.scenario.base import CSV_COLUMNS
from comems4build_ros.core.scenario.csvio import (
    MISSING_MARKER,
    ScenarioError,
    check_diffuse,
    check_values,
    fill_gaps,
    local_time,
    parse_times,
    read_text_file,
)
from comems4build_ros.files.inputs import ASCII_SPACE, InputFileError, load_json_text, parse_decimal, text_lines

#: aWATTar market data endpoint (aWATTar API documentation, api.awattar.de).
AWATTAR_URL = "https://api.awattar.de/v1/marketdata"
#: Milliseconds per hour (aWATTar time stamps are epoch milliseconds, UTC).
MS_PER_HOUR = 3_600_000
#: Joule per cm2 -> Joule per m2.
CM2_PER_M2 = 10_000.0
#: Seconds in a DWD 10-minute interval.
SECONDS_PER_10MIN = 600.0
#: Minimum number of valid 10-minute values for an hourly value.
MIN_VALID_10MIN = 4
#: Watt per kilowatt.
W_PER_KW = 1000.0
HOURS_PER_DAY = 24
#: DHWCalc rows per year -> step length [s] (365-day years).
DHWCALC_STEPS = {365 * HOURS_PER_DAY * k: 3600 // k for k in (1, 2, 4, 6, 12, 60)}


def j_per_cm2_10min_to_w_m2(value_j_cm2: np.ndarray | float) -> np.ndarray:
    """Convert a DWD 10-minute radiation sum to the mean irradiance: ``v * 10000 / 600``.

    Parameters
    ----------
    value_j_cm2 : numpy.ndarray or float
        Radiation sum over 10 minutes (DWD ``GS_10``, ``DS_10``) [J/cm2].

    Returns
    -------
    numpy.ndarray
        Mean irradiance over the 10 minutes [W/m2].
    """
    return np.asarray(value_j_cm2, dtype=float) * CM2_PER_M2 / SECONDS_PER_10MIN


# --------------------------------------------------------------------------- aWATTar


def read_awattar_json(path: str | Path) -> pd.Series:
    """Read the day-ahead prices of an aWATTar ``/v1/marketdata`` answer file.

    Parameters
    ----------
    path : str or pathlib.Path
        The JSON file.

    Returns
    -------
    pandas.Series
        Spot prices [EUR/MWh] by UTC hour start (:func:`parse_awattar`).
    """
    return parse_awattar(read_text_file(path), str(Path(path)))


def parse_awattar(text: str, source: str) -> pd.Series:
    """Parse the day-ahead prices of an aWATTar ``/v1/marketdata`` answer into an hourly series.

    Parameters
    ----------
    text : str
        The JSON answer (``{"data": [{"start_timestamp": ms, "end_timestamp": ms,
        "marketprice": EUR/MWh, "unit": "Eur/MWh"}]}``, aWATTar API).
    source : str
        The file or URL, for messages.

    Returns
    -------
    pandas.Series
        Spot prices [EUR/MWh] indexed by the UTC start of each hour. Intervals shorter than
        1 h (e.g. 15 min) are averaged to the hour.

    Raises
    ------
    ScenarioError
        Naming the source (file or URL) and the entry (``data[i]``) for bad JSON, a wrong
        unit, missing fields, duplicate/overlapping/decreasing intervals or gaps.
    """
    path = source
    try:
        doc = load_json_text(text, str(path))
    except InputFileError as exc:
        raise ScenarioError(str(exc)) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("data"), list):
        raise ScenarioError(f"{path}: expected an object with a 'data' list (aWATTar marketdata format)")
    if not doc["data"]:
        raise ScenarioError(f"{path}: 'data' is empty")
    starts, ends, prices = [], [], []
    for i, entry in enumerate(doc["data"]):
        for key in ("start_timestamp", "end_timestamp", "marketprice"):
            if not isinstance(entry, dict) or key not in entry:
                raise ScenarioError(f"{path}: data[{i}]: field '{key}' missing")
        unit = str(entry.get("unit", "Eur/MWh"))
        if unit.lower().replace(" ", "") != "eur/mwh":
            raise ScenarioError(f"{path}: data[{i}], field 'unit': '{unit}' (expected Eur/MWh)")
        price = entry["marketprice"]
        if isinstance(price, bool) or not isinstance(price, int | float) or not np.isfinite(price):
            raise ScenarioError(f"{path}: data[{i}], field 'marketprice': {json.dumps(price)} is not a number")
        starts.append(int(entry["start_timestamp"]))
        ends.append(int(entry["end_timestamp"]))
        prices.append(float(price))
    check_values(path, "spot_eur_per_mwh", np.array(prices), lambda i: f"data[{i}]", "field 'marketprice'")
    starts_a, ends_a = np.array(starts), np.array(ends)
    length = ends_a - starts_a
    if np.any(length <= 0) or np.any(MS_PER_HOUR % length != 0):
        i = int(np.flatnonzero((length <= 0) | (MS_PER_HOUR % np.maximum(length, 1) != 0))[0])
        raise ScenarioError(f"{path}: data[{i}]: interval of {length[i]} ms does not divide one hour")
    for i in range(1, len(starts_a)):
        if starts_a[i] != ends_a[i - 1]:
            kind = "gap" if starts_a[i] > ends_a[i - 1] else "overlapping or decreasing interval"
            t = pd.Timestamp(starts_a[i], unit="ms", tz="UTC").isoformat()
            raise ScenarioError(f"{path}: data[{i}], field 'start_timestamp': {kind} at {t}")
    index = pd.DatetimeIndex(pd.to_datetime(starts_a, unit="ms", utc=True))
    series = pd.Series(prices, index=index, name="spot_eur_per_mwh")
    weights = pd.Series(length / MS_PER_HOUR, index=index)
    hourly = (series * weights).resample("1h").sum(min_count=1) / weights.resample("1h").sum(min_count=1)
    coverage = weights.resample("1h").sum()
    partial = coverage[(coverage > 0) & (coverage < 1 - 1e-9)]
    if len(partial):
        raise ScenarioError(f"{path}: hour {partial.index[0].isoformat()} only partly covered by the data")
    return hourly.rename("spot_eur_per_mwh")


def fetch_awattar(start: pd.Timestamp, end: pd.Timestamp, timeout_s: float = 30.0) -> str:
    """Download aWATTar market data between two times (needs internet access).

    Parameters
    ----------
    start, end : pandas.Timestamp
        The window, tz-aware.
    timeout_s : float, optional
        Time limit of the request [s].

    Returns
    -------
    str
        The JSON text of ``GET /v1/marketdata?start=<ms>&end=<ms>``.
    """
    query = urllib.parse.urlencode(
        {"start": int(start.tz_convert("UTC").timestamp() * 1000), "end": int(end.tz_convert("UTC").timestamp() * 1000)}
    )
    request = urllib.request.Request(f"{AWATTAR_URL}?{query}", headers={"User-Agent": "comems4build_ros"})
    with urllib.request.urlopen(request, timeout=timeout_s) as response:  # noqa: S310 (fixed https URL)
        return response.read().decode("utf-8")


# --------------------------------------------------------------------------- DWD

#: ``MESS_DATUM`` formats by length (UTC): 10-minute and hourly products.
DWD_TIME_FORMATS = {12: "%Y%m%d%H%M", 10: "%Y%m%d%H"}


def read_dwd_product(
    path: str | Path, columns: tuple[str, ...],
    check: Callable[[pd.DataFrame, Callable[[int], str]], None] | None = None,
    empty_ok: tuple[str, ...] = (), encoding: str = "latin-1",
) -> pd.DataFrame:
    """Read a DWD open-data product (semicolon separated, ``MESS_DATUM`` UTC, rows end with ``eor``).

    A value is a plain decimal number (:func:`~comems4build_ros.files.inputs.parse_decimal`).

    Parameters
    ----------
    path : str or pathlib.Path
        The product file.
    columns : tuple of str
        The columns to read.
    check : callable, optional
        ``check(frame, where)`` judges the values before any averaging; ``where(i)`` is the
        file line of row ``i`` (for :func:`~.csvio.check_values`).
    empty_ok : tuple of str, optional
        Columns where an empty field is NaN (sunshine at night in the hourly station
        product); elsewhere it is refused.
    encoding : str, optional
        The file's encoding.

    Returns
    -------
    pandas.DataFrame
        The requested columns (floats in the product's units, -999 -> NaN) indexed by UTC
        time.

    Raises
    ------
    ScenarioError
        Naming the file, line and column for a missing column, a bad time stamp, a
        non-numeric value, a row without ``eor`` or with the wrong number of fields, and
        whatever ``check`` refuses.
    """
    path = Path(path)
    lines = text_lines(read_text_file(path, encoding))
    header = [h.strip(ASCII_SPACE) for h in lines[0].split(";")]
    for col in ("MESS_DATUM", *columns):
        if col not in header:
            raise ScenarioError(f"{path}: line 1 (header): column '{col}' missing (found {';'.join(header)})")
    pos = {c: header.index(c) for c in ("MESS_DATUM", *columns)}
    stamps, line_nos, rows = [], [], []
    for n, line in enumerate(lines[1:], start=2):
        if not line.strip(ASCII_SPACE):
            continue
        fields = [f.strip(ASCII_SPACE) for f in line.split(";")]
        if len(fields) != len(header):
            raise ScenarioError(f"{path}: line {n}: {len(fields)} fields, header has {len(header)}")
        if header[-1].lower() == "eor" and fields[-1].lower() != "eor":
            raise ScenarioError(f"{path}: line {n}, column 'eor': row does not end with 'eor'")
        stamps.append(fields[pos["MESS_DATUM"]])
        line_nos.append(n)
        row = []
        for col in columns:
            text = fields[pos[col]]
            if text == "" and col in empty_ok:
                row.append(np.nan)
                continue
            try:
                value = parse_decimal(text)
            except ValueError:
                raise ScenarioError(f"{path}: line {n}, column '{col}': {text[:40]!r} is not a number") from None
            row.append(np.nan if value == MISSING_MARKER else value)
        rows.append(row)
    if not rows:
        raise ScenarioError(f"{path}: no data rows")
    df = pd.DataFrame(rows, index=_dwd_times(path, stamps, line_nos), columns=list(columns))
    for col in columns:
        if col not in empty_ok and df[col].isna().all():
            raise ScenarioError(
                f"{path}: column '{col}': every one of the {len(df)} values is missing ({MISSING_MARKER:g}); "
                "no data to build from"
            )
    if check is not None:
        check(df, lambda i: f"line {line_nos[i]}")
    dup = df.index.duplicated()
    if dup.any() or not df.index.is_monotonic_increasing:
        i = int(np.flatnonzero(dup)[0]) if dup.any() else int(np.flatnonzero(np.diff(df.index.asi8) < 0)[0]) + 1
        kind = "duplicate" if dup.any() else "decreasing"
        raise ScenarioError(f"{path}: data row {i + 1}, column 'MESS_DATUM': {kind} time {df.index[i].isoformat()}")
    return df


def _dwd_times(path: Path, stamps: list[str], line_nos: list[int]) -> pd.DatetimeIndex:
    """Parse DWD ``MESS_DATUM`` stamps to a UTC index (one vectorised parse per stamp length).

    :class:`ScenarioError` names the line of the first stamp that is not yyyymmddHH[MM].
    """
    lengths = np.array([len(s) for s in stamps])
    ns = np.zeros(len(stamps), dtype="int64")
    bad = ~np.isin(lengths, list(DWD_TIME_FORMATS)) | ~np.array([s.isdigit() for s in stamps], dtype=bool)
    for length, fmt in DWD_TIME_FORMATS.items():
        sel = np.flatnonzero((lengths == length) & ~bad)
        if sel.size:
            parsed = pd.to_datetime(pd.Index([stamps[i] for i in sel]), format=fmt, errors="coerce")
            bad[sel[np.asarray(parsed.isna())]] = True
            ns[sel] = parsed.as_unit("ns").asi8
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ScenarioError(f"{path}: line {line_nos[i]}, column 'MESS_DATUM': '{stamps[i]}' is not yyyymmddHH[MM]")
    return pd.DatetimeIndex(ns.astype("datetime64[ns]"), name="time").tz_localize("UTC").as_unit("us")


def _hourly_from_10min(df: pd.DataFrame, end_stamped: bool) -> pd.DataFrame:
    """Average 10-minute values to hours; hours with fewer than MIN_VALID_10MIN values are NaN."""
    shifted = df.copy()
    if end_stamped:
        shifted.index = shifted.index - pd.Timedelta(minutes=10)
    mean = shifted.resample("1h").mean()
    count = shifted.resample("1h").count()
    return mean.where(count >= MIN_VALID_10MIN)


def read_dwd_temperature(path: str | Path) -> pd.Series:
    """Read the hourly air temperature from a DWD 10-minute (``TT_10``) or hourly (``TT_TU``) file.

    Parameters
    ----------
    path : str or pathlib.Path
        The DWD product file.

    Returns
    -------
    pandas.Series
        ``t_amb_c`` [degC] by UTC hour start; NaN for hours without enough valid values.

    Raises
    ------
    ScenarioError
        Naming the file, line and column.
    """
    path = Path(path)
    header = _read_text_lines(path)[0].upper()
    for col in ("TT_10", "TT_TU"):
        if col in header:
            def check(df: pd.DataFrame, where: Callable[[int], str], col: str = col) -> None:
                """Judge each value as an air temperature [degC]."""
                check_values(path, "t_amb_c", df[col].to_numpy(), where, f"column '{col}'")

            df = read_dwd_product(path, (col,), check)
            if col == "TT_10":
                return _hourly_from_10min(df, end_stamped=False)["TT_10"].rename("t_amb_c")
            return df["TT_TU"].asfreq("1h").rename("t_amb_c")
    raise ScenarioError(f"{path}: line 1 (header): neither 'TT_10' nor 'TT_TU' found (DWD air temperature)")


def read_dwd_solar(path: str | Path) -> pd.DataFrame:
    """Read the hourly mean global and diffuse horizontal irradiance from a DWD 10-minute solar file.

    ``GS_10`` and ``DS_10`` are sums over 10 minutes in J/cm2; the mean irradiance of an
    interval is ``v * 10000 / 600`` W/m2 (:func:`j_per_cm2_10min_to_w_m2`).

    Parameters
    ----------
    path : str or pathlib.Path
        The DWD 10-minute solar product (``GS_10``, ``DS_10``).

    Returns
    -------
    pandas.DataFrame
        ``ghi_w_m2`` and ``dhi_w_m2`` [W/m2] by UTC hour start.

    Raises
    ------
    ScenarioError
        Naming the file, line and column, also for diffuse above global irradiance.
    """
    def check(df: pd.DataFrame, where: Callable[[int], str]) -> None:
        """Judge each 10-minute value as irradiance [W/m2] within the scenario's range."""
        for c, col in (("GS_10", "ghi_w_m2"), ("DS_10", "dhi_w_m2")):
            check_values(path, col, j_per_cm2_10min_to_w_m2(df[c].to_numpy()), where,
                         f"column '{c}' (J/cm2 in 10 min as W/m2)")

    df = read_dwd_product(path, ("GS_10", "DS_10"), check)
    w = pd.DataFrame(
        {"ghi_w_m2": j_per_cm2_10min_to_w_m2(df["GS_10"]), "dhi_w_m2": j_per_cm2_10min_to_w_m2(df["DS_10"])},
        index=df.index,
    )
    hourly = _hourly_from_10min(w, end_stamped=True)

    def hour(i: int) -> str:  # the 10-minute stamps (end of each interval) that make up hour i
        """Name the 10-minute stamps of hourly row ``i``."""
        first = hourly.index[i] + pd.Timedelta(minutes=10)
        return f"MESS_DATUM {first:%Y%m%d%H%M}..{first + pd.Timedelta(minutes=50):%Y%m%d%H%M} (hourly mean)"

    check_diffuse(path, hourly["ghi_w_m2"].to_numpy(), hourly["dhi_w_m2"].to_numpy(), hour,
                  "column 'DS_10' above 'GS_10'")
    return hourly


# --------------------------------------------------------------------------- DHWCalc, load


def _read_text_lines(path: Path) -> list[str]:
    """Return the lines of a Latin-1 source file (DWD, DHWCalc), checked by :func:`~.csvio.read_text_file`."""
    return text_lines(read_text_file(path, "latin-1"))


def _is_number(text: str) -> bool:
    """Tell whether ``text`` is a plain decimal number."""
    try:
        parse_decimal(text)
    except ValueError:
        return False
    return True


def read_dhwcalc(path: str | Path, year: int, timezone: str) -> pd.Series:
    """Read the hourly hot-water draws from a DHWCalc output file (one value in l/h per line, one year).

    A file with two columns (separated by ``;``, ``,`` or blanks) must hold a step counter
    (consecutive integers) and the draw: the draw column is read, never the counter; more
    columns, or a first column that is not such a counter, are refused.
    The number of rows gives the step (8760 -> 1 h, 35040 -> 15 min, ... 525600 -> 1 min);
    step ``i`` starts at ``year``-01-01 00:00 local time + ``i`` steps (DHWCalc ignores
    daylight saving). A header line that is not a number is skipped.

    Parameters
    ----------
    path : str or pathlib.Path
        The DHWCalc file.
    year : int
        Calendar year the profile is laid on.
    timezone : str
        The site's IANA time zone (its standard-time offset places the steps).

    Returns
    -------
    pandas.Series
        ``dhw_l_per_h`` [l/h], hourly means by UTC hour start (8760 values).

    Raises
    ------
    ScenarioError
        Naming the file, line and column.
    """
    path = Path(path)
    values: list[float] = []
    first_data_line = 1
    n_fields = 0
    counter0 = 0.0  # first step counter of a two-column file
    for n, line in enumerate(_read_text_lines(path), start=1):
        fields = re.split(r"[;, \t]+", line.strip(ASCII_SPACE)) if line.strip(ASCII_SPACE) else []
        if not fields:
            continue
        if not values and n == 1 and not _is_number(fields[-1]):
            first_data_line = 2  # a header line
            continue
        if not n_fields:
            n_fields = len(fields)
            if n_fields > 2:
                raise ScenarioError(
                    f"{path}: line {n}: {n_fields} columns; a DHWCalc file has one column of draws in l/h "
                    "(or two: a step counter and the draw)"
                )
            counter0 = parse_decimal(fields[0]) if n_fields == 2 and _is_number(fields[0]) else 0.0
        if len(fields) != n_fields:
            raise ScenarioError(f"{path}: line {n}: {len(fields)} column(s), line {first_data_line} has {n_fields}")
        if n_fields == 2 and not (_is_number(fields[0]) and parse_decimal(fields[0]) == counter0 + len(values)):
            raise ScenarioError(
                f"{path}: line {n}, column 1: '{fields[0]}' is not the step counter of a two-column DHWCalc file "
                f"(expected {counter0 + len(values):g}); a two-column file must hold a counter and the draws in l/h"
            )
        try:
            values.append(parse_decimal(fields[-1]))
        except ValueError:
            raise ScenarioError(
                f"{path}: line {n}, column {n_fields}: {fields[-1][:40]!r} is not a number (l/h)") from None
    arr = np.asarray(values)
    if len(arr) not in DHWCALC_STEPS:
        raise ScenarioError(
            f"{path}: {len(arr)} rows; a DHWCalc year has one of {sorted(DHWCALC_STEPS)} rows (365 days)"
        )
    bad = np.flatnonzero(~np.isfinite(arr))
    if len(bad):
        raise ScenarioError(f"{path}: line {first_data_line + int(bad[0])}, column {n_fields}: '{arr[bad[0]]}' "
                            "is not a finite number (l/h)")
    check_values(path, "dhw_l_per_h", arr, lambda i: f"line {first_data_line + i}", f"column {n_fields} (l/h)")
    per_hour = len(arr) // (365 * HOURS_PER_DAY)
    hourly = arr.reshape(-1, per_hour).mean(axis=1)
    start = pd.Timestamp(year, 1, 1).tz_localize(timezone)
    std_offset = start.utcoffset()
    index = pd.date_range((pd.Timestamp(year, 1, 1) - std_offset).tz_localize("UTC"), periods=len(hourly), freq="h")
    return pd.Series(hourly, index=index, name="dhw_l_per_h")


def read_load_csv(path: str | Path, column: str | None = None, unit: str | None = None) -> pd.Series:
    """Read the hourly mean appliance load from a CSV with ``time`` (ISO 8601 with offset) and a power column.

    Sub-hourly rows (regular steps dividing one hour, value = mean power over the step
    starting at its time) are averaged to 1 h.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file.
    column : str, optional
        Power column (default: the only column other than ``time``).
    unit : str, optional
        ``W`` or ``kW`` (default: from a ``_w`` / ``_kw`` suffix of the column name).

    Returns
    -------
    pandas.Series
        ``p_load_w`` [W] by UTC hour start.

    Raises
    ------
    ScenarioError
        Naming the file, line and column.
    """
    import io

    path = Path(path)
    text = read_text_file(path)
    try:
        df = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        raise ScenarioError(f"{path}: cannot read CSV: {exc}") from None
    df.columns = [str(c).strip() for c in df.columns]
    if "time" not in df.columns:
        raise ScenarioError(f"{path}: line 1 (header): column 'time' missing")
    others = [c for c in df.columns if c != "time"]
    if column is None:
        if len(others) != 1:
            raise ScenarioError(
                f"{path}: line 1 (header): several power columns {others}; choose one with --load-column"
            )
        column = others[0]
    if column not in df.columns:
        raise ScenarioError(f"{path}: line 1 (header): column '{column}' missing")
    if unit is None:
        low = column.lower()
        unit = "kW" if low.endswith("_kw") else "W" if low.endswith("_w") else None
        if unit is None:
            raise ScenarioError(f"{path}: column '{column}': unit unknown; name it *_w or *_kw or pass --load-unit")
    factor = {"w": 1.0, "kw": W_PER_KW}.get(unit.lower())
    if factor is None:
        raise ScenarioError(f"{path}: unit '{unit}' is not W or kW")
    index = parse_times(path, df["time"])
    numeric = pd.to_numeric(df[column].replace(r"^\s*$", np.nan, regex=True), errors="coerce")
    values = numeric.to_numpy(dtype=float, copy=True)
    bad = np.flatnonzero(np.isnan(values) & ~df[column].str.strip().str.lower().isin(("", "nan")).to_numpy())
    if len(bad):
        text = df[column].iloc[bad[0]]
        raise ScenarioError(f"{path}: line {bad[0] + 2}, column '{column}': '{text}' is not a number")
    values[values == MISSING_MARKER] = np.nan
    steps = np.diff(index.as_unit("s").asi8)
    if len(steps):
        step = int(steps[0])
        wrong = np.flatnonzero(steps != step)
        if step <= 0 or 3600 % step != 0 or len(wrong):
            i = int(wrong[0]) + 1 if len(wrong) else 1
            raise ScenarioError(
                f"{path}: line {i + 2}, column 'time': irregular, duplicate or decreasing time "
                f"({index[i - 1].isoformat()} -> {index[i].isoformat()})"
            )
    watts = check_values(path, "p_load_w", values * factor, lambda i: f"line {i + 2}",
                         f"column '{column}' (read as {unit})")
    series = pd.Series(watts, index=index)
    hourly = series.resample("1h").mean()
    return hourly.rename("p_load_w")


# --------------------------------------------------------------------------- build


def repeat_year_profile(profile: pd.Series, index: pd.DatetimeIndex, timezone: str) -> pd.Series:
    """Return the values of a one-year hourly profile (e.g. DHWCalc) at ``index``, by position in the year.

    The position is (day of year, hour) in local standard time (UTC + the zone's January
    offset, as DHWCalc ignores daylight saving); day 366 of leap years reuses day 365.
    So a profile for one year serves a window in any year, e.g. Dec 2022 .. Feb 2023.

    Parameters
    ----------
    profile : pandas.Series
        8760 hourly values, in any unit.
    index : pandas.DatetimeIndex
        Hour starts, tz-aware.
    timezone : str
        The site's IANA time zone.

    Returns
    -------
    pandas.Series
        The profile's values on ``index``, in its unit.
    """
    values = profile.to_numpy(dtype=float)
    year = index[0].year
    std_offset = pd.Timestamp(year, 1, 1).tz_localize(timezone).utcoffset()
    local_std = index.tz_convert("UTC").tz_localize(None) + std_offset
    doy = np.minimum(local_std.day_of_year.to_numpy(), 365)
    pos = (doy - 1) * HOURS_PER_DAY + local_std.hour.to_numpy()
    return pd.Series(values[pos], index=index, name=profile.name)


def build_scenario_frame(
    params: PlantParams,
    prices: tuple[str, pd.Series],
    temperature: tuple[str, pd.Series],
    solar: tuple[str, pd.DataFrame],
    dhw: tuple[str, pd.Series] | None = None,
    load: tuple[str, pd.Series] | None = None,
    start: str | None = None,
    end: str | None = None,
    seed: int | None = None,
) -> tuple[pd.DataFrame, dict[str, str]]:
    """Combine hourly source series into a scenario frame (UTC index, the CSV columns).

    Each source is ``(name, series)``; the name appears in messages. The window is the
    common span of prices, temperature and solar, cut to ``start`` / ``end`` (ISO, naive =
    local time, end exclusive). DHW and load are taken from the default generator when not
    given (same window, same seed), and the returned provenance says so.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (site, time zone, holiday calendar).
    prices : tuple of (str, pandas.Series)
        Spot prices [EUR/MWh].
    temperature : tuple of (str, pandas.Series)
        Ambient temperature [degC].
    solar : tuple of (str, pandas.DataFrame)
        ``ghi_w_m2`` and ``dhi_w_m2`` [W/m2].
    dhw : tuple of (str, pandas.Series), optional
        One-year hot-water profile [l/h] (:func:`read_dhwcalc`).
    load : tuple of (str, pandas.Series), optional
        Appliance load [W].
    start, end : str, optional
        Window bounds (ISO, naive = local time, end exclusive).
    seed : int, optional
        Seed of the generated DHW and load (default ``config/scenario.yaml``).

    Returns
    -------
    frame : pandas.DataFrame
        UTC-indexed, the columns of :data:`CSV_COLUMNS` after ``time``; short gaps filled.
    provenance : dict of str to str
        Column -> source name.

    Raises
    ------
    ScenarioError
        If the sources share no hours or a gap is too long to fill.
    """
    tz = params.site.timezone
    required = {
        "spot_eur_per_mwh": prices,
        "t_amb_c": temperature,
        "ghi_w_m2": (solar[0], solar[1]["ghi_w_m2"]),
        "dhi_w_m2": (solar[0], solar[1]["dhi_w_m2"]),
    }
    first = max(s.first_valid_index() for _, s in required.values())
    last = min(s.last_valid_index() for _, s in required.values())

    if start is not None:
        first = max(first, local_time(start, tz, "start").tz_convert("UTC"))
    if end is not None:
        last = min(last, local_time(end, tz, "end").tz_convert("UTC") - pd.Timedelta(hours=1))
    if last < first:
        spans = "; ".join(f"{n}: {s.first_valid_index()} .. {s.last_valid_index()}" for n, s in required.values())
        raise ScenarioError(f"the sources share no common hours ({spans})")
    index = pd.date_range(first, last, freq="h")
    provenance: dict[str, str] = {}
    frame = pd.DataFrame(index=index)
    sources: dict[str, tuple[str, pd.Series]] = dict(required)
    if load is not None:
        sources["p_load_w"] = load
    if dhw is not None:
        sources["dhw_l_per_h"] = (dhw[0], repeat_year_profile(dhw[1], index, tz))
    for col, (name, series) in sources.items():
        values = series.reindex(index).to_numpy(dtype=float)

        def where(i: int, _index: pd.DatetimeIndex = index) -> str:
            """Name row ``i`` by its local time."""
            return f"time {_index[i].tz_convert(tz).isoformat()}"

        frame[col] = fill_gaps(name, col, values, where=where)
        provenance[col] = name
    missing = [c for c in ("p_load_w", "dhw_l_per_h") if c not in frame]
    if missing:
        from comems4build_ros.core.scenario.generator import generate
        from comems4build_ros.core.scenario.settings import load_scenario_settings

        settings = load_scenario_settings()
        seed = settings.seed if seed is None else seed
        g = generate(settings, params.site, params.comfort.holidays_country, params.comfort.holidays_subdivision,
                     len(index), seed, start=index[0].tz_convert(tz))
        for col in missing:
            frame[col] = getattr(g, col)
            provenance[col] = f"default generator (seed {seed})"
    return frame[list(CSV_COLUMNS[1:])], provenance


def write_frame_csv(frame: pd.DataFrame, path: str | Path, timezone: str) -> Path:
    """Write a scenario frame (UTC index) as a scenario CSV with local times and offsets (all or nothing).

    Parameters
    ----------
    frame : pandas.DataFrame
        UTC-indexed scenario columns.
    path : str or pathlib.Path
        The CSV file.
    timezone : str
        Zone of the written times.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from comems4build_ros.files.outputs import atomic_write

    path = Path(path)
    out = frame.copy()
    out.insert(0, "time", [t.tz_convert(timezone).isoformat() for t in frame.index])
    with atomic_write(path) as fh:
        out.to_csv(fh, index=False, float_format="%.10g")
    return path
