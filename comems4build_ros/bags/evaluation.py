"""A recorded run read back: the per-step timeseries, the gap check and the KPIs of a bag.

:func:`read_runs` rebuilds every house's timeseries from ``plant/record`` (one row of
the in-process loop per step), :func:`find_gaps` names the steps a topic published once a
step lacks (:func:`is_per_step`, the rule the recorder's end of run shares), and
:func:`evaluate_bag` computes weekly KPIs and the summary with the in-process KPI code
(``comems4build evaluate``, ``comems4build launch``). The bag itself is read through
:mod:`comems4build_ros.bags.bag`. No rclpy here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.bags.bag import NS_PER_S, BagError, BagInfo, bag_set, decode, iter_messages, ns_key
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import load_json_text
from comems4build_ros.wire.contract import EVENTS_TOPIC, WITHHELD_EVENT, event_step_kind

#: Topic (relative contract name) with one timeseries row per step.
RECORD_TOPIC = "plant/record"
#: Topic carrying the EMS's per-step ``step_info`` as JSON.
INFO_TOPIC = "ems/info"
#: Topic carrying the run length (element ``n_steps``).
TRUTH_TOPIC = "feed/truth"
#: The plant's step announcements (data = step).
STEP_TOPIC = "plant/step"
#: The feed's scenario description (JSON, once).
FEED_INFO_TOPIC = "feed/info"
FEED_EVENTS_TOPIC = "feed/events"
#: Steps before the last record of a cut bag that the gap check leaves out (feed
#: look-ahead + 1) [steps].
CUT_TAIL_STEPS = 5
#: The coordinator's messages to a house of a community (docs/community.md "Over ROS"), from which
#: the house's ``hub_*`` columns come: topic -> (column, label) pairs.
HUB_TOPICS = {"hub/allotment": (("hub_dloh_per_day", "dloh_per_day"), ("hub_transfer_wh", "transfer_wh")),
              "hub/settlement": (("hub_credited_wh", "credited_wh"), ("hub_split", "split"))}
#: File the recorder writes next to the MCAP file with the run's description.
RUN_INFO_FILE = "run_info.json"
#: File the launcher writes next to the MCAP file of a run it cut short (why, which node).
RUN_CUT_FILE = "run_cut.json"
#: Node role of the MQTT bridge in the contract (what it publishes is what it can withhold).
BRIDGE_ROLE = "bridge"


#: Fallback kinds of ``mqtt_bridge`` (``fallback_<kind>`` in its statistics) -> cause in
#: ``summary.json``'s ``fallback_causes``: the watchdog (a measurement missing, stale, out of
#: range), the user's switch in Home Assistant, or no valid command of the EMS in time.
FALLBACK_CAUSES = {"missing": "watchdog", "stale": "watchdog", "out_of_range": "watchdog",
                   "forced": "user_switch", "ems_silent": "late_command"}
#: ``summary.json``'s ``mqtt`` entries -> statistics of ``mqtt_bridge`` (plus the house's, ``house_<name>``).
MQTT_STATS = {"foreign_messages": "foreign_mqtt", "retained_cleared": "retained_cleared",
              "setpoints_held": "setpoints_held", "reconnects": "mqtt_reconnects"}


@dataclass
class BagRun:
    """One house's run rebuilt from a bag.

    Attributes
    ----------
    namespace : ``/`` or ``/house_<i>``
    timeseries : one row per step, columns of ``comems4build_ros.core.loop.TIMESERIES_COLUMNS``
        (plus ``ems_<key>`` when the EMS published its step_info for every step)
    n_steps : steps of the run according to ``feed/truth`` (None if never recorded)
    first_ns, last_ns : receive times of the first message and of the last ``plant/record`` [ns]
    counters : the plant's fault counters after the last recorded step
    gaps : topic -> steps of the recorded run with no message on it (:func:`find_gaps`)
    ems, scenario : EMS name (from ``ems/info``) and scenario description (``feed/info``)
        as the nodes announced them, None if not recorded
    stand_in : for a run on live inputs, ``(step, state)`` of the feed's ``stand_in`` lines on
        ``feed/events`` (:data:`~comems4build_ros.core.scenario.live.STAND_IN_EVENT`: which inputs
        stand-in values replace from that step on); empty otherwise
    plant_stats : the lock-step master's final statistics (its ``stats`` line on
        ``plant/events``: name -> value); empty if the run was cut before it
    event_steps : kind -> the steps of the ``plant/events`` lines of :data:`STEP_LIST_EVENTS`
    silent : the topics of ``gaps`` without any message in the bag
    """

    namespace: str
    timeseries: Any
    n_steps: int | None
    first_ns: int
    last_ns: int
    counters: dict[str, int] = field(default_factory=dict)
    gaps: dict[str, list[int]] = field(default_factory=dict)
    ems: str | None = None
    scenario: dict[str, Any] | None = None
    stand_in: list[tuple[int, str]] = field(default_factory=list)
    plant_stats: dict[str, float] = field(default_factory=dict)
    event_steps: dict[str, list[int]] = field(default_factory=dict)
    silent: set[str] = field(default_factory=set)

    def fallback_causes(self) -> dict[str, int]:
        """Fallback steps of the plant side by cause (:data:`FALLBACK_CAUSES`): from the
        ``fallback_<kind>`` statistics of ``mqtt_bridge``; a step no kind covers (plant_sim
        names none: its only cause is a late command) counts as ``late_command``."""
        out = dict.fromkeys(dict.fromkeys(FALLBACK_CAUSES.values()), 0)
        for kind, cause in FALLBACK_CAUSES.items():
            out[cause] += int(self.plant_stats.get(f"fallback_{kind}", 0))
        plant_steps = int(self.timeseries["fallback"].astype(float).gt(0.5).sum()) if "fallback" in self.timeseries \
            else 0
        out["late_command"] += max(plant_steps - sum(out.values()), 0)
        return out

    def mqtt_faults(self) -> dict[str, Any] | None:
        """What ``mqtt_bridge`` counted on the MQTT side (:data:`MQTT_STATS`); None for another plant."""
        if "mqtt_connects" not in self.plant_stats:
            return None
        out: dict[str, Any] = {key: int(self.plant_stats.get(stat, 0)) + int(self.plant_stats.get(f"house_{stat}", 0))
                               for key, stat in MQTT_STATS.items()}
        for kind in STEP_LIST_EVENTS:
            if self.event_steps.get(kind):
                out[f"{kind}_at"] = list(self.event_steps[kind])
        return out

    def stand_in_steps(self) -> dict[str, int]:
        """Recorded steps whose price, and whose weather, stand-in values replaced
        (:attr:`stand_in`; both 0 for a run on live inputs without any)."""
        from comems4build_ros.core.scenario.live import STAND_IN_STATES

        n = len(self.timeseries)
        out = {"stand_in_price_steps": 0, "stand_in_weather_steps": 0}
        marks = sorted(m for m in self.stand_in if m[1] in STAND_IN_STATES and m[0] < n)
        for i, (k, state) in enumerate(marks):
            end = marks[i + 1][0] if i + 1 < len(marks) else n
            if "prices" in state:
                out["stand_in_price_steps"] += end - k
            if "weather" in state:
                out["stand_in_weather_steps"] += end - k
        return out

    @property
    def complete(self) -> bool:
        """Every step of the run is in the bag."""
        return self.n_steps is not None and len(self.timeseries) == self.n_steps


def read_run_info(path: str | Path) -> dict[str, Any]:
    """The ``run_info.json`` beside the MCAP file (``{}`` if absent)."""
    from comems4build_ros.files.inputs import load_json_file

    p = bag_set(path)[0]
    f = (p if p.is_dir() else p.parent) / RUN_INFO_FILE
    if not f.exists():
        return {}
    out = load_json_file(f, "the bag's run information")
    if not isinstance(out, dict):
        raise BagError(f"{f}: expected a JSON object")
    return check_run_info(out, str(f))


#: Entries of ``run_info.json`` that the evaluation reads and their JSON types.
RUN_INFO_TYPES: dict[str, tuple[type, ...]] = {
    "config_files": (list,), "overrides": (dict,), "ems": (str,), "scenario": (str,), "forecast": (str,),
    "run_id": (str,),
}


def check_run_info(info: dict[str, Any], source: str) -> dict[str, Any]:
    """``info`` if the entries the evaluation reads have their types (``null`` allowed for each).

    ``config_files`` must be a list of file names (each is read as a parameter file, through
    the one YAML loader), ``overrides`` a mapping of dotted parameter names.

    Raises
    ------
    ValueError
        Naming ``source`` and the entry.
    """
    for key, types in RUN_INFO_TYPES.items():
        value = info.get(key)
        if value is not None and not isinstance(value, types):
            raise BagError(f"{source}: '{key}' must be a {types[0].__name__}, got {type(value).__name__}")
    if not all(isinstance(f, str) and f for f in info.get("config_files") or []):
        raise BagError(f"{source}: 'config_files' must list file names")
    if not all(isinstance(k, str) and k for k in info.get("overrides") or {}):
        raise BagError(f"{source}: 'overrides' must map parameter names (section.key) to values")
    return info


def _split(topic: str, name: str) -> str | None:
    """Namespace of ``topic`` if it ends with the contract name ``name``."""
    if topic == f"/{name}":
        return "/"
    if topic.endswith(f"/{name}"):
        return topic[: -len(name) - 1]
    return None


@dataclass
class _Scan:
    """What one pass over a bag's messages collected, per namespace (see :func:`read_runs`)."""

    records: dict[str, dict[int, tuple[int, Any]]] = field(default_factory=dict)  # ns -> step -> (t_ns, data)
    infos: dict[str, dict[int, dict[str, float]]] = field(default_factory=dict)  # ns -> step -> ems/info
    ems_names: dict[str, str] = field(default_factory=dict)
    scenarios: dict[str, dict[str, Any]] = field(default_factory=dict)
    n_steps: dict[str, int] = field(default_factory=dict)
    seen: dict[str, set[int]] = field(default_factory=dict)  # topic -> steps with a message (gap check)
    withheld: dict[str, set[int]] = field(default_factory=dict)  # ns -> steps without state by design
    stand_in: dict[str, list[tuple[int, str]]] = field(default_factory=dict)  # ns -> the feed's stand_in lines
    plant_stats: dict[str, dict[str, float]] = field(default_factory=dict)  # ns -> the master's final statistics
    step_events: dict[str, dict[str, set[int]]] = field(default_factory=dict)  # ns -> kind -> steps
    first_ns: int | None = None
    #: ns -> steps whose plant/record came more than once -> whether the copies differ
    twice: dict[str, dict[int, bool]] = field(default_factory=dict)
    feed_infos: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # ns -> distinct feed/info documents
    hub: dict[str, dict[str, dict[int, Any]]] = field(default_factory=dict)  # ns -> HUB_TOPICS topic -> step -> data


