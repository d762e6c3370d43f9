"""The rule-based coordinator (``--coordinator rule``): crisp rules, no forecast, no optimisation.

Electrolysis: the hub runs on the community's surplus as the houses offer it. Each house's
EMS decides, as in an isolated house with an electrolyser, how much of its surplus it would
put into electrolysis (its action's ``p_el_w``: ComEMS4Build's FLC_EL, the RBC's surplus
after the battery); the coordinator sets the hub to the sum of these offers, and the hub
keeps it within its limits (modules staged, minimal load, the store's room). The H2 a step
makes is credited to the houses in proportion to their offers: a house gets the H2 its
electricity made. With one house the hub runs exactly at that house's request, as the
house's own electrolyser would.

H2 shares (option ``h2_split``), at the first step of every day:

``equal``
    Every account stays its house's own; each house's daily permissible H2 is its own
    ``eq:deltaLOH`` (as an isolated house), and the pool (production an account could not
    take) is given to the accounts with room, in proportion to that room.
``need``
    The H2 the accounts and the pool hold above the accounts' floors is shared out again in
    proportion to each house's need, its grid purchase over the last ``need_days`` days (the
    deficit its fuel cell can cover), each account up to its size (the rest stays in the
    pool); the community's daily permissible H2, the sum of the houses' ``eq:deltaLOH``, is
    divided in the same proportion. Before a house has bought anything, the shares are equal.

The coordinator reads only the records of :mod:`.coordinator`: the accounts, the hub's
pool, the metered purchases and the offers.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Any, Literal

from pydantic import Field

from comems4build_ros.core.community.coordinator import (
    Allotment,
    CommunityInfo,
    CommunityView,
    Dispatch,
    Request,
)
from comems4build_ros.core.config import Section, parse_model


class RuleOptions(Section):
    """Options of the rule-based coordinator (``config/coordinators.yaml``, row ``rule``)."""

    h2_split: Literal["equal", "need"]
    need_days: int = Field(ge=1, le=366)


def offered(request: Request) -> float:
    """Return a house's offer as a finite power >= 0 [W] (anything else offers nothing)."""
    p = request.p_el_w
    return p if isinstance(p, int | float) and math.isfinite(p) and p > 0.0 else 0.0


def water_fill(total: float, weights: list[float], caps: list[float]) -> list[float]:
    """``total`` split in proportion to ``weights``, none above its cap, the capped remainder spread again.

    Returns the amounts (sum = min(total, sum of caps) up to rounding).
    """
    out = [0.0] * len(weights)
    open_ = [i for i, c in enumerate(caps) if c > 0.0]
    left = max(total, 0.0)
    while left > 0.0 and open_:
        w = sum(weights[i] for i in open_)
        if w <= 0.0:
            weights = [1.0] * len(weights)
            w = float(len(open_))
        full = [i for i in open_ if out[i] + left * weights[i] / w >= caps[i]]
        if not full:
            for i in open_:
                out[i] += left * weights[i] / w
            return out
        for i in full:
            left -= caps[i] - out[i]
            out[i] = caps[i]
        open_ = [i for i in open_ if i not in full]
    return out


class RuleCoordinator:
    """Electrolysis on the houses' offered surplus; H2 shares equal or by need (module docstring).

    Parameters
    ----------
    info : the community's fixed figures
    options : ``h2_split`` (``equal`` or ``need``), ``need_days``
    """

    name = "rule"

    def __init__(self, info: CommunityInfo, options: Mapping[str, Any] | None = None) -> None:
        self.info = info
        self.options = parse_model(RuleOptions, dict(options or {}), "coordinator 'rule' options")
        self.step_info: dict[str, float] = {}
        self.reset()

    def reset(self) -> None:
        """Forget the purchases seen."""
        window = self.options.need_days * self.info.steps_per_day
        self._bought: list[deque[float]] = [deque(maxlen=window) for _ in self.info.names]
        self._started = False
        self.step_info = {}

    # ---------------------------------------------------------------- allot
    def allot(self, view: CommunityView) -> Allotment:
        """Transfers at the first step of a day; every house's ``eq:deltaLOH`` (module docstring)."""
        houses = view.houses
        if self._started:
            for q, h in zip(self._bought, houses):
                q.append(h.p_buy_prev_w)
        self._started = True
        own = tuple(h.dloh_own_per_day for h in houses)
        transfers = [0.0] * len(houses)
        if self.options.h2_split == "equal":
            if view.new_day and view.hub.pool_wh > 0.0:
                rooms = [max(h.share_wh - h.account_wh, 0.0) for h in houses]
                transfers = water_fill(view.hub.pool_wh, rooms, rooms)
            return Allotment(own, tuple(transfers))
        weights = self._need_weights()
        if view.new_day:
            usable = view.hub.pool_wh + sum(max(h.account_wh - h.floor_wh, 0.0) for h in houses)
            caps = [max(h.share_wh - h.floor_wh, 0.0) for h in houses]
            targets = water_fill(usable, weights, caps)
            transfers = [h.floor_wh + t - h.account_wh for h, t in zip(houses, targets)]
        total = sum(h.dloh_own_per_day * h.share_wh for h in houses)
        w_sum = sum(weights)
        dloh = tuple(total * w / w_sum / h.share_wh for w, h in zip(weights, houses))
        self.step_info = {"need_weight_max": max(weights) / w_sum}
        return Allotment(dloh, tuple(transfers))

    def _need_weights(self) -> list[float]:
        """Every house's grid purchase over the window [Wh-proportional]; equal before any purchase."""
        need = [sum(q) for q in self._bought]
        if sum(need) <= 0.0:
            return [1.0] * len(need)
        return need

    # ------------------------------------------------------------- dispatch
    def dispatch(self, view: CommunityView, requests: tuple[Request, ...]) -> Dispatch:
        """Return the hub at the sum of the houses' offers; the production split in proportion to them."""
        offers = [offered(r) for r in requests]
        total = offers[0]
        for p in offers[1:]:
            total += p
        split = tuple(p / total for p in offers) if total > 0.0 else tuple(0.0 for _ in offers)
        self.step_info = {**self.step_info, "offers_w": total}
        return Dispatch(total, split)
