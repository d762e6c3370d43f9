"""The paper's 4R3C building model as an FMI 2.0 co-simulation slave (built into an FMU by pythonfmu).

This file is the FMU's model: ``comems4build export-fmu`` hands it to pythonfmu's builder
together with ``rc_parameters.json`` (the 4R3C parameters of the plant file, SI units), and
the FMU carries both. It imports nothing of comems4build_ros, so the FMU runs wherever
pythonfmu's library finds a Python with NumPy and SciPy.

Equations: ``eq:dT_i`` .. ``eq:dT_wout``, discretised with a zero-order hold over the
master's communication step h (``eq:state_update_bldgs``): expm([[A, B], [0, 0]] h) gives
A_d and B_d, rounded to 12 significant digits exactly as
:func:`comems4build_ros.core.models.building.discretize` rounds them, so that the FMU and the
in-process model compute the same numbers.

Variables (FMI causality): inputs ``Q_floor`` [W] (heat into the floor, negative when
cooling), ``T_amb`` [degC], ``q_sol`` [W/m2] (global horizontal irradiance) and ``P_gains``
[W] (appliance load: the paper's 4R3C has no internal-gain term; an identified model's
``f_gains_air`` > 0 heats the air node with that share of it);
outputs ``T_air``, ``T_w_in``, ``T_w_out`` [degC]; parameters ``T_air_start`` and
``T_amb_start`` [degC] (the walls start on the steady profile between the two, without sun)
and the model's ten parameters under their plant-file names.
"""

from __future__ import annotations

import json
import os

import numpy as np
from pythonfmu.fmi2slave import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

#: Parameter names (plant file, section ``building``), in the order of the JSON file.
PARAMETERS = ("c_air_j_per_k", "c_wall_j_per_k", "r_w_air_k_per_w", "r_air_amb_k_per_w", "r_w_k_per_w",
              "r_w_amb_k_per_w", "g_s_m2", "f_conv", "a_sol_k_m2_per_w", "f_gains_air")
#: Significant digits of A_d and B_d (as the in-process model).
EXPM_DIGITS = 12


class RCBuildingFMU(Fmi2Slave):
    """4R3C building (ComEMS4Build paper, eq:state_update_bldgs) as an FMI 2.0 co-simulation slave.

    Parameters
    ----------
    **kwargs
        pythonfmu's instance arguments; ``resources`` is the folder holding ``rc_parameters.json``
        (the ten 4R3C parameters in SI units, T_air,init and T_amb,init [degC]).
    """

    author = "comems4build_ros"
    description = "4R3C building model of the ComEMS4Build paper (eq:dT_i .. eq:dT_wout), zero-order hold per step"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        values = {}
        resources = kwargs.get("resources") or ""
        path = os.path.join(resources, "rc_parameters.json")
        if os.path.isfile(path):
            with open(path, encoding="utf-8") as f:
                values = json.load(f)
        for name in PARAMETERS:
            setattr(self, name, float(values.get(name, 0.0 if name == "f_gains_air" else 1.0)))
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.T_air_start = float(values.get("t_air_init_c", 21.0))
        self.T_amb_start = float(values.get("t_amb_init_c", 4.2))
        for name in ("T_air_start", "T_amb_start"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.Q_floor = 0.0
        self.T_amb = 0.0
        self.q_sol = 0.0
        self.P_gains = 0.0
        for name in ("Q_floor", "T_amb", "q_sol", "P_gains"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        self.T_air = self.T_air_start
        self.T_w_in = self.T_air_start
        self.T_w_out = self.T_air_start
        for name in ("T_air", "T_w_in", "T_w_out"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))
        self._h = None
        self._ad = None
        self._bd = None
        self._bg = None

    def exit_initialization_mode(self) -> None:
        """Put the walls on the steady profile between T_air_start and T_amb_start (as the in-process model)."""
        r_chain = self.r_w_air_k_per_w + self.r_w_k_per_w + self.r_w_amb_k_per_w
        dt = self.T_air_start - self.T_amb_start
        self.T_air = self.T_air_start
        self.T_w_in = self.T_air_start - dt * self.r_w_air_k_per_w / r_chain
        self.T_w_out = self.T_air_start - dt * (self.r_w_air_k_per_w + self.r_w_k_per_w) / r_chain
        self._h = None

    def _discretize(self, h: float) -> None:
        from scipy.linalg import expm

        ca, cw = self.c_air_j_per_k, self.c_wall_j_per_k
        g_wa, g_aa = 1.0 / self.r_w_air_k_per_w, 1.0 / self.r_air_amb_k_per_w
        g_w, g_wamb = 1.0 / self.r_w_k_per_w, 1.0 / self.r_w_amb_k_per_w
        m = 4 if self.f_gains_air else 3
        aug = np.zeros((3 + m, 3 + m))
        aug[:3, :3] = [[-(g_wa + g_aa) / ca, g_wa / ca, 0.0],
                       [g_wa / cw, -(g_wa + g_w) / cw, g_w / cw],
                       [0.0, g_w / cw, -(g_w + g_wamb) / cw]]
        bm = [[self.f_conv / ca, g_aa / ca, self.g_s_m2 / ca],
              [(1.0 - self.f_conv) / cw, 0.0, 0.0],
              [0.0, g_wamb / cw, g_wamb * self.a_sol_k_m2_per_w / cw]]
        if m == 4:
            bm = [bm[0] + [self.f_gains_air / ca], bm[1] + [0.0], bm[2] + [0.0]]
        aug[:3, 3:] = bm
        aug *= h
        phi = expm(aug)
        phi = [[float(f"{v:.{EXPM_DIGITS - 1}e}") for v in row] for row in phi]
        self._ad = [row[:3] for row in phi[:3]]
        self._bd = [row[3:6] for row in phi[:3]]
        self._bg = [row[6] for row in phi[:3]] if m == 4 else None
        self._h = h

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Advance x[k+1] = A_d x[k] + B_d u[k] over the step (plain float arithmetic, the in-process order).

        Parameters
        ----------
        current_time : float
            The master's time at the step's start [s].
        step_size : float
            Communication step h [s] (A_d and B_d are computed again when it changes).

        Returns
        -------
        bool
            True (the step always succeeds).
        """
        if self._h != step_size:
            self._discretize(step_size)
        x0, x1, x2 = self.T_air, self.T_w_in, self.T_w_out
        q, t_amb, q_s = self.Q_floor, self.T_amb, self.q_sol
        a0, a1, a2 = self._ad
        b0, b1, b2 = self._bd
        self.T_air = a0[0] * x0 + a0[1] * x1 + a0[2] * x2 + b0[0] * q + b0[1] * t_amb + b0[2] * q_s
        self.T_w_in = a1[0] * x0 + a1[1] * x1 + a1[2] * x2 + b1[0] * q + b1[1] * t_amb + b1[2] * q_s
        self.T_w_out = a2[0] * x0 + a2[1] * x1 + a2[2] * x2 + b2[0] * q + b2[1] * t_amb + b2[2] * q_s
        if self._bg is not None:
            g = self.P_gains
            self.T_air += self._bg[0] * g
            self.T_w_in += self._bg[1] * g
            self.T_w_out += self._bg[2] * g
        return True
