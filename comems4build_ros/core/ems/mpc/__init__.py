"""Model-predictive controllers (paper sec:MPC): the MILP (``mpc``) and its OSQP relaxation (``mpc-qp``)."""

from __future__ import annotations

from comems4build_ros.core.ems.mpc.controller import MPCController
from comems4build_ros.core.ems.mpc.qp import QPController

__all__ = ["MPCController", "QPController"]
