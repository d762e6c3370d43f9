"""The economic comparison of a community: isolated houses, each with its own H2 system, against one shared hub.

The runs of ``comems4build size --community FILE`` and the annual cost of every household
(docs/community.md, "Isolated houses or a shared hub"); its tables and report are
:mod:`comems4build_ros.report.community_sizing`.

Two arms over the year scenario, both made of the houses of one community file:

- **hub**: the community with its hub at each size of the design (store ``store_kwh`` and
  ``modules`` electrolyser modules), one run each: the houses keep their fuel cells, the hub
  holds every electrolyser and the store (:class:`~comems4build_ros.study.community.CommunityTask`);
- **isolated**: every house alone with its own H2 system, a store of the size of its
  nominal share of each hub store and its own electrolyser (the plant's ``n_modules``): a
  community of that one house whose hub is its own H2 system, which the rule-based
  coordinator runs as the isolated house bit for bit (docs/community.md, "Checks").

The sharing rule sets only settle what the meters measured (``config/sharing.yaml``): one run
serves every rule set. Every household's annual cost under a rule set is, as in ``size``
(:func:`comems4build_ros.core.economics.annual_costs`): its energy under the rule set (its
meter and, with a hub, its part of the hub's electricity), the annuity and O&M of its own
components (PV, battery, FC; isolated also its electrolyser and store) with their wear, and
with a hub its part of the hub's annuity and O&M (:data:`HUB_COST_SPLIT`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from comems4build_ros.core import economics
from comems4build_ros.core.kpi import HOURS_PER_WEEK

#: The two arms of the comparison.
ARMS = ("isolated", "hub")
#: How the hub's annuity and O&M are split among the households.
HUB_COST_SPLIT = ("in proportion to each household's nominal share of the hub's store (its account's size, "
                  "h2_weight): each household owns that part of the shared hardware; the hub's electricity is "
                  "borne in proportion to the H2 each step made for each household (the rule set's settlement)")


@dataclass(frozen=True)
class HubSize:
    """One hub size of the design: the store [kWh LHV] and the electrolyser modules [-]."""

    store_kwh: float
    modules: int

    @property
    def name(self) -> str:
        """Its run's directory name: ``hub__h2<kWh>_el<modules>``."""
        return f"hub__h2{self.store_kwh:g}_el{self.modules}"


def isolated_name(house: str, store_kwh: float) -> str:
    """The directory name of an isolated house's run: ``isolated__<house>__h2<kWh>``."""
    return f"isolated__{house}__h2{store_kwh:g}"


def shares_kwh(store_kwh: float, weights: Mapping[str, float]) -> dict[str, float]:
    """Every house's nominal share of a hub store [kWh LHV]: ``store w_i / sum w`` (``h2_weight``)."""
    total = sum(weights.values())
    return {name: store_kwh * w / total for name, w in weights.items()}


def hub_annual_costs(size: HubSize, module_hours: float, weeks: float, costs: economics.Costs
                     ) -> dict[str, float]:
    """The hub's annuity, O&M and investment per year [EUR/a, EUR] (:func:`economics.annual_costs`).

    The electrolysers' wear life is their hour life over the hours each module works per year,
    the modules sharing the run's module hours (``el_module_hours``) equally (a controller that
    rotates the lead module); the store's life is its calendar life.
    """
    per_module_h = module_hours / size.modules if size.modules else 0.0
    sizes = {"pv_kwp": 0.0, "battery_kwh": 0.0, "fc_kw": 0.0, "el_modules": size.modules, "h2_kwh": size.store_kwh}
    summary = {"weeks": weeks, "cost_net_eur": 0.0, "fc_working_hours": 0.0, "fc_toggles": 0.0,
               "el_working_hours": per_module_h, "bess_charged_kwh_total": 0.0}
    return economics.annual_costs(sizes, summary, costs, 0.0)


def run_weeks(community: Mapping[str, Any], dt_h: float) -> float:
    """The length of a community run in weeks, from its ``community.json`` (``steps``) [-].

    A house's ``summary.json`` counts its weekly rows (a partial week as one); the annual
    figures scale the run by its length.
    """
    return float(community["steps"]) * dt_h / HOURS_PER_WEEK


