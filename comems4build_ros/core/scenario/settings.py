"""Settings of the default scenario generator (``config/scenario.yaml``, section ``scenario``).

The file is a ROS 2 parameter file (``/**: ros__parameters: scenario: {...}``), read with
:func:`comems4build_ros.core.config.read_ros_params` and checked with
:func:`comems4build_ros.core.config.parse_model`, so an invalid value is reported with the file
and the parameter path.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from datetime import date, datetime
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, Field, model_validator

from comems4build_ros.core.config import ConfigError, Section, config_dir, parse_model, read_param_section, set_dotted

HOURS_PER_DAY = 24


def _local(value: datetime) -> datetime:
    """Accept a naive time (the site's clock); refuse one with a UTC offset."""
    if value.tzinfo is not None:
        raise ValueError("a local time of the site: give it without UTC offset")
    return value


#: A time of the site's clock (naive ``datetime``; the site's time zone gives its UTC offset).
LocalTime = Annotated[datetime, AfterValidator(_local)]


class _Section(Section):
    """A generator section: the parameter rule of :class:`~comems4build_ros.core.config.Section`."""


class Episode(_Section):
    """A weather episode: daily-mean anomaly [K] and wind offset between two local dates (inclusive).

    Attributes
    ----------
    start, end : datetime.date
        First and last local day of the episode.
    anomaly_k : float
        Offset of the daily mean temperature [K].
    wind : float
        Offset of the latent daily wind index [-].
    """

    start: date
    end: date
    anomaly_k: float
    wind: float = 0.0

    @model_validator(mode="after")
    def _check(self) -> Episode:
        if self.end < self.start:
            raise ValueError(f"episode end {self.end} before start {self.start}")
        return self


class TemperatureParams(_Section):
    """Ambient temperature model [degC, K].

    Daily mean = ``mean_c`` + episode anomaly + ``wind_k`` * wind index + AR(1) anomaly;
    hourly value = daily means interpolated between noons + diurnal cycle + AR(1) noise.
    Values and sources (DWD Rheinstetten statistics): ``config/scenario.yaml``.

    Attributes
    ----------
    mean_c : float
        Climate mean [degC].
    ar_phi, ar_sigma_k : float
        AR(1) coefficient [-] and innovation standard deviation [K] of the daily anomaly.
    wind_k : float
        Warming per unit of the wind index [K].
    amp_overcast_k, amp_clear_k : float
        Daily range = ``amp_overcast_k + amp_clear_k * kc_day`` [K].
    t_min_hour, t_max_hour : float
        Local hours of the diurnal minimum and maximum [h].
    noise_phi, noise_sigma_k : float
        AR(1) coefficient [-] and standard deviation [K] of the hourly noise.
    episodes : list of Episode
        Configured warm and cold spells.
    episode_ramp_days : int
        Length of the linear ramp into and out of an episode [d].
    """

    mean_c: float
    ar_phi: float = Field(ge=0, lt=1)
    ar_sigma_k: float = Field(ge=0)
    wind_k: float
    amp_overcast_k: float = Field(ge=0)
    amp_clear_k: float = Field(ge=0)
    t_min_hour: float = Field(ge=0, lt=24)
    t_max_hour: float = Field(ge=0, lt=24)
    noise_phi: float = Field(ge=0, lt=1)
    noise_sigma_k: float = Field(ge=0)
    episodes: list[Episode] = []
    episode_ramp_days: int = Field(ge=0)

    @model_validator(mode="after")
    def _check(self) -> TemperatureParams:
        if self.t_max_hour <= self.t_min_hour:
            raise ValueError("t_max_hour must be later than t_min_hour")
        return self


class WindParams(_Section):
    """Latent daily wind index (dimensionless).

    Attributes
    ----------
    ar_phi : float
        AR(1) coefficient of the daily index [-].
    """

    ar_phi: float = Field(ge=0, lt=1)


class SolarParams(_Section):
    """Clear-sky model and stochastic cloudiness.

    Attributes
    ----------
    clearsky_model : str
        pvlib clear-sky model (``ineichen``, ``haurwitz``, ``simplified_solis``).
    p_overcast_to_fair, p_fair_to_overcast : float
        Daily transition probabilities of the two-state Markov chain [-].
    overcast_kc_mean, fair_kc_mean : float
        Mean daily clear-sky index of each state [-].
    kc_concentration : float
        Sum a + b of the Beta distribution of the daily index [-].
    wind_kc : float
        Lowering of the daily index per unit of the wind index [-].
    hourly_phi, hourly_sigma : float
        AR(1) coefficient and relative standard deviation of the hourly variation [-].
    kc_max : float
        Cap of the clear-sky index (cloud enhancement) [-].
    """

    clearsky_model: str
    p_overcast_to_fair: float = Field(gt=0, le=1)
    p_fair_to_overcast: float = Field(gt=0, le=1)
    overcast_kc_mean: float = Field(gt=0, lt=1)
    fair_kc_mean: float = Field(gt=0, lt=1)
    kc_concentration: float = Field(gt=0)
    wind_kc: float = Field(ge=0)
    hourly_phi: float = Field(ge=0, lt=1)
    hourly_sigma: float = Field(ge=0)
    kc_max: float = Field(gt=0)

    @model_validator(mode="after")
    def _check(self) -> SolarParams:
        if self.clearsky_model not in ("ineichen", "haurwitz", "simplified_solis"):
            raise ValueError(f"clearsky_model '{self.clearsky_model}' is not a pvlib clear-sky model")
        return self


class PriceParams(_Section):
    """Day-ahead spot price model [EUR/MWh].

    Daily level = fuel-cost level (interpolated between anchors) times a residual-load
    factor; hourly price = level * (1 + ``shape_gain`` * s(h)) + noise. Values and sources
    (ENTSO-E DE-LU statistics): ``config/scenario.yaml``.

    Attributes
    ----------
    level_dates : list of datetime.date
        Anchor dates of the fuel-cost level (strictly increasing).
    level_eur_per_mwh : list of float
        Level at each anchor [EUR/MWh].
    wind_coef, calm_coef : float
        Lowering of the residual-load factor per unit of positive / negative wind [-].
    wind_saturation : float
        s of ``s * tanh(W / s)`` for the wind index [-].
    temp_coef : float
        Rise of the factor per K below the climate mean [1/K].
    offday_coef : float
        Change of the factor on weekends and public holidays [-].
    ar_phi, ar_sigma : float
        AR(1) coefficient and innovation standard deviation of the daily remainder [-].
    hour_profile_eur_per_mwh : list of float
        Hour-of-day mean prices, 24 values (its shape is used) [EUR/MWh].
    shape_gain : float
        Gain on the relative hourly shape s(h) [-].
    noise_phi : float
        AR(1) coefficient of the hourly noise [-].
    noise_abs_eur_per_mwh : float
        Absolute part of the noise standard deviation [EUR/MWh].
    noise_rel : float
        Part of the noise standard deviation relative to the daily level [-].
    negative_compression : float
        Factor on negative prices [-].
    """

    level_dates: list[date]
    level_eur_per_mwh: list[float]
    wind_coef: float
    calm_coef: float
    wind_saturation: float = Field(gt=0)
    temp_coef: float
    offday_coef: float
    ar_phi: float = Field(ge=0, lt=1)
    ar_sigma: float = Field(ge=0)
    hour_profile_eur_per_mwh: list[float]
    shape_gain: float = Field(ge=0)
    noise_phi: float = Field(ge=0, lt=1)
    noise_abs_eur_per_mwh: float = Field(ge=0)
    noise_rel: float = Field(ge=0)
    negative_compression: float = Field(ge=0, le=1)

    @model_validator(mode="after")
    def _check(self) -> PriceParams:
        if len(self.level_dates) != len(self.level_eur_per_mwh) or not self.level_dates:
            raise ValueError("level_dates and level_eur_per_mwh need the same non-zero length")
        if any(b <= a for a, b in zip(self.level_dates, self.level_dates[1:])):
            raise ValueError("level_dates must increase strictly")
        if len(self.hour_profile_eur_per_mwh) != HOURS_PER_DAY:
            raise ValueError("hour_profile_eur_per_mwh needs 24 values")
        if sum(self.hour_profile_eur_per_mwh) <= 0:
            raise ValueError("hour_profile_eur_per_mwh must have a positive mean")
        return self


class LoadParams(_Section):
    """Appliance load model [W].

    Expected load = ``annual_kwh`` * BDEW H0 dynamisation * day-type shape; split into a
    steady base, a log-normal activity part and appliance cycles. Values and sources:
    ``config/scenario.yaml``.

    Attributes
    ----------
    annual_kwh : float
        Annual appliance energy [kWh/a].
    dynamisation_coef : list of float
        Coefficients c_i of the BDEW dynamisation polynomial ``F(d) = sum c_i d^i``.
    shape_workday, shape_offday : list of float
        Relative hourly shapes of workdays and off days, 24 values each [-].
    base_share : float
        Share of the expected load that is steady [-].
    noise_phi, noise_sigma : float
        AR(1) coefficient and standard deviation of the log of the activity part [-].
    cycles_per_day : float
        Mean appliance runs per day (Poisson) [1/d].
    cycle_kwh : float
        Energy of one run [kWh].
    cycle_hours : int
        Duration of one run [h].
    """

    annual_kwh: float = Field(gt=0)
    dynamisation_coef: list[float]
    shape_workday: list[float]
    shape_offday: list[float]
    base_share: float = Field(ge=0, lt=1)
    noise_phi: float = Field(ge=0, lt=1)
    noise_sigma: float = Field(ge=0)
    cycles_per_day: float = Field(ge=0)
    cycle_kwh: float = Field(ge=0)
    cycle_hours: int = Field(ge=1, le=12)

    @model_validator(mode="after")
    def _check(self) -> LoadParams:
        for name in ("shape_workday", "shape_offday"):
            shape = getattr(self, name)
            if len(shape) != HOURS_PER_DAY or min(shape) < 0 or sum(shape) <= 0:
                raise ValueError(f"{name} needs 24 non-negative values with a positive sum")
        return self


class DHWDrawParams(_Section):
    """Hot-water draw profile via OpenDHW (the DHWCalc method) [l/h].

    Attributes
    ----------
    litres_per_day : float
        Mean daily draw (``sec:parameters``: 200 l/day) [l/d].
    weekend_weekday_factor : float
        Off-day draws over workday draws (DHWCalc) [-].
    categories : int
        DHWCalc draw-off categories, 1 or 4.
    step_s : int
        Generation step, dividing one hour [s].
    """

    litres_per_day: float = Field(gt=0)
    weekend_weekday_factor: float = Field(gt=0)
    categories: int
    step_s: int

    @model_validator(mode="after")
    def _check(self) -> DHWDrawParams:
        if self.categories not in (1, 4):
            raise ValueError("categories must be 1 or 4 (DHWcalc)")
        if self.step_s not in (60, 300, 600, 900, 1800, 3600):
            raise ValueError("step_s must divide 3600 and be one of 60, 300, 600, 900, 1800, 3600")
        return self


class ScenarioParams(_Section):
    """The ``scenario`` section of ``config/scenario.yaml``: the synthetic generator.

    Attributes
    ----------
    seed : int
        Default random seed.
    start : datetime.datetime
        First hour, local time of the site.
    weeks : int
        Configured length [weeks].
    lookahead_h : int
        Hours generated after the run for the day-ahead window [h].
    temperature : TemperatureParams
    wind : WindParams
    solar : SolarParams
    price : PriceParams
    load : LoadParams
    dhw : DHWDrawParams
    """

    seed: int = Field(ge=0)
    start: LocalTime
    weeks: int = Field(ge=1)
    lookahead_h: int = Field(ge=0)
    temperature: TemperatureParams
    wind: WindParams
    solar: SolarParams
    price: PriceParams
    load: LoadParams
    dhw: DHWDrawParams


class MeasuredTemperatureParams(_Section):
    """How the measured temperature record is extended past its last hour.

    Attributes
    ----------
    file : str
        DWD hourly ``TT_TU`` file (package data or absolute path).
    fill : str
        Fill method, one of :data:`FILL_METHODS`.
    fill_reference_days : int
        Measured days the fill refers to [d].
    fill_seam_h : int
        Hours over which the seam offset of ``repeat`` decays [h].
    """

    file: str
    fill: str
    fill_reference_days: int = Field(ge=1, le=60)
    fill_seam_h: int = Field(ge=0, le=240)

    @model_validator(mode="after")
    def _check(self) -> MeasuredTemperatureParams:
        if self.fill not in FILL_METHODS:
            raise ValueError(f"fill '{self.fill}' is not one of {', '.join(FILL_METHODS)}")
        return self


class MeasuredParams(_Section):
    """The ``measured`` section of ``config/scenario.yaml``: the embedded default scenario.

    Measured prices, temperature and hot-water draws of the paper's winter (package data,
    ``comems4build_ros/data``), radiation and appliance load modelled with the generator's
    ``solar`` and ``load`` settings and the seed given here.

    Attributes
    ----------
    start : datetime.datetime
        First hour, local time of the site.
    weeks : int
        Default run length [weeks].
    lookahead_h : int
        Hours of data kept after the run for the day-ahead window [h].
    seed : int
        Seed of the modelled radiation and load.
    prices_file, prices_column : str
        ENTSO-E day-ahead price file and its price column [EUR/MWh].
    temperature : MeasuredTemperatureParams
    dhw_file : str
        DHWcalc file at 1 h resolution [l/h].
    dhw_day1_weekday : int
        Weekday of the DHWcalc file's day 1 (0 = Monday).
    kc_from_temperature_amplitude : bool
        Re-order the daily clear-sky indices by the measured daily temperature amplitude.
    """

    start: LocalTime
    weeks: int = Field(ge=1)
    lookahead_h: int = Field(ge=0)
    seed: int = Field(ge=0)
    prices_file: str
    prices_column: str
    temperature: MeasuredTemperatureParams
    dhw_file: str
    dhw_day1_weekday: int = Field(ge=0, le=6)
    kc_from_temperature_amplitude: bool


#: Methods that fill the hours after the end of the measured temperature record.
FILL_METHODS = ("repeat", "synthetic")


def _section(path: str | Path | None, name: str, overrides: Mapping[str, Any] | None) -> tuple[dict, str]:
    """Return section ``name`` of a scenario parameter file with dotted ``overrides`` applied, and its label."""
    path = Path(path) if path is not None else default_scenario_file()
    section = copy.deepcopy(read_param_section(path, name))
    for key, value in (overrides or {}).items():
        set_dotted(section, str(key), value)
    label = f"{path} + overrides ({', '.join(f'{name}.{k}' for k in overrides)})" if overrides else str(path)
    return section, label


def load_measured_settings(
    path: str | Path | None = None, overrides: Mapping[str, Any] | None = None, section: str = "measured"
) -> MeasuredParams:
    """Read and check a measured-data section of a parameter file (default ``config/scenario.yaml``).

    ``section``: ``measured`` (the paper's winter, ``--scenario default``) or
    ``measured_year`` (the year around it, ``--scenario year``).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The parameter file (default ``config/scenario.yaml``).
    overrides : mapping, optional
        Dotted keys inside the section (``{"temperature.fill": "synthetic"}``).
    section : str, optional
        ``measured`` or ``measured_year``.

    Returns
    -------
    MeasuredParams
        The validated section.

    Raises
    ------
    ConfigError
        Naming the file and the parameter if the section is missing or invalid.
    """
    data, label = _section(path, section, overrides)
    return parse_model(MeasuredParams, data, label)


def default_scenario_file() -> Path:
    """Return the path of the default scenario settings, ``config/scenario.yaml``."""
    return config_dir() / "scenario.yaml"


def load_scenario_settings(
    path: str | Path | None = None, overrides: Mapping[str, Any] | None = None
) -> ScenarioParams:
    """Read and check the ``scenario`` section (the synthetic generator) of a parameter file.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        The parameter file (default ``config/scenario.yaml``).
    overrides : mapping, optional
        Dotted keys inside the section (``{"load.annual_kwh": 4000}``).

    Returns
    -------
    ScenarioParams
        The validated section.

    Raises
    ------
    ConfigError
        Naming the file and the parameter if the section is missing or invalid.
    """
    section, label = _section(path, "scenario", overrides)
    return parse_model(ScenarioParams, section, label)


def split_overrides(overrides: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """Split dotted overrides ``{"scenario.load.annual_kwh": 4000, "measured.seed": 3}`` by section.

    Parameters
    ----------
    overrides : mapping or None
        Keys ``<section>.<dotted key>``.

    Returns
    -------
    dict of str to dict
        ``scenario``, ``measured`` and ``measured_year`` -> their overrides without the
        section prefix (empty where none is given).

    Raises
    ------
    ConfigError
        For a key outside the sections ``scenario``, ``measured`` and ``measured_year``.
    """
    out: dict[str, dict[str, Any]] = {"scenario": {}, "measured": {}, "measured_year": {}}
    for key, value in (overrides or {}).items():
        head, _, rest = str(key).partition(".")
        if head not in out or not rest:
            raise ConfigError(f"scenario override '{key}': must start with 'scenario.', 'measured.' or "
                              "'measured_year.'")
        out[head][rest] = value
    return out
