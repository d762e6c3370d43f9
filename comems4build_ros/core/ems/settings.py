"""One settings class per controller: every option with its unit, meaning and source.

Each controller of the EMS table (``config/ems.yaml``) is built from one frozen settings
object, read by one function, :func:`load_settings`:

============================  ===========================================================
settings                      read from (its values are the defaults; the file gives sources)
============================  ===========================================================
:class:`ThermostatSettings`   ``config/thermostat.yaml``, section ``thermostat``
:class:`RBCSettings`          ``config/rbc.yaml``, section ``rbc`` (``sec:RBC``)
:class:`FuzzySettings`        ``config/fuzzy/{flex,fc,battery,el}.yaml``, sections ``flc_flex``,
                              ``flc_fc``, ``flc_b``, ``flc_el`` (``sec:FLC``, ``sec:appendix``)
:class:`MILPSettings`         ``config/mpc.yaml``, section ``mpc`` over ``/**`` (``sec:MPC``)
:class:`QPSettings`           ``config/mpc.yaml``, section ``mpc_qp`` over ``/**``
============================  ===========================================================

Options (``--ems-option KEY=VALUE``, a study's ``ems_options``, the EMS node's parameter
``ems_options``) are applied over the file's values and the result is checked once by the
rules of :class:`~comems4build_ros.core.config.Section`: unknown keys are named, a boolean
is no number and a number no boolean, inf and NaN are refused, and each field's range
holds. A bad value raises :class:`~comems4build_ros.core.config.ConfigError` naming the
file, the section and the option. The defaults live in the files only (each value there
carries its source), so a field here has no default of its own (only a fuzzy section
without a rule list has none).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal, TypeVar

from pydantic import ConfigDict, Field, model_validator

from comems4build_ros.core.config import (
    ConfigError,
    Phys,
    Section,
    config_dir,
    deep_merge,
    parse_model,
    read_ros_params,
    set_dotted,
)

#: Option naming another parameter file to read instead of a controller's shipped one.
CONFIG_OPTION = "config"
#: Shortest time limit of one MPC solve [s]: below the solve time of the 24-h horizon (median
#: 33 ms on a quiet machine, docs/mpc.md), no solve finishes and the MPC decides nothing.
MIN_SOLVE_S = 0.1
#: Why no time limit below :data:`MIN_SOLVE_S` is real (said in a refusal).
SOLVE_WHY = "the 24-h horizon's solves take a median 33 ms on a quiet machine (docs/mpc.md); less decides nothing"


@dataclass(frozen=True)
class SettingsFile:
    """Where a controller's settings, or one part of them, are read.

    Parameters
    ----------
    name : str
        File name below ``config/``.
    node : str or None
        ROS node whose section is merged over the file's ``/**`` section (None: every
        section of the file, in file order).
    section : str or None
        Mapping below ``ros__parameters`` that holds the settings (None: all of it).
    """

    name: str
    node: str | None
    section: str | None = None


class Settings(Section):
    """A group of controller options under the :class:`~comems4build_ros.core.config.Section` rules.

    Each field is documented by the docstring below it (also its pydantic description).
    """

    model_config = ConfigDict(use_attribute_docstrings=True)


class ControllerSettings(Settings):
    """The settings of one controller and where :func:`load_settings` reads them.

    ``FILES`` maps ``""`` to the one file of a controller whose fields are the file's
    section; a controller read from several files (the fuzzy EMS) maps each field that
    holds one file's section to that file instead.
    """

    FILES: ClassVar[Mapping[str, SettingsFile]] = {}
    #: The controller's name in messages about its options.
    LABEL: ClassVar[str] = ""


S = TypeVar("S", bound=ControllerSettings)


def _read(path: Path, where: SettingsFile) -> dict[str, Any]:
    """Read the values of ``where`` in the parameter file ``path`` (a new dict)."""
    data = read_ros_params(path, node=where.node)
    if where.section is None:
        return data
    section = data.get(where.section)
    if not isinstance(section, Mapping):
        raise ConfigError(f"{path}: no section '{where.section}' (a mapping) under ros__parameters")
    return deep_merge({}, section)


def _label(path: Path, where: SettingsFile, changed: bool) -> str:
    return f"{path} [{where.section or where.node}]" + (" + options" if changed else "")


def load_settings(cls: type[S], options: Mapping[str, Any] | None = None) -> S:
    """Read the settings ``cls`` of a controller: its files' values with ``options`` applied, checked once.

    Parameters
    ----------
    cls : type[ControllerSettings]
        The settings class (e.g. :class:`RBCSettings`).
    options : Mapping[str, Any], optional
        Option -> value (``--ems-option KEY=VALUE`` as parsed). A controller read
        from one file takes ``config`` (another parameter file read instead of the shipped
        one) and its fields: a value replaces the file's, a dotted key reaches into a
        mapping (``highs_options.presolve``). The fuzzy EMS takes ``<flc>_file`` (another
        rule file) and ``<flc>`` for each of its controllers: overrides merged key by key
        over that file's section (``fc.fc.cap_to_demand``, ``flex.inputs.price.terms``).

    Returns
    -------
    S
        The checked settings, an instance of ``cls``.

    Raises
    ------
    ConfigError
        Naming the file, the section and the option that is unknown, missing or invalid.
    """
    if "" in cls.FILES:  # one file: the settings are its section
        where = cls.FILES[""]
        opts = dict(options or {})
        path = Path(opts.pop(CONFIG_OPTION, None) or config_dir() / where.name)
        data = _read(path, where)
        source = _label(path, where, bool(opts))
        for key, value in opts.items():
            try:
                set_dotted(data, str(key), value)
            except ConfigError as exc:
                raise ConfigError(f"{source}: {exc}") from None
        return parse_model(cls, data, source)
    opts = {}
    for key, value in (options or {}).items():
        set_dotted(opts, str(key), value)
    known = [*cls.FILES, *(f"{k}_file" for k in cls.FILES)]
    unknown = sorted(set(opts) - set(known))
    if unknown:
        raise ConfigError(f"{cls.LABEL} options: unknown option(s) {', '.join(unknown)} "
                          f"(known: {', '.join(sorted(known))})")
    parts: dict[str, Any] = {}
    for key, where in cls.FILES.items():
        path = Path(opts.get(f"{key}_file") or config_dir() / where.name)
        overrides = opts.get(key) or {}
        if not isinstance(overrides, Mapping):
            raise ConfigError(f"{cls.LABEL} options: '{key}' must be a mapping of overrides for {path}")
        section = deep_merge(_read(path, where), overrides)
        parts[key] = parse_model(cls.model_fields[key].annotation, section, _label(path, where, bool(overrides)),
                                 prefix=f"{key}.")
        parts[f"{key}_file"] = str(path)
    return cls(**parts)


# ============================================================================ thermostat


class ThermostatSettings(ControllerSettings):
    """The plain on/off thermostat (``--ems thermostat``; not a controller of the paper).

    Hot water first, then the room, each by a hysteresis; every value is a choice of this
    baseline (``config/thermostat.yaml``).
    """

    FILES: ClassVar[Mapping[str, SettingsFile]] = {"": SettingsFile("thermostat.yaml", "thermostat_ems",
                                                                    "thermostat")}
    LABEL: ClassVar[str] = "thermostat EMS"

    sh_on_k: float = Field(ge=0)
    """Room heating switches on below T_air,min + this [K]."""
    sh_off_k: float = Field(ge=0)
    """Room heating switches off above T_air,min + this [K]; above ``sh_on_k``."""
    dhw_on_fill: float = Field(ge=0, le=1)
    """Tank heating switches on below this fill of the usable volume V_DHW,min .. V_DHW,max [-]."""
    dhw_off_fill: float = Field(ge=0, le=1)
    """Tank heating switches off at or above this fill [-]; above ``dhw_on_fill``."""

    @model_validator(mode="after")
    def _check(self) -> ThermostatSettings:
        for low, high in (("sh_on_k", "sh_off_k"), ("dhw_on_fill", "dhw_off_fill")):
            if not getattr(self, low) < getattr(self, high):
                raise ValueError(f"{low} ({getattr(self, low)}) must be below {high} ({getattr(self, high)})")
        return self


# ============================================================================ RBC


class RBCSettings(ControllerSettings):
    """The paper's rule-based controller (``--ems rbc``, ``sec:RBC``).

    Each hysteresis switches on at or below its ``*_on_chi`` and off at or above its
    ``*_off_chi``, so ``on`` must lie below ``off``; the EDF quartile that charges from
    the grid must lie below the one that runs the FC. Sources of the values:
    ``config/rbc.yaml``.
    """

    FILES: ClassVar[Mapping[str, SettingsFile]] = {"": SettingsFile("rbc.yaml", "rbc_ems", "rbc")}
    LABEL: ClassVar[str] = "RBC"

    sh_on_chi: float = Field(ge=0, le=1)
    """Room heating on at or below this thermal state chi_SH (``eq:s_sh`` with T_air,min[k]) [-]."""
    sh_off_chi: float = Field(ge=0, le=1)
    """Room heating off at or above this chi_SH [-] (1: at T_air,max, ``sec:results``)."""
    dhw_on_chi: float = Field(ge=0, le=1)
    """Tank heating on at or below this thermal state chi_DHW (``eq:s_dhw``) [-]."""
    dhw_off_chi: float = Field(ge=0, le=1)
    """Tank heating off at or above this chi_DHW [-]."""
    hp_mod_on: float = Field(gt=0, le=1)
    """Heat pump modulation while it heats or cools [-] (1: full power, a hysteresis)."""
    p_el_ref_t_amb_c: float
    """Ambient temperature at which dP estimates the heat pump's intake P_el,max [degC]
    (the RBC does not see T_amb; EN 14511 rating point A2)."""
    edf_upper_quartile: float = Field(ge=0, le=1)
    """The FC runs when dP < 0 and the EDF price (``eq:EDF_prices``) is above this [-] (``sec:RBC``)."""
    edf_lower_quartile: float = Field(ge=0, le=1)
    """The battery charges at full power from the grid when the EDF price is at or below this [-]."""
    loh_reserve: float = Field(ge=0, le=1)
    """The RBC's own lower limit of the H2 store: no FC at or below it [-] (``sec:results``)."""
    cool_off_chi: float = Field(gt=0, le=1)
    """Year-round plant: cooling off at or above this thermal state towards T_air,max [-]
    (on at 0; not in the paper)."""
    p_el_ref_cool_t_amb_c: float
    """Ambient temperature at which dP estimates the cooling intake Q_cool,max / EER [degC]
    (EN 14511 cooling rating point A35)."""

    @model_validator(mode="after")
    def _check(self) -> RBCSettings:
        for low, high in (("sh_on_chi", "sh_off_chi"), ("dhw_on_chi", "dhw_off_chi"),
                          ("edf_lower_quartile", "edf_upper_quartile")):
            if not getattr(self, low) < getattr(self, high):
                raise ValueError(f"{low} ({getattr(self, low)}) must be below {high} ({getattr(self, high)})")
        return self


