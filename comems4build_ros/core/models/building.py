"""4R3C building model, ``eq:dT_i`` .. ``eq:dT_wout`` and ``eq:state_update_bldgs``.

    C_air dT_air/dt  = (T_w,in - T_air)/R_w,air + (T_amb - T_air)/R_air,amb + g_s q_s + f_conv Q_h,SH   (eq:dT_i)
    C_w   dT_w,in/dt = (T_air - T_w,in)/R_w,air + (T_w,out - T_w,in)/R_w + (1 - f_conv) Q_h,SH         (eq:dT_win)
    C_w   dT_w,out/dt = (T_w,in - T_w,out)/R_w + (T_amb,eq - T_w,out)/R_w,amb                           (eq:dT_wout)

with the sol-air temperature T_amb,eq = T_amb + a_sol * q_s at the exterior surface.
State x = [T_air, T_w,in, T_w,out] [degC], input u = [Q_h,SH [W], T_amb [degC], q_s [W/m2]].
The continuous system dx/dt = A x + B u is discretised once with a zero-order hold
(inputs constant over the step): with M = [[A, B], [0, 0]] * t_s,
expm(M) = [[A_d, B_d], [0, I]] and x[k+1] = A_d x[k] + B_d u[k] (``eq:state_update_bldgs``).

The default parameters (``config/plant.yaml``, section ``building``) are calibrated in
``docs/models.md``.

The plant sees its building model through :class:`BuildingModel`: per step the heat of the
emission system into the floor (negative when cooling) and the step's weather and appliance
load (its internal gains, ``exo.p_load_w``) go in, the node temperatures come out; ``close``
ends a model that runs a simulator of its own. :class:`RCBuilding` is the paper's 4R3C model
(it has no internal-gain term, as in the paper); the detailed models in co-simulation
(:mod:`~comems4build_ros.core.models.building_energyplus`,
:mod:`~comems4build_ros.core.models.building_fmu`, chosen with
:mod:`~comems4build_ros.core.models.buildings`) implement the same methods and leave the
devices as they are.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from comems4build_ros.core.config import SECONDS_PER_HOUR, BuildingParams
from comems4build_ros.core.numerics import rowdot
from comems4build_ros.core.types import Exogenous

#: Node temperatures of a building model: (T_air, T_w,in, T_w,out) [degC].
Temperatures = tuple[float, float, float]


def continuous(b: BuildingParams) -> tuple[np.ndarray, np.ndarray]:
    """Build the continuous-time matrices of dx/dt = A x + B u (``eq:dT_i`` .. ``eq:dT_wout``).

    Parameters
    ----------
    b : BuildingParams
        Capacities ``c_air_j_per_k``, ``c_wall_j_per_k`` [J/K], resistances ``r_*_k_per_w``
        [K/W], ``f_conv`` [-], ``g_s_m2`` [m2], ``a_sol_k_m2_per_w`` [K m2/W] and
        ``f_gains_air`` [-].

    Returns
    -------
    A : numpy.ndarray, shape (3, 3)
        State matrix [1/s] for x = [T_air, T_w,in, T_w,out].
    B : numpy.ndarray, shape (3, 3), or (3, 4) with ``f_gains_air`` > 0
        Input matrix for u = [Q_h,SH [W], T_amb [degC], q_s [W/m2]] (and the appliance load
        P_el,load [W] as a fourth input into the air node).
    """
    ca, cw = b.c_air_j_per_k, b.c_wall_j_per_k
    g_wa = 1.0 / b.r_w_air_k_per_w
    g_aa = 1.0 / b.r_air_amb_k_per_w
    g_w = 1.0 / b.r_w_k_per_w
    g_wamb = 1.0 / b.r_w_amb_k_per_w
    a = np.array(
        [
            [-(g_wa + g_aa) / ca, g_wa / ca, 0.0],
            [g_wa / cw, -(g_wa + g_w) / cw, g_w / cw],
            [0.0, g_w / cw, -(g_w + g_wamb) / cw],
        ]
    )
    bm = np.array(
        [
            [b.f_conv / ca, g_aa / ca, b.g_s_m2 / ca],
            [(1.0 - b.f_conv) / cw, 0.0, 0.0],
            [0.0, g_wamb / cw, g_wamb * b.a_sol_k_m2_per_w / cw],
        ]
    )
    if b.f_gains_air:  # an identified model's internal gains: a fourth input P_el,load [W]
        bm = np.hstack([bm, np.array([[b.f_gains_air / ca], [0.0], [0.0]])])
    return a, bm


def discretize(b: BuildingParams, dt_h: float) -> tuple[np.ndarray, np.ndarray]:
    """Discretise the model with a zero-order hold, ``eq:state_update_bldgs``.

    Parameters
    ----------
    b : BuildingParams
        The 4R3C's parameters (:func:`continuous`).
    dt_h : float
        Step t_s [h] (> 0).

    Returns
    -------
    Ad : numpy.ndarray, shape (3, 3)
        State transition over one step [-].
    Bd : numpy.ndarray, shape (3, 3) or (3, 4)
        Input matrix over one step: x[k+1] = Ad x[k] + Bd u[k] for x = [T_air, T_w,in,
        T_w,out] [degC] and u = [Q_h,SH [W], T_amb [degC], q_s [W/m2]] (and P_el,load [W]).

    Raises
    ------
    ValueError
        If ``dt_h`` is not positive.
    """
    if not dt_h > 0:
        raise ValueError(f"building: dt_h must be > 0 h, got {dt_h}")
    from comems4build_ros.core.result_cache import cached

    a, bm = continuous(b)
    n, m = a.shape[0], bm.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = a
    aug[:n, n:] = bm
    aug *= dt_h * SECONDS_PER_HOUR
    # cached on disk (comems4build_ros.core.result_cache): a hit skips SciPy's import in plant_sim
    (phi,) = cached("expm", {}, [aug], lambda: (_expm(aug),), dists=("scipy", "numpy"), shape=aug.shape)
    return phi[:n, :n], phi[:n, n:]


#: Significant digits kept of the discretised matrices: SciPy's ``expm`` multiplies matrices
#: through OpenBLAS, whose kernels (chosen by the CPU) differ in the last bits; rounded to 12
#: digits (a relative 1e-12, far below the model's accuracy) every CPU gets the same Ad and Bd,
#: and so the same runs.
EXPM_DIGITS = 12


def _expm(m: np.ndarray) -> np.ndarray:
    """Return the matrix exponential of ``m`` (SciPy's Pade approximation), rounded to :data:`EXPM_DIGITS`."""
    from scipy.linalg import expm  # here, not at the top: a process that finds it cached skips SciPy

    phi = expm(m)
    return np.array([[float(f"{v:.{EXPM_DIGITS - 1}e}") for v in row] for row in phi])


def steady_state_c(q_sh_w: float, t_amb_c: float, q_s_w_m2: float, b: BuildingParams) -> np.ndarray:
    """Solve for the equilibrium node temperatures under constant inputs (A x + B u = 0, no internal gains).

    Parameters
    ----------
    q_sh_w : float
        Space-heating heat Q_h,SH [W].
    t_amb_c : float
        Ambient temperature [degC].
    q_s_w_m2 : float
        Global horizontal irradiance q_s [W/m2].
    b : BuildingParams
        The 4R3C's parameters.

    Returns
    -------
    numpy.ndarray, shape (3,)
        [T_air, T_w,in, T_w,out] [degC].
    """
    a, bm = continuous(b)
    u = [q_sh_w, t_amb_c, q_s_w_m2] + [0.0] * (bm.shape[1] - 3)
    return np.linalg.solve(a, -bm @ np.array(u, dtype=float))


def simulate(x0, u, Ad: np.ndarray, Bd: np.ndarray) -> np.ndarray:
    """Free-run the discrete model over an input sequence.

    Parameters
    ----------
    x0 : array_like, shape (3,)
        Initial state [degC].
    u : array_like, shape (n, 3)
        Inputs per step: Q_h,SH [W], T_amb [degC], q_s [W/m2].
    Ad, Bd : numpy.ndarray
        The discrete model (:func:`discretize`).

    Returns
    -------
    numpy.ndarray, shape (n + 1, 3)
        States x[0..n] [degC].
    """
    u = np.asarray(u, dtype=float)
    x = np.empty((len(u) + 1, 3))
    x[0] = x0
    for k in range(len(u)):
        x[k + 1] = rowdot(Ad, x[k]) + rowdot(Bd, u[k])
    return x


@runtime_checkable
class BuildingModel(Protocol):
    """The thermal model of the house's rooms as the plant uses it.

    A model that keeps a state of its own (a simulator in co-simulation) advances it at each
    :meth:`step` call; the plant calls it once per step, in order.

    Attributes
    ----------
    name : str
        The model's name (``rc`` for the paper's 4R3C).
    """

    name: str

    def initial_temperatures(self, t_air_c: float, t_amb_c: float) -> Temperatures:
        """Return the node temperatures at the start of a run.

        Parameters
        ----------
        t_air_c : float
            Indoor air temperature at the start [degC].
        t_amb_c : float
            Ambient temperature before the run [degC].

        Returns
        -------
        Temperatures
            (T_air, T_w,in, T_w,out) [degC].
        """
        ...

    def step(self, temps: Temperatures, q_floor_w: float, exo: Exogenous) -> Temperatures:
        """Advance the model by one step.

        Parameters
        ----------
        temps : Temperatures
            Node temperatures at the step's start [degC].
        q_floor_w : float
            Heat into the floor from the emission system [W] (negative: cooling).
        exo : Exogenous
            The step's weather and loads (``t_amb_c`` [degC], ``ghi_w_m2`` [W/m2], the
            appliance load ``p_load_w`` [W] whose heat a detailed model releases in the rooms).

        Returns
        -------
        Temperatures
            Node temperatures at the step's end [degC].
        """
        ...

    def close(self) -> None:
        """End the model's own simulator, if any (idempotent)."""
        ...


class RCBuilding:
    """The paper's 4R3C building model (``eq:state_update_bldgs``) for steps of ``dt_h`` hours.

    The model structure is Langner et al. (2024), the one the paper cites in ``sec:bldg``.

    Parameters
    ----------
    b : BuildingParams
        The 4R3C's parameters (:func:`continuous`).
    dt_h : float
        Step t_s [h].

    Attributes
    ----------
    Ad, Bd : numpy.ndarray
        The discrete model (:func:`discretize`).
    """

    name = "rc"
    __slots__ = ("params", "Ad", "Bd", "_coef", "_gains")

    def __init__(self, b: BuildingParams, dt_h: float) -> None:
        self.params = b
        self.Ad, self.Bd = discretize(b, dt_h)
        #: row by row: A_d[i, 0..2], B_d[i, 0..2] as floats
        self._coef = tuple(float(v) for i in range(3) for v in (*self.Ad[i], *self.Bd[i, :3]))
        #: B_d[:, 3] of the internal gains, or None without them
        self._gains = tuple(float(v) for v in self.Bd[:, 3]) if self.Bd.shape[1] > 3 else None

    def initial_temperatures(self, t_air_c: float, t_amb_c: float) -> Temperatures:
        """Return the walls on the steady-state profile between the air and the ambient, without sun.

        Parameters
        ----------
        t_air_c : float
            Indoor air temperature [degC].
        t_amb_c : float
            Ambient temperature [degC].

        Returns
        -------
        Temperatures
            (T_air, T_w,in, T_w,out) [degC] along the resistance chain R_w,air, R_w, R_w,amb.
        """
        b = self.params
        r_chain = b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w
        dt = t_air_c - t_amb_c
        return (t_air_c, t_air_c - dt * b.r_w_air_k_per_w / r_chain,
                t_air_c - dt * (b.r_w_air_k_per_w + b.r_w_k_per_w) / r_chain)

    def step(self, temps: Temperatures, q_floor_w: float, exo: Exogenous) -> Temperatures:
        """Advance by one step, x[k+1] = A_d x[k] + B_d u[k] with u = [Q_h,SH, T_amb, q_s] (``eq:state_update_bldgs``).

        With ``f_gains_air`` > 0 the appliance load ``exo.p_load_w`` is a fourth input.

        Parameters
        ----------
        temps : Temperatures
            x[k] [degC].
        q_floor_w : float
            Q_h,SH [W] (negative: cooling).
        exo : Exogenous
            T_amb [degC], q_s [W/m2] (and P_el,load [W]).

        Returns
        -------
        Temperatures
            x[k+1] [degC].
        """
        x0, x1, x2 = temps
        t_amb, q_s = exo.t_amb_c, exo.ghi_w_m2
        a00, a01, a02, b00, b01, b02, a10, a11, a12, b10, b11, b12, a20, a21, a22, b20, b21, b22 = self._coef
        t_air = a00 * x0 + a01 * x1 + a02 * x2 + b00 * q_floor_w + b01 * t_amb + b02 * q_s
        t_wi = a10 * x0 + a11 * x1 + a12 * x2 + b10 * q_floor_w + b11 * t_amb + b12 * q_s
        t_wo = a20 * x0 + a21 * x1 + a22 * x2 + b20 * q_floor_w + b21 * t_amb + b22 * q_s
        if self._gains is None:
            return t_air, t_wi, t_wo
        g = exo.p_load_w
        g0, g1, g2 = self._gains
        return t_air + g0 * g, t_wi + g1 * g, t_wo + g2 * g

    def close(self) -> None:
        """Do nothing: the 4R3C is plain arithmetic, with no simulator to end."""
