"""PEM fuel cell and hydrogen store, ``eq:molar_flows`` .. ``eq:FC_sys_efficiency``, ``eq:LOH``.

The paper writes the molar hydrogen flow as a function of the electrical output,
``n_FC = f(P_el,FC)`` (``eq:molar_flows``), and the electrical efficiency from it with
Faraday's law and the lower heating value (``eq:efficiency_FC``). Here ``f`` comes from a
cell polarization curve (Horizon H-2000 PEM stack datasheet: 48 cells, 2000 W at about
28.8 V / 70 A, about 26 l/min H2 at full power):

    V_cell(i) = E_ocv - A * ln(1 + i / i_T) - R_ohm * i                  [V]
    P_el(i)   = N_cells * V_cell(i) * i                                   [W]
    n_FC(i)   = N_cells * i / (2 F)                                       [mol/s]   (eq:molar_flows)
    eta_el    = P_el / (n_FC * LHV) = V_cell / (LHV / 2F) = V_cell / 1.253 V        (eq:efficiency_FC)
    Q_hr      = n_FC * LHV * (eta_sys - eta_el)                           [W]       (eq:FC_sys_efficiency)

The output rises with the current on the branch ``0 <= i <= i_mpp`` (maximum power
point); requests are solved on that branch, so the efficiency falls with the load.
Hydrogen is counted as LHV power ``P_H2 = n_FC * LHV`` [W]; the store's level falls by
``P_H2 * t_s / E_H2,max`` per step (``eq:LOH``).

:class:`FuelCellTable` precomputes ``P_H2(P_el)`` on a fine uniform grid so that the plant
step looks it up with plain float arithmetic.
"""

from __future__ import annotations

import bisect

import numpy as np

from comems4build_ros.core.config import (  # the constants re-exported: the model's figures
    ELECTRONS_PER_H2,
    FARADAY_C_PER_MOL,
    LHV_H2_J_PER_MOL,
    V_LHV_V,
    W_PER_KW,
    FuelCellParams,
    HydrogenParams,
)
from comems4build_ros.core.types import CLIP_FC_H2, CLIP_FC_RANGE

_NEWTON_MAX_ITER = 60
_NEWTON_TOL_W = 1e-9


def cell_voltage_v(i_a, fc: FuelCellParams):
    """Compute the cell voltage V_cell(i) of the polarization model (vectorised).

    Parameters
    ----------
    i_a : float or array_like
        Stack current [A] (>= 0).
    fc : FuelCellParams
        ``e_ocv_v`` [V], ``a_tafel_v`` [V], ``i_tafel_a`` [A], ``r_ohm_ohm`` [Ohm] (fitted to
        the Horizon H-2000 datasheet).

    Returns
    -------
    numpy.ndarray
        V_cell = E_ocv - A ln(1 + i / i_T) - R_ohm i [V].
    """
    return fc.cell_voltage_v(np.asarray(i_a, dtype=float))


def stack_power_w(i_a, fc: FuelCellParams):
    """Compute the stack's electrical output P = N_cells * V_cell(i) * i (vectorised).

    Parameters
    ----------
    i_a : float or array_like
        Stack current [A].
    fc : FuelCellParams
        Polarization parameters and ``n_cells``.

    Returns
    -------
    numpy.ndarray
        P_el,FC [W].
    """
    return fc.stack_power_w(np.asarray(i_a, dtype=float))


def _dpower_di(i, fc: FuelCellParams):
    """Return dP/di of the stack [W/A]."""
    return fc.dpower_di(i)


def max_power_point(fc: FuelCellParams) -> tuple[float, float]:
    """Find the maximum of P(i): :meth:`FuelCellParams.max_power_point` of ``fc``.

    Parameters
    ----------
    fc : FuelCellParams
        Polarization parameters and ``n_cells``.

    Returns
    -------
    tuple of float
        Current [A] and output [W] at the maximum (the end of the monotone branch).
    """
    return fc.max_power_point()


def current_for_power_a(p_el_w, fc: FuelCellParams):
    """Solve for the stack current that delivers ``p_el_w`` on the monotone branch (vectorised).

    Newton's method from i = 0: P(i) is increasing and concave on the branch, so the
    iterates approach the root from below and never overshoot.

    Parameters
    ----------
    p_el_w : float or array_like
        Electrical output [W] (0 .. the maximum power point).
    fc : FuelCellParams
        Polarization parameters and ``n_cells``.

    Returns
    -------
    numpy.ndarray
        Stack current [A].

    Raises
    ------
    ValueError
        If a request is negative, not finite or above the curve's maximum power.
    """
    p = np.asarray(p_el_w, dtype=float)
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError("fuel_cell: electrical power must be finite and >= 0 W")
    i_mpp, p_mpp = max_power_point(fc)
    if np.any(p > p_mpp):
        raise ValueError(f"fuel_cell: {float(np.max(p)):.1f} W exceeds the stack's maximum power {p_mpp:.1f} W")
    i = np.zeros_like(p)
    for _ in range(_NEWTON_MAX_ITER):
        f = stack_power_w(i, fc) - p
        if np.all(np.abs(f) < _NEWTON_TOL_W):
            break
        i = np.minimum(i - f / _dpower_di(i, fc), i_mpp)
    return i