# ============================================================================ ComEMS4Build (fuzzy)


class FlexOptions(Settings):
    """Post-processing of FLC_flex's output alpha_HP (group ``hp`` of ``flc_flex``)."""

    update: Literal["increment", "level"]
    """How alpha_HP sets the modulation: ``increment``: eta_HP[k] = Q(eta_HP[k-1] + alpha_HP);
    ``level``: eta_HP[k] = Q(alpha_HP), Q snapping to {0} U [mod_min, 1]
    (:func:`~comems4build_ros.core.ems.features.update_modulation`)."""
    p_el_ref_t_amb_c: float
    """Ambient temperature at which dP estimates the heat pump's intake P_el,max [degC]
    (the EMS does not see T_amb; EN 14511 rating point A2)."""
    dhw_priority_chi: float = Field(ge=0, le=1)
    """The heat pump serves the tank when chi_DHW <= chi_SH or chi_DHW is below this [-]
    (DHW priority, ``sec:results``)."""
    cool_below_chi: float = Field(ge=0, le=1)
    """Year-round plant with cooling: the heat pump cools when chi_cool is below this [-]
    (not in the paper)."""
    p_el_ref_cool_t_amb_c: float
    """Ambient temperature at which dP estimates the cooling intake Q_cool,max / EER [degC]
    (EN 14511 cooling rating point A35)."""