def _scan_bag(path: str | Path, info: BagInfo, layout: Any, n_idx: int) -> _Scan:
    """One pass over every message of a bag, sorted into a :class:`_Scan` (see :func:`read_runs`)."""

    from comems4build_ros.core.scenario.live import STAND_IN_EVENT

    scan = _Scan()
    for topic, msgtype, t_ns, raw in iter_messages(path, info=info):
        scan.first_ns = t_ns if scan.first_ns is None else min(scan.first_ns, t_ns)
        if (ns := _split(topic, RECORD_TOPIC)) is not None:
            data = decode(msgtype, raw).data
            if len(data) != layout.length:
                raise BagError(
                    f"bag {path}: topic '{topic}': {len(data)} elements, the contract layout has {layout.length}"
                )
            by_step = scan.records.setdefault(ns, {})
            step = int(data[0])
            if step in by_step:  # a plant publishes each step's record once: a second plant on the topic
                twice = scan.twice.setdefault(ns, {})
                twice[step] = twice.get(step, False) or list(by_step[step][1]) != list(data)
            else:
                by_step[step] = (t_ns, data)
        elif msgtype.endswith("Float64MultiArray"):
            data = decode(msgtype, raw).data
            if len(data):
                scan.seen.setdefault(topic, set()).add(int(data[0]))
                for name in HUB_TOPICS:
                    if (hub_ns := _split(topic, name)) is not None:
                        scan.hub.setdefault(hub_ns, {}).setdefault(name, {})[int(data[0])] = data
            ns = _split(topic, TRUTH_TOPIC)
            if ns is not None and ns not in scan.n_steps:
                scan.n_steps[ns] = int(data[n_idx])
        elif (ns := _split(topic, INFO_TOPIC)) is not None:
            try:
                msg = load_json_text(decode(msgtype, raw).data, f"bag {path}: topic '{topic}'")
                step = int(msg["step"])
                scan.infos.setdefault(ns, {})[step] = {k: float(v) for k, v in msg["info"].items()}
            except (ValueError, KeyError, TypeError) as exc:
                raise BagError(f"bag {path}: topic '{topic}': invalid step info: {exc}") from None
            scan.seen.setdefault(topic, set()).add(step)
            if isinstance(msg.get("ems"), str):
                scan.ems_names.setdefault(ns, msg["ems"])
        elif _split(topic, STEP_TOPIC) is not None:
            scan.seen.setdefault(topic, set()).add(int(decode(msgtype, raw).data))
        elif (ns := _split(topic, EVENTS_TOPIC)) is not None:
            line = decode(msgtype, raw).data
            step_kind = event_step_kind(line)
            if step_kind is not None and step_kind[1] == WITHHELD_EVENT:
                scan.withheld.setdefault(ns, set()).add(step_kind[0])
            elif step_kind is not None and step_kind[1] in STEP_LIST_EVENTS:
                scan.step_events.setdefault(ns, {}).setdefault(step_kind[1], set()).add(step_kind[0])
            elif step_kind is not None and step_kind[1] == STATS_EVENT:
                parts = line.split(None, 2)
                scan.plant_stats[ns] = parse_stats(parts[2] if len(parts) > 2 else "")
        elif (ns := _split(topic, FEED_EVENTS_TOPIC)) is not None:
            line = decode(msgtype, raw).data
            step_kind = event_step_kind(line)
            if step_kind is not None and step_kind[1] == STAND_IN_EVENT:
                scan.stand_in.setdefault(ns, []).append((step_kind[0], line.split(None, 2)[2].split(":", 1)[0]))
        elif (ns := _split(topic, FEED_INFO_TOPIC)) is not None:
            try:
                doc = dict(load_json_text(decode(msgtype, raw).data, f"bag {path}: '{topic}'"))
                scan.scenarios.setdefault(ns, doc)
                docs = scan.feed_infos.setdefault(ns, [])
                if doc not in docs:
                    docs.append(doc)
            except (ValueError, TypeError) as exc:
                raise BagError(f"bag {path}: topic '{topic}': invalid scenario information: {exc}") from None
    return scan


