"""Supervisor: starts the processes of a :class:`~comems4build_ros.run.plan.RunPlan` and watches them.

No rclpy in this process. :func:`run_plan` writes the plan's files, starts every
process in plan order with the plan's environment, waits for the end of the run by one
exit rule, and stops everything in the plan's stop stages.

Isolation: the children get the parent's full environment (the ROS wheels' bootstrap
needs its ``LD_LIBRARY_PATH``) plus ``ROS_DOMAIN_ID`` (a free id, see
:func:`acquire_domain_id`), ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, ``ROS_LOG_DIR``
under the output directory, ``PYTHONPATH`` starting with the directory this package
was imported from (the nodes run the same code as the launcher) and, unless set,
``FASTRTPS_DEFAULT_PROFILES_FILE`` (what Fast DDS 2.x reads; ``FASTDDS_...`` for 3.x too) =
``launch_scripts/fastdds_profile.xml`` (deep
shared-memory port queues: without it a briefly descheduled recorder loses messages),
then the plan's, the network side's and the process's own environment additions.

Process hygiene: every child runs in its own session (a terminal Ctrl-C reaches only the
launcher, which then stops the children in order) and gets ``PR_SET_PDEATHSIG`` =
SIGTERM (if the launcher itself is killed, the kernel stops the children). Stopping is
SIGINT (rclpy shuts down cleanly), then SIGTERM after ``grace_s``, then SIGKILL; the
recorders are stopped after the nodes so that they close the bags, services last.

Exit rule: any process that leaves while the run is in progress fails the launch, with
one exception: exit code 0 of a process marked ``finishes`` (every node process), which
a node gives only once its part of the run is complete (:mod:`comems4build_ros.wire.exits`:
the lock-step master after its last step, feed and EMS after ``plant/done``, the recorder
once every plant is done; a signal before that gives exit code 3, a stalled run 4). The
:class:`LaunchError` (within one poll period, :data:`POLL_S`, of the exit) names the
process, its exit code and what it means, the cause the node gave (the last
``cause:`` line of its log) and the log file. The run is done when every recorder has
exited 0 (the bags are closed), whatever the other processes do; then everything still
running is stopped, a process that ignores SIGINT and SIGTERM (or is paused) is killed.

Stalls: the lock-step master ends a run whose EMS, feed, recorder or house fell silent
(``stall_steps`` step time-outs, naming it). As a backstop for a master that is itself
paused or hung, the supervisor ends a run in which no step was recorded for the plan's
``stall_s`` (naming every paused process, state ``T``); the plan's overall time limit
ends any run.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.outputs import create_file, open_dir, write_new_file
from comems4build_ros.files.paths import SOURCE_ROOT, installed_from_source
from comems4build_ros.run.plan import (
    STAGE_NODES,
    STAGE_RECORDERS,
    STAGE_SERVICES,
    RunPlan,
    discovery_hint,
    fastdds_profile,
    node_label,
    profile_env,
)
from comems4build_ros.wire.exits import CAUSE_TAG, CLEANUP_TAG, decided_before_hang, exit_meaning
from comems4build_ros.wire.tokens import private_dir, write_token_file

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
#: How often the supervisor looks for paused (SIGSTOP) processes to name them [s].
PAUSE_CHECK_S = 1.0
#: prctl option number of PR_SET_PDEATHSIG (linux/prctl.h).
PR_SET_PDEATHSIG = 1


class LaunchError(RuntimeError):
    """The launch failed: a node crashed or left early, the run stalled, or it timed out.

    Attributes
    ----------
    process : name of the process that left or is to blame (None: not known)
    code : its exit code (None: it did not exit)
    nodes : full names of the ROS nodes that process ran (empty: not known, or no node)
    cause : one line: why the run was cut (the first line of the message)
    log : its log file (None: none)
    summaries : namespace -> summary of the cut run, when the launcher could evaluate the bag
    """

    def __init__(self, message: str, process: str | None = None, code: int | None = None,
                 log: Path | None = None, nodes: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.process = process
        self.code = code
        self.nodes = tuple(nodes)
        self.log = log
        self.cause = message.splitlines()[0] if message else ""
        self.summaries: dict[str, dict[str, Any]] = {}


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
            raise InputError(f"ROS domain id {preferred} outside 0..232")
        ids = [preferred]
    else:
        n = len(DOMAIN_IDS)
        off = os.getpid() % n
        ids = [DOMAIN_IDS[(off + i) % n] for i in range(n)]
    for did in ids:
        try:  # shared by every user's launches, read-only: never opened through a link (one is passed over)
            fd = os.open(LOCK_DIR / f"comems4build_ros_domain_{did}.lock",
                         os.O_RDONLY | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            if exc.errno in (errno.ELOOP, errno.EACCES):
                continue
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                continue
            raise
        try:
            yield did
        finally:
            os.close(fd)
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


#: A node's log line as rclpy's console writes it, ``[ERROR] [1795...] [house_0.plant_sim]: cause: ...``
#: (``ros2 launch`` puts ``[<process>] `` in front): the logger's name and the message.
LOG_LINE = re.compile(r"\[(?P<name>[^\]\s]+)\]: (?P<message>.*)$")


def tagged_line(line: str) -> tuple[str, str, str] | None:
    """``(logger, tag, text)`` of a node's log line whose message starts with a tag of
    :mod:`comems4build_ros.wire.exits` (``cause:``, ``cleaning up:``), else None."""
    m = LOG_LINE.search(line)
    if m is None:
        return None
    for tag in (CAUSE_TAG, CLEANUP_TAG):
        if m.group("message").startswith(f"{tag} "):
            return m.group("name"), tag, m.group("message")[len(tag) + 1:].strip()
    return None


@dataclass
class Child:
    """One running node process."""

    name: str  # e.g. "plant_sim" or "house_3/plant_sim"
    role: str  # plant, feed, ems, recorder, replay
    proc: subprocess.Popen
    log_path: Path
    stdout_reader: threading.Thread | None = None
    stage: int = STAGE_NODES
    finishes: bool = False
    nodes: tuple[str, ...] = ()  # full names of the ROS nodes the process runs ("/house_0/plant_sim")
    hang_reported: bool = False  # exit_code() has warned of a clean-up hang after a complete run
    paused_reported: bool = False  # the supervisor has said that the process is paused (SIGSTOP)
    may_leave: bool = False  # the run goes on when it leaves (a house of a community on a wall clock)
    left: bool = False  # it left the run, and the run went on without its houses

    @property
    def houses(self) -> frozenset[str]:
        """The namespaces of the ROS nodes the process runs (its houses)."""
        return frozenset(n.rpartition("/")[0] or "/" for n in self.nodes)

    def log_text(self) -> str:
        """The node's log so far ("" if it cannot be read)."""
        try:
            return self.log_path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""

    def tail(self, lines: int = 8) -> str:
        """Last lines of the node's log."""
        return "\n".join(self.log_text().rstrip().splitlines()[-lines:])

    def cause(self) -> str | None:
        """The last ``cause: <text>`` line of the log (:mod:`comems4build_ros.wire.exits`) as
        ``[<logger>] cause: <text>``, or None (see :func:`tagged_line`)."""
        lines = [m for m in map(tagged_line, self.log_text().splitlines()) if m and m[1] == CAUSE_TAG]
        return f"[{lines[-1][0]}] {CAUSE_TAG} {lines[-1][2]}" if lines else None

    def decided_before_hang(self) -> int | None:
        """The exit code the node's run had decided when its clean-up hung and the C-level
        backstop ended it with code 1 (:func:`~comems4build_ros.ros.process.cleanup_deadline`:
        a ``cleaning up: exit code N`` line of the log, later the backstop's ``Timeout (``),
        or None if that is not what happened."""
        return decided_before_hang(self.log_text())

    def paused(self) -> bool:
        """The process is stopped (SIGSTOP, state ``T`` in ``/proc/<pid>/stat``)."""
        try:
            stat = Path(f"/proc/{self.proc.pid}/stat").read_text()
        except OSError:
            return False
        return stat.rsplit(")", 1)[-1].split()[:1] == ["T"]


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
        # the launcher reads the logs again (a node's last lines, its decision): this user's alone
        os.close(open_dir(log_dir, create=True, private=True, what="the folder of the node logs"))

    def start(
        self,
        name: str,
        role: str,
        argv: Sequence[str],
        on_stdout_line: Callable[[str], None] | None = None,
        nice: int = 0,
        env: dict[str, str] | None = None,
        stage: int | None = None,
        finishes: bool | None = None,
        nodes: Sequence[str] = (),
        may_leave: bool = False,
    ) -> Child:
        """Start ``argv``; with ``on_stdout_line`` its stdout is read line by line in a thread.

        ``nice`` lowers the child's CPU priority (a node off the critical path of a step);
        ``env`` is added to the group's environment. ``stage`` (stop order) and
        ``finishes`` (exit 0 at the end of the run is normal) default by ``role``:
        recorders stop after the nodes, a discovery server last; plants and recorders finish.
        ``nodes``: full names of the ROS nodes the process runs (named when it leaves the run);
        ``may_leave``: the run goes on when it leaves (:func:`supervise`).
        """
        log_path = self.log_dir / f"{name.replace('/', '__')}.log"
        log: IO[bytes] = os.fdopen(create_file(log_path, private=True, exclusive=False, what="a node's log"), "wb")
        try:
            proc = subprocess.Popen(
                list(argv),
                env=self.env if not env else {**self.env, **env},
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE if on_stdout_line else log,
                stderr=log,
                start_new_session=True,
                preexec_fn=_child_setup(nice),
            )
        finally:
            log.close()
        if stage is None:
            stage = {"recorder": STAGE_RECORDERS, "discovery": STAGE_SERVICES}.get(role, STAGE_NODES)
        if finishes is None:
            finishes = role in ("plant", "recorder")
        child = Child(name, role, proc, log_path, stage=stage, finishes=finishes, nodes=tuple(nodes),
                      may_leave=may_leave)
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
        """SIGINT, then SIGTERM after ``grace_s``, then SIGKILL; waits until all are gone.

        Each signal is followed by SIGCONT, so a stopped (SIGSTOP) process handles it too.
        """
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            alive = [c for c in children if c.proc.poll() is None]
            if not alive:
                break
            for c in alive:
                with contextlib.suppress(ProcessLookupError):
                    c.proc.send_signal(sig)
                    c.proc.send_signal(signal.SIGCONT)
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
        """Stop every process by stage: nodes first, then the recorders (they close the bags), then services."""
        for stage in (STAGE_NODES, STAGE_RECORDERS, STAGE_SERVICES):
            self.stop([c for c in self.children if c.stage == stage], recorder_grace_s if stage == STAGE_RECORDERS
                      else grace_s)
        self.stop([c for c in self.children if c.stage not in (STAGE_NODES, STAGE_RECORDERS, STAGE_SERVICES)],
                  grace_s)

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
    """Within the block, SIGTERM to this process (a launch, a study) behaves like Ctrl-C, so it ends
    cleanly (main thread only)."""
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
    # Running from a source tree: children import this same tree. An installed package is
    # found by the children's interpreter anyway; putting site-packages on PYTHONPATH would
    # place it before the standard library (and the old 'pathlib' backport that OpenDHW
    # pulls in would then shadow the real pathlib).
    if installed_from_source():
        root = str(SOURCE_ROOT)
        parts = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != root]
        env["PYTHONPATH"] = os.pathsep.join([root, *parts])
    env["PYTHONUNBUFFERED"] = "1"
    env.update(profile_env(fastdds_profile(), env))
    return env


