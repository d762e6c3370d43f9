"""The community's KPIs, composed of the houses' (:mod:`comems4build_ros.core.kpi`) and the hub's records.

Per house: the paper's KPIs of its own run (``sec:evaluation_metrics``, comfort first) from
:func:`~comems4build_ros.core.loop.evaluate_timeseries`, and its settlement under every
sharing rule set (:mod:`.sharing`). For the community (:func:`community_kpis`):

- cost: at the connection point (its grid exchange at the buy and sell prices) and, per
  rule set, the community's cost and its mean per household, the energy shared inside and
  the charges it bore;
- self-sufficiency: 1 - the connection point's purchase / (the houses' appliances and heat
  pumps and the hub's electrolysers);
- peaks: the connection point's largest import and export, beside the sum of the houses'
  own peaks (what the community's diversity saves);
- hydrogen: produced, used by the fuel cells, lost, the hub's LOH (start, lowest, highest,
  end, at the heating season's start; over time in the hub's timeseries), the pool at the end,
  the electrolysers' intake, working hours and starts;
- balances: the largest H2 residual (store - accounts - pool) over the run's H2 throughput
  and the largest electricity residual at the connection point;
- the coordinator: messages (per step and in total) and its time per decision (allotment
  and dispatch of one step).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.community.sharing import Settlement, charge_parts, load_sharing_rules, settle
from comems4build_ros.core.community.spec import Community
from comems4build_ros.core.config import W_PER_KW
from comems4build_ros.core.kpi import DISCOMFORT_TOL_KH, at_resolution, cost_eur, loh_heating_season_start
from comems4build_ros.core.loop import RunResult

#: The per-house KPIs of the houses' table, from each house's summary.
HOUSE_KPIS = ("discomfort_kh_total", "cost_eur_total", "reimbursement_eur_total", "buy_kwh_total", "sell_kwh_total",
              "h2_kwh_total", "fc_working_hours", "fc_toggles", "loh_end", "dhw_unmet_kwh")


def _kwh(power_w: np.ndarray, dt_h: float) -> float:
    return float(np.sum(power_w) * dt_h / W_PER_KW)


def hub_attribution(houses: dict[str, RunResult], shares_wh: tuple[float, ...]) -> np.ndarray:
    """Every house's part of the hub's intake per step: its production share, normalised (nominal share without one)."""
    split = np.vstack([r.timeseries["hub_split"].to_numpy(float) for r in houses.values()])
    total = split.sum(axis=0)
    nominal = np.asarray(shares_wh, float) / float(np.sum(shares_wh))
    return np.where(total > 0, split / np.where(total > 0, total, 1.0), nominal[:, None])


def settle_meters(time: pd.Series, timezone: str, buy_w: np.ndarray, sell_w: np.ndarray, hub_w: np.ndarray,
                  attribution: np.ndarray, price_buy: np.ndarray, price_sell: np.ndarray, dt_h: float,
                  names: list[str], sharing_file: str | Path | None = None,
                  tariff_file: str | Path | None = None) -> dict[str, Settlement]:
    """Members' meters settled under every rule set of ``config/sharing.yaml`` (:func:`.sharing.settle`).

    Parameters
    ----------
    time : ISO time of every step
    timezone : the site's time zone (the calendar year of the charges)
    buy_w, sell_w : every house's purchase and sale at its meter, shape (houses, steps) [W]
    hub_w : the hub's intake per step [W] (zeros for houses without a hub)
    attribution : every house's part of the hub's intake, shape (houses, steps) [-]
    price_buy, price_sell : the tariff per step [EUR/kWh]
    dt_h : step [h]
    names : the houses' names
    sharing_file, tariff_file : the rule sets and the tariff data (default: ``config/``)
    """
    times = pd.to_datetime(pd.Series(time).astype(str), utc=True)
    parts = charge_parts(pd.DatetimeIndex(times), timezone, tariff_file)
    rules = load_sharing_rules(sharing_file)
    return {name: settle(name, rule, buy_w, sell_w, hub_w, attribution, price_buy, price_sell, parts, dt_h, names)
            for name, rule in rules.rule_sets.items()}


def settlements(community: Community, houses: dict[str, RunResult], hub: pd.DataFrame,
                sharing_file: str | Path | None = None, tariff_file: str | Path | None = None) -> dict[str, Settlement]:
    """Return the run settled under every rule set of ``config/sharing.yaml``."""
    first = next(iter(houses.values())).timeseries
    buy = np.vstack([r.timeseries["p_buy_w"].to_numpy(float) for r in houses.values()])
    sell = np.vstack([r.timeseries["p_sell_w"].to_numpy(float) for r in houses.values()])
    return settle_meters(first["time"], community.houses[0].params.site.timezone, buy, sell,
                         hub["p_el_w"].to_numpy(float), hub_attribution(houses, community.shares_wh),
                         first["price_buy_eur_per_kwh"].to_numpy(float),
                         first["price_sell_eur_per_kwh"].to_numpy(float), community.hub.dt_h, list(houses),
                         sharing_file, tariff_file)


def household_self_sufficiency(settlement: Settlement, consumption_kwh: pd.Series) -> pd.Series:
    """Every household's self-sufficiency under one rule set's settlement [-].

    1 - what it takes from the grid (its meter's purchase not covered by shared energy, and its
    part of what the hub took from the grid) / what it uses (``consumption_kwh``: its
    appliances, heat pump and any electrolyser behind its own meter, plus its part of the hub's
    intake). Under a rule set that shares nothing every member buys at its own meter; under
    one that shares, the households' grid purchases add up to the connection point's.
    """
    h = settlement.houses
    use = consumption_kwh.reindex(h.index).astype(float) + h["hub_kwh"]
    grid = h["grid_buy_kwh"] + h["hub_grid_kwh"]
    return (1.0 - grid / use.where(use > 0, 1.0)).where(use > 0, 0.0)


def community_kpis(community: Community, houses: dict[str, RunResult], hub: pd.DataFrame,
                   settled: dict[str, Settlement]) -> dict[str, Any]:
    """Return the community's KPIs (module docstring), rounded as the houses' are.

    :func:`~comems4build_ros.core.kpi.at_resolution` rounds them; the balance figures stay
    unrounded (their size is the point).
    """
    dt_h = community.hub.dt_h
    first = next(iter(houses.values())).timeseries
    price_buy = first["price_buy_eur_per_kwh"].to_numpy(float)
    price_sell = first["price_sell_eur_per_kwh"].to_numpy(float)
    cp_buy, cp_sell = hub["cp_p_buy_w"].to_numpy(float), hub["cp_p_sell_w"].to_numpy(float)
    consumption = _kwh(hub["cp_p_load_w"].to_numpy(float) + hub["cp_p_hp_el_w"].to_numpy(float)
                       + hub["cp_p_el_w"].to_numpy(float), dt_h)
    peaks_in = [float(r.timeseries["p_buy_w"].max()) for r in houses.values()]
    peaks_out = [float(r.timeseries["p_sell_w"].max()) for r in houses.values()]
    produced = _kwh(hub["p_h2_el_w"].to_numpy(float), dt_h)
    used = _kwh(hub["p_h2_fc_w"].to_numpy(float), dt_h)
    lost = _kwh(hub["p_h2_loss_w"].to_numpy(float), dt_h)
    loh = hub["loh"].to_numpy(float)
    sim = community.houses[0].params.simulation
    hub_loh_init = sum(h.share_wh * h.params.simulation.loh_init for h in community.houses) / community.hub.e_max_wh
    throughput = hub_loh_init * community.hub.e_max_wh / W_PER_KW + produced + used + lost
    residual = float(np.max(np.abs(hub["h2_residual_wh"].to_numpy(float)))) / W_PER_KW
    el_on = hub["el_on"].to_numpy(float) > 0.5
    step_s = hub["coord_allot_s"].to_numpy(float) + hub["coord_dispatch_s"].to_numpy(float)
    messages = hub["coord_messages"].to_numpy(float)
    discomfort = [float(r.summary["discomfort_kh_total"]) for r in houses.values()]
    n = len(houses)
    out: dict[str, Any] = {
        "houses": n,
        "steps": int(len(hub)),
        "cost_cp_eur": cost_eur(price_buy, cp_buy, dt_h) - cost_eur(price_sell, cp_sell, dt_h),
        "self_sufficiency": 1.0 - _kwh(cp_buy, dt_h) / consumption if consumption > 0 else 0.0,
        "grid_buy_kwh": _kwh(cp_buy, dt_h),
        "grid_sell_kwh": _kwh(cp_sell, dt_h),
        "houses_buy_kwh": float(sum(float(r.summary["buy_kwh_total"]) for r in houses.values())),
        "houses_sell_kwh": float(sum(float(r.summary["sell_kwh_total"]) for r in houses.values())),
        "peak_import_w": float(np.max(cp_buy)),
        "peak_export_w": float(np.max(cp_sell)),
        "peak_import_houses_sum_w": float(sum(peaks_in)),
        "peak_export_houses_sum_w": float(sum(peaks_out)),
        "peak_import_house_max_w": float(max(peaks_in)),
        "h2_produced_kwh": produced,
        "h2_used_kwh": used,
        "h2_lost_kwh": lost,
        "h2_pool_end_kwh": float(hub["pool_kwh"].iloc[-1]),
        "el_input_kwh": _kwh(hub["p_el_w"].to_numpy(float), dt_h),
        "el_working_hours": float(np.count_nonzero(el_on) * dt_h),
        "el_module_hours": float(hub["modules_on"].to_numpy(float).sum() * dt_h),
        "el_starts": int(np.count_nonzero(hub["el_start"].to_numpy(float) > 0.5)),
        "hub_e_max_kwh": community.hub.e_max_wh / W_PER_KW,
        "hub_modules": int(community.hub.electrolyser.n_modules),
        "hub_loh_init": hub_loh_init,
        "hub_loh_min": float(np.min(loh)),
        "hub_loh_max": float(np.max(loh)),
        "hub_loh_end": float(loh[-1]),
        "hub_loh_heating_season_start": loh_heating_season_start(hub, sim.heating_season_start, sim.heating_season_end),
        "h2_balance_max_rel": residual / throughput if throughput > 0 else 0.0,
        "electricity_balance_max_w": float(np.max(np.abs(hub["cp_balance_residual_w"].to_numpy(float)))),
        "discomfort_kh_total": float(sum(discomfort)),
        "discomfort_kh_house_max": float(max(discomfort)),
        "houses_with_discomfort": int(sum(d > DISCOMFORT_TOL_KH for d in discomfort)),
        "coordinator_messages_total": int(messages.sum()),
        "coordinator_messages_per_step": float(messages.mean()),
        "coordinator_s_per_decision_mean": float(step_s.mean()),
        "coordinator_s_per_decision_max": float(step_s.max()),
    }
    if "coord_iterations" in hub:
        out["coordinator_iterations_mean"] = float(hub["coord_iterations"].mean())
    for name, s in settled.items():
        for key in ("cost_eur", "cost_eur_per_household", "shared_kwh", "charges_on_shared_eur", "hub_cost_eur"):
            out[f"{key}_{name}"] = s.totals[key]
    return {k: (at_resolution(k, v) if k not in ("h2_balance_max_rel", "electricity_balance_max_w") else v)
            for k, v in out.items()}


def house_table(houses: dict[str, RunResult], settled: dict[str, Settlement], dt_h: float) -> pd.DataFrame:
    """Tabulate the houses' figures, one row per house.

    Parameters
    ----------
    houses : dict[str, RunResult]
        Every house's run, by name.
    settled : dict[str, Settlement]
        The settlement of every rule set, by name.
    dt_h : float
        Step [h].

    Returns
    -------
    pandas.DataFrame
        Per house its KPIs (:data:`HOUSE_KPIS`), its peaks [W], the H2 it received [kWh], the
        electricity its appliances and heat pump used (``consumption_kwh``), and per rule set
        its settlement, its part of the hub's intake and its self-sufficiency
        (:func:`household_self_sufficiency`).
    """
    rows = {}
    for name, r in houses.items():
        ts = r.timeseries
        row = {k: r.summary.get(k) for k in HOUSE_KPIS}
        row["peak_import_w"] = float(ts["p_buy_w"].max())
        row["peak_export_w"] = float(ts["p_sell_w"].max())
        row["h2_received_kwh"] = float((ts["hub_credited_wh"].sum() + ts["hub_transfer_wh"].sum()) / W_PER_KW)
        row["el_offered_kwh"] = float(ts["cmd_p_el_w"].clip(lower=0).sum() / W_PER_KW)
        row["consumption_kwh"] = float((ts["p_load_w"].sum() + ts["p_hp_el_w"].sum()) * dt_h / W_PER_KW)
        rows[name] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    for rule, s in settled.items():
        for col in ("cost_eur", "shared_in_kwh", "shared_out_kwh", "hub_cost_eur", "hub_kwh"):
            table[f"{col}_{rule}"] = s.houses[col].astype(float)
        table[f"self_sufficiency_{rule}"] = household_self_sufficiency(s, table["consumption_kwh"])
    return table


def evaluate_community(community: Community, coordinator: str, ems: str, houses: dict[str, RunResult],
                       hub: pd.DataFrame, timing: dict[str, float], sharing_file: str | Path | None = None,
                       tariff_file: str | Path | None = None) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Return the houses' table and the community's summary.

    See :func:`house_table` and :func:`community_kpis` (the run's facts).
    """
    settled = settlements(community, houses, hub, sharing_file, tariff_file)
    summary: dict[str, Any] = {"community": community.name, "community_file": community.source,
                               "coordinator": coordinator, "ems": ems, "scenario": community.scenario.name,
                               "start": str(community.scenario.time[0].isoformat())}
    summary.update(community_kpis(community, houses, hub, settled))
    summary["rule_sets"] = {name: load_sharing_rules(sharing_file).rule_sets[name].label for name in settled}
    summary.update(timing)
    return house_table(houses, settled, community.hub.dt_h), summary
