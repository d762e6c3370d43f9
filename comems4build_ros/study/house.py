"""The co-simulation house against its typology: heat loss coefficient, design heat load, heating demand.

Three figures of the EnergyPlus house (``comems4build house`` prints them):

1. **Heat loss coefficient.** By the typology's method (sum of U A b plus ventilation,
   :func:`~comems4build_ros.core.models.house_idf.heat_loss_coefficient`), and measured
   in EnergyPlus: two steady states with the air held at 20 degC, no sun, no internal gains,
   at constant outdoor temperatures of -10 and +10 degC; H_amb = (Q(-10) - Q(+10)) / 20 K is the
   coefficient towards the outdoor air (the ground under the slab keeps its own temperature).
   Both are set beside the default 4R3C's H = 1/R_air,amb + 1/(R_w,air + R_w + R_w,amb).
2. **Design heat load**: the steady heat that holds 20 degC at the design outdoor temperature
   :data:`DESIGN_T_AMB_C` in EnergyPlus, beside H (typology) x (20 degC - design temperature).
3. **Heating demand over the run with the thermostat** (``--ems thermostat``, the heat pump's
   space heat), beside the range the typology's quasi-steady method gives on the same weather
   and gains (EN ISO 13790 monthly method applied per week, as TABULA computes heat need):
   Q = Q_ht - eta Q_gn with Q_ht from H at the run's own air temperature (:func:`demand_range_kwh`)
   and the gains Q_gn of the appliances, the occupants and the sun on the windows; eta = 1 gives
   the lower end, eta of EN ISO 13790 with the time constant :data:`TAU_LIGHT_H` (a light
   building uses less of its gains) the upper.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.models import house_idf as house
from comems4build_ros.core.models.epw import Weather

#: Design outdoor temperature for Karlsruhe [degC] (DIN/TS 12831-1 lists about -12 degC for the
#: Upper Rhine valley; choice, stated).
DESIGN_T_AMB_C = -12.0
#: Indoor temperature of the steady-state tests [degC] (TABULA's standard indoor temperature).
T_INDOOR_C = 20.0
#: Days of a steady-state test (the slab's time constant is about a day; the last day is averaged).
STEADY_DAYS = 12
#: Time constant of a light building for the upper end of the demand range [h] (EN ISO 13790).
TAU_LIGHT_H = 30.0
#: Sensible heat of one occupant at home [W] (about 100 W metabolic, two thirds sensible).
OCCUPANT_SENSIBLE_W = 65.0
#: Proportional-integral gains of the steady-state tests' hourly thermostat [W/K].
KP_W_PER_K, KI_W_PER_K = 2000.0, 400.0


@dataclass
class SteadyState:
    """One steady-state test: outdoor temperature [degC], mean heat of the last day [W], air temperature [degC]."""

    t_amb_c: float
    q_w: float
    t_air_c: float


def steady_heat(params: PlantParams, t_amb_c: float, idf: str | Path | None = None,
                days: int = STEADY_DAYS) -> SteadyState:
    """The heat that holds :data:`T_INDOOR_C` in the EnergyPlus house at a constant outdoor temperature.

    No sun, no appliance gains, occupants off; an hourly PI thermostat sets the floor heat.
    """
    from comems4build_ros.core.models.building_energyplus import EnergyPlusBuilding
    from comems4build_ros.core.types import Exogenous

    n = 24 * days
    time = pd.date_range("2023-01-02 00:00", periods=n + 24, freq="h", tz=params.site.timezone)
    weather = Weather(time, np.full(n + 24, float(t_amb_c)), np.zeros(n + 24), np.zeros(n + 24))
    b = EnergyPlusBuilding(idf, weather, params.site, n, T_INDOOR_C, occupants=False)
    exo = Exogenous(float(t_amb_c), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, T_INDOOR_C, 24.0)
    qs, temps = [], []
    try:
        x = b.initial_temperatures(T_INDOOR_C, t_amb_c)
        integral = 0.0
        for _ in range(n):
            err = T_INDOOR_C - x[0]
            integral = max(integral + KI_W_PER_K * err, 0.0)
            q = max(KP_W_PER_K * err + integral, 0.0)
            x = b.step(x, q, exo)
            qs.append(b.last.q_floor_received_w)
            temps.append(x[0])
    finally:
        b.close()
    return SteadyState(float(t_amb_c), float(np.mean(qs[-24:])), float(np.mean(temps[-24:])))


def rc_heat_loss_coefficient(params: PlantParams) -> float:
    """The 4R3C's steady-state H = 1/R_air,amb + 1/(R_w,air + R_w + R_w,amb) [W/K]."""
    b = params.building
    return 1.0 / b.r_air_amb_k_per_w + 1.0 / (b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w)


def gains_w(ts: pd.DataFrame, params: PlantParams, dhi: np.ndarray,
            spec: house.HouseSpec | None = None) -> dict[str, np.ndarray]:
    """Hourly internal and solar gains of the house [W] over a run's timeseries (typology method).

    ``dhi`` is the scenario's diffuse horizontal irradiance of the run's steps [W/m2].
    """
    import pvlib

    from comems4build_ros.core.models.epw import direct_normal_w_m2

    spec = spec or house.HouseSpec()
    time = pd.DatetimeIndex(pd.to_datetime(ts["time"], utc=True)).tz_convert(params.site.timezone)
    site = params.site
    mid = time + pd.Timedelta(minutes=30)
    pos = pvlib.solarposition.get_solarposition(mid, site.latitude_deg, site.longitude_deg, site.altitude_m)
    ghi = ts["ghi_w_m2"].to_numpy(float)
    dhi = np.asarray(dhi, dtype=float)
    dni = direct_normal_w_m2(Weather(time, ts["t_amb_c"].to_numpy(float), ghi, dhi), site)
    solar = np.zeros(len(ts))
    for azimuth, share in zip((180.0, 90.0, 0.0, 270.0), spec.window_share):
        poa = pvlib.irradiance.get_total_irradiance(90.0, azimuth, pos["apparent_zenith"], pos["azimuth"], dni, ghi,
                                                    dhi, albedo=0.2, model="isotropic")["poa_global"]
        solar += spec.window_m2 * share * spec.g_window * np.nan_to_num(poa.to_numpy(float))
    hour, wd = time.hour.to_numpy(), time.day_of_week.to_numpy()
    home = (wd >= 5) | (hour < 8) | (hour >= 17)
    occupants = spec.occupants * OCCUPANT_SENSIBLE_W * home
    return {"appliances": ts["p_load_w"].to_numpy(float), "occupants": occupants, "solar": solar}


