"""Parameter files: loading, merging and validation.

All parameters live in ``config/*.yaml`` in the ROS 2 parameter-file form::

    /**:                       # or a node name such as plant_sim
      ros__parameters:
        battery:
          e_max_kwh: 6.5

The same files are passed to the ROS nodes with ``--ros-args --params-file``. This
module reads them without rclpy, merges several files (later ones win, key by key) and
validates the plant sections against :class:`PlantParams`. An invalid file raises
:class:`ConfigError` naming the file, the parameter path and the rule broken.

Other packages of the project (scenario generator, controllers) read their own sections
with :func:`read_ros_params` and validate them with :func:`validate`.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator

from comems4build_ros.files.inputs import InputFileError, load_yaml_file, load_yaml_text, path_kind
from comems4build_ros.files.paths import PACKAGE, SOURCE_ROOT, shared_path

__all__ = ["path_kind"]  # re-exported: the check of an input path

#: Hours per second, seconds per hour and similar named conversion factors.
SECONDS_PER_HOUR = 3600.0
W_PER_KW = 1000.0


class ConfigError(ValueError):
    """A parameter file is unreadable or a parameter breaks a rule."""


def config_dir() -> Path:
    """Directory of the default parameter files.

    The source tree's ``config/`` when running from a checkout, else the installed
    ``<prefix>/share/comems4build_ros/config``.
    """
    found = shared_path("config", "config")
    if found is None or not found.is_dir():
        raise ConfigError(f"cannot find the config directory ({SOURCE_ROOT / 'config'} or "
                          f"{Path(sys.prefix) / 'share' / PACKAGE / 'config'})")
    return found


#: Embedded scenarios whose plant differs from ``config/plant.yaml``: scenario -> the plant
#: parameter file merged over it before any user file (``--config``) and ``--set``.
SCENARIO_PLANT_FILES = {"year": "year.yaml"}


def scenario_config_files(scenario: str | Path, files: Iterable[str | Path] = ()) -> list[str]:
    """``files`` with the plant file of an embedded ``scenario`` in front (once; absolute path).

    ``--scenario year`` runs the year-round plant (``config/year.yaml``: electrolyser,
    cooling, a nearly empty store at the start); every other scenario the files as given.
    """
    out = [str(f) for f in files]
    name = SCENARIO_PLANT_FILES.get(str(scenario))
    if name is None:
        return out
    path = str((config_dir() / name).resolve())
    return out if any(Path(f).resolve() == Path(path) for f in out) else [path, *out]


def default_plant_file() -> Path:
    """Path of the default ``plant.yaml``."""
    return config_dir() / "plant.yaml"


def load_yaml(path: str | Path, what: str, error: type[Exception] = ConfigError) -> Any:
    """Parse a YAML file through the project's one YAML loader (:func:`comems4build_ros.files.inputs.load_yaml_file`).

    ``error`` names the file (and ``what`` it is) when that fails: a directory, a device, a
    file that is not UTF-8 text (e.g. binary), invalid YAML, a document over the loader's
    limits (size, depth, aliases), a key that is not a string or is given twice, each with
    the line and column.
    """
    try:
        return load_yaml_file(path, what)
    except InputFileError as exc:
        raise error(str(exc)) from None


def check_input_file(path: str | Path, what: str) -> Path:
    """``path`` if it is a readable regular file, else :class:`ConfigError` naming ``what`` (e.g. ``--config``)."""
    kind = path_kind(path)
    if kind:
        raise ConfigError(f"{what} {path}: {kind}")
    return Path(path)


def read_ros_params(path: str | Path, node: str | None = None) -> dict[str, Any]:
    """Read a ROS 2 parameter file and return the merged ``ros__parameters`` dict.

    Parameters
    ----------
    path : file name
    node : node name whose section is merged over the ``/**`` section; ``None`` merges
        every section in file order.

    Raises
    ------
    ConfigError
        If the file cannot be read or is not in parameter-file form.
    """
    path = Path(path)
    doc = load_yaml(path, "parameter file")
    if not isinstance(doc, Mapping):
        raise ConfigError(f"{path}: expected '<node>: ros__parameters: ...' at the top level")
    merged: dict[str, Any] = {}
    for key, section in doc.items():
        if not isinstance(section, Mapping) or "ros__parameters" not in section:
            raise ConfigError(f"{path}: section '{key}' has no 'ros__parameters' mapping")
        if node is not None and key not in ("/**", node, f"/{node}"):
            continue
        params = section["ros__parameters"]
        if not isinstance(params, Mapping):
            raise ConfigError(f"{path}: '{key}.ros__parameters' must be a mapping")
        deep_merge(merged, params)
    return merged


def read_param_section(path: str | Path, name: str) -> dict[str, Any]:
    """Section ``name`` (a mapping) of the merged ``ros__parameters`` of the parameter file ``path``.

    Raises
    ------
    ConfigError
        Naming the file: unreadable, not in parameter-file form, or without the section.
    """
    data = read_ros_params(path).get(name)
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: no '{name}' section (a mapping) under ros__parameters")
    return dict(data)


def deep_merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """Merge ``extra`` into ``base`` in place, recursing into mappings; return ``base``."""
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            deep_merge(base[key], value)
        elif isinstance(value, Mapping):
            base[key] = deep_merge({}, value)
        else:
            base[key] = value
    return base


def set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``data['a']['b'] = value`` for ``dotted='a.b'`` (creating mappings)."""
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise ConfigError(f"parameter '{dotted}': '{key}' is not a section")
    node[keys[-1]] = value


M = TypeVar("M", bound=BaseModel)


def parse_assignments(items: Iterable[str], what: str) -> dict[str, Any]:
    """``["a.b=1.5", "c=x"]`` -> ``{"a.b": 1.5, "c": "x"}``, each value read as YAML (``--set``, ``--ems-option``).

    Empty items are skipped (a ROS string-array parameter's empty default).

    Raises
    ------
    ConfigError
        Naming ``what`` (the option or node parameter) and the item, for an item that is not
        ``KEY=VALUE`` or a value that is not valid YAML (``[1`` without its bracket).
    """
    out: dict[str, Any] = {}
    for item in items:
        if not str(item).strip():
            continue
        key, sep, value = str(item).partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"{what} '{item}' is not KEY=VALUE")
        try:
            out[key.strip()] = load_yaml_text(value, f"{what} '{item}'")
        except InputFileError as exc:
            raise ConfigError(f"{what} '{item}': the value is not valid YAML ({exc.problem})") from None
    return out


def check_known_keys(data: Mapping[str, Any], known: Iterable[str], where: str) -> None:
    """Raise :class:`ConfigError` naming the first key of ``data`` that is not in ``known``.

    For option mappings read without a pydantic model (the fuzzy rule-base files and their
    overrides): a misspelt key is refused instead of silently ignored.
    """
    import difflib

    known = list(known)
    for key in data:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(f"{where}: unknown parameter '{key}' ({hint}known: {', '.join(known)})")


def finite_number(value: Any, where: str) -> float:
    """``value`` as a float; :class:`ConfigError` naming ``where`` for a boolean, text, inf or NaN."""
    import math

    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def validate(model: type[M], data: Mapping[str, Any], source: str) -> M:
    """Validate ``data`` against a pydantic model; errors name source and parameter."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        lines = []
        for err in exc.errors():
            loc = ".".join(str(p) for p in err["loc"])
            msg = err["msg"].removeprefix("Value error, ")
            if err["type"] == "extra_forbidden":
                msg = "unknown parameter"
            lines.append(f"{source}: parameter '{loc}': {msg}" if loc else f"{source}: {msg}")
        raise ConfigError("\n".join(lines)) from None


def load_section(model: type[M], path: str | Path | None, default_file: str, section: str,
                 overrides: Mapping[str, Any] | None = None) -> M:
    """Section ``section`` of the parameter file ``path`` (``None``: ``config/<default_file>``)
    with ``overrides`` (top-level keys) applied, validated as ``model``.

    Raises
    ------
    ConfigError
        Naming the file and the parameter that is missing or invalid, or the missing section.
    """
    path = Path(path) if path else config_dir() / default_file
    data = read_param_section(path, section)
    data.update(overrides or {})
    return validate(model, data, str(path))


class Section(BaseModel):
    """A parameter section: unknown keys, booleans as numbers and inf/NaN are refused.

    The one rule for every validated parameter set: the plant sections here and the
    controllers' options (``config/rbc.yaml``, ``config/mpc.yaml``), from files, ``--set``,
    ``--config`` and ``--ems-option`` alike.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """``e_max_kwh: true`` must not become 1.0 (YAML ``true``/``yes``/``on`` are booleans).

        Text is parsed as a number (PyYAML reads ``7.27e6`` without a sign in the exponent as
        text); text that is not a number is refused by the field's type.
        """
        field = cls.model_fields.get(info.field_name or "")
        if field is None or field.annotation is bool:
            return value
        items = value if isinstance(value, list | tuple) else [value]
        if any(isinstance(v, bool) for v in items):
            raise ValueError(f"expected a number, got the boolean {value!r}")
        return value


Pos = Field(gt=0)
NonNeg = Field(ge=0)
Frac = Field(ge=0, le=1)


def Phys(lo: float, hi: float, lo_open: bool = False) -> Any:  # noqa: N802 (reads as a field type, like Field)
    """A physical range ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``) of a parameter.

    The ranges bound what a residential building and its devices can have, generously (a
    decade or more beyond the largest shipped or studied value), so that a value no
    building has (a room air capacity of 1e-300 J/K, a sell price of 1e300 EUR/kWh) is
    refused naming the parameter instead of surfacing later as a non-finite state or a
    solver that finds nothing.
    """
    return Field(gt=lo, le=hi) if lo_open else Field(ge=lo, le=hi)


#: Largest electrical power of one device of the house [W] (1 MW: far beyond any residential device).
P_MAX_W = 1.0e6
#: Largest price or cost per kWh [EUR/kWh] (day-ahead prices reached 0.87 EUR/kWh in 2022).
PRICE_MAX_EUR_PER_KWH = 10.0


class SimulationParams(Section):
    """Run settings: step [h], horizon [h], H2 season [weeks] and initial states."""

    #: Step [h]: the scenarios have 1 h rows (paper sec:parameters), a run checks the match;
    #: at most a day, since the day-based rules (``eq:deltaLOH``, forecasts) count steps per day.
    time_step_h: float = Phys(0, 24, lo_open=True)
    horizon_h: int = Field(gt=0, le=168)
    season_weeks: float = Phys(0, 53, lo_open=True)
    soc_init: float = Frac
    loh_init: float = Frac
    t_air_init_c: float = Phys(-30, 50)
    v_dhw_init_l: float = Phys(0, 1.0e5)
    #: Heating season of a year-round run, local ``MM-DD`` dates (end exclusive): the FC's
    #: daily H2 budget (``eq:deltaLOH``) is spread over it, the electrolyser fills the store
    #: before it (only used when an electrolyser is installed).
    heating_season_start: str = Field(default="12-01", pattern=r"^\d\d-\d\d$")
    heating_season_end: str = Field(default="03-01", pattern=r"^\d\d-\d\d$")
    #: LOH the store should hold at the end of the heating season (year-round runs) [-].
    loh_season_end: float = Field(default=0.0, ge=0, le=1)

    @model_validator(mode="after")
    def _check_season(self) -> SimulationParams:
        for name in ("heating_season_start", "heating_season_end"):
            month, day = (int(x) for x in getattr(self, name).split("-"))
            if not (1 <= month <= 12 and 1 <= day <= 28):
                raise ValueError(f"{name} '{getattr(self, name)}': month 01..12, day 01..28")
        if self.heating_season_start == self.heating_season_end:
            raise ValueError("heating_season_start and heating_season_end must differ")
        return self


class SiteParams(Section):
    """Location of the house (degrees, metres, IANA time zone)."""

    latitude_deg: float = Field(ge=-90, le=90)
    longitude_deg: float = Field(ge=-180, le=180)
    altitude_m: float = Phys(-500, 9000)
    timezone: str

    @field_validator("timezone")
    @classmethod
    def _known_zone(cls, value: str) -> str:
        """An IANA time zone name the tz database knows (e.g. ``Europe/Berlin``)."""
        import zoneinfo

        try:
            zoneinfo.ZoneInfo(value)
        except (zoneinfo.ZoneInfoNotFoundError, ValueError):
            raise ValueError(f"unknown IANA time zone '{value}' (e.g. Europe/Berlin)") from None
        return value


class PVParams(Section):
    """PV array, ``eq:power_pv``."""

    n_modules: int = Field(ge=0, le=10_000)
    a_module_m2: float = Phys(0, 10, lo_open=True)
    eta_stc: float = Phys(0, 0.5)
    eta_lt: float = Frac
    eta_t_per_k: float = Phys(0, 0.02)
    noct_c: float = Phys(20, 80)
    t_stc_c: float = Phys(15, 35)
    tilt_deg: float = Field(ge=0, le=90)
    azimuth_deg: float = Field(ge=0, le=360)
    albedo: float = Frac
    sky_model: Literal["isotropic", "klucher", "haydavies", "reindl", "king", "perez"] = "isotropic"


class BatteryParams(Section):
    """Battery energy storage, ``eq:batt_soc`` .. ``eq:s_summ``."""

    e_max_kwh: float = Phys(0, 1.0e4, lo_open=True)
    p_ch_max_w: float = Phys(0, P_MAX_W)
    p_d_max_w: float = Phys(0, P_MAX_W)
    p_ch_min_w: float = Phys(0, P_MAX_W)
    p_d_min_w: float = Phys(0, P_MAX_W)
    eta_ch: float = Phys(0.5, 1)
    eta_d: float = Phys(0.5, 1)
    soc_min: float = Frac
    soc_max: float = Frac

    @model_validator(mode="after")
    def _check(self) -> BatteryParams:
        if self.soc_min >= self.soc_max:
            raise ValueError(f"soc_min ({self.soc_min}) must be below soc_max ({self.soc_max})")
        if self.p_ch_min_w > self.p_ch_max_w:
            raise ValueError("p_ch_min_w must not exceed p_ch_max_w")
        if self.p_d_min_w > self.p_d_max_w:
            raise ValueError("p_d_min_w must not exceed p_d_max_w")
        return self


class FuelCellParams(Section):
    """PEM fuel cell, ``eq:molar_flows`` .. ``eq:FC_sys_efficiency``."""

    p_max_w: float = Phys(0, P_MAX_W, lo_open=True)
    p_nom_w: float = Phys(0, P_MAX_W, lo_open=True)
    p_min_w: float = Phys(0, P_MAX_W)
    zeta: float = Field(gt=0, le=1)
    eta_sys: float = Field(gt=0, le=1)
    n_cells: int = Field(gt=0, le=1000)
    e_ocv_v: float = Phys(0.5, 1.25)  # [V per cell]: below the reversible 1.229 V at 25 degC
    a_tafel_v: float = Phys(0, 0.5)
    i_tafel_a: float = Phys(0, 1000, lo_open=True)
    r_ohm_ohm: float = Phys(0, 1)
    eta_el_mpc: float = Field(gt=0, lt=1)

    @model_validator(mode="after")
    def _check(self) -> FuelCellParams:
        if self.p_min_w > self.zeta * self.p_max_w:
            raise ValueError(
                f"p_min_w ({self.p_min_w}) must not exceed zeta * p_max_w ({self.zeta * self.p_max_w})"
            )
        return self


class HydrogenParams(Section):
    """Hydrogen store, ``eq:LOH`` (energy content at LHV)."""

    e_max_kwh: float = Phys(0, 1.0e6, lo_open=True)
    loh_min: float = Frac
    loh_max: float = Frac

    @model_validator(mode="after")
    def _check(self) -> HydrogenParams:
        if self.loh_min >= self.loh_max:
            raise ValueError(f"loh_min ({self.loh_min}) must be below loh_max ({self.loh_max})")
        return self


class ElectrolyserParams(Section):
    """Electrolyser (EL) modules filling the H2 store (:mod:`comems4build_ros.core.models.electrolyser`).

    Per module: electrical power ``p_el_points_w`` [W] of stack and balance of plant at the
    H2 outputs ``load_points`` (fractions of ``h2_rated_nl_per_h``; the first is the
    minimal load, the last 1.0), standby draw [W] while installed and off, the H2 lost
    in a start [h of production], compression from ``p_out_bar`` to ``p_store_bar`` with an
    isothermal efficiency, and the share of the stack's waste heat recovered into the DHW
    tank. ``n_modules = 0``: no electrolyser (the paper's plant).
    """

    n_modules: int = Field(ge=0, le=100)
    h2_rated_nl_per_h: float = Phys(0, 1.0e6, lo_open=True)
    load_points: list[float]
    p_el_points_w: list[float]
    p_standby_w: float = Phys(0, 1.0e4)
    start_lost_h: float = NonNeg
    p_out_bar: float = Phys(0, 1000, lo_open=True)
    p_store_bar: float = Phys(0, 1000, lo_open=True)
    t_compression_c: float = Phys(-40, 100)
    eta_compressor: float = Field(gt=0, le=1)
    heat_recovery: float = Frac

    @model_validator(mode="after")
    def _check(self) -> ElectrolyserParams:
        n = len(self.load_points)
        if n < 2 or len(self.p_el_points_w) != n:
            raise ValueError("load_points and p_el_points_w need the same length (>= 2)")
        if not 0 < self.load_points[0] or self.load_points[-1] != 1.0:
            raise ValueError("load_points must start above 0 and end at 1.0 (rated output)")
        for name in ("load_points", "p_el_points_w"):
            values = getattr(self, name)
            if any(b <= a for a, b in zip(values, values[1:])):
                raise ValueError(f"{name} must increase strictly")
        if min(self.p_el_points_w) <= 0 or max(self.p_el_points_w) > P_MAX_W:
            raise ValueError(f"p_el_points_w must be positive and at most {P_MAX_W:g} W")
        if self.start_lost_h > 1.0:
            raise ValueError("start_lost_h must not exceed one hour")
        return self


class CoolingParams(Section):
    """Cooling by the reversible heat pump through the underfloor system.

    ``q_cool_max_w``: heat the floor can take from the rooms at the supply temperature
    ``t_supply_c`` [W]; EER(T_amb) piecewise linear (``eer_t_amb_c``, ``eer``), held
    outside the table. The supply must stay above the dew point of the room air at the
    design state (``design_room_c``, ``design_rh``) plus ``dew_point_margin_k``.
    """

    enabled: bool
    q_cool_max_w: float = Phys(0, P_MAX_W, lo_open=True)
    t_supply_c: float = Phys(5, 30)
    design_room_c: float = Phys(15, 40)
    design_rh: float = Field(gt=0, le=1)
    dew_point_margin_k: float = NonNeg
    eer_t_amb_c: list[float]
    eer: list[float]

    @model_validator(mode="after")
    def _check(self) -> CoolingParams:
        from comems4build_ros.core.psychrometrics import dew_point_c

        n = len(self.eer_t_amb_c)
        if n < 2 or len(self.eer) != n:
            raise ValueError("eer_t_amb_c and eer need the same length (>= 2)")
        if any(b <= a for a, b in zip(self.eer_t_amb_c, self.eer_t_amb_c[1:])):
            raise ValueError("eer_t_amb_c must increase strictly")
        if min(self.eer) <= 0 or max(self.eer) > 30:
            raise ValueError("EER values must be positive and at most 30")
        if min(self.eer_t_amb_c) < -60 or max(self.eer_t_amb_c) > 60:
            raise ValueError("eer_t_amb_c must lie within -60..60 degC")
        limit = dew_point_c(self.design_room_c, self.design_rh) + self.dew_point_margin_k
        if self.t_supply_c < limit:
            raise ValueError(f"t_supply_c ({self.t_supply_c}) below the dew point of the room air plus margin "
                             f"({limit:.2f} degC): the floor would condense")
        return self


class HeatPumpParams(Section):
    """Air-source heat pump, ``sec:hp``."""

    t_supply_sh_c: float = Phys(20, 80)
    t_supply_dhw_c: float = Phys(30, 80)
    mod_min: float = Field(gt=0, le=1)
    cop_t_amb_c: list[float]
    cop_45c: list[float]
    cop_55c: list[float]
    p_el_max_t_amb_c: list[float]
    p_el_max_w: list[float]

    @model_validator(mode="after")
    def _check(self) -> HeatPumpParams:
        n = len(self.cop_t_amb_c)
        if n < 2 or len(self.cop_45c) != n or len(self.cop_55c) != n:
            raise ValueError("cop_t_amb_c, cop_45c and cop_55c need the same length (>= 2)")
        if any(b <= a for a, b in zip(self.cop_t_amb_c, self.cop_t_amb_c[1:])):
            raise ValueError("cop_t_amb_c must increase strictly")
        if min(self.cop_45c + self.cop_55c) <= 1.0 or max(self.cop_45c + self.cop_55c) > 15:
            raise ValueError("COP values must exceed 1 and be at most 15")
        if min(self.cop_t_amb_c + self.p_el_max_t_amb_c) < -60 or max(self.cop_t_amb_c + self.p_el_max_t_amb_c) > 60:
            raise ValueError("cop_t_amb_c and p_el_max_t_amb_c must lie within -60..60 degC")
        m = len(self.p_el_max_t_amb_c)
        if m < 2 or len(self.p_el_max_w) != m:
            raise ValueError("p_el_max_t_amb_c and p_el_max_w need the same length (>= 2)")
        if any(b <= a for a, b in zip(self.p_el_max_t_amb_c, self.p_el_max_t_amb_c[1:])):
            raise ValueError("p_el_max_t_amb_c must increase strictly")
        if min(self.p_el_max_w) <= 0 or max(self.p_el_max_w) > P_MAX_W:
            raise ValueError(f"p_el_max_w must be positive and at most {P_MAX_W:g} W")
        return self


class DHWParams(Section):
    """Hot-water tank, ``eq:DHW_model``."""

    v_max_l: float = Phys(0, 1.0e5, lo_open=True)
    v_min_l: float = Phys(0, 1.0e5)
    t_dhw_c: float = Phys(30, 95)
    t_cold_c: float = Phys(0, 30)
    q_loss_w: float = Phys(0, 1.0e4)
    rho_kg_per_l: float = Phys(0.9, 1.1)  # water
    c_j_per_kg_k: float = Phys(3000, 5000)  # water: 4186 J/(kg K)

    @model_validator(mode="after")
    def _check(self) -> DHWParams:
        if self.v_min_l >= self.v_max_l:
            raise ValueError(f"v_min_l ({self.v_min_l}) must be below v_max_l ({self.v_max_l})")
        if self.t_dhw_c <= self.t_cold_c:
            raise ValueError("t_dhw_c must exceed t_cold_c")
        return self


class BuildingParams(Section):
    """4R3C building, ``eq:dT_i`` .. ``eq:dT_wout`` (SI units)."""

    c_air_j_per_k: float = Phys(1.0e4, 1.0e10)  # a room of 10 m3 of air (1.2e4 J/K) .. a large building's mass
    c_wall_j_per_k: float = Phys(1.0e5, 1.0e11)
    r_w_air_k_per_w: float = Phys(1.0e-6, 10)
    r_air_amb_k_per_w: float = Phys(1.0e-6, 10)
    r_w_k_per_w: float = Phys(1.0e-6, 10)
    r_w_amb_k_per_w: float = Phys(1.0e-6, 10)
    g_s_m2: float = Phys(0, 1000)
    f_conv: float = Frac
    a_sol_k_m2_per_w: float = Phys(0, 1)
    t_amb_init_c: float = Phys(-60, 60)
    #: Share of the appliance load that heats the air node [-]: 0 is the paper's model, which has
    #: no internal-gain input (eq:dT_i); a model identified on a house with gains sets it
    #: (``comems4build identify``), and the 4R3C and the MPC then take P_el,load as a fourth input.
    f_gains_air: float = Field(default=0.0, ge=0.0, le=2.0)


class GridParams(Section):
    """Tariff: ``p_buy = a + b * spot`` [EUR/kWh] (spot in EUR/kWh); constant sell price ``eq:costs``."""

    buy_offset_eur_per_kwh: float = Phys(-PRICE_MAX_EUR_PER_KWH, PRICE_MAX_EUR_PER_KWH)
    buy_spot_factor: float = Phys(0, 10, lo_open=True)
    price_sell_eur_per_kwh: float = Phys(0, PRICE_MAX_EUR_PER_KWH)


class ComfortParams(Section):
    """Comfort bounds, ``eq:T_min``."""

    t_min_home_c: float = Phys(5, 30)
    t_min_away_c: float = Phys(5, 30)
    t_max_c: float = Phys(15, 40)
    home_hours_weekday: list[int]
    home_hours_weekend: list[int]
    holidays_country: str
    holidays_subdivision: str
    discomfort_sample: Literal["end", "start", "mean"] = "end"
    #: Upper bound in the cooling season [degC] and the season's first and last month (inclusive).
    t_max_cooling_c: float = Field(default=26.0, ge=15, le=40)
    cooling_season_months: list[int] = [5, 9]

    @model_validator(mode="after")
    def _check(self) -> ComfortParams:
        check_holiday_calendar(self.holidays_country, self.holidays_subdivision)
        for name in ("home_hours_weekday", "home_hours_weekend"):
            hours = getattr(self, name)
            if len(hours) % 2 or any(not 0 <= h <= 24 for h in hours):
                raise ValueError(f"{name} must hold [start, end) hour pairs within 0..24")
            if any(b <= a for a, b in zip(hours[::2], hours[1::2])):
                raise ValueError(f"{name}: each pair needs start < end")
        if max(self.t_min_home_c, self.t_min_away_c) >= min(self.t_max_c, self.t_max_cooling_c):
            raise ValueError("t_max_c and t_max_cooling_c must exceed both lower bounds")
        months = self.cooling_season_months
        if len(months) != 2 or any(not 1 <= m <= 12 for m in months) or months[1] < months[0]:
            raise ValueError("cooling_season_months must be [first, last] months within 1..12, first <= last")
        return self


def check_holiday_calendar(country: str, subdivision: str) -> None:
    """Raise ``ValueError`` naming the parameter unless the ``holidays`` library knows the calendar.

    ``country`` is an ISO 3166-1 alpha-2 code (``DE``), ``subdivision`` one of its
    subdivisions (``BW``) or empty (the national holidays only). A calendar found once is
    remembered on disk for the installed ``holidays`` version
    (:mod:`comems4build_ros.core.result_cache`): ``holidays`` imports every country's calendar to
    look one up (0.1 s), in every process that validates the plant parameters.
    """
    from comems4build_ros.core.result_cache import cached

    calendar = {"country": country, "subdivision": subdivision}
    cached("holidays", calendar, [], lambda: _check_holiday_calendar(country, subdivision) or (), dists=("holidays",))


def _check_holiday_calendar(country: str, subdivision: str) -> None:
    """:func:`check_holiday_calendar` asking the ``holidays`` library."""
    import holidays

    supported = holidays.list_supported_countries()
    if country not in supported:
        import difflib

        close = difflib.get_close_matches(country.upper(), list(supported), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise ValueError(f"holidays_country '{country}': no holiday calendar for this country in the holidays "
                         f"library (an ISO 3166-1 alpha-2 code such as DE, AT, FR{hint})")
    if subdivision:
        try:
            holidays.country_holidays(country, subdiv=subdivision, years=[])
        except NotImplementedError:
            known = ", ".join(str(s) for s in supported[country]) or "none"
            raise ValueError(f"holidays_subdivision '{subdivision}' is not a subdivision of {country} in the "
                             f"holidays library (known: {known}; empty for the national holidays only)") from None


class DegradationParams(Section):
    """Lifecycle and toggling costs, ``tab:degradation_HESS``."""

    sigma_in_fc_eur: float = Phys(0, 1.0e7)
    l_fc_h: float = Phys(0, 1.0e6, lo_open=True)
    sigma_om_fc_eur_per_h: float = Phys(0, 1.0e3)
    sigma_fc_on_eur: float = Phys(0, 1.0e3)
    sigma_fc_off_eur: float = Phys(0, 1.0e3)
    sigma_in_b_eur: float = Phys(0, 1.0e7)
    sigma_om_b_eur_per_h: float = Phys(0, 1.0e3)
    n_b_cycles: float = Phys(0, 1.0e6, lo_open=True)


class PlantParams(Section):
    """All plant parameters (one section per device)."""

    simulation: SimulationParams
    site: SiteParams
    pv: PVParams
    battery: BatteryParams
    fuel_cell: FuelCellParams
    hydrogen: HydrogenParams
    electrolyser: ElectrolyserParams
    heat_pump: HeatPumpParams
    cooling: CoolingParams
    dhw: DHWParams
    building: BuildingParams
    grid: GridParams
    comfort: ComfortParams
    degradation: DegradationParams


PLANT_SECTIONS = tuple(PlantParams.model_fields)
#: Sections of the other parameter files, which a plant parameter file (``--config``,
#: ``--set``) does not read: section -> where its values go instead.
OTHER_SECTIONS = {
    "mpc": "MPC options: --ems-option KEY=VALUE (defaults in config/mpc.yaml)",
    "mpc_qp": "QP-MPC options: --ems-option KEY=VALUE (defaults in config/mpc.yaml)",
    "rbc": "RBC options: --ems-option KEY=VALUE (defaults in config/rbc.yaml)",
    "flc_flex": "fuzzy options: --ems-option flex.KEY=VALUE or flex_file=FILE (config/fuzzy/flex.yaml)",
    "flc_fc": "fuzzy options: --ems-option fc.KEY=VALUE or fc_file=FILE (config/fuzzy/fc.yaml)",
    "flc_b": "fuzzy options: --ems-option battery.KEY=VALUE or battery_file=FILE (config/fuzzy/battery.yaml)",
    "forecast": "forecast mode: --forecast perfect|imperfect (settings in config/forecast.yaml)",
    "scenario": "scenario generator settings: config/scenario.yaml",
}


def unknown_section_text(key: str) -> str:
    """Message for a section that is not a plant section: what it is, or the closest plant section."""
    import difflib

    if key in OTHER_SECTIONS:
        return f"section '{key}' is not a plant section and is not read here; {OTHER_SECTIONS[key]}"
    close = difflib.get_close_matches(key, PLANT_SECTIONS, n=1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return f"unknown section '{key}' ({hint}plant sections: {', '.join(PLANT_SECTIONS)})"


def load_plant_params(
    paths: Iterable[str | Path] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> PlantParams:
    """Load and validate the plant parameters.

    Parameters
    ----------
    paths : parameter files merged over the default ``config/plant.yaml`` in order.
        Sections that are not plant sections (e.g. ``mpc``) are ignored here.
    overrides : ``{"battery.e_max_kwh": 10.0}``-style dotted overrides applied last.

    Raises
    ------
    ConfigError
        Naming the file (or ``overrides``), the parameter and the rule broken.
    """
    files = [default_plant_file(), *(Path(p) for p in (paths or []))]
    merged: dict[str, Any] = {}
    for i, path in enumerate(files):
        data = read_ros_params(path)
        unknown_plant = [k for k in data if k not in PLANT_SECTIONS and not isinstance(data[k], Mapping)]
        if unknown_plant:
            raise ConfigError(f"{path}: unknown top-level parameter(s): {', '.join(unknown_plant)}")
        if i > 0:  # a user's file: every section must be one that is read
            for key in data:
                if key not in PLANT_SECTIONS:
                    raise ConfigError(f"{path}: {unknown_section_text(key)}")
        deep_merge(merged, {k: v for k, v in data.items() if k in PLANT_SECTIONS})
    source = " + ".join(str(f) for f in files)
    if overrides:
        for key, value in overrides.items():
            if key.split(".")[0] not in PLANT_SECTIONS:
                raise ConfigError(f"overrides: parameter '{key}': {unknown_section_text(key.split('.')[0])}")
            set_dotted(merged, key, value)
        source += " + overrides"
    return validate(PlantParams, merged, source)


def table_rows(doc: Any, key: str, row_keys: Sequence[str], class_key: str, source: str,
               what: str) -> Iterator[tuple[str, dict[str, Any], str]]:
    """The rows of a table of classes (``config/ems.yaml``, ``config/coordinators.yaml``), checked.

    ``doc`` is ``{key: {name: row}}``; every row must hold exactly ``row_keys``, its
    ``class_key`` as ``module:Class``. Yields ``(name, row, where)`` with ``where`` naming the
    file and the row for further checks.

    Raises
    ------
    ConfigError
        Naming the file, the row (``what 'name'``) and the key that is missing, unknown or invalid.
    """
    rows = doc.get(key) if isinstance(doc, dict) else None
    if not isinstance(rows, dict) or not rows:
        raise ConfigError(f"{source}: needs a mapping '{key}' of {what} name -> row")
    for name, row in rows.items():
        where = f"{source}: {what} '{name}'"
        if not isinstance(name, str) or not isinstance(row, dict):
            raise ConfigError(f"{where}: a name and a mapping of {', '.join(row_keys)}")
        missing = [k for k in row_keys if k not in row]
        extra = sorted(set(row) - set(row_keys))
        if missing or extra:
            problems = ([f"missing {', '.join(missing)}"] if missing else []) + (
                [f"unknown {', '.join(extra)}"] if extra else [])
            raise ConfigError(f"{where}: " + "; ".join(problems))
        if not isinstance(row[class_key], str) or row[class_key].count(":") != 1:
            raise ConfigError(f"{where}: {class_key} must be 'module:Class', got {row[class_key]!r}")
        yield name, row, where


def table_class(spec: str, methods: Sequence[str], kind: str, what: str, error: type[Exception]) -> type:
    """The class ``module:Class`` of a table's row, with the ``methods`` a ``kind`` class has.

    Raises
    ------
    error
        Naming ``what`` (the row, e.g. ``EMS 'rbc'``) when its module or class is missing.
    """
    import importlib

    module_name, _, class_name = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            raise error(f"{what} is in the table but its module {module_name} is missing") from None
        raise
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type) or not all(callable(getattr(cls, m, None)) for m in methods):
        raise error(f"module {module_name} defines no {kind} class {class_name} ({what})")
    return cls
