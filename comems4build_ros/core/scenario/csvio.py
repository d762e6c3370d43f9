"""Scenario CSV: reading with checks, and writing.

Format (one row per hour, header in the first line)::

    time,t_amb_c,ghi_w_m2,dhi_w_m2,spot_eur_per_mwh,p_load_w,dhw_l_per_h[,price_buy_eur_per_kwh]
    2022-12-01T00:00:00+01:00,3.1,0.0,0.0,210.5,350.2,0.0

``time`` is ISO 8601 with a UTC offset (start of the hour); other columns are ignored.

Checks on reading (each error names the file, the line and the column):

- missing required column, a time that is not ISO 8601 or has no UTC offset -> error;
- duplicate, decreasing or non-hourly (gap) times -> error (a gap in time is not filled:
  the rows around it may come from different sources);
- missing values (empty, NaN, the DWD marker -999) -> runs of at most
  :data:`MAX_FILL_H` hours inside the file are filled by linear interpolation with a
  :class:`ScenarioWarning` naming the lines; longer runs or runs at the first/last row -> error;
- implausible values / wrong units -> error: a spot price column whose values all lie within
  +-2 (EUR/kWh instead of EUR/MWh), a buy price above 5 EUR/kWh (EUR/MWh or ct/kWh), air
  temperatures outside -60..60 degC (e.g. Kelvin), irradiance below -10 or above 1500 W/m2,
  diffuse above global by more than 10 W/m2, negative load or draws, a load above 100 kW, a load
  column whose values all lie below 20 (kW instead of W); the source loaders apply the same
  rules (:func:`check_values`, :func:`check_diffuse`);
- small negative irradiance (-10..0 W/m2, sensor offset at night) -> set to 0 with a warning.
"""

from __future__ import annotations

import csv
import io
import warnings
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd

from comems4build_ros.core.scenario.base import CSV_COLUMNS, OPTIONAL_CSV_COLUMNS, Scenario
from comems4build_ros.files.errors import InputError

#: Longest run of missing values filled by interpolation [h].
MAX_FILL_H = 3
#: Marker of missing values in DWD products (also accepted in scenario CSVs).
MISSING_MARKER = -999.0
#: A spot price column whose values all lie within +-this is taken as EUR/kWh [EUR/MWh].
SPOT_EUR_PER_KWH_SUSPECT = 2.0
#: Buy prices above this are taken as EUR/MWh or ct/kWh [EUR/kWh].
BUY_PRICE_MAX_EUR_PER_KWH = 5.0
#: A load column whose values all lie below this is taken as kW [W].
LOAD_KW_SUSPECT_W = 20.0
#: Header line is line 1, first data row is line 2.
FIRST_DATA_LINE = 2


#: Diffuse irradiance may exceed the global one by this much (measurement noise) [W/m2].
DIFFUSE_EXCESS_W_M2 = 10.0
#: column -> (min, max, unit hint): the plausible range of each scenario column, for the scenario
#: CSV and every source loader (:func:`check_values`). Air temperature -60..60 degC (a value in
#: Kelvin falls far outside); irradiance up to 1500 W/m2 (above the solar constant, 1361 W/m2);
#: spot prices from the day-ahead market's harmonised minimum of -500 EUR/MWh (EPEX SPOT / SDAC)
#: to 10000 EUR/MWh, above its maximum clearing price; a household load up to 100 kW, beyond
#: any house connection's main fuse (3 x 63 A at 230 V is 43 kW), so W read as kW is refused.
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "t_amb_c": (-60.0, 60.0, "degC (Kelvin?)"),
    "ghi_w_m2": (-10.0, 1500.0, "W/m2"),
    "dhi_w_m2": (-10.0, 1500.0, "W/m2"),
    "spot_eur_per_mwh": (-500.0, 10000.0, "EUR/MWh"),
    "p_load_w": (0.0, 1e5, "W"),
    "dhw_l_per_h": (0.0, 1e5, "l/h"),
    "price_buy_eur_per_kwh": (-BUY_PRICE_MAX_EUR_PER_KWH, BUY_PRICE_MAX_EUR_PER_KWH, "EUR/kWh"),
}


class ScenarioError(InputError):
    """Invalid scenario input; the message names the file, line and column."""


class ScenarioWarning(UserWarning):
    """A documented repair of scenario input (gap fill, clipped sensor offset)."""


def _line(i: int) -> int:
    """Return the file line of data row ``i`` (the header is line 1)."""
    return i + FIRST_DATA_LINE