class MixedRunsError(BagError):
    """A bag whose records in one namespace come from more than one plant or run (never one run's KPIs)."""


def check_one_run(ns: str, scan: _Scan, path: str | Path, run_id: str | None) -> None:
    """Refuse namespace ``ns`` of a bag unless its records are one run's.

    A plant publishes each step's ``plant/record`` once and a feed one ``feed/info`` per run, so
    a step recorded twice, two different ``feed/info`` documents, or a ``feed/info`` naming
    another run than the bag's ``run_info.json`` (``run_id``) mean that two runs published in
    the same namespace (e.g. one launch file included twice without a namespace of its own):
    summarised as one, the bag would give one run's KPIs under the other's name.

    Raises
    ------
    MixedRunsError
        Naming the topic, the steps or run ids, and what to do.
    """
    where = f"bag {path}: namespace '{ns}'"
    advice = ("records of different runs are never summarised as one; record each run in a namespace of its own "
              "(namespace:=, or PushRosNamespace around each inclusion of the launch file)")
    twice = scan.twice.get(ns, {})
    if twice:
        differ = sorted(k for k, d in twice.items() if d)
        how = (f"{len(differ)} of them with different values" if differ else "each time with the same values")
        raise MixedRunsError(f"{where}: topic '{resolve_ns(ns, RECORD_TOPIC)}' carries records of more than one "
                             f"plant: {len(twice)} step(s) recorded twice ({_ranges(sorted(twice))}), {how}; a "
                             f"plant publishes each step's record once; {advice}")
    docs = scan.feed_infos.get(ns, [])
    if len(docs) > 1:
        ids = ", ".join(str(d.get("run_id") or d.get("scenario")) for d in docs)
        raise MixedRunsError(f"{where}: topic '{resolve_ns(ns, FEED_INFO_TOPIC)}' carries {len(docs)} different "
                             f"scenario descriptions (runs or scenarios: {ids}): the inputs of more than one feed; "
                             f"{advice}")
    foreign = [d.get("run_id") for d in docs if run_id and d.get("run_id") and d.get("run_id") != run_id]
    if foreign:
        raise MixedRunsError(f"{where}: topic '{resolve_ns(ns, FEED_INFO_TOPIC)}' names run '{foreign[0]}', the "
                             f"bag's run_info.json run '{run_id}': the records are another run's; {advice}")


