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
   heats the air node: the detailed house has internal gains, the paper's model has none) and
   the two initial wall temperatures minimise the simulation (output) error of T_air over the
   training window (SciPy ``least_squares``, positive parameters on a log scale, ZOH of each
   candidate as ``eq:state_update_bldgs``).
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
#: Fitted parameters: name, lower bound, upper bound, log scale.
FIT_PARAMETERS: tuple[tuple[str, float, float, bool], ...] = (
    ("c_air_j_per_k", 1e5, 1e9, True),
    ("c_wall_j_per_k", 1e5, 1e10, True),
    ("r_w_air_k_per_w", 1e-5, 1.0, True),
    ("r_air_amb_k_per_w", 1e-4, 1.0, True),
    ("r_w_k_per_w", 1e-5, 1.0, True),
    ("r_w_amb_k_per_w", 1e-5, 1.0, True),
    ("g_s_m2", 0.0, 50.0, False),
    ("f_conv", 0.0, 1.0, False),
    ("a_sol_k_m2_per_w", 0.0, 0.2, False),
    ("f_gains_air", 0.0, 2.0, False),
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


def params_of(theta: np.ndarray, base: BuildingParams) -> BuildingParams:
    """Building parameters of a parameter vector (log-scaled entries exponentiated)."""
    values = {}
    for (name, _, _, log), v in zip(FIT_PARAMETERS, theta):
        values[name] = float(math.exp(v) if log else v)
    return base.model_copy(update=values)


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


def fit(data: Data, base: BuildingParams) -> tuple[BuildingParams, dict[str, float]]:
    """Least-squares fit of the 4R3C and ``f_gains_air`` to ``data`` (output error of T_air)."""
    from scipy.optimize import least_squares

    start = np.array([math.log(getattr(base, n)) if log else getattr(base, n) for n, _, _, log in FIT_PARAMETERS])
    start[-1] = 0.5  # f_gains_air: half of the appliance load into the air as a neutral start
    lo = np.array([math.log(a) if log else a for _, a, _, log in FIT_PARAMETERS] + [0.0, -10.0])
    hi = np.array([math.log(b) if log else b for _, _, b, log in FIT_PARAMETERS] + [40.0, 40.0])
    x0 = np.concatenate([start, [data.t_air0_c - 1.0, 0.5 * (data.t_air0_c + data.t_amb_c[0])]])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    u = data.u

    def residuals(theta: np.ndarray) -> np.ndarray:
        b = params_of(theta[: len(FIT_PARAMETERS)], base)
        ad, bd = zoh(b)
        xs = simulate(ad, bd, np.array([data.t_air0_c, theta[-2], theta[-1]]), u)
        return xs[:, 0] - data.t_air_c

    res = least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", max_nfev=3000)
    b = params_of(res.x[: len(FIT_PARAMETERS)], base)
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
    say("fitting the 4R3C")
    b, info = fit(train, params.building)
    report: dict[str, Any] = {
        "building": str(building),
        "excitation": {"q_excite_w": Q_EXCITE_W, "band_c": [T_LOW_C, T_HIGH_C], "hold_h": [HOLD_MIN_H, HOLD_MAX_H],
                       "seed": seed},
        "train": {"start": TRAIN_START, "weeks": TRAIN_WEEKS},
        "fit": info,
        "identified": {name: float(getattr(b, name)) for name, *_ in FIT_PARAMETERS},
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
