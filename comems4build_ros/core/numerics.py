"""Arithmetic whose rounding does not depend on the CPU.

NumPy's ``@`` hands matrix-vector products to OpenBLAS, which picks its kernels by CPU; the
kernels sum in other orders and differ in the last bits, so a closed-loop run (whose MPC
and fuzzy decisions can flip on such bits) would give other results on another machine.
The core uses :func:`rowdot` instead wherever a result feeds a run.
"""

from __future__ import annotations

from bisect import bisect_right

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
    """Scalar piecewise-linear interpolation of one or two ordinate rows over a table, held constant outside it.

    ``y = y_j + (x - x_j) * (y_{j+1} - y_j) / (x_{j+1} - x_j)`` on the interval holding ``x``.
    The plant step evaluates its device tables with it in plain float arithmetic (a scalar
    ``numpy.interp`` call costs about ten times as much); ``numpy.interp`` orders the same
    operations otherwise and can differ from it in the last bit. The differences
    ``y_{j+1} - y_j`` and ``x_{j+1} - x_j`` are computed once, with the same rounding; rows
    over the same abscissae share the search for the interval (:meth:`at2`).

    Parameters
    ----------
    xs : sequence of float
        Increasing abscissae (at least two), in the unit of the table's input.
    ys : sequence of float
        Ordinates, one per abscissa, in the unit of the table's output.
    *more : sequence of float
        A second ordinate row over the same abscissae (then evaluate with :meth:`at2`).
    """

    __slots__ = ("xs", "ys", "_inner", "_segments", "_x_first", "_x_last", "_first", "_last")

    def __init__(self, xs, ys, *more) -> None:
        self.xs = [float(x) for x in xs]
        self.ys = [float(y) for y in ys]
        xs = self.xs
        rows = [self.ys] + [[float(y) for y in row] for row in more]
        if len(rows) > 2:
            raise ValueError("PiecewiseLinear: one or two ordinate rows")
        self._x_first, self._x_last = xs[0], xs[-1]
        self._first = tuple(row[0] for row in rows) if more else rows[0][0]
        self._last = tuple(row[-1] for row in rows) if more else rows[0][-1]
        #: the inner abscissae: the number of them at or below x is the index of x's interval
        self._inner = xs[1:-1]
        #: per interval: x_j, x_{j+1} - x_j, then y_j and y_{j+1} - y_j of each row
        self._segments = [
            (xs[j], xs[j + 1] - xs[j], *(v for row in rows for v in (row[j], row[j + 1] - row[j])))
            for j in range(len(xs) - 1)
        ]

    def at(self, x: float) -> float:
        """Interpolate a table of one row at ``x`` (its first or last ordinate outside the table).

        Parameters
        ----------
        x : float
            Abscissa, in the unit of ``xs``.

        Returns
        -------
        float
            Interpolated ordinate, in the unit of ``ys``.
        """
        if x <= self._x_first:
            return self._first
        if x >= self._x_last:
            return self._last
        x_j, dx, y_j, dy = self._segments[bisect_right(self._inner, x)]
        return y_j + (x - x_j) * dy / dx

    def at2(self, x: float) -> tuple[float, float]:
        """Interpolate a table of two rows at ``x`` (one interval search for both).

        Parameters
        ----------
        x : float
            Abscissa, in the unit of ``xs``.

        Returns
        -------
        tuple of float
            The interpolated ordinates of both rows, in their units.
        """
        if x <= self._x_first:
            return self._first
        if x >= self._x_last:
            return self._last
        x_j, dx, y_j, dy, z_j, dz = self._segments[bisect_right(self._inner, x)]
        t = x - x_j
        return y_j + t * dy / dx, z_j + t * dz / dx