#: Example of an ISO 8601 time with its UTC offset, for messages.
ISO_EXAMPLE = "2022-12-01T06:00:00+01:00"


def iso_time(text: str, what: str) -> datetime:
    """Parse an ISO 8601 date or date/time (``datetime.fromisoformat``: naive or with an offset).

    The one rule for every time that enters as text (``--start``, ``--end``, the ``time``
    column of a scenario or load CSV): ``12/01/2022`` or ``1.12.2022`` are refused, not
    guessed.

    Parameters
    ----------
    text : str
        The time as written.
    what : str
        Where it was written (the option, or file, line and column), for the message.

    Returns
    -------
    datetime.datetime
        The time, naive or with its UTC offset.

    Raises
    ------
    ScenarioError
        Naming ``what`` for a text that is not ISO 8601.
    """
    try:
        return datetime.fromisoformat(str(text).strip())
    except ValueError:
        raise ScenarioError(f"{what}: '{text}' is not an ISO 8601 date/time (e.g. 2022-12-01, 2022-12-01T06:00 "
                            f"or {ISO_EXAMPLE})") from None


def local_time(text: str, timezone: str, what: str) -> pd.Timestamp:
    """Parse an ISO 8601 date/time as a time of the zone ``timezone``; a naive one is local time there.

    A naive local time that the clocks skip (the spring-forward gap of daylight saving
    time) or pass twice (autumn) is refused with a message naming ``what`` and the offsets
    that make it unique, instead of being shifted or guessed.

    Parameters
    ----------
    text : str
        The time as written.
    timezone : str
        IANA time zone of the site.
    what : str
        Where it was written, for the message.

    Returns
    -------
    pandas.Timestamp
        The time, tz-aware in ``timezone``.

    Raises
    ------
    ScenarioError
        For a text that is not ISO 8601, a time in the gap or an ambiguous time.
    """
    t = pd.Timestamp(iso_time(text, what))
    if t.tzinfo is not None:
        return t.tz_convert(timezone)
    try:
        return t.tz_localize(timezone)
    except ValueError as exc:  # pandas' NonExistentTimeError / AmbiguousTimeError
        if "nonexistent" in str(exc).lower():
            raise ScenarioError(f"{what}: '{text}' does not exist in {timezone}: the clocks jump over it (start of "
                                "daylight saving time); give a time outside the gap or with its UTC offset") from None
        both = " or ".join(t.tz_localize(timezone, ambiguous=dst).isoformat() for dst in (True, False))
        raise ScenarioError(f"{what}: '{text}' occurs twice in {timezone} (end of daylight saving time); give the "
                            f"UTC offset: {both}") from None


def parse_times(path: str | Path, raw: pd.Series, column: str = "time", line_of=None,
                whole_hours: bool = False) -> pd.DatetimeIndex:
    """Parse a column of ISO 8601 times, each with its UTC offset (:func:`iso_time`), to a UTC index.

    Parameters
    ----------
    path : str or pathlib.Path
        The source, for messages.
    raw : pandas.Series
        The times as written.
    column : str, optional
        The column's name, for messages.
    line_of : callable, optional
        Row index -> file line (default: data rows from line 2).
    whole_hours : bool, optional
        Every time must be the start of an hour in the offset it is written with
        (``10:00+01:00``; ``10:30+05:30`` is a whole hour of India's time), as the hourly
        steps of a scenario are (the comfort bounds of ``eq:T_min`` change on the hour).

    Returns
    -------
    pandas.DatetimeIndex
        The times in UTC.

    Raises
    ------
    ScenarioError
        Naming the file, the line and the column of the first time that is not ISO 8601,
        has no offset or (``whole_hours``) is not on a whole hour.
    """
    line_of = line_of or _line
    times = []
    for i, text in enumerate(raw.astype(str)):
        where = f"{path}: line {line_of(i)}, column '{column}'"
        t = iso_time(text, where)
        if t.tzinfo is None:
            raise ScenarioError(f"{where}: '{text.strip()}' has no UTC offset (ISO 8601 with offset required, "
                                f"e.g. {ISO_EXAMPLE})")
        if whole_hours and (t.minute or t.second or t.microsecond):
            raise ScenarioError(f"{where}: '{text.strip()}' is not on a whole hour (each row is one hour from "
                                f"hh:00, e.g. {ISO_EXAMPLE})")
        times.append(t)
    return pd.DatetimeIndex(pd.to_datetime(times, utc=True))


