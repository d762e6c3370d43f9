"""Scenarios: the embedded default winter scenario, scenario CSV files and comfort bounds.

Public API
----------
- :func:`default_scenario` : the embedded default, the paper's winter from measured data
  (``config/scenario.yaml`` section ``measured``, :mod:`.measured`)
- :func:`synthetic_scenario` : the seeded synthetic generator (section ``scenario``)
- :func:`load_scenario_csv` / :func:`write_scenario_csv` : the scenario CSV format
- :func:`resolve_scenario` : ``"default"`` or a CSV path, with ``start`` / ``weeks`` cuts
- :func:`comfort_bounds` : ``eq:T_min`` with public holidays counted as weekend days
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..config import PlantParams
from .base import CSV_COLUMNS, OPTIONAL_CSV_COLUMNS, SERIES, Scenario
from .comfort import comfort_bounds, is_off_day
from .csvio import ScenarioError, ScenarioWarning, read_scenario_frame, write_scenario_csv
from .settings import (
    MeasuredSettings,
    ScenarioSettings,
    load_measured_settings,
    load_scenario_settings,
    split_overrides,
)

__all__ = [
    "CSV_COLUMNS",
    "OPTIONAL_CSV_COLUMNS",
    "SERIES",
    "HOURS_PER_WEEK",
    "MeasuredSettings",
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "ScenarioSettings",
    "comfort_bounds",
    "default_scenario",
    "is_off_day",
    "load_measured_settings",
    "load_scenario_csv",
    "load_scenario_settings",
    "resolve_scenario",
    "scenario_from_frame",
    "synthetic_scenario",
    "write_scenario_csv",
]

#: Steps of one week at 1 h [h].
HOURS_PER_WEEK = 168
#: Conversion of a spot price [EUR/MWh] to [EUR/kWh].
KWH_PER_MWH = 1000.0

_CACHE: dict[tuple, object] = {}
#: Names of the embedded scenarios (``--scenario``).
EMBEDDED = ("default", "synthetic")


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
    """Buy price ``a + b * spot / 1000`` and the constant sell price [EUR/kWh] (paper ``eq:costs``).

    ``a`` = ``grid.buy_offset_eur_per_kwh``, ``b`` = ``grid.buy_spot_factor`` (derivation in
    ``config/plant.yaml``).
    """
    g = params.grid
    buy = g.buy_offset_eur_per_kwh + g.buy_spot_factor * spot_eur_per_mwh / KWH_PER_MWH
    sell = np.full(len(spot_eur_per_mwh), params.grid.price_sell_eur_per_kwh)
    return buy, sell


def scenario_from_frame(
    name: str, frame: pd.DataFrame, params: PlantParams, n_steps: int, meta: dict | None = None
) -> Scenario:
    """Build a :class:`Scenario` from a frame with the CSV columns (index: tz-aware hourly time).

    The time is converted to the site's zone; the tariff comes from ``price_buy_eur_per_kwh``
    when present, else ``a + b * spot / 1000`` (``grid``); comfort bounds from
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


def synthetic_scenario(
    params: PlantParams, weeks: float = 12, seed: int | None = None, settings: ScenarioSettings | None = None
) -> Scenario:
    """The synthetic winter scenario (generated, deterministic, no network; ``--scenario synthetic``).

    Parameters
    ----------
    params : plant parameters (site, tariff, comfort)
    weeks : run length [weeks] (fractions allowed when ``weeks * 168`` is a whole number of
        hours); the arrays hold ``weeks * 168 + lookahead_h`` hours
    seed : random seed (default: ``scenario.seed`` of ``config/scenario.yaml``)
    settings : generator settings (default: ``config/scenario.yaml``)

    Returns
    -------
    Scenario named ``synthetic`` with ``n_steps = weeks * 168``.
    """
    settings = settings or load_scenario_settings()
    n_steps = steps_of_weeks(weeks, "synthetic scenario")
    if weeks > settings.weeks:
        warnings.warn(
            f"synthetic scenario: {weeks} weeks requested, the generator is calibrated for {settings.weeks} weeks "
            "from its start; the price level is held flat beyond its last anchor",
            ScenarioWarning,
            stacklevel=2,
        )
    seed = settings.seed if seed is None else int(seed)
    # The generator's series depend on its length (calibration anchors, smoothing), so
    # always generate at least the configured period and cut: a shorter run is then
    # exactly the beginning of the full default scenario.
    n_gen = max(n_steps, steps_of_weeks(settings.weeks, "synthetic scenario"))
    frame = _generated_frame(params, settings, n_gen, seed).iloc[: n_steps + settings.lookahead_h]
    meta = {"source": "generator", "seed": seed, "settings": "config/scenario.yaml", "weeks": weeks}
    return scenario_from_frame("synthetic", frame, params, n_steps, meta)