def _run_of(ns: str, scan: _Scan, path: str | Path, timezone: str, contract: Any, layout: Any,
            recorded: set[str], run_info: dict[str, Any] | None = None) -> BagRun:
    """The :class:`BagRun` of namespace ``ns`` from a scan of its bag (``run_info``: the bag's
    ``run_info.json``: its run id, :func:`check_one_run`, and its EMS, :func:`_unread_inputs`)."""
    run_info = run_info or {}
    run_id = run_info.get("run_id")
    import pandas as pd

    from comems4build_ros.core.loop import TIMESERIES_COLUMNS

    by_step = scan.records[ns]
    check_one_run(ns, scan, path, run_id if isinstance(run_id, str) else None)
    steps = sorted(by_step)
    if steps != list(range(len(steps))):
        missing = sorted(set(range(steps[-1] + 1)) - set(steps))
        raise BagError(
            f"bag {path}: topic '{resolve_ns(ns, RECORD_TOPIC)}': steps missing in the middle of the run: "
            f"{_ranges(missing)} (recorder overloaded or messages lost)"
        )
    rows = [layout.unpack(by_step[k][1]) for k in steps]
    columns = [c for c in TIMESERIES_COLUMNS if c != "time"]
    ts = pd.DataFrame({c: [r[c] for r in rows] for c in columns})
    times = pd.to_datetime([r["time_unix_s"] for r in rows], unit="s", utc=True).tz_convert(timezone)
    ts.insert(0, "time", [t.isoformat() for t in times])
    ts = ts[list(TIMESERIES_COLUMNS)]
    step_infos = scan.infos.get(ns, {})
    if step_infos and all(k in step_infos for k in steps):
        ts = pd.concat([ts, pd.DataFrame([step_infos[k] for k in steps]).add_prefix("ems_")], axis=1)
    ts = _with_hub_columns(ts, scan.hub.get(ns, {}), contract, steps)
    n_steps = scan.n_steps.get(ns)
    complete = n_steps is not None and len(steps) == n_steps
    fallback = {k for k, r in zip(steps, rows) if r["fallback"]}
    gaps = find_gaps(contract, ns, len(steps), fallback, scan.seen, complete, recorded, scan.withheld.get(ns, set()),
                     _unread_inputs(contract, scan.scenarios.get(ns), scan.ems_names.get(ns), run_info.get("ems")))
    counter_names = ("fallback_steps", "rejected_commands", "wrong_step_commands", "foreign_commands")
    return BagRun(
        namespace=ns,
        timeseries=ts,
        n_steps=n_steps,
        first_ns=int(scan.first_ns or 0),
        last_ns=max(t for t, _ in by_step.values()),
        counters={c: int(rows[-1][c]) for c in counter_names},
        gaps=gaps,
        silent={t for t in gaps if t not in scan.seen},
        ems=scan.ems_names.get(ns),
        scenario=scan.scenarios.get(ns),
        stand_in=sorted(set(scan.stand_in.get(ns, []))),
        plant_stats=scan.plant_stats.get(ns, {}),
        event_steps={kind: sorted(steps) for kind, steps in scan.step_events.get(ns, {}).items()},
    )


