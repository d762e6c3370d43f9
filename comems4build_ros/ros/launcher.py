"""Python launcher of the node set: separate OS processes on an isolated ROS 2 domain.

:func:`launch` starts, per building, ``plant_sim``, ``feed`` and the EMS node, plus one
``recorder`` for the whole graph, each as its own OS process (the venv's console script,
or ``python -m <module>`` when none is installed), waits for the run, stops every
process and evaluates the bag with the in-process KPI code
(:func:`comems4build_ros.ros.bag.evaluate_bag`). No rclpy in this process.

Isolation: the children get the parent's full environment (the ROS wheels' bootstrap
needs its ``LD_LIBRARY_PATH``; TOOLCHAIN facts) plus ``ROS_DOMAIN_ID`` (a free id, see
:func:`acquire_domain_id`), ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, ``ROS_LOG_DIR``
under the output directory, ``PYTHONPATH`` starting with the directory this package
was imported from (the nodes run the same code as the launcher) and, unless set,
``FASTDDS_DEFAULT_PROFILES_FILE`` = ``launch_scripts/fastdds_profile.xml`` (deep
shared-memory port queues: without it a briefly descheduled recorder loses messages).

Process hygiene: every child runs in its own session (a terminal Ctrl-C reaches only the
launcher, which then stops the children in order) and gets ``PR_SET_PDEATHSIG`` =
SIGTERM (if the launcher itself is killed, the kernel stops the children). Stopping is
SIGINT (rclpy shuts down cleanly), then SIGTERM after ``grace_s``, then SIGKILL; the
recorder is stopped last so that it closes the bag. Any node that exits while the run is
in progress (a crash, or a plant exiting with an error) stops the whole launch with
:class:`LaunchError` naming the node, its exit code and its log file.

``--buildings N``: building ``i`` runs under the namespace ``/building_<i>`` with
scenario seed ``seed + i`` (default scenario) and its own recorder writing
``bag/building_<i>/`` (one recorder for all namespaces spent its time in rclpy's executor,
whose per-wake-up bookkeeping grows with the square of the number of subscriptions: 512
subscriptions for 16 buildings could not keep up).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

#: Console script of each node and the module run with ``python -m`` when there is none.
NODE_MODULES: dict[str, str] = {
    "plant_sim": "comems4build_ros.ros.nodes.plant_sim",
    "feed": "comems4build_ros.ros.nodes.feed",
    "recorder": "comems4build_ros.ros.nodes.recorder",
    "replay": "comems4build_ros.ros.nodes.replay",
}
#: EMS name -> console script (EMS without one run as ``python -m ...ems_node --ems NAME``).
EMS_SCRIPTS: dict[str, str] = {"fuzzy": "fuzzy_ems", "rbc": "rbc_ems", "mpc": "mpc_ems"}
EMS_MODULE = "comems4build_ros.ros.nodes.ems_node"
#: Domain ids tried by :func:`acquire_domain_id` (0..101 keep Fast DDS's ports below the
#: Linux ephemeral range).
DOMAIN_IDS = range(1, 102)
LOCK_DIR = Path(tempfile.gettempdir())
#: Wait after SIGINT and after SIGTERM before the next signal [s].
GRACE_S = 5.0
#: The recorder may need longer to write the summary of a large bag [s].
RECORDER_GRACE_S = 20.0
#: Wait for the recorder to drain its queues and stop by itself after the last plant exited [s].
RECORDER_DRAIN_S = 60.0
#: Poll period of the supervision loop [s].
POLL_S = 0.05
#: Recorder progress line period [s].
PROGRESS_PERIOD_S = 0.25
#: UDP port of the discovery server: this base + the (locked) domain id.
DISCOVERY_PORT_BASE = 11811
#: Fast DDS profile given to every node unless the user sets one (see the file's comment).
FASTDDS_PROFILE = "fastdds_profile.xml"
#: Module of the host processes (one process per role for many buildings).
HOST_MODULE = "comems4build_ros.ros.host"
#: Buildings per recorder process in host mode (one recorder process for all 16 buildings
#: would hold 16 x 32 subscriptions in one executor, see the module docstring).
HOST_BUILDINGS_PER_RECORDER = 4
#: Host mode: plant_sim's step timeout [s]. One EMS process answers every building in
#: turn, so on a loaded machine a command can come later than the 5 s meant to detect a
#: dead EMS (a dead host process stops the launch anyway). Overridden by ``plant_params``.
HOST_STEP_TIMEOUT_S = 60.0
#: Host mode: plant_sim's watchdog and the recorder's housekeeping timer periods [s]
#: (instead of 0.02 s and 0.05 s: N nodes' timers wake one shared executor N times as often).
HOST_WATCHDOG_PERIOD_S = 0.1
HOST_RECORDER_TICK_S = 0.2
#: prctl option number of PR_SET_PDEATHSIG (linux/prctl.h).
PR_SET_PDEATHSIG = 1


class LaunchError(RuntimeError):
    """The launch failed: a node crashed or exited early, or the run timed out."""


# ---------------------------------------------------------------------- domain ids
@contextlib.contextmanager
def acquire_domain_id(preferred: int | None = None) -> Iterator[int]:
    """Hold an exclusive lock on a ROS domain id for the duration of the block.

    With ``preferred`` that id is locked (waiting is not an option: an error if another
    launcher holds it); otherwise the first free id of :data:`DOMAIN_IDS`, starting at an
    offset derived from the process id, is taken. Locks are ``flock`` locks on
    ``$TMPDIR/comems4build_ros_domain_<id>.lock`` and vanish with the process.
    """
    ids: Sequence[int]
    if preferred is not None:
        if not 0 <= preferred <= 232:
            raise ValueError(f"ROS domain id {preferred} outside 0..232")
        ids = [preferred]
    else:
        n = len(DOMAIN_IDS)
        off = os.getpid() % n
        ids = [DOMAIN_IDS[(off + i) % n] for i in range(n)]
    for did in ids:
        fh = open(LOCK_DIR / f"comems4build_ros_domain_{did}.lock", "a")  # noqa: SIM115
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            fh.close()
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                continue
            raise
        try:
            yield did
        finally:
            fh.close()
        return
    raise LaunchError(f"no free ROS domain id (tried {ids[0]}..{ids[-1]})")


# ---------------------------------------------------------------------- processes
def _set_pdeathsig() -> None:
    """In the child before exec: receive SIGTERM when the launcher dies."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the launcher's own clean-up still applies
        pass