def run_commands(commands: Sequence[Sequence[str]], optional: bool = False) -> list[str]:
    """Run set-up or tear-down commands in order; returns the notes of failed optional ones.

    Raises
    ------
    LaunchError
        When a required command fails (naming it and its error output).
    """
    notes = []
    for cmd in commands:
        res = subprocess.run(list(cmd), capture_output=True, text=True)
        if res.returncode != 0:
            msg = f"'{' '.join(cmd)}' failed ({res.returncode}): {res.stderr.strip()}"
            if not optional:
                raise LaunchError(msg)
            notes.append(msg)
    return notes


class Progress:
    """Recorded and total steps, as last reported by each recorder (thread-safe)."""

    def __init__(self, n: int) -> None:
        self._lock = threading.Lock()
        self.recorded = [0] * n
        self.total = [0] * n

    def set(self, i: int, recorded: int, total: int) -> None:
        with self._lock:
            self.recorded[i], self.total[i] = recorded, total

    def get(self) -> tuple[int, int]:
        """Recorded steps of all houses, and their total (0 until every recorder knows its own)."""
        with self._lock:
            return sum(self.recorded), (sum(self.total) if all(self.total) else 0)

    def listener(self, i: int) -> Callable[[str], None]:
        """stdout line handler of recorder ``i``."""

        def on_line(line: str) -> None:
            parts = line.split()
            if len(parts) == 3 and parts[0] == "progress":
                self.set(i, int(parts[1]), int(parts[2]))

        return on_line


