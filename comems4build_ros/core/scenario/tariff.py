"""Tariffs: how a scenario's day-ahead prices become the buy and sell prices of the house.

Two tariffs, one mechanism (:class:`Tariff`, ``prices(time, spot) -> (buy, sell)``):

- :class:`PaperTariff` (``paper``): the paper's own tariff of its winter, ``p_buy = a + b * spot``
  with ``a``, ``b`` and the constant sell price of ``config/plant.yaml`` ``grid`` (derivation
  there; paper ``eq:costs``, ``sec:parameters``). The default scenario and every scenario that
  names no other tariff use it.
- :class:`HouseholdTariff` (``household``): what a German household on a spot-indexed tariff
  paid in the hour's calendar year, from the data file ``config/tariffs.yaml``::

      p_buy = (1 + VAT) * ((1 + s) * spot + margin + network + EEG + KWKG + StromNEV19
                           + offshore + AbLaV + electricity tax + concession fee)

  every component of the hour's calendar year in the site's local time (a component given per
  half-year changes on 1 July), and the sell price the EEG feed-in rate of a small rooftop PV
  system commissioned in December of the winter's first year, constant over the run.

A validation case names its tariff (``config/validation.yaml`` ``tariff``;
:func:`~comems4build_ros.core.scenario.validation.case_tariff`); the paper's winter keeps the
paper's tariff.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd
from pydantic import Field, model_validator

from comems4build_ros.core.config import PRICE_MAX_EUR_PER_KWH, PlantParams, Section, config_dir, load_section
from comems4build_ros.core.scenario.csvio import ScenarioError, check_values

#: Tariff data file in ``config/``.
TARIFF_FILE = "tariffs.yaml"
#: Names of the tariffs.
PAPER, HOUSEHOLD = "paper", "household"
TARIFFS = (PAPER, HOUSEHOLD)
#: Conversion of a spot price [EUR/MWh] to [EUR/kWh].
KWH_PER_MWH = 1000.0
#: First month of the second half-year (a component given per half-year changes then).
JULY = 7
#: The components added to the energy price, net of VAT [EUR/kWh], in the order of the file.
NET_COMPONENTS = (
    "supplier_margin_eur_per_kwh",
    "network_eur_per_kwh",
    "eeg_eur_per_kwh",
    "kwkg_eur_per_kwh",
    "stromnev19_eur_per_kwh",
    "offshore_eur_per_kwh",
    "ablav_eur_per_kwh",
    "electricity_tax_eur_per_kwh",
    "concession_fee_eur_per_kwh",
)
#: Short labels of :data:`NET_COMPONENTS` and the other fields of a year (tables).
LABELS = {
    "supplier_margin_eur_per_kwh": "margin",
    "network_eur_per_kwh": "network",
    "eeg_eur_per_kwh": "EEG",
    "kwkg_eur_per_kwh": "KWKG",
    "stromnev19_eur_per_kwh": "§19 StromNEV",
    "offshore_eur_per_kwh": "offshore",
    "ablav_eur_per_kwh": "AbLaV",
    "electricity_tax_eur_per_kwh": "electricity tax",
    "concession_fee_eur_per_kwh": "concession fee",
    "spot_surcharge_share": "spot surcharge",
    "vat_share": "VAT",
    "feed_in_dec_eur_per_kwh": "feed-in (Dec)",
}


class _Section(Section):
    """A section of ``config/tariffs.yaml``."""


class Sourced(_Section):
    """One value of the tariff data with the key of its source.

    Either ``value`` (the whole year) or ``jan_jun`` and ``jul_dec`` (the half-years); ``value``
    may be null only for a published figure that was not found (its source says so).
    """

    value: float | None = None
    jan_jun: float | None = None
    jul_dec: float | None = None
    source: str = Field(min_length=1)
    note: str = ""

    @model_validator(mode="after")
    def _check(self) -> Sourced:
        halves = (self.jan_jun is None, self.jul_dec is None)
        if halves == (False, False) and self.value is not None:
            raise ValueError("give either 'value' or 'jan_jun' and 'jul_dec', not both")
        if halves in ((True, False), (False, True)):
            raise ValueError("give both 'jan_jun' and 'jul_dec' (the two half-years)")
        return self

    @property
    def halves(self) -> tuple[float | None, float | None]:
        """The values of January-June and July-December."""
        if self.jan_jun is not None:
            return self.jan_jun, self.jul_dec
        return self.value, self.value

    @property
    def known(self) -> bool:
        """True when the value is given (not a published figure left out)."""
        return self.value is not None or self.jan_jun is not None

    def at(self, month: np.ndarray) -> np.ndarray:
        """The value in each hour of the local calendar ``month`` (1..12) [-]."""
        first, second = self.halves
        return np.where(np.asarray(month) >= JULY, second, first).astype(float)


#: The range of a net price component [EUR/kWh] (the offshore surcharge was negative in 2015 and 2017).
COMPONENT_RANGE = (-1.0, PRICE_MAX_EUR_PER_KWH)
#: The range of a share (VAT, spot surcharge) [-].
SHARE_RANGE = (0.0, 1.0)


class YearTariff(_Section):
    """The components of one calendar year (``tariffs.years."<yyyy>"``)."""

    supplier_margin_eur_per_kwh: Sourced
    network_eur_per_kwh: Sourced
    eeg_eur_per_kwh: Sourced
    kwkg_eur_per_kwh: Sourced
    stromnev19_eur_per_kwh: Sourced
    offshore_eur_per_kwh: Sourced
    ablav_eur_per_kwh: Sourced
    electricity_tax_eur_per_kwh: Sourced
    concession_fee_eur_per_kwh: Sourced
    spot_surcharge_share: Sourced
    vat_share: Sourced
    feed_in_dec_eur_per_kwh: Sourced | None = None
    bdew_average_gross_eur_per_kwh: Sourced | None = None
    bnetza_average_gross_eur_per_kwh: Sourced | None = None
    note: str = ""

    @model_validator(mode="after")
    def _check(self) -> YearTariff:
        ranges = {**dict.fromkeys(NET_COMPONENTS, COMPONENT_RANGE), "spot_surcharge_share": SHARE_RANGE,
                  "vat_share": SHARE_RANGE, "feed_in_dec_eur_per_kwh": (0.0, PRICE_MAX_EUR_PER_KWH),
                  "bdew_average_gross_eur_per_kwh": (0.0, PRICE_MAX_EUR_PER_KWH),
                  "bnetza_average_gross_eur_per_kwh": (0.0, PRICE_MAX_EUR_PER_KWH)}
        for name, (lo, hi) in ranges.items():
            item = getattr(self, name)
            if item is None:
                continue
            if not item.known and not name.endswith("average_gross_eur_per_kwh"):
                raise ValueError(f"{name}: a value is needed (only a published average may be null)")
            for v in item.halves:
                if v is not None and not lo <= v <= hi:
                    raise ValueError(f"{name}: {v:g} is outside [{lo:g}, {hi:g}]")
        return self

    def sourced(self) -> dict[str, Sourced]:
        """Every field given, by name (the components, shares, feed-in and published averages)."""
        return {name: getattr(self, name) for name in type(self).model_fields
                if isinstance(getattr(self, name), Sourced)}


class TariffData(_Section):
    """The ``tariffs`` section of ``config/tariffs.yaml``: the sources and the years."""

    sources: dict[str, str]
    years: dict[str, YearTariff]

    @model_validator(mode="after")
    def _check(self) -> TariffData:
        for year, entry in self.years.items():
            if not (year.isascii() and year.isdigit() and len(year) == 4):
                raise ValueError(f"years.{year}: a year is four digits in quotes (\"2015\")")
            for name, item in entry.sourced().items():
                if item.source not in self.sources:
                    raise ValueError(f"years.{year}.{name}.source: '{item.source}' is not among the sources "
                                     f"({', '.join(self.sources)})")
                if item.known and "http" not in self.sources[item.source]:
                    raise ValueError(f"years.{year}.{name}.source: sources.{item.source} names no URL; a value "
                                     "names where it is published")
        return self

    def year(self, year: int, path: str | Path, why: str) -> YearTariff:
        """The components of ``year``.

        Raises
        ------
        ScenarioError
            Naming the file, the year, the years it holds and ``why`` it is needed.
        """
        entry = self.years.get(str(year))
        if entry is None:
            raise ScenarioError(f"{path}: no tariff for {year} (the file holds {', '.join(sorted(self.years))}); "
                                f"needed for {why}")
        return entry


@dataclass(frozen=True)
class Tables:
    """The tariff data and the file it was read from."""

    data: TariffData
    path: Path


_LOADED: dict[str, Tables] = {}


def load_tariffs(path: str | Path | None = None) -> Tables:
    """Read and check ``config/tariffs.yaml`` (or ``path``); cached per file.

    Raises
    ------
    ConfigError
        Naming the file and the field that is missing or invalid (a value outside its range, a
        source key not among ``sources``, a half-year without the other).
    """
    p = Path(path) if path else config_dir() / TARIFF_FILE
    key = str(p.resolve())
    if key not in _LOADED:
        _LOADED[key] = Tables(load_section(TariffData, p, TARIFF_FILE, "tariffs"), p)
    return _LOADED[key]


class Tariff(Protocol):
    """A tariff: the buy and sell price of each hour from its day-ahead price."""

    name: str

    def prices(self, time: pd.DatetimeIndex, spot_eur_per_mwh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Buy and sell price [EUR/kWh] of each hour (tz-aware ``time``, spot [EUR/MWh])."""

    def meta(self) -> dict[str, Any]:
        """Provenance for the scenario's ``meta`` (empty for the paper's tariff)."""