def _child_setup(nice: int) -> Callable[[], None]:
    def setup() -> None:
        _set_pdeathsig()
        if nice:
            os.nice(nice)

    return setup


def node_command(executable: str, ems: str | None = None) -> list[str]:
    """Command line of a node: the venv's console script if installed, else ``python -m``.

    ``executable`` is a key of :data:`NODE_MODULES` or ``"ems"`` (then ``ems`` names it).
    """
    bindir = Path(sys.executable).parent
    if executable == "ems":
        if ems is None:
            raise ValueError("node_command('ems') needs the EMS name")
        script = EMS_SCRIPTS.get(ems)
        if script and (bindir / script).is_file():
            return [str(bindir / script)]
        return [sys.executable, "-m", EMS_MODULE, "--ems", ems]
    module = NODE_MODULES[executable]
    if (bindir / executable).is_file():
        return [str(bindir / executable)]
    return [sys.executable, "-m", module]


def ros_args(namespace: str = "", params: dict[str, Any] | None = None, params_files: Sequence[str] = ()) -> list[str]:
    """``--ros-args`` part of a command line: namespace, ``-p name:=value``, params files.

    Values are written as YAML (lists and strings as JSON, which YAML reads); empty
    lists are left out (their type cannot be inferred).
    """
    out = ["--ros-args"]
    if namespace and namespace != "/":
        out += ["-r", f"__ns:={namespace}"]
    for f in params_files:
        out += ["--params-file", str(f)]
    for name, value in (params or {}).items():
        if isinstance(value, (list, tuple)):
            if not value:
                continue
            text = json.dumps([str(v) for v in value] if all(isinstance(v, str) for v in value) else list(value))
        elif isinstance(value, bool):
            text = "true" if value else "false"
        elif isinstance(value, str):
            text = json.dumps(value)
        else:
            text = repr(value)
        out += ["-p", f"{name}:={text}"]
    return out


