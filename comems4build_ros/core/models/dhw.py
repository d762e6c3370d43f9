"""Domestic hot-water (DHW) storage, ``eq:DHW_model`` and ``eq:DHW_heat``.

The tank is held at T_DHW; its state is the usable volume at T_DHW:

    V[k] = V[k-1] + (Q_DHW - Q_dm,DHW - Q_l,DHW) / (Delta T_DHW * rho * c) * t_s     (eq:DHW_model)
    Q_DHW = Q_h,DHW (heat pump) + Q_hr,FC (recovered fuel-cell heat)                (eq:DHW_heat)
    V_min <= V[k] <= V_max

with Delta T_DHW = T_DHW - T_cold. Volumes in litres, density in kg/l, so
``rho * c * Delta T`` is the heat per litre [J/l].
"""

from __future__ import annotations

import numpy as np

from comems4build_ros.core.config import SECONDS_PER_HOUR, DHWParams


def heat_per_litre_j(dhw: DHWParams) -> float:
    """Compute the heat that raises one litre from T_cold to T_DHW (``eq:DHW_model``).

    Parameters
    ----------
    dhw : DHWParams
        ``rho_kg_per_l`` [kg/l], ``c_j_per_kg_k`` [J/(kg K)], ``t_dhw_c`` and ``t_cold_c`` [degC].

    Returns
    -------
    float
        rho * c * Delta T_DHW [J/l].
    """
    return dhw.rho_kg_per_l * dhw.c_j_per_kg_k * (dhw.t_dhw_c - dhw.t_cold_c)


def heat_w_from_l_per_h(l_per_h, dhw: DHWParams):
    """Compute the heat flow of a hot-water draw at T_DHW (vectorised, ``eq:DHW_model``).

    Q_dm,DHW = V_dot * rho * c * Delta T_DHW, with V_dot [l/s] = l_per_h / 3600.

    Parameters
    ----------
    l_per_h : float or array_like
        Draw at T_DHW [l/h].
    dhw : DHWParams
        The tank's water properties and temperatures.

    Returns
    -------
    numpy.ndarray
        Q_dm,DHW [W].
    """
    return np.asarray(l_per_h, dtype=float) / SECONDS_PER_HOUR * heat_per_litre_j(dhw)


class Tank:
    """The DHW tank of the plant step: its bounds and conversions for a step of ``dt_h`` hours (``sec:dhw``).

    Parameters
    ----------
    dhw : DHWParams
        Water properties and temperatures, ``v_min_l`` and ``v_max_l`` [l], standing loss
        ``q_loss_w`` [W].
    dt_h : float
        Step t_s [h].

    Attributes
    ----------
    l_per_w : float
        Litres at T_DHW that one watt held over the step heats [l/W].
    w_per_l_per_h : float
        Heat flow of a draw of 1 l/h [W/(l/h)].
    v_min_l, v_max_l : float
        Volume bounds [l].
    q_loss_w : float
        Standing loss Q_l,DHW [W].
    """

    __slots__ = ("l_per_w", "w_per_l_per_h", "v_min_l", "v_max_l", "q_loss_w")

    def __init__(self, dhw: DHWParams, dt_h: float) -> None:
        j_per_l = heat_per_litre_j(dhw)
        self.l_per_w = dt_h * SECONDS_PER_HOUR / j_per_l  # litres per W held over the step
        self.w_per_l_per_h = j_per_l / SECONDS_PER_HOUR
        self.v_min_l = float(dhw.v_min_l)
        self.v_max_l = float(dhw.v_max_l)
        self.q_loss_w = float(dhw.q_loss_w)

    def demand_w(self, dhw_l_per_h: float) -> float:
        """Return the heat flow of a draw, Q_dm,DHW (``eq:DHW_model``).

        Parameters
        ----------
        dhw_l_per_h : float
            Draw at T_DHW [l/h].

        Returns
        -------
        float
            Q_dm,DHW [W].
        """
        return dhw_l_per_h * self.w_per_l_per_h

    def room_w(self, v_l: float, q_demand_w: float) -> float:
        """Return the largest net heat inflow that fits: what fills the tank from ``v_l`` over the step.

        Parameters
        ----------
        v_l : float
            V_DHW[k-1] [l].
        q_demand_w : float
            Heat of the step's draws [W].

        Returns
        -------
        float
            Heat inflow that brings the volume to V_max, draws and standing loss included [W].
        """
        return (self.v_max_l - v_l) / self.l_per_w + q_demand_w + self.q_loss_w

    def step(self, v_l: float, q_hp_w: float, q_fc_w: float, q_el_w: float, q_demand_w: float,
             room_w: float) -> tuple[float, float, float, float, float, float]:
        """Advance the tank by one step of ``eq:DHW_model`` with the heat of ``eq:DHW_heat``.

        Recovered FC heat goes in first, then recovered EL heat; what no longer fits beside
        the heat pump's is dumped. Draws and standing losses that would take the volume
        below V_min are unmet.

        Parameters
        ----------
        v_l : float
            V_DHW[k-1] [l].
        q_hp_w : float
            Heat-pump heat into the tank Q_h,DHW [W] (already fitted to ``room_w``).
        q_fc_w, q_el_w : float
            Recoverable fuel-cell heat Q_hr,FC and electrolyser heat [W].
        q_demand_w : float
            Heat of the draws Q_dm,DHW [W].
        room_w : float
            :meth:`room_w` of this step [W].

        Returns
        -------
        v_l : float
            V_DHW[k] [l].
        q_fc_in_w, q_fc_dump_w : float
            FC heat taken into and dumped beside the tank [W].
        q_el_in_w, q_el_dump_w : float
            EL heat taken and dumped [W].
        q_unmet_w : float
            Draws and losses the tank could not serve [W].
        """
        q_fc_in, q_fc_dump, q_el_in, q_el_dump = q_fc_w, 0.0, q_el_w, 0.0
        if q_fc_w + q_el_w + q_hp_w > room_w:
            avail = room_w - q_hp_w
            if avail < 0.0:
                avail = 0.0
            if q_el_w > 0.0:  # FC heat first, then EL heat
                q_fc_in = q_fc_w if q_fc_w < avail else avail
                q_el_in = min(q_el_w, avail - q_fc_in)
                q_el_dump = q_el_w - q_el_in
            else:
                q_fc_in = avail
            q_fc_dump = q_fc_w - q_fc_in
        v_new = v_l + (q_hp_w + q_fc_in + q_el_in - q_demand_w - self.q_loss_w) * self.l_per_w
        q_unmet = 0.0
        if v_new < self.v_min_l:
            q_unmet = (self.v_min_l - v_new) / self.l_per_w
            v_new = self.v_min_l
        elif v_new > self.v_max_l:
            v_new = self.v_max_l
        return v_new, q_fc_in, q_fc_dump, q_el_in, q_el_dump, q_unmet
