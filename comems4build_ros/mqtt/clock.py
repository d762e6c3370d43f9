"""Clock of a run: ``sim`` (lock-step, as fast as the loop goes), ``wall`` (one step per
hour of wall time, aligned to the hour) or ``wall:<factor>`` (accelerated wall time: one
step per ``3600 / factor`` s, e.g. ``wall:3600`` = one simulated hour per wall second).

In the wall modes step ``k`` starts at ``t0 + k * period`` where ``t0`` is a multiple of
the period in Unix time (so ``wall`` steps start on the full hour), and the EMS acts on
the latest measurements at that time instead of a step handshake.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

SECONDS_PER_STEP_HOUR = 3600.0


class ClockError(ValueError):
    """An invalid clock specification."""


@dataclass(frozen=True)
class Clock:
    """A parsed clock: ``mode`` is ``sim`` or ``wall``; ``factor`` speeds wall time up."""

    mode: str
    factor: float = 1.0
    step_h: float = 1.0

    @property
    def wall(self) -> bool:
        """True for the wall-clock modes."""
        return self.mode == "wall"

    @property
    def period_s(self) -> float:
        """Wall time of one step [s] (wall modes)."""
        return self.step_h * SECONDS_PER_STEP_HOUR / self.factor

    def first_boundary(self, now_unix_s: float, lead_s: float = 0.0) -> float:
        """First step boundary (multiple of the period in Unix time) at least ``lead_s`` after ``now``."""
        p = self.period_s
        return math.ceil((now_unix_s + lead_s) / p) * p

    def spec(self) -> str:
        """The text form (``sim``, ``wall``, ``wall:3600``)."""
        if not self.wall:
            return "sim"
        return "wall" if self.factor == 1.0 else f"wall:{self.factor:g}"


def parse_clock(text: str, step_h: float = 1.0) -> Clock:
    """``sim``, ``wall`` or ``wall:<factor>`` (factor > 0) -> :class:`Clock`.

    Raises
    ------
    ClockError
        Naming the text and the accepted forms.
    """
    t = text.strip().lower()
    if t == "sim":
        return Clock("sim", 1.0, step_h)
    if t == "wall":
        return Clock("wall", 1.0, step_h)
    if t.startswith("wall:"):
        try:
            factor = float(t[5:])
        except ValueError:
            factor = math.nan
        if math.isfinite(factor) and factor > 0:
            return Clock("wall", factor, step_h)
    raise ClockError(f"clock {text!r}: expected 'sim', 'wall' or 'wall:<factor>' with a factor > 0")
