# ruff: noqa: E501  (the template holds markdown table rows, one per line)
"""The prose of ``docs/cosimulation.md`` around the figures :mod:`comems4build_ros.report.cosim` computes."""

from __future__ import annotations

from typing import Any


def _f(x: Any, digits: int = 1) -> str:
    try:
        return f"{float(x):.{digits}f}"
    except (TypeError, ValueError):
        return "-"


def at_bounds(ident: dict[str, Any]) -> str:
    """The fitted quantities that ended on a physical bound of the fit (text), or ``none``."""
    names = ident.get("at_bounds", [])
    if not names:
        return "none"
    bounds = {b["name"]: b for b in ident.get("bounds", [])}
    fitted = ident.get("fitted", {})
    return "; ".join(f"{n} = {fitted.get(n, float('nan')):.3g} (bounds {bounds[n]['lo']:.3g} .. {bounds[n]['hi']:.3g}: "
                     f"{bounds[n]['reason']})" if n in bounds else n for n in names)


def bounds_table(ident: dict[str, Any]) -> str:
    """The fit's physical bounds and where each fitted quantity ended, as markdown rows."""
    fitted = ident.get("fitted", {})
    rows = ["| fitted quantity | identified | lower bound | upper bound | bounds from |", "|---|---|---|---|---|"]
    for b in ident.get("bounds", []):
        rows.append(f"| {b['name']} | {fitted.get(b['name'], float('nan')):.3g} | {b['lo']:.3g} | {b['hi']:.3g} | "
                    f"{b['reason']} |")
    return "\n".join(rows) + "\n"


def side_by_side(house: dict[str, Any]) -> str:
    """The ``comems4build house`` lines as a markdown table."""
    rows = ["| line | unit | EnergyPlus house | 4R3C | tolerance | result |", "|---|---|---|---|---|---|"]
    for line in house.get("lines", []):
        result = {True: "pass", False: "**fail**", None: "-"}[line["pass"]]
        rows.append(f"| {line['name']} | {line['unit']} | {_f(line['energyplus'], 2)} | {_f(line['rc'], 2)} | "
                    f"{line['tolerance']} | {result} |")
    return "\n".join(rows) + "\n"


def side_by_side_notes(house: dict[str, Any]) -> str:
    """The notes of the ``comems4build house`` lines as a markdown list."""
    return "\n".join(f"- {line['name']}: {line['note']}." for line in house.get("lines", []) if line["note"]) + "\n"


def _differences(house: dict[str, Any]) -> str:
    """The lines outside their tolerance, with both figures, as a sentence."""
    failed = [line for line in house.get("lines", []) if line["pass"] is False]
    if not failed:
        return "every line lies within its tolerance."
    return "; ".join(f"{line['name']}: {_f(line['energyplus'], 2)} {line['unit']} in EnergyPlus against "
                     f"{_f(line['rc'], 2)} {line['unit']} in the 4R3C (tolerance {line['tolerance']})"
                     for line in failed) + "."


def document(*, table: str, findings: str, notes: str, held: dict[str, int], evaluated: dict[str, int],
             ratios: str, linearity: str, ident: dict[str, Any], house: dict[str, Any],
             thermostat: dict[str, dict[str, Any]], commands: dict[str, str], changes: str) -> str:
    """The document's markdown: the house, its coupling, the MPC's identified model, then the results."""
    return (_house_part(house, commands) + _COUPLING + _identified_part(ident, commands)
            + _results_part(table=table, findings=findings, notes=notes, held=held, evaluated=evaluated,
                            ratios=ratios, linearity=linearity, thermostat=thermostat, commands=commands,
                            changes=changes))


