"""One way to run a study's many runs: local worker processes or a Dask cluster, resumable.

A study (``compare``, ``sweep``, ``reproduce``, ``size``, and any command with a set of runs) hands
its runs (:class:`Job` objects, e.g. :class:`comems4build_ros.study.runner.RunTask`) to
:func:`run_jobs` with a :class:`StudyPool`, which says where they execute and where the
finished ones are stored:

- :class:`LocalBackend`: worker processes of this machine (``--jobs N``, default the CPU
  count; one job runs in this process);
- :class:`DaskBackend`: the workers of a Dask cluster (``--scheduler tcp://HOST:PORT``),
  each checked before any run to have this machine's environment
  (:func:`comems4build_ros.study.spec.environment`).

Every run executes by the same function, :func:`execute`, in a temporary directory of the
process that runs it; its files come back to this process with its summary, are stored in
the study's :class:`~comems4build_ros.study.store.RunStore` as it finishes, and are copied
into the run's ``out_dir``. So the results do not depend on where a run executed, and an
interrupted study resumes (``--resume``) without running its finished runs again. A worker
that dies during a run (killed, out of memory) costs that run only: it runs again on
another worker, up to :data:`MAX_ATTEMPTS` times. Progress: one line per event with the
runs done, running and failed (and the Dask dashboard's address), and one bar per running
run on a terminal (:class:`comems4build_ros.run.progress.RunProgress`).
"""

from __future__ import annotations

import contextlib
import contextvars
import ctypes
import datetime as dt
import multiprocessing
import multiprocessing.connection
import os
import pickle
import queue as _queue
import signal
import socket
import tempfile
import time
import traceback
import uuid
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from comems4build_ros.files.errors import InputError
from comems4build_ros.run.progress import ProgressCallback, RunProgress, echo
from comems4build_ros.study.spec import differences, environment, spec_hash
from comems4build_ros.study.store import RunStore, StoredRun, StoreError, materialize, place

#: Times a run is started when its worker dies under it (then the study fails naming it).
MAX_ATTEMPTS = 3
#: Least time between two progress reports a Dask worker sends for one run [s].
DASK_REPORT_INTERVAL_S = 1.0
#: How often the client looks for finished runs and progress events [s].
POLL_S = 0.05
#: How often the client asks the scheduler which workers are alive [s].
WORKER_POLL_S = 2.0
#: Time to connect to a scheduler and to wait for its first worker [s].
CONNECT_TIMEOUT_S = 10.0
WORKER_TIMEOUT_S = 30.0


class RunFailedError(RuntimeError):
    """A run ended without its outputs (message names the run directory and the cause)."""


class PoolError(InputError):
    """The study pool cannot be used (no scheduler, no worker, a worker's environment differs); names it."""


class Job(Protocol):
    """One run of a study, as the study pool sees it (picklable).

    ``out_dir``: where its results go (its name is the run's name); :meth:`spec`: everything
    that decides its outputs (JSON-ready; hashed to recognise a stored run); :meth:`portable`:
    the job with the files it reads from outside the package carried inside it;
    :meth:`run`: write the outputs into ``out_dir`` and return the summary; ``weight``:
    relative cost (longest first).
    """

    out_dir: str

    @property
    def weight(self) -> float: ...

    def spec(self) -> dict[str, Any]: ...

    def portable(self) -> Job: ...

    def run(self, out_dir: str, progress: ProgressCallback | None = None) -> dict[str, Any]: ...


