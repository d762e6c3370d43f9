"""Scenarios: the embedded default winter scenario, scenario CSV files and comfort bounds.

Public API
----------
- :func:`default_scenario` : the generated 12-week winter scenario (``config/scenario.yaml``)
- :func:`load_scenario_csv` / :func:`write_scenario_csv` : the scenario CSV format
- :func:`resolve_scenario` : ``"default"`` or a CSV path, with ``start`` / ``weeks`` cuts
- :func:`comfort_bounds` : ``eq:T_min`` with public holidays counted as weekend days
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from ..config import PlantParams
from .base import CSV_COLUMNS, OPTIONAL_CSV_COLUMNS, SERIES, Scenario
from .comfort import comfort_bounds, is_off_day
from .csvio import ScenarioError, ScenarioWarning, read_scenario_frame, write_scenario_csv
from .settings import ScenarioSettings, load_scenario_settings

__all__ = [
    "CSV_COLUMNS",
    "OPTIONAL_CSV_COLUMNS",
    "SERIES",
    "HOURS_PER_WEEK",
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "ScenarioSettings",
    "comfort_bounds",
    "default_scenario",
    "is_off_day",
    "load_scenario_csv",
    "load_scenario_settings",
    "resolve_scenario",
    "scenario_from_frame",
    "write_scenario_csv",
]

#: Steps of one week at 1 h [h].
HOURS_PER_WEEK = 168
#: Conversion of a spot price [EUR/MWh] to [EUR/kWh].
KWH_PER_MWH = 1000.0

_CACHE: dict[tuple, object] = {}


def steps_of_weeks(weeks: float, name: str) -> int:
    """Run length [steps] of ``weeks`` weeks at 1 h; fractions allowed if they give whole hours.

    Raises
    ------
    ScenarioError
        If ``weeks * 168`` is below 1 or not a whole number of hours.
    """
    hours = float(weeks) * HOURS_PER_WEEK
    n = round(hours)
    if n < 1 or abs(hours - n) > 1e-6:
        raise ScenarioError(f"{name}: weeks={weeks} gives {hours:g} h; it must give a whole number >= 1 of hours")
    return int(n)
_CACHE_MAX = 16


def _tariff(spot_eur_per_mwh: np.ndarray, params: PlantParams) -> tuple[np.ndarray, np.ndarray]:
    """Buy price ``spot / 1000 + surcharge`` and the constant sell price [EUR/kWh] (paper ``eq:costs``)."""
    buy = spot_eur_per_mwh / KWH_PER_MWH + params.grid.surcharge_eur_per_kwh
    sell = np.full(len(spot_eur_per_mwh), params.grid.price_sell_eur_per_kwh)
    return buy, sell


def scenario_from_frame(
    name: str, frame: pd.DataFrame, params: PlantParams, n_steps: int, meta: dict | None = None
) -> Scenario:
    """Build a :class:`Scenario` from a frame with the CSV columns (index: tz-aware hourly time).

    The time is converted to the site's zone; the tariff comes from ``price_buy_eur_per_kwh``
    when present, else ``spot / 1000 + grid.surcharge_eur_per_kwh``; comfort bounds from
    ``params.comfort`` (``eq:T_min``).
    """
    time = pd.DatetimeIndex(frame.index).tz_convert(params.site.timezone)
    time.name = "time"
    spot = np.array(frame["spot_eur_per_mwh"], dtype=float)
    buy, sell = _tariff(spot, params)
    if "price_buy_eur_per_kwh" in frame:
        buy = np.array(frame["price_buy_eur_per_kwh"], dtype=float)
    t_min, t_max = comfort_bounds(time, params.comfort)
    return Scenario(
        name=name,
        time=time,
        t_amb_c=np.array(frame["t_amb_c"], dtype=float),
        ghi_w_m2=np.array(frame["ghi_w_m2"], dtype=float),
        dhi_w_m2=np.array(frame["dhi_w_m2"], dtype=float),
        spot_eur_per_mwh=spot,
        price_buy_eur_per_kwh=buy,
        price_sell_eur_per_kwh=sell,
        p_load_w=np.array(frame["p_load_w"], dtype=float),
        dhw_l_per_h=np.array(frame["dhw_l_per_h"], dtype=float),
        t_min_c=t_min,
        t_max_c=t_max,
        n_steps=n_steps,
        meta=dict(meta or {}),
    )


def _generated_frame(params: PlantParams, settings: ScenarioSettings, n_steps: int, seed: int) -> pd.DataFrame:
    """Generated series as a frame, cached in memory on everything they depend on."""
    from .generator import generate

    hours = n_steps + settings.lookahead_h
    key = (
        settings.model_dump_json(),
        params.site.model_dump_json(),
        params.comfort.holidays_country,
        params.comfort.holidays_subdivision,
        hours,
        seed,
    )
    if key not in _CACHE:
        g = generate(settings, params.site, params.comfort.holidays_country, params.comfort.holidays_subdivision,
                     hours, seed)
        frame = pd.DataFrame({c: getattr(g, c) for c in CSV_COLUMNS[1:]}, index=g.time)
        if len(_CACHE) >= _CACHE_MAX:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = frame
    return _CACHE[key].copy()


def default_scenario(
    params: PlantParams, weeks: float = 12, seed: int | None = None, settings: ScenarioSettings | None = None
) -> Scenario:
    """The embedded default winter scenario (generated, deterministic, no network).

    Parameters
    ----------
    params : plant parameters (site, tariff, comfort)
    weeks : run length [weeks] (fractions allowed when ``weeks * 168`` is a whole number of
        hours); the arrays hold ``weeks * 168 + lookahead_h`` hours
    seed : random seed (default: ``scenario.seed`` of ``config/scenario.yaml``)
    settings : generator settings (default: ``config/scenario.yaml``)

    Returns
    -------
    Scenario named ``default`` with ``n_steps = weeks * 168``.
    """
    settings = settings or load_scenario_settings()
    n_steps = steps_of_weeks(weeks, "default scenario")
    if weeks > settings.weeks:
        warnings.warn(
            f"default scenario: {weeks} weeks requested, the generator is calibrated for {settings.weeks} weeks "
            "from its start; the price level is held flat beyond its last anchor",
            ScenarioWarning,
            stacklevel=2,
        )
    seed = settings.seed if seed is None else int(seed)
    # The generator's series depend on its length (calibration anchors, smoothing), so
    # always generate at least the configured period and cut: a shorter run is then
    # exactly the beginning of the full default scenario.
    n_gen = max(n_steps, steps_of_weeks(settings.weeks, "default scenario"))
    frame = _generated_frame(params, settings, n_gen, seed).iloc[: n_steps + settings.lookahead_h]
    meta = {"source": "generator", "seed": seed, "settings": "config/scenario.yaml", "weeks": weeks}
    return scenario_from_frame("default", frame, params, n_steps, meta)


def _window(
    name: str, frame: pd.DataFrame, params: PlantParams, start: str | None, weeks: float | None, lookahead_h: int,
    meta: dict,
) -> Scenario:
    """Cut ``frame`` to start at ``start`` and run ``weeks`` weeks (plus available look-ahead)."""
    tz = params.site.timezone
    if start is not None:
        try:
            t0 = pd.Timestamp(start)
        except ValueError:
            raise ScenarioError(f"{name}: start '{start}' is not an ISO date/time") from None
        t0 = t0.tz_localize(tz) if t0.tzinfo is None else t0
        pos = frame.index.searchsorted(t0.tz_convert("UTC"))
        if pos >= len(frame) or frame.index[pos] != t0.tz_convert("UTC"):
            raise ScenarioError(
                f"{name}: start {t0.isoformat()} is not an hour of the data "
                f"({frame.index[0].tz_convert(tz).isoformat()} .. {frame.index[-1].tz_convert(tz).isoformat()})"
            )
        frame = frame.iloc[pos:]
        meta["start"] = t0.isoformat()
    rows = len(frame)
    if weeks is not None:
        n_steps = steps_of_weeks(weeks, name)
        if n_steps > rows:
            raise ScenarioError(
                f"{name}: {weeks} week(s) need {n_steps} hourly rows from "
                f"{frame.index[0].tz_convert(tz).isoformat()}, only {rows} available"
            )
    else:
        n_steps = (rows // HOURS_PER_WEEK) * HOURS_PER_WEEK if rows >= HOURS_PER_WEEK else rows
    frame = frame.iloc[: n_steps + lookahead_h]
    return scenario_from_frame(name, frame, params, n_steps, meta)


def load_scenario_csv(
    path: str | Path, params: PlantParams, start: str | None = None, weeks: float | None = None,
    lookahead_h: int = 24,
) -> Scenario:
    """Read a scenario CSV (see :mod:`.csvio` for the format and the checks).

    Parameters
    ----------
    path : CSV file
    params : plant parameters (tariff unless the file has ``price_buy_eur_per_kwh``, comfort, time zone)
    start : ISO date/time of the first step (naive = local time of the site); default: first row
    weeks : run length [weeks] (fractions giving whole hours allowed); default: all whole weeks
        of the file (rows after them are look-ahead; a file shorter than one week runs all its rows)
    lookahead_h : rows kept after the run for the day-ahead window [h]

    Raises
    ------
    ScenarioError
        Naming the file, line and column of bad input, or a window outside the file.
    """
    path = Path(path)
    frame = read_scenario_frame(path)
    return _window(path.name, frame, params, start, weeks, lookahead_h, {"source": str(path)})


def resolve_scenario(
    spec: str | Path, params: PlantParams, start: str | None = None, weeks: float | None = None
) -> Scenario:
    """``"default"`` (the generated scenario) or a scenario CSV path, cut to ``start`` and ``weeks``.

    For the default scenario without ``start`` the generator runs for ``weeks`` (default:
    the configured 12); with ``start`` the configured period is generated and cut.
    """
    if str(spec) == "default":
        settings = load_scenario_settings()
        if start is None:
            return default_scenario(params, weeks=weeks or settings.weeks, settings=settings)
        full = default_scenario(params, weeks=settings.weeks, settings=settings)
        frame = pd.DataFrame({c: getattr(full, c) for c in CSV_COLUMNS[1:]}, index=full.time.tz_convert("UTC"))
        return _window("default", frame, params, start, weeks, settings.lookahead_h, dict(full.meta))
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(f"scenario '{spec}': no such file (use 'default' or a scenario CSV)")
    return load_scenario_csv(path, params, start=start, weeks=weeks)
