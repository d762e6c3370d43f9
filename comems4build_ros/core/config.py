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
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import InputFileError, load_yaml_file, load_yaml_text, path_kind
from comems4build_ros.files.paths import PACKAGE, SOURCE_ROOT, shared_path

__all__ = ["path_kind"]  # re-exported: the check of an input path

#: Hours per second, seconds per hour and similar named conversion factors.
SECONDS_PER_HOUR = 3600.0
W_PER_KW = 1000.0


class ConfigError(InputError):
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
            bound = _bound_reason(model, tuple(err["loc"])) if err["type"] == "greater_than_equal" else None
            if bound is not None:
                msg = below_least_text(err.get("input"), bound["least"], bound["why"], bound["off"])
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

    @field_validator("*", mode="after")
    @classmethod
    def _off_or_least(cls, value: Any, info: ValidationInfo) -> Any:
        """A :func:`Phys` field with ``off``: 0 (none), or at least its smallest real value."""
        field = cls.model_fields.get(info.field_name or "")
        extra = getattr(field, "json_schema_extra", None)
        if isinstance(extra, dict) and extra.get("off") and value != 0 and value < extra["least"]:
            raise ValueError(below_least_text(value, extra["least"], extra["why"], off=True))
        return value


NonNeg = Field(ge=0)
Frac = Field(ge=0, le=1)


def Phys(lo: float, hi: float, why: str = "", off: bool = False, **field: Any) -> Any:  # noqa: N802 (a field type)
    """A physical range ``[lo, hi]`` of a parameter; ``off``: 0 (none) or ``[lo, hi]``.

    The ranges bound what a residential building and its devices can have, generously (a
    decade or more beyond the largest shipped or studied value), so that a value no
    building has (a room air capacity of 1e-300 J/K, a sell price of 1e300 EUR/kWh, a
    battery of 5e-324 kWh) is refused naming the parameter instead of acting as 0 or
    surfacing later as a non-finite state or a solver that finds nothing. ``lo`` is never a
    bare "> 0": it is the smallest value the thing the parameter stands for has, and ``why``
    says so; a refusal names ``lo`` as the smallest real value and gives ``why``. ``field``:
    further arguments of ``Field`` (a ``default``).
    """
    return Field(ge=0 if off else lo, le=hi, json_schema_extra={"least": lo, "why": why, "off": off}, **field)


def _bound_reason(model: type[BaseModel], loc: tuple[Any, ...]) -> dict[str, Any] | None:
    """The :func:`Phys` record (least value, reason) of the field at ``loc`` of ``model``, if it has one."""
    info = None
    node: Any = model
    for part in loc:
        fields = getattr(node, "model_fields", None)
        if not isinstance(fields, dict) or str(part) not in fields:
            return None
        info = fields[str(part)]
        node = info.annotation
    extra = getattr(info, "json_schema_extra", None)
    return extra if isinstance(extra, dict) and "least" in extra else None


def below_least_text(value: Any, least: float, why: str, off: bool = False) -> str:
    """The refusal of a value below a physical lower bound: the value, the smallest real value, why."""
    shown = value if isinstance(value, str) else repr(value)  # a number PyYAML read as text: as written
    first = f"{shown} is neither 0 (none) nor at least {least:g}" if off else f"{shown} is below {least:g}"
    return f"{first}, the smallest real value" + (f": {why}" if why else "")


#: Faraday constant [C/mol] (CODATA 2018, exact).
FARADAY_C_PER_MOL = 96485.33212
#: Lower heating value of hydrogen [J/mol]: the enthalpy of formation of water vapour, 241.8 kJ/mol
#: (NIST Chemistry WebBook).
LHV_H2_J_PER_MOL = 241.8e3
#: Electrons transferred per H2 molecule.
ELECTRONS_PER_H2 = 2
#: Thermoneutral-at-LHV cell voltage LHV / (2F) [V] (about 1.253 V): eta_el = V_cell / this (eq:efficiency_FC).
V_LHV_V = LHV_H2_J_PER_MOL / (ELECTRONS_PER_H2 * FARADAY_C_PER_MOL)

