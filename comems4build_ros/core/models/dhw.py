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