@dataclass(frozen=True)
class PaperTariff:
    """The paper's tariff ``p_buy = a + b * spot / 1000`` and a constant sell price (``config/plant.yaml`` ``grid``)."""

    params: PlantParams
    name: str = PAPER

    def prices(self, time: pd.DatetimeIndex, spot_eur_per_mwh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Buy ``a + b * spot / 1000`` and the constant sell price [EUR/kWh] (paper ``eq:costs``).

        Raises
        ------
        ScenarioError
            Naming ``grid.buy_offset_eur_per_kwh`` and ``grid.buy_spot_factor`` and the row of a
            buy price outside the plausible range.
        """
        g = self.params.grid
        with np.errstate(over="ignore"):
            buy = g.buy_offset_eur_per_kwh + g.buy_spot_factor * spot_eur_per_mwh / KWH_PER_MWH
        check_values(f"plant parameters grid.buy_offset_eur_per_kwh = {g.buy_offset_eur_per_kwh:g}, "
                     f"grid.buy_spot_factor = {g.buy_spot_factor:g}", "price_buy_eur_per_kwh", buy,
                     lambda i: f"spot price {spot_eur_per_mwh[i]:g} EUR/MWh (row {i})", "buy price")
        sell = np.full(len(spot_eur_per_mwh), g.price_sell_eur_per_kwh)
        return buy, sell

    def meta(self) -> dict[str, Any]:
        """Nothing: the paper's tariff is the scenarios' default (``config/plant.yaml``)."""
        return {}


def composed_buy(year: YearTariff, month: np.ndarray, spot_eur_per_kwh: np.ndarray) -> np.ndarray:
    """The household buy price [EUR/kWh] of hours of one year: the module docstring's formula.

    Parameters
    ----------
    year : the year's components
    month : local calendar month of each hour (1..12)
    spot_eur_per_kwh : day-ahead price of each hour [EUR/kWh]
    """
    fixed = sum(getattr(year, c).at(month) for c in NET_COMPONENTS)
    energy = (1.0 + year.spot_surcharge_share.at(month)) * spot_eur_per_kwh
    return (1.0 + year.vat_share.at(month)) * (energy + fixed)


def non_energy_gross(year: YearTariff, month: int) -> float:
    """The gross sum of the components without the energy price [EUR/kWh]: the buy price at spot 0."""
    m = np.array([month])
    return float(composed_buy(year, m, np.zeros(1))[0])


@dataclass(frozen=True)
class HouseholdTariff:
    """A German household's spot-indexed tariff of each hour's year (``config/tariffs.yaml``).

    Attributes
    ----------
    tables : the tariff data and its file
    timezone : the site's time zone (the calendar year and half-year of an hour are local)
    commissioned : year of the December in which the house's PV system was commissioned (its
        feed-in rate is the sell price of the whole run)
    """

    tables: Tables
    timezone: str
    commissioned: int
    name: str = HOUSEHOLD

    def sell_price(self) -> float:
        """The feed-in rate of rooftop PV (<= 10 kWp) commissioned in December of :attr:`commissioned` [EUR/kWh].

        Raises
        ------
        ScenarioError
            Naming the file and the field when the year or its feed-in rate is missing.
        """
        why = f"the feed-in rate of a PV system commissioned in December {self.commissioned}"
        entry = self.tables.data.year(self.commissioned, self.tables.path, why)
        if entry.feed_in_dec_eur_per_kwh is None:
            raise ScenarioError(f"{self.tables.path}: years.{self.commissioned}.feed_in_dec_eur_per_kwh is not given; "
                                f"needed for {why}")
        return float(entry.feed_in_dec_eur_per_kwh.halves[0])

    def prices(self, time: pd.DatetimeIndex, spot_eur_per_mwh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Buy price of each hour from its year's components and the constant feed-in rate [EUR/kWh].

        Raises
        ------
        ScenarioError
            Naming the file and the year an hour needs that the file does not hold.
        """
        local = pd.DatetimeIndex(time).tz_convert(self.timezone)
        spot = np.asarray(spot_eur_per_mwh, dtype=float) / KWH_PER_MWH
        buy = np.empty(len(spot))
        years, months = local.year.to_numpy(), local.month.to_numpy()
        for y in np.unique(years):
            rows = years == y
            first = local[int(np.flatnonzero(rows)[0])].isoformat()
            entry = self.tables.data.year(int(y), self.tables.path, f"the hour {first}")
            buy[rows] = composed_buy(entry, months[rows], spot[rows])
        check_values(self.tables.path, "price_buy_eur_per_kwh", buy,
                     lambda i: f"spot price {spot_eur_per_mwh[i]:g} EUR/MWh (row {i})", "buy price")
        return buy, np.full(len(spot), self.sell_price())

    def meta(self) -> dict[str, Any]:
        """The tariff's name, file and the PV system's commissioning month."""
        return {"tariff": {"name": self.name, "file": self.tables.path.name,
                           "pv_commissioned": f"{self.commissioned}-12",
                           "price_buy_eur_per_kwh": "day-ahead price + the components of each hour's calendar year",
                           "price_sell_eur_per_kwh": "EEG feed-in rate of rooftop PV <= 10 kWp, partial feed-in"}}