class FCOptions(Settings):
    """Post-processing of FLC_FC's output alpha_FC (group ``fc`` of ``flc_fc``)."""

    cap_to_demand: bool
    """Cap P_el,FC = alpha_FC * zeta * P_FC,max at the demand -dP (``sec:FLC``); false: a
    surplus goes to FLC_B (``sec:appendix``)."""
    stop_when_allowance_used: bool
    """No FC once today's permissible H2 (``eq:deltaLOH``) is used up."""
    h2_allowance: Literal["fixed", "rolling"]
    """The daily H2 allowance ``eq:deltaLOH``: ``rolling`` re-evaluates it each day with the
    current LOH over the remaining days; ``fixed`` books dLOH of LOH_init every day
    (:class:`~comems4build_ros.core.ems.features.DailyH2Allowance`)."""


class BatteryOptions(Settings):
    """Post-processing of FLC_B's output alpha_B (group ``battery`` of ``flc_b``)."""

    absorb_surplus: bool
    """With surplus (dP_new > 0) and alpha_B > 0 the battery takes at least the surplus, up
    to P_ch,max (the paper gives the charging formula only for the demand case)."""


class ELOptions(Settings):
    """Post-processing of FLC_EL's output alpha_EL (group ``el`` of ``flc_el``; not in the paper)."""

    cap_to_surplus: bool
    """Cap P_EL at the PV surplus dP, so the electrolyser never runs on bought or battery power."""


