"""State observer of the MPC's building model, for a house the model did not shape.

On the 4R3C plant the MPC reads its model's three node temperatures from the plant (the
paper's full information, ``tab:level_of_information``). On a detailed building (EnergyPlus,
an FMU) only the air temperature is a measurement of what the MPC's model calls T_air; its
wall nodes exist only in the model. :class:`KalmanObserver` estimates them as a real MPC
would: a steady-state Kalman filter of the MPC's own discretised model (``eq:state_update_bldgs``,
an identified model when the MPC plans with one), driven by the heat the MPC commanded in the
previous step and the measured weather and appliance load, corrected by the measured T_air.

Noise covariances (choice, stated): process noise :data:`Q_PROCESS_K2` on each node per step,
measurement noise :data:`R_MEASURE_K2` on T_air; the gain is that of the stationary filter
(discrete algebraic Riccati equation, SciPy).
"""

from __future__ import annotations

import numpy as np

#: Process noise variance per node and step [K^2] (choice: model error of a few tenths of a kelvin per hour).
Q_PROCESS_K2 = (0.04, 0.01, 0.01)
#: Measurement noise variance of T_air [K^2] (choice: a room sensor's 0.1 K).
R_MEASURE_K2 = 0.01


def kalman_gain(ad: np.ndarray, q: tuple[float, ...] = Q_PROCESS_K2, r: float = R_MEASURE_K2) -> np.ndarray:
    """Compute the stationary Kalman gain of x[k+1] = A_d x[k] + B_d u[k], y = T_air = x[0] (filter form).

    Parameters
    ----------
    ad : numpy.ndarray
        The model's ZOH state matrix (3, 3) (``eq:state_update_bldgs``).
    q : tuple[float, ...]
        Process noise variance per node and step [K^2].
    r : float
        Measurement noise variance of T_air [K^2].

    Returns
    -------
    numpy.ndarray
        The gain L, shape (3,) [-].
    """
    from scipy.linalg import solve_discrete_are

    c = np.array([[1.0, 0.0, 0.0]])
    p = solve_discrete_are(ad.T, c.T, np.diag(q), np.array([[r]]))
    return (p @ c.T / (c @ p @ c.T + r)).ravel()


def wall_split(b) -> tuple[float, float]:
    """Compute where the walls lie in the steady temperature profile between room and ambient.

    Parameters
    ----------
    b : BuildingParams
        The 4R3C's resistances [K/W] (``sec:bldg``).

    Returns
    -------
    tuple[float, float]
        (r_w,air / R, (r_w,air + r_w) / R) [-] with R = r_w,air + r_w + r_w,amb.
    """
    r = b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w
    return b.r_w_air_k_per_w / r, (b.r_w_air_k_per_w + b.r_w_k_per_w) / r


class KalmanObserver:
    """Estimates the model's node temperatures from measured T_air (see the module docstring).

    Parameters
    ----------
    ad, bd : numpy.ndarray
        The MPC model's ZOH matrices, (3, 3) and (3, 3 or 4); x = [T_air, T_w_in, T_w_out]
        [degC], u = [Q_h,SH [W], T_amb [degC], q_s [W/m2], P_load [W]].
    wall_split : tuple[float, float] or None
        (r_w,air / R, (r_w,air + r_w) / R) [-] (:func:`wall_split`): where the walls start
        between the measured air and the ambient temperature (the steady profile without
        sun, as the plant's initial state); None: at the air temperature.
    """

    def __init__(self, ad: np.ndarray, bd: np.ndarray, wall_split: tuple[float, float] | None = None) -> None:
        self.ad = np.asarray(ad, dtype=float)
        self.bd = np.asarray(bd, dtype=float)
        self.wall_split = wall_split
        self.gain = kalman_gain(self.ad)
        self.reset()

    def reset(self) -> None:
        """Forget the estimate (the next :meth:`update` starts from the measurement)."""
        self.x: np.ndarray | None = None
        self._u: np.ndarray | None = None

    def update(self, t_air_c: float, t_amb_c: float | None = None) -> np.ndarray:
        """Correct the estimate with the measurement of the step that just ended.

        Parameters
        ----------
        t_air_c : float
            Measured T_air [degC].
        t_amb_c : float, optional
            Ambient temperature [degC]: places the walls of the first estimate (:attr:`wall_split`).

        Returns
        -------
        numpy.ndarray
            The estimate (T_air, T_w_in, T_w_out) [degC], a copy.
        """
        if self.x is None or self._u is None:
            t = float(t_air_c)
            if self.wall_split is None or t_amb_c is None:
                self.x = np.full(3, t)
            else:
                d = t - float(t_amb_c)
                self.x = np.array([t, t - d * self.wall_split[0], t - d * self.wall_split[1]])
        else:
            pred = self.ad @ self.x + self.bd @ self._u
            self.x = pred + self.gain * (float(t_air_c) - pred[0])
        return self.x.copy()

    def applied(self, q_floor_w: float, t_amb_c: float, ghi_w_m2: float, p_load_w: float) -> None:
        """Record the inputs of the step now decided (the next :meth:`update` predicts with them).

        Parameters
        ----------
        q_floor_w : float
            Commanded floor heat [W] (negative: cooling).
        t_amb_c : float
            Ambient temperature [degC].
        ghi_w_m2 : float
            Global horizontal irradiance [W/m2].
        p_load_w : float
            Appliance load [W] (its heat gain, where the model has that input).
        """
        u = [q_floor_w, t_amb_c, ghi_w_m2, p_load_w][: self.bd.shape[1]]
        self._u = np.asarray(u, dtype=float)