def make_tariff(name: str, params: PlantParams, commissioned: int | None = None,
                path: str | Path | None = None) -> Tariff:
    """The tariff called ``name`` (:data:`TARIFFS`).

    Parameters
    ----------
    name : ``paper`` or ``household``
    params : plant parameters (the paper's ``grid``; the site's time zone)
    commissioned : year of the December the house's PV system was commissioned (``household``)
    path : tariff data file (default ``config/tariffs.yaml``)

    Raises
    ------
    ScenarioError
        For an unknown name or a household tariff without a commissioning year.
    """
    if name == PAPER:
        return PaperTariff(params)
    if name == HOUSEHOLD:
        if commissioned is None:
            raise ScenarioError("the household tariff needs the year its PV system was commissioned")
        return HouseholdTariff(load_tariffs(path), params.site.timezone, int(commissioned))
    raise ScenarioError(f"unknown tariff '{name}' (known: {', '.join(TARIFFS)})")


def components_of(tables: Tables, year: int, month: int) -> Mapping[str, float]:
    """The net components, shares and feed-in rate of ``year`` in ``month`` (tables, tests) [EUR/kWh, -]."""
    entry = tables.data.year(year, tables.path, "a table of the components")
    out = {name: float(item.at(np.array([month]))[0]) for name, item in entry.sourced().items()
           if item.known and not name.endswith("average_gross_eur_per_kwh")}
    return out
