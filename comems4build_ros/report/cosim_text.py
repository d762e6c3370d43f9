# ruff: noqa: E501  (the template holds markdown table rows, one per line)
"""The prose of ``docs/cosimulation.md`` around the figures :mod:`comems4build_ros.report.cosim` computes."""

from __future__ import annotations

from typing import Any


def _f(x: Any, digits: int = 1) -> str:
    try:
        return f"{float(x):.{digits}f}"
    except (TypeError, ValueError):
        return "-"


def at_bounds(identified: dict[str, float]) -> str:
    """The identified parameters that ended on a bound of the fit (text), or ``none``."""
    from comems4build_ros.study.identify import FIT_PARAMETERS

    hits = []
    for name, lo, hi, _ in FIT_PARAMETERS:
        value = identified.get(name)
        if value is None:
            continue
        for bound in (lo, hi):
            if abs(value - bound) <= 1e-6 * max(abs(bound), 1e-9):
                hits.append(f"{name} = {value:.3g} (the bound {bound:g})")
    if not hits:
        return "none"
    return "; ".join(hits) + ": the data do not pin it down, the model's other node carries the heat storage"


def document(*, table: str, findings: str, notes: str, held: dict[str, int], evaluated: dict[str, int],
             ratios: str, linearity: str, ident: dict[str, Any], house: dict[str, Any],
             thermostat: dict[str, dict[str, Any]], commands: dict[str, str], changes: str) -> str:
    """The document's markdown: the house, its coupling, the MPC's identified model, then the results."""
    return (_house_part(house, commands) + _COUPLING + _identified_part(ident, commands)
            + _results_part(table=table, findings=findings, notes=notes, held=held, evaluated=evaluated,
                            ratios=ratios, linearity=linearity, thermostat=thermostat, commands=commands,
                            changes=changes))


def _house_part(house: dict[str, Any], commands: dict[str, str]) -> str:
    """Why the study, and the house against its typology."""
    lo, hi = house["heating_kwh_typology_range"]
    return f"""# Co-simulation: the paper's claims on a building the code did not shape

*Written by `{commands['study']}`; every number below comes from that command's runs (the
house's figures also from `{commands['house']}`, the identification also from
`{commands['identify']}`).*

The paper presents ComEMS4Build as "a model- and forecast-free alternative to MPC" suitable
for real-world deployment (abstract), and its last item of future work asks for the test of that claim:
"more detailed models could be utilized for evaluation in a co-simulation environment, where
MPC does not have a perfect forecast" (`sec:conclusion`). In every other run of this project
the plant's building is the 4R3C of `eq:state_update_bldgs`, the very model the MPC plans
with, and the reproduction was calibrated on it. Here the building is a detailed EnergyPlus
model of a German single-family house; the devices (PV, battery, H2 store, fuel cell with
heat recovery, heat pump, hot-water tank) stay as they are, and the MPC plans with a 4R3C
identified from the house's data, as it would on a real house.

## The house

| figure | value | source / command |
|---|---|---|
| typology | TABULA DE.N.SFH.09.Gen (single-family house 1995-2001), advanced refurbishment DE.N.SFH.09.Gen.ReEx.001.003 | IWU, TABULA/EPISCOPE German residential typology |
| heated floor area | {_f(house['heated_floor_m2'])} m2 (TABULA reference area 121.9 m2) in two storeys | `house_idf.HouseSpec` |
| transmission H_tr, typology method | {_f(house['h_tr_typology_w_per_k'])} W/K (TABULA's variant: {_f(house['h_tr_tabula_w_per_k'], 0)} W/K) | `{commands['house']}` |
| ventilation H_ve (infiltration 0.1 1/h, ventilation 0.4 1/h with 80 % heat recovery) | {_f(house['h_ve_typology_w_per_k'])} W/K | `{commands['house']}` |
| heat loss coefficient to the outdoor air, EnergyPlus steady states (-10 and +10 degC) | {_f(house['h_energyplus_w_per_k'])} W/K; the default 4R3C's: {_f(house['h_rc_w_per_k'])} W/K (ratio {_f(house['h_ratio_to_rc'], 3)}, the design rule asks for +-25 %) | `{commands['house']}` |
| design heat load at {_f(house['design_t_amb_c'], 0)} degC, 20 degC inside | EnergyPlus {_f(house['design_load_energyplus_w'], 0)} W; typology H x dT {_f(house['design_load_typology_w'], 0)} W | `{commands['house']}` |
| space heat over the 12 weeks with the thermostat | {_f(house['heating_kwh_thermostat'], 0)} kWh; the typology's quasi-steady method on the same weather, gains and indoor temperature: {_f(lo, 0)} .. {_f(hi, 0)} kWh | `{commands['house']}` |

Geometry and envelope (`comems4build_ros/core/models/house_idf.py`, which writes the
shipped `comems4build_ros/data/energyplus_house_sfh.idf`): a compact box of 7.81 m x 7.81 m,
two storeys of 2.7 m, a flat insulated roof; window area 0.266 of the reference area (the
TABULA ratio of the age band, as tabulated in the TEASER archetype of the TABULA DE
single-family house), 40 % of it facing south; U-values typical of an advanced
refurbishment (wall 0.20 W/m2K plus thermal bridges of 0.05 W/m2K over the envelope, roof
0.14, slab on ground 0.25, triple glazing 0.95 with g = 0.5). They sum to the variant's H_tr
within a few per cent. The ground under the slab follows a monthly temperature of 9.5 to
13.5 degC (choice). Internal gains: the scenario's appliance load, all of it released in the
zones (30 % radiant), and four occupants at home on weekday evenings and nights and all
weekend. Zone time step 15 min.

Underfloor heating: each storey has an electric low-temperature radiant system
(`ZoneHVAC:LowTemperatureRadiant:Electric`) whose heat enters the floor construction at the
pipes' level, between the lower 3.5 cm and the upper 3 cm of the screed
(`ConstructionProperty:InternalHeatSource`): the screed's mass takes it, and the floor's
surface passes it on to the room by convection and radiation; none of it enters the air
directly. The co-simulation drives the systems through their set points (`HalfFlowPower`:
power = capacity x (set point + range/2 - T_air) / range), computed at every system time step
and HVAC iteration from the zone's current air temperature, so that their power is exactly
the heat pump's space heat (split by the floors' areas). Cooling (the year-round plant) enters
as a negative source term at the floors' face. Every step the study checks that the heat the
plant gave equals the heat EnergyPlus reports it received (`Zone Radiant HVAC Heating Rate`,
`Surface Inside Face Heat Source Gain Rate per Area`): the largest relative difference over
the thermostat's twelve weeks was {house['heat_balance_max_rel']:.1e}.

Weather (`comems4build_ros/core/models/epw.py`): the scenario's own series written as an EPW
in local standard time: the DWD temperature of Rheinstetten, the modelled global and diffuse
radiation the PV sees, the direct normal part from them at mid-hour; relative humidity 85 %,
pressure 1005 hPa, wind 3 m/s from the south-west, sky cover 8/10 (6/10 opaque) and albedo
0.2 are choices (the EPW's header names them).

"""