def supervise(
    group: ProcessGroup,
    recorders: list[Child],
    plants: list[Child],
    progress: Progress,
    report: Callable[[int, int], None] | None,
    t0: float,
    timeout_s: float | None,
    stall_s: float | None = None,
) -> float | None:
    """Wait for the end of the run; returns when the first record came.

    The run is done when every recorder has exited 0 (a recorder exits 0 once every plant
    said ``plant/done`` and every record is written: the bags are closed), whatever the
    other processes do (they are stopped afterwards); without recorders, when every plant
    has exited 0. Recorders still running :data:`RECORDER_DRAIN_S` after the last plant
    exited are stopped (SIGINT, SIGTERM, SIGKILL).

    ``stall_s`` (None = never): no new record for this long after the first one, while
    some plant still runs, ends the run (the backstop for a paused or hung master).

    A process marked ``may_leave`` (a house of a community on a wall clock, whose coordinator
    goes on without it) that exits otherwise does not end the run: the supervisor says so on
    stderr, and the recorders and plants of the houses it ran (its namespaces) are no longer
    waited for; what is left of them is stopped with the rest after the run.

    Raises
    ------
    LaunchError
        When a process exits against the exit rule, a recorder had to be killed, no step
        was recorded for ``stall_s``, or ``timeout_s`` passes.
    """
    t_first_record: float | None = None
    t_plants_done: float | None = None
    last_r, t_last_r = 0, time.monotonic()
    t_pause_check = time.monotonic()
    while True:
        time.sleep(POLL_S)
        r, n = progress.get()
        now = time.monotonic()
        if r and t_first_record is None:
            t_first_record = now
        if r != last_r:
            last_r, t_last_r = r, now
        if report is not None:
            report(r, n)
        if now - t_pause_check > PAUSE_CHECK_S:  # a paused process is named as such, as soon as it is seen
            t_pause_check = now
            _report_paused(group)
        for c in group.children:
            code = exit_code(c)
            # exit 0 of a node: its part of the run is complete (exits.py); anything else cuts the run
            if code is None or (c.finishes and code == 0) or c.left:
                continue
            if c.may_leave:
                house_left(group, c, code)
                continue
            raise left_error(c, code, paused=[p.name for p in group.children
                                              if p is not c and p.proc.poll() is None and p.paused()])
        staying = [c for c in recorders if not c.left]
        if staying and all(exit_code(c) == 0 for c in staying):
            return t_first_record
        plants_done = all(exit_code(p) == 0 for p in plants if not p.left)
        if plants_done and not recorders:
            return t_first_record
        if plants_done:
            t_plants_done = t_plants_done or time.monotonic()
            if time.monotonic() - t_plants_done > RECORDER_DRAIN_S:
                running = [c for c in recorders if c.proc.poll() is None]
                print(f"launcher: {len(running)} recorder(s) still running {RECORDER_DRAIN_S:g} s after the last "
                      "plant exited; stopping them (SIGINT closes the bag)", file=sys.stderr)
                group.stop(running, RECORDER_GRACE_S)
                bad = [c for c in running if exit_code(c) != 0]
                if bad:
                    raise LaunchError(
                        "recorder(s) " + ", ".join(f"'{c.name}' (exit {c.proc.returncode})" for c in bad)
                        + " did not stop by themselves after the run and had to be stopped; the bag may lack "
                        "its summary (evaluate reads it anyway)"
                    )
                return t_first_record
        if (stall_s is not None and t_first_record is not None and not plants_done and (not n or r < n)
                and now - t_last_r > stall_s):
            raise LaunchError(f"run stalled: no step recorded for {now - t_last_r:.0f} s (recorded {r} of {n or '?'} "
                              f"steps); {_paused(group)}")
        if timeout_s is not None and now - t0 > timeout_s:
            raise LaunchError(
                f"run not finished within the time limit of {timeout_s:g} s (recorded {r} of {n or '?'} steps; "
                f"{_paused(group)}; --timeout sets the limit)"
            )


