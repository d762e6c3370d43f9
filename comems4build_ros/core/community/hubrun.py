"""The hub's half of a community run: the coordinator's two calls and the hub's step, one step at a time.

A community step ``k`` has two halves. The houses' half is each house's EMS and plant: its
EMS acts on the house's observation and its plant steps, its fuel cell drawing from its H2
account. The hub's half is everything else, and :class:`HubRun` holds it:

1. :meth:`HubRun.allot`, before the houses act: the coordinator reads the hub and every
   house at the end of ``k - 1`` (:class:`~comems4build_ros.core.community.coordinator.CommunityView`)
   and allots; the hub applies the allotment's transfers to the accounts;
2. :meth:`HubRun.settle`, after the houses' plants stepped: the coordinator reads the
   houses' requests and decides the hub's dispatch; the hub steps (the fuel cells' draws,
   the standing loss, the electrolysers, the production credited to the accounts) and the
   connection point exchanges the net of the houses' meters and the hub
   (:func:`~comems4build_ros.core.community.plant.connection_exchange`); one row of the hub's
   timeseries is recorded.

The in-process loop (:func:`~comems4build_ros.core.community.loop.simulate_community`) calls
these between its houses' EMS and plants, the accounts being the houses' own states; the
coordinator node of a community over ROS 2 calls the same methods with the accounts and
flows the houses' ``plant_sim`` nodes report, so both runs do the same arithmetic in the same
order and their figures are the same, bit for bit.

A house that is absent in a step (``present`` false: a house that left a run on the wall
clock, docs/community.md "Over ROS") keeps its account frozen: no transfer, no fuel-cell
draw and no credit reach it (its production share goes to the pool); its flows count as
zero at the connection point and its request as no offer. The hub's balance stays closed.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import pandas as pd

from comems4build_ros.core.community.coordinator import (
    Allotment,
    CommunityInfo,
    CommunityView,
    Coordinator,
    Dispatch,
    HouseReport,
    HubReport,
    Request,
    make_coordinator,
)
from comems4build_ros.core.community.hub import Hub, HubFlows, HubState, community_hub
from comems4build_ros.core.community.plant import ConnectionFlows, connection_exchange
from comems4build_ros.core.community.spec import Community
from comems4build_ros.core.config import W_PER_KW
from comems4build_ros.core.ems.base import PRICE_WINDOW, Observation
from comems4build_ros.core.loop import HOURS_PER_DAY, dloh_per_day
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.scenario.comfort import heating_season_days

#: The hub's flows, state and balance per step.
HUB_COLUMNS = ("p_el_set_w", "p_el_w", "el_on", "el_start", "modules_on", "p_h2_el_w", "q_el_rec_w", "p_h2_fc_w",
               "p_h2_loss_w", "h2_credited_wh", "h2_to_pool_wh", "transfer_wh", "clipped", "loh", "store_kwh",
               "pool_kwh", "accounts_kwh", "h2_residual_wh")
#: The connection point's flows per step (prefixed ``cp_`` in the hub's timeseries).
CONNECTION_COLUMNS = ("p_buy_w", "p_sell_w", "balance_residual_w", "p_pv_w", "p_load_w", "p_hp_el_w", "p_ch_w",
                      "p_dis_w", "p_fc_w", "p_el_w")
#: The coordinator's record per step (more ``coord_*`` columns from its ``step_info``) and the
#: houses present in the step.
COORDINATOR_COLUMNS = ("coord_allot_s", "coord_dispatch_s", "coord_messages", "houses_present")
#: Every column of the hub's timeseries before the coordinator's own ``coord_*`` ones.
HUB_TIMESERIES_COLUMNS = ("time", "step", *HUB_COLUMNS, *(f"cp_{c}" for c in CONNECTION_COLUMNS),
                          *COORDINATOR_COLUMNS)


class HouseFlows(Protocol):
    """What the hub reads of a house's flows in one step (:class:`~comems4build_ros.core.types.Flows` has it) [W]."""

    p_h2_w: float
    p_buy_w: float
    p_sell_w: float
    p_pv_w: float
    p_load_w: float
    p_hp_el_w: float
    p_ch_w: float
    p_dis_w: float
    p_fc_w: float


class AccountLike(Protocol):
    """A house's H2 account as the hub keeps it: ``loh``, its level as a fraction of the house's share [-]."""

    loh: float