@dataclass
class Child:
    """One running node process."""

    name: str  # e.g. "plant_sim" or "building_3/plant_sim"
    role: str  # plant, feed, ems, recorder, replay
    proc: subprocess.Popen
    log_path: Path
    stdout_reader: threading.Thread | None = None

    def tail(self, lines: int = 8) -> str:
        """Last lines of the node's log."""
        try:
            text = self.log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""
        return "\n".join(text.rstrip().splitlines()[-lines:])


class ProcessGroup:
    """Node processes started with one environment; stops them all, in order, on exit.

    Parameters
    ----------
    env : environment of every child
    log_dir : directory of the per-node log files (stdout and stderr)
    """

    def __init__(self, env: dict[str, str], log_dir: Path) -> None:
        self.env = env
        self.log_dir = log_dir
        self.children: list[Child] = []
        log_dir.mkdir(parents=True, exist_ok=True)

    def start(
        self,
        name: str,
        role: str,
        argv: Sequence[str],
        on_stdout_line: Callable[[str], None] | None = None,
        nice: int = 0,
    ) -> Child:
        """Start ``argv``; with ``on_stdout_line`` its stdout is read line by line in a thread.

        ``nice`` lowers the child's CPU priority (a node off the critical path of a step).
        """
        log_path = self.log_dir / f"{name.replace('/', '__')}.log"
        log: IO[bytes] = log_path.open("wb")
        try:
            proc = subprocess.Popen(
                list(argv),
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE if on_stdout_line else log,
                stderr=log,
                start_new_session=True,
                preexec_fn=_child_setup(nice),
            )
        finally:
            log.close()
        child = Child(name, role, proc, log_path)
        if on_stdout_line is not None:
            assert proc.stdout is not None
            stream = proc.stdout

            def pump() -> None:
                for raw in stream:
                    on_stdout_line(raw.decode("utf-8", errors="replace").rstrip("\n"))

            child.stdout_reader = threading.Thread(target=pump, name=f"stdout-{name}", daemon=True)
            child.stdout_reader.start()
        self.children.append(child)
        return child

    def running(self) -> list[Child]:
        """Children that have not exited."""
        return [c for c in self.children if c.proc.poll() is None]

    def stop(self, children: Sequence[Child], grace_s: float = GRACE_S) -> None:
        """SIGINT, then SIGTERM after ``grace_s``, then SIGKILL; waits until all are gone."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            alive = [c for c in children if c.proc.poll() is None]
            if not alive:
                break
            for c in alive:
                with contextlib.suppress(ProcessLookupError):
                    c.proc.send_signal(sig)
            deadline = time.monotonic() + grace_s
            while time.monotonic() < deadline and any(c.proc.poll() is None for c in alive):
                time.sleep(0.02)
        for c in children:
            with contextlib.suppress(subprocess.TimeoutExpired):
                c.proc.wait(timeout=grace_s)
            if c.stdout_reader is not None:
                c.stdout_reader.join(timeout=1.0)
            if c.proc.stdout is not None:
                c.proc.stdout.close()

    def stop_all(self, grace_s: float = GRACE_S, recorder_grace_s: float = RECORDER_GRACE_S) -> None:
        """Stop every node: plants, feeds and EMS first, then the recorder (it closes the bag), then discovery."""
        self.stop([c for c in self.children if c.role not in ("recorder", "discovery")], grace_s)
        self.stop([c for c in self.children if c.role == "recorder"], recorder_grace_s)
        self.stop([c for c in self.children if c.role == "discovery"], grace_s)

    def __enter__(self) -> ProcessGroup:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
        marker = self.env.get("ROS_LOG_DIR")
        if marker:  # anything a node started itself and left behind
            sweep("ROS_LOG_DIR", marker)


def processes_with_env(name: str, value: str) -> list[int]:
    """Ids of this user's processes whose environment has ``name=value`` (Linux ``/proc``).

    Every node of a launch carries the launch's own ``ROS_LOG_DIR``, so this finds all
    processes of one launch, including any a node may have started itself.
    """
    needle = f"{name}={value}".encode()
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            env = (d / "environ").read_bytes()
        except OSError:
            continue
        if needle in env.split(b"\0"):
            out.append(int(d.name))
    return out


def sweep(name: str, value: str, grace_s: float = GRACE_S) -> list[int]:
    """SIGTERM, then SIGKILL, every process left with ``name=value`` in its environment."""
    left = processes_with_env(name, value)
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in left:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, sig)
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline and processes_with_env(name, value):
            time.sleep(0.05)
        if not processes_with_env(name, value):
            break
    return left


@contextlib.contextmanager
def sigterm_as_keyboard_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM to the launcher behaves like Ctrl-C (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def child_env(domain_id: int, ros_log_dir: Path, base: dict[str, str] | None = None) -> dict[str, str]:
    """The parent's full environment plus the isolation variables and PYTHONPATH."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_LOG_DIR"] = str(ros_log_dir)
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; the range above replaces it
    root_path = Path(__file__).resolve().parents[2]
    # Running from a source tree: children import this same tree. An installed package is
    # found by the children's interpreter anyway; putting site-packages on PYTHONPATH would
    # place it before the standard library (and the old 'pathlib' backport that OpenDHW
    # pulls in would then shadow the real pathlib).
    if root_path.name not in ("site-packages", "dist-packages"):
        root = str(root_path)
        parts = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != root]
        env["PYTHONPATH"] = os.pathsep.join([root, *parts])
    env["PYTHONUNBUFFERED"] = "1"
    if "FASTDDS_DEFAULT_PROFILES_FILE" not in env and "FASTRTPS_DEFAULT_PROFILES_FILE" not in env:
        profile = fastdds_profile()
        if profile is not None:
            env["FASTDDS_DEFAULT_PROFILES_FILE"] = str(profile)
    return env


