"""Economics of a sized plant: investments, annuities, O&M and wear, per year.

The paper names the economic analysis as future work ("at which level this setup would be
economically beneficial and what component dimensions would be optimal",
``sec:conclusion``). This module turns a run's summary (``summary.json`` of a year-round run,
``kpi.year_kpis``) and the sizes of its components into annual costs:

- energy: bought minus sold (``cost_net_eur``) of the run, scaled to 52 weeks;
- annuity of each component: ``invest * CRF(r, life)``, ``CRF = r (1+r)^n / ((1+r)^n - 1)``,
  with ``life = min(calendar life, wear life)``; the wear life of the FC and the electrolyser
  is their hour life over their working hours per year, the battery's its cycle life
  (``tab:degradation_HESS`` N_B) over its equivalent full cycles per year;
- O&M: a share of the investment per year, plus the FC's hourly O&M and its on/off costs
  (``tab:degradation_HESS`` sigma_om,FC, sigma_FC,on, sigma_FC,off).

The cost figures come from ``config/costs.yaml`` (sources in its comments). Pure: no ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from comems4build_ros.core.config import ConfigError, config_dir, read_param_section

#: Weeks of the year the annual figures refer to (the year scenario: 52 weeks).
WEEKS_PER_YEAR = 52.0
#: Tolerance of "LOH at the end >= LOH at the start" (LOH is stored to 1e-9 in summary.json).
LOH_CLOSE_TOL = 1e-6

#: Keys of ``costs`` in config/costs.yaml: section -> key -> (lower bound, lower bound open).
COST_KEYS: dict[str, dict[str, tuple[float, bool]]] = {
    "pv": {"invest_eur_per_kwp": (0, False), "life_a": (0, True), "om_share_per_a": (0, False)},
    "battery": {"invest_eur_per_kwh": (0, False), "n_cycles": (0, True), "life_a": (0, True),
                "om_share_per_a": (0, False)},
    "fuel_cell": {"invest_eur_per_kw": (0, False), "life_h": (0, True), "life_a": (0, True),
                  "om_eur_per_h": (0, False), "on_eur": (0, False), "off_eur": (0, False)},
    "electrolyser": {"invest_eur_per_module": (0, False), "life_h": (0, True), "life_a": (0, True),
                     "om_share_per_a": (0, False)},
    "hydrogen": {"invest_eur_per_kwh": (0, False), "life_a": (0, True), "om_share_per_a": (0, False)},
}
#: The sized components, in table order.
COMPONENTS = ("pv", "battery", "electrolyser", "fuel_cell", "hydrogen")


@dataclass(frozen=True)
class Costs:
    """The cost figures of ``config/costs.yaml`` (sources in its comments).

    Attributes
    ----------
    interest_rate : float
        Interest rate of the annuities, in [0, 1) [1/a].
    items : dict of str to dict of str to float
        Per component of :data:`COMPONENTS`, its figures keyed as in :data:`COST_KEYS`
        (units in the key names: ``invest_eur_per_kwp`` [EUR/kWp], ``life_a`` [a],
        ``life_h`` [h], ``om_share_per_a`` [1/a], ``om_eur_per_h`` [EUR/h], ``on_eur`` [EUR]...).
    """

    interest_rate: float
    items: dict[str, dict[str, float]]

    def __getitem__(self, component: str) -> dict[str, float]:
        """Return the figures of one component (``costs["fuel_cell"]["life_h"]``)."""
        return self.items[component]


def default_costs_file() -> Path:
    """Return the path of the default cost figures, ``config/costs.yaml``."""
    return config_dir() / "costs.yaml"


def load_costs(files: Sequence[str | Path] = ()) -> Costs:
    """Read the cost figures: ``config/costs.yaml`` with each of ``files`` merged over it.

    Parameters
    ----------
    files : sequence of str or pathlib.Path, optional
        Parameter files with a ``costs`` section, merged in order (only the keys a file
        gives replace the earlier ones).

    Returns
    -------
    Costs
        The merged figures, every key of :data:`COST_KEYS` present.

    Raises
    ------
    ConfigError
        Naming the file and the key: an unknown section or key, a value that is not a
        number or out of its range (costs >= 0, lives > 0, interest rate in [0, 1)).
    """
    merged: dict[str, Any] = {}
    for path in [default_costs_file(), *files]:
        data = read_param_section(path, "costs")
        for key, value in data.items():
            if key == "interest_rate":
                merged[key] = _number(path, "costs.interest_rate", value, 0.0, False)
                if merged[key] >= 1.0:
                    raise ConfigError(f"{path}: costs.interest_rate {value} must be below 1 (a fraction per year)")
                continue
            if key not in COST_KEYS:
                raise ConfigError(f"{path}: unknown section costs.{key} (known: interest_rate, "
                                  f"{', '.join(COST_KEYS)})")
            if not isinstance(value, Mapping):
                raise ConfigError(f"{path}: costs.{key} must be a mapping")
            section = merged.setdefault(key, {})
            for k, v in value.items():
                if k not in COST_KEYS[key]:
                    raise ConfigError(f"{path}: unknown key costs.{key}.{k} (known: {', '.join(COST_KEYS[key])})")
                lo, lo_open = COST_KEYS[key][k]
                section[k] = _number(path, f"costs.{key}.{k}", v, lo, lo_open)
    missing = [f"costs.{s}.{k}" for s, keys in COST_KEYS.items() for k in keys if k not in merged.get(s, {})]
    if "interest_rate" not in merged:
        missing.insert(0, "costs.interest_rate")
    if missing:
        raise ConfigError(f"{default_costs_file()}: missing {', '.join(missing)}")
    return Costs(interest_rate=merged["interest_rate"], items={s: merged[s] for s in COST_KEYS})


def _number(path: str | Path, name: str, value: Any, lo: float, lo_open: bool) -> float:
    """Return ``value`` as a float, or raise ConfigError if not finite or below ``lo``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{path}: {name} = {value!r} is not a finite number")
    if value < lo or (lo_open and value == lo):
        raise ConfigError(f"{path}: {name} = {value} must be {'>' if lo_open else '>='} {lo}")
    return float(value)