def _measured_frame(
    params: PlantParams, measured: MeasuredSettings, settings: ScenarioSettings, seed: int, fill: str | None
) -> tuple[pd.DataFrame, dict]:
    """The measured frame (all covered hours), cached in memory on everything it depends on."""
    from .measured import measured_frame

    key = (
        "measured",
        measured.model_dump_json(),
        settings.model_dump_json(),
        params.site.model_dump_json(),
        params.comfort.model_dump_json(),
        seed,
        fill,
    )
    if key not in _CACHE:
        if len(_CACHE) >= _CACHE_MAX:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = measured_frame(params, measured, settings, seed, fill)
    frame, meta = _CACHE[key]
    return frame.copy(), dict(meta)


def default_scenario(
    params: PlantParams,
    weeks: float | None = None,
    seed: int | None = None,
    settings: ScenarioSettings | None = None,
    measured: MeasuredSettings | None = None,
    fill: str | None = None,
) -> Scenario:
    """The embedded default scenario: the paper's winter from measured data (no network).

    Prices, ambient temperature and hot-water draws are measured (package data; the
    temperature after the end of its record is filled and flagged in
    ``meta["t_amb_filled"]``); radiation and appliance load are modelled with ``seed``.
    See :mod:`.measured`.

    Parameters
    ----------
    params : plant parameters (site, tariff, comfort)
    weeks : run length [weeks] (default ``measured.weeks`` = 12; fractions allowed when
        they give whole hours); the arrays hold ``weeks * 168 + lookahead_h`` hours
    seed : seed of the modelled radiation and load (default ``measured.seed``)
    settings : synthetic generator settings (its ``solar`` and ``load`` models)
    measured : the ``measured`` settings (default ``config/scenario.yaml``)
    fill : temperature fill method (default ``measured.temperature.fill``)

    Raises
    ------
    ScenarioError
        If the run and its look-ahead need more hours than the data cover.
    """
    measured = measured or load_measured_settings()
    settings = settings or load_scenario_settings()
    weeks = measured.weeks if weeks is None else weeks
    n_steps = steps_of_weeks(weeks, "default scenario")
    seed = measured.seed if seed is None else int(seed)
    frame, meta = _measured_frame(params, measured, settings, seed, fill)
    need = n_steps + measured.lookahead_h
    if need > len(frame):
        max_weeks = (len(frame) - measured.lookahead_h) / HOURS_PER_WEEK
        raise ScenarioError(
            f"default scenario: {weeks} week(s) need {need} hours with the {measured.lookahead_h} h look-ahead; "
            f"the measured data cover {len(frame)} hours from {measured.start.isoformat()} "
            f"(at most {max_weeks:.2f} weeks); use --scenario synthetic for longer runs"
        )
    meta["weeks"] = weeks
    return scenario_from_frame("default", frame.iloc[:need], params, n_steps, meta)


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
    spec: str | Path,
    params: PlantParams,
    start: str | None = None,
    weeks: float | None = None,
    seed: int | None = None,
    settings_overrides: Mapping[str, Any] | None = None,
) -> Scenario:
    """``"default"`` (measured), ``"synthetic"`` (generated) or a scenario CSV path, cut to ``start`` and ``weeks``.

    Without ``start`` both embedded scenarios run ``weeks`` (default: the configured 12)
    from their start; with ``start`` the configured period is built and cut. ``seed``
    seeds the synthetic generator, or the modelled radiation and load of the default
    scenario; ``settings_overrides`` are dotted keys of ``config/scenario.yaml``
    (``{"measured.temperature.fill": "synthetic", "scenario.load.annual_kwh": 4000}``).
    Both are refused for a CSV file.
    """
    if str(spec) in EMBEDDED:
        parts = split_overrides(settings_overrides)
        settings = load_scenario_settings(overrides=parts["scenario"])
        if str(spec) == "default":
            measured = load_measured_settings(overrides=parts["measured"])

            def make(params: PlantParams, weeks: float, settings: ScenarioSettings) -> Scenario:
                return default_scenario(params, weeks=weeks, seed=seed, settings=settings, measured=measured)
        else:
            if parts["measured"]:
                raise ScenarioError("scenario 'synthetic': 'measured.*' settings apply to the default scenario only")

            def make(params: PlantParams, weeks: float, settings: ScenarioSettings) -> Scenario:
                return synthetic_scenario(params, weeks=weeks, seed=seed, settings=settings)
        if start is None:
            return make(params, weeks=weeks or settings.weeks, settings=settings)
        full = make(params, weeks=settings.weeks, settings=settings)
        frame = pd.DataFrame({c: getattr(full, c) for c in CSV_COLUMNS[1:]}, index=full.time.tz_convert("UTC"))
        return _window(full.name, frame, params, start, weeks, settings.lookahead_h, dict(full.meta))
    if seed is not None or settings_overrides:
        raise ScenarioError(f"scenario '{spec}': a seed or scenario settings apply to the embedded scenarios only")
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(f"scenario '{spec}': no such file (use 'default', 'synthetic' or a scenario CSV)")
    return load_scenario_csv(path, params, start=start, weeks=weeks)