def fastdds_profile() -> Path | None:
    """``fastdds_profile.xml`` (deep shared-memory port queues): source tree, then installed share."""
    src = Path(__file__).resolve().parents[2] / "launch_scripts" / FASTDDS_PROFILE
    if src.is_file():
        return src
    installed = Path(sys.prefix) / "share" / "comems4build_ros" / "launch" / FASTDDS_PROFILE
    return installed if installed.is_file() else None


# ---------------------------------------------------------------------- the launch
@dataclass
class LaunchOptions:
    """What :func:`launch` runs.

    Attributes
    ----------
    ems : EMS name (fuzzy, rbc, mpc; thermostat and mpc-qp run through ``ems_node``)
    out : output directory (``bag/``, ``log/``, ``weekly.csv``, ``summary.json``, ...)
    scenario : ``default`` or a scenario CSV path
    weeks : run length [weeks] (None = the scenario's default)
    steps : cut the run to its first ``steps`` steps (short test runs; None = all)
    start : ISO start time (CSV scenarios)
    buildings : number of independent buildings
    seed : scenario seed of building 0 (default scenario; None = the configured seed)
    config_files : parameter files merged over ``config/plant.yaml``
    overrides : ``section.key`` -> value overrides of the plant parameters
    ems_options : options of the EMS (``key=value`` strings)
    forecast : forecast mode of the MPC (None = ``config/forecast.yaml``)
    domain_id : ROS domain id (None = a free one)
    timeout_s : stop with an error after this wall time [s] (None = no limit)
    progress : show a progress bar (tqdm on stderr)
    plant_params : extra ``-p`` parameters of plant_sim (e.g. ``step_timeout_s``)
    discovery_server : use a Fast DDS discovery server (None = with more than one building
        in process-per-node mode; never in host mode)
    host_mode : one process per role hosting the nodes of all buildings (see
        :mod:`comems4build_ros.ros.host`); None = with more than one building
    buildings_per_recorder : buildings recorded by one recorder process in host mode
    """

    ems: str
    out: Path
    scenario: str = "default"
    weeks: float | None = None
    steps: int | None = None
    start: str | None = None
    buildings: int = 1
    seed: int | None = None
    config_files: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)
    ems_options: list[str] = field(default_factory=list)
    forecast: str | None = None
    domain_id: int | None = None
    timeout_s: float | None = None
    progress: bool = False
    plant_params: dict[str, Any] = field(default_factory=dict)
    discovery_server: bool | None = None
    host_mode: bool | None = None
    buildings_per_recorder: int = HOST_BUILDINGS_PER_RECORDER