@dataclass(slots=True)
class Account:
    """A house's H2 account where no house state holds it (the coordinator node's copy).

    Attributes
    ----------
    loh : H2 in the account, fraction of the house's nominal share [-]
    """

    loh: float


@dataclass(frozen=True, slots=True)
class HouseMeter:
    """What the hub reads of a house's flows in one step, as a house's report carries them [W].

    The fields of :class:`HouseFlows`, in the order of ``hub/report``; all zero for an absent
    house (nothing metered, nothing drawn).
    """

    p_h2_w: float = 0.0
    p_buy_w: float = 0.0
    p_sell_w: float = 0.0
    p_pv_w: float = 0.0
    p_load_w: float = 0.0
    p_hp_el_w: float = 0.0
    p_ch_w: float = 0.0
    p_dis_w: float = 0.0
    p_fc_w: float = 0.0


#: An absent house's flows and request: nothing metered, no offer.
NO_FLOWS = HouseMeter()
NO_REQUEST = Request(0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Allotted:
    """The allotment of one step as the hub applied it.

    Attributes
    ----------
    dloh_per_day : each house's allotted daily permissible H2 ``eq:deltaLOH`` [1/day]
    moved_wh : H2 the hub moved into each account at the step's start [Wh LHV]
    clip : clip bits of the transfers (:data:`~comems4build_ros.core.community.hub.CLIP_TRANSFER`)
    el_on_prev : the hub's electrolysers produced in step ``k - 1`` (what each house's EMS reads)
    """

    dloh_per_day: tuple[float, ...]
    moved_wh: list[float]
    clip: int
    el_on_prev: bool


@dataclass(frozen=True, slots=True)
class Settled:
    """The hub's step after the houses' plants stepped.

    Attributes
    ----------
    credited_wh : production credited to each account [Wh LHV]
    split : the coordinator's production split [-]
    hub_flows : the hub's flows
    connection : the connection point's exchange
    """

    credited_wh: list[float]
    split: tuple[float, ...]
    hub_flows: HubFlows
    connection: ConnectionFlows


def community_info(community: Community, hub: Hub) -> CommunityInfo:
    """Return the fixed figures a coordinator is built with.

    Parameters
    ----------
    community : Community
        The built community.
    hub : Hub
        Its hub (:func:`~comems4build_ros.core.community.hub.community_hub`).

    Returns
    -------
    CommunityInfo
        The houses' names and shares [Wh], the step [h] and steps per day, the hub's store
        [Wh] and bounds [-], its electrolyser modules and their intake range [W], their rated
        efficiency [-] and every house's parameters as its EMS knows them.
    """
    bank = hub.bank
    spec = community.hub
    dt_h = spec.dt_h
    el = ElectrolyserTable(spec.electrolyser.model_copy(update={"n_modules": 1}))
    return CommunityInfo(tuple(h.name for h in community.houses), community.shares_wh, dt_h,
                         int(round(HOURS_PER_DAY / dt_h)), hub.e_wh, bank.n, bank.p_module_min_w,
                         bank.p_module_max_w, spec.loh_min, spec.loh_max, float(el.efficiency(1.0)),
                         tuple(h.plant_params for h in community.houses))


def public_series(community: Community) -> dict[str, list[float]]:
    """Return the community's public figures per step.

    Parameters
    ----------
    community : Community
        The built community.

    Returns
    -------
    dict[str, list[float]]
        ``buy``: the tariff's buy prices [EUR/kWh] padded by a day for the day-ahead window
        (as :class:`~comems4build_ros.core.loop.ObservationBuilder` pads them), ``sell``: its
        sell prices [EUR/kWh], ``to_season``: the days to the next heating season [d].
    """
    sc = community.scenario
    sim = community.houses[0].params.simulation
    buy = sc.price_buy_eur_per_kwh.tolist()
    to_season, _ = heating_season_days(sc.time, sim.heating_season_start, sim.heating_season_end)
    return {"buy": buy + [buy[-1]] * PRICE_WINDOW, "sell": sc.price_sell_eur_per_kwh.tolist(),
            "to_season": np.asarray(to_season, dtype=float).tolist()}


def initial_accounts(community: Community) -> list[Account]:
    """Every house's account at the start: its plant's ``simulation.loh_init``."""
    return [Account(float(h.plant_params.simulation.loh_init)) for h in community.houses]


@dataclass
class HubRun:
    """The hub's half of a community run (module docstring).

    Parameters
    ----------
    community : the built community
    coordinator : a coordinator's name (``config/coordinators.yaml``) or a coordinator object
    coordinator_options : options merged over the coordinator's row (name only)
    hub : the hub (default: :func:`~comems4build_ros.core.community.hub.community_hub`)
    """

    community: Community
    coordinator: str | Coordinator
    coordinator_options: Mapping[str, Any] | None = None
    hub: Hub | None = None
    coord: Coordinator = field(init=False)
    info: CommunityInfo = field(init=False)
    state: HubState = field(init=False)
    coordinator_s: float = field(init=False, default=0.0)

    def __post_init__(self) -> None:
        """Build the hub, the coordinator and the run's calendar."""
        community = self.community
        self.hub = self.hub or community_hub(community)
        self.info = community_info(community, self.hub)
        c = self.coordinator
        self.coord = make_coordinator(c, self.info, self.coordinator_options) if isinstance(c, str) else c
        self.coord.reset()
        #: ``hub`` (the reports only) or ``mpc`` (also every house's MPC-level observation).
        self.info_level = getattr(self.coord, "info_level", "hub")
        self._public = public_series(community)
        houses = community.houses
        self.n = len(houses)
        time = community.scenario.time[:community.scenario.n_steps]
        self.times = [t.isoformat() for t in time]
        self.day = ((time - time[0]).total_seconds() / 3600.0 // HOURS_PER_DAY).astype(int).tolist()
        self._own_dloh = [dloh_per_day(h.params) for h in houses]
        self._floors = [h.params.hydrogen.loh_min * h.share_wh for h in houses]
        self._prev: Sequence[HouseFlows] | None = None
        self._view: CommunityView | None = None
        self._allot: Allotment | None = None
        self._moved: tuple[list[float], int] = ([], 0)
        self._t_allot = 0.0
        self.rows: list[list[Any]] = []
        self.coord_infos: list[dict[str, float]] = []

    @property
    def n_steps(self) -> int:
        """Steps of the run."""
        return len(self.times)

    def start(self, accounts: Sequence[AccountLike]) -> None:
        """Start the hub: every account as given (the houses' initial LOH), nothing in the pool."""
        assert self.hub is not None
        self.state = self.hub.initial_state(accounts)

    def allot(self, k: int, accounts: Sequence[AccountLike], present: Sequence[bool] | None = None,
              observations: Sequence[Observation] = ()) -> Allotted:
        """Apply the coordinator's allotment of step ``k`` to ``accounts`` (changed in place).

        Parameters
        ----------
        k : int
            The step.
        accounts : Sequence[AccountLike]
            Every house's account at the end of ``k - 1``.
        present : Sequence[bool], optional
            The houses that take part in the step (default: all).
        observations : Sequence[Observation]
            Every house's observation at the MPC's level, in the houses' order, for a
            coordinator of information level ``mpc`` (which refuses a view without them);
            empty otherwise.

        Returns
        -------
        Allotted
            The allotment as the hub applied it.

        Raises
        ------
        ValueError
            For an allotment without one value per house.
        """
        assert self.hub is not None
        pub = self._public
        view = CommunityView(k, self.times[k], self.day[k], k == 0 or self.day[k] != self.day[k - 1],
                             self.info.steps_per_day, self._hub_report(), self._house_reports(accounts),
                             pub["buy"][k], tuple(pub["buy"][k:k + PRICE_WINDOW]), pub["sell"][k],
                             pub["to_season"][k], tuple(observations))
        t0 = _time.perf_counter()
        allot = self.coord.allot(view)
        self._t_allot = _time.perf_counter() - t0
        _check_lengths(self.coord, "allotment", self.n, dloh_per_day=allot.dloh_per_day,
                       transfers_wh=allot.transfers_wh)
        transfers = allot.transfers_wh
        if present is not None and not all(present):  # an absent house's account is frozen
            transfers = tuple(t if p else 0.0 for t, p in zip(transfers, present))
        self._moved = self.hub.transfer(accounts, self.state, transfers)
        self._view, self._allot = view, allot
        return Allotted(tuple(allot.dloh_per_day), self._moved[0], self._moved[1], self.state.el_on)

    def settle(self, k: int, accounts: Sequence[AccountLike], flows: Sequence[HouseFlows],
               requests: Sequence[Request], present: Sequence[bool] | None = None) -> Settled:
        """Run the coordinator's dispatch of step ``k`` and the hub's step (module docstring).

        Parameters
        ----------
        k : the step
        accounts : every account after the houses' fuel cells drew from it (credited in place)
        flows : every house's flows of the step (an absent house's are :data:`NO_FLOWS`)
        requests : every house's request (an absent house's is :data:`NO_REQUEST`)
        present : the houses that took part in the step (default: all)
        """
        assert self.hub is not None and self._view is not None
        t0 = _time.perf_counter()
        dispatch: Dispatch = self.coord.dispatch(self._view, tuple(requests))
        t_dispatch = _time.perf_counter() - t0
        self.coordinator_s += self._t_allot + t_dispatch
        _check_lengths(self.coord, "dispatch", self.n, production_split=dispatch.production_split)
        split = tuple(dispatch.production_split)
        applied = split
        if present is not None and not all(present):
            applied = tuple(s if p else 0.0 for s, p in zip(split, present))
        hub_new, hub_flows, credits = self.hub.step(accounts, self.state, dispatch.p_el_w, applied,
                                                    [f.p_h2_w for f in flows], self._moved)
        self.state = hub_new
        connection = connection_exchange(flows, hub_flows.p_el_w)
        self._prev = flows
        step_info = dict(getattr(self.coord, "step_info", None) or {})
        messages = step_info.pop("messages", 2 * self.n + 1)
        self.coord_infos.append(step_info)
        self.rows.append([self.times[k], k, *self._hub_values(hub_flows, accounts),
                          *(getattr(connection, name) for name in CONNECTION_COLUMNS), self._t_allot, t_dispatch,
                          messages, self.n if present is None else sum(bool(p) for p in present)])
        return Settled(credits, split, hub_flows, connection)

    def timeseries(self) -> pd.DataFrame:
        """Return the hub's, the connection point's and the coordinator's timeseries of the steps settled so far."""
        hub_ts = pd.DataFrame(self.rows, columns=list(HUB_TIMESERIES_COLUMNS))
        if self.coord_infos and any(self.coord_infos):
            hub_ts = pd.concat([hub_ts, pd.DataFrame(self.coord_infos).add_prefix("coord_")], axis=1)
        return hub_ts

    # ------------------------------------------------------------------ records
    def _hub_report(self) -> HubReport:
        assert self.hub is not None
        bank, s = self.hub.bank, self.state
        return HubReport(self.hub.e_wh, self.hub.store_wh(s), s.pool_wh, s.el_on, s.modules_on, bank.n,
                         bank.p_module_min_w, bank.p_module_max_w)

    def _house_reports(self, accounts: Sequence[AccountLike]) -> tuple[HouseReport, ...]:
        out = []
        prev = self._prev
        for i, (h, a) in enumerate(zip(self.community.houses, accounts)):
            f = prev[i] if prev is not None else None
            out.append(HouseReport(h.name, h.share_wh, a.loh * h.share_wh, self._floors[i], self._own_dloh[i],
                                   f.p_buy_w if f else 0.0, f.p_sell_w if f else 0.0, f.p_h2_w if f else 0.0))
        return tuple(out)

    def _hub_values(self, f: HubFlows, accounts: Sequence[AccountLike]) -> list[Any]:
        assert self.hub is not None
        hub, state = self.hub, self.state
        total = math.fsum(hub.accounts_wh(accounts))
        return [f.p_el_set_w, f.p_el_w, f.el_on, f.el_start, f.modules_on, f.p_h2_el_w, f.q_el_rec_w, f.p_h2_fc_w,
                f.p_h2_loss_w, f.h2_credited_wh, f.h2_to_pool_wh, f.transfer_wh, f.clipped, state.loh,
                hub.store_wh(state) / W_PER_KW, state.pool_wh / W_PER_KW, total / W_PER_KW,
                hub.balance_residual_wh(accounts, state)]


def _check_lengths(coord: Coordinator, what: str, n: int, **values: Sequence[float]) -> None:
    for name, v in values.items():
        if len(v) != n:
            raise ValueError(f"coordinator '{coord.name}': {what}.{name} has {len(v)} values for {n} houses")