#: Largest electrical power of one device of the house [W] (1 MW: far beyond any residential device).
P_MAX_W = 1.0e6
#: Largest price or cost per kWh [EUR/kWh] (day-ahead prices reached 0.87 EUR/kWh in 2022).
PRICE_MAX_EUR_PER_KWH = 10.0


class SimulationParams(Section):
    """Run settings: step [h], horizon [h], H2 season [weeks] and initial states."""

    #: Step [h]: the scenarios have 1 h rows (paper sec:parameters), a run checks the match;
    #: at most a day, since the day-based rules (``eq:deltaLOH``, forecasts) count steps per day.
    time_step_h: float = Phys(1 / 60, 24, "a minute: no input resolves less (DWD's finest products are 10-minute "
                                           "values) and a step is a whole number of the scenario's rows")
    horizon_h: int = Field(gt=0, le=168)
    season_weeks: float = Phys(1 / 7, 53, "a day: eq:deltaLOH gives the store's budget per day")
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
    a_module_m2: float = Phys(0.1, 10, "the smallest framed modules (about 10 Wp) have about 0.1 m2")
    eta_stc: float = Phys(0.02, 0.5, "below every commercial module (amorphous silicon about 0.06)")
    eta_lt: float = Phys(0.5, 1, "inverter, MPPT and wiring: commercial inverters convert above 0.9")
    eta_t_per_k: float = Phys(0, 0.02)
    noct_c: float = Phys(20, 80)
    t_stc_c: float = Phys(15, 35)
    tilt_deg: float = Field(ge=0, le=90)
    azimuth_deg: float = Field(ge=0, le=360)
    albedo: float = Frac
    sky_model: Literal["isotropic", "klucher", "haydavies", "reindl", "king", "perez"] = "isotropic"