def _with_hub_columns(ts: Any, hub: dict[str, dict[int, Any]], contract: Any, steps: list[int]) -> Any:
    """A community's house: its timeseries with the ``hub_*`` columns of the in-process run (the
    allotted ``eq:deltaLOH``, the H2 moved into and credited to its account, its production
    share), from the coordinator's ``hub/allotment`` and ``hub/settlement`` of every step; as it is
    for a house without them."""
    import pandas as pd

    if not hub or not all(all(k in hub.get(t, {}) for k in steps) for t in HUB_TOPICS):
        return ts
    columns = {}
    for topic, pairs in HUB_TOPICS.items():
        index = contract.topic(topic).layout({}).index
        for column, label in pairs:
            columns[column] = [float(hub[topic][k][index[label]]) for k in steps]
    return pd.concat([ts, pd.DataFrame(columns)], axis=1)


def read_runs(path: str | Path, timezone: str, info: BagInfo | None = None) -> dict[str, BagRun]:
    """:func:`_read_runs`; every refusal names the bag (a damaged record's too)."""
    try:
        return _read_runs(path, timezone, info)
    except ValueError as exc:
        if str(path) in str(exc):
            raise
        raise BagError(f"bag {path}: {exc}") from None


def _read_runs(path: str | Path, timezone: str, info: BagInfo | None = None) -> dict[str, BagRun]:
    """Rebuild the per-step timeseries of every namespace of a bag.

    Parameters
    ----------
    path : rosbag2 directory or ``.mcap`` file (complete or cut short by a SIGKILL)
    timezone : time zone of the ``time`` column (the site's, ``site.timezone``)
    info : filled like :func:`iter_messages` does

    Raises
    ------
    ValueError
        If the bag has no ``plant/record`` topic, a record does not match the contract
        layout, or steps are missing in the middle of a run (naming topic and steps).
    MixedRunsError
        If a namespace holds records of more than one plant or run (:func:`check_one_run`).
    """
    from comems4build_ros.wire.contract import load_contract

    contract = load_contract()
    layout = contract.topic(RECORD_TOPIC).layout({})
    n_idx = contract.topic(TRUTH_TOPIC).layout({}).index["n_steps"]
    info = info if info is not None else BagInfo(Path(path), [], False)
    scan = _scan_bag(path, info, layout, n_idx)
    if not scan.records:
        topics = ", ".join(sorted(info.topics)) or "none"
        damage = f"; damage: {'; '.join(info.damage)}" if info.damage else ""
        raise BagError(f"bag {path}: no '{RECORD_TOPIC}' messages could be read (topics: {topics}){damage}")
    run_info = read_run_info(path)
    return {ns: _run_of(ns, scan, path, timezone, contract, layout, set(info.topics), run_info)
            for ns in sorted(scan.records, key=ns_key)}


#: Kind of the lock-step master's final line on ``plant/events`` (``<step> stats name=value ...``).
STATS_EVENT = "stats"
#: ``plant/events`` kinds whose steps ``summary.json`` lists (``mqtt``: ``<kind>_at``): the
#: steps that ran on the safe fallback, and those that ran on set-points the house held.
STEP_LIST_EVENTS = ("fallback", "setpoints_held")


def parse_stats(text: str) -> dict[str, float]:
    """``name=value`` pairs of a ``stats`` line (pairs that do not read as numbers are left out)."""
    out: dict[str, float] = {}
    for pair in text.split():
        name, sep, value = pair.partition("=")
        if sep:
            try:
                out[name] = float(value)
            except ValueError:
                pass
    return out


def _unread_inputs(contract: Any, feed_info: dict[str, Any] | None, ems: str | None,
                   run_ems: Any = None) -> set[str]:
    """Feed topics the run's feed did not publish: those its EMS node does not read, the node the
    feed served as its ``feed/info`` names it (``for_ems``; none when it served every EMS), else
    the EMS ``ems`` announced on ``ems/info``, else ``run_ems`` of ``run_info.json`` (an EMS of
    one's own publishes no ``ems/info``); none if the bag names none of them."""
    if feed_info is not None and "for_ems" in feed_info:
        node = feed_info.get("for_ems")
        try:
            return set(contract.inputs_not_read(node)) if isinstance(node, str) and node else set()
        except ValueError:  # ContractError: a node this contract does not know
            return set()
    name = ems or (run_ems if isinstance(run_ems, str) else None)
    try:
        return set(contract.inputs_not_read(contract.ems_node_name(name))) if name else set()
    except ValueError:  # ContractError: an EMS this contract does not know
        return set()


def is_per_step(spec: Any) -> bool:
    """Whether a contract topic carries one message per step (its step in the message):
    every ``Float64MultiArray`` topic (element 0), ``plant/step`` and ``ems/info``. The gap
    check and the recorder's end of run expect each step of these."""
    return bool(spec.is_array) or spec.name in (STEP_TOPIC, INFO_TOPIC)


def withheld_topics(contract: Any) -> set[str]:
    """Topics published once a step that a step named by a :data:`WITHHELD_EVENT` lacks by
    design: those the MQTT bridge publishes besides ``plant/step`` and ``plant/record``
    (``state/*``, ``feed/measured``)."""
    bridges = {name for name, spec in contract.nodes.items() if spec.role == BRIDGE_ROLE}
    return {spec.name for spec in contract.topics.values()
            if is_per_step(spec) and spec.name not in (STEP_TOPIC, RECORD_TOPIC) and bridges & set(spec.publishers)}


