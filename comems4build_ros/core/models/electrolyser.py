"""Electrolyser (EL) modules that fill the H2 store, with compression to the store's pressure.

Each of ``n_modules`` identical modules runs at the same load x (H2 output as a fraction
of its rated output), x in {0} U [x_min, 1]. Per module:

    P_stack(x)  piecewise linear over the datasheet/part-load points (stack + balance of plant)
    m_H2(x)   = x * m_rated,            m_rated = h2_rated_nl_per_h * rho_n
    P_comp(x) = m_H2(x) * w_comp,       w_comp = R T ln(p_store / p_out) / (M_H2 eta_comp)
    P_EL(x)   = P_stack(x) + P_comp(x)  (what the EL draws from the house's bus)
    P_H2(x)   = m_H2(x) * LHV           (what enters the store, ``eq:LOH`` in LHV terms)

A start (the EL was off in the previous step) produces no H2 for ``start_lost_h`` of the
step while drawing its power (warm-up of the stack). While installed and off, each module
draws ``p_standby_w``. The stack's waste heat P_stack - P_H2 is recovered into the DHW tank
with the share ``heat_recovery`` (the compressor's heat is not).

Constants: LHV 33.33 kWh/kg and normal density 0.08988 kg/Nm3 of hydrogen (0 degC,
1.01325 bar), molar mass 2.016 g/mol, R = 8.314 J/(mol K).
"""

from __future__ import annotations

import bisect
import math

from comems4build_ros.core.config import SECONDS_PER_HOUR, ElectrolyserParams
from comems4build_ros.core.types import CLIP_EL_H2, CLIP_EL_RANGE

#: Lower heating value of hydrogen [Wh/kg].
LHV_WH_PER_KG = 33_330.0
#: Density of hydrogen at normal conditions (0 degC, 1.01325 bar) [kg/Nm3].
RHO_N_KG_PER_M3 = 0.08988
#: Molar mass of H2 [kg/mol] and the gas constant [J/(mol K)].
M_H2_KG_PER_MOL = 2.01588e-3
R_J_PER_MOL_K = 8.314462618
#: Litres per cubic metre.
L_PER_M3 = 1000.0


def compression_wh_per_kg(el: ElectrolyserParams) -> float:
    """Compute the electrical work of compressing 1 kg of H2 from ``p_out_bar`` to ``p_store_bar``.

    Isothermal ideal-gas work R T ln(p_store / p_out) / M_H2 at ``t_compression_c`` divided
    by ``eta_compressor``; zero when the store's pressure is not above the EL's output pressure.

    Parameters
    ----------
    el : ElectrolyserParams
        ``p_out_bar`` and ``p_store_bar`` [bar], ``t_compression_c`` [degC], ``eta_compressor`` [-].

    Returns
    -------
    float
        Compression work [Wh/kg].
    """
    if el.p_store_bar <= el.p_out_bar:
        return 0.0
    t_k = el.t_compression_c + 273.15
    w_j_per_kg = R_J_PER_MOL_K * t_k * math.log(el.p_store_bar / el.p_out_bar) / M_H2_KG_PER_MOL
    return w_j_per_kg / el.eta_compressor / SECONDS_PER_HOUR


