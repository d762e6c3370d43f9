"""The community plant: every house's unchanged plant and the hub in one step.

One step ``k`` (:meth:`CommunityPlant.step`), after the coordinator's transfers
(:meth:`CommunityPlant.begin_step`) and the houses' actions:

1. every house's :class:`~comems4build_ros.core.plant.Plant` steps with its EMS's action,
   its electrolyser request removed (the house has no electrolyser; the request went to
   the coordinator as the surplus it offers): its fuel cell draws from its H2 account, its
   balance ``eq:power_balance`` gives its exchange at its own meter;
2. the hub steps (:class:`~comems4build_ros.core.community.hub.Hub`): the fuel cells' draws,
   the standing loss, the electrolysers at the coordinator's set-point, the production
   credited to the accounts;
3. the connection point: ``eq:power_balance`` of the whole community, the houses' PV, fuel
   cells and battery discharge against their appliances, heat pumps, battery charging and the
   hub's electrolysers (:func:`~comems4build_ros.core.models.grid.exchange` of the sums).

Where the electrolysers' electricity enters the balance: at the connection point, beside
the houses. The hub is a member of the community behind its own meter, as a house is; what
the houses' meters export covers it first (energy shared inside the community,
:mod:`.sharing`), the grid the rest. Physically the connection point's exchange is the net of
the members' exchanges; how the shared energy is priced is a rule set of :mod:`.sharing`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from comems4build_ros.core.community.hub import HubFlows, HubState, community_hub
from comems4build_ros.core.community.spec import Community
from comems4build_ros.core.models import grid
from comems4build_ros.core.plant import Plant
from comems4build_ros.core.types import Action, Exogenous, Flows, PlantState


@dataclass(slots=True)
class ConnectionFlows:
    """The community's exchange at its connection point in one step (mean powers [W]).

    ``p_pv_w + p_buy_w + p_fc_w + p_dis_w = p_sell_w + p_load_w + p_hp_el_w + p_ch_w + p_el_w``
    summed over the houses (and the hub's electrolysers, ``p_el_w``); ``balance_residual_w``
    is left side minus right side.
    """

    p_buy_w: float
    p_sell_w: float
    balance_residual_w: float
    p_pv_w: float
    p_load_w: float
    p_hp_el_w: float
    p_ch_w: float
    p_dis_w: float
    p_fc_w: float
    p_el_w: float


@dataclass(slots=True)
class CommunityStep:
    """What one step of the community plant gives.

    Attributes
    ----------
    states : every house's state at the end of the step
    hub : the hub's state
    flows : every house's flows
    hub_flows : the hub's flows
    connection : the connection point's exchange
    credited_wh : the production credited to each house's account [Wh LHV]
    """

    states: list[PlantState]
    hub: HubState
    flows: list[Flows]
    hub_flows: HubFlows
    connection: ConnectionFlows
    credited_wh: list[float]


def _total(values: Sequence[float]) -> float:
    """Sum in order, starting from the first value (one value is returned as it is)."""
    total = values[0]
    for v in values[1:]:
        total += v
    return total


def connection_exchange(flows: Sequence[Flows], p_el_hub_w: float) -> ConnectionFlows:
    """Return the connection point's exchange of the houses' flows and the hub's intake."""
    load = _total([f.p_load_w for f in flows])
    hp = _total([f.p_hp_el_w for f in flows])
    ch = _total([f.p_ch_w for f in flows])
    pv = _total([f.p_pv_w for f in flows])
    fc = _total([f.p_fc_w for f in flows])
    dis = _total([f.p_dis_w for f in flows])
    buy, sell, residual = grid.exchange(load, hp, ch, p_el_hub_w, pv, fc, dis)
    return ConnectionFlows(buy, sell, residual, pv, load, hp, ch, dis, fc, p_el_hub_w)


def without_electrolyser(action: Action) -> Action:
    """Return a house's action as its plant applies it: its electrolyser request removed (the hub has them)."""
    return Action(action.hp_mod, action.hp_mode, action.p_fc_w, action.p_bess_w, 0.0)


class CommunityPlant:
    """Every house's plant and the hub.

    Parameters
    ----------
    community : the built community (:func:`~comems4build_ros.core.community.spec.build_community`)
    buildings : each house's building model (default: the 4R3C of its parameters)
    """

    def __init__(self, community: Community, buildings: Sequence[object] | None = None) -> None:
        self.community = community
        models = list(buildings) if buildings is not None else [None] * len(community.houses)
        self.plants = [Plant(h.plant_params, b) for h, b in zip(community.houses, models)]
        self.hub = community_hub(community)

    def initial_state(self) -> tuple[list[PlantState], HubState]:
        """Every house's initial state and the hub's."""
        states = self.initial_states()
        return states, self.hub.initial_state(states)

    def initial_states(self) -> list[PlantState]:
        """Every house's initial state."""
        return [p.initial_state() for p in self.plants]

    def begin_step(self, states: list[PlantState], hub: HubState,
                   transfers_wh: Sequence[float]) -> tuple[list[float], int]:
        """Apply the coordinator's transfers at the start of a step.

        The states change in place; see :meth:`Hub.transfer`.
        """
        return self.hub.transfer(states, hub, transfers_wh)

    def houses_step(self, states: Sequence[PlantState], actions: Sequence[Action],
                    exos: Sequence[Exogenous]) -> tuple[list[PlantState], list[Flows]]:
        """Step every house's plant with its EMS's action, its electrolyser request removed.

        The house has no electrolyser; the request goes to the coordinator as its offer.
        Return the new states (each account as its fuel cell left it) and the flows.
        """
        new_states, flows = [], []
        for plant, state, action, exo in zip(self.plants, states, actions, exos):
            s, f = plant.step(state, without_electrolyser(action), exo)
            new_states.append(s)
            flows.append(f)
        return new_states, flows

    def step(self, states: Sequence[PlantState], hub: HubState, actions: Sequence[Action],
             exos: Sequence[Exogenous], p_el_set_w: float, split: Sequence[float],
             transfer: tuple[Sequence[float], int] = ((), 0)) -> CommunityStep:
        """Advance every house and the hub by one step (module docstring)."""
        new_states, flows = self.houses_step(states, actions, exos)
        hub_new, hub_flows, credits = self.hub.step(new_states, hub, p_el_set_w, split, [f.p_h2_w for f in flows],
                                                    transfer)
        return CommunityStep(new_states, hub_new, flows, hub_flows, connection_exchange(flows, hub_flows.p_el_w),
                             credits)
