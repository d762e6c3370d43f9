"""The hub: the shared electrolyser modules and H2 store, with one H2 account per house.

The store's physics are those of the house's store (``eq:LOH`` in LHV terms): its level
``LOH = content / E_max``, lowered by the hydrogen the houses' fuel cells draw through the
pipeline and raised by the electrolysers' production, in the same expressions and order
as the house plant's (:class:`~comems4build_ros.core.models.fuel_cell.FuelCell`, then
:class:`~comems4build_ros.core.models.electrolyser.ElectrolyserTable`). The electrolyser
modules are those of :mod:`~comems4build_ros.core.models.electrolyser`, staged
(:class:`ElectrolyserBank`): a set-point runs as many modules as it needs, each at one load.

Ownership: every house owns an account, the H2 its plant and EMS see as their store
(``PlantState.loh`` of the house = account / its nominal share); the H2 in the store that
is in no account is the pool. Per step ``k``:

1. at its start, the coordinator's transfers move H2 between the pool and the accounts
   (:meth:`Hub.transfer`);
2. the houses' plants step: each fuel cell draws from its own account;
3. :meth:`Hub.step`: the store loses the fuel cells' draws, the standing loss (charged to
   the accounts and the pool above their floors), and gains the electrolysers' production
   (within the store's room); the production is credited to the accounts by the
   coordinator's split, what an account cannot take and the unsplit rest go to the pool.

H2 is conserved in every step: store change = production - fuel cells' use - standing loss,
and store = sum of the accounts + pool (:meth:`Hub.balance_residual_wh`, reported per step).
Pipeline: the houses' fuel cells draw at low pressure through a short pipeline from a store
at 300 bar (``electrolyser.p_store_bar``); a pressure reduction needs no electricity, and
hydrogen lost from a tight steel pipeline and steel bottles is small against the throughput,
so the loss is a parameter (``hub.standing_loss_per_h``) that is 0 by default.

The electrolysers' recoverable waste heat (``electrolyser.heat_recovery``) is reported
(``q_el_rec_w``) but reaches no house's tank: the hub stands apart from the houses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from comems4build_ros.core.community.spec import Community, HubParams
from comems4build_ros.core.config import ElectrolyserParams
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.types import PlantState

#: A transfer or credit beyond an account's room or the pool by less than this is rounding
#: (the account is clamped at its bound as the house's store is) [Wh LHV].
ROOM_TOL_WH = 1e-6
#: Clip bit of :attr:`HubFlows.clipped`: a coordinator's transfer was cut to what the pool or
#: an account held (bits of the electrolyser as in :mod:`~comems4build_ros.core.types`).
CLIP_TRANSFER = 1024


class ElectrolyserBank:
    """``n_modules`` electrolyser modules of one curve, staged: as many run as a set-point needs.

    A set-point ``P`` runs ``m = ceil(P / P_max,1)`` modules (at most ``n``), one fewer when
    ``m`` modules at their minimal load would draw more than ``P`` (the bank stays within the
    surplus it is given); they share ``P`` at one load. Modules that produced in the step
    before run warm; modules started in this step lose ``start_lost_h`` of production as a
    single module does; idle modules draw their standby power. With one module the bank is
    exactly :class:`~comems4build_ros.core.models.electrolyser.ElectrolyserTable`.

    Parameters
    ----------
    el : the module's parameters with the number installed (``n_modules``)
    """

    def __init__(self, el: ElectrolyserParams) -> None:
        self.n = int(el.n_modules)
        self._tables = [ElectrolyserTable(el.model_copy(update={"n_modules": m})) for m in range(self.n + 1)]
        one = self._tables[1] if self.n else ElectrolyserTable(el.model_copy(update={"n_modules": 1}))
        self.p_module_min_w = one.p_min_w
        self.p_module_max_w = one.p_max_w
        self.p_standby_module_w = float(el.p_standby_w)

    @property
    def p_max_w(self) -> float:
        """Intake of every module at full load [W]."""
        return self.n * self.p_module_max_w

    def modules_for(self, p_w: float) -> int:
        """Modules a set-point ``p_w`` [W] runs (0 for none)."""
        if self.n == 0 or not p_w > 0.0:
            return 0
        m = min(self.n, max(1, math.ceil(p_w / self.p_module_max_w)))
        if m > 1 and p_w < m * self.p_module_min_w:
            m -= 1
        return m

    def run(self, p_req_w: float, loh: float, warm: int, dt_h: float, loh_max: float,
            e_h2_wh: float) -> tuple[float, float, int, float, float, int, bool]:
        """One step of the bank for a set-point.

        Parameters
        ----------
        p_req_w : set-point [W] (finite)
        loh : store level after the fuel cells' draw and the losses of this step [-]
        warm : modules that produced in the step before
        dt_h : step [h]
        loh_max : upper bound of the store [-]
        e_h2_wh : the store's size [Wh LHV]

        Returns
        -------
        (intake [W] incl. standby and compression, H2 made [W LHV], modules producing,
         recoverable heat [W], LOH after the step [-], clip bits, a module started)
        """
        m = self.modules_for(p_req_w)
        if m == 0:
            p, h2, on, q, loh, clip = self._tables[self.n].run(p_req_w, loh, False, dt_h, loh_max, e_h2_wh)
            return p, h2, 0, q, loh, clip, False
        warm_m = min(m, warm)
        groups = [(warm_m, True), (m - warm_m, False)]
        p_el = h2 = q = 0.0
        on_m, clip, started = 0, 0, False
        for count, was_on in groups:
            if count == 0:
                continue
            share = p_req_w if count == m else p_req_w * count / m
            p, h, on, qq, loh, c = self._tables[count].run(share, loh, was_on, dt_h, loh_max, e_h2_wh)
            p_el, h2, q, clip = p_el + p, h2 + h, q + qq, clip | c
            if on:
                on_m += count
                started = started or not was_on
        p_el += (self.n - m) * self.p_standby_module_w
        return p_el, h2, on_m, q, loh, clip, started


@dataclass(slots=True)
class HubState:
    """The hub at the end of a step.

    Attributes
    ----------
    loh : the store's level, fraction of ``e_max_wh`` [-]
    pool_wh : H2 in the store that is in no account [Wh LHV]
    modules_on : electrolyser modules that produced in the step
    """

    loh: float
    pool_wh: float
    modules_on: int = 0

    @property
    def el_on(self) -> bool:
        """The electrolyser produced in the step."""
        return self.modules_on > 0


@dataclass(slots=True)
class HubFlows:
    """Everything that flowed at the hub in one step (mean powers [W], energies [Wh]).

    Attributes
    ----------
    p_el_set_w : the coordinator's set-point [W]
    p_el_w : the electrolysers' intake, standby and compression included [W]
    el_on, el_start : a module produced; a module started
    modules_on : modules producing
    p_h2_el_w : H2 produced [W LHV]
    q_el_rec_w : recoverable electrolyser heat (not used by any house) [W]
    p_h2_fc_w : H2 drawn by the houses' fuel cells [W LHV]
    p_h2_loss_w : standing loss [W LHV]
    h2_credited_wh : production credited to the accounts [Wh LHV]
    h2_to_pool_wh : production that went to the pool [Wh LHV]
    transfer_wh : H2 moved from the pool into the accounts at the step's start (net) [Wh LHV]
    clipped : clip bits (the electrolyser's, :data:`CLIP_TRANSFER`)
    """

    p_el_set_w: float
    p_el_w: float
    el_on: bool
    el_start: bool
    modules_on: int
    p_h2_el_w: float
    q_el_rec_w: float
    p_h2_fc_w: float
    p_h2_loss_w: float
    h2_credited_wh: float
    h2_to_pool_wh: float
    transfer_wh: float
    clipped: int


class Hub:
    """The shared store and electrolysers with the houses' accounts.

    Parameters
    ----------
    params : the hub's figures
    shares_wh : every house's nominal share (its account's size) [Wh LHV]
    loh_min, loh_max : every house's store bounds [-] (its account's floor and top, as fractions)
    """

    def __init__(self, params: HubParams, shares_wh: Sequence[float], loh_min: Sequence[float],
                 loh_max: Sequence[float]) -> None:
        self.params = params
        self.e_wh = float(params.e_max_wh)
        self.loh_min = float(params.loh_min)
        self.loh_max = float(params.loh_max)
        self.dt_h = float(params.dt_h)
        self.bank = ElectrolyserBank(params.electrolyser)
        self.shares_wh = [float(s) for s in shares_wh]
        self.account_min = [float(x) for x in loh_min]
        self.account_max = [float(x) for x in loh_max]
        self._weights = [s / self.e_wh for s in self.shares_wh]

    # ------------------------------------------------------------------ state
    def initial_state(self, houses: Sequence[PlantState]) -> HubState:
        """Return the hub at the start: every account as its house's initial LOH, nothing in the pool."""
        loh = 0.0
        for w, s in zip(self._weights, houses):
            loh += s.loh * w
        return HubState(loh=loh, pool_wh=0.0, modules_on=0)

    def accounts_wh(self, houses: Sequence[PlantState]) -> list[float]:
        """H2 in every account [Wh LHV]."""
        return [s.loh * share for s, share in zip(houses, self.shares_wh)]

    def store_wh(self, hub: HubState) -> float:
        """H2 in the store [Wh LHV]."""
        return hub.loh * self.e_wh

    def balance_residual_wh(self, houses: Sequence[PlantState], hub: HubState) -> float:
        """Store minus the accounts and the pool [Wh LHV] (0 up to rounding: H2 is conserved)."""
        return self.store_wh(hub) - (math.fsum(self.accounts_wh(houses)) + hub.pool_wh)

    # --------------------------------------------------------------- transfers
    def transfer(self, houses: Sequence[PlantState], hub: HubState,
                 transfers_wh: Sequence[float]) -> tuple[list[float], int]:
        """Move H2 between the pool and the accounts at the start of a step (in place).

        Moves back to the pool (negative) go first, limited to what an account holds above
        its floor; then moves into the accounts in order, limited to the pool and to each
        account's room. A cut move sets :data:`CLIP_TRANSFER`.

        Returns
        -------
        (H2 moved into each account [Wh LHV], clip bits)

        Raises
        ------
        ValueError
            For a transfer that is not a finite number, or one per house not given.
        """
        if len(transfers_wh) != len(houses):
            raise ValueError(f"hub: {len(transfers_wh)} transfers for {len(houses)} houses")
        clip = 0
        moved = [0.0] * len(houses)
        order = sorted(range(len(houses)), key=lambda i: transfers_wh[i] >= 0.0)
        for i in order:
            t = float(transfers_wh[i])
            if not math.isfinite(t):
                raise ValueError(f"hub: transfer to house {i} is not finite: {transfers_wh[i]!r}")
            if t == 0.0:
                continue
            s, share = houses[i], self.shares_wh[i]
            held = (s.loh - self.account_min[i]) * share
            room = (self.account_max[i] - s.loh) * share
            if t < 0.0:
                cut = max(t, -max(held, 0.0))
            else:
                cut = min(t, max(room, 0.0), max(hub.pool_wh, 0.0))
            if abs(cut - t) > ROOM_TOL_WH:
                clip |= CLIP_TRANSFER
            if cut == 0.0:
                continue
            s.loh = min(max(s.loh + cut / share, self.account_min[i]), self.account_max[i])
            hub.pool_wh -= cut
            if hub.pool_wh < 0.0:
                hub.pool_wh = 0.0
            moved[i] = cut
        return moved, clip

    # -------------------------------------------------------------------- step
    def step(self, houses: Sequence[PlantState], hub: HubState, p_set_w: float, split: Sequence[float],
             p_h2_fc_w: Sequence[float], transfer: tuple[Sequence[float], int] = ((), 0),
             ) -> tuple[HubState, HubFlows, list[float]]:
        """Return the hub's step after the houses' plants stepped (the accounts hold their FC draws).

        Parameters
        ----------
        houses : every house's state at the end of the step (its account credited in place)
        hub : the hub at the end of the step before
        p_set_w : the electrolysers' set-point [W] (not finite: 0)
        split : share of the production credited to each account [-]
        p_h2_fc_w : every house's FC hydrogen draw [W LHV]
        transfer : what :meth:`transfer` moved at the step's start and its clip bits

        Returns
        -------
        (HubState, HubFlows, the production credited to each account [Wh LHV])
        """
        dt_h, e_wh = self.dt_h, self.e_wh
        p_fc = 0.0
        for x in p_h2_fc_w:
            p_fc += x
        loh = hub.loh - p_fc * dt_h / e_wh
        if loh < self.loh_min:
            loh = self.loh_min
        pool = hub.pool_wh
        loss_wh = 0.0
        rate = self.params.standing_loss_per_h
        if rate > 0.0:
            loss_wh, pool = self._standing_loss(houses, pool, rate * dt_h)
            loh -= loss_wh / e_wh
            if loh < self.loh_min:
                loh = self.loh_min
        p_set = float(p_set_w) if math.isfinite(float(p_set_w)) else 0.0
        p_el, h2, modules, q_rec, loh, clip, started = self.bank.run(p_set, loh, hub.modules_on, dt_h, self.loh_max,
                                                                    e_wh)
        credits = [0.0] * len(houses)
        h2_wh = h2 * dt_h
        if h2_wh > 0.0:
            credits = self._credit(houses, h2_wh, split)
        credited = math.fsum(credits)
        pool += h2_wh - credited
        if pool < 0.0:  # the shares of a production summed a rounding above it
            pool = 0.0
        new = HubState(loh=loh, pool_wh=pool, modules_on=modules)
        flows = HubFlows(p_set, p_el, modules > 0, started, modules, h2, q_rec, p_fc, loss_wh / dt_h, credited,
                         h2_wh - credited, math.fsum(transfer[0]), clip | transfer[1])
        return new, flows, credits

    def _credit(self, houses: Sequence[PlantState], h2_wh: float, split: Sequence[float]) -> list[float]:
        """Credit ``h2_wh`` to the accounts by ``split`` (each within its room); the H2 credited to each [Wh LHV]."""
        if len(split) != len(houses):
            raise ValueError(f"hub: a production split of {len(split)} shares for {len(houses)} houses")
        credited = [0.0] * len(houses)
        for i, f in enumerate(split):
            f = float(f)
            if not (math.isfinite(f) and f > 0.0):
                continue
            s, share = houses[i], self.shares_wh[i]
            part = h2_wh * f
            room = (self.account_max[i] - s.loh) * share
            if part > room + ROOM_TOL_WH:
                part = max(room, 0.0)
            s.loh = s.loh + part / share
            if s.loh > self.account_max[i]:
                s.loh = self.account_max[i]
            credited[i] = part
        return credited

    def _standing_loss(self, houses: Sequence[PlantState], pool: float, fraction: float) -> tuple[float, float]:
        """Take ``fraction`` of what every account holds above its floor and of the pool; (loss [Wh], pool [Wh])."""
        loss = 0.0
        for i, s in enumerate(houses):
            share = self.shares_wh[i]
            held = (s.loh - self.account_min[i]) * share
            if held > 0.0:
                take = held * fraction
                s.loh = max(s.loh - take / share, self.account_min[i])
                loss += take
        take = max(pool, 0.0) * fraction
        return loss + take, pool - take


def community_hub(community: Community) -> Hub:
    """Return the hub of a built community: its store and electrolysers, one account per house (share, bounds)."""
    return Hub(community.hub, community.shares_wh, [h.params.hydrogen.loh_min for h in community.houses],
               [h.params.hydrogen.loh_max for h in community.houses])
