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

In cooling mode (``HP_COOL``, :mod:`~comems4build_ros.core.models.cooling`) ``cop`` is the
EER and the intake at full modulation is Q_cool,max / EER(T_amb).

:func:`cop` is the COP of the model; :class:`HeatPump` evaluates the same tables for the
plant step with scalar arithmetic (:class:`~comems4build_ros.core.numerics.PiecewiseLinear`),
which can differ from ``numpy.interp`` in the last bit only.
"""

from __future__ import annotations

import numpy as np

from comems4build_ros.core.config import CoolingParams, HeatPumpParams
from comems4build_ros.core.numerics import PiecewiseLinear
from comems4build_ros.core.types import CLIP_HP_DHW_FULL, CLIP_HP_MOD, HP_COOL, HP_DHW, HP_OFF, HP_SH

#: Supply temperatures of the two COP tables [degC] (paper ``sec:hp``).
T_SUPPLY_TABLE_C = (45.0, 55.0)


def supply_weight(t_supply_c):
    """Weight of the 55 degC table at supply temperature ``t_supply_c`` [degC], clipped to 0..1 (vectorised)."""
    lo, hi = T_SUPPLY_TABLE_C
    w = np.clip((np.asarray(t_supply_c, dtype=float) - lo) / (hi - lo), 0.0, 1.0)
    return float(w) if w.ndim == 0 else w


def blend(cop_45c, cop_55c, weight):
    """COP between the two supply-temperature tables: ``COP45 + w * (COP55 - COP45)`` [-]."""
    return cop_45c + weight * (cop_55c - cop_45c)


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
    out = blend(c45, c55, np.asarray(supply_weight(t_supply_c)))
    return float(out) if out.ndim == 0 else out


def p_el_max_w(t_amb_c, hp: HeatPumpParams):
    """Maximal electrical intake P_el,max(T_amb) [W] (vectorised, piecewise linear)."""
    out = np.interp(np.asarray(t_amb_c, dtype=float), hp.p_el_max_t_amb_c, hp.p_el_max_w)
    return float(out) if np.ndim(out) == 0 else out


def heat_capacity_w(t_amb_c, t_supply_c, hp: HeatPumpParams):
    """Heat output at full modulation COP * P_el,max [W] (vectorised)."""
    return np.asarray(cop(t_amb_c, t_supply_c, hp)) * np.asarray(p_el_max_w(t_amb_c, hp))


def modulation(hp_mod: float, mode: int, mod_min: float) -> tuple[float, int, int]:
    """A requested modulation onto {0} U [eta_min, 1] (``eq:zetas``).

    A request below eta_min is raised to it from half of eta_min on, else the heat pump
    stops; a modulation without a circuit, or a circuit without modulation, is off.

    Parameters
    ----------
    hp_mod : requested eta_HP [-] (finite)
    mode : requested circuit (``HP_OFF``, ``HP_SH``, ``HP_DHW``, ``HP_COOL``)
    mod_min : eta_min [-]

    Returns
    -------
    (eta_HP [-], circuit, clip bits ``CLIP_HP_MOD``)
    """
    clip = 0
    if mode == HP_OFF:
        if hp_mod != 0.0:
            clip = CLIP_HP_MOD
        mod = 0.0
    elif hp_mod <= 0.0:
        if hp_mod < 0.0:
            clip = CLIP_HP_MOD
        mod = 0.0
    elif hp_mod > 1.0:
        mod = 1.0
        clip = CLIP_HP_MOD
    elif hp_mod < mod_min:
        mod = mod_min if hp_mod >= 0.5 * mod_min else 0.0
        clip = CLIP_HP_MOD
    else:
        mod = hp_mod
    return mod, (HP_OFF if mod == 0.0 else mode), clip


class HeatPump:
    """The heat pump of the plant step: COP, EER and P_el,max tables evaluated per step.

    Parameters
    ----------
    hp : HeatPumpParams
    cooling : CoolingParams (EER table and the floor's cooling capacity)
    """

    __slots__ = ("mod_min", "_cop45", "_cop55", "_p_el_max", "_eer", "_q_cool_max", "_weight")

    def __init__(self, hp: HeatPumpParams, cooling: CoolingParams) -> None:
        self.mod_min = float(hp.mod_min)
        self._cop45 = PiecewiseLinear(hp.cop_t_amb_c, hp.cop_45c)
        self._cop55 = PiecewiseLinear(hp.cop_t_amb_c, hp.cop_55c)
        self._p_el_max = PiecewiseLinear(hp.p_el_max_t_amb_c, hp.p_el_max_w)
        self._eer = PiecewiseLinear(cooling.eer_t_amb_c, cooling.eer)
        self._q_cool_max = float(cooling.q_cool_max_w)
        self._weight = {HP_SH: supply_weight(hp.t_supply_sh_c), HP_DHW: supply_weight(hp.t_supply_dhw_c)}

    def operating_point(self, mode: int, t_amb_c: float) -> tuple[float, float]:
        """COP (EER when cooling) [-] and intake at full modulation [W] of a running circuit."""
        if mode == HP_COOL:
            eer = self._eer(t_amb_c)
            return eer, self._q_cool_max / eer
        c45 = self._cop45(t_amb_c)
        return blend(c45, self._cop55(t_amb_c), self._weight[mode]), self._p_el_max(t_amb_c)

    def run(self, hp_mod: float, mode: int, t_amb_c: float) -> tuple[int, float, float, float, float, float, int]:
        """One step of the heat pump for a request.

        Returns
        -------
        (circuit, eta_HP [-], COP [-], P_el,max [W], P_el,HP [W], Q_h [W], clip bits)
        """
        mod, mode, clip = modulation(hp_mod, mode, self.mod_min)
        if mod == 0.0:
            return HP_OFF, 0.0, 0.0, 0.0, 0.0, 0.0, clip
        c, p_el_max = self.operating_point(mode, t_amb_c)
        p_hp = mod * p_el_max
        return mode, mod, c, p_el_max, p_hp, c * p_hp, clip

    def fit_heat(self, q_cap_w: float, cop_: float, p_el_max: float) -> tuple[float, float, float, int]:
        """The modulation that delivers at most ``q_cap_w`` [W] of heat (a DHW tank that would overflow).

        Returns
        -------
        (eta_HP [-], P_el,HP [W], Q_h [W], ``CLIP_HP_DHW_FULL``); eta_HP = 0 (off) when less
        than eta_min would be needed.
        """
        mod_fit = q_cap_w / (cop_ * p_el_max) if q_cap_w > 0.0 else 0.0
        if mod_fit < self.mod_min:
            return 0.0, 0.0, 0.0, CLIP_HP_DHW_FULL
        p_hp = mod_fit * p_el_max
        return mod_fit, p_hp, cop_ * p_hp, CLIP_HP_DHW_FULL