def find_gaps(
    contract: Any,
    ns: str,
    n: int,
    fallback: set[int],
    seen: dict[str, set[int]],
    complete: bool,
    recorded: set[str] | None = None,
    withheld: set[int] | None = None,
    unread: set[str] | None = None,
) -> dict[str, list[int]]:
    """Steps of a recorded run with no message, per topic of namespace ``ns``.

    Checked: every ``Float64MultiArray`` topic of the contract (element 0 is the step),
    ``plant/step`` and, if the EMS published it at all, ``ems/info``, among the topics the
    bag records (``recorded``: its connections; None = all; a topic left out of a
    recording is not a gap); steps ``0 .. n-1``
    (``n`` = recorded ``plant/record`` steps), except the fallback steps for the EMS's
    topics (no command is expected there) and the ``withheld`` steps (:data:`WITHHELD_EVENT`)
    for the topics of :func:`withheld_topics` (no state was announced there, by design).
    A topic of ``unread`` (feed inputs the run's EMS does not read,
    :meth:`~comems4build_ros.wire.contract.Contract.inputs_not_read`) without any message was
    not published in the run (a feed serving that EMS), not lost; so is a topic of the link to
    a community's coordinator (scope ``community_house``) in the bag of an independent house.
    A bag cut short (recorder killed) is checked up to :data:`CUT_TAIL_STEPS` steps before
    its last record (the feed runs ahead and the last messages before the cut need not all
    be in), and each topic with messages only up to its own last recorded step: the
    recorder's queues of different topics can be many steps apart when it is killed (what
    it had not written is the cut, reported as ``bag_incomplete``; a step missing inside a
    topic's recorded span is a gap).
    """
    roles = {name: spec.role for name, spec in contract.nodes.items()}
    last = n if complete else max(0, n - CUT_TAIL_STEPS)
    withheld = withheld or set()
    no_state = withheld_topics(contract) if withheld else set()
    # published only if the run had them at all: ems/info (an EMS without step info), the
    # inputs the run's EMS does not read, the link to a community's coordinator
    unless_absent = (unread or set()) | {INFO_TOPIC} | {t.name for t in contract.in_scope("community_house")}
    out: dict[str, list[int]] = {}
    for spec in contract.topics.values():
        if spec.name == RECORD_TOPIC:
            continue
        full = resolve_ns(ns, spec.name)
        if recorded is not None and full not in recorded:
            continue
        if not is_per_step(spec) or (spec.name in unless_absent and full not in seen):
            continue
        from_ems = any(roles.get(p) == "ems" for p in spec.publishers)
        got = seen.get(full, set())
        end = last if complete or not got else min(last, max(got) + 1)
        skip = (fallback if from_ems else set()) | (withheld if spec.name in no_state else set())
        missing = [k for k in range(end) if k not in got and k not in skip]
        if missing:
            out[full] = missing
    return out


class BagGapError(InputError):
    """The bag misses messages in the middle of a run (names topics and steps)."""


def describe_gaps(gaps: dict[str, list[int]], silent: set[str] | frozenset[str] = frozenset()) -> str:
    """``topic: N step(s) missing (ranges)`` per topic, one per line; a topic of ``silent`` (no
    message at all in the bag) says so, and that the bag cannot tell why."""
    return "\n".join(
        f"  {t}: no message at all ({len(steps)} step(s)): not published in this run, or never received by "
        "the recorder (the bag does not tell which)" if t in silent else
        f"  {t}: {len(steps)} step(s) missing ({_ranges(steps)})" for t, steps in sorted(gaps.items()))


def resolve_ns(ns: str, name: str) -> str:
    """``/`` + ``a/b`` -> ``/a/b``; ``/house_1`` + ``a/b`` -> ``/house_1/a/b``; ``/clock`` stays."""
    return name if name.startswith("/") else f"{ns.rstrip('/')}/{name}"


def _ranges(values: list[int]) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"`` (at most 10 ranges)."""
    out: list[str] = []
    start = prev = None
    for v in values:
        if start is None:
            start = prev = v
        elif v == prev + 1:
            prev = v
        else:
            out.append(f"{start}-{prev}" if prev != start else f"{start}")
            start = prev = v
    if start is not None:
        out.append(f"{start}-{prev}" if prev != start else f"{start}")
    return ", ".join(out[:10]) + (" ..." if len(out) > 10 else "")


def house_dir(out: Path, namespace: str, n_namespaces: int) -> Path:
    """Output directory of one namespace: ``out`` itself for a single root-namespace run."""
    return out if n_namespaces == 1 and namespace == "/" else out / namespace.strip("/")


