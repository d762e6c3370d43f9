"""rosbag2 / MCAP bags: writing with a bounded chunk, reading complete and interrupted bags.

No rclpy here: the evaluator reads bags without a ROS graph.

Writing (:class:`BagWriter`) goes through rosbags 0.11.9 (``Writer(path, version=8,
storage_plugin=StoragePlugin.MCAP)``, metadata version 8 so that Jazzy's ``ros2 bag info``
parses the QoS strings). rosbags keeps the pending MCAP chunk in memory
and writes it only when it exceeds 1 MiB; a recorder killed with SIGKILL would lose
everything in that chunk. :class:`BagWriter` therefore closes the pending chunk itself when
it holds ``chunk_max_bytes`` or is ``chunk_period_s`` old and then flushes the file to the
operating system, so after a SIGKILL the ``.mcap`` file holds every message up to the last
closed chunk (at most ``chunk_period_s`` of data is lost). A SIGKILLed recorder writes no
summary section, no footer and no ``metadata.yaml``: :func:`iter_messages` then reads the
``.mcap`` file sequentially with the ``mcap`` library's stream reader and stops at the
truncated record.

Reading (:func:`iter_messages`) uses rosbags' ``AnyReader`` for complete bags (a
``metadata.yaml`` is present) and the ``mcap`` stream reader otherwise; messages are
decoded with the Jazzy typestore of rosbags. A bag whose ``metadata.yaml`` or ``.mcap``
file cannot be read whole (malformed YAML, a truncated or corrupt file) is salvaged the
same way: everything before the damage is read, and :class:`BagInfo` says what was lost.
"""

from __future__ import annotations

import re
import struct
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.writer import CompressionMode
from rosbags.typesys import Stores, get_typestore

#: rosbag2 metadata version that Jazzy reads (version 9 writes QoS as a list Jazzy rejects).
METADATA_VERSION = 8
#: MCAP message record header: opcode, record length, channel id, sequence, log time,
#: publish time (little endian); the fixed part of the record length [byte].
_MSG_HEAD = struct.Struct("<BQHIQQ")
MSG_RECORD_FIXED = 2 + 4 + 8 + 8
#: ROS distribution the bags are written for (``ros_distro`` of metadata.yaml).
ROS_DISTRO = "jazzy"
#: Default: close the pending chunk when it is this old [s] ...
DEFAULT_CHUNK_PERIOD_S = 1.0
#: ... or when it holds this many bytes of records [byte].
DEFAULT_CHUNK_MAX_BYTES = 256 * 1024
NS_PER_S = 1_000_000_000

_TYPESTORE = None


def typestore() -> Any:
    """The rosbags typestore of ROS 2 Jazzy (type hashes match Jazzy's)."""
    global _TYPESTORE
    if _TYPESTORE is None:
        _TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
    return _TYPESTORE


def ros_type_to_bag_type(ros_type: str) -> str:
    """``std_msgs/msg/Float64`` (or ``std_msgs/Float64``) -> ``std_msgs/msg/Float64``."""
    parts = ros_type.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] == "msg":
        return ros_type
    raise ValueError(f"not a ROS 2 message type name: {ros_type!r}")


def qos_for_bag(reliable: bool = True, transient_local: bool = False, depth: int = 10) -> Qos:
    """A rosbag2 QoS record (offered_qos_profiles) for a publisher of the given kind."""
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=depth,
        reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        deadline=QosTime(0, 0),
        lifespan=QosTime(0, 0),
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=QosTime(0, 0),
        avoid_ros_namespace_conventions=False,
    )