@dataclass
class LaunchResult:
    """Outcome of :func:`launch`."""

    out: Path
    bag: Path
    domain_id: int
    wall_s: float  # from the first process start to the end of the run [s]
    run_s: float  # from the recorder's first record to the end of the run [s]
    summaries: dict[str, dict[str, Any]]  # namespace -> summary


def bag_dir(bag: Path, ns: str) -> Path:
    """Bag of namespace ``ns``: ``bag`` itself for the root namespace, else ``bag/building_<i>``."""
    return bag if ns == "/" else bag / ns.strip("/")


def namespaces(buildings: int) -> list[str]:
    """``["/"]`` for one building, else ``["/building_0", ...]``."""
    if buildings < 1:
        raise ValueError(f"--buildings must be >= 1, got {buildings}")
    return ["/"] if buildings == 1 else [f"/building_{i}" for i in range(buildings)]


def _feed_window(weeks: float | None, steps: int | None) -> tuple[int, int]:
    """``weeks`` and ``steps`` parameters of the feed (integer weeks, fractions via steps)."""
    from ..scenario import HOURS_PER_WEEK

    if weeks is None:
        return 0, int(steps or 0)
    whole = math.ceil(weeks - 1e-9)
    n = int(round(weeks * HOURS_PER_WEEK))
    if steps is not None:
        n = min(n, steps)
    return whole, (0 if n == whole * HOURS_PER_WEEK else n)


def run_info(opts: LaunchOptions, params: Any, seeds: list[int | None]) -> dict[str, Any]:
    """The run's description stored in the bag (``run_info.json``): what evaluate needs."""
    from ..ems import controller_class
    from ..sim import load_forecast_settings

    level = controller_class(opts.ems).info_level
    forecast = load_forecast_settings(**({"mode": opts.forecast} if opts.forecast else {})).mode
    name = "default" if opts.scenario == "default" else Path(opts.scenario).name
    return {
        "ems": opts.ems,
        "scenario": name,
        "forecast": forecast if level == "mpc" else None,
        "weeks": opts.weeks,
        "steps": opts.steps,
        "start": opts.start,
        "buildings": [{"namespace": ns, "seed": s} for ns, s in zip(namespaces(opts.buildings), seeds)],
        "config_files": [str(Path(f).resolve()) for f in opts.config_files],
        "overrides": opts.overrides,
        "ems_options": opts.ems_options,
        "timezone": params.site.timezone,
    }


