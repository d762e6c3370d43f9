"""The in-process community run: the houses' EMS, the coordinator, the community plant, the KPIs.

One step ``k`` of :func:`simulate_community`:

1. the coordinator reads the hub and the houses at the end of ``k - 1``
   (:class:`~comems4build_ros.core.community.coordinator.CommunityView`) and publishes its
   allotment; the hub applies its transfers;
2. every house's EMS observes its house at its own information level through the house's
   :class:`~comems4build_ros.core.loop.ObservationBuilder`, as an isolated house's EMS does;
   where that EMS reads its own store's figures it reads the hub's: its account as ``loh``,
   the allotted ``dloh_per_day`` (``eq:deltaLOH``) and the hub's ``el_on_prev``;
3. the coordinator reads the houses' requests (their electrolyser offers, PV and load) and
   decides the hub's dispatch;
4. the community plant steps (:class:`~comems4build_ros.core.community.plant.CommunityPlant`).

Every house's timeseries has the columns of an isolated run (``record_row``: the command
columns hold what its EMS asked, the electrolyser request included) and its KPIs come from
the same code (:func:`~comems4build_ros.core.loop.evaluate_timeseries`), with ``hub_*``
columns added: the allotted ``dloh_per_day``, the H2 moved into its account at the step's
start and credited from the step's production, and its share of that production. The
hub's timeseries holds the hub, the connection point and the coordinator's time and
messages per step. :mod:`.kpi` evaluates the community.
"""

from __future__ import annotations

import json
import math
import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.community.coordinator import (
    CommunityInfo,
    CommunityView,
    Coordinator,
    HouseReport,
    HubReport,
    Request,
    make_coordinator,
)
from comems4build_ros.core.community.hub import HubFlows, HubState
from comems4build_ros.core.community.kpi import evaluate_community
from comems4build_ros.core.community.plant import CommunityPlant, ConnectionFlows
from comems4build_ros.core.community.spec import Community
from comems4build_ros.core.config import W_PER_KW
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import PRICE_WINDOW, Observation
from comems4build_ros.core.loop import (
    HOURS_PER_DAY,
    TIMESERIES_COLUMNS,
    ForecastParams,
    ObservationBuilder,
    RunResult,
    dloh_per_day,
    evaluate_timeseries,
    exogenous_series,
    load_forecast_settings,
    record_row,
    write_run,
)
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.scenario.comfort import heating_season_days
from comems4build_ros.core.types import Flows, PlantState
from comems4build_ros.files.outputs import atomic_dir

#: Columns a house's timeseries adds to an isolated run's.
HOUSE_HUB_COLUMNS = ("hub_dloh_per_day", "hub_transfer_wh", "hub_credited_wh", "hub_split")
#: The hub's flows, state and balance per step.
HUB_COLUMNS = ("p_el_set_w", "p_el_w", "el_on", "el_start", "modules_on", "p_h2_el_w", "q_el_rec_w", "p_h2_fc_w",
               "p_h2_loss_w", "h2_credited_wh", "h2_to_pool_wh", "transfer_wh", "clipped", "loh", "store_kwh",
               "pool_kwh", "accounts_kwh", "h2_residual_wh")
#: The connection point's flows per step (prefixed ``cp_`` in the hub's timeseries).
CONNECTION_COLUMNS = ("p_buy_w", "p_sell_w", "balance_residual_w", "p_pv_w", "p_load_w", "p_hp_el_w", "p_ch_w",
                      "p_dis_w", "p_fc_w", "p_el_w")
#: The coordinator's record per step (more ``coord_*`` columns from its ``step_info``).
COORDINATOR_COLUMNS = ("coord_allot_s", "coord_dispatch_s", "coord_messages")
#: Files of a community run directory (``houses/<name>/`` holds each house's run files).
COMMUNITY_FILES = ("hub.csv", "houses.csv", "community.json", "houses")