class BagWriter:
    """rosbag2 directory with MCAP storage whose data survive a SIGKILL up to the last chunk.

    Parameters
    ----------
    path : bag directory to create (must not exist)
    chunk_period_s : close the pending chunk once its first message is this old [s]
    chunk_max_bytes : close the pending chunk once it holds this many bytes [byte]
    """

    def __init__(
        self,
        path: str | Path,
        chunk_period_s: float = DEFAULT_CHUNK_PERIOD_S,
        chunk_max_bytes: int = DEFAULT_CHUNK_MAX_BYTES,
    ) -> None:
        if chunk_period_s <= 0 or chunk_max_bytes <= 0:
            raise ValueError("chunk_period_s and chunk_max_bytes must be positive")
        self.path = Path(path)
        if self.path.exists():
            raise FileExistsError(f"bag directory already exists: {self.path}")
        self.chunk_period_s = chunk_period_s
        self.chunk_max_bytes = chunk_max_bytes
        self._writer = Writer(self.path, version=METADATA_VERSION, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        storage = self._writer.storage
        # rosbags' McapWriter: the pending chunk is storage.chunk.bio, close_chunk() writes it to storage.bio.
        if not (hasattr(storage, "close_chunk") and hasattr(storage, "chunk") and hasattr(storage, "bio")):
            raise RuntimeError("unsupported rosbags version: MCAP writer without close_chunk() (pin rosbags==0.11.9)")
        if self._writer.compression_mode != CompressionMode.NONE:
            raise RuntimeError("BagWriter writes uncompressed MCAP records only")
        self._storage = storage
        self._connections: dict[str, Any] = {}
        self._chunk_opened_at: float | None = None
        self.message_count = 0
        self.chunks_written = 0
        self.closed = False

    @property
    def mcap_path(self) -> Path:
        """The ``.mcap`` file inside the bag directory."""
        return Path(self._storage.path)

    def add_topic(self, topic: str, msgtype: str, qos: Qos | None = None) -> None:
        """Register ``topic`` of type ``msgtype`` (e.g. ``std_msgs/msg/Float64``)."""
        if topic in self._connections:
            raise ValueError(f"topic registered twice in bag {self.path}: {topic}")
        self._connections[topic] = self._writer.add_connection(
            topic,
            ros_type_to_bag_type(msgtype),
            typestore=typestore(),
            offered_qos_profiles=[qos or qos_for_bag()],
        )

    def set_custom_data(self, key: str, value: str) -> None:
        """Add a ``custom_data`` entry to ``metadata.yaml`` (written on close)."""
        self._writer.set_custom_data(key, value)

    def write(self, topic: str, t_ns: int, raw: bytes | memoryview) -> None:
        """Append one CDR-serialized message received at ``t_ns`` [ns since the epoch].

        The MCAP message record (opcode 0x05: channel id, sequence 0, log and publish
        time, data) is appended to the pending chunk here, with the bookkeeping rosbags'
        ``Writer.write`` does (message counts, time range, the chunk's message index):
        the same bytes, without its linear search of the connection list and its five
        small writes per record, the recorder's largest cost per message.
        """
        conn = self._connections[topic]
        t = int(t_ns)
        w, st = self._writer, self._storage
        chunk = st.chunk
        w.counts[conn.id] += 1
        if t < w.min_timestamp:
            w.min_timestamp = t
        if t > w.max_timestamp:
            w.max_timestamp = t
        if t < st.message_start_time:
            st.message_start_time = t
        if t > st.message_end_time:
            st.message_end_time = t
        st.channel_stats[conn.id] += 1
        if t < chunk.message_start_time:
            chunk.message_start_time = t
        if t > chunk.message_end_time:
            chunk.message_end_time = t
        bio = chunk.bio
        chunk.msgs[conn.id].append((t, bio.tell()))
        bio.write(_MSG_HEAD.pack(0x05, MSG_RECORD_FIXED + len(raw), conn.id, 0, t, t))
        bio.write(raw)
        self.message_count += 1
        if self._chunk_opened_at is None:
            self._chunk_opened_at = time.monotonic()
        if bio.tell() >= self.chunk_max_bytes:
            self.flush_chunk()

    def tick(self) -> None:
        """Close the pending chunk if it is older than ``chunk_period_s`` (call periodically)."""
        if self._chunk_opened_at is not None and time.monotonic() - self._chunk_opened_at >= self.chunk_period_s:
            self.flush_chunk()

    def flush_chunk(self) -> None:
        """Write the pending chunk and its message index to the file and flush it to the OS."""
        if self.closed or not self._storage.chunk.bio.tell():
            return
        self._storage.close_chunk()
        self._storage.bio.flush()
        self._chunk_opened_at = None
        self.chunks_written += 1

    def close(self) -> None:
        """Write the last chunk, the MCAP summary and footer, and ``metadata.yaml``."""
        if self.closed:
            return
        self._writer.close()
        self.closed = True
        set_ros_distro(self.path / "metadata.yaml")

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def set_ros_distro(metadata: Path, distro: str = ROS_DISTRO) -> None:
    """Write ``ros_distro: <distro>`` into a bag's ``metadata.yaml`` (rosbags writes its own
    name there); atomically (temporary file + rename)."""
    import os

    text = metadata.read_text(encoding="utf-8")
    new = re.sub(r"(?m)^(\s*ros_distro:\s*).*$", lambda m: m.group(1) + distro, text, count=1)
    if new == text:
        return
    tmp = metadata.with_name(metadata.name + ".tmp")
    tmp.write_text(new, encoding="utf-8")
    os.replace(tmp, metadata)


@dataclass
class BagInfo:
    """What :func:`bag_info` found.

    Attributes
    ----------
    path : the bag directory or ``.mcap`` file given
    mcap_files : the MCAP files read, in order
    complete : ``metadata.yaml`` present (bag closed cleanly)
    topics : topic -> message type
    message_count : messages read
    truncated : the last MCAP file ended inside a record (writer was killed)
    damage : what could not be read (unreadable ``metadata.yaml``, a corrupt or truncated
        ``.mcap`` record), one text per problem, naming the file; what came before it
        was salvaged
    """

    path: Path
    mcap_files: list[Path]
    complete: bool
    topics: dict[str, str] = field(default_factory=dict)
    message_count: int = 0
    truncated: bool = False
    damage: list[str] = field(default_factory=list)


def _locate(path: str | Path) -> tuple[Path, list[Path], bool]:
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"bag not found: {p}")
    if p.is_file():
        if p.suffix != ".mcap":
            raise ValueError(f"not an MCAP file or rosbag2 directory: {p}")
        return p, [p], False
    files = sorted(p.glob("*.mcap"))
    if not files:
        raise ValueError(f"no .mcap file in bag directory {p} (only MCAP storage is supported)")
    return p, files, (p / "metadata.yaml").is_file()