def evaluate_bag(
    path: str | Path,
    out: str | Path,
    params: Any = None,
    wall_s: float | None = None,
    timeseries: bool = True,
    accept_gaps: bool = False,
) -> dict[str, dict[str, Any]]:
    """Weekly KPIs and summary of every house in a bag, with the in-process KPI code.

    Writes, per namespace, ``timeseries.csv`` (optional), ``weekly.csv`` and
    ``summary.json`` through :func:`comems4build_ros.core.loop.write_run` (into ``out`` for a
    single house in the root namespace, else into ``out/house_<i>/``, and then
    ``out/weekly.csv`` with a ``house`` column and ``out/summary.json`` with one
    summary per house).

    Parameters
    ----------
    path : rosbag2 directory or ``.mcap`` file
    out : output directory
    params : plant parameters (default: those named in the bag's ``run_info.json``)
    wall_s : wall time of the run [s] for the summary (the launcher's; None for a bag
        evaluated on its own: the bag does not know it)
    accept_gaps : evaluate a bag with messages missing on some topic (default: refuse)

    Summary entries besides the KPIs: :func:`summary_extra`. Every file is written all-or-nothing.

    Raises
    ------
    BagGapError
        When some topic misses messages and ``accept_gaps`` is false (naming the
        topics and the steps).

    Returns
    -------
    namespace -> summary
    """
    import json

    import pandas as pd

    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import evaluate_timeseries, write_run
    from comems4build_ros.files.outputs import atomic_dir

    out = Path(out)
    run_info = read_run_info(path)
    if params is None:
        params = load_plant_params(run_info.get("config_files") or [], run_info.get("overrides") or {})
    runs, bag_of = read_bag_set(path, params.site.timezone)
    gaps = {t: steps for run in runs.values() for t, steps in run.gaps.items()}
    if gaps and not accept_gaps:
        silent = {t for run in runs.values() for t in run.silent}
        raise BagGapError(
            f"bag {path}: messages of topics published once a step missing on {len(gaps)} topic(s):\n"
            f"{describe_gaps(gaps, silent)}\n"
            "KPIs from plant/record would still be exact, but the bag is not a complete record of the run; "
            "evaluate it anyway with --accept-gaps"
        )
    summaries: dict[str, dict[str, Any]] = {}
    weekly_parts = []
    for ns, run in runs.items():
        info, cut = bag_of[ns]  # the bag of this house: its own damage and cut, no other's
        result = evaluate_timeseries(run.timeseries, params, summary_extra(run, info, cut, run_info, wall_s))
        write_run(result, house_dir(out, ns, len(runs)), timeseries=timeseries)
        summaries[ns] = result.summary
        weekly_parts.append(result.weekly.assign(house=ns.strip("/") or "root"))
    if len(runs) > 1 or "/" not in runs:
        weekly = pd.concat(weekly_parts, ignore_index=True)
        weekly = weekly[["house", *[c for c in weekly.columns if c != "house"]]]
        combined = {"houses": {ns.strip("/"): s for ns, s in summaries.items()}}
        with atomic_dir(out) as tmp:
            weekly.to_csv(tmp / "weekly.csv", index=False)
            (tmp / "summary.json").write_text(json.dumps(combined, indent=2, default=_json_default) + "\n", "utf-8")
    return summaries


BagOf = dict[str, tuple[BagInfo, dict[str, Any]]]


def summary_extra(run: BagRun, info: BagInfo, cut: dict[str, Any], run_info: dict[str, Any],
                   wall_s: float | None) -> dict[str, Any]:
    """The summary entries of one house's run besides its KPIs (:func:`evaluate_bag`).

    Besides the KPIs (as in-process): ``ems``, ``scenario``, ``forecast``
    from ``run_info.json`` or, without it, as the EMS (``ems/info``) and the feed
    (``feed/info``) announced them in the bag; ``wall_s``; ``ems_s`` = None (the
    controller's own compute time is not in the bag); ``bag_duration_s`` (receive time of
    the last record minus that of the first message); ``lost_messages`` (topic -> steps
    without a message, ``{}`` for a complete recording). An incomplete run or bag adds
    ``bag_incomplete`` (steps recorded and expected, whether ``metadata.yaml`` was
    read, whether an ``.mcap`` file ended early, and the damage found in this house's
    own bag, see :class:`BagInfo`; for a run the launcher cut short also ``run_cut``, its
    :data:`RUN_CUT_FILE`, whose cause is repeated as the summary's ``run_cut``, with
    ``nodes_here``: the nodes of this house among those of the process that left, so
    that a house whose own nodes all ran on is told apart from the one that lost them); a
    partial last week is left out of the weekly medians like any
    partial week. Fault counters of the plant other than fallback steps are added as
    ``ros_faults`` when non-zero. A run on live inputs adds ``live_inputs``: the recorded
    steps whose price (``stand_in_price_steps``) and whose weather
    (``stand_in_weather_steps``) stand-in values replaced, as the feed stated them on
    ``feed/events``. A house behind MQTT adds ``fallback_causes`` (:meth:`BagRun.fallback_causes`,
    when any fallback step has a cause) and ``mqtt`` (:meth:`BagRun.mqtt_faults`).
    """
    scen = run.scenario or {}
    extra: dict[str, Any] = {
        "ems": run_info.get("ems") or run.ems,
        "scenario": run_info.get("scenario") or scenario_label(scen.get("scenario")),
        "wall_s": wall_s,
        "ems_s": None,
        "forecast": run_info.get("forecast") if run_info else _forecast_of(run.ems, scen.get("forecast")),
        "bag_duration_s": (run.last_ns - run.first_ns) / NS_PER_S,
        "lost_messages": {t: len(steps) for t, steps in sorted(run.gaps.items())},
    }
    if not run.complete or not info.complete or info.damage or cut:
        extra["bag_incomplete"] = {
            "steps_recorded": len(run.timeseries),
            "steps_expected": run.n_steps,
            "metadata_yaml": info.complete,
            "truncated_mcap": info.truncated,
            "damage": list(info.damage),
        }
        if cut:
            extra["bag_incomplete"]["run_cut"] = dict(cut, nodes_here=nodes_of(cut.get("nodes") or [], run.namespace))
            extra["run_cut"] = cut.get("cause")
    if run.stand_in:  # a run on live inputs: how many steps ran on stand-in values
        extra["live_inputs"] = run.stand_in_steps()
    causes = run.fallback_causes()
    if any(causes.values()):
        extra["fallback_causes"] = causes
    mqtt = run.mqtt_faults()
    if mqtt is not None:
        extra["mqtt"] = mqtt
    faults = {k: v for k, v in run.counters.items() if k != "fallback_steps" and v}
    if faults:
        extra["ros_faults"] = faults
    return extra


