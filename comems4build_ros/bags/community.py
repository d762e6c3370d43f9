"""A community's run over ROS 2 read back from its bags: every house's and the coordinator's, composed.

A community launch (docs/community.md "Over ROS") writes one bag per house (``bag/<house>/``:
its plant, feed, EMS and the coordinator's messages to it) and the coordinator's bag
(``bag/coordinator/``: ``hub/record``, ``coordinator/info``, ``hub/events``), whose
``run_info.json`` names the community file, the run's plant file, the scenario window and the
coordinator. :func:`evaluate_community_bags` rebuilds the run as the in-process loop has it
(:class:`~comems4build_ros.core.community.loop.CommunityResult`): each house's timeseries from its
bag (:func:`~comems4build_ros.bags.evaluation.read_runs`, its ``hub_*`` columns included) and
its KPIs with its own plant parameters, the hub's timeseries from ``hub/record`` and the
coordinator's ``step_info``, and the community's KPIs with the same code as in-process
(:func:`~comems4build_ros.core.community.kpi.evaluate_community`); it writes the run directory of
``compare --community`` (``houses/<name>/``, ``hub.csv``, ``houses.csv``, ``community.json``).

A house that left a run on the wall clock (``house_left`` on ``hub/events``) has fewer steps
than the community: its KPIs cover its own steps, and for the community's figures its meter
and production share count as zero from the step it left (the hub froze its account);
``community.json`` names it under ``houses_left`` with that step and its steps recorded.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from comems4build_ros.bags.bag import BagInfo, decode, iter_messages
from comems4build_ros.bags.evaluation import (
    read_bag_set,
    read_run_info,
    summary_extra,
)
from comems4build_ros.files.inputs import load_json_text

#: The coordinator's bag under a community run's bag directory (and so a name no house may have).
COORDINATOR_BAG = "coordinator"
#: The coordinator's topics in its bag (relative to its namespace).
RECORD = "hub/record"
INFO = "coordinator/info"
EVENTS = "hub/events"
#: Kind of the ``hub/events`` line of a house that left a wall-clock run.
HOUSE_LEFT = "house_left"


class CommunityBagError(ValueError):
    """A community's bags that cannot be evaluated (names the bag and what is missing)."""


def is_community_bag(path: str | Path) -> bool:
    """Whether ``path`` holds a community's bags (a coordinator's bag with its ``run_info.json``)."""
    return bool(_coordinator_info(Path(path)))


def _coordinator_info(path: Path) -> dict[str, Any]:
    info_dir = path / COORDINATOR_BAG
    if not (info_dir / "run_info.json").is_file():
        return {}
    info = read_run_info(info_dir)
    return info if isinstance(info.get("community"), dict) else {}


def read_coordinator_bag(path: str | Path, timezone: str) -> tuple[Any, list[str], dict[str, float]]:
    """The hub's timeseries of a coordinator's bag (``hub/record`` rows in step order, the
    coordinator's ``step_info`` as ``coord_<key>`` columns), its ``hub/events`` lines and its
    final statistics (the ``stats`` line).

    Raises
    ------
    CommunityBagError
        For a bag without ``hub/record`` or with a step missing in the middle.
    """
    import pandas as pd

    from comems4build_ros.bags.evaluation import parse_stats
    from comems4build_ros.core.community.hubrun import HUB_TIMESERIES_COLUMNS
    from comems4build_ros.wire.contract import load_contract

    layout = load_contract().topic(RECORD).layout({})
    rows: dict[int, dict[str, Any]] = {}
    infos: dict[int, dict[str, float]] = {}
    events: list[str] = []
    stats: dict[str, float] = {}
    info = BagInfo(Path(path), [], False)
    for topic, msgtype, _t, raw in iter_messages(path, info=info):
        if topic.endswith("/" + RECORD):
            row = layout.unpack(decode(msgtype, raw).data)
            rows.setdefault(int(row["step"]), row)
        elif topic.endswith("/" + INFO):
            msg = load_json_text(decode(msgtype, raw).data, f"bag {path}: topic '{topic}'")
            infos[int(msg["step"])] = {k: float(v) for k, v in msg["info"].items()}
        elif topic.endswith("/" + EVENTS):
            line = str(decode(msgtype, raw).data)
            events.append(line)
            parts = line.split(None, 2)
            if len(parts) > 1 and parts[1] == "stats":
                stats = parse_stats(parts[2] if len(parts) > 2 else "")
    if not rows:
        raise CommunityBagError(f"bag {path}: no '{RECORD}' messages (the coordinator's record of the hub)")
    steps = sorted(rows)
    if steps != list(range(len(steps))):
        missing = sorted(set(range(steps[-1] + 1)) - set(steps))
        raise CommunityBagError(f"bag {path}: topic '{RECORD}': steps missing in the middle of the run: {missing[:10]}")
    times = pd.to_datetime([rows[k]["time_unix_s"] for k in steps], unit="s", utc=True).tz_convert(timezone)
    data = {c: [rows[k][c] for k in steps] for c in HUB_TIMESERIES_COLUMNS if c not in ("time", "step")}
    hub = pd.DataFrame({"time": [t.isoformat() for t in times], "step": steps, **data})
    if infos and all(k in infos for k in steps) and any(infos[k] for k in steps):
        hub = pd.concat([hub, pd.DataFrame([infos[k] for k in steps]).add_prefix("coord_")], axis=1)
    return hub, events, stats


def houses_left(events: list[str], names: list[str]) -> dict[str, int]:
    """House name -> the step from which it was left out (``house_left`` lines of ``hub/events``)."""
    out: dict[str, int] = {}
    for line in events:
        parts = line.split(None, 2)
        if len(parts) < 3 or parts[1] != HOUSE_LEFT:
            continue
        for name in names:
            if parts[2].startswith(f"house '{name}' "):
                out.setdefault(name, int(parts[0]))
    return out


