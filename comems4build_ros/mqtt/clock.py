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

from comems4build_ros.files.errors import InputError

SECONDS_PER_STEP_HOUR = 3600.0


class ClockError(InputError):
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
            return check_period(Clock("wall", factor, step_h), text)
    raise ClockError(f"clock {text!r}: expected 'sim', 'wall' or 'wall:<factor>' with a factor > 0")


#: Shortest wall time of a step [s]: the house's measurements, the EMS's decision (an MPC solve takes a
#: median 33 ms on a quiet machine, docs/mpc.md) and the set-points over MQTT must fit in one step.
MIN_PERIOD_S = 0.1
#: Longest wall time of a step [s]: a day. Slower than real time serves only watching a run (a year's
#: 8760 hourly steps would end 24 years later); real time (``wall``) is one hour per hourly step.
MAX_PERIOD_S = 86400.0


def check_period(clock: Clock, text: str) -> Clock:
    """``clock`` if the wall time of its step lies in :data:`MIN_PERIOD_S` .. :data:`MAX_PERIOD_S`.

    The factor's derived quantity is checked with the option: ``wall:1e308`` gives steps of
    1e-305 s, ``wall:5e-324`` steps longer than any calendar; both are refused naming the
    clock, the step's wall time and the factors allowed for the run's time step.

    Raises
    ------
    ClockError
        Naming the clock, the period and the allowed factors.
    """
    period = clock.period_s
    if MIN_PERIOD_S <= period <= MAX_PERIOD_S:
        return clock
    hour_s = clock.step_h * SECONDS_PER_STEP_HOUR
    raise ClockError(f"clock {text!r}: a step of {clock.step_h:g} h would take {period:.4g} s of wall time; allowed "
                     f"{MIN_PERIOD_S:g} s (the exchange of measurements, decision and set-points of one step) .. "
                     f"{MAX_PERIOD_S:g} s (a day), i.e. a factor in {hour_s / MAX_PERIOD_S:.3g} .. "
                     f"{hour_s / MIN_PERIOD_S:g}")
