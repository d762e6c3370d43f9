"""Scenarios: the embedded default winter scenario, scenario CSV files and comfort bounds.

Public API
----------
- :func:`default_scenario` : the embedded default, the paper's winter from measured data
  (``config/scenario.yaml`` section ``measured``, :mod:`.measured`)
- :func:`synthetic_scenario` : the seeded synthetic generator (section ``scenario``)
- :func:`load_scenario_csv` / :func:`write_scenario_csv` : the scenario CSV format
- :func:`resolve_scenario` : ``"default"``, a validation case (``validation/<id>``,
  :mod:`.validation`) or a CSV path, with ``start`` / ``weeks`` cuts
- :func:`comfort_bounds` : ``eq:T_min`` with public holidays counted as weekend days
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams, path_kind
from comems4build_ros.core.scenario.base import CSV_COLUMNS, OPTIONAL_CSV_COLUMNS, SERIES, Scenario
from comems4build_ros.core.scenario.comfort import comfort_bounds, is_off_day
from comems4build_ros.core.scenario.csvio import (
    ScenarioError,
    ScenarioWarning,
    local_time,
    read_scenario_frame,
    write_scenario_csv,
)
from comems4build_ros.core.scenario.settings import (
    MeasuredParams,
    ScenarioParams,
    load_measured_settings,
    load_scenario_settings,
    split_overrides,
)
from comems4build_ros.core.scenario.tariff import PaperTariff, Tariff

__all__ = [
    "CSV_COLUMNS",
    "OPTIONAL_CSV_COLUMNS",
    "SERIES",
    "HOURS_PER_WEEK",
    "MeasuredParams",
    "Scenario",
    "ScenarioError",
    "ScenarioWarning",
    "ScenarioParams",
    "comfort_bounds",
    "default_scenario",
    "run_steps",
    "is_embedded",
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
EMBEDDED = ("default", "synthetic", "year")
#: Embedded scenarios from measured data -> their section of ``config/scenario.yaml``.
MEASURED_SECTIONS = {"default": "measured", "year": "measured_year"}


def is_embedded(spec: str | Path) -> bool:
    """True for a scenario built from package data by its name alone (no file of the caller's disk).

    The embedded scenarios (:data:`EMBEDDED`) and the validation cases (``validation/<id>``).
    """
    from comems4build_ros.core.scenario.validation import is_validation

    return str(spec) in EMBEDDED or is_validation(spec)


def steps_of_weeks(weeks: float, name: str) -> int:
    """Run length [steps] of ``weeks`` weeks at 1 h; fractions allowed if they give whole hours.

    Raises
    ------
    ScenarioError
        If ``weeks * 168`` is below 1 or not a whole number of hours.
    """
    hours = float(weeks) * HOURS_PER_WEEK
    if not np.isfinite(hours):
        raise ScenarioError(f"{name}: weeks={weeks}: the run length must be a finite number > 0")
    n = round(hours)
    if n < 1 or abs(hours - n) > 1e-6:
        raise ScenarioError(f"{name}: weeks={weeks} gives {hours:g} h; it must give a whole number >= 1 of hours")
    return int(n)


_CACHE_MAX = 16


def scenario_from_frame(
    name: str, frame: pd.DataFrame, params: PlantParams, n_steps: int, meta: dict | None = None,
    tariff: Tariff | None = None,
) -> Scenario:
    """Build a :class:`Scenario` from a frame with the CSV columns (index: tz-aware hourly time).

    The time is converted to the site's zone; the buy price comes from ``price_buy_eur_per_kwh``
    when present, else from ``tariff`` (default: the paper's ``a + b * spot / 1000``,
    ``grid``), as does the sell price (:mod:`.tariff`); comfort bounds from ``params.comfort``
    (``eq:T_min``).
    """
    time = pd.DatetimeIndex(frame.index).tz_convert(params.site.timezone)
    time.name = "time"
    spot = np.array(frame["spot_eur_per_mwh"], dtype=float)
    tariff = tariff or PaperTariff(params)
    buy, sell = tariff.prices(time, spot)
    meta = {**(meta or {}), **tariff.meta()}
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
        meta=meta,
    )


def _generated_frame(params: PlantParams, settings: ScenarioParams, n_steps: int, seed: int) -> pd.DataFrame:
    """Generated series as a frame, cached in memory on everything they depend on."""
    from comems4build_ros.core.scenario.generator import generate

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
    params: PlantParams, weeks: float = 12, seed: int | None = None, settings: ScenarioParams | None = None
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
    params: PlantParams, measured: MeasuredParams, settings: ScenarioParams, seed: int, fill: str | None
) -> tuple[pd.DataFrame, dict]:
    """The measured frame (all covered hours), cached in memory on everything it depends on."""
    from comems4build_ros.core.scenario.measured import measured_frame

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
    settings: ScenarioParams | None = None,
    measured: MeasuredParams | None = None,
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


#: ``extend`` values of :func:`resolve_scenario`: how a run longer than its data is filled.
EXTEND_METHODS = ("synthetic",)


def run_steps(weeks: float | None, hours: int | None, name: str) -> int | None:
    """Run length [steps at 1 h] of ``weeks`` or ``hours`` (at most one given; None = the scenario's default).

    Raises
    ------
    ScenarioError
        If both are given, ``hours`` is not an integer >= 1, or ``weeks`` does not give a
        whole number >= 1 of hours.
    """
    if weeks is not None and hours is not None:
        raise ScenarioError(f"{name}: give the run length as weeks or as hours, not both")
    if hours is not None:
        if isinstance(hours, bool) or int(hours) != hours or hours < 1:
            raise ScenarioError(f"{name}: hours={hours}: the run length must be an integer >= 1 of hours")
        return int(hours)
    if weeks is not None:
        return steps_of_weeks(weeks, name)
    return None


def check_time_step(params: PlantParams, name: str) -> None:
    """Refuse a plant step that differs from the scenario's hourly rows.

    Every scenario (generated or CSV) has one row per hour; a ``simulation.time_step_h``
    of 2 would integrate 2 h of physics per 1 h row and report twice the weeks.

    Raises
    ------
    ScenarioError
        Naming the parameter, its value and the data's step.
    """
    dt_h = params.simulation.time_step_h
    if abs(dt_h - 1.0) > 1e-9:
        raise ScenarioError(
            f"{name}: parameter simulation.time_step_h = {dt_h:g} h does not match the scenario's 1 h rows "
            "(the plant would integrate that step over each hourly row); use 1"
        )


def _synthetic_extension(
    params: PlantParams, after: pd.Timestamp, rows: int, seed: int | None, settings: ScenarioParams | None = None
) -> tuple[pd.DataFrame, int]:
    """``rows`` generated hours starting one hour after ``after`` (UTC index, the CSV columns) and the seed used."""
    from comems4build_ros.core.scenario.generator import generate

    settings = settings or load_scenario_settings()
    seed = settings.seed if seed is None else int(seed)
    start = (after + pd.Timedelta(hours=1)).tz_convert(params.site.timezone)
    g = generate(settings, params.site, params.comfort.holidays_country, params.comfort.holidays_subdivision,
                 rows, seed, start=start)
    frame = pd.DataFrame({c: getattr(g, c) for c in CSV_COLUMNS[1:]}, index=g.time.tz_convert("UTC"))
    return frame, seed


def _window(
    name: str, frame: pd.DataFrame, params: PlantParams, start: str | None, n_steps: int | None, lookahead_h: int,
    meta: dict, extend: str | None = None, seed: int | None = None, length_text: str = "",
    keep_lookahead: bool = False, generator: ScenarioParams | None = None, tariff: Tariff | None = None,
) -> Scenario:
    """Cut ``frame`` to start at ``start`` and run ``n_steps`` steps (plus the available look-ahead).

    The rows available to the run are those from ``start`` (less ``lookahead_h`` if
    ``keep_lookahead``: the embedded scenarios keep their look-ahead in the data; a CSV
    file's last rows may be run, its look-ahead then repeats the last row). A longer run
    is refused unless ``extend="synthetic"``: then rows of the synthetic generator
    (``generator`` settings, seed ``seed``) follow the data's last row, for the run and its
    look-ahead, and ``meta["extended"]`` says from when and how many (a CSV's own buy-price
    column continues with the configured tariff, ``eq:costs``). ``tariff`` prices the rows
    (default: the paper's, :mod:`.tariff`), the extension's as the data's.
    """
    tz = params.site.timezone
    if extend is not None and extend not in EXTEND_METHODS:
        raise ScenarioError(f"{name}: extend '{extend}' unknown (known: {', '.join(EXTEND_METHODS)})")
    if start is not None:
        t0 = local_time(start, tz, f"{name}: start")
        pos = frame.index.searchsorted(t0.tz_convert("UTC"))
        if pos >= len(frame) or frame.index[pos] != t0.tz_convert("UTC"):
            raise ScenarioError(
                f"{name}: start {t0.isoformat()} is not an hour of the data "
                f"({frame.index[0].tz_convert(tz).isoformat()} .. {frame.index[-1].tz_convert(tz).isoformat()})"
            )
        frame = frame.iloc[pos:]
        meta["start"] = t0.isoformat()
    rows = len(frame) - (lookahead_h if keep_lookahead else 0)
    if n_steps is None:
        n_steps = (rows // HOURS_PER_WEEK) * HOURS_PER_WEEK if rows >= HOURS_PER_WEEK else max(rows, 1)
    if n_steps > rows:
        last = frame.index[-1]
        if extend is None:
            where = f"scenario '{name}'" if keep_lookahead else name
            ahead = f", less the {lookahead_h} h look-ahead they keep" if keep_lookahead else ""
            raise ScenarioError(
                f"{where}: the run ({length_text or f'{n_steps} h'}) needs {n_steps} hourly steps from "
                f"{frame.index[0].tz_convert(tz).isoformat()}; the data allow only {rows} ({len(frame)} hours until "
                f"{(last + pd.Timedelta(hours=1)).tz_convert(tz).isoformat()}{ahead}); shorten the run or allow "
                "generated data after the end with extend 'synthetic' (simulate, compare, sweep: --extend synthetic)"
            )
        ext, used_seed = _synthetic_extension(params, last, n_steps + lookahead_h - len(frame), seed, generator)
        if "price_buy_eur_per_kwh" in frame:  # a CSV's own tariff column: the configured tariff after its end
            ext["price_buy_eur_per_kwh"] = (tariff or PaperTariff(params)).prices(
                pd.DatetimeIndex(ext.index), ext["spot_eur_per_mwh"].to_numpy(dtype=float))[0]
        frame = pd.concat([frame, ext[list(frame.columns)]])
        meta["extended"] = {
            "method": extend,
            "from": ext.index[0].tz_convert(tz).isoformat(),
            "rows": len(ext),
            "run_steps_extended": max(n_steps - (len(frame) - len(ext)), 0),
            "seed": used_seed,
        }
    frame = frame.iloc[: n_steps + lookahead_h]
    return scenario_from_frame(name, frame, params, n_steps, meta, tariff)


def load_scenario_csv(
    path: str | Path, params: PlantParams, start: str | None = None, weeks: float | None = None,
    lookahead_h: int = 24, hours: int | None = None, extend: str | None = None, seed: int | None = None,
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
    hours : run length [h] instead of ``weeks``
    extend : ``"synthetic"`` allows a run longer than the file (generated rows after its end)
    seed : generator seed of such an extension (default ``config/scenario.yaml``)

    Raises
    ------
    ScenarioError
        Naming the file, line and column of bad input, or a window outside the file.
    """
    path = Path(path)
    n_steps = run_steps(weeks, hours, path.name)
    frame = read_scenario_frame(path)
    return _window(path.name, frame, params, start, n_steps, lookahead_h, {"source": str(path)}, extend, seed,
                   _length_text(weeks, hours))


def _length_text(weeks: float | None, hours: int | None) -> str:
    if weeks is not None:
        return f"{weeks:g} week(s)"
    return f"{hours} h" if hours is not None else ""


def data_weeks(spec: str | Path, params: PlantParams, start: str | None = None) -> int | None:
    """Whole weeks of run the data of scenario ``spec`` hold from ``start`` (default: the first
    hour), its look-ahead kept: the largest ``weeks`` :func:`resolve_scenario` accepts without
    an extension (0 for a CSV file shorter than a week, which runs all its rows). None where
    that is not known without generating the data (``synthetic`` with a ``start``).

    Raises
    ------
    ScenarioError
        For a missing or invalid file or a start outside the data (as :func:`resolve_scenario`).
    """
    name = str(spec) if str(spec) in EMBEDDED else Path(spec).name
    if str(spec) == "synthetic":
        return None if start is not None else load_scenario_settings().weeks
    if str(spec) in MEASURED_SECTIONS:
        from comems4build_ros.core.scenario.measured import measured_hours

        measured = load_measured_settings(section=MEASURED_SECTIONS[str(spec)])
        index, lookahead_h = measured_hours(params, measured), measured.lookahead_h
    else:
        kind = path_kind(Path(spec))
        if kind:
            raise ScenarioError(f"scenario '{spec}': {kind} (use 'default', 'synthetic' or a scenario CSV file)")
        index, lookahead_h = read_scenario_frame(Path(spec)).index, 0
    if start is not None:
        t0 = local_time(start, params.site.timezone, f"{name}: start").tz_convert("UTC")
        index = index[index >= t0]
    return max(0, len(index) - lookahead_h) // HOURS_PER_WEEK


def resolve_scenario(
    spec: str | Path,
    params: PlantParams,
    start: str | None = None,
    weeks: float | None = None,
    hours: int | None = None,
    seed: int | None = None,
    extend: str | None = None,
    settings_overrides: Mapping[str, Any] | None = None,
) -> Scenario:
    """The scenario of a run: ``"default"`` (measured), ``"synthetic"`` (generated) or a CSV path, cut to its window.

    Parameters
    ----------
    spec : ``"default"``, ``"synthetic"``, ``"year"``, a validation case ``"validation/<id>"``
        (``config/validation.yaml``; a winter case needs the plant at its station) or a CSV path
    params : plant parameters (``simulation.time_step_h`` must be the data's 1 h)
    start : ISO date/time of the first step (naive = site local time); default: the first row
    weeks, hours : run length (at most one; default: the configured 12 weeks of an embedded
        scenario, the whole weeks of a CSV file or of the data after ``start``)
    seed : seed of generated data: the synthetic generator, the modelled radiation and load of
        the default scenario, and any synthetic extension
    extend : ``None`` refuses a run longer than the scenario's data; ``"synthetic"``
        appends generated data after its end (recorded in ``meta["extended"]``)
    settings_overrides : dotted keys of ``config/scenario.yaml`` for an embedded scenario
        (``{"measured.temperature.fill": "synthetic", "scenario.load.annual_kwh": 4000}``)

    The data of the default scenario are every hour its package data cover (2160 h from
    2022-12-01); those of the synthetic one the generator's configured period (``weeks``
    plus ``lookahead_h``). An embedded scenario's run must leave its look-ahead in the data
    (or in the extension); a shorter run is exactly the beginning of the full one.

    Raises
    ------
    ScenarioError
        For a missing or invalid file, a window outside the data, a bad run length, a seed
        or settings given for a CSV, or a plant step other than the data's.
    """
    name = str(spec) if is_embedded(spec) else Path(spec).name
    check_time_step(params, f"scenario '{name}'")
    n_steps = run_steps(weeks, hours, f"scenario '{name}'")
    length = _length_text(weeks, hours)
    from comems4build_ros.core.scenario.validation import is_validation

    if is_validation(spec):
        return _validation_scenario(name, params, start, n_steps, length, seed, extend, settings_overrides)
    if str(spec) in EMBEDDED:
        return _embedded_scenario(str(spec), name, params, start, n_steps, length, seed, extend, settings_overrides)
    if settings_overrides:
        raise ScenarioError(f"scenario '{spec}': scenario settings apply to the embedded scenarios only")
    if seed is not None and extend is None:
        raise ScenarioError(f"scenario '{name}': a seed applies to generated data only (the embedded scenarios or "
                            "--extend synthetic), not to a CSV file")
    path = Path(spec)
    kind = path_kind(path)
    if kind:
        raise ScenarioError(f"scenario '{spec}': {kind} (use 'default', 'synthetic' or a scenario CSV file)")
    return load_scenario_csv(path, params, start=start, weeks=weeks, hours=hours, extend=extend, seed=seed)


def _embedded_scenario(spec: str, name: str, params: PlantParams, start: str | None, n_steps: int | None,
                       length: str, seed: int | None, extend: str | None,
                       settings_overrides: Mapping[str, Any] | None) -> Scenario:
    """An embedded scenario (``default``, ``year``: measured; ``synthetic``: generated) cut to
    its window (the arguments as :func:`resolve_scenario` has checked them)."""
    parts = split_overrides(settings_overrides)
    settings = load_scenario_settings(overrides=parts["scenario"])
    if str(spec) in MEASURED_SECTIONS:
        section = MEASURED_SECTIONS[str(spec)]
        other = next(s for s in MEASURED_SECTIONS.values() if s != section)
        if parts[other]:
            raise ScenarioError(f"scenario '{spec}': '{other}.*' settings apply to another scenario "
                                f"(this one reads '{section}.*')")
        measured = load_measured_settings(overrides=parts[section], section=section)
        frame, meta = _measured_frame(params, measured, settings, measured.seed if seed is None else int(seed),
                                      None)
        lookahead_h, default_weeks = measured.lookahead_h, measured.weeks
    else:
        if parts["measured"] or parts["measured_year"]:
            raise ScenarioError("scenario 'synthetic': 'measured.*' and 'measured_year.*' settings apply to the "
                                "scenarios from measured data only")
        full = synthetic_scenario(params, weeks=settings.weeks, seed=seed, settings=settings)
        frame = pd.DataFrame({c: getattr(full, c) for c in CSV_COLUMNS[1:]}, index=full.time.tz_convert("UTC"))
        meta = dict(full.meta)
        lookahead_h, default_weeks = settings.lookahead_h, settings.weeks
    meta.pop("weeks", None)
    if n_steps is None and start is None:
        n_steps = steps_of_weeks(default_weeks, f"scenario '{name}'")
    return _window(name, frame, params, start, n_steps, lookahead_h, meta, extend, seed, length,
                   keep_lookahead=True, generator=settings)


def _validation_scenario(
    name: str, params: PlantParams, start: str | None, n_steps: int | None, length: str, seed: int | None,
    extend: str | None, settings_overrides: Mapping[str, Any] | None,
) -> Scenario:
    """A case of the validation set (:mod:`.validation`), cut to its window and priced by the
    tariff the case names (:func:`~comems4build_ros.core.scenario.validation.case_tariff`).

    Raises
    ------
    ScenarioError
        For an unknown case, a seed or scenario settings given (the case fixes both), or a
        plant that does not stand at a winter case's station.
    """
    from comems4build_ros.core.scenario.validation import (
        WEATHER,
        case_of,
        case_tariff,
        check_site,
        load_validation_settings,
        validation_frame,
    )

    if seed is not None and extend is None:
        raise ScenarioError(f"scenario '{name}': a validation case fixes its own seeds; give no seed")
    if settings_overrides:
        raise ScenarioError(f"scenario '{name}': a validation case takes no scenario settings "
                            "(config/validation.yaml defines it)")
    settings = load_validation_settings()
    case = case_of(name, settings)
    if case.kind == WEATHER:
        check_site(case, params, settings)
    frame, meta = validation_frame(case, params, settings)
    if n_steps is None and start is None:
        n_steps = steps_of_weeks(settings.weeks, f"scenario '{name}'")
    return _window(name, frame, params, start, n_steps, settings.lookahead_h, meta, extend, seed, length,
                   keep_lookahead=True, generator=load_scenario_settings(), tariff=case_tariff(case, params))
