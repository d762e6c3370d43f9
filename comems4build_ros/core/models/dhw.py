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
    """Heat to raise one litre from T_cold to T_DHW, rho * c * Delta T_DHW [J/l]."""
    return dhw.rho_kg_per_l * dhw.c_j_per_kg_k * (dhw.t_dhw_c - dhw.t_cold_c)


def heat_w_from_l_per_h(l_per_h, dhw: DHWParams):
    """Heat flow [W] of a hot-water draw at T_DHW given in l/h (vectorised).

    Q_dm,DHW = V_dot * rho * c * Delta T_DHW, with V_dot [l/s] = l_per_h / 3600.
    """
    return np.asarray(l_per_h, dtype=float) / SECONDS_PER_HOUR * heat_per_litre_j(dhw)




class Tank:
    """The DHW tank of the plant step: its bounds and conversions for a step of ``dt_h`` hours.

    Parameters
    ----------
    dhw : DHWParams
    dt_h : step t_s [h]
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
        """Heat flow of a draw Q_dm,DHW [W] (``eq:DHW_model``)."""
        return dhw_l_per_h * self.w_per_l_per_h

    def room_w(self, v_l: float, q_demand_w: float) -> float:
        """Largest net heat inflow [W] that fits: what fills the tank from ``v_l`` over the step."""
        return (self.v_max_l - v_l) / self.l_per_w + q_demand_w + self.q_loss_w

    def step(self, v_l: float, q_hp_w: float, q_fc_w: float, q_el_w: float, q_demand_w: float,
             room_w: float) -> tuple[float, float, float, float, float, float]:
        """One step of ``eq:DHW_model`` with the heat of ``eq:DHW_heat``.

        Recovered FC heat goes in first, then recovered EL heat; what no longer fits beside
        the heat pump's is dumped. Draws and standing losses that would take the volume
        below V_min are unmet.

        Parameters
        ----------
        v_l : V_DHW[k-1] [l]
        q_hp_w : heat-pump heat into the tank [W] (already fitted to ``room_w``)
        q_fc_w, q_el_w : recoverable fuel-cell and electrolyser heat [W]
        q_demand_w : heat of the draws [W]
        room_w : :meth:`room_w` of this step [W]

        Returns
        -------
        (V_DHW[k] [l], FC heat taken [W], FC heat dumped [W], EL heat taken [W],
         EL heat dumped [W], unmet demand [W])
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
