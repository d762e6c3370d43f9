"""Parameter files: loading, merging and checking.

All parameters live in ``config/*.yaml`` in the ROS 2 parameter-file form::

    /**:                       # or a node name such as plant_sim
      ros__parameters:
        battery:
          e_max_kwh: 6.5

The same files are passed to the ROS nodes with ``--ros-args --params-file``. This
module reads them without rclpy, merges several files (later ones win, key by key) and
checks the plant sections against :class:`PlantParams`. An invalid file raises
:class:`ConfigError` naming the file, the parameter path and the rule broken.

Other packages of the project (scenario generator, controllers) read their own sections
with :func:`read_ros_params` and check them with :func:`parse_model`.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
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
    """Return the directory of the default parameter files.

    Returns
    -------
    pathlib.Path
        The source tree's ``config/`` when running from a checkout, else the installed
        ``<prefix>/share/comems4build_ros/config``.

    Raises
    ------
    ConfigError
        If neither directory exists.
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
    """Put the plant file of an embedded scenario in front of the user's parameter files.

    ``--scenario year`` runs the year-round plant (``config/year.yaml``: electrolyser,
    cooling, a nearly empty store at the start); every other scenario the files as given.

    Parameters
    ----------
    scenario : str or pathlib.Path
        Scenario name (``winter``, ``year``...) or file.
    files : iterable of str or pathlib.Path, optional
        The user's parameter files (``--config``), in order.

    Returns
    -------
    list of str
        ``files`` with the scenario's plant file (absolute path) in front, once; ``files``
        unchanged for a scenario without one (:data:`SCENARIO_PLANT_FILES`).
    """
    out = [str(f) for f in files]
    name = SCENARIO_PLANT_FILES.get(str(scenario))
    if name is None:
        return out
    path = str((config_dir() / name).resolve())
    return out if any(Path(f).resolve() == Path(path) for f in out) else [path, *out]


def default_plant_file() -> Path:
    """Return the path of the default plant parameters, ``config/plant.yaml``."""
    return config_dir() / "plant.yaml"


def load_yaml(path: str | Path, what: str, error: type[Exception] = ConfigError) -> Any:
    """Parse a YAML file through the project's one YAML loader.

    The loader is :func:`comems4build_ros.files.inputs.load_yaml_file`.

    Parameters
    ----------
    path : str or pathlib.Path
        The YAML file.
    what : str
        What the file is, for the message (``"parameter file"``).
    error : type of Exception, optional
        Exception raised on failure (default :class:`ConfigError`).

    Returns
    -------
    object
        The parsed document.

    Raises
    ------
    Exception
        ``error``, naming the file and ``what`` it is: a directory, a device, a file that is
        not UTF-8 text (e.g. binary), invalid YAML, a document over the loader's limits
        (size, depth, aliases), a key that is not a string or is given twice, each with the
        line and column.
    """
    try:
        return load_yaml_file(path, what)
    except InputFileError as exc:
        raise error(str(exc)) from None


def check_input_file(path: str | Path, what: str) -> Path:
    """Check that an input path is a readable regular file.

    Parameters
    ----------
    path : str or pathlib.Path
        The path given.
    what : str
        Where it was given, for the message (e.g. ``--config``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ConfigError
        Naming ``what`` and the path if it is missing, a directory, unreadable...
    """
    kind = path_kind(path)
    if kind:
        raise ConfigError(f"{what} {path}: {kind}")
    return Path(path)


def read_ros_params(path: str | Path, node: str | None = None) -> dict[str, Any]:
    """Read a ROS 2 parameter file and return the merged ``ros__parameters`` dict.

    Parameters
    ----------
    path : str or pathlib.Path
        The parameter file.
    node : str, optional
        Node name whose section is merged over the ``/**`` section; None merges every
        section in file order.

    Returns
    -------
    dict
        The merged parameters (nested sections as dicts).

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
    """Read one section of a parameter file's merged ``ros__parameters``.

    Parameters
    ----------
    path : str or pathlib.Path
        The parameter file.
    name : str
        The section (a mapping), e.g. ``costs``.

    Returns
    -------
    dict
        A copy of the section.

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
    """Merge a mapping into a dict in place, recursing into mappings (``extra`` wins).

    Parameters
    ----------
    base : dict
        Updated in place.
    extra : mapping
        Values merged over ``base``; its nested mappings are copied.

    Returns
    -------
    dict
        ``base``.
    """
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(base.get(key), dict):
            deep_merge(base[key], value)
        elif isinstance(value, Mapping):
            base[key] = deep_merge({}, value)
        else:
            base[key] = value
    return base