def _utc(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat()


@dataclass
class Outcome:
    """A finished run as it comes back from the process that ran it."""

    summary: dict[str, Any]
    files: dict[str, bytes]
    attempt: dict[str, Any]


def _where(worker: str) -> dict[str, Any]:
    return {"worker": worker, "host": socket.gethostname(), "pid": os.getpid(), "started": _utc(time.time())}


def execute(job: Job, progress: ProgressCallback | None = None, worker: str = "local",
            expected_env: Mapping[str, Any] | None = None) -> Outcome:
    """Run ``job`` in a temporary directory of this process; its summary, files and attempt record.

    ``expected_env``: the client's environment record; a worker whose own differs refuses
    the run (:class:`PoolError` naming the worker and what differs).
    """
    attempt = _where(worker)
    if expected_env is not None:
        diff = differences(dict(expected_env), environment())
        if diff:
            raise PoolError(f"worker {worker} on {attempt['host']}: its environment differs from the "
                                f"client's ({'; '.join(diff[:4])})")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="comems4build-run-") as tmp:
        out = Path(tmp) / "run"
        summary = job.run(str(out), progress)
        files = {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    attempt.update(ended=_utc(time.time()), wall_s=time.perf_counter() - t0)
    return Outcome(dict(summary), files, attempt)


# ============================================================================ the study's state


@dataclass
class _Slot:
    job: Job
    name: str
    spec: dict[str, Any]
    hash: str
    status: str = "waiting"  # waiting, running, done, failed
    attempts: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] | None = None
    resumed: bool = False


class Monitor:
    """What the study knows of its runs: stores each finished run, prints progress lines."""

    def __init__(self, slots: list[_Slot], store: RunStore | None, study_id: str,
                 on_done: Callable[[Any, dict[str, Any]], None] | None, quiet: bool = False) -> None:
        self.slots = slots
        self.store = store
        self.study_id = study_id
        self.on_done = on_done
        self.quiet = quiet

    def counts(self) -> dict[str, int]:
        """Runs per status."""
        out = {"waiting": 0, "running": 0, "done": 0, "failed": 0}
        for s in self.slots:
            out[s.status] += 1
        return out

    def status(self) -> str:
        """``[3/12 done, 2 running, 0 failed]``."""
        c = self.counts()
        return f"[{c['done']}/{len(self.slots)} done, {c['running']} running, {c['failed']} failed]"

    def say(self, text: str) -> None:
        """A progress line above the bars."""
        if not self.quiet:
            echo(f"  {self.status()} {text}")

    def started(self, i: int, where: Mapping[str, Any]) -> None:
        """Run ``i`` started on a worker (a running attempt elsewhere was lost)."""
        s = self.slots[i]
        if s.status == "running":
            lost_on = s.attempts[-1].get("worker")
            self._lose(s, "started again elsewhere")
            self.say(f"{s.name}: its worker {lost_on} was lost; it runs again")
        s.attempts.append({**where, "outcome": "running"})
        s.status = "running"
        self.say(f"{s.name}: started on {where.get('worker')} (host {where.get('host')}, pid {where.get('pid')})")

    def lost(self, i: int, why: str) -> int:
        """The worker of run ``i`` died; the run waits to run again. Returns its attempts so far."""
        s = self.slots[i]
        if s.status == "running":
            self._lose(s, why)
            s.status = "waiting"
            self.say(f"{s.name}: {why}; it runs again")
        return len(s.attempts)

    def _lose(self, s: _Slot, why: str) -> None:
        s.attempts[-1].update(outcome=f"lost: {why}", ended=_utc(time.time()))

    def running_on(self, i: int) -> str | None:
        """The worker of run ``i``'s running attempt."""
        s = self.slots[i]
        return str(s.attempts[-1].get("worker")) if s.status == "running" and s.attempts else None

    def finished(self, i: int, outcome: Outcome) -> None:
        """Run ``i`` finished: store it, copy it into its ``out_dir``, report it."""
        s = self.slots[i]
        attempt = {**outcome.attempt, "outcome": "finished"}
        if s.attempts and s.attempts[-1].get("outcome") == "running":
            s.attempts[-1] = attempt
        else:
            s.attempts.append(attempt)
        summary = outcome.summary
        record = {"name": s.name, "spec_hash": s.hash, "study": self.study_id, "summary": summary,
                  "attempts": s.attempts, "spec": s.spec}
        try:
            if self.store is not None:
                materialize(self.store.save(s.name, outcome.files, record), s.job.out_dir)
            else:
                place(s.job.out_dir, outcome.files, record)
        except OSError as exc:  # the run store or the output became unwritable (EPERM, ENOSPC, EROFS, ...)
            where = exc.filename or (self.store.root if self.store is not None else s.job.out_dir)
            self.failed(i, f"finished, but its files could not be stored: {where}: {exc.strerror or exc}")
            raise OSError(exc.errno, exc.strerror or str(exc), str(where)) from exc
        s.summary = summary
        s.status = "done"
        wall = attempt.get("wall_s")
        self.say(f"{s.name}: finished in {wall:.1f} s on {attempt.get('worker')}" if wall is not None
                 else f"{s.name}: finished")
        if self.on_done:
            self.on_done(s.job, summary)

    def resumed(self, i: int, stored: StoredRun) -> None:
        """Run ``i`` is taken from the store (not run again)."""
        s = self.slots[i]
        materialize(stored, s.job.out_dir)
        s.summary = dict(stored.record.get("summary") or {})
        s.attempts = list(stored.record.get("attempts") or [])
        s.status = "done"
        s.resumed = True
        if self.on_done:
            self.on_done(s.job, s.summary)

    def failed(self, i: int, message: str) -> None:
        """Run ``i`` failed (its error is raised once the running runs are stored)."""
        s = self.slots[i]
        if s.attempts and s.attempts[-1].get("outcome") == "running":
            s.attempts[-1].update(outcome=f"failed: {message}", ended=_utc(time.time()))
        s.status = "failed"
        self.say(f"{s.name}: FAILED: {message}")