def h2_molar_flow_mol_s(i_a, fc: FuelCellParams):
    """Compute the hydrogen consumption n_FC = N_cells * i / (2F), ``eq:molar_flows`` (Faraday's law).

    Parameters
    ----------
    i_a : float or array_like
        Stack current [A].
    fc : FuelCellParams
        ``n_cells``.

    Returns
    -------
    numpy.ndarray
        Molar H2 flow n_FC [mol/s].
    """
    return fc.n_cells * np.asarray(i_a, dtype=float) / (ELECTRONS_PER_H2 * FARADAY_C_PER_MOL)


def operating_point(p_el_w, fc: FuelCellParams):
    """Compute the hydrogen LHV power and electrical efficiency of an electrical output (vectorised).

    Parameters
    ----------
    p_el_w : float or array_like
        Electrical output P_el,FC [W] (0 = off).
    fc : FuelCellParams
        Polarization parameters and ``n_cells``.

    Returns
    -------
    p_h2_w : float or numpy.ndarray
        Hydrogen consumed as LHV power n_FC * LHV [W].
    eta_el : float or numpy.ndarray
        eta_el,FC [-] (``eq:efficiency_FC``; 0 where the cell is off).
    """
    p = np.asarray(p_el_w, dtype=float)
    i = current_for_power_a(p, fc)
    p_h2 = h2_molar_flow_mol_s(i, fc) * LHV_H2_J_PER_MOL
    with np.errstate(invalid="ignore", divide="ignore"):
        eta = np.where(p_h2 > 0.0, p / np.where(p_h2 > 0.0, p_h2, 1.0), 0.0)
    if p.ndim == 0:
        return float(p_h2), float(eta)
    return p_h2, eta


class FuelCellTable:
    """P_H2(P_el) on a uniform grid for fast scalar lookups in the plant step.

    Parameters
    ----------
    fc : FuelCellParams
        Polarization parameters, ``n_cells`` and ``p_max_w`` [W].
    n_points : int
        Grid points between 0 W and ``fc.p_max_w`` (the interpolation error of the
        default 4097 points is below 1e-6 relative over [P_min, P_max]).

    Raises
    ------
    ValueError
        If the polarization curve cannot deliver ``fc.p_max_w``.
    """

    def __init__(self, fc: FuelCellParams, n_points: int = 4097) -> None:
        _, p_mpp = max_power_point(fc)
        if p_mpp < fc.p_max_w:
            raise ValueError(
                f"fuel_cell: the polarization curve peaks at {p_mpp:.1f} W, below p_max_w = {fc.p_max_w} W; "
                "check e_ocv_v, a_tafel_v, i_tafel_a, r_ohm_ohm"
            )
        grid = np.linspace(0.0, fc.p_max_w, n_points)
        i = current_for_power_a(grid, fc)
        h2 = h2_molar_flow_mol_s(i, fc) * LHV_H2_J_PER_MOL
        self.p_top_w = float(fc.p_max_w)
        self.step_w = float(grid[1] - grid[0])
        self._inv_step = 1.0 / self.step_w
        self._n = n_points
        self._p: list[float] = grid.tolist()
        self._h2: list[float] = h2.tolist()

    def h2_power_w(self, p_el_w: float) -> float:
        """Look up the hydrogen LHV power of an output (linear interpolation, ``eq:molar_flows``).

        Parameters
        ----------
        p_el_w : float
            Electrical output, 0 <= p_el_w <= p_max_w [W].

        Returns
        -------
        float
            n_FC * LHV [W].
        """
        x = p_el_w * self._inv_step
        j = int(x)
        if j >= self._n - 1:
            return self._h2[-1]
        h = self._h2
        return h[j] + (x - j) * (h[j + 1] - h[j])

    def el_power_w(self, p_h2_w: float) -> float:
        """Look up the electrical output that consumes a hydrogen LHV power (inverse of :meth:`h2_power_w`).

        Parameters
        ----------
        p_h2_w : float
            Hydrogen LHV power [W].

        Returns
        -------
        float
            P_el,FC [W], at most ``p_max_w``.
        """
        h = self._h2
        if p_h2_w <= 0.0:
            return 0.0
        if p_h2_w >= h[-1]:
            return self._p[-1]
        j = bisect.bisect_right(h, p_h2_w) - 1
        frac = (p_h2_w - h[j]) / (h[j + 1] - h[j])
        return self._p[j] + frac * self.step_w


