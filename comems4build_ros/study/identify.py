"""The MPC's building model identified from data of a detailed building, as on a real house.

``comems4build identify`` (this module's :func:`identify`):

1. **Data.** The detailed building (EnergyPlus by default) runs over a *training window*
   outside the paper's twelve evaluation weeks, under a documented excitation
   (:func:`excitation`): the floor heat is held at a random level of {0, 1/4, 1/2, 3/4, 1} x
   :data:`Q_EXCITE_W` for a random 3 to 12 hours (a multi-level pseudo-random sequence, seeded),
   overridden to 0 above :data:`T_HIGH_C` and to full heat below :data:`T_LOW_C` (the house
   stays near its operating range). The weather and the appliance load are the measured-data
   scenario's of those weeks (DWD temperature, modelled radiation and load).
2. **Fit.** The 4R3C's parameters (``eq:dT_i`` .. ``eq:dT_wout``: C_air, C_w, the four
   resistances, g_s, f_conv, a_sol) plus ``f_gains_air`` (the share of the appliance load that
   heats the air node; with 0 it is the paper's model) and the two initial wall temperatures
   minimise the simulation (output) error of T_air over the training window (SciPy
   ``least_squares``, ZOH of each candidate as ``eq:state_update_bldgs``). The resistances are
   fitted as the heat loss coefficient H, the share of H through the air path (windows and
   ventilation, 1/R_air,amb) and the split of the wall chain, so that every fitted quantity has
   a physical bound taken from the house (:func:`physical_bounds`: H within 20 % of the
   typology's, capacities between the air's and half the constructions' total, the sun at most
   the windows' area times their g-value, gain and convective shares in [0, 1.2] and [0, 1]);
   the report names any that ends on a bound.
3. **Validation.** On held-out data (a validation window with another excitation seed, and
   the twelve evaluation weeks under the thermostat): every hour a stationary Kalman filter of
   the identified model (:mod:`comems4build_ros.core.ems.mpc.observer`) gives the state from
   the measured T_air so far, and the model predicts T_air 24 h ahead open loop with the true
   inputs; the RMSE over all those predictions is the model error the MPC faces.
4. **Output.** A parameter file in the plant-file form with the identified ``building``
   section (``--config FILE`` gives it to the MPC; with ``--building energyplus`` the plant
   stays EnergyPlus, so the MPC plans with the identified model, never with EnergyPlus) and a
   JSON report.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import SECONDS_PER_HOUR, BuildingParams, PlantParams

#: Full heat of the excitation [W] (about the heat pump's heat at 55 degC flow in winter).
Q_EXCITE_W = 4500.0
#: Band the excitation keeps the air in [degC].
T_LOW_C, T_HIGH_C = 18.0, 24.5
#: Hold times of the excitation's levels [h].
HOLD_MIN_H, HOLD_MAX_H = 3, 12
#: Training and validation windows (local start, weeks): before the paper's winter (2022-12-01).
TRAIN_START, TRAIN_WEEKS = "2022-11-01T00:00:00", 3.0
VALID_START, VALID_WEEKS = "2022-11-22T00:00:00", 1.0
#: Prediction horizon of the validation [h] (the MPC's).
HORIZON_H = 24
#: Fraction of the typology's heat loss coefficient the identified H may deviate by.
H_BOUND = 0.20
#: Largest share of the appliance load that may heat the air node [-]: all of the appliances'
#: electricity ends as heat in the house (1), plus the occupants' sensible heat, which comes with
#: the load (four occupants at 65 W while at home, about a fifth of the mean appliance load).
F_GAINS_MAX = 1.2
#: Largest sol-air factor a_sol = alpha / h_e [K m2/W] times the facades' irradiance over the
#: horizontal's: absorptance 1, h_e = 25 W/(m2 K) (EN ISO 6946: R_se = 0.04 m2 K/W), a winter
#: facade at 1.5 times the horizontal irradiance.
A_SOL_MAX = 1.5 / 25.0
#: The 4R3C parameters the report lists (fields of ``building``).
REPORTED = ("c_air_j_per_k", "c_wall_j_per_k", "r_w_air_k_per_w", "r_air_amb_k_per_w", "r_w_k_per_w",
            "r_w_amb_k_per_w", "g_s_m2", "f_conv", "a_sol_k_m2_per_w", "f_gains_air")


@dataclass(frozen=True)
class Bound:
    """A fitted quantity: name, physical lower and upper bound, fitted on a log scale, and why the bounds."""

    name: str
    lo: float
    hi: float
    log: bool
    reason: str


def physical_bounds(spec: Any = None) -> tuple[Bound, ...]:
    """The fitted quantities and their bounds from the house (default: the shipped EnergyPlus house's spec)."""
    from comems4build_ros.core.models import house_idf as house

    spec = spec or house.HouseSpec()
    typ = house.heat_loss_coefficient(spec)
    cap = house.heat_capacity(spec)
    h = typ["h_w_per_k"]
    air_share = (typ["window"] + typ["h_ve_w_per_k"]) / h
    buffered = typ["floor"] + (typ["wall"] if spec.construction == "masonry" else 0.0)
    return (
        Bound("h_w_per_k", (1 - H_BOUND) * h, (1 + H_BOUND) * h, False,
              f"the typology's H = {h:.1f} W/K (TABULA method) +-{H_BOUND:.0%}"),
        Bound("air_share", 0.5 * air_share, 1.0 - buffered / h, False,
              f"at least half the typology's share of windows and ventilation in H ({air_share:.2f}), at most all "
              f"but the {'masonry walls and ' if spec.construction == 'masonry' else ''}floor slab, whose mass "
              "buffers its loss"),
        Bound("inner_share", 1e-3, 0.5, False, "R_w,air / (R_w,air + R_w + R_w,amb): the inner surfaces at most half "
              "the wall chain"),
        Bound("wall_share", 0.05, 0.95, False, "R_w / (R_w + R_w,amb): the insulation between the two wall nodes"),
        Bound("c_air_j_per_k", cap["air"], cap["total"] / 2, True,
              f"from the air's {cap['air']:.3g} J/K to half the constructions' total {cap['total']:.3g} J/K"),
        Bound("c_wall_j_per_k", cap["air"], cap["total"] / 2, True,
              "each wall node at most half the constructions' total"),
        Bound("g_s_m2", 0.0, spec.window_m2 * spec.g_window, False,
              f"at most the window area {spec.window_m2:.1f} m2 times its g-value {spec.g_window:g}"),
        Bound("f_conv", 0.0, 1.0, False, "a share of the floor heat"),
        Bound("a_sol_k_m2_per_w", 0.0, A_SOL_MAX, False, "absorptance <= 1 over h_e = 25 W/(m2 K), facade at 1.5 x "
              "the horizontal irradiance"),
        Bound("f_gains_air", 0.0, F_GAINS_MAX, False,
              "the appliance load's heat plus the occupants' that comes with it"),
    )


@dataclass
class Data:
    """Hourly input-output data of a building (arrays of equal length n; T_air at the end of each hour).

    Attributes
    ----------
    q_w : heat into the floor [W]; t_amb_c [degC]; ghi_w_m2 [W/m2]; p_load_w [W]; t_air_c [degC];
    t_air0_c : the air temperature at the start [degC]
    """

    q_w: np.ndarray
    t_amb_c: np.ndarray
    ghi_w_m2: np.ndarray
    p_load_w: np.ndarray
    t_air_c: np.ndarray
    t_air0_c: float

    @property
    def u(self) -> np.ndarray:
        """Inputs (n, 4): Q, T_amb, q_s, P_load."""
        return np.column_stack([self.q_w, self.t_amb_c, self.ghi_w_m2, self.p_load_w])


def excitation(seed: int) -> Callable[[float], float]:
    """The excitation as a controller: ``next_heat(t_air_c) -> q_w`` per hour (see the module docstring)."""
    rng = np.random.default_rng(seed)
    state = {"left": 0, "level": 0.0}

    def next_heat(t_air_c: float) -> float:
        if state["left"] <= 0:
            state["level"] = float(rng.integers(0, 5)) / 4.0 * Q_EXCITE_W
            state["left"] = int(rng.integers(HOLD_MIN_H, HOLD_MAX_H + 1))
        state["left"] -= 1
        if t_air_c > T_HIGH_C:
            return 0.0
        if t_air_c < T_LOW_C:
            return Q_EXCITE_W
        return state["level"]

    return next_heat


def collect(params: PlantParams, building: Any, start: str, weeks: float, seed: int) -> Data:
    """Run the detailed building over a window of the year scenario under the excitation."""
    from comems4build_ros.core.loop import building_model, exogenous_series
    from comems4build_ros.core.scenario import resolve_scenario

    scenario = resolve_scenario("year", params, start=start, weeks=weeks)
    exo = exogenous_series(scenario, params)
    model = building_model(building, params, scenario)
    heat = excitation(seed)
    rows = []
    try:
        x = model.initial_temperatures(params.simulation.t_air_init_c, float(scenario.t_amb_c[0]))
        t0 = x[0]
        for k in range(scenario.n_steps):
            q = heat(x[0])
            x = model.step(x, q, exo[k])
            rows.append((q, exo[k].t_amb_c, exo[k].ghi_w_m2, exo[k].p_load_w, x[0]))
    finally:
        model.close()
    a = np.asarray(rows, dtype=float)
    return Data(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], float(t0))


