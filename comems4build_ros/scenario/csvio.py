"""Scenario CSV: reading with checks, and writing.

Format (one row per hour, header in the first line)::

    time,t_amb_c,ghi_w_m2,dhi_w_m2,spot_eur_per_mwh,p_load_w,dhw_l_per_h[,price_buy_eur_per_kwh]
    2022-12-01T00:00:00+01:00,3.1,0.0,0.0,210.5,350.2,0.0

``time`` is ISO 8601 with a UTC offset (start of the hour); other columns are ignored.

Checks on reading (each error names the file, the line and the column):

- missing required column, unparsable time or time without UTC offset -> error;
- duplicate, decreasing or non-hourly (gap) times -> error (a gap in time is not filled:
  the rows around it may come from different sources);
- missing values (empty, NaN, the DWD marker -999) -> runs of at most
  :data:`MAX_FILL_H` hours inside the file are filled by linear interpolation with a
  :class:`ScenarioWarning` naming the lines; longer runs or runs at the first/last row -> error;
- implausible values / wrong units -> error: a spot price column whose values all lie within
  +-2 (EUR/kWh instead of EUR/MWh), a buy price above 5 EUR/kWh (EUR/MWh or ct/kWh), air
  temperatures outside -60..60 degC (e.g. Kelvin), irradiance below -10 or above 1500 W/m2,
  diffuse above global by more than 10 W/m2, negative load or draws, a load column whose
  values all lie below 20 (kW instead of W);
- small negative irradiance (-10..0 W/m2, sensor offset at night) -> set to 0 with a warning.
"""

from __future__ import annotations

import csv
import io
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .base import CSV_COLUMNS, OPTIONAL_CSV_COLUMNS, Scenario

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

_OFFSET_RE = re.compile(r"(Z|[+-]\d{2}:?\d{2})$")

#: column -> (min, max, unit hint) plausibility range
_RANGES: dict[str, tuple[float, float, str]] = {
    "t_amb_c": (-60.0, 60.0, "degC (Kelvin?)"),
    "ghi_w_m2": (-10.0, 1500.0, "W/m2"),
    "dhi_w_m2": (-10.0, 1500.0, "W/m2"),
    "spot_eur_per_mwh": (-500.0, 10000.0, "EUR/MWh"),
    "p_load_w": (0.0, 1e6, "W"),
    "dhw_l_per_h": (0.0, 1e5, "l/h"),
    "price_buy_eur_per_kwh": (-BUY_PRICE_MAX_EUR_PER_KWH, BUY_PRICE_MAX_EUR_PER_KWH, "EUR/kWh"),
}


class ScenarioError(ValueError):
    """Invalid scenario input; the message names the file, line and column."""


class ScenarioWarning(UserWarning):
    """A documented repair of scenario input (gap fill, clipped sensor offset)."""


def _line(i: int) -> int:
    return i + FIRST_DATA_LINE


def _parse_time(path: Path, raw: pd.Series) -> pd.DatetimeIndex:
    for i, text in enumerate(raw.astype(str)):
        t = text.strip()
        if not _OFFSET_RE.search(t):
            raise ScenarioError(f"{path}: line {_line(i)}, column 'time': '{t}' has no UTC offset (ISO 8601 required)")
    try:
        return pd.DatetimeIndex(pd.to_datetime(raw.str.strip(), utc=True, format="ISO8601"))
    except (ValueError, TypeError):
        for i, text in enumerate(raw):
            try:
                pd.Timestamp(str(text).strip())
            except ValueError:
                raise ScenarioError(f"{path}: line {_line(i)}, column 'time': cannot parse '{text}'") from None
        raise


def check_hourly(path: str | Path, time: pd.DatetimeIndex, column: str = "time", line_of=_line) -> None:
    """Raise :class:`ScenarioError` unless ``time`` increases by exactly one hour per row."""
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
    values = pd.to_numeric(df[col].replace(r"^\s*$", np.nan, regex=True), errors="coerce")
    bad = values.isna() & df[col].notna() & ~df[col].astype(str).str.strip().str.lower().isin(("", "nan"))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ScenarioError(f"{path}: line {_line(i)}, column '{col}': '{df[col].iloc[i]}' is not a number")
    arr = values.to_numpy(dtype=float, copy=True)
    arr[arr == MISSING_MARKER] = np.nan
    return arr


def _line_label(i: int) -> str:
    return f"line {_line(i)}"