def crf(rate: float, years: float) -> float:
    """Capital recovery factor: the annuity of 1 EUR over ``years`` at ``rate``.

    ``CRF = r (1+r)^n / ((1+r)^n - 1)``, and ``1/n`` at ``r = 0``.

    Parameters
    ----------
    rate : float
        Interest rate r [1/a].
    years : float
        Life n, > 0 [a].

    Returns
    -------
    float
        Capital recovery factor [1/a].

    Raises
    ------
    ValueError
        If ``years`` is not positive.
    """
    if years <= 0:
        raise ValueError(f"life {years} a must be > 0")
    if rate == 0:
        return 1.0 / years
    q = (1.0 + rate) ** years
    return rate * q / (q - 1.0)


def investments(sizes: Mapping[str, float], costs: Costs) -> dict[str, float]:
    """Return the investment of each component: its size times its specific cost.

    Parameters
    ----------
    sizes : mapping of str to float
        ``pv_kwp`` [kWp], ``battery_kwh`` [kWh], ``el_modules`` [-], ``fc_kw`` [kW] and
        ``h2_kwh`` [kWh, LHV].
    costs : Costs
        Cost figures (:func:`load_costs`).

    Returns
    -------
    dict of str to float
        Component of :data:`COMPONENTS` -> investment [EUR].
    """
    return {
        "pv": sizes["pv_kwp"] * costs["pv"]["invest_eur_per_kwp"],
        "battery": sizes["battery_kwh"] * costs["battery"]["invest_eur_per_kwh"],
        "electrolyser": sizes["el_modules"] * costs["electrolyser"]["invest_eur_per_module"],
        "fuel_cell": sizes["fc_kw"] * costs["fuel_cell"]["invest_eur_per_kw"],
        "hydrogen": sizes["h2_kwh"] * costs["hydrogen"]["invest_eur_per_kwh"],
    }


def battery_cycles(summary: Mapping[str, Any], usable_kwh: float) -> float:
    """Return the battery's equivalent full cycles in a run: energy charged over usable capacity.

    Parameters
    ----------
    summary : mapping
        The run's summary with ``bess_charged_kwh_total`` [kWh].
    usable_kwh : float
        Usable capacity ``E_max * (SOC_max - SOC_min)`` [kWh].

    Returns
    -------
    float
        Equivalent full cycles [-]; 0 for a battery without usable capacity.
    """
    return float(summary["bess_charged_kwh_total"]) / usable_kwh if usable_kwh > 0 else 0.0