def household_costs(sizes: Mapping[str, float], summary: Mapping[str, Any], energy_eur: float,
                    costs: economics.Costs, usable_battery_kwh: float, weeks: float, el_hours: float = 0.0,
                    hub: Mapping[str, float] | None = None, hub_part: float = 0.0) -> dict[str, float]:
    """One household's annual cost under one rule set [EUR/a].

    Parameters
    ----------
    sizes : its components (``pv_kwp``, ``battery_kwh``, ``fc_kw``; ``el_modules`` and ``h2_kwh``
        of its own H2 system, 0 with a hub)
    summary : its house's run summary (``fc_working_hours``, ``fc_toggles``, ``bess_charged_kwh_total``)
    energy_eur : its energy cost over the run under the rule set (meter and part of the hub) [EUR]
    costs : the cost figures (``config/costs.yaml``)
    usable_battery_kwh : its battery's usable capacity [kWh]
    weeks : the run's length (:func:`run_weeks`) [-]
    el_hours : working hours of its own electrolyser over the run [h]
    hub : :func:`hub_annual_costs` of the hub it shares (None: isolated)
    hub_part : its part of the hub's annuity and O&M [-]

    Returns
    -------
    dict with ``energy_eur_a``, ``annuity_eur_a`` and ``om_eur_a`` of its own components,
    ``hub_annuity_eur_a`` and ``hub_om_eur_a`` (its part), ``total_eur_a``, ``invest_eur``
    (its own and its part of the hub's), the wear per year and the lives used.
    """
    run = {**summary, "weeks": weeks, "cost_net_eur": energy_eur, "el_working_hours": el_hours}
    own = economics.annual_costs(sizes, run, costs, usable_battery_kwh)
    hub_annuity = hub_part * hub["annuity_eur_a"] if hub else 0.0
    hub_om = hub_part * hub["om_eur_a"] if hub else 0.0
    return {**own, "hub_annuity_eur_a": hub_annuity, "hub_om_eur_a": hub_om,
            "total_eur_a": own["total_eur_a"] + hub_annuity + hub_om,
            "invest_eur": own["invest_eur"] + (hub_part * hub["invest_eur"] if hub else 0.0)}


def community_cycle(community: Mapping[str, Any], houses: Mapping[str, Mapping[str, Any]]) -> tuple[bool | None, str]:
    """Whether a shared hub closes the seasonal cycle, and why (not): ``size``'s criterion on the hub.

    :func:`comems4build_ros.core.economics.cycle_closes` with the hub as the store: the
    summer filled the hub (its LOH at the heating season's start above its start), the hub
    ends the year with at least its starting LOH, no house's account ran dry (a household
    without H2 while the hub holds some is not served by it) and no house had a heating-season
    week with discomfort.

    Parameters
    ----------
    community : the run's ``community.json`` (``hub_loh_init``, ``hub_loh_end``, ``hub_loh_heating_season_start``)
    houses : every house's ``summary.json``, by name
    """
    empty = [f"{name}'s account at {s['h2_empty_at']}" for name, s in houses.items() if s.get("h2_empty_at")]
    hub = {"heating_season_weeks": max(int(s.get("heating_season_weeks") or 0) for s in houses.values()),
           "loh_heating_season_start": community.get("hub_loh_heating_season_start"),
           "loh_init": community["hub_loh_init"], "loh_end": community["hub_loh_end"],
           "h2_empty_at": "; ".join(empty) or None,
           "heating_season_discomfort_weeks": sum(int(s.get("heating_season_discomfort_weeks") or 0)
                                                  for s in houses.values())}
    return economics.cycle_closes(hub)


def smallest_closing(points: Sequence[Mapping[str, Any]]) -> Mapping[str, Any] | None:
    """The closing point of the least H2 capacity per house (ties: the fewest modules, then the least cost)."""
    ok = [p for p in points if p["closes"] is True]
    if not ok:
        return None
    return min(ok, key=lambda p: (p["h2_kwh_per_house"], p["el_modules_per_house"], p["total_eur_a_per_household"]))
