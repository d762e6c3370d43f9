"""Validation of ``ems/command`` messages: length, finiteness, circuit, token and device ranges.

The lock-step masters (plant_sim, mqtt_bridge) apply only commands that pass these checks;
a rejected command names the field it fails (docs/ros_nodes.md "Faults"). No rclpy here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.types import ACTION_FIELDS, HP_COOL, HP_DHW, HP_OFF, HP_SH, Action
from comems4build_ros.wire.contract import Layout
from comems4build_ros.wire.tokens import MAX_TOKEN

#: Relative tolerance on the command range checks [-]: a command up to 1 % beyond a
#: device limit is accepted and clipped by the plant exactly as in-process (solver and
#: rounding noise); anything further out is rejected as invalid.
COMMAND_RANGE_REL_TOL = 0.01
#: Absolute tolerance on the command power range checks [W].
COMMAND_RANGE_ABS_TOL_W = 1.0


class CommandError(ValueError):
    """An ``ems/command`` message is invalid; ``field`` names the offending element.

    Parameters
    ----------
    field : str
        Label of the offending element (``(length)`` for a wrong length).
    reason : str
        What is wrong with it.
    """

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"field '{field}': {reason}")
        self.field = field
        self.reason = reason



def command_bounds(params: PlantParams) -> dict[str, tuple[float, float]]:
    """Return the accepted range of each ``ems/command`` field (device limits plus tolerance).

    hp_mod [-] in [0, 1]; p_fc_w [W] in [0, P_FC,max]; p_bess_w [W] in [-P_d,max, P_ch,max];
    p_el_w [W] in [0, P_EL,max]; each widened by :data:`COMMAND_RANGE_REL_TOL` and
    :data:`COMMAND_RANGE_ABS_TOL_W`.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (device limits, ``tab:parameters_PV_batt_dhw_h2``).

    Returns
    -------
    dict of str to tuple of (float, float)
        Field -> (lowest, highest) accepted value, in the field's unit.
    """

    def widen(lo: float, hi: float, abs_tol: float) -> tuple[float, float]:
        """Widen ``[lo, hi]`` by the relative and the absolute tolerance."""
        span = max(abs(lo), abs(hi))
        tol = COMMAND_RANGE_REL_TOL * span + abs_tol
        return lo - tol, hi + tol

    return {
        "hp_mod": widen(0.0, 1.0, 0.0),
        "p_fc_w": widen(0.0, params.fuel_cell.p_max_w, COMMAND_RANGE_ABS_TOL_W),
        "p_bess_w": widen(-params.battery.p_d_max_w, params.battery.p_ch_max_w, COMMAND_RANGE_ABS_TOL_W),
        "p_el_w": widen(0.0, ElectrolyserTable(params.electrolyser).p_max_w, COMMAND_RANGE_ABS_TOL_W),
    }


VALID_HP_MODES = (HP_OFF, HP_SH, HP_DHW, HP_COOL)


def check_token(token: float) -> None:
    """Refuse a value that is not a run token (an integer in 1 .. 2^53-1).

    Parameters
    ----------
    token : float
        The command's token element.

    Raises
    ------
    CommandError
        Naming the field ``token``.
    """
    if not 0 < token < MAX_TOKEN or token != int(token):
        raise CommandError("token", f"not an integer in 1..2^53-1: {token}")


def command_to_action(
    data: Sequence[float], layout: Layout, bounds: dict[str, tuple[float, float]]
) -> tuple[int, Action]:
    """Validate one ``ems/command`` payload and return ``(step, Action)``.

    Parameters
    ----------
    data : sequence of float
        The payload: step, the :class:`Action` fields (units in their names), token.
    layout : Layout
        The contract layout of ``ems/command``.
    bounds : dict of str to tuple of (float, float)
        Accepted ranges (:func:`command_bounds`).

    Returns
    -------
    tuple of (int, Action)
        The step and the action.

    Raises
    ------
    CommandError
        For a wrong length, a non-finite value, a non-integral step, circuit or token, an
        unknown circuit, or a value outside :func:`command_bounds`; ``field`` names it.
    """
    if len(data) != layout.length:
        raise CommandError("(length)", f"{len(data)} elements, the contract layout has {layout.length}")
    for label, value in zip(layout.labels, data):
        if not math.isfinite(value):
            raise CommandError(label, f"non-finite value {value}")
    step_f = data[0]
    if step_f < 0 or step_f != int(step_f):
        raise CommandError("step", f"not a non-negative integer: {step_f}")
    check_token(data[layout.length - 1])
    values = dict(zip(ACTION_FIELDS, data[1:]))
    mode = values["hp_mode"]
    if mode not in VALID_HP_MODES:
        raise CommandError("hp_mode", f"{mode} is not one of {VALID_HP_MODES} (off, SH, DHW, cooling)")
    for name, (lo, hi) in bounds.items():
        v = values[name]
        if not lo <= v <= hi:
            raise CommandError(name, f"{v} outside the accepted range [{lo:g}, {hi:g}]")
    return int(step_f), Action(
        hp_mod=float(values["hp_mod"]),
        hp_mode=int(mode),
        p_fc_w=float(values["p_fc_w"]),
        p_bess_w=float(values["p_bess_w"]),
        p_el_w=float(values["p_el_w"]),
    )