def check_hourly(path: str | Path, time: pd.DatetimeIndex, column: str = "time", line_of=_line) -> None:
    """Refuse a time index that does not increase by exactly one hour per row.

    Parameters
    ----------
    path : str or pathlib.Path
        The source, for messages.
    time : pandas.DatetimeIndex
        The times of the rows.
    column : str, optional
        The column's name, for messages.
    line_of : callable, optional
        Row index -> file line.

    Raises
    ------
    ScenarioError
        For no rows, or naming the line of a duplicate, backward, gap or non-hourly time.
    """
    if len(time) == 0:
        raise ScenarioError(f"{path}: no data rows")
    step = np.diff(time.as_unit("s").asi8).astype(float)
    for i, dt in enumerate(step):
        if dt == 3600:
            continue
        cur, nxt = time[i], time[i + 1]
        if dt == 0:
            kind = f"duplicate time {nxt.isoformat()}"
        elif dt < 0:
            kind = f"time goes backwards from {cur.isoformat()} to {nxt.isoformat()}"
        elif dt % 3600 == 0:
            kind = (
                f"gap: time jumps from {cur.isoformat()} to {nxt.isoformat()} "
                f"({dt / 3600:.0f} h; {dt / 3600 - 1:.0f} rows missing)"
            )
        else:
            kind = f"not hourly: {cur.isoformat()} -> {nxt.isoformat()}"
        raise ScenarioError(f"{path}: line {line_of(i + 1)}, column '{column}': {kind}")


def _numeric(path: Path, df: pd.DataFrame, col: str) -> np.ndarray:
    """Return a text column as floats, missing values (empty, NaN, -999) as NaN; refuse text and inf."""
    values = pd.to_numeric(df[col].replace(r"^\s*$", np.nan, regex=True), errors="coerce")
    bad = values.isna() & df[col].notna() & ~df[col].astype(str).str.strip().str.lower().isin(("", "nan"))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ScenarioError(f"{path}: line {_line(i)}, column '{col}': '{df[col].iloc[i]}' is not a number")
    arr = values.to_numpy(dtype=float, copy=True)
    infinite = np.flatnonzero(np.isinf(arr))
    if len(infinite):  # 'inf' is a value, not a missing one: never filled
        i = int(infinite[0])
        raise ScenarioError(f"{path}: line {_line(i)}, column '{col}': '{df[col].iloc[i]}' is not a finite number")
    arr[arr == MISSING_MARKER] = np.nan
    return arr


def _line_label(i: int) -> str:
    """Return ``line N`` for data row ``i``."""
    return f"line {_line(i)}"


def fill_gaps(
    path: str | Path, col: str, arr: np.ndarray, where=_line_label, max_fill_h: int = MAX_FILL_H
) -> np.ndarray:
    """Linearly interpolate runs of at most ``max_fill_h`` missing values (with a warning).

    Parameters
    ----------
    path : str or pathlib.Path
        Source named in messages.
    col : str
        Column named in messages.
    arr : numpy.ndarray
        Values with NaN for missing ones, in the column's unit.
    where : callable, optional
        Row index -> location text for messages (default ``line N`` of a CSV).
    max_fill_h : int, optional
        Longest run that is filled [rows = h].

    Returns
    -------
    numpy.ndarray
        ``arr`` with the runs filled (``arr`` itself when nothing is missing).

    Warns
    -----
    ScenarioWarning
        Naming the filled rows.

    Raises
    ------
    ScenarioError
        For longer runs and for runs touching the first or last row.
    """
    miss = ~np.isfinite(arr)
    if not miss.any():
        return arr
    idx = np.flatnonzero(miss)
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)

    def span(run: np.ndarray) -> str:
        first, last = int(run[0]), int(run[-1])
        return where(first) if first == last else f"{where(first)} to {where(last)}"

    for run in runs:
        if run[0] == 0 or run[-1] == len(arr) - 1:
            raise ScenarioError(f"{path}: {span(run)}, column '{col}': missing value at the start or end of the data")
        if len(run) > max_fill_h:
            raise ScenarioError(
                f"{path}: {span(run)}, column '{col}': {len(run)} missing values in a row "
                f"(at most {max_fill_h} are filled)"
            )
    x = np.arange(len(arr))
    out = arr.copy()
    out[miss] = np.interp(x[miss], x[~miss], arr[~miss])
    warnings.warn(
        f"{path}: column '{col}': {int(miss.sum())} missing value(s) filled by linear interpolation "
        f"({'; '.join(span(r) for r in runs)})",
        ScenarioWarning,
        stacklevel=3,
    )
    return out