def _house_part(house: dict[str, Any], commands: dict[str, str]) -> str:
    """Why the study, and the house beside the 4R3C."""
    return f"""# Co-simulation: the paper's claims on a detailed model of the same house

*Written by `{commands['study']}`; every number below comes from that command's runs (the
house's figures also from `{commands['house']}`, the identification also from
`{commands['identify']}`).*

The paper presents ComEMS4Build as "a model- and forecast-free alternative to MPC" suitable
for real-world deployment (abstract), and its last item of future work asks for the test of that claim:
"more detailed models could be utilized for evaluation in a co-simulation environment, where
MPC does not have a perfect forecast" (`sec:conclusion`). In every other run of this project
the plant's building is the 4R3C of `eq:state_update_bldgs`, the very model the MPC plans
with, and the reproduction was calibrated on it. Here the building is a detailed EnergyPlus
model of a German single-family house, built to be the house the 4R3C describes; the devices
(PV, battery, H2 store, fuel cell with heat recovery, heat pump, hot-water tank) stay as they
are, and the MPC plans with a 4R3C identified from the house's data, as it would on a real
house: the house's multi-zone dynamics, its floor heating in the screed and its sun are what
the paper's model and the MPC's do not see.

## The house

The EnergyPlus house is built to be the house the 4R3C describes, so that the two runs
compare one house in two models. `{commands['house']}` measures both the same way, each
through the plant's building-model interface (per hour the floor heat and the weather in,
T_air out), and sets them side by side with a tolerance per line:

{side_by_side(house)}
{side_by_side_notes(house)}
How each line is measured: the heat loss coefficient from two steady states (air held at
20 degC by an hourly PI thermostat, no sun, no gains, outdoor -10 and +10 degC); the effective
heat capacity from a day's free cool-down after the +10 degC steady state (C_eff = H_total
tau); the solar aperture of the windows as the heat the sun through the windows saves over the
winter weeks, per kWh/m2 of horizontal irradiation (runs with and without the sun, and with
the sun on the windows only); the heat demand of the {_f(house['winter_weeks'], 0)} winter weeks
from 2022-12-01 under the same hourly PI on both, holding T_air at T_air,min (`eq:T_min`) with the heat pump's capacity as
its limit; the summer over the year scenario (2022-03-01 to 2023-02-28) under the same PI
without cooling. The
tolerances: H +-10 % (alone it moves the demand by as much), the capacity +-25 % (within one
mass class of EN ISO 13790), the solar aperture +-25 % (the sun is 5-15 % of the winter's
losses), the winter demand +-10 %; DIN 4108-2:2013-02 limits the overtemperature degree hours
of residential buildings to 1200 Kh/a above 27 degC in summer climate region C (the Upper
Rhine valley; 25 and 26 degC in regions A and B).

What was moved, and why (`comems4build_ros/core/models/house_idf.py`, which writes
the shipped `comems4build_ros/data/energyplus_house_sfh.idf`): the house keeps its typology,
TABULA DE.N.SFH.09.Gen (single-family house 1995-2001) in the advanced refurbishment
DE.N.SFH.09.Gen.ReEx.001.003 (IWU, TABULA/EPISCOPE German residential typology): heated
floor area {_f(house['heated_floor_m2'])} m2 (TABULA reference area 121.9 m2) in two storeys,
H_tr {_f(house['h_tr_typology_w_per_k'])} W/K by the typology's method (TABULA's variant:
{_f(house['h_tr_tabula_w_per_k'], 0)} W/K), H_ve {_f(house['h_ve_typology_w_per_k'])} W/K
(infiltration 0.1 1/h, ventilation 0.4 1/h with 80 % heat recovery, over TABULA's room height
of 2.5 m); the design heat load at {_f(house['design_t_amb_c'], 0)} degC and 20 degC inside is
{_f(house['design_load_energyplus_w'], 0)} W in EnergyPlus, {_f(house['design_load_typology_w'], 0)} W
by the typology's H x dT. Toward the 4R3C's house:

- *Internal gains*: none in either model. The paper's building model has no internal-gain
  input (`eq:dT_i`), and the 4R3C's heat loss coefficient is calibrated to the paper's energy
  flows with that model (`docs/calibration.md`, `building_envelope`), so the appliance
  load's heat, which EN ISO 13790 and DIN V 18599 count as a gain, is already lumped into its
  parameters. The EnergyPlus house receives the appliance load's electricity with all of its
  heat lost, and no occupants.
- *Windows*: 32.4 m2 (TABULA's window ratio of the age band), facing as the windows of
  TABULA's example building of the type (south 5.0, east 3.6, north 20.3, west 3.6 m2), with
  TABULA's solar conventions (g_gl,n = 0.5, frame area fraction 0.3, reduction factor for external shading
  0.6 in the heating season) as the whole window's solar heat gain coefficient 0.21.
- *Thermal mass*: a timber-frame construction (sheathed timber-frame walls, a timber joist
  storey floor, drywall partitions; the floors keep their 6.5 cm screed for the underfloor
  heating), chosen for the 4R3C's effective capacity (whose capacities come from the
  identified house of Sperber, Frey and Bertsch 2020); the masonry variant of the same house
  (sand-lime walls, a concrete storey slab, masonry partitions; `HouseSpec.construction`) has
  about twice that capacity.
- *Summer*: from May to September exterior sun protection closes on a window receiving more
  than 300 W/m2 (200 W/m2 facing north; DIN 4108-2's thresholds for residential buildings),
  and the windows open (3 1/h by day, 2 1/h at night) while the room is above 23 degC and
  warmer than outside (choice after that standard's increased day and night ventilation).

What is not the same house: {_differences(house)} The EnergyPlus house loses heat to the
ground under its slab as well, which the 4R3C does not have (the first line's note).

The ground under the slab follows a monthly temperature of 9.5 to 13.5 degC (choice). Zone
time step 15 min.

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
the {_f(house['winter_weeks'], 0)} winter weeks of `{commands['house']}` was {house['heat_balance_max_rel']:.1e}.

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
    bounds = at_bounds(ident)
    e = ident.get("evaluation_weeks_thermostat", {})
    idp = ident["identified"]
    return f"""## The MPC's model, identified

