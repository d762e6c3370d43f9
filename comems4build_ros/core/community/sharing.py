"""Electricity inside the community: the sharing rule sets (``config/sharing.yaml``) and the settlement.

The houses' EMS see their own tariff as an isolated house does (their information level
is unchanged); the rule sets only settle, after the fact and step by step, what the
members' meters measured, as an energy-sharing settlement does with quarter-hour meter
data. Per step (energies over the step):

- importers: every house's purchase at its meter ``d_i`` and the hub's electrolysers'
  intake ``d_hub``; exporters: every house's sale ``s_i``;
- shared energy ``S = min(sum d, sum s)`` (0 under a rule set that shares nothing); each
  importer receives ``S d_j / sum d``, each exporter gives ``S s_i / sum s``; the rest is
  bought from the grid at the buy price ``p_buy`` and sold at the feed-in price ``F``;
- a kWh shared costs the importer ``P_s + (1 + VAT) (n N + c C + l L + t T)`` and pays the
  exporter ``P_s = F + position max(E - F, 0)``, with the retail energy component
  ``E = p_buy / (1 + VAT) - (N + C + L + T)``, the hour's network charges ``N``, concession
  fee ``C``, levies ``L`` and electricity tax ``T`` (net, :func:`charge_parts`) and the rule
  set's shares ``n, c, l, t`` and price ``position``;
- the hub's cost is borne by the houses in proportion to the H2 its step made for them
  (the coordinator's production split), by their nominal shares in a step without one.

The physical connection point (:mod:`.plant`) buys ``sum d - S`` and sells ``sum s - S``
of a rule set that shares: its cost at ``p_buy`` and ``F`` is the community's cost when the
shared energy bears no charge (``one_connection``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from pydantic import Field, model_validator

from comems4build_ros.core.config import W_PER_KW, ConfigError, Section, config_dir, load_yaml, parse_model

#: The rule-set file in ``config/``.
SHARING_FILE = "sharing.yaml"
#: The levies of the tariff data (``config/tariffs.yaml``) that fall on electricity taken from the grid.
LEVIES = ("eeg_eur_per_kwh", "kwkg_eur_per_kwh", "stromnev19_eur_per_kwh", "offshore_eur_per_kwh",
          "ablav_eur_per_kwh")
Share = Field(ge=0, le=1)


class RuleSet(Section):
    """One rule set of ``config/sharing.yaml`` (see the file for the meaning and sources)."""

    label: str = Field(min_length=1)
    legal_status: str = Field(min_length=1)
    shares_energy: bool
    network_share: float = Share
    concession_share: float = Share
    levies_share: float = Share
    electricity_tax_share: float = Share
    price_position: float = Share
    sources: list[str] = Field(min_length=1)


class SharingRules(Section):
    """The ``sharing`` mapping: the sources and the rule sets by name."""

    sources: dict[str, str]
    rule_sets: dict[str, RuleSet] = Field(min_length=1)

    @model_validator(mode="after")
    def _check_sources(self) -> SharingRules:
        for name, rule in self.rule_sets.items():
            for key in rule.sources:
                if key not in self.sources:
                    raise ValueError(f"rule_sets.{name}.sources: '{key}' is not among the sources "
                                     f"({', '.join(self.sources)})")
        return self


_LOADED: dict[str, SharingRules] = {}


def load_sharing_rules(path: str | Path | None = None) -> SharingRules:
    """Read and check ``config/sharing.yaml`` (or ``path``); cached per file.

    Raises
    ------
    ConfigError
        Naming the file and the field that is missing or invalid.
    """
    p = Path(path) if path else config_dir() / SHARING_FILE
    key = str(p.resolve())
    if key not in _LOADED:
        doc = load_yaml(p, "sharing rules")
        if not isinstance(doc, dict) or not isinstance(doc.get("sharing"), dict):
            raise ConfigError(f"{p}: needs a mapping 'sharing' with sources and rule_sets")
        _LOADED[key] = parse_model(SharingRules, doc["sharing"], str(p))
    return _LOADED[key]


@dataclass(frozen=True)
class ChargeParts:
    """The non-energy components of the buy price in every step, net of VAT [EUR/kWh], and VAT [-].

    Attributes
    ----------
    network : network charges incl. metering
    concession : concession fee
    levies : the surcharges on electricity taken from the grid (:data:`LEVIES`)
    electricity_tax : electricity tax
    vat_share : VAT rate
    """

    network: np.ndarray
    concession: np.ndarray
    levies: np.ndarray
    electricity_tax: np.ndarray
    vat_share: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """Network, concession, levies and tax together, net [EUR/kWh]."""
        return self.network + self.concession + self.levies + self.electricity_tax


def charge_parts(time: pd.DatetimeIndex, timezone: str, path: str | Path | None = None) -> ChargeParts:
    """Return the components of every step from the tariff data of its local calendar year (``config/tariffs.yaml``).

    The one place the community reads the household tariff data, the same the validation
    winters' household tariff is composed of (:mod:`comems4build_ros.core.scenario.tariff`).

    Raises
    ------
    ScenarioError
        Naming the tariff file and a year a step needs that it does not hold.
    """
    from comems4build_ros.core.scenario.tariff import load_tariffs

    tables = load_tariffs(path)
    local = pd.DatetimeIndex(time).tz_convert(timezone)
    years, months = local.year.to_numpy(), local.month.to_numpy()
    out = {k: np.zeros(len(local)) for k in ("network", "concession", "levies", "electricity_tax", "vat_share")}
    for y in np.unique(years):
        rows = years == y
        entry = tables.data.year(int(y), tables.path, f"the sharing charges of the hour {local[rows][0].isoformat()}")
        m = months[rows]
        out["network"][rows] = entry.network_eur_per_kwh.at(m)
        out["concession"][rows] = entry.concession_fee_eur_per_kwh.at(m)
        out["levies"][rows] = sum(getattr(entry, name).at(m) for name in LEVIES)
        out["electricity_tax"][rows] = entry.electricity_tax_eur_per_kwh.at(m)
        out["vat_share"][rows] = entry.vat_share.at(m)
    return ChargeParts(**out)


def share_prices(rule: RuleSet, price_buy: np.ndarray, price_sell: np.ndarray,
                 parts: ChargeParts) -> tuple[np.ndarray, np.ndarray]:
    """Return the exporter's price ``P_s`` and the importer's price of a kWh shared [EUR/kWh].

    Per step; see the module docstring.
    """
    energy = price_buy / (1.0 + parts.vat_share) - parts.total
    p_s = price_sell + rule.price_position * np.maximum(energy - price_sell, 0.0)
    charges = (rule.network_share * parts.network + rule.concession_share * parts.concession
               + rule.levies_share * parts.levies + rule.electricity_tax_share * parts.electricity_tax)
    return p_s, p_s + (1.0 + parts.vat_share) * charges


@dataclass
class Settlement:
    """One rule set's settlement of a community run.

    Attributes
    ----------
    rule : the rule set's name
    houses : per house [kWh, EUR]: ``grid_buy_kwh``, ``grid_sell_kwh``, ``shared_in_kwh``,
        ``shared_out_kwh``, ``hub_kwh`` (its part of the hub's intake), ``hub_grid_kwh`` (its part of
        what the hub took from the grid, not shared), ``hub_cost_eur``,
        ``cost_eur`` (its own meter and its part of the hub, net of what it earned)
    totals : ``cost_eur`` (the community's), ``cost_eur_per_household``, ``shared_kwh``,
        ``grid_buy_kwh``, ``grid_sell_kwh``, ``hub_cost_eur``, ``charges_on_shared_eur``
    """

    rule: str
    houses: pd.DataFrame
    totals: dict[str, float]


def settle(rule_name: str, rule: RuleSet, buy_w: np.ndarray, sell_w: np.ndarray, hub_w: np.ndarray,
           hub_attribution: np.ndarray, price_buy: np.ndarray, price_sell: np.ndarray, parts: ChargeParts,
           dt_h: float, names: Sequence[str]) -> Settlement:
    """Settle a run under one rule set (module docstring).

    Parameters
    ----------
    rule_name, rule : the rule set
    buy_w, sell_w : every house's purchase and sale at its meter, shape (houses, steps) [W]
    hub_w : the hub's intake per step [W]
    hub_attribution : every house's part of the hub's intake, shape (houses, steps), columns summing to 1 [-]
    price_buy, price_sell : the tariff per step [EUR/kWh]
    parts : the charges per step
    dt_h : step [h]
    names : the houses' names
    """
    kwh = dt_h / W_PER_KW
    d_houses = np.asarray(buy_w, dtype=float) * kwh
    s_houses = np.asarray(sell_w, dtype=float) * kwh
    d_hub = np.asarray(hub_w, dtype=float) * kwh
    demand = d_houses.sum(axis=0) + d_hub
    supply = s_houses.sum(axis=0)
    shared = np.minimum(demand, supply) if rule.shares_energy else np.zeros_like(demand)
    f_in = np.divide(shared, demand, out=np.zeros_like(shared), where=demand > 0)
    f_out = np.divide(shared, supply, out=np.zeros_like(shared), where=supply > 0)
    p_s, p_c = share_prices(rule, np.asarray(price_buy, float), np.asarray(price_sell, float), parts)
    r_houses, g_houses, r_hub = d_houses * f_in, s_houses * f_out, d_hub * f_in
    own = ((d_houses - r_houses) * price_buy + r_houses * p_c
           - (s_houses - g_houses) * price_sell - g_houses * p_s)
    hub_cost = (d_hub - r_hub) * price_buy + r_hub * p_c
    attribution = np.asarray(hub_attribution, dtype=float)
    hub_part = attribution * hub_cost
    houses = pd.DataFrame({
        "grid_buy_kwh": (d_houses - r_houses).sum(axis=1),
        "grid_sell_kwh": (s_houses - g_houses).sum(axis=1),
        "shared_in_kwh": r_houses.sum(axis=1),
        "shared_out_kwh": g_houses.sum(axis=1),
        "hub_kwh": (attribution * d_hub).sum(axis=1),
        "hub_grid_kwh": (attribution * (d_hub - r_hub)).sum(axis=1),
        "hub_cost_eur": hub_part.sum(axis=1),
        "cost_eur": own.sum(axis=1) + hub_part.sum(axis=1),
    }, index=list(names))
    charges = (p_c - p_s) * shared
    totals = {
        "cost_eur": float(houses["cost_eur"].sum()),
        "cost_eur_per_household": float(houses["cost_eur"].mean()),
        "shared_kwh": float(shared.sum()),
        "grid_buy_kwh": float((demand - shared).sum()),
        "grid_sell_kwh": float((supply - shared).sum()),
        "hub_cost_eur": float(hub_cost.sum()),
        "charges_on_shared_eur": float(charges.sum()),
    }
    return Settlement(rule_name, houses, totals)
