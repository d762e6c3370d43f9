"""The in-process closed loop: scenario -> observation -> EMS -> plant -> KPIs.

``simulate`` runs one EMS over a scenario and returns the per-step timeseries, the
weekly KPI table and the run summary; ``write_run`` stores them as ``timeseries.csv``,
``weekly.csv`` and ``summary.json``. The ROS nodes reuse :class:`ObservationBuilder`,
:func:`exogenous_series` and :func:`record_row`, so both paths compute identical numbers.
"""

from __future__ import annotations

import json
import math
import time as _time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pydantic import Field

from comems4build_ros.core import kpi
from comems4build_ros.core.config import PlantParams, Section, load_section
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import (
    BOUNDS_AHEAD,
    FORECAST_KEYS,
    INFO_LEVELS,
    PRICE_WINDOW,
    Controller,
    Observation,
    check_mpc_horizon,
)
from comems4build_ros.core.forecast import RealisticForecast, RealisticParams, error_statistics
from comems4build_ros.core.models.pv import pv_power_w
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.scenario.base import Scenario
from comems4build_ros.core.scenario.comfort import heating_season_days, holiday_dates
from comems4build_ros.core.types import (
    ACTION_FIELDS,
    FLOW_FIELDS,
    FORECAST_MODES,
    STATE_COLUMNS,
    Action,
    Exogenous,
    Flows,
    PlantState,
)
from comems4build_ros.files.outputs import atomic_dir

#: Hours of a day and of a week [h].
HOURS_PER_DAY = 24.0
HOURS_PER_WEEK = 168.0

#: Applied-command columns (what the EMS asked for, before the plant clipped it).
COMMAND_COLUMNS = tuple(f"cmd_{name}" for name in ACTION_FIELDS)
#: Exogenous columns not already among the flows.
EXO_COLUMNS = ("t_amb_c", "ghi_w_m2", "dhw_l_per_h", "t_min_c", "t_max_c", "spot_eur_per_mwh")
#: Fixed timeseries columns, in file order (EMS info columns ``ems_*`` follow).
TIMESERIES_COLUMNS = ("time", "step", *FLOW_FIELDS, *STATE_COLUMNS, *COMMAND_COLUMNS, *EXO_COLUMNS, "fallback")


def dloh_per_day(params: PlantParams) -> float:
    """Daily permissible H2 use ``eq:deltaLOH``: ``24 h * LOH_init / N``.

    ``N`` is the number of steps of the whole winter (``simulation.season_weeks``, the
    paper's twelve weeks), not of the run: a run shorter than the season spends H2 at the
    season's pace, so that the first weeks of a long run and a short run agree.

    Parameters
    ----------
    params : PlantParams
        Plant parameters: ``simulation.loh_init`` [-], ``time_step_h`` [h] and
        ``season_weeks`` [weeks].

    Returns
    -------
    float
        Delta LOH, the share of the store's energy the EMS may spend per day [1/day].
    """
    sim = params.simulation
    steps_per_day = HOURS_PER_DAY / sim.time_step_h
    season_steps = sim.season_weeks * HOURS_PER_WEEK / sim.time_step_h
    return sim.loh_init * steps_per_day / season_steps


def exogenous_series(scenario: Scenario, params: PlantParams) -> list[Exogenous]:
    """Build the per-step :class:`Exogenous` records of a whole scenario (PV computed once).

    Parameters
    ----------
    scenario : Scenario
        The run's inputs (weather, loads, prices, comfort bounds).
    params : PlantParams
        Plant parameters; ``pv`` and ``site`` give the PV output (``eq:power_pv``).

    Returns
    -------
    list of Exogenous
        One record per row of the scenario.
    """
    p_pv = pv_power_w(
        scenario.time, scenario.ghi_w_m2, scenario.dhi_w_m2, scenario.t_amb_c, params.pv, params.site
    )
    cols = zip(
        scenario.t_amb_c.tolist(),
        scenario.ghi_w_m2.tolist(),
        np.asarray(p_pv, dtype=float).tolist(),
        scenario.p_load_w.tolist(),
        scenario.dhw_l_per_h.tolist(),
        scenario.price_buy_eur_per_kwh.tolist(),
        scenario.price_sell_eur_per_kwh.tolist(),
        scenario.t_min_c.tolist(),
        scenario.t_max_c.tolist(),
    )
    return [Exogenous(*c) for c in cols]