@dataclass
class CommunityResult:
    """Outputs of one community run.

    Attributes
    ----------
    houses : every house's run (timeseries, weekly KPIs, summary), by name
    hub : the hub's, the connection point's and the coordinator's timeseries
    table : one row per house: its KPIs and its settlement under every rule set
    summary : the community's KPIs (:func:`~comems4build_ros.core.community.kpi.community_kpis`)
    """

    houses: dict[str, RunResult]
    hub: pd.DataFrame
    table: pd.DataFrame
    summary: dict[str, Any] = field(default_factory=dict)


def _hub_report(plant: CommunityPlant, hub: HubState) -> HubReport:
    bank = plant.hub.bank
    return HubReport(plant.hub.e_wh, plant.hub.store_wh(hub), hub.pool_wh, hub.el_on, hub.modules_on, bank.n,
                     bank.p_module_min_w, bank.p_module_max_w)


def community_info(community: Community, plant: CommunityPlant) -> CommunityInfo:
    """Return the fixed figures a coordinator is built with."""
    bank = plant.hub.bank
    hub = community.hub
    dt_h = hub.dt_h
    el = ElectrolyserTable(hub.electrolyser.model_copy(update={"n_modules": 1}))
    return CommunityInfo(tuple(h.name for h in community.houses), community.shares_wh, dt_h,
                         int(round(HOURS_PER_DAY / dt_h)), plant.hub.e_wh, bank.n, bank.p_module_min_w,
                         bank.p_module_max_w, hub.loh_min, hub.loh_max, float(el.efficiency(1.0)),
                         tuple(h.plant_params for h in community.houses))