def data_of_run(ts: pd.DataFrame, t_air0_c: float) -> Data:
    """The input-output data of a closed-loop run's timeseries (floor heat = SH heat minus cooling)."""
    q = ts["q_hp_sh_w"].to_numpy(float) - ts["q_cool_w"].to_numpy(float)
    return Data(q, ts["t_amb_c"].to_numpy(float), ts["ghi_w_m2"].to_numpy(float), ts["p_load_w"].to_numpy(float),
                ts["t_air_c"].to_numpy(float), float(t_air0_c))


def params_of(theta: np.ndarray, base: BuildingParams, bounds: tuple[Bound, ...] | None = None) -> BuildingParams:
    """Building parameters of a vector of fitted quantities (log-scaled entries exponentiated).

    H, the air path's share s and the wall chain's shares f_in, f_w give R_air,amb = 1/(s H),
    R_chain = 1/((1 - s) H), R_w,air = f_in R_chain, R_w = f_w (1 - f_in) R_chain and
    R_w,amb = (1 - f_w)(1 - f_in) R_chain.
    """
    v = {b.name: float(math.exp(x) if b.log else x) for b, x in zip(bounds or physical_bounds(), theta)}
    chain = 1.0 / ((1.0 - v["air_share"]) * v["h_w_per_k"])
    values = {
        "r_air_amb_k_per_w": 1.0 / (v["air_share"] * v["h_w_per_k"]),
        "r_w_air_k_per_w": v["inner_share"] * chain,
        "r_w_k_per_w": v["wall_share"] * (1.0 - v["inner_share"]) * chain,
        "r_w_amb_k_per_w": (1.0 - v["wall_share"]) * (1.0 - v["inner_share"]) * chain,
        **{k: v[k] for k in ("c_air_j_per_k", "c_wall_j_per_k", "g_s_m2", "f_conv", "a_sol_k_m2_per_w",
                             "f_gains_air")},
    }
    return base.model_copy(update=values)