def annual_costs(sizes: Mapping[str, float], summary: Mapping[str, Any], costs: Costs,
                 usable_battery_kwh: float) -> dict[str, float]:
    """Annual costs [EUR/a] and wear figures of one sized run.

    Figures of the run are scaled to :data:`WEEKS_PER_YEAR`; each component's life is the
    shorter of its calendar life and its wear life (``tab:degradation_HESS``).

    Parameters
    ----------
    sizes : mapping of str to float
        ``pv_kwp`` [kWp], ``battery_kwh`` [kWh], ``el_modules`` [-], ``fc_kw`` [kW],
        ``h2_kwh`` [kWh].
    summary : mapping
        The run's ``summary.json`` (a year-round run): ``cost_net_eur`` [EUR],
        ``fc_working_hours`` [h], ``fc_toggles`` [-], ``el_working_hours`` [h] (optional),
        ``bess_charged_kwh_total`` [kWh], ``weeks`` [-].
    costs : Costs
        Cost figures (:func:`load_costs`).
    usable_battery_kwh : float
        ``E_max * (SOC_max - SOC_min)`` [kWh].

    Returns
    -------
    dict of str to float
        ``energy_eur_a`` (bought - sold per 52 weeks), ``annuity_eur_a``, ``om_eur_a``,
        ``total_eur_a`` [EUR/a]; ``invest_eur`` [EUR]; per component ``life_<c>_a`` (the
        life used) [a]; and the wear per year: ``fc_hours_a`` [h/a], ``fc_toggles_a`` [1/a],
        ``el_hours_a`` [h/a], ``battery_cycles_a`` [1/a].
    """
    scale = WEEKS_PER_YEAR / float(summary["weeks"])
    fc_h = float(summary["fc_working_hours"]) * scale
    fc_on = float(summary["fc_toggles"]) * scale
    el_h = float(summary.get("el_working_hours", 0.0)) * scale
    cycles = battery_cycles(summary, usable_battery_kwh) * scale
    inv = investments(sizes, costs)

    def life(calendar: float, wear: float | None) -> float:
        return min(calendar, wear) if wear is not None else calendar

    lives = {
        "pv": costs["pv"]["life_a"],
        "battery": life(costs["battery"]["life_a"], costs["battery"]["n_cycles"] / cycles if cycles > 0 else None),
        "electrolyser": life(costs["electrolyser"]["life_a"],
                             costs["electrolyser"]["life_h"] / el_h if el_h > 0 else None),
        "fuel_cell": life(costs["fuel_cell"]["life_a"], costs["fuel_cell"]["life_h"] / fc_h if fc_h > 0 else None),
        "hydrogen": costs["hydrogen"]["life_a"],
    }
    annuity = sum(inv[c] * crf(costs.interest_rate, lives[c]) for c in COMPONENTS)
    fc = costs["fuel_cell"]
    om = sum(inv[c] * costs[c]["om_share_per_a"] for c in ("pv", "battery", "electrolyser", "hydrogen"))
    om += fc_h * fc["om_eur_per_h"] + fc_on * (fc["on_eur"] + fc["off_eur"])
    energy = float(summary["cost_net_eur"]) * scale
    out = {"energy_eur_a": energy, "annuity_eur_a": annuity, "om_eur_a": om, "total_eur_a": energy + annuity + om,
           "invest_eur": sum(inv.values()), "fc_hours_a": fc_h, "fc_toggles_a": fc_on, "el_hours_a": el_h,
           "battery_cycles_a": cycles}
    out.update({f"life_{c}_a": lives[c] for c in COMPONENTS})
    return out


def cycle_closes(summary: Mapping[str, Any]) -> tuple[bool | None, str]:
    """Tell whether a run closes the seasonal H2 cycle, and why (or why not).

    The cycle closes when all four hold: the summer filled the store (LOH at the heating
    season's start above LOH at the run's start; not tested when the run starts inside the
    season), the store ends the run with at least the LOH it started with (``loh_end >=
    loh_init``: the year gives back the hydrogen it was given), it never ran dry
    (``h2_empty_at`` is None: LOH never reached LOH_min), and the heating season was served
    (no heating-season week with discomfort, ``eq:discomfort``). ``None`` when the run has no
    full heating-season week (a window outside it): then the cycle is not tested.

    Parameters
    ----------
    summary : mapping
        The run's ``summary.json``: ``heating_season_weeks``, ``loh_init``, ``loh_end`` and
        ``loh_heating_season_start`` [-] (LOH as fractions), ``h2_empty_at`` (a time or
        None), ``heating_season_discomfort_weeks``.

    Returns
    -------
    tuple of (bool or None, str)
        Whether the cycle closes (None: not tested), and ``"closes"`` or the reasons it does
        not, joined by ``"; "``.
    """
    if not int(summary.get("heating_season_weeks") or 0):
        return None, "the run has no full heating-season week"
    why = []
    start = summary.get("loh_heating_season_start")
    if start is not None and float(start) <= float(summary["loh_init"]) + LOH_CLOSE_TOL:
        why.append(f"LOH at the heating season's start {float(start):.3f} not above the start's "
                   f"{float(summary['loh_init']):.3f} (the summer did not fill the store)")
    if float(summary["loh_end"]) < float(summary["loh_init"]) - LOH_CLOSE_TOL:
        why.append(f"LOH at the end {float(summary['loh_end']):.3f} < at the start {float(summary['loh_init']):.3f}")
    if summary.get("h2_empty_at"):
        why.append(f"store empty at {summary['h2_empty_at']}")
    if int(summary.get("heating_season_discomfort_weeks") or 0):
        why.append(f"{summary['heating_season_discomfort_weeks']} heating-season week(s) with discomfort")
    return (not why), ("; ".join(why) if why else "closes")