#: How the building model is coupled to the plant (no figures).
_COUPLING = """## How the building is coupled

The building's thermal model is one part of the plant (`BuildingModel`: per step the floor
heat, the weather and the appliance load in, T_air and two further temperatures out, and a
`close`). `--building rc` is the paper's 4R3C (default, runs unchanged bit for bit),
`--building energyplus[:IDF]` runs EnergyPlus 25.2 in the same process through its runtime
API (EnergyPlus in a thread, control handed over in two callbacks per zone time step),
`--building fmu:PATH` an FMI 2.0 co-simulation FMU through fmpy with a variable map. The FMU
path is proven on the project's own model: `comems4build export-fmu` exports the 4R3C with
pythonfmu, and `--building fmu:` that FMU gives the runs of `--building rc` exactly.

EnergyPlus runs inside the process that owns the plant (`simulate`, and the `plant_sim` node
over ROS) rather than as a node of its own: the building is part of the plant's step (the
heat pump's heat goes in, the air temperature comes out within the same step), so a separate
node would add a lock-step exchange per step for no new information, and the in-process and
ROS runs share one code path.

"""


def _identified_part(ident: dict[str, Any], commands: dict[str, str]) -> str:
    """The MPC's 4R3C identified from the house: excitation, fit and held-out prediction errors."""
    v = ident["validation"]
    bounds = at_bounds(ident["identified"])
    e = ident.get("evaluation_weeks_thermostat", {})
    idp = ident["identified"]
    return f"""## The MPC's model, identified

`{commands['identify']}` runs the house over {_f(ident['train']['weeks'], 0)} weeks from
{ident['train']['start'][:10]} (outside the twelve evaluation weeks) under a multi-level
pseudo-random excitation (a heat level of 0, 1/4, ... 1 x {_f(ident['excitation']['q_excite_w'], 0)} W
held for 3 to 12 h, overridden below 18 and above 24.5 degC) and fits the 4R3C's nine
parameters plus `f_gains_air`, the share of the appliance load that heats the air node: the
house has internal gains, the paper's model has no input for them (with 0 it is the paper's
model, and the MPC takes the appliance-load forecast as a fourth input of its building
equations otherwise). The MPC estimates the model's wall nodes from the measured T_air with a
stationary Kalman filter (`--ems-option observer=kalman`).

| figure | value |
|---|---|
| fit RMSE of T_air over the training window | {_f(ident['fit']['fit_rmse_k'], 3)} K |
| 24-h open-loop T_air prediction RMSE, held-out week from {v['start'][:10]} (excitation) | {_f(v['rmse_k'], 3)} K ({v['predictions']} predictions, largest error {_f(v['max_abs_k'], 2)} K) |
| the same on the 12 evaluation weeks under the thermostat (held out) | {_f(e.get('rmse_k'), 3)} K ({e.get('predictions', 0)} predictions, largest error {_f(e.get('max_abs_k'), 2)} K) |
| identified heat loss coefficient | {_f(ident['heat_loss_coefficient_w_per_k'])} W/K |
| identified C_air, C_w | {idp['c_air_j_per_k']:.3g} J/K, {idp['c_wall_j_per_k']:.3g} J/K |
| identified g_s, f_conv, a_sol, f_gains_air | {_f(idp['g_s_m2'], 2)} m2, {_f(idp['f_conv'], 2)}, {_f(idp['a_sol_k_m2_per_w'], 3)} K m2/W, {_f(idp['f_gains_air'], 2)} |
| parameters at a bound of the fit | {bounds} |

"""