# ============================================================================ where runs execute


class LocalBackend:
    """Worker processes of this machine (``jobs`` at most, and at most the CPU count)."""

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = jobs

    def workers_for(self, n: int) -> int:
        """Worker processes for ``n`` runs."""
        cpus = os.cpu_count() or 1
        return max(1, min(self.jobs or cpus, cpus, n))

    def open(self) -> None:
        """Nothing to connect to."""

    def close(self) -> None:
        """Nothing to release (worker processes end with each study)."""

    def describe(self, n: int) -> str:
        """Where ``n`` runs execute."""
        w = self.workers_for(n)
        return "this process" if w == 1 else f"{w} local worker processes"

    def execute(self, items: Sequence[tuple[int, Job]], monitor: Monitor, bars: RunProgress) -> None:
        """Run ``items`` (slot, job), longest first; raise the first run's error once the others ended."""
        if self.workers_for(len(items)) == 1:
            for i, job in items:
                monitor.started(i, _where("local"))
                try:
                    outcome = execute(job, bars.callback(i), "local")
                except Exception as exc:
                    monitor.failed(i, _message(exc))
                    raise
                monitor.finished(i, outcome)
            return
        _LocalPool(self.workers_for(len(items)), monitor, bars).run(items)


def _message(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _die_with_parent() -> None:
    """Linux: this process gets SIGKILL when its parent dies (no orphaned worker keeps running)."""
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def _local_worker(conn: multiprocessing.connection.Connection, init: Any, initargs: tuple) -> None:
    """Main of a local worker process: run the jobs sent over ``conn`` until ``None``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent ends its workers on Ctrl-C
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent()
    if init is not None:
        init(*initargs)
    name = f"local:{os.getpid()}"
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        slot, job, reporter = msg
        conn.send(("start", slot, _where(name)))
        try:
            outcome = execute(job, reporter, name)
        except Exception as exc:
            try:
                pickle.dumps(exc)
                error: BaseException = exc
            except Exception:
                error = RunFailedError(_message(exc))
            conn.send(("error", slot, (error, traceback.format_exc())))
            continue
        conn.send(("done", slot, outcome))


class _Proc:
    def __init__(self, ctx: Any, init: Any, initargs: tuple) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_local_worker, args=(child, init, initargs), daemon=True)
        self.proc.start()
        child.close()
        self.slot: int | None = None
        self.job: Job | None = None

    def stop(self, grace_s: float = 2.0) -> None:
        with contextlib.suppress(OSError, ValueError):
            if self.slot is None and self.proc.is_alive():
                self.conn.send(None)
        self.proc.join(0.1 if self.slot is not None else grace_s)
        if self.proc.is_alive():
            self.proc.terminate()
            self.proc.join(grace_s)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join()
        self.conn.close()


class _LocalPool:
    """Long-lived worker processes, each with its own pipe: a dead one costs its own run only."""

    def __init__(self, n: int, monitor: Monitor, bars: RunProgress) -> None:
        self.n = n
        self.monitor = monitor
        self.bars = bars
        self.ctx = multiprocessing.get_context()
        self.procs: list[_Proc] = []
        self.failure: BaseException | None = None

    def run(self, items: Sequence[tuple[int, Job]]) -> None:
        todo = deque(items)
        try:
            while True:
                while todo and self.failure is None:
                    proc = next((p for p in self.procs if p.slot is None), None)
                    if proc is None and len(self.procs) < self.n:
                        proc = _Proc(self.ctx, self.bars.initializer, self.bars.initargs)
                        self.procs.append(proc)
                    if proc is None:
                        break
                    slot, job = todo.popleft()
                    proc.slot, proc.job = slot, job
                    proc.conn.send((slot, job, self.bars.reporter(slot)))
                busy = [p for p in self.procs if p.slot is not None]
                if not busy:
                    break
                ready = multiprocessing.connection.wait([p.conn for p in busy] + [p.proc.sentinel for p in busy],
                                                        timeout=1.0)
                for proc in busy:
                    if proc.conn in ready or proc.proc.sentinel in ready:
                        self._handle(proc, todo)
        finally:
            for proc in self.procs:
                proc.stop()
            self.procs = []
        if self.failure is not None:
            raise self.failure

    def _handle(self, proc: _Proc, todo: deque) -> None:
        dead = False
        received = []
        try:  # only the pipe's own failure means a dead worker (not an error of storing its run, below)
            while proc.slot is not None and proc.conn.poll():
                kind, slot, payload = proc.conn.recv()
                if kind != "start":
                    proc.slot = proc.job = None
                received.append((kind, slot, payload))
        except (EOFError, OSError):
            dead = True
        for kind, slot, payload in received:
            if kind == "start":
                self.monitor.started(slot, payload)
            elif kind == "done":
                self.monitor.finished(slot, payload)
            else:
                error, text = payload
                self.monitor.failed(slot, _message(error))
                if self.failure is None:
                    self.failure = error
        if proc.slot is None and not dead:
            return
        if not dead and proc.proc.is_alive():
            return
        proc.proc.join(1.0)
        code = proc.proc.exitcode
        slot, job = proc.slot, proc.job
        self.procs.remove(proc)
        proc.slot = None
        proc.stop(0.0)
        if slot is None:
            return
        how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        attempts = self.monitor.lost(slot, f"worker process {proc.proc.pid} ended ({how})")
        if attempts >= MAX_ATTEMPTS:
            message = f"its worker process died {attempts} times under it (last: {how})"
            self.monitor.failed(slot, message)
            if self.failure is None:
                self.failure = RunFailedError(f"{job.out_dir}: {message}")
        else:
            todo.appendleft((slot, job))


class DaskBackend:
    """The workers of a Dask cluster (``dask scheduler`` and ``dask worker`` processes, any hosts)."""

    def __init__(self, address: str, connect_timeout_s: float = CONNECT_TIMEOUT_S,
                 worker_timeout_s: float = WORKER_TIMEOUT_S, security: Any = None) -> None:
        self.address = address
        self.security = security  # distributed.Security of a TLS cluster (None: Dask's configuration)
        self.connect_timeout_s = connect_timeout_s
        self.worker_timeout_s = worker_timeout_s
        self.client: Any = None
        self.dashboard: str | None = None

    def open(self) -> None:
        """Connect, wait for a worker, check every worker's environment (before any run)."""
        try:
            from distributed import Client
        except ImportError as exc:  # pragma: no cover - a dependency of requirements.txt
            raise PoolError(f"--scheduler {self.address}: dask.distributed is not installed ({exc})") from None
        try:
            self.client = Client(self.address, timeout=self.connect_timeout_s, set_as_default=False,
                                 security=self.security)
        except (OSError, TimeoutError) as exc:
            raise PoolError(f"--scheduler {self.address}: no scheduler answered within "
                                f"{self.connect_timeout_s:.0f} s ({exc})") from None
        try:
            self.client.wait_for_workers(1, timeout=self.worker_timeout_s)
        except (OSError, TimeoutError) as exc:
            self.close()
            raise PoolError(f"--scheduler {self.address}: no worker connected within "
                                f"{self.worker_timeout_s:.0f} s ({type(exc).__name__})") from None
        check_environment(self.client.run(prepare_worker), self.address)
        info = self.client.scheduler_info()
        if "dashboard" in info.get("services", {}):
            self.dashboard = self.client.dashboard_link

    def close(self) -> None:
        """Disconnect (the cluster keeps running)."""
        if self.client is not None:
            with contextlib.suppress(Exception):
                self.client.close(timeout=5)
            self.client = None

    def workers(self) -> dict[str, int]:
        """Worker address -> threads."""
        return {a: int(w.get("nthreads", 1)) for a, w in self.client.scheduler_info()["workers"].items()}

    def describe(self, n: int) -> str:
        """The scheduler, its workers and the dashboard."""
        w = self.workers()
        text = f"Dask scheduler {self.address}: {len(w)} workers, {sum(w.values())} threads"
        return text + (f"; dashboard {self.dashboard}" if self.dashboard else "; no dashboard")

    def execute(self, items: Sequence[tuple[int, Job]], monitor: Monitor, bars: RunProgress) -> None:
        """Submit ``items`` (longest first by priority); take each result as it comes."""
        client = self.client
        topic = f"comems4build-{monitor.study_id}"
        events: _queue.SimpleQueue = _queue.SimpleQueue()
        client.subscribe_topic(topic, events.put)
        env = environment()
        futures: dict[Any, tuple[int, Job]] = {}
        for rank, (i, job) in enumerate(items):
            s = monitor.slots[i]
            key = f"comems4build-{s.name}-{s.hash[:12]}-{monitor.study_id[:8]}"
            fut = client.submit(_execute_on_worker, job, env, topic, i, key=key, pure=False,
                                priority=len(items) - rank)
            futures[fut] = (i, job)
        pending = set(futures)
        failure: BaseException | None = None
        callbacks: dict[int, ProgressCallback | None] = {}
        last_poll = time.monotonic()
        try:
            while pending:
                for fut in [f for f in pending if f.done()]:  # before the events: a worker's next run starts after
                    pending.discard(fut)
                    i, job = futures[fut]
                    if fut.status == "finished":
                        monitor.finished(i, fut.result())
                        continue
                    if fut.status == "cancelled":  # not by this study: the scheduler dropped it
                        monitor.failed(i, "cancelled by the cluster")
                        failure = failure or RunFailedError(f"{job.out_dir}: the Dask cluster cancelled the run "
                                                            "(scheduler restarted or connection lost)")
                        continue
                    exc = fut.exception()
                    monitor.failed(i, _message(exc))
                    if failure is None:
                        failure = (RunFailedError(f"{job.out_dir}: its worker died {MAX_ATTEMPTS}+ times under it "
                                                  f"({exc})") if type(exc).__name__ == "KilledWorker" else exc)
                        waiting = [f for f in pending if monitor.slots[futures[f][0]].status == "waiting"]
                        client.cancel(waiting)
                        pending.difference_update(waiting)
                self._events(events, monitor, bars, callbacks)
                if time.monotonic() - last_poll > WORKER_POLL_S:
                    last_poll = time.monotonic()
                    alive = set(self.workers())
                    for i in range(len(monitor.slots)):
                        where = monitor.running_on(i)
                        if where is not None and where not in alive:
                            monitor.lost(i, f"worker {where} left the cluster")
                if pending:
                    time.sleep(POLL_S)
        except BaseException:
            with contextlib.suppress(Exception):
                client.cancel(list(pending))
            raise
        finally:
            with contextlib.suppress(Exception):
                client.unsubscribe_topic(topic)
        if failure is not None:
            raise failure

    @staticmethod
    def _events(events: _queue.SimpleQueue, monitor: Monitor, bars: RunProgress,
                callbacks: dict[int, ProgressCallback | None]) -> None:
        while True:
            try:
                _, msg = events.get_nowait()
            except _queue.Empty:
                return
            i = int(msg.get("slot", -1))
            if not 0 <= i < len(monitor.slots) or monitor.slots[i].status in ("done", "failed"):
                continue
            if msg.get("event") == "start":
                monitor.started(i, {k: msg[k] for k in ("worker", "host", "pid", "started") if k in msg})
            elif msg.get("event") == "progress":
                if i not in callbacks:
                    callbacks[i] = bars.callback(i)
                cb = callbacks[i]
                if cb is not None:
                    cb(int(msg["done"]), int(msg["total"]))


def check_environment(envs: Mapping[str, Mapping[str, Any]], where: str) -> None:
    """Every worker's environment record equals this process's, else :class:`PoolError` naming them."""
    mine = environment()
    bad = []
    for worker, env in sorted(envs.items()):
        diff = differences(mine, dict(env))
        if diff:
            bad.append(f"worker {worker}: {'; '.join(diff[:4])}")
    if bad:
        raise PoolError(f"--scheduler {where}: {len(bad)} worker(s) run another environment than this one "
                            f"(install the same commit with tools/setup.sh there, stored as 'this -> worker'): "
                            + " | ".join(bad[:4]))


def prepare_worker() -> dict[str, Any]:
    """Run on each worker when a study connects: import the simulation, return the environment record."""
    import importlib

    for module in ("loop", "scenario", "ems", "kpi"):
        importlib.import_module(f"comems4build_ros.core.{module}")
    return environment()


class _EventReporter:
    """Progress of a run on a Dask worker, sent as events of the study's topic (at most every second)."""

    def __init__(self, worker: Any, topic: str, slot: int) -> None:
        self.worker, self.topic, self.slot = worker, topic, slot
        self.last = 0.0

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if now - self.last < DASK_REPORT_INTERVAL_S and not (total and done >= total):
            return
        self.last = now
        self.worker.log_event(self.topic, {"event": "progress", "slot": self.slot, "done": int(done),
                                           "total": int(total)})


def _execute_on_worker(job: Job, env: Mapping[str, Any], topic: str, slot: int) -> Outcome:
    """The task a Dask worker runs: announce the start, then :func:`execute` with the client's environment."""
    from distributed import get_worker

    worker = get_worker()
    worker.log_event(topic, {"event": "start", "slot": slot, **_where(worker.address)})
    return execute(job, _EventReporter(worker, topic, slot), worker.address, expected_env=env)


# ============================================================================ the study


_CURRENT: contextvars.ContextVar[StudyPool | None] = contextvars.ContextVar("study_pool", default=None)


class StudyPool:
    """Where a study's runs execute (a backend) and where its finished runs are kept (a store).

    Use it as a context manager: entering connects the backend (a Dask scheduler is asked
    for a worker and every worker's environment checked: :class:`PoolError` before any
    run), turns SIGTERM into KeyboardInterrupt for the block, locks the store and checks it
    (a store with finished runs and no ``resume`` is refused:
    :class:`~comems4build_ros.study.store.StoreError`), and makes the pool the one
    :func:`comems4build_ros.study.runner.run_tasks` uses when given none. Call
    :meth:`complete` once the study's results are in place: it removes the store.

    Parameters
    ----------
    backend : :class:`LocalBackend` (default, ``jobs`` processes) or :class:`DaskBackend`
    store : the resumable store (None: finished runs are only copied to their ``out_dir``)
    resume : take stored runs of the same specification instead of running them again
    """

    def __init__(self, backend: LocalBackend | DaskBackend | None = None, store: RunStore | None = None,
                 resume: bool = False) -> None:
        self.backend = backend or LocalBackend()
        self.store = store
        self.resume = resume
        self.resumed = 0
        self.ran = 0
        self._token: Any = None
        self._stack: contextlib.ExitStack | None = None
        self._made_parent = False

    def __enter__(self) -> StudyPool:
        stack = contextlib.ExitStack()
        try:
            if self.store is not None:
                parent = self.store.root.parent
                self._made_parent = not parent.exists()
                stack.callback(self._tidy_store)
                stack.enter_context(self.store.locked())
                stored, _ = self.store.finished()
                if stored and not self.resume:
                    raise StoreError(f"{self.store.root} holds {len(stored)} finished run(s) of a study that did not "
                                     "finish: --resume takes those of this study instead of running them again; "
                                     "remove that directory to start over")
            self.backend.open()
            stack.callback(self.backend.close)
            from comems4build_ros.run.supervisor import sigterm_as_keyboard_interrupt

            stack.enter_context(sigterm_as_keyboard_interrupt())  # SIGTERM ends the study as Ctrl-C does
        except BaseException:
            stack.close()
            raise
        self._stack = stack
        self._token = _CURRENT.set(self)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        _CURRENT.reset(self._token)
        if exc_type is not None and self.store is not None:
            stored, _ = self.store.finished()
            if stored:
                echo(f"  {len(stored)} finished run(s) are kept in {self.store.root}: the same command with --resume "
                     "continues the study without running them again")
        if self._stack is not None:
            self._stack.close()
            self._stack = None

    def _tidy_store(self) -> None:
        """A store without finished runs goes (and the output directory it alone created)."""
        if self.store is None or self.store.finished()[0]:
            return
        self.store.remove()
        if self._made_parent:
            with contextlib.suppress(OSError):
                self.store.root.parent.rmdir()

    def complete(self) -> None:
        """The study's results are in place: remove the store."""
        if self.store is not None:
            self.store.remove()


def current() -> StudyPool | None:
    """The pool of the enclosing ``with StudyPool(...)`` block, if any."""
    return _CURRENT.get()


def run_jobs(
    jobs: Sequence[Job],
    pool: StudyPool | None = None,
    on_done: Callable[[Any, dict[str, Any]], None] | None = None,
    progress: bool | None = None,
    quiet: bool = False,
) -> list[dict[str, Any]]:
    """Run ``jobs`` with ``pool`` (default: the current one, else local processes, no store).

    Returns the summaries in job order; ``on_done(job, summary)`` is called as each run
    finishes (and for each run taken from the store). With ``pool.resume`` a stored run
    of the same specification hash is taken as it is; one whose specification differs is
    refused before any run starts (:class:`~comems4build_ros.study.store.StoreError`
    naming the runs and what differs). The first run error is raised once the runs already
    running have finished and been stored. ``progress``: one bar per running run (None = on
    a terminal); ``quiet``: no progress lines.
    """
    ex = pool or current() or StudyPool()
    names = [Path(j.out_dir).name for j in jobs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise PoolError(f"runs named twice in one study: {', '.join(dup)}")
    slots = []
    for job, name in zip(jobs, names):
        spec = job.spec()
        slots.append(_Slot(job, name, spec, spec_hash(spec)))
    monitor = Monitor(slots, ex.store, uuid.uuid4().hex, on_done, quiet)
    reuse: dict[int, StoredRun] = {}
    if ex.store is not None and ex.resume:
        stored, notes = ex.store.finished()
        for note in notes:
            echo(f"  {note}")
        differ = []
        for i, s in enumerate(slots):
            run = stored.get(s.name)
            if run is None:
                continue
            if run.spec_hash != s.hash:
                diff = differences(run.record.get("spec") or {}, s.spec)
                differ.append(f"{s.name} ({'; '.join(diff[:3]) or 'hash differs'})")
            else:
                reuse[i] = run
        if differ:
            raise StoreError(f"{ex.store.root}: {len(differ)} stored run(s) have another specification than this "
                             f"study's (stored -> now): {', '.join(differ[:3])}"
                             + (f" and {len(differ) - 3} more" if len(differ) > 3 else "")
                             + "; run the same study to resume it, or remove that directory to start over")
    todo = [i for i in range(len(slots)) if i not in reuse]
    todo.sort(key=lambda i: -slots[i].job.weight)
    if not quiet:
        resumed = f", {len(reuse)} taken from {ex.store.root}" if reuse and ex.store is not None else ""
        echo(f"  {len(slots)} runs{resumed}; {len(todo)} to run on {ex.backend.describe(len(todo) or 1)}")
    for i, run in reuse.items():
        monitor.resumed(i, run)
    ex.resumed += len(reuse)
    items = [(i, slots[i].job.portable()) for i in todo]
    try:
        with RunProgress([s.name for s in slots], enable=progress) as bars:
            if items:
                ex.backend.execute(items, monitor, bars)
        unfinished = [s.name for s in slots if s.status != "done"]
        if unfinished:  # every backend raises first; this guards the summaries handed back
            raise RunFailedError(f"runs not finished: {', '.join(unfinished)}")
    finally:
        ex.ran += sum(1 for i in todo if slots[i].status == "done")
    return [s.summary or {} for s in slots]