class FuelCell:
    """The fuel cell and the H2 store of the plant step (``eq:molar_flows`` .. ``eq:FC_sys_efficiency``, ``eq:LOH``).

    Parameters
    ----------
    fc : FuelCellParams
        Polarization parameters, ``p_min_w`` and ``p_max_w`` [W], ``zeta`` and ``eta_sys`` [-].
    h2 : HydrogenParams
        The store's LHV content ``e_max_kwh`` [kWh] and ``loh_min``, ``loh_max`` [-].

    Attributes
    ----------
    table : FuelCellTable
        P_H2(P_el) of the stack.
    p_min_w, p_top_w : float
        Operating range [P_min, zeta P_max] [W].
    eta_sys : float
        System efficiency eta_sys,FC [-] (``eq:FC_sys_efficiency``).
    e_h2_wh : float
        The store's LHV energy E_H2,max [Wh].
    loh_min, loh_max : float
        Bounds of the store's level [-].

    Raises
    ------
    ValueError
        If the polarization curve cannot deliver ``fc.p_max_w``.
    """

    __slots__ = ("table", "p_min_w", "p_top_w", "eta_sys", "e_h2_wh", "loh_min", "loh_max")

    def __init__(self, fc: FuelCellParams, h2: HydrogenParams) -> None:
        self.table = FuelCellTable(fc)
        self.p_min_w = float(fc.p_min_w)
        self.p_top_w = float(fc.zeta * fc.p_max_w)
        self.eta_sys = float(fc.eta_sys)
        self.e_h2_wh = h2.e_max_kwh * W_PER_KW
        self.loh_min = float(h2.loh_min)
        self.loh_max = float(h2.loh_max)

    def run(self, p_req_w: float, loh: float, dt_h: float) -> tuple[float, float, float, float, float, int]:
        """Run the fuel cell for one step of a requested output.

        The request goes onto {0} U [P_min, zeta P_max] (from half of P_min on it is raised
        to P_min, below it the cell stays off), then down to what the store holds above
        LOH_min (off if that is below P_min).

        Parameters
        ----------
        p_req_w : float
            Requested electrical output [W] (finite).
        loh : float
            LOH[k-1] [-].
        dt_h : float
            Step t_s [h].

        Returns
        -------
        p_el_w : float
            P_el,FC [W].
        p_h2_w : float
            Hydrogen drawn as LHV power n_FC * LHV [W].
        eta_el : float
            eta_el,FC [-] (``eq:efficiency_FC``), 0 when off.
        q_rec_w : float
            Recoverable heat Q_hr,FC = n_FC LHV (eta_sys - eta_el) [W] (``eq:FC_sys_efficiency``).
        loh : float
            LOH after the draw [-] (``eq:LOH``).
        clip : int
            ``CLIP_FC_RANGE`` and ``CLIP_FC_H2`` bits.
        """
        clip = 0
        p_min = self.p_min_w
        p_fc = p_req_w
        if p_fc <= 0.0:
            if p_fc < 0.0:
                clip = CLIP_FC_RANGE
            p_fc = 0.0
        elif p_fc < p_min:
            p_fc = p_min if p_fc >= 0.5 * p_min else 0.0
            clip = CLIP_FC_RANGE
        elif p_fc > self.p_top_w:
            p_fc = self.p_top_w
            clip = CLIP_FC_RANGE
        p_h2 = 0.0
        if p_fc > 0.0:
            table = self.table
            p_h2 = table.h2_power_w(p_fc)
            h2_avail = (loh - self.loh_min) * self.e_h2_wh / dt_h
            if p_h2 > h2_avail:
                clip |= CLIP_FC_H2
                p_fc = table.el_power_w(h2_avail)
                if p_fc < p_min:
                    p_fc = 0.0
                    p_h2 = 0.0
                else:
                    p_h2 = min(table.h2_power_w(p_fc), h2_avail)
        if p_fc > 0.0:
            eta_el = p_fc / p_h2
            q_rec = self.eta_sys * p_h2 - p_fc
            if q_rec < 0.0:
                q_rec = 0.0
        else:
            eta_el = 0.0
            q_rec = 0.0
        loh_new = loh - p_h2 * dt_h / self.e_h2_wh
        if loh_new < self.loh_min:
            loh_new = self.loh_min
        return p_fc, p_h2, eta_el, q_rec, loh_new, clip


def efficiency_summary(fc: FuelCellParams) -> dict[str, float]:
    """Summarise the electrical efficiency over the operating range (``eq:efficiency_FC``).

    Parameters
    ----------
    fc : FuelCellParams
        Polarization parameters and operating points.

    Returns
    -------
    dict of str to float
        eta_el [-] at P_min, P_nom, zeta * P_max and P_max, at the Horizon H-2000 datasheet
        point (70 A), and its mean over [P_min, zeta P_max].
    """
    points = {
        "p_min": fc.p_min_w,
        "p_nom": fc.p_nom_w,
        "zeta_p_max": fc.zeta * fc.p_max_w,
        "p_max": fc.p_max_w,
    }
    out = {f"eta_el_{k}": operating_point(v, fc)[1] for k, v in points.items()}
    i_ds = 70.0  # Horizon H-2000 datasheet point, 70 A
    out["eta_el_datasheet_70a"] = float(cell_voltage_v(i_ds, fc)) / V_LHV_V
    grid = np.linspace(fc.p_min_w, fc.zeta * fc.p_max_w, 201)
    out["eta_el_mean_operating_range"] = float(np.mean(operating_point(grid, fc)[1]))
    return out