class BatteryParams(Section):
    """Battery energy storage, ``eq:batt_soc`` .. ``eq:s_summ``."""

    e_max_kwh: float = Phys(0.1, 1.0e4, "a tenth of the smallest home battery modules (about 1 kWh)")
    p_ch_max_w: float = Phys(1, P_MAX_W, "less than 1 W moves under 1 Wh an hour into a battery of at least "
                                         "0.1 kWh", off=True)
    p_d_max_w: float = Phys(1, P_MAX_W, "less than 1 W moves under 1 Wh an hour out of a battery of at least "
                                        "0.1 kWh", off=True)
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

    p_max_w: float = Phys(10, P_MAX_W, "the smallest PEM stacks sold deliver about 12 W")
    p_nom_w: float = Phys(10, P_MAX_W, "the smallest PEM stacks sold deliver about 12 W")
    p_min_w: float = Phys(0, P_MAX_W, "no minimum")
    zeta: float = Phys(0.1, 1, "a security factor below 0.1 keeps the FC under a tenth of its rating")
    #: At least the FC's electrical efficiency wherever it runs (checked below): the recovered heat is never negative.
    eta_sys: float = Phys(0.2, 1, "no PEM system turns less than a fifth of its H2's LHV into electricity and heat")
    n_cells: int = Field(gt=0, le=1000)
    e_ocv_v: float = Phys(0.5, 1.25)  # [V per cell]: below the reversible 1.229 V at 25 degC
    a_tafel_v: float = Phys(0, 0.5)
    i_tafel_a: float = Phys(1e-3, 1000, "a PEM cell's exchange current: about 1e-3 A/cm2 on tens of cm2")
    r_ohm_ohm: float = Phys(0, 1)
    eta_el_mpc: float = Phys(0.2, 0.99, "PEM systems deliver 0.4..0.6 of the H2's LHV at their nominal point "
                                        "(datasheets); a fifth generously below")

    @model_validator(mode="after")
    def _check(self) -> FuelCellParams:
        if self.p_min_w > self.zeta * self.p_max_w:
            raise ValueError(
                f"p_min_w ({self.p_min_w}) must not exceed zeta * p_max_w ({self.zeta * self.p_max_w})"
            )
        if self.p_nom_w > self.p_max_w:
            raise ValueError(f"p_nom_w ({self.p_nom_w}) must not exceed p_max_w ({self.p_max_w})")
        _, p_mpp = self.max_power_point()
        if p_mpp < self.p_max_w:
            raise ValueError(f"the polarization curve peaks at {p_mpp:.1f} W, below p_max_w = {self.p_max_w} W; "
                             "check e_ocv_v, a_tafel_v, i_tafel_a, r_ohm_ohm, n_cells")
        if self.eta_sys < self.eta_el_mpc:
            raise ValueError(f"eta_sys ({self.eta_sys}) is below eta_el_mpc ({self.eta_el_mpc}): the system "
                             "efficiency counts the electricity and the recovered heat (eq:FC_sys_efficiency)")
        eta_el = self.eta_el_max()
        if self.eta_sys < eta_el:
            where = f"at p_min_w = {self.p_min_w:g} W" if self.p_min_w > 0 else "near no load (p_min_w = 0)"
            raise ValueError(f"eta_sys ({self.eta_sys}) is below the electrical efficiency {eta_el:.3f} the "
                             f"polarization curve gives {where} (eq:efficiency_FC): the recovered heat "
                             "(eq:FC_sys_efficiency) would be negative")
        return self

    # the polarization model (eq:molar_flows, eq:efficiency_FC): core.models.fuel_cell uses these
    def cell_voltage_v(self, i_a: Any) -> Any:
        """Cell voltage ``V_cell(i) = E_ocv - A ln(1 + i / i_T) - R_ohm i`` [V] at the stack current ``i_a`` [A]
        (numpy arrays element-wise)."""
        import numpy as np

        return self.e_ocv_v - self.a_tafel_v * np.log1p(i_a / self.i_tafel_a) - self.r_ohm_ohm * i_a

    def stack_power_w(self, i_a: Any) -> Any:
        """Stack electrical output ``P = N_cells V_cell(i) i`` [W] at the current ``i_a`` [A]."""
        return self.n_cells * self.cell_voltage_v(i_a) * i_a

    def dpower_di(self, i_a: Any) -> Any:
        """``dP/di`` [W/A] of :meth:`stack_power_w`."""
        dv = -self.a_tafel_v / (self.i_tafel_a + i_a) - self.r_ohm_ohm
        return self.n_cells * (self.cell_voltage_v(i_a) + i_a * dv)

    def max_power_point(self) -> tuple[float, float]:
        """Current [A] and output [W] at the maximum of ``P(i)`` (the end of the monotone branch).

        Raises
        ------
        ValueError
            If the curve rises beyond 1e7 A (no maximum: the parameters describe no cell).
        """
        lo, hi = 0.0, 1.0
        while self.dpower_di(hi) > 0.0:
            lo, hi = hi, 2.0 * hi
            if hi > 1e7:
                raise ValueError("the polarization curve has no maximum power point")
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if self.dpower_di(mid) > 0.0:
                lo = mid
            else:
                hi = mid
        i_mpp = 0.5 * (lo + hi)
        return i_mpp, float(self.stack_power_w(i_mpp))

    def eta_el_max(self) -> float:
        """The highest electrical efficiency ``V_cell / (LHV / 2F)`` where the FC runs: at ``p_min_w``
        (the efficiency falls with the load), the open-circuit limit with ``p_min_w = 0``."""
        if self.p_min_w <= 0.0:
            return float(self.e_ocv_v / V_LHV_V)
        lo, hi = 0.0, self.max_power_point()[0]
        for _ in range(200):  # P rises on [0, i_mpp]: the current that gives p_min_w
            mid = 0.5 * (lo + hi)
            if self.stack_power_w(mid) < self.p_min_w:
                lo = mid
            else:
                hi = mid
        return float(self.cell_voltage_v(hi) / V_LHV_V)