class FLCSection(Settings):
    """One fuzzy controller's section of its rule file: its rule base.

    The engine (:func:`~comems4build_ros.core.ems.fuzzy.engine.build_system`) checks the
    rule base and names the variable, term or rule at fault.
    """

    inputs: Any
    """The input variables: ``order`` and, per input, its universe and terms (points
    [a, b, c] of a triangle or [a, b, c, d] of a trapezoid, or device quantities by name;
    ``fig:all_memb_functions``)."""
    output: Any
    """The output variable: name, universe, grid points and terms."""
    rules_paper: Any = Field(default_factory=list)
    """The paper's rules (``tab:FLCflex_rules``, ``tab:FLCfc_rules``, ``tab:FLCb_rules``);
    none when the section has no such list."""
    rules_design: Any = Field(default_factory=list)
    """Our rules beside the paper's, which together cover every combination of input terms
    once; none when the section has no such list."""


class LoadFLCSection(FLCSection):
    """The section of a fuzzy controller with a power input (dP or dP_new): its rule base and load scale."""

    load_scale_w: float = Field(gt=0)
    """Power the load input is divided by [W] (``sec:appendix``: loads normalised on 10 kW);
    the device quantities ``dp_*``, ``p_ch``, ``p_d`` of the membership points are divided
    by it too."""


class FlexSection(FLCSection):
    """FLC_flex: the flexible heating load (section ``flc_flex`` of ``config/fuzzy/flex.yaml``)."""

    hp: FlexOptions
    """How alpha_HP becomes the heat pump's set-points."""


class FCSection(LoadFLCSection):
    """FLC_FC: the fuel cell's power (section ``flc_fc`` of ``config/fuzzy/fc.yaml``)."""

    fc: FCOptions
    """How alpha_FC becomes the fuel cell's power."""


class BatterySection(LoadFLCSection):
    """FLC_B: the battery's power (section ``flc_b`` of ``config/fuzzy/battery.yaml``)."""

    battery: BatteryOptions
    """How alpha_B becomes the battery's power."""


class ELSection(LoadFLCSection):
    """FLC_EL: the electrolyser's power (section ``flc_el`` of ``config/fuzzy/el.yaml``; not in the paper)."""

    el: ELOptions
    """How alpha_EL becomes the electrolyser's power."""