def simulate_community(
    community: Community,
    coordinator: str | Coordinator,
    ems: str,
    ems_options: Mapping[str, Any] | None = None,
    coordinator_options: Mapping[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    forecast: ForecastParams | None = None,
    sharing_file: str | Path | None = None,
    tariff_file: str | Path | None = None,
) -> CommunityResult:
    """Run a community in closed loop over its scenario (module docstring).

    Parameters
    ----------
    community : the built community (:func:`~comems4build_ros.core.community.spec.build_community`)
    coordinator : a coordinator's name (``config/coordinators.yaml``) or a coordinator object
    ems : the EMS of every house (``config/ems.yaml``)
    ems_options : options of every house's EMS
    coordinator_options : options merged over the coordinator's row (name only)
    progress : called as ``progress(steps done, total steps)`` after every step
    forecast : forecast settings of an MPC (default ``config/forecast.yaml``)
    sharing_file, tariff_file : the sharing rule sets and the tariff data (default: ``config/``)
    """
    t_start = _time.perf_counter()
    plant = CommunityPlant(community)
    info = community_info(community, plant)
    coord = make_coordinator(coordinator, info, coordinator_options) if isinstance(coordinator, str) else coordinator
    coord.reset()
    houses = community.houses
    ctrls = [make_controller(ems, h.params, ems_options) for h in houses]
    for c in ctrls:
        c.reset()
    forecast = forecast or load_forecast_settings()
    exos = [exogenous_series(h.scenario, h.plant_params) for h in houses]
    builders = [ObservationBuilder(h.scenario, h.params, c.info_level, e, forecast) for h, c, e in
                zip(houses, ctrls, exos)]
    coord_builders = ([ObservationBuilder(h.scenario, h.params, "mpc", e, forecast) for h, e in zip(houses, exos)]
                      if getattr(coord, "info_level", "hub") == "mpc" else [])
    public = _public_series(community)
    n_steps = community.scenario.n_steps
    time = community.scenario.time[:n_steps]
    times = [t.isoformat() for t in time]
    day = ((time - time[0]).total_seconds() / 3600.0 // HOURS_PER_DAY).astype(int).tolist()
    ghi = community.scenario.ghi_w_m2.tolist()
    spot = community.scenario.spot_eur_per_mwh.tolist()
    own_dloh = [dloh_per_day(h.params) for h in houses]
    floors = [h.params.hydrogen.loh_min * h.share_wh for h in houses]
    states, hub = plant.initial_state()
    prev: list[Flows] | None = None
    rows: list[list[list[Any]]] = [[] for _ in houses]
    extra_rows: list[list[tuple[float, ...]]] = [[] for _ in houses]
    infos: list[list[dict[str, float]]] = [[] for _ in houses]
    hub_rows: list[list[Any]] = []
    coord_infos: list[dict[str, float]] = []
    ems_s = coord_s = 0.0
    n = len(houses)
    for k in range(n_steps):
        observations = tuple(b.build(k, s) for b, s in zip(coord_builders, states))
        view = CommunityView(k, times[k], day[k], k == 0 or day[k] != day[k - 1], info.steps_per_day,
                             _hub_report(plant, hub), _house_reports(houses, states, floors, own_dloh, prev),
                             public["buy"][k], tuple(public["buy"][k:k + PRICE_WINDOW]), public["sell"][k],
                             public["to_season"][k], observations)
        t0 = _time.perf_counter()
        allot = coord.allot(view)
        coord_allot = _time.perf_counter() - t0
        _check_lengths(coord, "allotment", n, dloh_per_day=allot.dloh_per_day, transfers_wh=allot.transfers_wh)
        transfer = plant.begin_step(states, hub, allot.transfers_wh)
        actions = []
        t1 = _time.perf_counter()
        for i, (builder, ctrl) in enumerate(zip(builders, ctrls)):
            data = builder.data(k, states[i])
            if "dloh_per_day" in data:
                data["dloh_per_day"] = allot.dloh_per_day[i]
            if "el_on_prev" in data:
                data["el_on_prev"] = hub.el_on
            actions.append(ctrl.act(Observation(builder.level, data)))
            step_info = getattr(ctrl, "step_info", None)
            if step_info:
                infos[i].append(dict(step_info))
        ems_s += _time.perf_counter() - t1
        requests = tuple(Request(a.p_el_w, e[k].p_pv_w, e[k].p_load_w) for a, e in zip(actions, exos))
        t2 = _time.perf_counter()
        dispatch = coord.dispatch(view, requests)
        coord_dispatch = _time.perf_counter() - t2
        coord_s += coord_allot + coord_dispatch
        _check_lengths(coord, "dispatch", n, production_split=dispatch.production_split)
        out = plant.step(states, hub, actions, [e[k] for e in exos], dispatch.p_el_w, dispatch.production_split,
                         transfer)
        states, hub, prev = out.states, out.hub, out.flows
        for i in range(n):
            rows[i].append(record_row(times[k], k, out.flows[i], states[i], actions[i], exos[i][k], (ghi[k], spot[k]),
                                      False))
            extra_rows[i].append((allot.dloh_per_day[i], transfer[0][i], out.credited_wh[i],
                                  float(dispatch.production_split[i])))
        step_info = dict(getattr(coord, "step_info", None) or {})
        messages = step_info.pop("messages", 2 * n + 1)
        coord_infos.append(step_info)
        hub_rows.append([times[k], k, *_hub_values(plant, out.hub_flows, hub, states), *_cp_values(out.connection),
                         coord_allot, coord_dispatch, messages])
        if progress is not None:
            progress(k + 1, n_steps)
    results = {}
    for i, h in enumerate(houses):
        ts = pd.DataFrame(rows[i], columns=list(TIMESERIES_COLUMNS))
        if infos[i] and len(infos[i]) == len(ts):
            ts = pd.concat([ts, pd.DataFrame(infos[i]).add_prefix("ems_")], axis=1)
        ts = pd.concat([ts, pd.DataFrame(extra_rows[i], columns=list(HOUSE_HUB_COLUMNS))], axis=1)
        extra = {"ems": ctrls[i].name, "scenario": community.scenario.name, "house": h.name,
                 "community": community.name, "forecast": forecast.mode if ctrls[i].info_level == "mpc" else None}
        results[h.name] = evaluate_timeseries(ts, h.plant_params, extra)
    hub_ts = pd.DataFrame(hub_rows, columns=["time", "step", *HUB_COLUMNS,
                                             *(f"cp_{c}" for c in CONNECTION_COLUMNS), *COORDINATOR_COLUMNS])
    if coord_infos and any(coord_infos):
        hub_ts = pd.concat([hub_ts, pd.DataFrame(coord_infos).add_prefix("coord_")], axis=1)
    timing = {"wall_s": _time.perf_counter() - t_start, "ems_s": ems_s, "coordinator_s": coord_s}
    table, summary = evaluate_community(community, coord.name, ctrls[0].name, results, hub_ts, timing, sharing_file,
                                        tariff_file)
    return CommunityResult(results, hub_ts, table, summary)


def _public_series(community: Community) -> dict[str, list[float]]:
    """Return the community's public figures per step.

    These are the tariff (the buy prices padded by a day for the day-ahead window, as
    :class:`~comems4build_ros.core.loop.ObservationBuilder` pads them) and the days to the next
    heating season.
    """
    sc = community.scenario
    sim = community.houses[0].params.simulation
    buy = sc.price_buy_eur_per_kwh.tolist()
    to_season, _ = heating_season_days(sc.time, sim.heating_season_start, sim.heating_season_end)
    return {"buy": buy + [buy[-1]] * PRICE_WINDOW, "sell": sc.price_sell_eur_per_kwh.tolist(),
            "to_season": np.asarray(to_season, dtype=float).tolist()}


def _check_lengths(coord: Coordinator, what: str, n: int, **values: tuple[float, ...]) -> None:
    for name, v in values.items():
        if len(v) != n:
            raise ValueError(f"coordinator '{coord.name}': {what}.{name} has {len(v)} values for {n} houses")


def _house_reports(houses: Any, states: list[PlantState], floors: list[float], own_dloh: list[float],
                   prev: list[Flows] | None) -> tuple[HouseReport, ...]:
    out = []
    for i, (h, s) in enumerate(zip(houses, states)):
        f = prev[i] if prev is not None else None
        out.append(HouseReport(h.name, h.share_wh, s.loh * h.share_wh, floors[i], own_dloh[i],
                               f.p_buy_w if f else 0.0, f.p_sell_w if f else 0.0, f.p_h2_w if f else 0.0))
    return tuple(out)


def _hub_values(plant: CommunityPlant, f: HubFlows, hub: HubState, states: list[PlantState]) -> list[Any]:
    accounts = math.fsum(plant.hub.accounts_wh(states))
    return [f.p_el_set_w, f.p_el_w, f.el_on, f.el_start, f.modules_on, f.p_h2_el_w, f.q_el_rec_w, f.p_h2_fc_w,
            f.p_h2_loss_w, f.h2_credited_wh, f.h2_to_pool_wh, f.transfer_wh, f.clipped, hub.loh,
            plant.hub.store_wh(hub) / W_PER_KW, hub.pool_wh / W_PER_KW, accounts / W_PER_KW,
            plant.hub.balance_residual_wh(states, hub)]


def _cp_values(c: ConnectionFlows) -> list[float]:
    return [getattr(c, name) for name in CONNECTION_COLUMNS]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_community(result: CommunityResult, out_dir: str | Path, timeseries: bool = True) -> Path:
    """Write a community run into ``out_dir``, all or nothing (:func:`~comems4build_ros.files.outputs.atomic_dir`).

    ``houses/<name>/`` holds each house's run files, then ``hub.csv``, ``houses.csv`` and
    ``community.json``; ``timeseries=False`` leaves out the houses' and the hub's timeseries.
    """
    out = Path(out_dir)
    clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in result.summary.items()}
    with atomic_dir(out, replaces=COMMUNITY_FILES) as tmp:
        for name, run in result.houses.items():
            write_run(run, tmp / "houses" / name, timeseries=timeseries)
        if timeseries:
            result.hub.to_csv(tmp / "hub.csv", index=False)
        result.table.to_csv(tmp / "houses.csv", index=True, index_label="house")
        (tmp / "community.json").write_text(json.dumps(clean, indent=2, default=_json_default) + "\n",
                                            encoding="utf-8")
    return out