def launch(opts: LaunchOptions) -> LaunchResult:
    """Run the node set, wait for the end, stop every process, evaluate the bag.

    Raises
    ------
    LaunchError
        If a node crashes or exits before the end, or ``timeout_s`` passes.
    KeyboardInterrupt
        On Ctrl-C or SIGTERM (after every child has been stopped).
    """
    from ..config import load_plant_params
    from ..scenario.settings import load_scenario_settings
    from .bag import evaluate_bag

    out = Path(opts.out)
    bag = out / "bag"
    if bag.exists():
        raise FileExistsError(f"{bag} exists: choose another --out or remove it")
    params = load_plant_params(opts.config_files, opts.overrides)
    ns_list = namespaces(opts.buildings)
    if opts.buildings > 1 and opts.scenario == "default":
        base = opts.seed if opts.seed is not None else load_scenario_settings().seed
        seeds: list[int | None] = [base + i for i in range(opts.buildings)]
    else:
        seeds = [opts.seed] * opts.buildings
    info = run_info(opts, params, seeds)
    weeks, steps = _feed_window(opts.weeks, opts.steps)
    out.mkdir(parents=True, exist_ok=True)
    if len(ns_list) > 1:
        bag.mkdir()

    common: dict[str, Any] = {"config_files": info["config_files"]}
    if opts.overrides:
        common["overrides"] = [f"{k}={json.dumps(v)}" for k, v in opts.overrides.items()]

    host = opts.host_mode if opts.host_mode is not None else opts.buildings > 1
    if host and opts.buildings_per_recorder < 1:
        raise ValueError(f"buildings_per_recorder must be >= 1, got {opts.buildings_per_recorder}")
    n_recorders = math.ceil(len(ns_list) / opts.buildings_per_recorder) if host else len(ns_list)
    progress = _Progress(n_recorders)

    bar = None
    if opts.progress:
        from tqdm import tqdm

        bar = tqdm(total=0, desc=f"launch {opts.ems} x{opts.buildings}", unit="step", mininterval=0.3, leave=False)
    try:
        with acquire_domain_id(opts.domain_id) as domain_id, sigterm_as_keyboard_interrupt():
            env = child_env(domain_id, out / "log" / "ros")
            t0 = time.monotonic()
            with ProcessGroup(env, out / "log") as group:
                use_server = opts.discovery_server
                if use_server is None:
                    use_server = opts.buildings > 1 and not host
                if use_server:
                    start_discovery_server(group, DISCOVERY_PORT_BASE + domain_id)
                recorders = []
                if host:
                    recorders, plants = _start_hosts(
                        group, opts, ns_list, seeds, common, weeks, steps, bag, info, progress, out / "host"
                    )
                for i, ns in enumerate([] if host else ns_list):
                    rec_params = {
                        "bag_path": str(bag_dir(bag, ns).resolve()),
                        "namespaces": [ns],
                        "run_info": json.dumps(info),
                        "progress_period_s": PROGRESS_PERIOD_S,
                    }
                    name = "recorder" if ns == "/" else f"{ns.strip('/')}/recorder"
                    argv = [*node_command("recorder"), *ros_args("", rec_params)]
                    recorders.append(group.start(name, "recorder", argv, progress.listener(i)))
                if not host:
                    plants = [
                        _start_building(group, opts, ns, seed, common, weeks, steps)
                        for ns, seed in zip(ns_list, seeds)
                    ]
                t_first_record = _supervise(group, recorders, plants, progress, bar, t0, opts.timeout_s)
                t_end = time.monotonic()
    finally:
        if bar is not None:
            bar.close()
    wall = t_end - t0
    run_s = t_end - (t_first_record or t0)
    summaries = evaluate_bag(bag, out, params=params, wall_s=wall)
    return LaunchResult(out, bag, domain_id, wall, run_s, summaries)