def fill_gaps(
    path: str | Path, col: str, arr: np.ndarray, where=_line_label, max_fill_h: int = MAX_FILL_H
) -> np.ndarray:
    """Linearly interpolate runs of at most ``max_fill_h`` missing values (with a warning).

    Parameters
    ----------
    path : source named in messages
    col : column named in messages
    arr : values with NaN for missing ones
    where : row index -> location text for messages (default ``line N`` of a CSV)
    max_fill_h : longest run that is filled [rows = h]

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


def _check_values(path: Path, col: str, arr: np.ndarray) -> np.ndarray:
    lo, hi, unit = _RANGES[col]
    if col == "spot_eur_per_mwh" and len(arr) >= 24 and np.all(np.abs(arr) < SPOT_EUR_PER_KWH_SUSPECT):
        raise ScenarioError(
            f"{path}: lines {_line(0)}-{_line(len(arr) - 1)}, column '{col}': all values within +-2, "
            "this looks like EUR/kWh; the column must be in EUR/MWh"
        )
    if col == "p_load_w" and len(arr) >= 24 and np.all(arr < LOAD_KW_SUSPECT_W):
        raise ScenarioError(
            f"{path}: lines {_line(0)}-{_line(len(arr) - 1)}, column '{col}': all values below 20, "
            "this looks like kW; the column must be in W"
        )
    bad = (arr < lo) | (arr > hi)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ScenarioError(
            f"{path}: line {_line(i)}, column '{col}': value {arr[i]:g} outside the plausible range "
            f"{lo:g}..{hi:g} {unit}"
        )
    if col in ("ghi_w_m2", "dhi_w_m2") and (arr < 0).any():
        neg = np.flatnonzero(arr < 0)
        warnings.warn(
            f"{path}: column '{col}': {len(neg)} small negative value(s) (sensor offset, first at line "
            f"{_line(int(neg[0]))}) set to 0",
            ScenarioWarning,
            stacklevel=3,
        )
        arr = np.maximum(arr, 0.0)
    return arr


#: Separators other than the comma that a scenario CSV is checked for (name in messages).
OTHER_SEPARATORS = {";": "semicolon", "\t": "tab", "|": "vertical bar"}


def read_text_file(path: str | Path, encoding: str = "utf-8-sig") -> str:
    """The text of a data file; :class:`ScenarioError` names a directory, a device, binary content or an empty file.

    Parameters
    ----------
    path : file to read
    encoding : ``utf-8-sig`` (scenario CSV, JSON) or ``latin-1`` (DWD and DHWCalc text files)
    """
    from ..config import path_kind

    path = Path(path)
    kind = path_kind(path)
    if kind:
        raise ScenarioError(f"{path}: {kind} (a text file is needed)")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read: {exc.strerror}") from None
    if b"\0" in raw:
        raise ScenarioError(f"{path}: binary content (NUL bytes), not a text file")
    try:
        text = raw.decode(encoding)
    except UnicodeDecodeError as exc:
        raise ScenarioError(
            f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); a binary file?"
        ) from None
    if not text.strip():
        raise ScenarioError(f"{path}: empty file")
    return text


def check_header(path: str | Path, text: str, required: tuple[str, ...]) -> list[str]:
    """Column names of the header line (stripped), checked for separator, duplicates and ``required``.

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
    """Read and check a scenario CSV; return a frame indexed by UTC time with the known columns.

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
    time = _parse_time(path, df["time"])
    check_hourly(path, time)
    out = pd.DataFrame(index=time)
    for col in CSV_COLUMNS[1:] + tuple(c for c in OPTIONAL_CSV_COLUMNS if c in df.columns):
        arr = fill_gaps(path, col, _numeric(path, df, col))
        out[col] = _check_values(path, col, arr)
    excess = out["dhi_w_m2"] > out["ghi_w_m2"] + 10.0
    if excess.any():
        i = int(np.flatnonzero(excess.to_numpy())[0])
        raise ScenarioError(
            f"{path}: line {_line(i)}, column 'dhi_w_m2': diffuse {out['dhi_w_m2'].iloc[i]:g} W/m2 exceeds "
            f"global {out['ghi_w_m2'].iloc[i]:g} W/m2"
        )
    out["dhi_w_m2"] = np.minimum(out["dhi_w_m2"], out["ghi_w_m2"])
    return out


def write_scenario_csv(scenario: Scenario, path: str | Path) -> Path:
    """Write every row of ``scenario`` (run and look-ahead) as a scenario CSV.

    The buy price is written as ``price_buy_eur_per_kwh`` so that a re-read scenario keeps
    the tariff it was built with. Times are written in the scenario's (local) zone with
    their UTC offset.
    """
    from ..fileio import atomic_write

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
