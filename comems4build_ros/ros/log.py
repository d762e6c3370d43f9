"""Logging of the package's nodes: every line through rclpy's logger, stamped with the simulated time.

Every message a node gives (start-up, events, errors, the ``cause:`` line naming why it
ends a run early, its clean-up) goes through an rclpy logger, so it obeys ``--ros-args
--log-level``, reaches ``/rosout`` while the node exists and is written to the log
files of ``ROS_LOG_DIR``. The one exception is the recorder's ``progress <recorded>
<total>`` lines on stdout, a machine protocol the launcher reads.

rclpy stamps a log record with the wall time (rcutils takes the system time; rclpy offers
no other stamp). With ``use_sim_time`` true and a ``/clock`` message received, a node's
:class:`SimTimeLogger` therefore starts every line with the simulated time,
``[sim 2022-11-30T23:00:00Z] ...``, so a log read next to a bag lines up with the run.

:class:`SimTimeLogger` is a subclass of rclpy's ``RcutilsLogger``: rclpy finds the caller of
a log call (for its ``once``/``throttle`` filters) by walking up the stack past its own
files, and keeps a list of them, ``rcutils_logger._internal_callers``, that third parties
may extend; this module adds itself to it so that the caller stays the node's code. No
other module reaches into rclpy's logging.
"""

from __future__ import annotations

import os
from datetime import UTC, datetime
from typing import Any

from rclpy.impl import rcutils_logger
from rclpy.impl.rcutils_logger import RcutilsLogger

rcutils_logger._internal_callers.append(os.path.realpath(__file__))  # see the module docstring

NS_PER_S = 1_000_000_000


def sim_stamp(t_ns: int) -> str:
    """``2022-11-30T23:00:00Z``: a simulated time [ns since the epoch] as ISO 8601 UTC."""
    return datetime.fromtimestamp(t_ns / NS_PER_S, tz=UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


class SimTimeLogger(RcutilsLogger):
    """The logger of a node: rclpy's, with the simulated time in front of each line while the
    node's clock follows ``/clock`` (``use_sim_time``) and has had a message from it.

    Parameters
    ----------
    name : the logger's name (the node's, e.g. ``house_0.plant_sim``)
    clock : the node's ROS clock (``Node.get_clock()``)
    """

    def __init__(self, name: str, clock: Any) -> None:
        super().__init__(name)
        self._clock = clock

    def log(self, message: Any, severity: Any, **kwargs: Any) -> bool:  # noqa: D102 (rclpy's)
        if self._clock.ros_time_is_active:
            t_ns = self._clock.now().nanoseconds
            if t_ns > 0:
                message = f"[sim {sim_stamp(t_ns)}] {message}"
        return super().log(message, severity, **kwargs)


def process_logger(label: str) -> Any:
    """rclpy's logger ``label`` for lines of a process without a node (a node that could not be
    created, a container process); dots separate namespace parts as in a node's logger name."""
    from rclpy.logging import get_logger

    return get_logger(label.strip("/").replace("/", ".") or "node")