def house_left(group: ProcessGroup, c: Child, code: int) -> None:
    """Process ``c`` (``may_leave``) left with exit code ``code``: say so, and mark it and every other
    process of only its houses as left (the run no longer waits for them)."""
    houses = c.houses
    c.left = True
    for other in group.children:
        if other.may_leave and other.houses and other.houses <= houses:
            other.left = True
    cause = c.cause()
    print(f"launcher: warning: node '{c.name}' exited with code {code} ({exit_meaning(code)}) and its house(s) "
          f"{', '.join(sorted(houses))} left the run{': ' + cause if cause else ''}; the community goes on without "
          f"them (log: {c.log_path})", file=sys.stderr, flush=True)


def exit_code(c: Child) -> int | None:
    """``c``'s exit code, None while it runs. A process whose clean-up hung after its run had
    decided exit 0, and that the C-level backstop ended with 1, counts as 0: its part of the
    run (a recorder's bag: closed before the clean-up) is complete. Said once on stderr,
    naming its log, where the stacks of the hang are."""
    code = c.proc.poll()
    if code == 1 and c.decided_before_hang() == 0:
        if not c.hang_reported:
            c.hang_reported = True
            print(f"launcher: warning: node '{c.name}' had finished its run (exit code 0) but its clean-up hung and "
                  f"its watchdog ended it; the stacks are in {c.log_path}", file=sys.stderr, flush=True)
        return 0
    return code


