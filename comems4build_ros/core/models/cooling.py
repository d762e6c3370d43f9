"""Cooling by the reversible air-water heat pump through the underfloor system.

In cooling mode (``HP_COOL``) the heat pump takes heat from the rooms through the floor
loops at a supply temperature kept above the dew point of the room air (no condensation
on the floor: ``CoolingParams`` refuses a lower supply). The floor's cooling capacity at
that supply, ``q_cool_max_w``, is what the modulation scales:

    Q_cool = eta_HP * Q_cool,max,   P_el,HP = Q_cool / EER(T_amb),   eta_HP in {0} U [eta_min, 1]

EER(T_amb) is piecewise linear over the table of ``config/plant.yaml`` (held constant
outside it); the sources of the figures are there. The heat enters the 4R3C building
model (``eq:state_update_bldgs``) as a negative floor heat flux.
"""

from __future__ import annotations

import numpy as np

from comems4build_ros.core.config import CoolingParams
from comems4build_ros.core.psychrometrics import dew_point_c

__all__ = ["dew_point_c", "eer", "p_el_max_cool_w"]


def eer(t_amb_c, cooling: CoolingParams):
    """Compute the energy efficiency ratio EER(T_amb) (vectorised, piecewise linear).

    Parameters
    ----------
    t_amb_c : float or array_like
        Ambient temperature [degC].
    cooling : CoolingParams
        ``eer_t_amb_c`` [degC] and ``eer`` [-] (sources in ``config/plant.yaml``).

    Returns
    -------
    float or numpy.ndarray
        EER [-], held constant outside the table.
    """
    out = np.interp(np.asarray(t_amb_c, dtype=float), cooling.eer_t_amb_c, cooling.eer)
    return float(out) if np.ndim(out) == 0 else out


def p_el_max_cool_w(t_amb_c, cooling: CoolingParams):
    """Compute the electrical intake at full cooling modulation, Q_cool,max / EER(T_amb) (vectorised).

    Parameters
    ----------
    t_amb_c : float or array_like
        Ambient temperature [degC].
    cooling : CoolingParams
        EER table and the floor's cooling capacity ``q_cool_max_w`` [W].

    Returns
    -------
    float or numpy.ndarray
        P_el,HP at eta_HP = 1 in cooling mode [W].
    """
    return cooling.q_cool_max_w / np.asarray(eer(t_amb_c, cooling)) if np.ndim(t_amb_c) else \
        cooling.q_cool_max_w / eer(t_amb_c, cooling)
