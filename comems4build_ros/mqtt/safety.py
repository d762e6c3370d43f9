"""Safety at the MQTT bridge: measurement watchdog, command clamping and rate limiting.

* :class:`MeasurementWatchdog` keeps the latest value of every measurement with its
  receive time and reports, for a step, every measurement that is missing, older than
  its ``max_age_s`` or outside its physical ``range`` (``config/mqtt.yaml``). The bridge
  then sends the safe fallback action (:func:`comems4build_ros.core.ems.fallback.safe_action`)
  instead of the EMS's command and publishes an alarm, in the same step.
* :class:`CommandLimiter` clamps every set-point to its device limits and to its ramp
  limit per step, and holds back set-point messages that come faster than
  ``min_interval_s`` (the latest wins); every change is counted.

No rclpy and no MQTT here: the bridge node feeds values and times in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import parse_decimal
from comems4build_ros.mqtt.topicmap import TopicMap


@dataclass(frozen=True)
class Problem:
    """One watchdog finding: ``kind`` is ``missing``, ``stale`` or ``out_of_range``."""

    measurement: str
    kind: str
    detail: str

    def __str__(self) -> str:
        return f"{self.measurement} {self.kind}: {self.detail}"


@dataclass
class Reading:
    """Latest value of a measurement [SI], its step tag and receive time [s, monotonic]."""

    value: float
    step: int | None
    t_recv: float


class MeasurementWatchdog:
    """Latest measurements and their checks (see the module docstring).

    Parameters
    ----------
    topic_map : the bridge's topic map (ranges, ``max_age_s``, required flags)
    """

    def __init__(self, topic_map: TopicMap) -> None:
        self.map = topic_map
        self.latest: dict[str, Reading] = {}

    def update(self, name: str, value: float, step: int | None, t_recv: float) -> None:
        """Store a decoded measurement (non-finite values are kept: the check flags them)."""
        self.latest[name] = Reading(value, step, t_recv)

    def complete_for(self, step: int) -> bool:
        """True when every mapped measurement carries the step tag ``step`` (lock-step clock)."""
        return all((r := self.latest.get(n)) is not None and r.step == step for n in self.map.measurements)

    def check(self, now: float, names: list[str] | None = None, check_age: bool = True) -> list[Problem]:
        """Problems of the measurements ``names`` (default: all mapped) at time ``now`` [s].

        A required measurement that never arrived is ``missing``; an optional one is only
        checked once it has arrived. ``check_age=False`` skips the age check (the
        lock-step clock, where simulated hours take milliseconds and the step tag proves
        freshness).
        """
        out: list[Problem] = []
        for name in names if names is not None else list(self.map.measurements):
            spec = self.map.measurements[name]
            r = self.latest.get(name)
            if r is None:
                if spec.required:
                    out.append(Problem(name, "missing", f"nothing received on '{spec.topic}'"))
                continue
            lo, hi = spec.range
            if not (math.isfinite(r.value) and lo <= r.value <= hi):
                out.append(Problem(name, "out_of_range", f"{r.value!r} outside [{lo:g}, {hi:g}] on '{spec.topic}'"))
            age = now - r.t_recv
            if check_age and age > self.map.max_age(name):
                out.append(Problem(name, "stale", f"last value {age:.1f} s old (limit {self.map.max_age(name):g} s) "
                                                  f"on '{spec.topic}'"))
        return out

    def value(self, name: str, default: float = math.nan) -> float:
        """Latest value of ``name`` [SI], ``default`` if none."""
        r = self.latest.get(name)
        return r.value if r is not None else default


@dataclass
class LimiterCounters:
    """Counts of the changes the limiter made (reported in the bridge's statistics)."""

    clamped: dict[str, int] = field(default_factory=dict)  # set-point -> commands clamped to device limits
    ramped: dict[str, int] = field(default_factory=dict)  # set-point -> commands cut by the ramp limit
    invalid_mode: int = 0  # unknown heat-pump mode replaced by off
    rate_limited: int = 0  # set-point messages held back by min_interval_s
    clamped_commands: int = 0  # commands with at least one field changed


class CommandLimiter:
    """Clamp to device limits, ramp limit, message rate limit (see the module docstring).

    Parameters
    ----------
    limits : device limits per set-point (``TopicMap.device_limits``) [SI]
    ramps : ramp limit per set-point and step [SI] (0 = none)
    min_interval_s : shortest wall time between two set-point messages [s] (0 = none)
    """

    def __init__(self, limits: dict[str, tuple[float, float]], ramps: dict[str, float], min_interval_s: float) -> None:
        self.device_limits = dict(limits)  # the devices' own (topic map or plant parameters)
        self.limits = dict(limits)  # in force: the device limits, narrowed by the user's settings
        self.ramps = ramps
        self.min_interval_s = min_interval_s
        self.counters = LimiterCounters()
        self._t_last_sent = -math.inf
        self._prev: Action | None = None

    @classmethod
    def from_map(cls, topic_map: TopicMap, params: object) -> CommandLimiter:
        """Limiter with the map's device limits (plant parameters where the map has none)."""
        ramps = {n: topic_map.setpoints[n].max_change_per_step for n in ("hp_mod", "p_fc_w", "p_bess_w")}
        return cls(topic_map.device_limits(params), ramps, topic_map.min_interval_s)  # type: ignore[arg-type]

    def set_power_limit(self, name: str, limit: float) -> tuple[float, float]:
        """The user's limit of set-point ``name`` (a magnitude, e.g. the battery power both ways
        [W]): the limits in force become the device limits within ``[-limit, limit]``; returns them."""
        lo, hi = self.device_limits[name]
        self.limits[name] = (max(lo, -limit), min(hi, limit))
        return self.limits[name]

    def limit(self, action: Action) -> tuple[Action, list[str]]:
        """The action within device and ramp limits, and one note per changed field.

        Non-finite values become 0 (device idle); an unknown heat-pump mode becomes off.
        The ramp limit applies against the previous limited action.
        """
        notes: list[str] = []
        mode = action.hp_mode
        if mode not in (HP_OFF, HP_SH, HP_DHW):
            notes.append(f"hp_mode {mode!r} unknown -> off")
            self.counters.invalid_mode += 1
            mode = HP_OFF
        values = {}
        for name in ("hp_mod", "p_fc_w", "p_bess_w"):
            v = float(getattr(action, name))
            lo, hi = self.limits[name]
            if not math.isfinite(v):
                notes.append(f"{name} {v!r} not finite -> 0")
                v = 0.0
            if not lo <= v <= hi:
                c = min(max(v, lo), hi)
                what = "device limits" if (lo, hi) == self.device_limits[name] else "the user's limits"
                notes.append(f"{name} {v:g} clamped to {c:g} ({what} [{lo:g}, {hi:g}])")
                self.counters.clamped[name] = self.counters.clamped.get(name, 0) + 1
                v = c
            ramp = self.ramps.get(name, 0.0)
            if ramp > 0 and self._prev is not None:
                prev = float(getattr(self._prev, name))
                if abs(v - prev) > ramp:
                    r = prev + math.copysign(ramp, v - prev)
                    notes.append(f"{name} {v:g} ramp-limited to {r:g} (max change {ramp:g} per step)")
                    self.counters.ramped[name] = self.counters.ramped.get(name, 0) + 1
                    v = r
            values[name] = v
        if notes:
            self.counters.clamped_commands += 1
        out = Action(hp_mod=values["hp_mod"], hp_mode=int(mode), p_fc_w=values["p_fc_w"], p_bess_w=values["p_bess_w"])
        self._prev = out
        return out, notes

    def may_send(self, now: float) -> bool:
        """True if a set-point message may go out at ``now`` [s]; else it is held and counted."""
        if now - self._t_last_sent >= self.min_interval_s:
            return True
        self.counters.rate_limited += 1
        return False

    def sent(self, now: float) -> None:
        """Note that set-points went out at ``now`` [s]."""
        self._t_last_sent = now


class SettingError(InputError):
    """A setting's payload that cannot be applied; the message names the topic and the range."""


def parse_setting(topic: str, payload: bytes, low: float, high: float) -> float:
    """The number of a Home Assistant ``number`` command (plain text, e.g. ``"500"`` or
    ``"500.0"``) within ``[low, high]``.

    Raises
    ------
    SettingError
        For a payload that is not UTF-8, not a plain decimal number (digits of other scripts,
        digit groups ``1_000``, control or Unicode space characters around it are refused;
        see :func:`~comems4build_ros.files.inputs.parse_decimal`), not finite or outside the range.
    """
    try:
        value = parse_decimal(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise SettingError(f"topic '{topic}': {payload[:40]!r} is not a number") from None
    if not math.isfinite(value) or not low <= value <= high:
        raise SettingError(f"topic '{topic}': {value:g} outside [{low:g}, {high:g}]")
    return value