def _report_paused(group: ProcessGroup) -> None:
    """Say once on stderr for each process of ``group`` that is paused (SIGSTOP) that it is, and what follows."""
    for c in group.children:
        if c.paused_reported or c.proc.poll() is not None or not c.paused():
            continue
        c.paused_reported = True
        print(f"launcher: warning: process '{c.name}' is paused (SIGSTOP, state T): it neither sends nor receives; "
              "the run waits for it (SIGCONT resumes it) until its time-outs end the run", file=sys.stderr, flush=True)


def left_error(c: Child, code: int, paused: Sequence[str] = ()) -> LaunchError:
    """The :class:`LaunchError` of process ``c`` that left the run with exit code ``code``:
    first line names it, the exit code and its meaning, and the cause the node gave; ``paused``:
    the other processes paused (SIGSTOP) at that time, named as the likely cause of a stall."""
    meaning = exit_meaning(code)
    cause = c.cause()  # "[<node>] cause: <text>"
    text = cause.split(f"] {CAUSE_TAG} ", 1)[1] if cause else ""
    if text.startswith(f"{meaning}: "):
        text = text[len(meaning) + 2:]
    said = f": {cause.split(f' {CAUSE_TAG} ', 1)[0]} {text}" if text and text != meaning else ""
    ran = f" (it ran {describe_nodes(c.nodes)})" if len(c.nodes) > 1 else ""
    stopped = ("; paused (SIGSTOP) at that time: " + ", ".join(f"'{n}'" for n in paused)) if paused else ""
    return LaunchError(
        f"run cut short: node '{c.name}' exited with code {code} ({meaning}) while the run was in progress{ran}{said}"
        f"{stopped} (log: {c.log_path})\n{c.tail()}",
        process=c.name, code=code, log=c.log_path, nodes=c.nodes,
    )


def describe_nodes(nodes: Sequence[str], max_namespaces: int = 4) -> str:
    """The nodes of a process that runs several, in words: node names per set of namespaces,
    e.g. ``plant_sim, feed, rbc_ems, recorder of /house_0`` or ``rbc_ems of /house_0 ..
    /house_7 (8 houses)``."""
    by_name: dict[str, list[str]] = {}
    for full in nodes:
        ns, _, name = full.rpartition("/")
        by_name.setdefault(name, []).append(ns or "/")
    groups: dict[tuple[str, ...], list[str]] = {}
    for name, spaces in by_name.items():
        groups.setdefault(tuple(spaces), []).append(name)
    parts = []
    for spaces, names in groups.items():
        where = (", ".join(spaces) if len(spaces) <= max_namespaces
                 else f"{spaces[0]} .. {spaces[-1]} ({len(spaces)} houses)")
        parts.append(f"{', '.join(names)} of {where}")
    return "; ".join(parts)


def _paused(group: ProcessGroup) -> str:
    """Which processes of ``group`` are paused (SIGSTOP), in words."""
    paused = [c.name for c in group.children if c.proc.poll() is None and c.paused()]
    if paused:
        return "paused (SIGSTOP) and so silent: " + ", ".join(f"'{n}'" for n in paused)
    return "no node exited and none is paused: a node hangs (its log may tell)"


@dataclass
class Supervised:
    """Times of a supervised run (``time.monotonic`` [s])."""

    t0: float  # first process started
    t_first_record: float | None  # first plant/record reported by a recorder
    t_end: float  # end of the run (before the processes were stopped)