def check_values(
    source: str | Path, col: str, arr: np.ndarray, where: Callable[[int], str] = _line_label, name: str = ""
) -> np.ndarray:
    """Apply the plausibility rules of a scenario column, wherever its values enter.

    The scenario CSV reader and the source loaders (aWATTar, DWD, DHWCalc, load CSV) call
    this with their own locations, so a value is judged by one rule whatever file it comes
    from: a value outside :data:`PLAUSIBLE` (Kelvin for degC, 15000 W/m2, a price of 1e15),
    a spot price column whose values all lie within +-2 (EUR/kWh for EUR/MWh) and a load
    column whose values all lie below 20 W (kW read as W), each over at least 24 values.
    Small negative irradiance (-10..0 W/m2, a sensor offset at night) is set to 0 with a
    warning. Missing values (NaN) pass.

    Parameters
    ----------
    source : str or pathlib.Path
        File named in messages.
    col : str
        Scenario column whose rules apply (a key of :data:`PLAUSIBLE`).
    arr : numpy.ndarray
        Values in the column's unit.
    where : callable, optional
        Row index -> position in the source (``line 5``, ``data[3]``).
    name : str, optional
        The values' name in the source (default ``column '<col>'``), e.g.
        ``column 'GS_10' (as ghi_w_m2)``.

    Returns
    -------
    numpy.ndarray
        The values, small negative irradiance set to 0.

    Warns
    -----
    ScenarioWarning
        When small negative irradiance is set to 0.

    Raises
    ------
    ScenarioError
        Naming ``source``, the position and ``name``.
    """
    lo, hi, unit = PLAUSIBLE[col]
    name = name or f"column '{col}'"
    finite = arr[np.isfinite(arr)]
    span = f"{where(0)} to {where(len(arr) - 1)}"
    if col == "spot_eur_per_mwh" and len(finite) >= 24 and np.all(np.abs(finite) < SPOT_EUR_PER_KWH_SUSPECT):
        raise ScenarioError(
            f"{source}: {span}, {name}: all values within +-{SPOT_EUR_PER_KWH_SUSPECT:g}, this looks like EUR/kWh; "
            "the prices must be in EUR/MWh"
        )
    if col == "p_load_w" and len(finite) >= 24 and np.all(finite < LOAD_KW_SUSPECT_W):
        raise ScenarioError(
            f"{source}: {span}, {name}: all values below {LOAD_KW_SUSPECT_W:g} W, this looks like kW read as W; "
            "the load must be in W (a load CSV: --load-unit kW or a column named *_kw)"
        )
    bad = (arr < lo) | (arr > hi)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ScenarioError(
            f"{source}: {where(i)}, {name}: value {arr[i]:g} outside the plausible range {lo:g}..{hi:g} {unit}"
        )
    if col in ("ghi_w_m2", "dhi_w_m2") and (arr < 0).any():
        neg = np.flatnonzero(arr < 0)
        warnings.warn(
            f"{source}: {name}: {len(neg)} small negative value(s) (sensor offset, first at {where(int(neg[0]))}) "
            "set to 0",
            ScenarioWarning,
            stacklevel=2,
        )
        arr = np.maximum(arr, 0.0)
    return arr


def check_diffuse(
    source: str | Path, ghi: np.ndarray, dhi: np.ndarray, where: Callable[[int], str] = _line_label,
    name: str = "column 'dhi_w_m2'",
) -> None:
    """Refuse diffuse irradiance above the global one by more than :data:`DIFFUSE_EXCESS_W_M2` [W/m2].

    Diffuse horizontal irradiance is a part of the global horizontal irradiance; a larger
    value is a swapped column or a bad record (DWD ``DS_10`` > ``GS_10``).

    Parameters
    ----------
    source : str or pathlib.Path
        File named in messages.
    ghi, dhi : numpy.ndarray
        Global and diffuse horizontal irradiance [W/m2].
    where : callable, optional
        Row index -> position in the source.
    name : str, optional
        The diffuse values' name in the source.

    Raises
    ------
    ScenarioError
        Naming the first row where the diffuse exceeds the global irradiance.
    """
    excess = np.flatnonzero(dhi > ghi + DIFFUSE_EXCESS_W_M2)
    if len(excess):
        i = int(excess[0])
        raise ScenarioError(f"{source}: {where(i)}, {name}: diffuse {dhi[i]:g} W/m2 exceeds global {ghi[i]:g} W/m2")


#: Separators other than the comma that a scenario CSV is checked for (name in messages).
OTHER_SEPARATORS = {";": "semicolon", "\t": "tab", "|": "vertical bar"}