class FuzzySettings(ControllerSettings):
    """ComEMS4Build, the hierarchical fuzzy EMS (``--ems fuzzy``, ``sec:FLC``).

    One rule file per fuzzy controller; an option ``<flc>_file`` reads another file, an
    option ``<flc>.<key>`` overrides a value of its section (``fc.fc.cap_to_demand``,
    ``flex.rules_design``). FLC_EL is read always and used only by a plant with an
    electrolyser.
    """

    FILES: ClassVar[Mapping[str, SettingsFile]] = {
        "flex": SettingsFile("fuzzy/flex.yaml", None, "flc_flex"),
        "fc": SettingsFile("fuzzy/fc.yaml", None, "flc_fc"),
        "battery": SettingsFile("fuzzy/battery.yaml", None, "flc_b"),
        "el": SettingsFile("fuzzy/el.yaml", None, "flc_el"),
    }
    LABEL: ClassVar[str] = "fuzzy EMS"

    flex_file: str
    """The rule file FLC_flex was read from."""
    flex: FlexSection
    """FLC_flex: min(chi_SH, chi_DHW), LOH, SOC, EDF, q_s -> alpha_HP (``tab:FLCflex_rules``)."""
    fc_file: str
    """The rule file FLC_FC was read from."""
    fc: FCSection
    """FLC_FC: dP, dLOH share, SOC, EDF, s_on/off -> alpha_FC (``tab:FLCfc_rules``)."""
    battery_file: str
    """The rule file FLC_B was read from."""
    battery: BatterySection
    """FLC_B: dP_new, SOC, EDF -> alpha_B (``tab:FLCb_rules``)."""
    el_file: str
    """The rule file FLC_EL was read from."""
    el: ELSection
    """FLC_EL: dP, SOC, LOH, EDF, days to the heating season -> alpha_EL (not in the paper)."""


# ============================================================================ MPC


class _MPCSettings(ControllerSettings):
    """What both MPC variants share (section ``/**`` of ``config/mpc.yaml``)."""

    LABEL: ClassVar[str] = "MPC"

    loh_min_mode: Literal["day", "step"]
    """``eq:LOHmin_MPC``: ``day``: the LOH_min of the current day bounds every step of the
    horizon (the paper); ``step``: each step gets the LOH_min of the day it falls in."""
    fc_lifecycle_eta: Literal["eta_el_mpc", "eta_sys", "one"]
    """Efficiency eta_i dividing the FC's cost per operating hour in
    ``eq:batt_andFC_operation_degradation`` (``tab:degradation_HESS``): ``one``,
    ``eta_sys`` (eta_FC,sys) or ``eta_el_mpc`` (the MPC's constant eta_el)."""
    fc_heat_dump: bool
    """false: every kWh of recovered FC heat enters the tank (``eq:DHW_heat`` as printed);
    true: the model may dump heat the full tank cannot take."""
    penalty_comfort_eur_per_kh: float = Field(gt=0)
    """Soft bound: T_air outside [T_air,min, T_air,max] [EUR per K and hour]."""
    penalty_dhw_eur_per_lh: float = Field(gt=0)
    """Soft bound: V_DHW outside [V_DHW,min, V_DHW,max] [EUR per litre and hour]."""
    penalty_soc_eur_per_h: float = Field(gt=0)
    """Soft bound: SOC outside [SOC_min, SOC_max] [EUR per unit SOC and hour]."""
    penalty_loh_eur_per_h: float = Field(gt=0)
    """Soft bound: LOH below LOH_min [EUR per unit LOH and hour]."""
    slack_report_tol: float = Field(gt=0)
    """A slack above this counts as used in the step's report [unit of its bound: K, l or -]."""


