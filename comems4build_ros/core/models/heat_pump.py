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
    """Weight of the 55 degC COP table at a supply temperature, clipped to 0..1 (vectorised).

    Parameters
    ----------
    t_supply_c : float or array_like
        Supply (flow) temperature [degC].

    Returns
    -------
    float or numpy.ndarray
        ``(T_supply - 45) / (55 - 45)`` clipped to [0, 1] [-]; 0 at 45 degC, 1 at 55 degC
        (the paper's two COP ranges, ``sec:hp``).
    """
    lo, hi = T_SUPPLY_TABLE_C
    w = np.clip((np.asarray(t_supply_c, dtype=float) - lo) / (hi - lo), 0.0, 1.0)
    return float(w) if w.ndim == 0 else w


def blend(cop_45c, cop_55c, weight):
    """Interpolate the COP between the two supply-temperature tables.

    Parameters
    ----------
    cop_45c, cop_55c : float or array_like
        COP at 45 and at 55 degC supply [-].
    weight : float or array_like
        Weight of the 55 degC table [-] (:func:`supply_weight`).

    Returns
    -------
    float or numpy.ndarray
        ``COP45 + weight * (COP55 - COP45)`` [-].
    """
    return cop_45c + weight * (cop_55c - cop_45c)


def cop(t_amb_c, t_supply_c, hp: HeatPumpParams):
    """Compute the coefficient of performance COP(T_amb, T_supply) (vectorised, ``sec:hp``).

    Parameters
    ----------
    t_amb_c : float or array_like
        Ambient air temperature [degC].
    t_supply_c : float or array_like
        Supply (flow) temperature [degC]; 55 for space heating, 45 for DHW.
    hp : HeatPumpParams
        ``cop_t_amb_c`` [degC], ``cop_45c`` and ``cop_55c`` [-] (LG Therma V HM051M U43 range).

    Returns
    -------
    float or numpy.ndarray
        COP [-], the tables held constant outside their T_amb range.
    """
    t_amb = np.asarray(t_amb_c, dtype=float)
    c45 = np.interp(t_amb, hp.cop_t_amb_c, hp.cop_45c)
    c55 = np.interp(t_amb, hp.cop_t_amb_c, hp.cop_55c)
    out = blend(c45, c55, np.asarray(supply_weight(t_supply_c)))
    return float(out) if out.ndim == 0 else out


def p_el_max_w(t_amb_c, hp: HeatPumpParams):
    """Compute the maximal electrical intake P_el,max(T_amb) (vectorised, piecewise linear).

    Parameters
    ----------
    t_amb_c : float or array_like
        Ambient air temperature [degC].
    hp : HeatPumpParams
        ``p_el_max_t_amb_c`` [degC] and ``p_el_max_w`` [W] (``config/plant.yaml``).

    Returns
    -------
    float or numpy.ndarray
        P_el,max [W], held constant outside the table.
    """
    out = np.interp(np.asarray(t_amb_c, dtype=float), hp.p_el_max_t_amb_c, hp.p_el_max_w)
    return float(out) if np.ndim(out) == 0 else out


def heat_capacity_w(t_amb_c, t_supply_c, hp: HeatPumpParams):
    """Compute the heat output at full modulation, COP * P_el,max (vectorised, ``sec:hp``).

    Parameters
    ----------
    t_amb_c : float or array_like
        Ambient air temperature [degC].
    t_supply_c : float or array_like
        Supply temperature [degC].
    hp : HeatPumpParams
        The heat pump's tables.

    Returns
    -------
    numpy.ndarray
        Heat output Q_h at eta_HP = 1 [W].
    """
    return np.asarray(cop(t_amb_c, t_supply_c, hp)) * np.asarray(p_el_max_w(t_amb_c, hp))