def read_text_file(path: str | Path, encoding: str = "utf-8-sig") -> str:
    """Read the text of a data file.

    Parameters
    ----------
    path : str or pathlib.Path
        File to read.
    encoding : str, optional
        ``utf-8-sig`` (scenario CSV, JSON) or ``latin-1`` (DWD and DHWCalc text files).

    Returns
    -------
    str
        The file's text.

    Raises
    ------
    ScenarioError
        Naming a directory, a device, binary content, an empty file or one over the size
        limit.
    """
    from comems4build_ros.files.inputs import MAX_FILE_BYTES, InputFileError, read_text

    try:
        return read_text(path, "a text file", MAX_FILE_BYTES, encoding, data_file=True)
    except InputFileError as exc:
        raise ScenarioError(str(exc)) from None


def check_header(path: str | Path, text: str, required: tuple[str, ...]) -> list[str]:
    """Return the column names of the header line (stripped), checked for separator, duplicates and ``required``.

    Parameters
    ----------
    path : str or pathlib.Path
        The file, for messages.
    text : str
        The file's text.
    required : tuple of str
        Columns that must be present.

    Returns
    -------
    list of str
        The column names in file order.

    Raises
    ------
    ScenarioError
        For a file separated by another character than the comma (named), a column name
        that appears twice, or a missing required column.
    """
    first = text.splitlines()[0]
    header = [c.strip() for c in next(csv.reader([first]))]
    if len(header) == 1:
        for sep, sep_name in OTHER_SEPARATORS.items():
            if sep in first:
                raise ScenarioError(
                    f"{path}: line 1 (header): the columns are separated by '{sep}' ({sep_name}), "
                    f"found '{first[:80]}'; a scenario CSV is comma-separated"
                )
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise ScenarioError(f"{path}: line 1 (header): column '{name}' appears twice")
        seen.add(name)
    missing = [c for c in required if c not in header]
    if missing:
        raise ScenarioError(f"{path}: line 1 (header): missing column(s) {', '.join(missing)} (found: "
                            f"{', '.join(header) or 'none'})")
    return header


def read_scenario_frame(path: str | Path) -> pd.DataFrame:
    """Read and check a scenario CSV.

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file (format in the module docstring).

    Returns
    -------
    pandas.DataFrame
        Indexed by UTC time, with the columns of :data:`CSV_COLUMNS` and any of
        :data:`OPTIONAL_CSV_COLUMNS` (units in the names), gaps filled.

    Warns
    -----
    ScenarioWarning
        For filled gaps and small negative irradiance set to 0.

    Raises
    ------
    ScenarioError
        Naming the file, line and column (see the module docstring for the rules).
    """
    path = Path(path)
    text = read_text_file(path)
    try:
        df = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False, skip_blank_lines=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ScenarioError(f"{path}: cannot read CSV: {exc}") from exc
    header = check_header(path, text, CSV_COLUMNS)
    df.columns = header
    if len(df) == 0:
        raise ScenarioError(f"{path}: no data rows")
    time = parse_times(path, df["time"], whole_hours=True)
    check_hourly(path, time)
    out = pd.DataFrame(index=time)
    for col in CSV_COLUMNS[1:] + tuple(c for c in OPTIONAL_CSV_COLUMNS if c in df.columns):
        arr = fill_gaps(path, col, _numeric(path, df, col))
        out[col] = check_values(path, col, arr)
    check_diffuse(path, out["ghi_w_m2"].to_numpy(), out["dhi_w_m2"].to_numpy())
    out["dhi_w_m2"] = np.minimum(out["dhi_w_m2"], out["ghi_w_m2"])
    return out


def write_scenario_csv(scenario: Scenario, path: str | Path) -> Path:
    """Write every row of ``scenario`` (run and look-ahead) as a scenario CSV.

    The buy price is written as ``price_buy_eur_per_kwh`` so that a re-read scenario keeps
    the tariff it was built with. Times are written in the scenario's (local) zone with
    their UTC offset; the file is replaced atomically.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    path : str or pathlib.Path
        The CSV file.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from comems4build_ros.files.outputs import atomic_write

    path = Path(path)
    df = pd.DataFrame(
        {
            "time": [t.isoformat() for t in scenario.time],
            **{c: getattr(scenario, c) for c in CSV_COLUMNS[1:]},
            "price_buy_eur_per_kwh": scenario.price_buy_eur_per_kwh,
        }
    )
    with atomic_write(path) as fh:
        df.to_csv(fh, index=False, float_format="%.10g")
    return path