def start_discovery_server(group: ProcessGroup, port: int) -> Child | None:
    """Start ``fast-discovery-server`` on 127.0.0.1:``port`` and point every later child at it.

    With simple discovery every participant announces itself to every other one; with
    dozens of node processes on one host (``--buildings 16``: 49) that did not complete
    within minutes here. A discovery server makes discovery O(n). Returns None (simple
    discovery stays) when the tool is not installed.
    """
    exe = Path(sys.executable).parent / "fast-discovery-server"
    if not exe.is_file():
        print(f"launcher: {exe} not found, using simple discovery", file=sys.stderr)
        return None
    child = group.start("discovery_server", "discovery", [str(exe), "-i", "0", "-l", "127.0.0.1", "-p", str(port)])
    group.env = dict(group.env, ROS_DISCOVERY_SERVER=f"127.0.0.1:{port}")
    return child


class _Progress:
    """Recorded and total steps, as last reported by each recorder (thread-safe)."""

    def __init__(self, n: int) -> None:
        self._lock = threading.Lock()
        self.recorded = [0] * n
        self.total = [0] * n

    def set(self, i: int, recorded: int, total: int) -> None:
        with self._lock:
            self.recorded[i], self.total[i] = recorded, total

    def get(self) -> tuple[int, int]:
        """Recorded steps of all buildings, and their total (0 until every recorder knows its own)."""
        with self._lock:
            return sum(self.recorded), (sum(self.total) if all(self.total) else 0)

    def listener(self, i: int) -> Callable[[str], None]:
        """stdout line handler of recorder ``i``."""

        def on_line(line: str) -> None:
            parts = line.split()
            if len(parts) == 3 and parts[0] == "progress":
                self.set(i, int(parts[1]), int(parts[2]))

        return on_line


def _start_building(
    group: ProcessGroup, opts: LaunchOptions, ns: str, seed: int | None, common: dict[str, Any], weeks: int, steps: int
) -> Child:
    """Start the EMS, the feed and the plant of one building; returns the plant."""
    prefix = "" if ns == "/" else ns.strip("/") + "/"
    params = _building_params(opts, seed, common, weeks, steps)
    group.start(f"{prefix}{opts.ems}_ems", "ems", [*node_command("ems", opts.ems), *ros_args(ns, params["ems"])])
    group.start(f"{prefix}feed", "feed", [*node_command("feed"), *ros_args(ns, params["feed"])])
    return group.start(
        f"{prefix}plant_sim", "plant", [*node_command("plant_sim"), *ros_args(ns, params["plant"])]
    )


def _building_params(
    opts: LaunchOptions, seed: int | None, common: dict[str, Any], weeks: int, steps: int
) -> dict[str, dict[str, Any]]:
    """Parameters of the EMS, feed and plant of one building (role -> parameters)."""
    ems_params = dict(common)
    if opts.ems_options:
        ems_params["ems_options"] = list(opts.ems_options)
    feed_params = dict(common, scenario=str(opts.scenario), weeks=weeks, steps=steps)
    if seed is not None:
        feed_params["seed"] = int(seed)
    if opts.start:
        feed_params["start"] = opts.start
    if opts.forecast:
        feed_params["forecast_mode"] = opts.forecast
    plant_params = dict(common, wait_for_recorder=True, **opts.plant_params)
    return {"ems": ems_params, "feed": feed_params, "plant": plant_params}


def host_command(role: str, spec_path: Path) -> list[str]:
    """Command line of a host process (``python -m comems4build_ros.ros.host``)."""
    return [sys.executable, "-m", HOST_MODULE, "--role", role, "--spec", str(spec_path)]