def run_plan(plan: RunPlan, report: Callable[[int, int], None] | None = None) -> Supervised:
    """Start every process of ``plan``, wait for the end of the run, stop them all.

    Parameters
    ----------
    plan : what to run (:func:`comems4build_ros.run.plans.plan_any`)
    report : called as ``report(recorded steps, total steps)`` while the run goes (a progress
        bar of :mod:`comems4build_ros.run.progress`; None = silent)

    Raises
    ------
    LaunchError
        If a process exits against the exit rule or the plan's time limit passes.
    KeyboardInterrupt
        On Ctrl-C or SIGTERM (after every child has been stopped).
    """
    env = dict(child_env(plan.domain_id, plan.out / "log" / "ros"), **plan.env)
    recorders_n = sum(1 for p in plan.processes if p.progress)
    progress = Progress(recorders_n)
    with sigterm_as_keyboard_interrupt(), _network(plan), _secrets(plan):
        t0 = time.monotonic()
        with ProcessGroup(env, plan.out / "log") as group:
            recorders: list[Child] = []
            plants: list[Child] = []
            reporting = 0  # processes that print progress lines so far
            write_plan_files(plan)
            if plan.discovery_server:
                print(f"launcher: {discovery_hint(plan.discovery_server)}", file=sys.stderr, flush=True)
            for p in plan.processes:
                extra = {**plan.sides[p.side].env, **p.env}
                listener = progress.listener(reporting) if p.progress else None
                reporting += p.progress
                child = group.start(p.name, p.role, p.argv, listener, env=extra, stage=p.stop_stage,
                                    finishes=p.finishes, nodes=[node_label(n) for n in p.nodes],
                                    may_leave=p.may_leave)
                if p.role in ("recorder", "container"):  # a container's recorders end with it
                    recorders.append(child)
                if p.role in ("plant", "container"):  # ... and so do its plants
                    plants.append(child)
            try:
                t_first_record = supervise(group, recorders, plants, progress, report, t0, plan.timeout_s,
                                           plan.stall_s)
            except LaunchError as exc:  # say so at once, before the processes are stopped and the bag is read
                print(f"launcher: {exc.cause}; stopping every process", file=sys.stderr, flush=True)
                raise
            t_end = time.monotonic()
    return Supervised(t0, t_first_record, t_end)


def write_plan_files(plan: RunPlan) -> None:
    """Write the files the plan's processes read (the plant parameter file, container specs).

    The processes read them after the launcher checked them: each is created new, mode 0600 in
    folders of mode 0700 whatever the umask, never through a link (refused, named), so another
    local user can neither read nor replace one before the nodes start.
    """
    root = Path(plan.out).resolve()
    for path, text in (*plan.files, *(f for p in plan.processes for f in p.files)):
        write_new_file(path, text, root=root, private=True, exclusive=False, what="a file the run's nodes read")


def write_secrets(plan: RunPlan) -> None:
    """Write the plan's token files (mode 0600 in a directory of mode 0700,
    :func:`comems4build_ros.wire.tokens.write_token_file`)."""
    root = Path(plan.out).resolve()
    for d in {Path(path).parent for path, _ in plan.secrets}:
        os.close(open_dir(d, root=root, create=True, private=True, what="the folder of the run secrets"))
        private_dir(d)
    for path, token in plan.secrets:
        write_token_file(path, token)


def remove_secrets(plan: RunPlan) -> None:
    """Remove the plan's token files and their directories (nothing of them is left)."""
    for path, _ in plan.secrets:
        Path(path).unlink(missing_ok=True)
    for d in {Path(path).parent for path, _ in plan.secrets}:
        with contextlib.suppress(OSError):
            d.rmdir()


@contextlib.contextmanager
def _secrets(plan: RunPlan) -> Iterator[None]:
    """The plan's token files for the run (:func:`write_secrets`), removed after it."""
    if not plan.secrets:
        yield
        return
    try:
        write_secrets(plan)
        yield
    finally:
        remove_secrets(plan)


@contextlib.contextmanager
def _network(plan: RunPlan) -> Iterator[None]:
    """Run the plan's set-up commands, then always its tear-down commands.

    A failed optional command (``tc netem`` where the kernel lacks it) is reported on
    stderr and the run goes on without it.
    """
    if not plan.setup and not plan.optional_setup:
        yield
        return
    try:
        run_commands(plan.setup)
        for note in run_commands(plan.optional_setup, optional=True):
            print(f"launcher: note: {note}; running without it (the kernel offers no netem here)", file=sys.stderr)
        yield
    finally:
        run_commands(plan.teardown, optional=True)