class MILPSettings(_MPCSettings):
    """The cost-optimal MILP MPC (``--ems mpc``, ``sec:MPC``; section ``mpc`` of ``config/mpc.yaml``).

    ``docs/mpc.md`` gives the measurements behind the solver settings.
    """

    FILES: ClassVar[Mapping[str, SettingsFile]] = {"": SettingsFile("mpc.yaml", "mpc")}

    solver: Literal["highs", "highs_pulp", "cbc", "gurobi"]
    """MILP solver: HiGHS through highspy, HiGHS through PuLP, PuLP's CBC, or gurobipy."""
    mip_rel_gap: float = Field(ge=0, lt=1)
    """Relative MIP gap at which a solve stops [-]."""
    time_limit_s: float = Phys(MIN_SOLVE_S, 86400.0, SOLVE_WHY)
    """Time limit of one solve [s], 0.1 s .. a day; the best solution found is used, none gives the
    safe fallback."""
    threads: int = Field(ge=1)
    """Solver threads [-]."""
    warm_start: bool
    """Start each solve from the previous plan shifted by one step."""
    formulation: Literal["tight", "paper"]
    """``tight``: semicontinuous heat pump powers, one battery binary; ``paper``: the literal
    formulation with a loose big-M."""
    integer_steps: int = Field(ge=1)
    """Horizon steps whose binaries stay binary [-]; the later steps' binaries are relaxed to 0..1."""
    relax_battery_binary: bool
    """Relax the battery's charge/discharge binary (``eq:bat_ch_dis_const``) when the sell price is >= 0."""
    big_m_loose_w: float = Field(gt=0)
    """Big-M of the ``paper`` formulation [W]."""
    log_fallback: bool
    """Print a line to stderr for every fallback step."""
    highs_options: dict[str, bool | int | float | str]
    """HiGHS options, name -> value."""
    gurobi_options: dict[str, bool | int | float | str]
    """Gurobi parameters, name -> value."""
    loh_season_target: float = Field(ge=0, le=1)
    """Year-round plant: the LOH the store's seasonal target rises to by the next heating
    season [-] (not in the paper)."""
    penalty_loh_season_eur_per_h: float = Field(ge=0)
    """Year-round plant: penalty on a deficit below the seasonal target [EUR per unit LOH and hour]."""
    h2_value_eur_per_kwh: float = Field(ge=0)
    """Year-round plant: value of the stored H2 at the end of the horizon outside the heating
    season [EUR per kWh LHV]."""
    sigma_el_on_eur: float = Field(ge=0)
    """Year-round plant: start cost of the electrolyser [EUR]."""
    observer: Literal["measured", "kalman"]
    """The building's wall temperatures: ``measured`` from the plant (``tab:level_of_information``)
    or ``kalman``: estimated from T_air by a stationary Kalman filter."""


class QPSettings(_MPCSettings):
    """The MPC's horizon problem relaxed to a QP for OSQP (``--ems mpc-qp``; section ``mpc_qp``)."""

    FILES: ClassVar[Mapping[str, SettingsFile]] = {"": SettingsFile("mpc.yaml", "mpc_qp")}

    w_fc_smooth_eur_per_kw2: float = Field(ge=0)
    """Weight of (P_FC[t] - P_FC[t-1])^2, in place of the start/stop binaries [EUR/kW2]."""
    w_comfort_track_eur_per_k2: float = Field(ge=0)
    """Weight of (T_air - (T_air,min + comfort_margin_k))^2 [EUR/K2]."""
    comfort_margin_k: float = Field(ge=0)
    """Margin above T_air,min the room temperature is drawn to [K]."""
    w_reg_eur_per_kw2: float = Field(gt=0)
    """Ridge on every power, so the problem is strictly convex [EUR/kW2]."""
    eps_abs: float = Field(gt=0)
    """OSQP's absolute tolerance of the residuals [-] (of the problem as OSQP scales it)."""
    eps_rel: float = Field(gt=0)
    """OSQP's relative tolerance of the residuals [-]."""
    max_iter: int = Field(gt=0)
    """OSQP's iteration limit [-]."""
    polish: bool
    """Polish OSQP's solution."""
    time_limit_s: float = Phys(MIN_SOLVE_S, 86400.0, SOLVE_WHY)
    """Time limit of one solve [s], 0.1 s .. a day."""