class ForecastParams(Section):
    """Forecast settings (``config/forecast.yaml``); see that file for the sources.

    Attributes
    ----------
    mode : str
        ``perfect`` (the paper's setting) or ``imperfect`` (:class:`ForecastModel`).
    seed : int
        Seed of the forecast errors.
    sigma_t_amb_k_24h : float
        Standard deviation of the ambient-temperature error at 24 h lead [K].
    sigma_ghi_rel_24h : float
        Relative standard deviation of the irradiance and PV error at 24 h lead [-].
    """

    mode: str = Field(pattern="^(" + "|".join(FORECAST_MODES) + ")$")
    seed: int
    sigma_t_amb_k_24h: float = Field(ge=0)
    sigma_ghi_rel_24h: float = Field(ge=0)
    realistic: RealisticParams


def load_forecast_settings(path: str | Path | None = None, **overrides: Any) -> ForecastParams:
    """Read the forecast settings.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        Parameter file with a ``forecast`` section; default ``config/forecast.yaml``.
    **overrides
        Settings replacing the file's (``mode="imperfect"``).

    Returns
    -------
    ForecastParams
        The validated settings.
    """
    return load_section(ForecastParams, path, "forecast.yaml", "forecast", overrides)


class ForecastModel:
    """The 24-step forecasts the MPC receives (``forecast`` field of the observation).

    ``perfect``: the scenario's future values (the paper's setting). ``imperfect``:
    persistence for ``p_load_w`` and ``dhw_l_per_h`` (value 24 h earlier; before the
    first day, the first value), noisy ``t_amb_c`` (additive Gaussian) and ``ghi_w_m2`` /
    ``p_pv_w`` (one multiplicative Gaussian factor, clipped at 0), with standard deviation
    ``sigma_24h * sqrt(lead / 24)``; lead 0 is the measured current step and stays exact.
    The noise of step ``k`` is drawn from a generator seeded with ``(seed, k)``, so runs
    are reproducible and the in-process and ROS paths see identical forecasts.

    Parameters
    ----------
    series : mapping of str to list of float
        Each key of :data:`FORECAST_KEYS` over the run, padded by at least
        :data:`PRICE_WINDOW` steps at the end (units in the key names).
    settings : ForecastParams
        Mode, seed and error sizes.
    steps_per_day : int
        Steps per day (24 at 1 h steps).
    """

    def __init__(self, series: Mapping[str, list[float]], settings: ForecastParams, steps_per_day: int,
                 times: pd.DatetimeIndex | None = None) -> None:
        self._series = series
        self._s = settings
        self._day = steps_per_day
        lead = np.arange(PRICE_WINDOW, dtype=float)
        self._scale = np.sqrt(lead / steps_per_day)
        self._realistic: RealisticForecast | None = None
        if settings.mode == "realistic":  # comems4build_ros.core.forecast; needs the steps' times
            if times is None:
                raise ValueError("forecast mode 'realistic' needs the scenario's times")
            self._realistic = RealisticForecast(series, settings.realistic, settings.seed, times, steps_per_day,
                                                PRICE_WINDOW)

    def errors(self, steps: int) -> dict[str, float]:
        """Return what the forecasts of steps ``0 .. steps-1`` got wrong (:func:`.forecast.error_statistics`)."""
        known = self._realistic.known_until if self._realistic is not None else None
        return error_statistics(self.window, self._series, steps, self._day, PRICE_WINDOW, known)

    def window(self, k: int) -> dict[str, tuple[float, ...]]:
        """Return the forecast of every key in :data:`FORECAST_KEYS` for steps ``k .. k+23``.

        Parameters
        ----------
        k : int
            The current step.

        Returns
        -------
        dict of str to tuple of float
            Key -> :data:`PRICE_WINDOW` values, in the key's unit (``t_amb_c`` [degC],
            ``ghi_w_m2`` [W/m2], ``p_pv_w`` and ``p_load_w`` [W], ``dhw_l_per_h`` [l/h]...).
        """
        if self._realistic is not None:
            return self._realistic.window(k)
        s = self._series
        out = {key: s[key][k : k + PRICE_WINDOW] for key in FORECAST_KEYS}
        if self._s.mode == "imperfect":
            day = self._day
            for key in ("p_load_w", "dhw_l_per_h"):
                vals = s[key]
                out[key] = [vals[k]] + [vals[max(k + i - day, 0)] for i in range(1, PRICE_WINDOW)]
            rng = np.random.default_rng((self._s.seed, k))
            e_t = rng.standard_normal(PRICE_WINDOW) * self._s.sigma_t_amb_k_24h * self._scale
            f_g = np.clip(1.0 + rng.standard_normal(PRICE_WINDOW) * self._s.sigma_ghi_rel_24h * self._scale, 0.0, None)
            out["t_amb_c"] = (np.asarray(out["t_amb_c"]) + e_t).tolist()
            out["ghi_w_m2"] = (np.asarray(out["ghi_w_m2"]) * f_g).tolist()
            out["p_pv_w"] = (np.asarray(out["p_pv_w"]) * f_g).tolist()
        return {key: tuple(v) for key, v in out.items()}