`{commands['identify']}` runs the house over {_f(ident['train']['weeks'], 0)} weeks from
{ident['train']['start'][:10]} (outside the twelve evaluation weeks) under a multi-level
pseudo-random excitation (a heat level of 0, 1/4, ... 1 x {_f(ident['excitation']['q_excite_w'], 0)} W
held for 3 to 12 h, overridden below 18 and above 24.5 degC) and fits the 4R3C's nine
parameters plus `f_gains_air`, the share of the appliance load that heats the air node (with
0 it is the paper's model; otherwise the MPC takes the appliance-load forecast as a fourth
input of its building equations). The resistances are fitted as the heat loss coefficient H,
the air path's share of it and the split of the wall chain, so that each fitted quantity has
a physical bound taken from the house; a quantity that ends on a bound is named below. The MPC
estimates the model's wall nodes from the measured T_air with a stationary Kalman filter
(`--ems-option observer=kalman`).

{bounds_table(ident)}
| figure | value |
|---|---|
| fit RMSE of T_air over the training window | {_f(ident['fit']['fit_rmse_k'], 3)} K |
| 24-h open-loop T_air prediction RMSE, held-out week from {v['start'][:10]} (excitation) | {_f(v['rmse_k'], 3)} K ({v['predictions']} predictions, largest error {_f(v['max_abs_k'], 2)} K) |
| the same on the 12 evaluation weeks under the thermostat (held out) | {_f(e.get('rmse_k'), 3)} K ({e.get('predictions', 0)} predictions, largest error {_f(e.get('max_abs_k'), 2)} K) |
| identified heat loss coefficient | {_f(ident['heat_loss_coefficient_w_per_k'])} W/K |
| identified C_air, C_w | {idp['c_air_j_per_k']:.3g} J/K, {idp['c_wall_j_per_k']:.3g} J/K |
| identified g_s, f_conv, a_sol, f_gains_air | {_f(idp['g_s_m2'], 2)} m2, {_f(idp['f_conv'], 2)}, {_f(idp['a_sol_k_m2_per_w'], 3)} K m2/W, {_f(idp['f_gains_air'], 2)} |
| fitted quantities at a bound | {bounds} |

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
