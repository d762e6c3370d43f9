"""A house's link to its community's coordinator, composed by ``plant_sim`` with ``hub:=true``.

In a community (docs/community.md "Over ROS") a house's H2 store is its account at the hub
the coordinator keeps. The house's lock-step master (``plant_sim``) then steps in lock-step
with the coordinator as well as with its EMS; per step ``k``:

1. the coordinator's ``hub/allotment`` of ``k`` (the house's account after the transfer at
   the start of the step, its allotted ``eq:deltaLOH``, the hub's electrolysers' state in
   ``k - 1``) comes before the plant announces ``k``: the announced ``state/loh`` is the
   account, ``state/el_on`` the hub's electrolysers;
2. after the plant stepped with the EMS's command (its electrolyser request goes to the
   hub, not to the house's plant) it sends ``hub/report`` (its account as its fuel cell left
   it, its flows, the EMS's request), again every ``republish_period_s`` until
3. the coordinator's ``hub/settlement`` of ``k`` gives the account at the end of the step
   (the hub's production credited); then the plant records the step and goes on.

:class:`HubLink` holds the link: its parameters (``hub_token_file``: the house's hub secret,
under which every ``hub/*`` message carries its authentication code, :func:`~comems4build_ros.wire.tokens.sign`;
``clock``: the coordinator's clock, whose step period widens the master's stall window), the
subscriptions (messages checked for length and code, kept by step), and the report.
"""

from __future__ import annotations

import dataclasses
from array import array
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from comems4build_ros.core.community.hubrun import HouseMeter
from comems4build_ros.ros.lockstep import LockStep
from comems4build_ros.ros.node import ArrayPublisher, ContractEndpoints
from comems4build_ros.ros.package_node import NodeParameters
from comems4build_ros.wire.tokens import authentic, read_token_file, secret_key, sign

#: The flows of ``hub/report`` after the account, in layout order (each a field of the house's ``Flows``).
REPORT_FLOWS = tuple(f.name for f in dataclasses.fields(HouseMeter))


@dataclass(frozen=True, slots=True)
class HubAllotment:
    """The coordinator's allotment of one step as the house reads it (``hub/allotment``).

    Attributes
    ----------
    loh : the account after the transfer at the start of the step, fraction of the house's share [-]
    dloh_per_day : the allotted daily permissible H2 ``eq:deltaLOH`` [1/day]
    el_on_prev : the hub's electrolysers produced in the step before
    transfer_wh : H2 moved into the account at the start of the step [Wh LHV]
    """

    loh: float
    dloh_per_day: float
    el_on_prev: bool
    transfer_wh: float


class HubLink:
    """The house's side of the link to the coordinator (module docstring).

    Parameters
    ----------
    parameters : the master's parameters (``hub_token_file`` and ``clock`` are declared here)
    endpoints : the master's contract endpoints
    loop : the master's lock-step (its fault events and counters; the clock's step period)
    on_message : called after a valid allotment or settlement came in
    """

    def __init__(self, parameters: NodeParameters, endpoints: ContractEndpoints, loop: LockStep,
                 on_message: Callable[[], None]) -> None:
        from comems4build_ros.mqtt.clock import parse_clock

        self.loop = loop
        token_file = parameters.param("hub_token_file", "")
        self._key = secret_key(read_token_file(token_file)) if token_file else None
        clock = parse_clock(parameters.param("clock", "sim"), loop.params.simulation.time_step_h)
        if clock.wall:  # the coordinator paces the steps: a wait of a step period is no stall
            loop.step_period_s = clock.period_s
        self._on_message = on_message
        contract = endpoints.contract
        self._lengths = {t: contract.topic(t).layout({}).length for t in ("hub/allotment", "hub/settlement")}
        self.allotments: dict[int, HubAllotment] = {}
        self.settlements: dict[int, float] = {}  # step -> the account at its end [-]
        self._report = ArrayPublisher(endpoints, "hub/report", {})
        self._last: array | None = None
        endpoints.subscription("hub/allotment", self._on_allotment)
        endpoints.subscription("hub/settlement", self._on_settlement)

    def _valid(self, topic: str, data: Any) -> int | None:
        """The step of a ``hub/*`` message from the coordinator, None (with an event) for a malformed or foreign one."""
        if len(data) != self._lengths[topic]:
            self.loop.event("rejected", f"topic '{topic}': {len(data)} elements, layout has {self._lengths[topic]}")
            return None
        if not authentic(self._key, data):
            self.loop.foreign_commands += 1
            self.loop.event("foreign", f"topic '{topic}': message for step {int(data[0])} ignored (not authenticated "
                                       "by the house's hub secret)")
            return None
        step = int(data[0])
        return step if step >= self.loop.k else None

    def _on_allotment(self, msg: Any) -> None:
        data = msg.data
        step = self._valid("hub/allotment", data)
        if step is None:
            return
        self.allotments[step] = HubAllotment(float(data[1]), float(data[2]), bool(data[3]), float(data[4]))
        self._on_message()

    def _on_settlement(self, msg: Any) -> None:
        data = msg.data
        step = self._valid("hub/settlement", data)
        if step is None:
            return
        self.settlements[step] = float(data[1])
        self._on_message()

    def report(self, k: int, loh: float, flows: Any, p_el_w: float) -> None:
        """Send the report of step ``k``: the account after the plant's step [-], its flows and the
        EMS's electrolyser request [W] (sent again by :meth:`resend` until the settlement comes)."""
        payload = array("d", (float(k), float(loh)))
        payload.extend(float(getattr(flows, f)) for f in REPORT_FLOWS)
        payload.append(float(p_el_w))
        self._last = sign(self._key, payload)
        self._report.publish(self._last)

    def resend(self) -> None:
        """The last report again (a report sent before the coordinator's reader matched is not delivered)."""
        if self._last is not None:
            self._report.publish(self._last)

    def forget(self, k: int) -> None:
        """Drop what is kept of step ``k`` (it is done)."""
        self.allotments.pop(k, None)
        self.settlements.pop(k, None)