def demand_range_kwh(ts: pd.DataFrame, params: PlantParams, dhi: np.ndarray,
                     spec: house.HouseSpec | None = None) -> tuple[float, float]:
    """Heating demand of a run by the typology's quasi-steady method, per week, summed [kWh].

    Transmission and ventilation at the run's own air temperature: Q_ht = (H - H_floor) sum
    (T_air - T_amb) + (U A)_floor sum (T_air - T_ground) with the ground temperatures of the IDF;
    gains Q_gn of :func:`gains_w`. Returns (eta = 1, eta of EN ISO 13790 for a time constant of
    at most :data:`TAU_LIGHT_H`).
    """
    spec = spec or house.HouseSpec()
    typ = house.heat_loss_coefficient(spec)
    ua_floor = typ["floor"] / spec.b_ground
    h_amb = typ["h_w_per_k"] - typ["floor"]
    g = gains_w(ts, params, dhi, spec)
    q_gn = g["appliances"] + g["occupants"] + g["solar"]
    t_air = ts["t_air_c"].to_numpy(float)
    month = pd.to_datetime(ts["time"], utc=True).dt.tz_convert(params.site.timezone).dt.month.to_numpy()
    t_ground = np.asarray(house.GROUND_C)[month - 1]
    q_ht = h_amb * (t_air - ts["t_amb_c"].to_numpy(float)) + ua_floor * (t_air - t_ground)
    c_m = 45.0 * 3600.0 * spec.heated_floor_m2  # TABULA c_bldg 45 Wh/(m2 K), medium construction
    tau_h = min(c_m / typ["h_w_per_k"] / 3600.0, TAU_LIGHT_H)
    a = 1.0 + tau_h / 15.0
    week = np.arange(len(ts)) // 168
    lo = hi = 0.0
    for w in np.unique(week):
        ht, gn = q_ht[week == w].sum() / 1000.0, q_gn[week == w].sum() / 1000.0
        lo += max(ht - gn, 0.0)
        gamma = gn / ht if ht > 0 else np.inf
        eta = (1 - gamma ** a) / (1 - gamma ** (a + 1)) if gamma != 1.0 else a / (a + 1)
        hi += max(ht - eta * gn, 0.0)
    return lo, hi


def house_figures(params: PlantParams, idf: str | Path | None = None, weeks: float = 12.0,
                  progress: Any = None) -> dict[str, Any]:
    """The three figures of the module docstring for the house of ``idf`` (default: the shipped house)."""
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.models.buildings import BuildingChoice
    from comems4build_ros.core.scenario import resolve_scenario

    spec = house.HouseSpec()
    typ = house.heat_loss_coefficient(spec)
    cold, mild, design = (steady_heat(params, t, idf) for t in (-10.0, 10.0, DESIGN_T_AMB_C))
    h_ep = (cold.q_w - mild.q_w) / (mild.t_amb_c - cold.t_amb_c)
    h_rc = rc_heat_loss_coefficient(params)
    scenario = resolve_scenario("default", params, weeks=weeks)
    run = simulate("thermostat", scenario, params, building=BuildingChoice("energyplus", Path(idf) if idf else None),
                   progress=progress)
    ts = run.timeseries
    demand = float(ts["q_hp_sh_w"].sum() / 1000.0 * params.simulation.time_step_h)
    lo, hi = demand_range_kwh(ts, params, scenario.dhi_w_m2[: scenario.n_steps], spec)
    return {
        "heated_floor_m2": spec.heated_floor_m2,
        "h_typology_w_per_k": typ["h_w_per_k"],
        "h_tr_typology_w_per_k": typ["h_tr_w_per_k"],
        "h_ve_typology_w_per_k": typ["h_ve_w_per_k"],
        "h_tr_tabula_w_per_k": TABULA_H_TR_W_PER_K,
        "h_energyplus_w_per_k": h_ep,
        "h_rc_w_per_k": h_rc,
        "h_ratio_to_rc": h_ep / h_rc,
        "steady_states": [cold.__dict__, mild.__dict__, design.__dict__],
        "design_t_amb_c": DESIGN_T_AMB_C,
        "design_load_energyplus_w": design.q_w,
        "design_load_typology_w": typ["h_w_per_k"] * (T_INDOOR_C - DESIGN_T_AMB_C),
        "heating_kwh_thermostat": demand,
        "heating_kwh_typology_range": (lo, hi),
        "heating_weeks": weeks,
        "discomfort_kh_week_median": run.summary["discomfort_kh_week_median"],
        "heat_balance_max_rel": run.summary.get("building_heat_balance_max_rel"),
    }


#: TABULA's transmission heat transfer coefficient of DE.N.SFH.09.Gen.ReEx.001.003 [W/K].
TABULA_H_TR_W_PER_K = 87.0
#: Allowed deviation of the house's H from the default 4R3C's (the co-simulation's design rule).
H_TOLERANCE = 0.25