def set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set a nested value by its dotted name: ``data['a']['b'] = value`` for ``'a.b'``.

    Parameters
    ----------
    data : dict
        Updated in place; missing sections are created.
    dotted : str
        Dotted parameter name, e.g. ``battery.e_max_kwh``.
    value : object
        The value.

    Raises
    ------
    ConfigError
        If a part of the name other than the last is not a section.
    """
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise ConfigError(f"parameter '{dotted}': '{key}' is not a section")
    node[keys[-1]] = value


M = TypeVar("M", bound=BaseModel)


def parse_assignments(items: Iterable[str], what: str) -> dict[str, Any]:
    """Parse ``KEY=VALUE`` assignments (``--set``, ``--ems-option``), each value read as YAML.

    ``["a.b=1.5", "c=x"]`` gives ``{"a.b": 1.5, "c": "x"}``. Empty items are skipped (a
    ROS string-array parameter's empty default).

    Parameters
    ----------
    items : iterable of str
        The assignments.
    what : str
        The option or node parameter they came from, for the message.

    Returns
    -------
    dict
        Key (stripped) -> parsed value; a later item overrides an earlier one.

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
    """Refuse keys that are not known, suggesting the closest known one.

    For option mappings read without a pydantic model (the fuzzy rule-base files and their
    overrides): a misspelt key is refused instead of silently ignored.

    Parameters
    ----------
    data : mapping
        The options read.
    known : iterable of str
        The keys allowed.
    where : str
        The file or option, for the message.

    Raises
    ------
    ConfigError
        Naming ``where`` and the first key of ``data`` that is not in ``known``.
    """
    import difflib

    known = list(known)
    for key in data:
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(f"{where}: unknown parameter '{key}' ({hint}known: {', '.join(known)})")


def _known_keys(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """Return `` (did you mean 'x'? known: a, b)``: the keys of the model that ``loc[:-1]`` leads to."""
    import difflib
    import typing

    for part in loc[:-1]:
        field = model.model_fields.get(str(part))
        if field is None:
            return ""
        inner = [t for t in (field.annotation, *typing.get_args(field.annotation))
                 if isinstance(t, type) and issubclass(t, BaseModel)]
        if not inner:
            return ""
        model = inner[0]
    known = list(model.model_fields)
    close = difflib.get_close_matches(str(loc[-1]), known, n=1)
    return f" ({f'did you mean {close[0]!r}? ' if close else ''}known: {', '.join(known)})"


def parse_model(model: type[M], data: Mapping[str, Any], source: str, prefix: str = "") -> M:
    """Check ``data`` against a pydantic model; errors name the source and the parameter.

    An unknown parameter's message lists the known ones of its section (and the closest).

    Parameters
    ----------
    model : type of pydantic.BaseModel
        The model, usually a :class:`Section`.
    data : mapping
        The parameters.
    source : str
        The file(s) they came from, for the messages.
    prefix : str, optional
        Put before each parameter's name (the key of ``data`` in a larger set).

    Returns
    -------
    pydantic.BaseModel
        The checked ``model`` instance.

    Raises
    ------
    ConfigError
        One line per error, naming ``source``, the parameter and the rule broken.
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        lines = []
        for err in exc.errors():
            loc = prefix + ".".join(str(p) for p in err["loc"]) if err["loc"] else ""
            msg = err["msg"].removeprefix("Value error, ")
            bound = _bound_reason(model, tuple(err["loc"])) if err["type"] == "greater_than_equal" else None
            if bound is not None:
                msg = below_least_text(err.get("input"), bound["least"], bound["why"], bound["off"])
            if err["type"] == "extra_forbidden":
                msg = "unknown parameter" + _known_keys(model, tuple(err["loc"]))
            lines.append(f"{source}: parameter '{loc}': {msg}" if loc else f"{source}: {msg}")
        raise ConfigError("\n".join(lines)) from None


def load_section(model: type[M], path: str | Path | None, default_file: str, section: str,
                 overrides: Mapping[str, Any] | None = None) -> M:
    """Read one section of a parameter file, apply overrides, and check it.

    Parameters
    ----------
    model : type of pydantic.BaseModel
        The model of the section.
    path : str or pathlib.Path or None
        The parameter file; None reads ``config/<default_file>``.
    default_file : str
        File name under ``config/`` used when ``path`` is None.
    section : str
        The section under ``ros__parameters``.
    overrides : mapping, optional
        Top-level keys of the section replaced before the check.

    Returns
    -------
    pydantic.BaseModel
        The section as a ``model`` instance.

    Raises
    ------
    ConfigError
        Naming the file and the parameter that is missing or invalid, or the missing section.
    """
    path = Path(path) if path else config_dir() / default_file
    data = read_param_section(path, section)
    data.update(overrides or {})
    return parse_model(model, data, str(path))


class Section(BaseModel):
    """A parameter section: unknown keys, booleans as numbers, numbers as booleans and inf/NaN are refused.

    The one rule for every checked parameter set: the plant sections here and the
    controllers' options (``config/rbc.yaml``, ``config/mpc.yaml``), from files, ``--set``,
    ``--config`` and ``--ems-option`` alike.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """Refuse booleans for number fields: ``e_max_kwh: true`` must not become 1.0.

        YAML ``true``/``yes``/``on`` are booleans.

        Text is parsed as a number (PyYAML reads ``7.27e6`` without a sign in the exponent as
        text); text that is not a number is refused by the field's type.
        """
        field = cls.model_fields.get(info.field_name or "")
        if field is None or field.annotation is Any:  # checked by its reader (a fuzzy rule base)
            return value
        if field.annotation is bool:
            if not isinstance(value, bool):
                raise ValueError(f"expected true or false, got {value!r}")
            return value
        items = value if isinstance(value, list | tuple) else [value]
        if any(isinstance(v, bool) for v in items):
            raise ValueError(f"expected a number, got the boolean {value!r}")
        return value

    @field_validator("*", mode="after")
    @classmethod
    def _off_or_least(cls, value: Any, info: ValidationInfo) -> Any:
        """Check a :func:`Phys` field with ``off``: 0 (none), or at least its smallest real value."""
        field = cls.model_fields.get(info.field_name or "")
        extra = getattr(field, "json_schema_extra", None)
        if isinstance(extra, dict) and extra.get("off") and value != 0 and value < extra["least"]:
            raise ValueError(below_least_text(value, extra["least"], extra["why"], off=True))
        return value


NonNeg = Field(ge=0)
Frac = Field(ge=0, le=1)


def Phys(lo: float, hi: float, why: str = "", off: bool = False, **field: Any) -> Any:  # noqa: N802 (a field type)
    """Declare a parameter's physical range ``[lo, hi]``; with ``off``, 0 (none) or ``[lo, hi]``.

    The ranges bound what a residential building and its devices can have, generously (a
    decade or more beyond the largest shipped or studied value), so that a value no
    building has (a room air capacity of 1e-300 J/K, a sell price of 1e300 EUR/kWh, a
    battery of 5e-324 kWh) is refused naming the parameter instead of acting as 0 or
    surfacing later as a non-finite state or a solver that finds nothing. ``lo`` is never a
    bare "> 0": it is the smallest value the thing the parameter stands for has, and ``why``
    says so; a refusal names ``lo`` as the smallest real value and gives ``why``.

    Parameters
    ----------
    lo, hi : float
        Bounds, in the parameter's unit: ``lo`` the smallest real value.
    why : str, optional
        Why nothing real lies below ``lo`` (said in a refusal).
    off : bool, optional
        Also allow 0, meaning none (default: only ``[lo, hi]``).
    **field : Any
        Further arguments of ``Field`` (a ``default``).

    Returns
    -------
    pydantic.fields.FieldInfo
        The field with the bounds.
    """
    return Field(ge=0 if off else lo, le=hi, json_schema_extra={"least": lo, "why": why, "off": off}, **field)


def _bound_reason(model: type[BaseModel], loc: tuple[Any, ...]) -> dict[str, Any] | None:
    """Return the :func:`Phys` record (least value, reason) of the field at ``loc`` of ``model``, if it has one."""
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
    """Return the refusal of a value below a physical lower bound: the value, the smallest real value, why."""
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
    """Run settings: step [h], horizon [h], H2 season [weeks] and initial states.

    Values and their sources: ``config/plant.yaml`` (``simulation``).

    Attributes
    ----------
    time_step_h : float
        Step t_s, in (0, 24] (``sec:parameters``: 1 h) [h].
    horizon_h : int
        MPC horizon H and day-ahead window of the price features (``eq:EDF_prices``) [h].
    season_weeks : float
        Length of the winter whose steps N enter ``eq:deltaLOH`` [weeks].
    soc_init, loh_init : float
        Initial SOC and LOH (``tab:parameters_PV_batt_dhw_h2``) [-].
    t_air_init_c : float
        Initial room air temperature [degC].
    v_dhw_init_l : float
        Initial usable hot-water volume [l].
    heating_season_start, heating_season_end : str
        Heating season of a year-round run as local ``MM-DD`` dates (end exclusive), over
        which the fuel cell's daily H2 budget (``eq:deltaLOH``) is spread; used only with an
        electrolyser.
    loh_season_end : float
        LOH the store should still hold at the end of the heating season [-].
    """

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


def known_timezone(value: str) -> str:
    """Return ``value`` if the tz database knows it as an IANA time zone name (``Europe/Berlin``).

    Parameters
    ----------
    value : str
        A time zone name.

    Returns
    -------
    str
        ``value`` unchanged.

    Raises
    ------
    ValueError
        For any other name (a pydantic validator turns it into the field's error).
    """
    import zoneinfo

    try:
        zoneinfo.ZoneInfo(value)
    except (zoneinfo.ZoneInfoNotFoundError, ValueError):
        raise ValueError(f"unknown IANA time zone '{value}' (e.g. Europe/Berlin)") from None
    return value


class SiteParams(Section):
    """Location of the house (degrees, metres, IANA time zone).

    Attributes
    ----------
    latitude_deg, longitude_deg : float
        Geographic coordinates, north and east positive [deg].
    altitude_m : float
        Altitude above sea level [m].
    timezone : str
        IANA time zone of the local clock (``Europe/Berlin``).
    """

    latitude_deg: float = Field(ge=-90, le=90)
    longitude_deg: float = Field(ge=-180, le=180)
    altitude_m: float = Phys(-500, 9000)
    timezone: str

    @field_validator("timezone")
    @classmethod
    def _known_zone(cls, value: str) -> str:
        """Accept an IANA time zone name the tz database knows (e.g. ``Europe/Berlin``)."""
        return known_timezone(value)


class PVParams(Section):
    """PV array, ``eq:power_pv``.

    Values: ``tab:parameters_PV_batt_dhw_h2`` and ``config/plant.yaml``.

    Attributes
    ----------
    n_modules : int
        Number of modules n_module [-].
    a_module_m2 : float
        Area of one module a_module [m2].
    eta_stc : float
        Module efficiency at standard test conditions eta_STC [-].
    eta_lt : float
        Inverter and tracking efficiency eta_L&T [-].
    eta_t_per_k : float
        Temperature coefficient eta_T [1/K].
    noct_c : float
        Nominal operating cell temperature NOCT [degC].
    t_stc_c : float
        Cell temperature at standard test conditions T_STC [degC].
    tilt_deg, azimuth_deg : float
        Array tilt from horizontal and azimuth (pvlib convention: 180 = south) [deg].
    albedo : float
        Ground reflectance [-].
    sky_model : str
        pvlib's sky-diffuse transposition model for G[k].
    """

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
    """Battery energy storage, ``eq:batt_soc`` .. ``eq:s_summ``.

    Values: ``tab:parameters_PV_batt_dhw_h2``.

    Attributes
    ----------
    e_max_kwh : float
        Capacity E_B,max [kWh].
    p_ch_max_w, p_d_max_w : float
        Largest charging and discharging power P_ch,max, P_d,max [W].
    p_ch_min_w, p_d_min_w : float
        Smallest non-zero charging and discharging power (``eq:bat_ch_dis_const``) [W].
    eta_ch, eta_d : float
        Charging and discharging efficiency [-].
    soc_min, soc_max : float
        SOC bounds (``eq:SOC_const``) [-].
    """

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
    """PEM fuel cell, ``eq:molar_flows`` .. ``eq:FC_sys_efficiency``.

    Values: ``tab:parameters_PV_batt_dhw_h2``, the Horizon H-2000 datasheet and
    ``config/plant.yaml``. The cell polarization
    ``V_cell(i) = e_ocv - a_tafel * ln(1 + i / i_tafel) - r_ohm * i`` gives the H2 flow of
    ``eq:molar_flows`` through Faraday's law.

    Attributes
    ----------
    p_max_w, p_nom_w, p_min_w : float
        Largest, nominal and smallest electrical output P_FC,max, P_FC,nom, P_FC,min [W].
    zeta : float
        Security factor: output at most ``zeta * p_max_w`` (``sec:h2``) [-].
    eta_sys : float
        System efficiency with heat recovery eta_sys,FC (``eq:FC_sys_efficiency``) [-].
    n_cells : int
        Cells in the stack (Horizon H-2000 datasheet) [-].
    e_ocv_v : float
        Open-circuit voltage per cell [V].
    a_tafel_v : float
        Activation-loss (Tafel) slope per cell [V].
    i_tafel_a : float
        Activation-loss reference current [A].
    r_ohm_ohm : float
        Ohmic resistance per cell [Ohm].
    eta_el_mpc : float
        Constant electrical efficiency of the MPC's linear model (``sec:MPC``) [-].
    """

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
        """Compute the cell voltage ``V_cell(i) = E_ocv - A ln(1 + i / i_T) - R_ohm i`` [V].

        Parameters
        ----------
        i_a : float or numpy.ndarray
            Stack current [A] (arrays element-wise).

        Returns
        -------
        float or numpy.ndarray
            V_cell [V].
        """
        import numpy as np

        return self.e_ocv_v - self.a_tafel_v * np.log1p(i_a / self.i_tafel_a) - self.r_ohm_ohm * i_a

    def stack_power_w(self, i_a: Any) -> Any:
        """Compute the stack's electrical output ``P = N_cells V_cell(i) i`` [W] at the current ``i_a`` [A]."""
        return self.n_cells * self.cell_voltage_v(i_a) * i_a

    def dpower_di(self, i_a: Any) -> Any:
        """Return ``dP/di`` [W/A] of :meth:`stack_power_w` at the current ``i_a`` [A]."""
        dv = -self.a_tafel_v / (self.i_tafel_a + i_a) - self.r_ohm_ohm
        return self.n_cells * (self.cell_voltage_v(i_a) + i_a * dv)

    def max_power_point(self) -> tuple[float, float]:
        """Find the maximum of ``P(i)``, the end of the monotone branch (bisection on dP/di).

        Returns
        -------
        i_mpp_a : float
            Current at the maximum [A].
        p_mpp_w : float
            Output at the maximum [W].

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
        """Return the highest electrical efficiency ``V_cell / (LHV / 2F)`` [-] where the FC runs.

        That is at ``p_min_w`` (the efficiency falls with the load), the open-circuit limit
        with ``p_min_w = 0`` (``eq:efficiency_FC``).
        """
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
    """Hydrogen store, ``eq:LOH`` (energy content at LHV).

    Attributes
    ----------
    e_max_kwh : float
        LHV energy of the full store E_H2,max (``tab:parameters_PV_batt_dhw_h2``) [kWh].
    loh_min, loh_max : float
        LOH bounds [-].
    """

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
    tank. ``n_modules = 0``: no electrolyser (the paper's plant). Values and sources
    (Enapter EL 2.1 datasheet): ``config/plant.yaml``.

    Attributes
    ----------
    n_modules : int
        Installed modules [-].
    h2_rated_nl_per_h : float
        Rated H2 output of one module [Nl/h].
    load_points : list of float
        H2 outputs of the power table as fractions of the rated output [-].
    p_el_points_w : list of float
        Electrical intake of one module at each load point [W].
    p_standby_w : float
        Draw of an installed module while off [W].
    start_lost_h : float
        H2 production lost in a start, at most 1 [h].
    p_out_bar, p_store_bar : float
        Module outlet and store pressure of the compression [bar].
    t_compression_c : float
        Gas temperature of the isothermal compression [degC].
    eta_compressor : float
        Isothermal efficiency of the compressor [-].
    heat_recovery : float
        Share of the stack's waste heat recovered into the DHW tank [-].
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
    design state (``design_room_c``, ``design_rh``) plus ``dew_point_margin_k``. Values and
    sources (EN 1264-5, EN 16798-1, EN 14511): ``config/plant.yaml``.

    Attributes
    ----------
    enabled : bool
        The heat pump can cool (``HP_COOL``).
    q_cool_max_w : float
        Heat the floor can take from the rooms [W].
    t_supply_c : float
        Cooling supply temperature [degC].
    design_room_c, design_rh : float
        Room air state of the condensation check [degC], [-].
    dew_point_margin_k : float
        Margin of the supply above the dew point [K].
    eer_t_amb_c, eer : list of float
        EER table over the ambient temperature [degC], [-].
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
    """Air-source heat pump, ``sec:hp``.

    LG Therma V HM051M U43 (``sec:parameters``). COP and largest electrical intake are
    piecewise linear in T_amb, held constant outside their tables.

    Attributes
    ----------
    t_supply_sh_c, t_supply_dhw_c : float
        Supply temperatures of space heating and hot water [degC].
    mod_min : float
        Smallest non-zero modulation eta_HP [-].
    cop_t_amb_c : list of float
        Ambient temperatures of the COP tables [degC].
    cop_45c, cop_55c : list of float
        COP at 45 degC and 55 degC supply at ``cop_t_amb_c`` [-].
    p_el_max_t_amb_c : list of float
        Ambient temperatures of the intake table [degC].
    p_el_max_w : list of float
        Largest electrical intake P_el,max at ``p_el_max_t_amb_c`` [W].
    """

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
    """Hot-water tank, ``eq:DHW_model``.

    Values: ``tab:parameters_PV_batt_dhw_h2``.

    Attributes
    ----------
    v_max_l, v_min_l : float
        Usable volume bounds V_DHW,max, V_DHW,min [l].
    t_dhw_c : float
        Tank temperature T_DHW [degC].
    t_cold_c : float
        Mains water temperature (Delta T_DHW = t_dhw_c - t_cold_c) [degC].
    q_loss_w : float
        Standing loss Q_l,DHW [W].
    rho_kg_per_l : float
        Water density [kg/l].
    c_j_per_kg_k : float
        Specific heat capacity of water [J/(kg K)].
    """

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
    """4R3C building, ``eq:dT_i`` .. ``eq:dT_wout`` (SI units).

    Values and sources (Sperber, Frey, Bertsch 2020; calibration): ``config/plant.yaml``.

    Attributes
    ----------
    c_air_j_per_k, c_wall_j_per_k : float
        Capacities C_air and C_w (each wall node) [J/K].
    r_w_air_k_per_w, r_air_amb_k_per_w, r_w_k_per_w, r_w_amb_k_per_w : float
        Resistances R_w,air, R_air,amb, R_w, R_w,amb [K/W].
    g_s_m2 : float
        Solar aperture g_s [m2].
    f_conv : float
        Convective share of the space-heating heat f_conv [-].
    a_sol_k_m2_per_w : float
        Sol-air factor: T_amb,eq = T_amb + a_sol * q_s [K m2/W].
    t_amb_init_c : float
        Ambient temperature of the initial steady wall profile [degC].
    f_gains_air : float
        Share of the appliance load that heats the air node (0: the paper's model) [-].
    """

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
    """Tariff: ``p_buy = a + b * spot`` [EUR/kWh] (spot in EUR/kWh); constant sell price ``eq:costs``.

    The derivation of a and b from ``sec:results`` and ``sec:heat_recovery`` on the ENTSO-E
    DE-LU day-ahead prices: ``config/plant.yaml``.

    Attributes
    ----------
    buy_offset_eur_per_kwh : float
        Offset a [EUR/kWh].
    buy_spot_factor : float
        Factor b on the spot price (spot in EUR/kWh) [-].
    price_sell_eur_per_kwh : float
        Sell price p_sell (``sec:parameters``) [EUR/kWh].
    """

    buy_offset_eur_per_kwh: float = Phys(-PRICE_MAX_EUR_PER_KWH, PRICE_MAX_EUR_PER_KWH)
    buy_spot_factor: float = Phys(0.01, 10, "a tariff passing on less than 1 % of the spot price is a flat "
                                            "tariff, which a + b * spot does not stand for")
    price_sell_eur_per_kwh: float = Phys(0, PRICE_MAX_EUR_PER_KWH)


class ComfortParams(Section):
    """Comfort bounds, ``eq:T_min``.

    Attributes
    ----------
    t_min_home_c, t_min_away_c : float
        Lower bound T_air,min when at home and when sleeping or away [degC].
    t_max_c : float
        Upper bound T_air,max [degC].
    home_hours_weekday, home_hours_weekend : list of int
        ``[start, end)`` pairs of home hours, local time [h].
    holidays_country, holidays_subdivision : str
        Calendar whose public holidays count as weekend days (ISO 3166 codes).
    discomfort_sample : str
        Where in a step ``eq:discomfort`` reads T_air: ``end``, ``start`` or ``mean``.
    t_max_cooling_c : float
        Upper bound in the cooling season (EN 16798-1 category II) [degC].
    cooling_season_months : list of int
        First and last month of the cooling season, inclusive.
    """

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
    """Check that the ``holidays`` library knows a holiday calendar.

    ``country`` is an ISO 3166-1 alpha-2 code (``DE``), ``subdivision`` one of its
    subdivisions (``BW``) or empty (the national holidays only). A calendar found once is
    remembered on disk for the installed ``holidays`` version
    (:mod:`comems4build_ros.core.result_cache`): ``holidays`` imports every country's calendar to
    look one up, in every process that checks the plant parameters.

    Parameters
    ----------
    country : str
        ISO 3166-1 alpha-2 code.
    subdivision : str
        A subdivision of ``country``, or empty.

    Raises
    ------
    ValueError
        Naming the parameter (``holidays_country``, ``holidays_subdivision``) and, where
        found, the closest known codes.
    """
    from comems4build_ros.core.result_cache import cached

    calendar = {"country": country, "subdivision": subdivision}
    cached("holidays", calendar, [], lambda: _check_holiday_calendar(country, subdivision) or (), dists=("holidays",))


def _check_holiday_calendar(country: str, subdivision: str) -> None:
    """Run :func:`check_holiday_calendar` by asking the ``holidays`` library."""
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
    """Lifecycle and toggling costs, ``tab:degradation_HESS``.

    Attributes
    ----------
    sigma_in_fc_eur : float
        Fuel-cell investment sigma_in,FC [EUR].
    l_fc_h : float
        Fuel-cell life L_FC [h].
    sigma_om_fc_eur_per_h : float
        Fuel-cell operation and maintenance sigma_om,FC [EUR/h].
    sigma_fc_on_eur, sigma_fc_off_eur : float
        Cost of a fuel-cell start and stop sigma_FC,on, sigma_FC,off [EUR].
    sigma_in_b_eur : float
        Battery investment sigma_in,B [EUR].
    sigma_om_b_eur_per_h : float
        Battery operation and maintenance [EUR/h].
    n_b_cycles : float
        Battery cycle life N_B (``eq:batt_lifecycle``) [-].
    """

    sigma_in_fc_eur: float = Phys(0, 1.0e7)
    l_fc_h: float = Phys(100, 1.0e6, "a fiftieth of any PEM stack's lifetime (datasheets: 5000..40000 h)")
    sigma_om_fc_eur_per_h: float = Phys(0, 1.0e3)
    sigma_fc_on_eur: float = Phys(0, 1.0e3)
    sigma_fc_off_eur: float = Phys(0, 1.0e3)
    sigma_in_b_eur: float = Phys(0, 1.0e7)
    sigma_om_b_eur_per_h: float = Phys(0, 1.0e3)
    n_b_cycles: float = Phys(10, 1.0e6, "a fiftieth of the cycle life of lead-acid batteries (about 500)")


class PlantParams(Section):
    """All plant parameters (one section per device).

    Read with :func:`load_plant_params`.

    Attributes
    ----------
    simulation : SimulationParams
    site : SiteParams
    pv : PVParams
    battery : BatteryParams
    fuel_cell : FuelCellParams
    hydrogen : HydrogenParams
    electrolyser : ElectrolyserParams
    heat_pump : HeatPumpParams
    cooling : CoolingParams
    dhw : DHWParams
    building : BuildingParams
    grid : GridParams
    comfort : ComfortParams
    degradation : DegradationParams
    """

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
    "forecast": "forecast mode: --forecast perfect|imperfect|realistic (settings in config/forecast.yaml)",
    "scenario": "scenario generator settings: config/scenario.yaml",
}


def unknown_section_text(key: str) -> str:
    """Explain why a section is not read as a plant section.

    Parameters
    ----------
    key : str
        A top-level section of a user's plant parameter file.

    Returns
    -------
    str
        Where its values go instead (:data:`OTHER_SECTIONS`), or the closest plant section.
    """
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
    """Load and check the plant parameters.

    Parameters
    ----------
    paths : iterable of str or pathlib.Path, optional
        Parameter files merged over the default ``config/plant.yaml`` in order; each may
        hold only plant sections (:data:`PLANT_SECTIONS`).
    overrides : mapping, optional
        ``{"battery.e_max_kwh": 10.0}``-style dotted overrides applied last.

    Returns
    -------
    PlantParams
        The validated parameters.

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
    return parse_model(PlantParams, merged, source)


def table_rows(doc: Any, key: str, row_keys: Sequence[str], class_key: str, source: str,
               what: str) -> Iterator[tuple[str, dict[str, Any], str]]:
    """Yield the checked rows of a table of classes (``config/ems.yaml``, ``config/coordinators.yaml``).

    Parameters
    ----------
    doc : object
        The file's content, ``{key: {name: row}}``.
    key : str
        The table's top-level key.
    row_keys : sequence of str
        The keys every row holds, exactly.
    class_key : str
        The key of the row's ``module:Class``.
    source : str
        The file, for the messages.
    what : str
        What a row is (``EMS``, ``coordinator``), for the messages.

    Yields
    ------
    tuple of (str, dict, str)
        ``(name, row, where)``, ``where`` naming the file and the row for further checks.

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
    """Import the class ``module:Class`` of a table's row, with the ``methods`` a ``kind`` class has.

    Parameters
    ----------
    spec : str
        ``module:Class``.
    methods : sequence of str
        Methods the class must have.
    kind : str
        What the class is (``controller``, ``coordinator``), for the message.
    what : str
        The row, e.g. ``EMS 'rbc'``, for the message.
    error : type of Exception
        The exception raised.

    Returns
    -------
    type
        The class.

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