def bag_set(path: str | Path) -> list[Path]:
    """The bags under ``path``: ``[path]`` for a bag or ``.mcap`` file, else its sub-directories holding bags.

    ``comems4build launch --buildings N`` writes one bag per building, ``bag/building_<i>/``.
    """
    p = Path(path)
    if not p.is_dir() or any(p.glob("*.mcap")) or (p / "metadata.yaml").exists():
        return [p]
    subs = sorted((d for d in p.iterdir() if d.is_dir() and any(d.glob("*.mcap"))), key=lambda d: _ns_key(d.name))
    return subs or [p]


def iter_messages(
    path: str | Path, topics: Iterable[str] | None = None, info: BagInfo | None = None
) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield ``(topic, msgtype, log_time_ns, cdr_bytes)`` of a bag, in log-time order per file.

    ``path`` is a rosbag2 directory or a bare ``.mcap`` file. A complete bag is read with
    rosbags' ``AnyReader``; a bag without ``metadata.yaml`` (recorder killed) is read
    sequentially from its ``.mcap`` files up to the last complete record. Pass a
    :class:`BagInfo` (e.g. from :func:`bag_info`) as ``info`` to have it filled.
    """
    parts = bag_set(path)
    if len(parts) > 1 or parts[0] != Path(path):
        for part in parts:
            yield from iter_messages(part, topics, info)
        if info is not None:
            info.path = Path(path)
        return
    root, files, complete = _locate(path)
    wanted = None if topics is None else set(topics)
    info = info if info is not None else BagInfo(root, [], False)
    first = not info.mcap_files
    info.path = root
    info.mcap_files.extend(files)
    info.complete = complete if first else (info.complete and complete)
    seen: set[tuple[str, int, bytes]] = set()
    if complete:
        from rosbags.highlevel import AnyReader

        try:
            with AnyReader([root], default_typestore=typestore()) as reader:
                conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
                info.topics.update({c.topic: c.msgtype for c in reader.connections})
                for conn, t_ns, raw in reader.messages(connections=conns):
                    seen.add((conn.topic, t_ns, bytes(raw)))
                    info.message_count += 1
                    yield conn.topic, conn.msgtype, t_ns, raw
            return
        except Exception as exc:  # noqa: BLE001 (rosbags, yaml, struct and decompression errors alike)
            # Salvage: read the .mcap records sequentially (as for a killed recorder),
            # skipping the messages already yielded.
            info.complete = False
            info.damage.append(f"{root}: not readable as a complete bag ({_brief(exc)}); salvaged record by record")
    yield from _stream_messages(files, wanted, info, seen)


def _stream_messages(
    files: list[Path], wanted: set[str] | None, info: BagInfo, seen: set[tuple[str, int, bytes]]
) -> Iterator[tuple[str, str, int, bytes]]:
    """Records of ``.mcap`` files read in file order, up to the first truncated or corrupt record."""
    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    for f in files:
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        with f.open("rb") as fh:
            records = StreamReader(fh).records
            while True:
                try:
                    rec = next(records)
                except StopIteration:
                    break
                except EndOfFile:
                    info.truncated = True
                    info.damage.append(f"{f}: ends inside a record (truncated); read up to there")
                    break
                except Exception as exc:  # noqa: BLE001 (corrupt record: bad magic, length, CRC, compression)
                    info.truncated = True
                    info.damage.append(f"{f}: corrupt record before byte {fh.tell()} ({_brief(exc)}); "
                                       "read up to there")
                    break
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    channels[rec.id] = (rec.topic, schemas.get(rec.schema_id, ""))
                    info.topics[rec.topic] = schemas.get(rec.schema_id, "")
                elif isinstance(rec, Message):
                    if rec.channel_id not in channels:
                        continue
                    topic, msgtype = channels[rec.channel_id]
                    if wanted is not None and topic not in wanted:
                        continue
                    if seen and (topic, rec.log_time, bytes(rec.data)) in seen:
                        continue
                    info.message_count += 1
                    yield topic, msgtype, rec.log_time, rec.data


def _brief(exc: Exception) -> str:
    """``Type: first line of the message`` (at most 160 characters)."""
    text = (str(exc).strip().splitlines() or [""])[0]
    return f"{type(exc).__name__}: {text[:160]}"


def bag_info(path: str | Path) -> BagInfo:
    """Read the whole bag once and report files, completeness, topics and message count."""
    info = BagInfo(Path(path), [], False)
    for _ in iter_messages(path, info=info):
        pass
    return info


def decode(msgtype: str, raw: bytes | memoryview) -> Any:
    """Deserialize CDR bytes of ``msgtype`` with the Jazzy typestore."""
    return typestore().deserialize_cdr(raw, ros_type_to_bag_type(msgtype))


# ---------------------------------------------------------------------- bag -> timeseries
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
#: Steps before the last record of a cut bag that the gap check leaves out (feed
#: look-ahead + 1) [steps].
CUT_TAIL_STEPS = 5
#: File the recorder writes next to the MCAP file with the run's description.
RUN_INFO_FILE = "run_info.json"


@dataclass
class BagRun:
    """One building's run rebuilt from a bag.

    Attributes
    ----------
    namespace : ``/`` or ``/building_<i>``
    timeseries : one row per step, columns of ``comems4build_ros.sim.TIMESERIES_COLUMNS``
        (plus ``ems_<key>`` when the EMS published its step_info for every step)
    n_steps : steps of the run according to ``feed/truth`` (None if never recorded)
    first_ns, last_ns : receive times of the first message and of the last ``plant/record`` [ns]
    counters : the plant's fault counters after the last recorded step
    gaps : topic -> steps of the recorded run with no message on it (:func:`find_gaps`)
    ems, scenario : EMS name (from ``ems/info``) and scenario description (``feed/info``)
        as the nodes announced them, None if not recorded
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

    @property
    def complete(self) -> bool:
        """Every step of the run is in the bag."""
        return self.n_steps is not None and len(self.timeseries) == self.n_steps


