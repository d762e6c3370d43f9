"""The in-process community run: the houses' EMS, the coordinator, the community plant, the KPIs.

One step ``k`` of :func:`simulate_community`:

1. the coordinator reads the hub and the houses at the end of ``k - 1``
   (:class:`~comems4build_ros.core.community.coordinator.CommunityView`) and publishes its
   allotment; the hub applies its transfers (:meth:`~comems4build_ros.core.community.hubrun.HubRun.allot`);
2. every house's EMS observes its house at its own information level through the house's
   :class:`~comems4build_ros.core.loop.ObservationBuilder`, as an isolated house's EMS does;
   where that EMS reads its own store's figures it reads the hub's: its account as ``loh``,
   the allotted ``dloh_per_day`` (``eq:deltaLOH``) and the hub's ``el_on_prev``;
3. every house's plant steps (:meth:`~comems4build_ros.core.community.plant.CommunityPlant.houses_step`);
4. the coordinator reads the houses' requests (their electrolyser offers, PV and load) and
   decides the hub's dispatch; the hub steps and the connection point exchanges the net of
   the houses and the hub (:meth:`~comems4build_ros.core.community.hubrun.HubRun.settle`).
   A house's plant does not depend on the dispatch, so deciding it after the houses'
   plants stepped is the same as before; the coordinator node over ROS 2 does the same
   (:mod:`.hubrun`).

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

from comems4build_ros.core.community.coordinator import Coordinator, Request
from comems4build_ros.core.community.hubrun import HubRun
from comems4build_ros.core.community.kpi import evaluate_community
from comems4build_ros.core.community.plant import CommunityPlant
from comems4build_ros.core.community.spec import Community
from comems4build_ros.core.ems import make_controller
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.loop import (
    TIMESERIES_COLUMNS,
    ForecastParams,
    ObservationBuilder,
    RunResult,
    evaluate_timeseries,
    exogenous_series,
    load_forecast_settings,
    record_row,
    write_run,
)
from comems4build_ros.files.outputs import atomic_dir

#: Columns a house's timeseries adds to an isolated run's.
HOUSE_HUB_COLUMNS = ("hub_dloh_per_day", "hub_transfer_wh", "hub_credited_wh", "hub_split")
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
    hub = HubRun(community, coordinator, coordinator_options, plant.hub)
    houses = community.houses
    ctrls = [make_controller(ems, h.params, ems_options) for h in houses]
    for c in ctrls:
        c.reset()
    forecast = forecast or load_forecast_settings()
    exos = [exogenous_series(h.scenario, h.plant_params) for h in houses]
    builders = [ObservationBuilder(h.scenario, h.params, c.info_level, e, forecast) for h, c, e in
                zip(houses, ctrls, exos)]
    coord_builders = ([ObservationBuilder(h.scenario, h.params, "mpc", e, forecast) for h, e in zip(houses, exos)]
                      if hub.info_level == "mpc" else [])
    n_steps = hub.n_steps
    times = hub.times
    ghi = community.scenario.ghi_w_m2.tolist()
    spot = community.scenario.spot_eur_per_mwh.tolist()
    states = plant.initial_states()
    hub.start(states)
    rows: list[list[list[Any]]] = [[] for _ in houses]
    extra_rows: list[list[tuple[float, ...]]] = [[] for _ in houses]
    infos: list[list[dict[str, float]]] = [[] for _ in houses]
    ems_s = 0.0
    n = len(houses)
    for k in range(n_steps):
        allot = hub.allot(k, states, observations=tuple(b.build(k, s) for b, s in zip(coord_builders, states)))
        actions = []
        t1 = _time.perf_counter()
        for i, (builder, ctrl) in enumerate(zip(builders, ctrls)):
            data = builder.data(k, states[i])
            if "dloh_per_day" in data:
                data["dloh_per_day"] = allot.dloh_per_day[i]
            if "el_on_prev" in data:
                data["el_on_prev"] = allot.el_on_prev
            actions.append(ctrl.act(Observation(builder.level, data)))
            step_info = getattr(ctrl, "step_info", None)
            if step_info:
                infos[i].append(dict(step_info))
        ems_s += _time.perf_counter() - t1
        requests = [Request(a.p_el_w, e[k].p_pv_w, e[k].p_load_w) for a, e in zip(actions, exos)]
        states, flows = plant.houses_step(states, actions, [e[k] for e in exos])
        settled = hub.settle(k, states, flows, requests)
        for i in range(n):
            rows[i].append(record_row(times[k], k, flows[i], states[i], actions[i], exos[i][k], (ghi[k], spot[k]),
                                      False))
            extra_rows[i].append((allot.dloh_per_day[i], allot.moved_wh[i], settled.credited_wh[i],
                                  float(settled.split[i])))
        if progress is not None:
            progress(k + 1, n_steps)
    results = {}
    for i, h in enumerate(houses):
        ts = pd.DataFrame(rows[i], columns=list(TIMESERIES_COLUMNS))
        if infos[i] and len(infos[i]) == len(ts):
            ts = pd.concat([ts, pd.DataFrame(infos[i]).add_prefix("ems_")], axis=1)
        ts = pd.concat([ts, pd.DataFrame(extra_rows[i], columns=list(HOUSE_HUB_COLUMNS))], axis=1)
        results[h.name] = evaluate_timeseries(ts, h.plant_params, house_extra(community, h.name, ctrls[i].name,
                                                                             ctrls[i].info_level, forecast))
    hub_ts = hub.timeseries()
    timing = {"wall_s": _time.perf_counter() - t_start, "ems_s": ems_s, "coordinator_s": hub.coordinator_s}
    table, summary = evaluate_community(community, hub.coord.name, ctrls[0].name, results, hub_ts, timing,
                                        sharing_file, tariff_file)
    return CommunityResult(results, hub_ts, table, summary)


def house_extra(community: Community, house: str, ems: str, info_level: str,
                forecast: ForecastParams | None) -> dict[str, Any]:
    """Return the summary entries of a community's house besides its KPIs.

    These are its EMS, scenario, house, community and, for an EMS of information level
    ``mpc``, the forecast mode.
    """
    mode = (forecast or load_forecast_settings()).mode if info_level == "mpc" else None
    return {"ems": ems, "scenario": community.scenario.name, "house": house, "community": community.name,
            "forecast": mode}


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