def nodes_of(nodes: list[str], namespace: str) -> list[str]:
    """The full node names of ``nodes`` that lie in ``namespace`` (``/`` or ``/house_<i>``)."""
    return [n for n in nodes if isinstance(n, str) and (n.rpartition("/")[0] or "/") == namespace]


def read_bag_set(path: str | Path, timezone: str) -> tuple[dict[str, BagRun], BagOf]:
    """Every house's run of the bag (or set of per-house bags) at ``path``, each with
    the :class:`BagInfo` of its own bag and that bag's :data:`RUN_CUT_FILE` (``{}`` if none).

    Each bag of a set is read on its own, so damage (a truncated MCAP file of a killed
    recorder) is attributed to the house whose bag has it. A bag of a set with no
    ``plant/record`` at all (its recorder died before the first step) is left out; if no
    bag has one, the ValueError names them.
    """
    parts = bag_set(path)
    runs: dict[str, BagRun] = {}
    bag_of: BagOf = {}
    errors: list[str] = []
    for part in parts:
        info = BagInfo(part, [], False)
        try:
            part_runs = read_runs(part, timezone, info)
        except MixedRunsError:
            raise  # never left out quietly: the set's figures would lack a house without a word
        except ValueError as exc:
            if len(parts) == 1:
                raise
            errors.append(str(exc))
            continue
        cut = read_run_cut(part)
        for ns, run in part_runs.items():
            runs[ns] = run
            bag_of[ns] = (info, cut)
    if not runs:
        raise BagError("; ".join(errors))
    return runs, bag_of


def read_run_cut(path: str | Path) -> dict[str, Any]:
    """The :data:`RUN_CUT_FILE` of one bag (``{}`` if the run was not cut or the file is unreadable)."""
    from comems4build_ros.files.inputs import load_json_file

    p = Path(path)
    f = (p if p.is_dir() else p.parent) / RUN_CUT_FILE
    try:
        doc = load_json_file(f, "the mark of a cut run")
    except ValueError:
        return {}
    return doc if isinstance(doc, dict) else {}


def mark_run_cut(path: str | Path, cut: dict[str, Any]) -> list[Path]:
    """Write ``cut`` (why the run was cut: cause, process, exit code, log) as
    :data:`RUN_CUT_FILE` into every bag under ``path`` that exists; returns the files."""
    import json

    from comems4build_ros.files.outputs import write_text_atomic

    p = Path(path)
    if not p.exists():
        return []
    out = []
    for part in bag_set(p):
        d = part if part.is_dir() else part.parent
        f = d / RUN_CUT_FILE
        write_text_atomic(f, json.dumps(cut, indent=2) + "\n")
        out.append(f)
    return out


def _json_default(value: Any) -> Any:
    import math

    import numpy as np

    if isinstance(value, np.generic):
        value = value.item()
        return None if isinstance(value, float) and not math.isfinite(value) else value
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def lost_messages(path: str | Path) -> dict[str, int]:
    """Per topic of every namespace, steps of the recorded run with no message (:func:`find_gaps`).

    A complete recording gives ``{}``; used by the tests and ``bench ros`` to show that
    the recorder kept up.
    """
    runs, _ = read_bag_set(path, "UTC")
    return {t: len(steps) for run in runs.values() for t, steps in sorted(run.gaps.items())}


def scenario_label(name: Any) -> str | None:
    """The feed's scenario name (``Scenario.name``, as the in-process summary has it), None if absent."""
    return name if isinstance(name, str) and name else None


def _forecast_of(ems: str | None, mode: Any) -> str | None:
    """Forecast mode of the summary: the feed's mode for an MPC-level EMS, else None (as in-process)."""
    if ems is None or not isinstance(mode, str):
        return None
    from comems4build_ros.core.ems import UnknownEMSError, ems_entry

    try:
        return mode if ems_entry(ems).info_level == "mpc" else None
    except UnknownEMSError:
        return None