class ElectrolyserTable:
    """Operating curve of the installed electrolyser modules (all running at one load).

    The default module is the Enapter EL 2.1 (AEM) of its datasheet (``config/plant.yaml``).

    Parameters
    ----------
    el : ElectrolyserParams
        ``n_modules``; per module the rated H2 output ``h2_rated_nl_per_h`` [Nl/h], the load
        points [-] and their stack power ``p_el_points_w`` [W], ``p_standby_w`` [W],
        ``start_lost_h`` [h], ``heat_recovery`` [-] and the compression parameters.

    Attributes
    ----------
    n : int
        Installed modules.
    p_min_w, p_max_w : float
        Intake of all modules at the minimal and at full load, compression included [W]
        (0 without modules).
    p_standby_w : float
        Standby draw of all modules [W].
    """

    def __init__(self, el: ElectrolyserParams) -> None:
        self.n = int(el.n_modules)
        self.x_points = [float(x) for x in el.load_points]
        self.p_stack_points = [float(p) for p in el.p_el_points_w]
        self.m_rated_kg_per_h = el.h2_rated_nl_per_h / L_PER_M3 * RHO_N_KG_PER_M3
        self.h2_rated_w = self.m_rated_kg_per_h * LHV_WH_PER_KG  # LHV power at rated output, per module
        self.p_comp_rated_w = self.m_rated_kg_per_h * compression_wh_per_kg(el)
        self.x_min = self.x_points[0]
        self.p_total_points = [
            self.n * (p + x * self.p_comp_rated_w) for x, p in zip(self.x_points, self.p_stack_points)
        ]
        self.p_min_w = self.p_total_points[0] if self.n else 0.0
        self.p_max_w = self.p_total_points[-1] if self.n else 0.0
        self.p_standby_w = self.n * float(el.p_standby_w)
        self.heat_recovery = float(el.heat_recovery)
        self.start_lost_h = float(el.start_lost_h)

    def p_stack_w(self, x: float) -> float:
        """Return the stack and balance-of-plant power of all modules at a load.

        Parameters
        ----------
        x : float
            Load, H2 output over the rated output [-], in [x_min, 1].

        Returns
        -------
        float
            Power [W], piecewise linear over the datasheet's load points.
        """
        xs, ps = self.x_points, self.p_stack_points
        if x <= xs[0]:
            return self.n * ps[0]
        j = min(bisect.bisect_right(xs, x) - 1, len(xs) - 2)
        return self.n * (ps[j] + (x - xs[j]) * (ps[j + 1] - ps[j]) / (xs[j + 1] - xs[j]))

    def p_total_w(self, x: float) -> float:
        """Return the electrical intake of all modules at a load, compression included.

        Parameters
        ----------
        x : float
            Load [-].

        Returns
        -------
        float
            P_EL = P_stack + P_comp [W].
        """
        return self.p_stack_w(x) + self.n * x * self.p_comp_rated_w

    def load_of_power(self, p_w: float) -> float:
        """Return the load at which the modules draw a given intake (inverse of :meth:`p_total_w`).

        Parameters
        ----------
        p_w : float
            Intake [W], in [p_min_w, p_max_w].

        Returns
        -------
        float
            Load x [-].
        """
        ps, xs = self.p_total_points, self.x_points
        if p_w <= ps[0]:
            return xs[0]
        if p_w >= ps[-1]:
            return 1.0
        j = bisect.bisect_right(ps, p_w) - 1
        return xs[j] + (p_w - ps[j]) * (xs[j + 1] - xs[j]) / (ps[j + 1] - ps[j])

    def h2_w(self, x: float) -> float:
        """Return the H2 output of all modules at a load in steady operation, as LHV power.

        Parameters
        ----------
        x : float
            Load [-].

        Returns
        -------
        float
            P_H2 = x * m_rated * LHV per module, times the modules [W].
        """
        return self.n * x * self.h2_rated_w

    def efficiency(self, x: float) -> float:
        """Return the LHV efficiency at a load, compression included.

        Parameters
        ----------
        x : float
            Load [-].

        Returns
        -------
        float
            P_H2 / P_EL [-].
        """
        return self.h2_w(x) / self.p_total_w(x)

    def run(self, p_req_w: float, loh: float, was_on: bool, dt_h: float, loh_max: float,
            e_h2_wh: float) -> tuple[float, float, bool, float, float, int]:
        """Run the modules for one step of a requested intake.

        The request goes onto {0} U [P_EL,min, P_EL,max] (from half of P_EL,min on it is
        raised to it), then down to what fits into the store below LOH_max (off below the
        minimal load). Off, the modules draw their standby power; a start loses
        ``start_lost_h`` of the step's H2. The H2 made enters the store (``eq:LOH`` with the
        sign of a filling).

        Parameters
        ----------
        p_req_w : float
            Requested intake [W] (finite).
        loh : float
            LOH after the fuel cell's draw of this step [-].
        was_on : bool
            The modules produced in the previous step.
        dt_h : float
            Step t_s [h].
        loh_max : float
            Upper bound of the store [-].
        e_h2_wh : float
            The store's LHV energy content E_H2,max [Wh].

        Returns
        -------
        p_el_w : float
            Intake, compression and standby included [W].
        p_h2_w : float
            H2 made as LHV power [W].
        on : bool
            The modules produced.
        q_rec_w : float
            Recoverable heat [W].
        loh : float
            LOH after the step [-].
        clip : int
            ``CLIP_EL_RANGE`` and ``CLIP_EL_H2`` bits.
        """
        clip = 0
        if self.n == 0:
            return 0.0, 0.0, False, 0.0, loh, (CLIP_EL_RANGE if p_req_w != 0.0 else 0)
        p_min, p_max = self.p_min_w, self.p_max_w
        if p_req_w <= 0.0:
            if p_req_w < 0.0:
                clip |= CLIP_EL_RANGE
            return self.p_standby_w, 0.0, False, 0.0, loh, clip
        if p_req_w < p_min:
            clip |= CLIP_EL_RANGE
            if p_req_w < 0.5 * p_min:
                return self.p_standby_w, 0.0, False, 0.0, loh, clip
            p_req_w = p_min
        elif p_req_w > p_max:
            clip |= CLIP_EL_RANGE
            p_req_w = p_max
        x = self.load_of_power(p_req_w)
        f_prod = 1.0 if was_on else max(0.0, 1.0 - self.start_lost_h / dt_h)
        room_w = (loh_max - loh) * e_h2_wh / dt_h
        h2 = self.h2_w(x) * f_prod
        if h2 > room_w:
            clip |= CLIP_EL_H2
            x_fit = room_w / (self.h2_w(1.0) * f_prod) if f_prod > 0.0 else 0.0
            if x_fit < self.x_min:
                return self.p_standby_w, 0.0, False, 0.0, loh, clip
            x = x_fit
            h2 = min(self.h2_w(x) * f_prod, room_w)
        p_el = self.p_total_w(x)
        waste = self.p_stack_w(x) - h2
        q_rec = self.heat_recovery * waste if waste > 0.0 else 0.0
        if h2 > 0.0:
            loh = loh + h2 * dt_h / e_h2_wh
            if loh > loh_max:
                loh = loh_max
        return p_el, h2, True, q_rec, loh, clip

    def specific_kwh_per_nm3(self, x: float, compression: bool = False) -> float:
        """Return the electricity per normal cubic metre of H2 at a load (the datasheet's figure).

        Parameters
        ----------
        x : float
            Load [-].
        compression : bool
            Include the compressor's work (the datasheet's figure does not).

        Returns
        -------
        float
            Specific consumption [kWh/Nm3].
        """
        nm3_per_h = self.n * x * self.m_rated_kg_per_h / RHO_N_KG_PER_M3
        p = self.p_total_w(x) if compression else self.p_stack_w(x)
        return p / 1000.0 / nm3_per_h
