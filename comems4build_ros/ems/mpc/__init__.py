"""Model-predictive controllers (paper sec:MPC): the MILP (``mpc``) and its OSQP relaxation (``mpc-qp``)."""

from __future__ import annotations

from .controller import MPCController
from .qp import QPController

__all__ = ["MPCController", "QPController"]