def _results_part(*, table: str, findings: str, notes: str, held: dict[str, int], evaluated: dict[str, int],
                  ratios: str, linearity: str, thermostat: dict[str, dict[str, Any]], commands: dict[str, str],
                  changes: str) -> str:
    """The paper's table and findings on both buildings, what changes and why, speed, reproducing."""
    t_rc, t_ep = thermostat.get("rc", {}), thermostat.get("energyplus", {})
    return f"""## The paper's table on the detailed house

Weekly medians over the twelve weeks at the paper's FC system efficiency of 75 %. The MPC on
the EnergyPlus house plans with the identified model and perfect forecasts of the weather,
load and prices (the forecast setting of the study's command); its model of the building is
the only imperfect forecast it has.

{table}
Ratios (the paper's cost ratios and FC operation relative to the MPC):

{ratios}
Linearity of the H2 use (R^2 of the LOH against a straight line over the twelve weeks):

{linearity}
Thermostat baseline: weekly cost median {_f(t_rc.get('cost_eur_week_median'), 2)} EUR on the
4R3C, {_f(t_ep.get('cost_eur_week_median'), 2)} EUR on the EnergyPlus house; discomfort median
{_f(t_rc.get('discomfort_kh_week_median'), 2)} and {_f(t_ep.get('discomfort_kh_week_median'), 2)} Kh/week.

## The paper's findings on both buildings

{held['rc']} of {evaluated['rc']} evaluated findings hold on the 4R3C, {held['energyplus']} of
{evaluated['energyplus']} on the EnergyPlus house (findings at 90 % FC efficiency are n/a: the
study runs the paper's main efficiency only). The co-simulation's headline findings first.

{findings}
### Findings that do not hold on the EnergyPlus house, with the figures behind them

{notes}

![Comfort on both buildings](figures/cosim/cosim_comfort.png)

*Figure.* Top: weekly thermal discomfort (`eq:discomfort`) of each EMS, the 4R3C hatched
beside the EnergyPlus house. Middle and bottom: T_air of each EMS in the week of
ComEMS4Build's largest discomfort on the house, with the comfort band (`eq:T_min`), on the
4R3C and on the house. Written by the study's command (PNG, PDF and SVG in
`DIR/figures/`, copied to `docs/figures/cosim/`). The reports of each building, with the
figures `compare` draws, are in `DIR/rc/` and `DIR/energyplus/`.

## What changes on the detailed house, and why

{changes}

## Speed

`comems4build bench cosim --identified DIR/identified.yaml` prints, with the load average,
the wall time of ComEMS4Build's twelve weeks on the EnergyPlus house (target under 60 s on
2 cores), of the MPC's twelve weeks on it (target under 15 min) and the FMU path's overhead
over the in-process 4R3C (target at most 3x); the figures depend on the machine's load and
are not repeated here.

## Reproducing

```
{commands['house']}
{commands['identify']}
{commands['study']}
```
"""
