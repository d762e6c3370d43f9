"""The community file: which houses, how they differ, and the hub's size (``config/community/*.yaml``).

A community file is a YAML document with one mapping ``community`` (a table, not a ROS
parameter file)::

    community:
      name: default
      hub: {store_kwh: null, electrolyser_modules: null, standing_loss_per_h: 0.0}
      houses:
        - {name: h1, reason: "...", load_scale: 0.71, load_seed: 101, pv_azimuth_deg: 90}

Every house is the plant of the run's parameter files (``config/plant.yaml``, the
scenario's plant file, ``--config``, ``--set``) with its own variation, each field with the
reason or source the file states: the appliance load (``load_scale``, ``load_seed``: another
household of the scenario generator's load model), the hot-water draws (``dhw_scale``,
``dhw_shift_days``: the scenario's draws shifted by whole days), the PV array
(``pv_n_modules``, ``pv_tilt_deg``, ``pv_azimuth_deg``), the building's size
(``building_scale``: the 4R3C's capacities, conductances and solar aperture times the
factor), the house's share of the hub's store (``h2_weight``) and any other plant
parameter (``set``, dotted keys; not the hydrogen, electrolyser or simulation sections,
which the hub and the run own). A bad file is refused naming the file and the field
(:class:`~comems4build_ros.core.config.ConfigError`).

:func:`build_community` turns a checked file into the houses' parameters and scenarios.
The hub's store is by default the sum of the houses' own stores (``hydrogen.e_max_kwh``) and
its electrolyser the sum of their modules (``electrolyser.n_modules``): the same hydrogen
hardware as the isolated houses, shared. Each house's nominal share of the store is the
store times its ``h2_weight`` over the sum of the weights; its plant and EMS see that share
as their store (``hydrogen.e_max_kwh``), and its plant has no electrolyser (the hub has it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, field_validator, model_validator

from comems4build_ros.core.config import (
    W_PER_KW,
    ConfigError,
    ElectrolyserParams,
    PlantParams,
    Section,
    check_input_file,
    load_plant_params,
    load_yaml,
    parse_model,
    scenario_config_files,
)
from comems4build_ros.core.scenario.base import Scenario

#: Most houses of one community (the ROS launch's limit of houses).
MAX_HOUSES = 1000
#: Plant sections a house's ``set`` may not change: the hub owns the H2 store and the
#: electrolyser, the run owns the simulation settings.
HUB_SECTIONS = ("hydrogen", "electrolyser", "simulation")
#: Building parameters scaled with ``building_scale``: capacities and the solar aperture
#: grow with it, resistances shrink with it (conductances grow).
_SCALED_UP = ("c_air_j_per_k", "c_wall_j_per_k", "g_s_m2")
_SCALED_DOWN = ("r_w_air_k_per_w", "r_air_amb_k_per_w", "r_w_k_per_w", "r_w_amb_k_per_w")
#: Hours per day.
HOURS_PER_DAY = 24


class HouseSpec(Section):
    """One house of a community file (its variation of the run's plant and scenario)."""

    name: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
    reason: str = Field(min_length=1)
    load_scale: float = Field(default=1.0, gt=0, le=10)
    load_seed: int | None = Field(default=None, ge=0, le=2**32 - 1)
    dhw_scale: float = Field(default=1.0, ge=0, le=10)
    dhw_shift_days: int = Field(default=0, ge=-366, le=366)
    pv_n_modules: int | None = Field(default=None, ge=0, le=10_000)
    pv_tilt_deg: float | None = Field(default=None, ge=0, le=90)
    pv_azimuth_deg: float | None = Field(default=None, ge=0, le=360)
    building_scale: float = Field(default=1.0, ge=0.25, le=4)
    h2_weight: float = Field(default=1.0, gt=0, le=1000)
    set: dict[str, Any] = Field(default_factory=dict)

    @field_validator("set")
    @classmethod
    def _check_set(cls, value: dict[str, Any]) -> dict[str, Any]:
        for key in value:
            if key.split(".")[0] in HUB_SECTIONS:
                raise ValueError(f"'{key}' is owned by the hub or the run ({', '.join(HUB_SECTIONS)}); "
                                 "size the hub under 'hub' and the run with its options")
        return value


class HubSpec(Section):
    """The hub's size and losses (``community.hub``); None = the sum of the houses' own."""

    store_kwh: float | None = Field(default=None, gt=0, le=1.0e7)
    electrolyser_modules: int | None = Field(default=None, ge=0, le=1000)
    standing_loss_per_h: float = Field(default=0.0, ge=0, le=0.01)


class CommunitySpec(Section):
    """A community file's ``community`` mapping."""

    name: str = Field(min_length=1)
    description: str = ""
    hub: HubSpec = HubSpec()
    houses: list[HouseSpec] = Field(min_length=1, max_length=MAX_HOUSES)

    @model_validator(mode="after")
    def _unique_names(self) -> CommunitySpec:
        seen: set[str] = set()
        for house in self.houses:
            if house.name in seen:
                raise ValueError(f"houses: the name '{house.name}' is given twice")
            seen.add(house.name)
        return self


def load_community(path: str | Path) -> CommunitySpec:
    """Read and check a community file.

    Raises
    ------
    ConfigError
        Naming the file and the field: unreadable, not a mapping ``community``, a missing or
        invalid field (``houses.2.load_scale``), an unknown key, a name given twice.
    """
    p = check_input_file(path, "community file")
    doc = load_yaml(p, "community file")
    if not isinstance(doc, Mapping) or not isinstance(doc.get("community"), Mapping):
        raise ConfigError(f"{p}: needs a mapping 'community' with name, hub and houses")
    extra = sorted(set(doc) - {"community"})
    if extra:
        raise ConfigError(f"{p}: unknown top-level key(s) {', '.join(map(str, extra))} (only 'community')")
    return parse_model(CommunitySpec, doc["community"], str(p))


def resized(spec: CommunitySpec, hub: Mapping[str, Any] | None = None, house: str | None = None,
            source: str = "community file") -> CommunitySpec:
    """Return the community of ``spec`` with the hub fields of ``hub`` replaced, or one of its houses alone.

    ``house`` keeps only that house: with ``hub`` of ``store_kwh`` its own store and
    ``electrolyser_modules`` None (its own modules) the house's H2 system is its own, and
    the rule-based coordinator runs it as an isolated house (docs/community.md, "Checks").

    Raises
    ------
    ConfigError
        Naming ``source`` and the field: an unknown hub field, a value out of its range, a house
        the file does not hold.
    """
    data = spec.model_dump()
    data["hub"].update(dict(hub or {}))
    if house is not None:
        data["houses"] = [h for h in data["houses"] if h["name"] == house]
        if not data["houses"]:
            raise ConfigError(f"{source}: no house '{house}' (houses: {', '.join(h.name for h in spec.houses)})")
    return parse_model(CommunitySpec, data, source)


@dataclass(frozen=True)
class HubParams:
    """The hub's figures (:mod:`.hub`).

    Attributes
    ----------
    e_max_wh : the store's size [Wh LHV]
    loh_min, loh_max : the store's bounds [-] (the houses' widest)
    electrolyser : the modules (one module's curve, ``n_modules`` installed)
    standing_loss_per_h : H2 lost per hour, fraction of what the accounts and the pool hold above their floors [1/h]
    dt_h : step [h]
    """

    e_max_wh: float
    loh_min: float
    loh_max: float
    electrolyser: ElectrolyserParams
    standing_loss_per_h: float
    dt_h: float


@dataclass(frozen=True)
class House:
    """One house of a built community.

    Attributes
    ----------
    name : its name
    spec : its entry of the community file
    params : the house as its EMS knows it: the run's plant with the house's variation and
        its nominal share of the hub's store as its H2 store
    plant_params : its plant: ``params`` without electrolyser modules (they are at the hub)
    scenario : its inputs (the run's scenario with its load and hot-water draws)
    share_wh : its nominal share, the size of its H2 account [Wh LHV]
    """

    name: str
    spec: HouseSpec
    params: PlantParams
    plant_params: PlantParams
    scenario: Scenario
    share_wh: float


@dataclass(frozen=True)
class Community:
    """A community ready to run: its houses, its hub and the run's common scenario.

    Attributes
    ----------
    name : the file's ``name``
    source : the community file
    houses : in the file's order
    hub : the hub's figures
    scenario : the run's scenario before the houses' variations (weather, prices, time)
    """

    name: str
    source: str
    houses: tuple[House, ...]
    hub: HubParams
    scenario: Scenario

    @property
    def shares_wh(self) -> tuple[float, ...]:
        """Every house's nominal H2 share [Wh LHV]."""
        return tuple(h.share_wh for h in self.houses)


def house_overrides(spec: HouseSpec, base: PlantParams) -> dict[str, Any]:
    """Return the dotted plant overrides of one house's variation (PV, building size, ``set``)."""
    out: dict[str, Any] = {}
    for key, field in (("pv_n_modules", "pv.n_modules"), ("pv_tilt_deg", "pv.tilt_deg"),
                       ("pv_azimuth_deg", "pv.azimuth_deg")):
        if getattr(spec, key) is not None:
            out[field] = getattr(spec, key)
    if spec.building_scale != 1.0:
        b = base.building
        for name in _SCALED_UP:
            out[f"building.{name}"] = getattr(b, name) * spec.building_scale
        for name in _SCALED_DOWN:
            out[f"building.{name}"] = getattr(b, name) / spec.building_scale
    out.update(spec.set)
    return out


def house_scenario(base: Scenario, spec: HouseSpec, params: PlantParams) -> Scenario:
    """Return the run's scenario with one house's appliance load and hot-water draws.

    ``load_seed`` replaces the load by another household of the generator's load model
    (:func:`~comems4build_ros.core.scenario.generator.appliance_load_w`, ``config/scenario.yaml``
    section ``scenario.load``) on the scenario's hours; ``load_scale`` multiplies it.
    ``dhw_shift_days`` shifts the draws by whole days (the days shifted out at one end come in
    at the other), ``dhw_scale`` multiplies them. The weather, prices and comfort bounds are
    the community's.
    """
    load = base.p_load_w
    if spec.load_seed is not None:
        from comems4build_ros.core.scenario import load_scenario_settings
        from comems4build_ros.core.scenario.comfort import is_off_day
        from comems4build_ros.core.scenario.generator import appliance_load_w

        load = appliance_load_w(base.time, is_off_day(base.time, params.comfort), load_scenario_settings(),
                                spec.load_seed)
    if spec.load_scale != 1.0:
        load = load * spec.load_scale
    dhw = base.dhw_l_per_h
    if spec.dhw_shift_days:
        dhw = np.roll(dhw, spec.dhw_shift_days * HOURS_PER_DAY)
    if spec.dhw_scale != 1.0:
        dhw = dhw * spec.dhw_scale
    meta = {**base.meta, "house": spec.name}
    return dataclasses.replace(base, p_load_w=np.asarray(load, dtype=float), dhw_l_per_h=np.asarray(dhw, dtype=float),
                               meta=meta)


def _house_params(files: Sequence[str], overrides: Mapping[str, Any], extra: Mapping[str, Any], where: str
                  ) -> PlantParams:
    try:
        return load_plant_params(files, {**overrides, **extra})
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def hub_size(spec: CommunitySpec, base: PlantParams) -> tuple[float, int]:
    """Return the hub's store [Wh LHV] and electrolyser modules.

    They are the file's, or else the sum of the houses' own (``hydrogen.e_max_kwh``,
    ``electrolyser.n_modules``). A house's own hydrogen system is the run's (its variation may
    not touch the ``hydrogen`` and ``electrolyser`` sections, :data:`HUB_SECTIONS`), so the sum
    is over the run's values, one per house.
    """
    store_wh = (spec.hub.store_kwh * W_PER_KW if spec.hub.store_kwh is not None
                else sum(base.hydrogen.e_max_kwh for _ in spec.houses) * W_PER_KW)
    n_modules = (spec.hub.electrolyser_modules if spec.hub.electrolyser_modules is not None
                 else sum(base.electrolyser.n_modules for _ in spec.houses))
    return store_wh, int(n_modules)


def house_params(spec: CommunitySpec, house: HouseSpec, files: Sequence[str], overrides: Mapping[str, Any],
                 base: PlantParams, source: str = "community file") -> tuple[PlantParams, PlantParams, float]:
    """Return one house's parameters as its EMS knows them, its plant's and its nominal share.

    The EMS knows the run's plant with the house's variation and its nominal share of the
    hub's store as its H2 store; its plant's are those without electrolyser modules (they are
    at the hub); the share is in [Wh LHV].

    Parameters
    ----------
    spec : the community file; house : its house
    files, overrides : the run's parameter files and dotted overrides (``base`` is what they give)
    base : the run's plant parameters
    source : the community file's name (messages)

    Raises
    ------
    ConfigError
        Naming the community file and the house whose variation breaks a plant parameter's rule.
    """
    store_wh, _ = hub_size(spec, base)
    share_kwh = store_wh * house.h2_weight / sum(h.h2_weight for h in spec.houses) / W_PER_KW
    where = f"{source}: house '{house.name}' (its H2 share {share_kwh:g} kWh)"
    params = _house_params(files, overrides, {**house_overrides(house, base), "hydrogen.e_max_kwh": share_kwh}, where)
    return params, house_plant(params), params.hydrogen.e_max_kwh * W_PER_KW


def house_plant(params: PlantParams) -> PlantParams:
    """Return a house's plant in a community: its parameters without electrolyser modules (they are at the hub)."""
    return params.model_copy(update={"electrolyser": params.electrolyser.model_copy(update={"n_modules": 0})})


def house_plants(spec: CommunitySpec, files: Sequence[str], overrides: Mapping[str, Any], base: PlantParams,
                 source: str = "community file") -> list[tuple[PlantParams, PlantParams, float]]:
    """Return every house's parameters, its plant's and its share (:func:`house_params`).

    Each house's own plant (its variation without the hub) is checked to be a valid plant first.

    Raises
    ------
    ConfigError
        Naming the community file and the house whose variation breaks a plant parameter's rule.
    """
    for h in spec.houses:
        _house_params(files, overrides, house_overrides(h, base), f"{source}: house '{h.name}'")
    return [house_params(spec, h, files, overrides, base, source) for h in spec.houses]


def house_spec(spec: CommunitySpec, name: str, source: str = "community file") -> HouseSpec:
    """Return the house called ``name`` of a community file.

    Raises
    ------
    ConfigError
        Naming the file and the houses it has.
    """
    for house in spec.houses:
        if house.name == name:
            return house
    raise ConfigError(f"{source}: no house '{name}' (houses: {', '.join(h.name for h in spec.houses)})")


def cut_scenario(scenario: Scenario, steps: int | None) -> Scenario:
    """Cut the scenario's run to its first ``steps`` steps, the rest kept as look-ahead (None: as it is).

    Raises
    ------
    ValueError
        For ``steps`` outside ``1 .. n_steps``.
    """
    if steps is None:
        return scenario
    if not 0 < steps <= scenario.n_steps:
        raise ValueError(f"steps: {steps} outside 1..{scenario.n_steps} of scenario '{scenario.name}'")
    return dataclasses.replace(scenario, n_steps=steps)


def build_community(
    spec: CommunitySpec,
    scenario: str | Path = "default",
    config: Sequence[str | Path] = (),
    overrides: Mapping[str, Any] | None = None,
    source: str = "community file",
    start: str | None = None,
    weeks: float | None = None,
    hours: int | None = None,
    seed: int | None = None,
    extend: str | None = None,
    steps: int | None = None,
) -> Community:
    """Return the houses' parameters and scenarios and the hub of a community file, for one run.

    Parameters
    ----------
    spec : the checked community file
    scenario : the run's scenario (``default``, ``year``, a CSV file, ...; its plant file comes first)
    config : parameter files merged over ``config/plant.yaml`` for every house
    overrides : dotted plant overrides for every house (``--set``)
    source : the community file's name (messages)
    start, weeks, hours, seed, extend : the run's window and data (as ``resolve_scenario``)
    steps : cut the run to its first ``steps`` steps, the rest kept as look-ahead (as a
        distributed run's ``--steps``; None = the whole window)

    Raises
    ------
    ConfigError
        Naming the community file and the house whose variation breaks a plant parameter's rule.
    """
    from comems4build_ros.core.scenario import resolve_scenario

    files = scenario_config_files(scenario, [str(c) for c in config])
    overrides = dict(overrides or {})
    base = load_plant_params(files, overrides)
    base_scenario = cut_scenario(resolve_scenario(scenario, base, start=start, weeks=weeks, hours=hours, seed=seed,
                                                  extend=extend), steps)
    return community_of(spec, files, overrides, base, base_scenario, source)


def community_of(spec: CommunitySpec, files: Sequence[str], overrides: Mapping[str, Any], base: PlantParams,
                 base_scenario: Scenario, source: str = "community file") -> Community:
    """Build the community of a file on the run's parameters ``base`` and scenario ``base_scenario``.

    ``base`` is of ``files`` and ``overrides`` (:func:`build_community`; a node that loaded
    them itself builds it here).

    Raises
    ------
    ConfigError
        Naming the community file and the house whose variation breaks a plant parameter's rule.
    """
    store_wh, n_modules = hub_size(spec, base)
    houses = []
    for h, (params, plant_params, share_wh) in zip(spec.houses, house_plants(spec, files, overrides, base, source)):
        houses.append(House(name=h.name, spec=h, params=params, plant_params=plant_params,
                            scenario=house_scenario(base_scenario, h, params), share_wh=share_wh))
    hub = HubParams(
        e_max_wh=store_wh,
        loh_min=min(p.params.hydrogen.loh_min for p in houses),
        loh_max=max(p.params.hydrogen.loh_max for p in houses),
        electrolyser=base.electrolyser.model_copy(update={"n_modules": int(n_modules)}),
        standing_loss_per_h=spec.hub.standing_loss_per_h,
        dt_h=float(base.simulation.time_step_h),
    )
    return Community(name=spec.name, source=source, houses=tuple(houses), hub=hub, scenario=base_scenario)
