"""The fuzzy coordinator (``--coordinator fuzzy``): the hub's electrolysis by a Mamdani FLC, rules as data.

FLC_hub (``config/fuzzy/hub.yaml``, the option ``rules``) is a fuzzy controller in the style
of the paper's (``sec:FLC``, ``sec:appendix``: Mamdani, min AND, max aggregation, centroid),
built and evaluated by the house's fuzzy engine
(:func:`~comems4build_ros.core.ems.fuzzy.engine.build_system`) from a rule file in the form
of the house's FLCs. Its inputs are the community's: the surplus the houses offer the hub
(the sum of their EMS's electrolyser requests), the hub store's level, the houses' H2 shares
(the fill of the emptiest account), the day-ahead prices' EDF (``eq:EDF_prices``) and the days
to the heating season. Its output ``alpha_hub`` sets the hub's intake, ``alpha_hub`` times the
hub's largest intake, capped at the offered surplus and 0 below one module's minimum; without
electrolyser modules the FLC is not evaluated. The H2 made is credited in proportion to the
offers and the pool is given to the accounts with room at the first step of a day, as the
rule-based coordinator's ``equal`` split does; every house keeps its own ``eq:deltaLOH``.

Information level: the reports only (``tab:level_of_information``: no forecasts, no model),
plus the day-ahead prices, which are not a forecast.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pydantic import Field

from comems4build_ros.core.community.coordinator import (
    Allotment,
    CommunityInfo,
    CommunityView,
    Dispatch,
    Request,
)
from comems4build_ros.core.community.rule import offered, water_fill
from comems4build_ros.core.config import ConfigError, Section, config_dir, parse_model, read_ros_params
from comems4build_ros.core.ems.features import edf_price
from comems4build_ros.core.ems.fuzzy.engine import FuzzySystem, build_system

#: The controller's section in its rule file.
FLC_NAME = "flc_hub"
#: Inputs FLC_hub must have, in this order.
FLC_INPUTS = ("surplus", "loh", "need", "price", "winter")


class FuzzyOptions(Section):
    """Options of the fuzzy coordinator (row ``fuzzy`` of ``config/coordinators.yaml``)."""

    rules: str = Field(min_length=1)


def hub_quantities(info: CommunityInfo) -> dict[str, float]:
    """Return the hub's quantities that FLC_hub's membership points may name.

    Returns
    -------
    dict with
        el_min : one module's minimal intake / the hub's largest intake [-] (with no modules
            installed, as if one were: the FLC is then never evaluated)
        loh_min, loh_mid, loh_max : the hub store's bounds and their mean [-]
    """
    p_max = max(info.n_modules, 1) * info.p_el_module_max_w
    return {
        "el_min": info.p_el_module_min_w / p_max if p_max > 0 else 0.0,
        "loh_min": info.hub_loh_min,
        "loh_mid": 0.5 * (info.hub_loh_min + info.hub_loh_max),
        "loh_max": info.hub_loh_max,
    }


def rule_file(name: str) -> Path:
    """Return the path of the rule file ``name``: a path as given, or a file of ``config/fuzzy/``."""
    path = Path(name)
    return path if path.is_absolute() or path.exists() else config_dir() / "fuzzy" / name


def load_hub_flc(path: str | Path, info: CommunityInfo) -> FuzzySystem:
    """FLC_hub from its rule file, checked.

    Raises
    ------
    ConfigError
        Naming the file and the section, input, term or rule at fault (the engine's checks: terms'
        points, rules' variables and terms, a complete and consistent rule base), or inputs other
        than :data:`FLC_INPUTS`.
    """
    path = Path(path)
    data = read_ros_params(path)
    if FLC_NAME not in data:
        raise ConfigError(f"{path}: no section '{FLC_NAME}' (the fuzzy coordinator's controller)")
    system = build_system(FLC_NAME, data[FLC_NAME], hub_quantities(info), str(path))
    if system.input_names != FLC_INPUTS:
        raise ConfigError(f"{path}: {FLC_NAME}: inputs.order must be {list(FLC_INPUTS)}, got "
                          f"{list(system.input_names)}")
    return system


class FuzzyCoordinator:
    """The hub's electrolysis by FLC_hub; H2 credited by offer, the pool to the accounts with room.

    Parameters
    ----------
    info : the community's fixed figures
    options : ``rules``, the rule file (a name in ``config/fuzzy/`` or a path)
    """

    name = "fuzzy"

    def __init__(self, info: CommunityInfo, options: Mapping[str, Any] | None = None) -> None:
        self.info = info
        self.options = parse_model(FuzzyOptions, dict(options or {}), "coordinator 'fuzzy' options")
        self.flc = load_hub_flc(rule_file(self.options.rules), info)
        self.p_max_w = info.n_modules * info.p_el_module_max_w
        self.step_info: dict[str, float] = {}

    def reset(self) -> None:
        """Nothing to forget (the FLC has no memory)."""
        self.step_info = {}

    def allot(self, view: CommunityView) -> Allotment:
        """Every house its own ``eq:deltaLOH``; at a day's first step the pool to the accounts with room."""
        houses = view.houses
        transfers = [0.0] * len(houses)
        if view.new_day and view.hub.pool_wh > 0.0:
            rooms = [max(h.share_wh - h.account_wh, 0.0) for h in houses]
            transfers = water_fill(view.hub.pool_wh, rooms, rooms)
        return Allotment(tuple(h.dloh_own_per_day for h in houses), tuple(transfers))

    def inputs(self, view: CommunityView, surplus_w: float) -> tuple[float, ...]:
        """FLC_hub's inputs in its order (module docstring)."""
        hub = view.hub
        fills = [(h.account_wh - h.floor_wh) / (h.share_wh - h.floor_wh) if h.share_wh > h.floor_wh else 1.0
                 for h in view.houses]
        prices = view.prices_buy_24h or (view.price_buy_eur_per_kwh,)
        return (surplus_w / self.p_max_w, hub.store_wh / hub.e_max_wh if hub.e_max_wh > 0 else 1.0,
                min(max(min(fills), 0.0), 1.0), edf_price(view.price_buy_eur_per_kwh, prices),
                float(view.days_to_heating_season))

    def dispatch(self, view: CommunityView, requests: tuple[Request, ...]) -> Dispatch:
        """FLC_hub's intake within the offered surplus; the production split in proportion to the offers."""
        offers = [offered(r) for r in requests]
        total = sum(offers)
        split = tuple(p / total for p in offers) if total > 0.0 else tuple(0.0 for _ in offers)
        p_el = alpha = 0.0
        if self.p_max_w > 0.0 and total > 0.0:
            alpha = self.flc(*self.inputs(view, total))
            p_el = min(alpha * self.p_max_w, total)
            if p_el < self.info.p_el_module_min_w:
                p_el = 0.0
        self.step_info = {"alpha_hub": alpha, "offers_w": total}
        return Dispatch(p_el, split)