def _start_hosts(
    group: ProcessGroup,
    opts: LaunchOptions,
    ns_list: list[str],
    seeds: list[int | None],
    common: dict[str, Any],
    weeks: int,
    steps: int,
    bag: Path,
    info: dict[str, Any],
    progress: _Progress,
    spec_dir: Path,
) -> tuple[list[Child], list[Child]]:
    """Host mode: recorder processes (one per ``buildings_per_recorder``), then one EMS,
    one feed and one plant process for all buildings; returns (recorders, [plant host])."""
    spec_dir.mkdir(parents=True, exist_ok=True)

    def write(name: str, spec: dict[str, Any]) -> Path:
        path = spec_dir / f"{name}.json"
        path.write_text(json.dumps(spec, indent=1) + "\n", encoding="utf-8")
        return path

    per = opts.buildings_per_recorder
    extra: dict[str, Any] = {}
    recorders = []
    for j in range(0, len(ns_list), per):
        nodes = [
            {"namespace": ns, "params": {
                "bag_path": str(bag_dir(bag, ns).resolve()),
                "namespaces": [ns],
                "run_info": json.dumps(info),
                "progress_period_s": 0.0,
                "tick_s": HOST_RECORDER_TICK_S,
            }}
            for ns in ns_list[j:j + per]
        ]
        name = f"host_recorder_{j // per}"
        path = write(name, dict(extra, progress_period_s=PROGRESS_PERIOD_S, nodes=nodes))
        recorders.append(group.start(name, "recorder", host_command("recorder", path), progress.listener(j // per)))
    by_role: dict[str, list[dict[str, Any]]] = {"ems": [], "feed": [], "plant": []}
    for ns, seed in zip(ns_list, seeds):
        for role, params in _building_params(opts, seed, common, weeks, steps).items():
            if role == "plant":
                params = {"step_timeout_s": HOST_STEP_TIMEOUT_S, "watchdog_period_s": HOST_WATCHDOG_PERIOD_S,
                          **params}
            by_role[role].append({"namespace": ns, "params": params})
    plant = None
    for role in ("ems", "feed", "plant"):
        path = write(f"host_{role}", dict(extra, ems=opts.ems, nodes=by_role[role]))
        child = group.start(f"host_{role}", role, host_command(role, path))
        if role == "plant":
            plant = child
    assert plant is not None
    return recorders, [plant]


def _supervise(
    group: ProcessGroup,
    recorders: list[Child],
    plants: list[Child],
    progress: _Progress,
    bar: Any,
    t0: float,
    timeout_s: float | None,
) -> float | None:
    """Wait until every plant and every recorder exited 0; returns when the first record came.

    Raises
    ------
    LaunchError
        When any other exit happens first, or after ``timeout_s``.
    """
    t_first_record: float | None = None
    t_plants_done: float | None = None
    while True:
        time.sleep(POLL_S)
        r, n = progress.get()
        if r and t_first_record is None:
            t_first_record = time.monotonic()
        if bar is not None:
            if n and bar.total != n:
                bar.reset(total=n)
            bar.n = r
            bar.refresh()
        plants_done = all(p.proc.poll() == 0 for p in plants)
        for c in group.children:
            code = c.proc.poll()
            # plants exit 0 after their last step; the recorder exits 0 once every plant said done
            if code is None or (c.role in ("plant", "recorder") and code == 0):
                continue
            raise LaunchError(
                f"node '{c.name}' exited with code {code} while the run was in progress (log: {c.log_path}):\n"
                f"{c.tail()}"
            )
        running = [r for r in recorders if r.proc.poll() is None]
        if plants_done and not running:
            return t_first_record
        if plants_done:
            t_plants_done = t_plants_done or time.monotonic()
            if time.monotonic() - t_plants_done > RECORDER_DRAIN_S:
                print(f"launcher: {len(running)} recorder(s) still running {RECORDER_DRAIN_S:g} s after the last "
                      "plant exited; stopping them (SIGINT closes the bag)", file=sys.stderr)
                for r in running:
                    r.proc.send_signal(signal.SIGINT)
                t_plants_done = time.monotonic() + RECORDER_GRACE_S  # one signal, then wait
        if timeout_s is not None and time.monotonic() - t0 > timeout_s:
            raise LaunchError(f"run not finished after {timeout_s} s (recorded {r} of {n} steps)")
