"""Arithmetic whose rounding does not depend on the CPU.

NumPy's ``@`` hands matrix-vector products to OpenBLAS, which picks its kernels by CPU; the
kernels sum in other orders and differ in the last bits, so a closed-loop run (whose MPC
and fuzzy decisions can flip on such bits) would give other results on another machine.
The core uses :func:`rowdot` instead wherever a result feeds a run.
"""

from __future__ import annotations

import bisect

import numpy as np


def rowdot(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Each row of ``a`` times ``x``, summed over the last axis: ``a @ x`` without BLAS.

    NumPy's own pairwise sum is the same on every CPU.

    Parameters
    ----------
    a : numpy.ndarray
        Matrix (or stack of matrices) of shape (..., m), any unit.
    x : numpy.ndarray
        Vector of shape (m,) or broadcastable against ``a``, any unit.

    Returns
    -------
    numpy.ndarray
        ``sum_j a[..., j] * x[j]`` of shape (...,), in the unit of ``a`` times that of ``x``.
    """
    return (a * x).sum(axis=-1)


class PiecewiseLinear:
    """Scalar piecewise-linear interpolation over a table, held constant outside it.

    ``y = y_j + (x - x_j) * (y_{j+1} - y_j) / (x_{j+1} - x_j)`` on the interval holding ``x``.
    The plant step evaluates its device tables with it in plain float arithmetic (a scalar
    ``numpy.interp`` call costs about ten times as much); ``numpy.interp`` orders the same
    operations otherwise and can differ from it in the last bit.

    Parameters
    ----------
    xs : sequence of float
        Increasing abscissae (at least two), in the unit of the table's input.
    ys : sequence of float
        Ordinates, one per abscissa, in the unit of the table's output.
    """

    __slots__ = ("xs", "ys")

    def __init__(self, xs, ys) -> None:
        self.xs = [float(x) for x in xs]
        self.ys = [float(y) for y in ys]

    def __call__(self, x: float) -> float:
        """Interpolate the table at ``x`` (the end values outside the table).

        Parameters
        ----------
        x : float
            Abscissa, in the unit of ``xs``.

        Returns
        -------
        float
            Interpolated ordinate, in the unit of ``ys``.
        """
        xs = self.xs
        if x <= xs[0]:
            return self.ys[0]
        if x >= xs[-1]:
            return self.ys[-1]
        j = bisect.bisect_right(xs, x) - 1
        y0 = self.ys[j]
        return y0 + (x - xs[j]) * (self.ys[j + 1] - y0) / (xs[j + 1] - xs[j])