def modulation(hp_mod: float, mode: int, mod_min: float) -> tuple[float, int, int]:
    """Put a requested modulation onto {0} U [eta_min, 1] (``eq:zetas``).

    A request below eta_min is raised to it from half of eta_min on, else the heat pump
    stops; a modulation without a circuit, or a circuit without modulation, is off.

    Parameters
    ----------
    hp_mod : float
        Requested modulation eta_HP [-] (finite).
    mode : int
        Requested circuit (``HP_OFF``, ``HP_SH``, ``HP_DHW``, ``HP_COOL``).
    mod_min : float
        Minimal modulation eta_min [-].

    Returns
    -------
    mod : float
        eta_HP [-].
    mode : int
        The circuit, ``HP_OFF`` when eta_HP = 0.
    clip : int
        ``CLIP_HP_MOD`` if the request was changed, else 0.
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
    """The heat pump of the plant step: COP, EER and P_el,max tables evaluated per step (``sec:hp``).

    Parameters
    ----------
    hp : HeatPumpParams
        Minimal modulation ``mod_min`` [-], COP tables over T_amb [degC] at 45 and 55 degC
        supply [-], P_el,max table [W], supply temperatures ``t_supply_sh_c`` and
        ``t_supply_dhw_c`` [degC].
    cooling : CoolingParams
        EER table over T_amb [degC] and the floor's cooling capacity ``q_cool_max_w`` [W].
    """

    __slots__ = ("mod_min", "_cop", "_p_el_max", "_eer", "_q_cool_max", "_weight")

    def __init__(self, hp: HeatPumpParams, cooling: CoolingParams) -> None:
        self.mod_min = float(hp.mod_min)
        self._cop = PiecewiseLinear(hp.cop_t_amb_c, hp.cop_45c, hp.cop_55c)  # COP45 and COP55 over one T_amb table
        self._p_el_max = PiecewiseLinear(hp.p_el_max_t_amb_c, hp.p_el_max_w)
        self._eer = PiecewiseLinear(cooling.eer_t_amb_c, cooling.eer)
        self._q_cool_max = float(cooling.q_cool_max_w)
        self._weight = {HP_SH: supply_weight(hp.t_supply_sh_c), HP_DHW: supply_weight(hp.t_supply_dhw_c)}

    def operating_point(self, mode: int, t_amb_c: float) -> tuple[float, float]:
        """Return the COP and the intake at full modulation of a circuit.

        Parameters
        ----------
        mode : int
            Circuit ``HP_SH``, ``HP_DHW`` or ``HP_COOL``.
        t_amb_c : float
            Ambient temperature [degC].

        Returns
        -------
        cop : float
            COP of the circuit's supply temperature (:func:`cop`), or the EER when cooling [-].
        p_el_max_w : float
            Electrical intake at eta_HP = 1 [W]: P_el,max(T_amb), or Q_cool,max / EER.
        """
        _, _, c, p_el_max, _, _, _ = self.run(1.0, mode, t_amb_c)
        return c, p_el_max

    def run(self, hp_mod: float, mode: int, t_amb_c: float) -> tuple[int, float, float, float, float, float, int]:
        """Run the heat pump for one step of a request (``eq:zetas`` .. ``eq:heat_flux_DHW``).

        Parameters
        ----------
        hp_mod : float
            Requested modulation eta_HP [-] (finite).
        mode : int
            Requested circuit.
        t_amb_c : float
            Ambient temperature [degC].

        Returns
        -------
        mode : int
            The circuit served (``HP_OFF`` when off).
        mod : float
            eta_HP [-] (:func:`modulation`).
        cop : float
            COP (EER when cooling) [-]; 0 when off.
        p_el_max_w : float
            Intake at full modulation [W]; 0 when off.
        p_el_w : float
            Electrical intake P_el,HP = eta_HP * P_el,max [W].
        q_w : float
            Heat delivered (taken from the rooms when cooling) Q_h = COP * P_el,HP [W].
        clip : int
            ``CLIP_HP_MOD`` if the modulation was changed.
        """
        mod, mode, clip = modulation(hp_mod, mode, self.mod_min)
        if mod == 0.0:
            return HP_OFF, 0.0, 0.0, 0.0, 0.0, 0.0, clip
        # the operating point, written out here (not a call) for the plant step's speed
        if mode == HP_COOL:
            c = self._eer.at(t_amb_c)
            p_el_max = self._q_cool_max / c
        else:
            c45, c55 = self._cop.at2(t_amb_c)
            c = c45 + self._weight[mode] * (c55 - c45)  # blend(c45, c55, weight)
            p_el_max = self._p_el_max.at(t_amb_c)
        p_hp = mod * p_el_max
        return mode, mod, c, p_el_max, p_hp, c * p_hp, clip

    def fit_heat(self, q_cap_w: float, cop_: float, p_el_max: float) -> tuple[float, float, float, int]:
        """Fit the modulation to deliver at most ``q_cap_w`` of heat (a DHW tank that would overflow).

        Parameters
        ----------
        q_cap_w : float
            Heat the tank can still take [W].
        cop_ : float
            COP of the DHW circuit [-].
        p_el_max : float
            Intake at full modulation [W].

        Returns
        -------
        mod : float
            eta_HP [-]; 0 (off) when less than eta_min would be needed.
        p_el_w : float
            Electrical intake [W].
        q_w : float
            Heat delivered [W].
        clip : int
            ``CLIP_HP_DHW_FULL``.
        """
        mod_fit = q_cap_w / (cop_ * p_el_max) if q_cap_w > 0.0 else 0.0
        if mod_fit < self.mod_min:
            return 0.0, 0.0, 0.0, CLIP_HP_DHW_FULL
        p_hp = mod_fit * p_el_max
        return mod_fit, p_hp, cop_ * p_hp, CLIP_HP_DHW_FULL
