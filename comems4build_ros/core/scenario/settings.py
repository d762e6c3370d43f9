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
    if value.tzinfo is not None:
        raise ValueError("a local time of the site: give it without UTC offset")
    return value


#: A time of the site's clock (naive ``datetime``; the site's time zone gives its UTC offset).
LocalTime = Annotated[datetime, AfterValidator(_local)]


class _Section(Section):
    """A generator section: the parameter rule of :class:`~comems4build_ros.core.config.Section`."""


class Episode(_Section):
    """A weather episode: daily-mean anomaly [K] and wind offset between two local dates (inclusive)."""

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
    """Ambient temperature model [degC, K]."""

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
    """Latent daily wind index (dimensionless)."""

    ar_phi: float = Field(ge=0, lt=1)


class SolarParams(_Section):
    """Clear-sky model and stochastic cloudiness."""

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
    """Day-ahead spot price model [EUR/MWh]."""

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
    """Appliance load model [W]."""

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
    """Hot-water draw profile via OpenDHW [l/h]."""

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
    """The ``scenario`` section of ``config/scenario.yaml``."""

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
    """How the measured temperature record is extended past its last hour."""

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
    """Section ``name`` of a scenario parameter file with dotted ``overrides`` applied, and its label."""
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

    ``overrides`` are dotted keys inside the section (``{"temperature.fill": "synthetic"}``).

    Raises
    ------
    ConfigError
        Naming the file and the parameter if the section is missing or invalid.
    """
    data, label = _section(path, section, overrides)
    return parse_model(MeasuredParams, data, label)


def default_scenario_file() -> Path:
    """Path of the default ``scenario.yaml``."""
    return config_dir() / "scenario.yaml"


def load_scenario_settings(
    path: str | Path | None = None, overrides: Mapping[str, Any] | None = None
) -> ScenarioParams:
    """Read and check the ``scenario`` section (the synthetic generator) of a parameter file.

    ``overrides`` are dotted keys inside the section (``{"load.annual_kwh": 4000}``).

    Raises
    ------
    ConfigError
        Naming the file and the parameter if the section is missing or invalid.
    """
    section, label = _section(path, "scenario", overrides)
    return parse_model(ScenarioParams, section, label)


def split_overrides(overrides: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """Dotted overrides ``{"scenario.load.annual_kwh": 4000, "measured.seed": 3}`` per section.

    Raises
    ------
    ConfigError
        For a key outside the sections ``scenario`` and ``measured``.
    """
    out: dict[str, dict[str, Any]] = {"scenario": {}, "measured": {}, "measured_year": {}}
    for key, value in (overrides or {}).items():
        head, _, rest = str(key).partition(".")
        if head not in out or not rest:
            raise ConfigError(f"scenario override '{key}': must start with 'scenario.', 'measured.' or "
                              "'measured_year.'")
        out[head][rest] = value
    return out