def read_run_info(path: str | Path) -> dict[str, Any]:
    """The ``run_info.json`` beside the MCAP file (``{}`` if absent)."""
    import json

    p = bag_set(path)[0]
    f = (p if p.is_dir() else p.parent) / RUN_INFO_FILE
    if not f.is_file():
        return {}
    try:
        out = json.loads(f.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{f}: invalid JSON: {exc}") from None
    if not isinstance(out, dict):
        raise ValueError(f"{f}: expected a JSON object")
    return out


def _split(topic: str, name: str) -> str | None:
    """Namespace of ``topic`` if it ends with the contract name ``name``."""
    if topic == f"/{name}":
        return "/"
    if topic.endswith(f"/{name}"):
        return topic[: -len(name) - 1]
    return None


def read_runs(path: str | Path, timezone: str, info: BagInfo | None = None) -> dict[str, BagRun]:
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
    """
    import json

    import pandas as pd

    from ..sim import TIMESERIES_COLUMNS
    from .contract import load_contract

    contract = load_contract()
    layout = contract.topic(RECORD_TOPIC).layout({})
    truth_layout = contract.topic(TRUTH_TOPIC).layout({})
    n_idx = truth_layout.index["n_steps"]
    info = info if info is not None else BagInfo(Path(path), [], False)
    records: dict[str, dict[int, tuple[int, Any]]] = {}
    infos: dict[str, dict[int, dict[str, float]]] = {}
    ems_names: dict[str, str] = {}
    scenarios: dict[str, dict[str, Any]] = {}
    n_steps: dict[str, int] = {}
    seen: dict[str, set[int]] = {}  # topic -> steps with a message (gap check)
    first_ns: int | None = None
    for topic, msgtype, t_ns, raw in iter_messages(path, info=info):
        first_ns = t_ns if first_ns is None else min(first_ns, t_ns)
        ns = _split(topic, RECORD_TOPIC)
        if ns is not None:
            data = decode(msgtype, raw).data
            if len(data) != layout.length:
                raise ValueError(
                    f"bag {path}: topic '{topic}': {len(data)} elements, the contract layout has {layout.length}"
                )
            step = int(data[0])
            records.setdefault(ns, {}).setdefault(step, (t_ns, data))
            continue
        if msgtype.endswith("Float64MultiArray"):
            data = decode(msgtype, raw).data
            if len(data):
                seen.setdefault(topic, set()).add(int(data[0]))
            ns = _split(topic, TRUTH_TOPIC)
            if ns is not None and ns not in n_steps:
                n_steps[ns] = int(data[n_idx])
            continue
        ns = _split(topic, INFO_TOPIC)
        if ns is not None:
            try:
                msg = json.loads(decode(msgtype, raw).data)
                step = int(msg["step"])
                infos.setdefault(ns, {})[step] = {k: float(v) for k, v in msg["info"].items()}
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"bag {path}: topic '{topic}': invalid step info: {exc}") from None
            seen.setdefault(topic, set()).add(step)
            if isinstance(msg.get("ems"), str):
                ems_names.setdefault(ns, msg["ems"])
            continue
        ns = _split(topic, STEP_TOPIC)
        if ns is not None:
            seen.setdefault(topic, set()).add(int(decode(msgtype, raw).data))
            continue
        ns = _split(topic, FEED_INFO_TOPIC)
        if ns is not None:
            try:
                scenarios.setdefault(ns, dict(json.loads(decode(msgtype, raw).data)))
            except (ValueError, TypeError) as exc:
                raise ValueError(f"bag {path}: topic '{topic}': invalid JSON: {exc}") from None
    if not records:
        topics = ", ".join(sorted(info.topics)) or "none"
        damage = f"; damage: {'; '.join(info.damage)}" if info.damage else ""
        raise ValueError(f"bag {path}: no '{RECORD_TOPIC}' messages could be read (topics: {topics}){damage}")
    columns = [c for c in TIMESERIES_COLUMNS if c != "time"]
    counter_names = ("fallback_steps", "rejected_commands", "wrong_step_commands", "foreign_commands")
    runs: dict[str, BagRun] = {}
    for ns in sorted(records, key=_ns_key):
        by_step = records[ns]
        steps = sorted(by_step)
        expected = list(range(len(steps)))
        if steps != expected:
            missing = sorted(set(range(steps[-1] + 1)) - set(steps))
            raise ValueError(
                f"bag {path}: topic '{resolve_ns(ns, RECORD_TOPIC)}': steps missing in the middle of the run: "
                f"{_ranges(missing)} (recorder overloaded or messages lost)"
            )
        rows = [layout.unpack(by_step[k][1]) for k in steps]
        ts = pd.DataFrame({c: [r[c] for r in rows] for c in columns})
        times = pd.to_datetime([r["time_unix_s"] for r in rows], unit="s", utc=True).tz_convert(timezone)
        ts.insert(0, "time", [t.isoformat() for t in times])
        ts = ts[list(TIMESERIES_COLUMNS)]
        step_infos = infos.get(ns, {})
        if step_infos and all(k in step_infos for k in steps):
            ts = pd.concat([ts, pd.DataFrame([step_infos[k] for k in steps]).add_prefix("ems_")], axis=1)
        last = rows[-1]
        complete = n_steps.get(ns) is not None and len(steps) == n_steps[ns]
        fallback = {k for k, r in zip(steps, rows) if r["fallback"]}
        runs[ns] = BagRun(
            namespace=ns,
            timeseries=ts,
            n_steps=n_steps.get(ns),
            first_ns=int(first_ns or 0),
            last_ns=max(t for t, _ in by_step.values()),
            counters={c: int(last[c]) for c in counter_names},
            gaps=find_gaps(contract, ns, len(steps), fallback, seen, complete, set(info.topics)),
            ems=ems_names.get(ns),
            scenario=scenarios.get(ns),
        )
    return runs


def is_per_step(spec: Any) -> bool:
    """Whether a contract topic carries one message per step (its step in the message):
    every ``Float64MultiArray`` topic (element 0), ``plant/step`` and ``ems/info``. The gap
    check and the recorder's end of run expect each step of these."""
    return bool(spec.is_array) or spec.name in (STEP_TOPIC, INFO_TOPIC)


def find_gaps(
    contract: Any,
    ns: str,
    n: int,
    fallback: set[int],
    seen: dict[str, set[int]],
    complete: bool,
    recorded: set[str] | None = None,
) -> dict[str, list[int]]:
    """Steps of a recorded run with no message, per topic of namespace ``ns``.

    Checked: every ``Float64MultiArray`` topic of the contract (element 0 is the step),
    ``plant/step`` and, if the EMS published it at all, ``ems/info``, among the topics the
    bag records (``recorded``: its connections; None = all; a topic left out of a
    recording is not a gap); steps ``0 .. n-1``
    (``n`` = recorded ``plant/record`` steps), except the fallback steps for the EMS's
    topics (no command is expected there). A bag cut short (recorder killed) is checked
    up to :data:`CUT_TAIL_STEPS` steps before its last record (the feed runs ahead and
    the last messages before the cut need not all be in), and each topic with messages
    only up to its own last recorded step: the recorder's queues of different topics can
    be many steps apart when it is killed (what it had not written is the cut, reported
    as ``bag_incomplete``; a step missing inside a topic's recorded span is a gap).
    """
    roles = {name: spec.role for name, spec in contract.nodes.items()}
    last = n if complete else max(0, n - CUT_TAIL_STEPS)
    out: dict[str, list[int]] = {}
    for spec in contract.topics.values():
        if spec.name == RECORD_TOPIC:
            continue
        full = resolve_ns(ns, spec.name)
        if recorded is not None and full not in recorded:
            continue
        if not is_per_step(spec) or (spec.name == INFO_TOPIC and full not in seen):
            continue
        from_ems = any(roles.get(p) == "ems" for p in spec.publishers)
        got = seen.get(full, set())
        end = last if complete or not got else min(last, max(got) + 1)
        missing = [k for k in range(end) if k not in got and not (from_ems and k in fallback)]
        if missing:
            out[full] = missing
    return out


class BagGapError(ValueError):
    """The bag misses messages in the middle of a run (names topics and steps)."""


def describe_gaps(gaps: dict[str, list[int]]) -> str:
    """``topic: N step(s) (ranges)`` per topic, one per line."""
    return "\n".join(f"  {t}: {len(steps)} step(s) missing ({_ranges(steps)})" for t, steps in sorted(gaps.items()))


def resolve_ns(ns: str, name: str) -> str:
    """``/`` + ``a/b`` -> ``/a/b``; ``/building_1`` + ``a/b`` -> ``/building_1/a/b``."""
    return f"{ns.rstrip('/')}/{name}"


def _ns_key(ns: str) -> tuple[int, str]:
    tail = ns.rsplit("_", 1)[-1]
    return (int(tail), ns) if tail.isdigit() else (-1, ns)


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


def building_dir(out: Path, namespace: str, n_namespaces: int) -> Path:
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
    """Weekly KPIs and summary of every building in a bag, with the in-process KPI code.

    Writes, per namespace, ``timeseries.csv`` (optional), ``weekly.csv`` and
    ``summary.json`` through :func:`comems4build_ros.sim.write_run` (into ``out`` for a
    single building in the root namespace, else into ``out/building_<i>/``, and then
    ``out/weekly.csv`` with a ``building`` column and ``out/summary.json`` with one
    summary per building).

    Parameters
    ----------
    path : rosbag2 directory or ``.mcap`` file
    out : output directory
    params : plant parameters (default: those named in the bag's ``run_info.json``)
    wall_s : wall time of the run [s] for the summary (the launcher's; None for a bag
        evaluated on its own: the bag does not know it)
    accept_gaps : evaluate a bag with messages missing on some topic (default: refuse)

    Summary entries besides the KPIs (as in-process): ``ems``, ``scenario``, ``forecast``
    from ``run_info.json`` or, without it, as the EMS (``ems/info``) and the feed
    (``feed/info``) announced them in the bag; ``wall_s``; ``ems_s`` = None (the
    controller's own compute time is not in the bag); ``bag_duration_s`` (receive time of
    the last record minus that of the first message); ``lost_messages`` (topic -> steps
    without a message, ``{}`` for a complete recording). An incomplete run or bag adds
    ``bag_incomplete`` (steps recorded and expected, whether ``metadata.yaml`` was
    read, whether an ``.mcap`` file ended early, and the damage found, see
    :class:`BagInfo`); a partial last week is left out of the weekly medians like any
    partial week. Fault counters of the plant other than fallback steps are added as
    ``ros_faults`` when non-zero. Every file is written all-or-nothing.

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

    from ..config import load_plant_params
    from ..fileio import atomic_dir
    from ..sim import evaluate_timeseries, write_run

    out = Path(out)
    run_info = read_run_info(path)
    if params is None:
        params = load_plant_params(run_info.get("config_files") or [], run_info.get("overrides") or {})
    info = BagInfo(Path(path), [], False)
    runs = read_runs(path, params.site.timezone, info)
    gaps = {t: steps for run in runs.values() for t, steps in run.gaps.items()}
    if gaps and not accept_gaps:
        raise BagGapError(
            f"bag {path}: messages missing (lost in the recording) on {len(gaps)} topic(s):\n{describe_gaps(gaps)}\n"
            "KPIs from plant/record would still be exact, but the bag is not a complete record of the run; "
            "evaluate it anyway with --accept-gaps"
        )
    summaries: dict[str, dict[str, Any]] = {}
    weekly_parts = []
    for ns, run in runs.items():
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
        if not run.complete or not info.complete or info.damage:
            extra["bag_incomplete"] = {
                "steps_recorded": len(run.timeseries),
                "steps_expected": run.n_steps,
                "metadata_yaml": info.complete,
                "truncated_mcap": info.truncated,
                "damage": list(info.damage),
            }
        faults = {k: v for k, v in run.counters.items() if k != "fallback_steps" and v}
        if faults:
            extra["ros_faults"] = faults
        result = evaluate_timeseries(run.timeseries, params, extra)
        write_run(result, building_dir(out, ns, len(runs)), timeseries=timeseries)
        summaries[ns] = result.summary
        weekly_parts.append(result.weekly.assign(building=ns.strip("/") or "root"))
    if len(runs) > 1 or "/" not in runs:
        weekly = pd.concat(weekly_parts, ignore_index=True)
        weekly = weekly[["building", *[c for c in weekly.columns if c != "building"]]]
        combined = {"buildings": {ns.strip("/"): s for ns, s in summaries.items()}}
        with atomic_dir(out) as tmp:
            weekly.to_csv(tmp / "weekly.csv", index=False)
            (tmp / "summary.json").write_text(json.dumps(combined, indent=2, default=_json_default) + "\n", "utf-8")
    return summaries


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
    runs = read_runs(path, "UTC")
    return {t: len(steps) for run in runs.values() for t, steps in sorted(run.gaps.items())}


def scenario_label(name: Any) -> str | None:
    """The feed's scenario name (``Scenario.name``, as the in-process summary has it), None if absent."""
    return name if isinstance(name, str) and name else None


def _forecast_of(ems: str | None, mode: Any) -> str | None:
    """Forecast mode of the summary: the feed's mode for an MPC-level EMS, else None (as in-process)."""
    if ems is None or not isinstance(mode, str):
        return None
    from ..ems import UnknownEMSError, controller_class

    try:
        return mode if controller_class(ems).info_level == "mpc" else None
    except UnknownEMSError:
        return None
