"""The coordinator of a community: what it may read, what it decides, and the table of coordinators.

A coordinator runs twice per step ``k`` of a community run (:mod:`.loop`):

1. :meth:`Coordinator.allot`, before the houses act: it reads the hub's state and every
   house's public figures at the end of step ``k - 1`` (:class:`CommunityView`) and
   publishes an :class:`Allotment`: H2 moved between the hub's unallocated pool and each
   house's account at the start of step ``k``, and each house's daily permissible H2
   (``eq:deltaLOH``, fraction of the house's nominal share per day), which the house's EMS
   reads where an isolated house's EMS reads its own ``dloh_per_day``.
2. :meth:`Coordinator.dispatch`, after the houses acted: it reads each house's
   :class:`Request` (the electrolyser power its EMS asked for: the surplus it offers the
   hub, and its measured PV output and appliance load of step ``k``) and decides the hub's
   :class:`Dispatch`: the electrolysis set-point of step ``k`` and how the H2 made in the
   step is split among the houses' accounts (the rest goes to the pool).

What a coordinator may read is exactly what these records hold: per house its account
and nominal share, its metered grid exchange and FC hydrogen use of the previous step,
its own ``eq:deltaLOH``, and its request; of the hub its store, pool, electrolyser state
and limits. It never reads a house's temperatures, tank or battery: each house's EMS keeps
its information level (``tab:level_of_information``).

Every coordinator is a row of ``config/coordinators.yaml`` (name, ``module:Class``, label,
colour, options, summary), read by :func:`coordinator_table`; :func:`make_coordinator`
builds one. To add one: write a class with the attributes and methods of
:class:`Coordinator` and add a row (``docs/community.md``, "Adding a coordinator").
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from comems4build_ros.core.config import (
    ConfigError,
    PlantParams,
    config_dir,
    load_yaml,
    table_class,
    table_rows,
)
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.files.errors import InputError

#: The coordinator table's file in ``config/``.
COORDINATOR_TABLE_FILE = "coordinators.yaml"
#: What a coordinator reads of the houses: the reports only, or also their MPC-level observations.
INFO_LEVELS = ("hub", "mpc")
#: The keys of a row of the table.
_ROW_KEYS = ("coordinator", "label", "colour", "options", "summary")


@dataclass(frozen=True, slots=True)
class HouseReport:
    """What a coordinator reads of one house at the start of step ``k`` (its state at the end of ``k - 1``).

    Attributes
    ----------
    name : the house's name in the community file
    share_wh : its nominal H2 share, the size of its account [Wh LHV]
    account_wh : H2 in its account [Wh LHV]
    floor_wh : the lowest its account may hold, ``hydrogen.loh_min`` of its share [Wh LHV]
    dloh_own_per_day : its own daily permissible H2 ``eq:deltaLOH`` as an isolated house would
        have it [1/day, fraction of its share]
    p_buy_prev_w, p_sell_prev_w : its metered grid exchange in step ``k - 1`` [W]
    p_h2_fc_prev_w : its fuel cell's H2 use in step ``k - 1`` [W LHV]
    """

    name: str
    share_wh: float
    account_wh: float
    floor_wh: float
    dloh_own_per_day: float
    p_buy_prev_w: float
    p_sell_prev_w: float
    p_h2_fc_prev_w: float


@dataclass(frozen=True, slots=True)
class HubReport:
    """The hub's state at the end of step ``k - 1`` and its limits.

    Attributes
    ----------
    e_max_wh : the store's size [Wh LHV]
    store_wh : H2 in the store [Wh LHV]
    pool_wh : H2 in the store that is in no house's account [Wh LHV]
    el_on_prev : the electrolyser produced in step ``k - 1``
    modules_on_prev : electrolyser modules that produced in step ``k - 1``
    n_modules : electrolyser modules installed
    p_el_module_min_w, p_el_module_max_w : intake range of one module [W]
    """

    e_max_wh: float
    store_wh: float
    pool_wh: float
    el_on_prev: bool
    modules_on_prev: int
    n_modules: int
    p_el_module_min_w: float
    p_el_module_max_w: float


@dataclass(frozen=True, slots=True)
class CommunityView:
    """Everything a coordinator reads at the start of step ``k``.

    Attributes
    ----------
    step : ``k``
    time : start of the step (ISO 8601, local time of the site)
    day_index : days since the start of the run (the houses' ``day_index``)
    new_day : the step is the first of its day (or of the run)
    steps_per_day : steps of one day
    hub : the hub's report
    houses : one report per house, in the community file's order
    price_buy_eur_per_kwh, price_sell_eur_per_kwh : the community's tariff in step ``k`` [EUR/kWh]
    prices_buy_24h : the day-ahead buy prices of steps ``k .. k+23`` [EUR/kWh] (known in advance,
        not a forecast, ``tab:level_of_information``)
    days_to_heating_season : days to the next heating season, 0 inside it [d]
    observations : only for a coordinator of information level ``mpc``: every house's
        observation at the MPC's level (``tab:level_of_information``: its states at the end of
        ``k - 1`` and the 24-step forecasts of the run's forecast model), in the houses' order;
        empty otherwise
    """

    step: int
    time: str
    day_index: int
    new_day: bool
    steps_per_day: int
    hub: HubReport
    houses: tuple[HouseReport, ...]
    price_buy_eur_per_kwh: float = math.nan
    prices_buy_24h: tuple[float, ...] = ()
    price_sell_eur_per_kwh: float = math.nan
    days_to_heating_season: float = 0.0
    observations: tuple[Observation, ...] = ()


@dataclass(frozen=True, slots=True)
class Request:
    """What one house sends the coordinator after its EMS acted in step ``k``.

    Attributes
    ----------
    p_el_w : the electrolyser intake its EMS asked for: the surplus it offers the hub [W]
    p_pv_w, p_load_w : its measured PV output and appliance load of step ``k`` [W]
    """

    p_el_w: float
    p_pv_w: float
    p_load_w: float


@dataclass(frozen=True, slots=True)
class Allotment:
    """What a coordinator publishes before the houses act in step ``k``.

    Attributes
    ----------
    dloh_per_day : each house's daily permissible H2 ``eq:deltaLOH`` [1/day, fraction of its share]
    transfers_wh : H2 moved from the pool into each house's account at the start of the
        step [Wh LHV] (negative: from the account back to the pool); the hub refuses moves
        that overdraw the pool or an account
    """

    dloh_per_day: tuple[float, ...]
    transfers_wh: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class Dispatch:
    """What a coordinator decides for the hub after the houses acted in step ``k``.

    Attributes
    ----------
    p_el_w : the electrolysers' intake set-point [W] (the hub keeps it within its limits)
    production_split : the share of the step's H2 production credited to each house's
        account [-] (each >= 0, sum <= 1; what an account cannot take, and the rest, goes to
        the pool)
    """

    p_el_w: float
    production_split: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class CommunityInfo:
    """What a coordinator knows from the start: the community's fixed figures.

    Attributes
    ----------
    names : the houses' names
    shares_wh : their nominal H2 shares [Wh LHV]
    dt_h : step length [h]
    steps_per_day : steps of one day
    hub_e_max_wh : the hub store's size [Wh LHV]
    n_modules : electrolyser modules at the hub
    p_el_module_min_w, p_el_module_max_w : intake range of one module [W]
    hub_loh_min, hub_loh_max : the hub store's bounds [-]
    eta_el : the electrolysers' rated LHV efficiency, compression included [-] (the MPC's constant)
    house_params : every house's parameters as its EMS knows them (its share as its store);
        read only by coordinators of information level ``mpc`` (their forecasting models)
    """

    names: tuple[str, ...]
    shares_wh: tuple[float, ...]
    dt_h: float
    steps_per_day: int
    hub_e_max_wh: float
    n_modules: int
    p_el_module_min_w: float
    p_el_module_max_w: float
    hub_loh_min: float = 0.0
    hub_loh_max: float = 1.0
    eta_el: float = 0.0
    house_params: tuple[PlantParams, ...] = ()


@runtime_checkable
class Coordinator(Protocol):
    """A coordinator: allotments before the houses act, the hub's dispatch after.

    Implementations set ``name`` as a class attribute (and ``info_level``: ``hub``, the
    default, reads the reports only; ``mpc`` also reads every house's observation at the
    MPC's level in :attr:`CommunityView.observations`), are built as
    ``Cls(info, options)`` with the :class:`CommunityInfo` and their options mapping (the
    row's ``options`` of ``config/coordinators.yaml`` with the user's overrides), and keep
    in ``step_info`` what they want recorded per step (numbers; ``messages`` and
    ``iterations`` are read by the KPIs when given).
    """

    name: str
    step_info: dict[str, float]

    def reset(self) -> None:
        """Forget everything before a new run."""

    def allot(self, view: CommunityView) -> Allotment:
        """Return the allotment of step ``view.step``."""

    def dispatch(self, view: CommunityView, requests: tuple[Request, ...]) -> Dispatch:
        """Return the hub's dispatch of step ``view.step``."""


class UnknownCoordinatorError(InputError):
    """The requested coordinator is not in the table (or its class is missing)."""


@dataclass(frozen=True)
class CoordinatorEntry:
    """One row of the coordinator table.

    Attributes
    ----------
    name : coordinator name (``--coordinator``)
    coordinator : ``module:Class``
    label : display name
    colour : figure colour (``#RRGGBB``)
    options : default options of the class
    summary : one-line description
    """

    name: str
    coordinator: str
    label: str
    colour: str
    options: Mapping[str, Any]
    summary: str


def parse_coordinator_table(doc: Any, source: str) -> dict[str, CoordinatorEntry]:
    """Return the rows of a coordinator table document (``{"coordinators": {name: row}}``), checked.

    Raises
    ------
    ConfigError
        Naming the file, the coordinator and the key that is missing or invalid.
    """
    table: dict[str, CoordinatorEntry] = {}
    for name, row, where in table_rows(doc, "coordinators", _ROW_KEYS, "coordinator", source, "coordinator"):
        if not isinstance(row["options"], dict):
            raise ConfigError(f"{where}: options must be a mapping (may be empty), got {row['options']!r}")
        for key in ("label", "colour", "summary"):
            if not isinstance(row[key], str) or not row[key].strip():
                raise ConfigError(f"{where}: {key} must be a non-empty text")
        table[name] = CoordinatorEntry(name=name, coordinator=row["coordinator"], label=row["label"],
                                       colour=row["colour"], options=dict(row["options"]), summary=row["summary"])
    return table


@functools.cache
def coordinator_table() -> dict[str, CoordinatorEntry]:
    """Every coordinator of ``config/coordinators.yaml`` by name, in the file's order."""
    path = config_dir() / COORDINATOR_TABLE_FILE
    return parse_coordinator_table(load_yaml(path, "the coordinator table"), str(path))


def coordinator_names() -> tuple[str, ...]:
    """Return the names of every coordinator (``--coordinator`` choices)."""
    return tuple(coordinator_table())


def coordinator_entry(name: str) -> CoordinatorEntry:
    """Return the table row of the coordinator ``name``.

    Raises
    ------
    UnknownCoordinatorError
        If no coordinator is called ``name``.
    """
    try:
        return coordinator_table()[name]
    except KeyError:
        known = ", ".join(sorted(coordinator_table()))
        raise UnknownCoordinatorError(f"unknown coordinator '{name}' (known: {known})") from None


def coordinator_class(name: str) -> type:
    """Class of the coordinator called ``name``.

    Raises
    ------
    UnknownCoordinatorError
        If the name is not in the table, its module or class is missing, or the class's
        ``name`` differs from its row.
    """
    entry = coordinator_entry(name)
    cls = table_class(entry.coordinator, ("allot", "dispatch", "reset"), "coordinator", f"coordinator '{name}'",
                      UnknownCoordinatorError)
    if getattr(cls, "name", None) != name:
        raise UnknownCoordinatorError(f"{entry.coordinator}: name '{getattr(cls, 'name', None)}' differs from the "
                                      f"coordinator table's '{name}'")
    return cls


def make_coordinator(name: str, info: CommunityInfo, options: Mapping[str, Any] | None = None) -> Coordinator:
    """Build the coordinator ``name`` with its row's options and ``options`` merged over them (key by key)."""
    entry = coordinator_entry(name)
    merged = {**entry.options, **dict(options or {})}
    return coordinator_class(name)(info, merged)
