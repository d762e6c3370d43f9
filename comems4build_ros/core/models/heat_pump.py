"""Air-source heat pump, ``sec:hp`` (``eq:zetas`` .. ``eq:heat_flux_DHW``).

    Q_h = COP(T_amb, T_supply) * P_el,HP,   P_el,HP = eta_HP * P_el,max(T_amb),
    eta_HP in {0} U [eta_min, 1],   s_SH + s_DHW <= 1

COP: the paper gives the range of the LG Therma V HM051M U43 (5 kW heating capacity):
1.93..5.16 at 45 degC supply and 1.6..4.15 at 55 degC supply for T_amb from -15 to 20
degC. The parameter file holds COP tables over T_amb for both supply temperatures
(default: the two range ends, i.e. linear in T_amb). Between the tables the COP is
interpolated linearly in T_supply; outside the T_amb table and outside 45..55 degC the
inputs are clipped to the table (the COP is held at the range end rather than
extrapolated).

P_el,max(T_amb): the maximal electrical intake, piecewise linear in T_amb from the
parameter file and held constant outside the table. The default table is a documented
choice (see ``config/plant.yaml``): about 5 kW of heat at A7/W55 and less in the cold.
"""

from __future__ import annotations

import numpy as np

from comems4build_ros.core.config import HeatPumpParams

#: Supply temperatures of the two COP tables [degC] (paper ``sec:hp``).
T_SUPPLY_TABLE_C = (45.0, 55.0)


def cop(t_amb_c, t_supply_c, hp: HeatPumpParams):
    """Coefficient of performance COP(T_amb, T_supply) [-] (vectorised).

    Parameters
    ----------
    t_amb_c : numeric
        Ambient air temperature [degC].
    t_supply_c : numeric
        Supply (flow) temperature [degC]; 55 for space heating, 45 for DHW.
    hp : HeatPumpParams
        ``cop_t_amb_c`` [degC], ``cop_45c`` and ``cop_55c`` [-].
    """
    t_amb = np.asarray(t_amb_c, dtype=float)
    c45 = np.interp(t_amb, hp.cop_t_amb_c, hp.cop_45c)
    c55 = np.interp(t_amb, hp.cop_t_amb_c, hp.cop_55c)
    lo, hi = T_SUPPLY_TABLE_C
    w = np.clip((np.asarray(t_supply_c, dtype=float) - lo) / (hi - lo), 0.0, 1.0)
    out = c45 + w * (c55 - c45)
    return float(out) if out.ndim == 0 else out


def p_el_max_w(t_amb_c, hp: HeatPumpParams):
    """Maximal electrical intake P_el,max(T_amb) [W] (vectorised, piecewise linear)."""
    out = np.interp(np.asarray(t_amb_c, dtype=float), hp.p_el_max_t_amb_c, hp.p_el_max_w)
    return float(out) if np.ndim(out) == 0 else out


def heat_capacity_w(t_amb_c, t_supply_c, hp: HeatPumpParams):
    """Heat output at full modulation COP * P_el,max [W] (vectorised)."""
    return np.asarray(cop(t_amb_c, t_supply_c, hp)) * np.asarray(p_el_max_w(t_amb_c, hp))