class ObservationBuilder:
    """Builder of the :class:`Observation` of one information level for each step.

    The levels are the inputs each EMS may use (``tab:level_of_information``).

    Parameters
    ----------
    scenario : Scenario
        The run's inputs.
    params : PlantParams
        Plant parameters.
    level : str
        Information level: ``basic``, ``fuzzy`` or ``mpc`` (:data:`INFO_LEVELS`).
    exo : sequence of Exogenous
        Per-step exogenous records from :func:`exogenous_series`.
    forecast : ForecastParams, optional
        Forecast settings for the MPC level (default: ``config/forecast.yaml``).

    Raises
    ------
    ValueError
        For an unknown level, or at the MPC level a horizon other than :data:`PRICE_WINDOW`
        steps.
    """

    def __init__(
        self,
        scenario: Scenario,
        params: PlantParams,
        level: str,
        exo: Sequence[Exogenous],
        forecast: ForecastParams | None = None,
    ) -> None:
        if level not in INFO_LEVELS:
            raise ValueError(f"unknown information level '{level}'")
        if level == "mpc":
            check_mpc_horizon(params.simulation.horizon_h, params.simulation.time_step_h)
        self.level = level
        self._fields = INFO_LEVELS[level]
        pad = PRICE_WINDOW

        def padded(values: Sequence[float]) -> list[float]:
            vals = list(values)
            return vals + [vals[-1]] * pad

        self._exo = exo
        self._prices = padded(scenario.price_buy_eur_per_kwh.tolist())
        self._t_min = padded(scenario.t_min_c.tolist())
        self._series = {
            "t_amb_c": padded(scenario.t_amb_c.tolist()),
            "ghi_w_m2": padded(scenario.ghi_w_m2.tolist()),
            "p_pv_w": padded([e.p_pv_w for e in exo]),
            "p_load_w": padded(scenario.p_load_w.tolist()),
            "dhw_l_per_h": padded(scenario.dhw_l_per_h.tolist()),
            "t_min_c": self._t_min,
            "t_max_c": padded(scenario.t_max_c.tolist()),
            "price_buy_eur_per_kwh": self._prices,
        }
        t0 = scenario.time[0]
        self._day_index = [int(((t - t0).total_seconds() / 3600.0) // 24) for t in scenario.time]
        self._hour = [int(t.hour) for t in scenario.time]
        self._weekday = [int(t.weekday()) for t in scenario.time]
        years = tuple(sorted({t.year for t in scenario.time}))
        hol = holiday_dates(params.comfort.holidays_country, params.comfort.holidays_subdivision, years)
        self._weekend = [wd >= 5 or t.date() in hol for wd, t in zip(self._weekday, scenario.time)]
        self._dloh = dloh_per_day(params)
        sim = params.simulation
        to_season, season_left = heating_season_days(scenario.time, sim.heating_season_start, sim.heating_season_end)
        self._to_season = to_season.tolist()
        self._season_left = season_left.tolist()
        self._forecast = ForecastModel(
            self._series,
            forecast or load_forecast_settings(),
            int(round(24.0 / params.simulation.time_step_h)),
            scenario.time,
        )

    def data(self, k: int, state: PlantState) -> dict[str, Any]:
        """Return every field of the level for step ``k``.

        Parameters
        ----------
        k : int
            The step to decide.
        state : PlantState
            State at the end of step ``k - 1``.

        Returns
        -------
        dict
            Field name -> value (units in the names: ``t_air_c`` [degC], ``soc`` [-],
            ``prices_buy_24h`` [EUR/kWh], ``dloh_per_day`` [1/day]...).
        """
        e = self._exo[k]
        d: dict[str, Any] = {
            "step": k,
            "day_index": self._day_index[k],
            "hour_of_day": self._hour[k],
            "weekday": self._weekday[k],
            "is_weekend": self._weekend[k],
            "t_air_c": state.t_air_c,
            "v_dhw_l": state.v_dhw_l,
            "soc": state.soc,
            "loh": state.loh,
            "hp_mod_prev": state.hp_mod,
            "p_pv_w": e.p_pv_w,
            "p_load_w": e.p_load_w,
            "t_min_c": e.t_min_c,
            "t_max_c": e.t_max_c,
            "price_buy_eur_per_kwh": e.price_buy_eur_per_kwh,
            "price_sell_eur_per_kwh": e.price_sell_eur_per_kwh,
            "prices_buy_24h": tuple(self._prices[k : k + PRICE_WINDOW]),
        }
        if self.level in ("fuzzy", "mpc"):
            d["t_min_5h_c"] = tuple(self._t_min[k : k + BOUNDS_AHEAD + 1])
            d["ghi_w_m2"] = e.ghi_w_m2
            d["dloh_per_day"] = self._dloh
            d["fc_on_prev"] = bool(state.fc_on)
            d["el_on_prev"] = bool(state.el_on)
            d["days_to_heating_season"] = self._to_season[k]
            d["heating_season_days_left"] = self._season_left[k]
        if self.level == "mpc":
            d["t_amb_c"] = e.t_amb_c
            d["t_wall_in_c"] = state.t_wall_in_c
            d["t_wall_out_c"] = state.t_wall_out_c
            d["forecast"] = self._forecast.window(k)
        return d

    def build(self, k: int, state: PlantState) -> Observation:
        """Build the :class:`Observation` for step ``k``.

        Parameters
        ----------
        k, state
            As for :meth:`data`.

        Returns
        -------
        Observation
            The level's fields (:meth:`data`).
        """
        return Observation(self.level, self.data(k, state))

    def forecast_errors(self, steps: int) -> dict[str, float]:
        """Return the error statistics of the MPC's forecasts of steps ``0 .. steps-1``.

        See :meth:`ForecastModel.errors`.
        """
        return self._forecast.errors(steps)


def record_row(
    time_iso: str,
    k: int,
    flows: Flows,
    state: PlantState,
    command: Action,
    exo: Exogenous,
    ghi_spot: tuple[float, float],
    fallback: bool,
) -> list[Any]:
    """Assemble one timeseries row in :data:`TIMESERIES_COLUMNS` order.

    Parameters
    ----------
    time_iso : str
        ISO start time of the step.
    k : int
        Step index.
    flows : Flows
        Everything that happened in the step.
    state : PlantState
        State at the end of the step.
    command : Action
        The EMS's action before the plant clipped it (``cmd_*`` columns).
    exo : Exogenous
        The step's exogenous inputs.
    ghi_spot : tuple of (float, float)
        ``(ghi_w_m2, spot_eur_per_mwh)`` from the scenario [W/m2], [EUR/MWh]; the spot price
        is not in ``exo``, so both come together.
    fallback : bool
        The plant applied a fallback action (no valid command in time).

    Returns
    -------
    list
        The row's values.
    """
    row: list[Any] = [time_iso, k]
    row.extend(getattr(flows, f) for f in FLOW_FIELDS)
    row.extend(getattr(state, f) for f in STATE_COLUMNS)
    row.extend(getattr(command, f) for f in ACTION_FIELDS)
    row.extend((exo.t_amb_c, ghi_spot[0], exo.dhw_l_per_h, exo.t_min_c, exo.t_max_c, ghi_spot[1]))
    row.append(bool(fallback))
    return row


@dataclass
class RunResult:
    """Outputs of one run: per-step timeseries, weekly KPIs and the summary.

    Attributes
    ----------
    timeseries : pandas.DataFrame
        One row per step, :data:`TIMESERIES_COLUMNS` and any ``ems_*``/``building_*``
        columns (units in the names).
    weekly : pandas.DataFrame
        :func:`comems4build_ros.core.kpi.weekly_kpis`.
    summary : dict
        :func:`comems4build_ros.core.kpi.summarize` and the run's details.
    monthly : pandas.DataFrame or None
        :func:`comems4build_ros.core.kpi.monthly_table`, for year-round plants only.
    """

    timeseries: pd.DataFrame
    weekly: pd.DataFrame
    summary: dict[str, Any] = field(default_factory=dict)
    monthly: pd.DataFrame | None = None  # year-round plants (electrolyser or cooling) only


def is_year_round(params: PlantParams) -> bool:
    """Tell whether the plant has an electrolyser or cooling.

    Such a plant's runs get the year's KPIs and the monthly table.

    Parameters
    ----------
    params : PlantParams
        Plant parameters.

    Returns
    -------
    bool
        True with ``electrolyser.n_modules > 0`` or ``cooling.enabled``.
    """
    return params.electrolyser.n_modules > 0 or params.cooling.enabled


def evaluate_timeseries(ts: pd.DataFrame, params: PlantParams, extra: Mapping[str, Any] | None = None) -> RunResult:
    """Compute the weekly KPIs and summary of a timeseries (in-process and bag evaluation alike).

    Parameters
    ----------
    ts : pandas.DataFrame
        Per-step timeseries of a run (:data:`TIMESERIES_COLUMNS`).
    params : PlantParams
        The run's plant parameters (step, comfort sampling, H2 store, season).
    extra : mapping, optional
        Entries added to the summary as they are.

    Returns
    -------
    RunResult
        ``ts`` with its weekly table, summary and (year-round plants) monthly table.
    """
    dt_h = params.simulation.time_step_h
    sample, t0 = params.comfort.discomfort_sample, params.simulation.t_air_init_c
    weekly = kpi.weekly_kpis(ts, dt_h, sample, t0)
    summary = kpi.summarize(
        ts, weekly, params.hydrogen.loh_min, dt_h, extra=extra, e_h2_max_kwh=params.hydrogen.e_max_kwh,
        t_comfort=kpi.comfort_sample_c(ts, sample, t0),
    )
    summary["discomfort_sample"] = sample
    monthly = None
    if is_year_round(params):
        t_c = kpi.comfort_sample_c(ts, sample, t0)
        sim = params.simulation
        summary.update(kpi.year_kpis(ts, weekly, dt_h, sim.heating_season_start, sim.heating_season_end, t_c))
        summary["loh_init"] = sim.loh_init
        monthly = kpi.monthly_table(ts, dt_h, t_c)
    return RunResult(ts, weekly, summary, monthly)


def simulate(
    ems: str | Controller,
    scenario: Scenario,
    params: PlantParams,
    ems_options: Mapping[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    forecast: ForecastParams | None = None,
    building: Any = None,
    building_dir: str | Path | None = None,
) -> RunResult:
    """Run one EMS in closed loop with the plant over ``scenario.n_steps`` steps.

    Parameters
    ----------
    ems : str or Controller
        EMS name (see :data:`comems4build_ros.core.ems.REGISTRY`) or a controller object.
    scenario : Scenario
        Inputs of the run.
    params : PlantParams
        Plant parameters.
    ems_options : mapping, optional
        Options passed to the controller's constructor (with a name only).
    progress : callable, optional
        Called as ``progress(steps done, total steps)`` after every step (for a bar, see
        :mod:`comems4build_ros.run.progress`); None = silent.
    forecast : ForecastParams, optional
        Forecast settings for an MPC (default ``config/forecast.yaml``: perfect).
    building : object, optional
        The building model: None or ``"rc"`` (the paper's 4R3C, ``sec:bldg``), a
        :class:`~comems4build_ros.core.models.buildings.BuildingChoice` or its text
        (``energyplus[:IDF]``, ``fmu:PATH``); closed at the end of the run. A detailed
        model's per-step record (the heat EnergyPlus reports it received) adds
        ``building_*`` columns.
    building_dir : str or pathlib.Path, optional
        EnergyPlus's output folder (default: a temporary folder, removed).

    Returns
    -------
    RunResult
        Timeseries, weekly KPIs, summary (and monthly table for year-round plants).
    """
    t_start = _time.perf_counter()
    ctrl = make_controller(ems, params, ems_options) if isinstance(ems, str) else ems
    ctrl.reset()
    model = building_model(building, params, scenario, building_dir)
    try:
        return _simulate(ctrl, scenario, params, progress, forecast, model, t_start)
    finally:
        model.close()


def building_model(building: Any, params: PlantParams, scenario: Scenario, workdir: str | Path | None = None) -> Any:
    """Make the run's building model.

    Parameters
    ----------
    building : object
        None or ``"rc"`` (the paper's 4R3C), a model object (returned as is), or a choice
        for :func:`~comems4build_ros.core.models.buildings.make_building`.
    params : PlantParams
        Plant parameters.
    scenario : Scenario
        The run's inputs (the weather of a detailed model).
    workdir : str or pathlib.Path, optional
        Output folder of a detailed model.

    Returns
    -------
    object
        A building model with ``step``, ``initial_temperatures`` and ``close``.
    """
    from comems4build_ros.core.models.building import RCBuilding
    from comems4build_ros.core.models.buildings import make_building
    from comems4build_ros.core.models.epw import Weather

    if building is None or building == "rc":
        return RCBuilding(params.building, float(params.simulation.time_step_h))
    if hasattr(building, "step") and hasattr(building, "initial_temperatures"):
        return building
    weather = Weather(scenario.time, scenario.t_amb_c, scenario.ghi_w_m2, scenario.dhi_w_m2)
    return make_building(building, params, weather, scenario.n_steps, workdir)


#: Columns a detailed building model's step record adds to the timeseries.
BUILDING_COLUMNS = ("building_q_floor_set_w", "building_q_floor_received_w", "building_gains_w")


def _simulate(ctrl: Controller, scenario: Scenario, params: PlantParams, progress: Any,
              forecast: ForecastParams | None, model: Any, t_start: float) -> RunResult:
    """Run the closed loop of :func:`simulate` with a reset controller and an open building model."""
    plant = Plant(params, model)
    record = hasattr(model, "last") and model.name != "rc"
    brows: list[tuple[float, float, float]] = []
    exo = exogenous_series(scenario, params)
    forecast = forecast or load_forecast_settings()
    builder = ObservationBuilder(scenario, params, ctrl.info_level, exo, forecast)
    times = [t.isoformat() for t in scenario.time[: scenario.n_steps]]
    ghi = scenario.ghi_w_m2.tolist()
    spot = scenario.spot_eur_per_mwh.tolist()
    state = plant.initial_state()
    rows: list[list[Any]] = []
    infos: list[dict[str, float]] = []
    n_steps = scenario.n_steps
    ems_s = 0.0
    for k in range(n_steps):
        obs = builder.build(k, state)
        t0 = _time.perf_counter()
        action = ctrl.act(obs)
        ems_s += _time.perf_counter() - t0
        info = getattr(ctrl, "step_info", None)
        if info:
            infos.append(dict(info))
        state, flows = plant.step(state, action, exo[k])
        if record:
            rec = model.last
            brows.append((rec.q_floor_set_w, rec.q_floor_received_w, rec.gains_w))
        rows.append(record_row(times[k], k, flows, state, action, exo[k], (ghi[k], spot[k]), False))
        if progress is not None:
            progress(k + 1, n_steps)
    ts = pd.DataFrame(rows, columns=list(TIMESERIES_COLUMNS))
    if infos and len(infos) == len(ts):
        info_df = pd.DataFrame(infos).add_prefix("ems_")
        ts = pd.concat([ts, info_df], axis=1)
    if record:
        ts = pd.concat([ts, pd.DataFrame(brows, columns=list(BUILDING_COLUMNS))], axis=1)
    wall = _time.perf_counter() - t_start
    extra = {
        "ems": ctrl.name,
        "scenario": scenario.name,
        "wall_s": wall,
        "ems_s": ems_s,
        "forecast": forecast.mode if ctrl.info_level == "mpc" else None,
    }
    if ctrl.info_level == "mpc" and forecast.mode != "perfect":
        extra["forecast_errors"] = builder.forecast_errors(n_steps)
    if model.name != "rc":
        extra["building"] = model.name
        if record and brows:
            extra["building_heat_balance_max_rel"] = heat_balance_error(ts)
    if scenario.meta.get("extended"):
        extra["scenario_extended"] = dict(scenario.meta["extended"])
    return evaluate_timeseries(ts, params, extra)


def heat_balance_error(ts: pd.DataFrame) -> float:
    """Return the largest relative difference between the heat the plant gave the building and what it received.

    Per step |Q_plant - Q_received| / max(|Q_plant|, 1 W), with Q_plant = q_hp_sh_w - q_cool_w
    (what the plant's heat pump put into the floor) and Q_received the heat the detailed model
    reports it received (EnergyPlus's source-term output, hourly mean).

    Parameters
    ----------
    ts : pandas.DataFrame
        Timeseries with ``q_hp_sh_w``, ``q_cool_w`` and ``building_q_floor_received_w`` [W].

    Returns
    -------
    float
        The largest relative difference over the steps [-].
    """
    q_plant = ts["q_hp_sh_w"].to_numpy(float) - ts["q_cool_w"].to_numpy(float)
    q_in = ts["building_q_floor_received_w"].to_numpy(float)
    return float(np.max(np.abs(q_plant - q_in) / np.maximum(np.abs(q_plant), 1.0)))


def _json_default(value: Any) -> Any:
    """Convert a NumPy scalar for ``json.dumps``; refuse anything else."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


#: Files of a run directory (:func:`write_run`; ``monthly.csv`` for year-round plants only).
RUN_FILES = ("timeseries.csv", "weekly.csv", "summary.json", "monthly.csv")


def write_run(result: RunResult, out_dir: str | Path, timeseries: bool = True) -> Path:
    """Write a run's files: ``timeseries.csv`` (optional), ``weekly.csv``, ``summary.json``.

    ``monthly.csv`` too for a year-round plant. All or nothing: the files are written into
    a temporary directory inside ``out_dir`` and renamed into place only when every one was
    written (:func:`comems4build_ros.files.outputs.atomic_dir`), so a failure (e.g. a full
    disk) leaves no partial result; a ``timeseries.csv`` of an earlier run in ``out_dir`` is
    removed when this one writes none. Non-finite summary values are written as ``null``.

    Parameters
    ----------
    result : RunResult
        The run's outputs.
    out_dir : str or pathlib.Path
        The run directory.
    timeseries : bool, optional
        Write ``timeseries.csv`` (default True).

    Returns
    -------
    pathlib.Path
        ``out_dir``.
    """
    out = Path(out_dir)
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in result.summary.items()}
    with atomic_dir(out, replaces=RUN_FILES) as tmp:  # no older timeseries.csv stays beside a run without one
        if timeseries:
            result.timeseries.to_csv(tmp / "timeseries.csv", index=False)
        result.weekly.to_csv(tmp / "weekly.csv", index=False)
        if result.monthly is not None:
            result.monthly.to_csv(tmp / "monthly.csv", index=False)
        (tmp / "summary.json").write_text(json.dumps(clean, indent=2, default=_json_default) + "\n", encoding="utf-8")
    return out