class HydrogenParams(Section):
    """Hydrogen store, ``eq:LOH`` (energy content at LHV)."""

    e_max_kwh: float = Phys(0.1, 1.0e6, "a third of the smallest metal-hydride canister (about 0.3 kWh)")
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
    h2_rated_nl_per_h: float = Phys(1, 1.0e6, "a tenth of the smallest laboratory electrolysers (about "
                                              "10 NL/h)")
    load_points: list[float]
    p_el_points_w: list[float]
    p_standby_w: float = Phys(0, 1.0e4)
    start_lost_h: float = NonNeg
    p_out_bar: float = Phys(1, 1000, "atmospheric pressure: no electrolyser delivers below it")
    p_store_bar: float = Phys(1, 1000, "atmospheric pressure: no store holds H2 below it")
    t_compression_c: float = Phys(-40, 100)
    eta_compressor: float = Phys(0.05, 1, "small compressors reach 0.3..0.7 isothermal efficiency")
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
    q_cool_max_w: float = Phys(10, P_MAX_W, "a thirtieth of one room's floor cooling (about 300 W)")
    t_supply_c: float = Phys(5, 30)
    design_room_c: float = Phys(15, 40)
    design_rh: float = Phys(0.05, 1, "the driest heated rooms hold about 0.2")
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
    mod_min: float = Phys(0.05, 1, "inverter heat pumps modulate down to 0.2..0.3 (paper: 0.2)")
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


#: One shower draw [l]: DHWCalc's shower category (40 l per draw-off; the shipped profile's log,
#: data/OpenDHW_DHWcalc_200L_60min_4cat_sf_nods_max1200_log.txt, category 4, 40 % of the volume).
DHW_ONE_DRAW_L = 40.0


class DHWParams(Section):
    """Hot-water tank, ``eq:DHW_model``."""

    v_max_l: float = Phys(5, 1.0e5, "the smallest hot-water stores (under-sink tanks) hold about 5 l")
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
        if self.v_max_l - self.v_min_l < DHW_ONE_DRAW_L:
            raise ValueError(f"the tank's usable volume v_max_l - v_min_l ({self.v_max_l - self.v_min_l:g} l) holds "
                             f"less than one shower draw ({DHW_ONE_DRAW_L:g} l, DHWCalc's shower category)")
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
    buy_spot_factor: float = Phys(0.01, 10, "a tariff passing on less than 1 % of the spot price is a flat "
                                            "tariff, which a + b * spot does not stand for")
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
    l_fc_h: float = Phys(100, 1.0e6, "a fiftieth of any PEM stack's lifetime (datasheets: 5000..40000 h)")
    sigma_om_fc_eur_per_h: float = Phys(0, 1.0e3)
    sigma_fc_on_eur: float = Phys(0, 1.0e3)
    sigma_fc_off_eur: float = Phys(0, 1.0e3)
    sigma_in_b_eur: float = Phys(0, 1.0e7)
    sigma_om_b_eur_per_h: float = Phys(0, 1.0e3)
    n_b_cycles: float = Phys(10, 1.0e6, "a fiftieth of the cycle life of lead-acid batteries (about 500)")


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

    @model_validator(mode="after")
    def _check(self) -> PlantParams:
        """Relations between sections: the initial states within their devices."""
        if self.simulation.v_dhw_init_l > self.dhw.v_max_l:
            raise ValueError(f"simulation.v_dhw_init_l ({self.simulation.v_dhw_init_l:g} l) exceeds the tank, "
                             f"dhw.v_max_l ({self.dhw.v_max_l:g} l)")
        return self


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
