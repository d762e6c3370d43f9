"""Arithmetic whose rounding does not depend on the CPU.

NumPy's ``@`` hands matrix-vector products to OpenBLAS, which picks its kernels by CPU; the
kernels sum in other orders and differ in the last bits, so a closed-loop run (whose MPC
and fuzzy decisions can flip on such bits) would give other results on another machine.
The core uses :func:`rowdot` instead wherever a result feeds a run.
"""

from __future__ import annotations

import numpy as np


def rowdot(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Each row of ``a`` times ``x``, summed over the last axis: ``a @ x`` without BLAS.

    ``a`` of shape (..., m) and ``x`` of shape (m,) (or broadcastable); NumPy's own pairwise
    sum is the same on every CPU.
    """
    return (a * x).sum(axis=-1)