def load_community_run(info: dict[str, Any]) -> Any:
    """The community of a run as its nodes built it, from the coordinator's ``run_info.json``
    (the community file and the plant file in the run's ``params/``, the scenario window)."""
    from comems4build_ros.core.community.spec import community_of, load_community
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.scenario.run import load_scenario

    community = info["community"]
    files = [str(f) for f in info.get("config_files") or []]
    overrides = dict(info.get("overrides") or {})
    base = load_plant_params(files, overrides)
    w = community["window"]  # as the feeds and the coordinator loaded it
    scenario = load_scenario(str(w["scenario"]), base, w.get("start") or None, w.get("weeks") or None,
                             w.get("seed"), w.get("steps") or None)
    spec = load_community(community["file"])
    return community_of(spec, files, overrides, base, scenario, str(community.get("source") or community["file"]))


def evaluate_community_bags(path: str | Path, out: str | Path, wall_s: float | None = None,
                            timeseries: bool = True) -> Any:
    """Evaluate a community's bags into ``out`` (module docstring); the
    :class:`~comems4build_ros.core.community.loop.CommunityResult`.

    Parameters
    ----------
    path : the run's bag directory (``bag/``: a bag per house and the coordinator's)
    out : the run directory to write (``houses/<name>/``, ``hub.csv``, ``houses.csv``, ``community.json``)
    wall_s : the launch's wall time [s] (None: not known to the bags)
    timeseries : write the houses' and the hub's timeseries

    Raises
    ------
    CommunityBagError
        For a directory without a coordinator's bag, a house without its bag, or a coordinator's
        bag without its record.
    """
    from comems4build_ros.core.community.kpi import evaluate_community
    from comems4build_ros.core.community.loop import CommunityResult, write_community
    from comems4build_ros.core.loop import evaluate_timeseries

    root = Path(path)
    info = _coordinator_info(root)
    if not info:
        raise CommunityBagError(f"{root}: no community's bags (no {COORDINATOR_BAG}/run_info.json naming a community)")
    community = load_community_run(info)
    tz = community.houses[0].params.site.timezone
    hub, events, stats = read_coordinator_bag(root / COORDINATOR_BAG, tz)
    names = [h.name for h in community.houses]
    left = houses_left(events, names)
    coordinator = str(info["community"].get("coordinator"))
    results: dict[str, Any] = {}
    composed: dict[str, Any] = {}
    over_ros: dict[str, Any] = {"lost_messages": {}, "steps_recorded": {}}
    n = len(hub)
    for h in community.houses:
        bag = root / h.name
        if not bag.exists():
            raise CommunityBagError(f"{root}: no bag of house '{h.name}' ({bag})")
        runs, bag_of = read_bag_set(bag, tz)
        if len(runs) != 1:
            raise CommunityBagError(f"bag {bag}: {len(runs)} namespaces, one house expected")
        ns, run = next(iter(runs.items()))
        house_info = read_run_info(bag)
        extra = summary_extra(run, *bag_of[ns], house_info, wall_s)
        extra.update(house=h.name, community=community.name, scenario=community.scenario.name)
        result = evaluate_timeseries(run.timeseries, h.plant_params, extra)
        results[h.name] = result
        over_ros["lost_messages"][h.name] = extra["lost_messages"]
        over_ros["steps_recorded"][h.name] = len(run.timeseries)
        composed[h.name] = result if len(run.timeseries) >= n else _padded(result, n, hub)
    timing = {"wall_s": wall_s, "ems_s": None, "coordinator_s": stats.get("coordinator_s")}
    ems = str(info.get("ems"))
    table, summary = evaluate_community(community, coordinator, ems, composed, hub, timing)
    gaps = {name: {"left_at_step": left.get(name), "steps_recorded": over_ros["steps_recorded"][name]}
            for name in names if name in left or over_ros["steps_recorded"][name] < n}
    summary.update(over_ros=True, houses_left=gaps, lost_messages=over_ros["lost_messages"],
                   clock=info["community"].get("clock"), coordinator_stats=stats)
    if gaps:
        table["left_at_step"] = [left.get(name) for name in table.index]
        table["steps_recorded"] = [over_ros["steps_recorded"][name] for name in table.index]
    result = CommunityResult(results, hub, table, summary)
    write_community(result, out, timeseries=timeseries)
    (Path(out) / "events.txt").write_text("\n".join(events) + ("\n" if events else ""), encoding="utf-8")
    return result


def _padded(result: Any, n: int, hub: Any) -> Any:
    """A house's run that ended before the community's, to ``n`` steps for the community's figures:
    its meter, offers and production share zero in the steps it was not there (the hub froze its
    account), the time and tariffs of the community's."""
    import dataclasses

    import pandas as pd

    ts = result.timeseries
    pad = pd.DataFrame(0.0, index=range(len(ts), n), columns=ts.columns)
    padded = pd.concat([ts, pad])
    padded["time"] = list(ts["time"]) + list(hub["time"].iloc[len(ts):n])
    return dataclasses.replace(result, timeseries=padded.reset_index(drop=True))


def community_summary_line(summary: dict[str, Any]) -> str:
    """The community's main figures in one JSON line (``launch --community``)."""
    keys = ("community", "coordinator", "houses", "steps", "cost_cp_eur", "self_sufficiency", "h2_produced_kwh",
            "h2_used_kwh", "hub_loh_end", "discomfort_kh_total", "h2_balance_max_rel", "houses_left")
    return json.dumps({k: summary.get(k) for k in keys})