def fitted_of(b: BuildingParams) -> dict[str, float]:
    """The fitted quantities of building parameters (the inverse of :func:`params_of`)."""
    chain = b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w
    h = heat_loss_coefficient(b)
    return {"h_w_per_k": h, "air_share": 1.0 / (b.r_air_amb_k_per_w * h), "inner_share": b.r_w_air_k_per_w / chain,
            "wall_share": b.r_w_k_per_w / (b.r_w_k_per_w + b.r_w_amb_k_per_w),
            **{k: float(getattr(b, k)) for k in ("c_air_j_per_k", "c_wall_j_per_k", "g_s_m2", "f_conv",
                                                 "a_sol_k_m2_per_w", "f_gains_air")}}


def at_bounds(fitted: dict[str, float], bounds: tuple[Bound, ...], rel: float = 1e-4) -> list[str]:
    """Names of the fitted quantities within ``rel`` of the width of their range from a bound."""
    out = []
    for b in bounds:
        x = fitted[b.name]
        lo, hi, x = (math.log(b.lo), math.log(b.hi), math.log(x)) if b.log else (b.lo, b.hi, x)
        if min(x - lo, hi - x) <= rel * (hi - lo):
            out.append(b.name)
    return out


def zoh(b: BuildingParams, dt_h: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A_d, B_d of ``b`` with the appliance load always as fourth input (uncached: for the fit)."""
    from scipy.linalg import expm

    from comems4build_ros.core.models.building import continuous

    a, bm = continuous(b.model_copy(update={"f_gains_air": 1.0}))
    bm[0, 3] = b.f_gains_air / b.c_air_j_per_k
    aug = np.zeros((7, 7))
    aug[:3, :3], aug[:3, 3:] = a, bm
    phi = expm(aug * dt_h * SECONDS_PER_HOUR)
    return phi[:3, :3], phi[:3, 3:]


def simulate(ad: np.ndarray, bd: np.ndarray, x0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """States x[1..n] (n, 3) of the model from x0 under the inputs u (n, 4)."""
    x = np.asarray(x0, dtype=float).copy()
    out = np.empty((len(u), 3))
    bu = u @ bd.T
    for k in range(len(u)):
        x = ad @ x + bu[k]
        out[k] = x
    return out


def fit(data: Data, base: BuildingParams,
        bounds: tuple[Bound, ...] | None = None) -> tuple[BuildingParams, dict[str, float]]:
    """Least-squares fit of the 4R3C and ``f_gains_air`` to ``data`` (output error of T_air) within ``bounds``.

    Starts from ``base`` (the plant's 4R3C) clipped into the bounds, ``f_gains_air`` at half its range.
    """
    from scipy.optimize import least_squares

    bounds = bounds or physical_bounds()
    start_v = fitted_of(base)
    start_v["f_gains_air"] = 0.5
    start = np.array([math.log(start_v[b.name]) if b.log else start_v[b.name] for b in bounds])
    lo = np.array([math.log(b.lo) if b.log else b.lo for b in bounds] + [0.0, -10.0])
    hi = np.array([math.log(b.hi) if b.log else b.hi for b in bounds] + [40.0, 40.0])
    x0 = np.concatenate([start, [data.t_air0_c - 1.0, 0.5 * (data.t_air0_c + data.t_amb_c[0])]])
    x0 = np.clip(x0, lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))
    u = data.u

    def residuals(theta: np.ndarray) -> np.ndarray:
        b = params_of(theta[: len(bounds)], base, bounds)
        ad, bd = zoh(b)
        xs = simulate(ad, bd, np.array([data.t_air0_c, theta[-2], theta[-1]]), u)
        return xs[:, 0] - data.t_air_c

    res = least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=3000)
    b = params_of(res.x[: len(bounds)], base, bounds)
    rmse = float(np.sqrt(np.mean(res.fun**2)))
    return b, {"fit_rmse_k": rmse, "nfev": int(res.nfev), "status": int(res.status)}


def predictions_24h(b: BuildingParams, data: Data, horizon: int = HORIZON_H) -> np.ndarray:
    """Open-loop prediction errors (n_starts, horizon) [K]: Kalman state from measured T_air, then predict."""
    from comems4build_ros.core.ems.mpc.observer import kalman_gain, wall_split

    ad, bd = zoh(b)
    gain = kalman_gain(ad)
    u = data.u
    bu = u @ bd.T
    n = len(u)
    s_in, s_out = wall_split(b)
    d = data.t_air0_c - data.t_amb_c[0]
    x = np.array([data.t_air0_c, data.t_air0_c - d * s_in, data.t_air0_c - d * s_out])
    errors = []
    for k in range(n):
        if k + horizon <= n and k >= horizon:  # a day of filtering before the first prediction
            xp = x.copy()
            e = np.empty(horizon)
            for j in range(horizon):
                xp = ad @ xp + bu[k + j]
                e[j] = xp[0] - data.t_air_c[k + j]
            errors.append(e)
        pred = ad @ x + bu[k]
        x = pred + gain * (data.t_air_c[k] - pred[0])
    return np.asarray(errors)


def rmse_report(errors: np.ndarray) -> dict[str, float]:
    """RMSE over all predictions and leads, at lead 24 h, and the largest error [K]."""
    if errors.size == 0:
        return {"rmse_k": math.nan, "rmse_24h_k": math.nan, "max_abs_k": math.nan, "predictions": 0}
    return {"rmse_k": float(np.sqrt(np.mean(errors**2))), "rmse_24h_k": float(np.sqrt(np.mean(errors[:, -1] ** 2))),
            "max_abs_k": float(np.max(np.abs(errors))), "predictions": int(len(errors))}


def identify(params: PlantParams, building: Any = "energyplus", seed: int = 1,
             held_out_run: pd.DataFrame | None = None, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Collect, fit and validate (see the module docstring); returns the report with ``building`` parameters."""
    say = progress or (lambda text: None)
    say(f"collecting the training window ({TRAIN_WEEKS:g} weeks from {TRAIN_START})")
    train = collect(params, building, TRAIN_START, TRAIN_WEEKS, seed)
    say(f"collecting the validation window ({VALID_WEEKS:g} week from {VALID_START})")
    valid = collect(params, building, VALID_START, VALID_WEEKS, seed + 1000)
    say("fitting the 4R3C within the house's physical bounds")
    bounds = physical_bounds()
    b, info = fit(train, params.building, bounds)
    fitted = fitted_of(b)
    report: dict[str, Any] = {
        "building": str(building),
        "excitation": {"q_excite_w": Q_EXCITE_W, "band_c": [T_LOW_C, T_HIGH_C], "hold_h": [HOLD_MIN_H, HOLD_MAX_H],
                       "seed": seed},
        "train": {"start": TRAIN_START, "weeks": TRAIN_WEEKS},
        "fit": info,
        "identified": {name: float(getattr(b, name)) for name in REPORTED},
        "fitted": fitted,
        "bounds": [{"name": x.name, "lo": x.lo, "hi": x.hi, "reason": x.reason} for x in bounds],
        "at_bounds": at_bounds(fitted, bounds),
        "heat_loss_coefficient_w_per_k": heat_loss_coefficient(b),
        "validation": {"start": VALID_START, "weeks": VALID_WEEKS, **rmse_report(predictions_24h(b, valid))},
        "training_24h": rmse_report(predictions_24h(b, train)),
    }
    if held_out_run is not None:
        data = data_of_run(held_out_run, float(held_out_run["t_air_c"].iloc[0]))
        report["evaluation_weeks_thermostat"] = rmse_report(predictions_24h(b, data))
    report["_params"] = b
    return report


def heat_loss_coefficient(b: BuildingParams) -> float:
    """Steady-state H = 1/R_air,amb + 1/(R_w,air + R_w + R_w,amb) [W/K]."""
    return 1.0 / b.r_air_amb_k_per_w + 1.0 / (b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w)


def write_parameter_file(path: str | Path, b: BuildingParams, report: dict[str, Any]) -> Path:
    """The identified ``building`` section as a plant parameter file (``--config``), with its provenance."""
    import yaml

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    section = {name: float(getattr(b, name)) for name in type(b).model_fields}
    v = report["validation"]
    head = (
        "# The MPC's building model identified by comems4build identify from the detailed building\n"
        f"# '{report['building']}' (4R3C of eq:dT_i..eq:dT_wout plus f_gains_air; training {report['train']['start']}"
        f" for {report['train']['weeks']:g} weeks\n"
        f"# under the excitation of comems4build_ros.study.identify). Fit RMSE {report['fit']['fit_rmse_k']:.3f} K;"
        f" 24-h open-loop T_air RMSE on the held-out week {v['rmse_k']:.3f} K.\n"
        "# Use: --config THIS_FILE with --building energyplus and --ems mpc --ems-option observer=kalman.\n"
    )
    body = yaml.safe_dump({"/**": {"ros__parameters": {"building": section}}}, sort_keys=False)
    path.write_text(head + body, encoding="utf-8")
    return path


def write_report(path: str | Path, report: dict[str, Any]) -> Path:
    """The report as JSON (without the parameter object)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({k: v for k, v in report.items() if not k.startswith("_")}, indent=1) + "\n",
                    encoding="utf-8")
    return path
