"""A Dask cluster of this machine as real processes: ``dask scheduler`` and ``dask worker``.

:class:`LocalDaskCluster` starts the scheduler and ``n`` workers with the ``dask`` command
of this Python environment (the one ``tools/setup.sh`` installs into ``.venv``), each in
its own process group, on the loopback address and free ports; it is what ``bench study``
measures and what the tests run studies against. A cluster of several hosts is started the
same way by hand (docs/cluster.md). :meth:`LocalDaskCluster.stop` ends every process it
started (SIGTERM, then SIGKILL to the process group), so no scheduler or worker outlives it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import IO, Any

#: Environment of the scheduler: a worker holds only the runs it executes (no second run
#: queued behind a long one while another worker is idle).
SCHEDULER_ENV = {"DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "1.0"}
#: Environment of the workers: no statistical profiler sampling the task thread every
#: 10 ms (a run is pure-Python work; the samples cost it time and the profile is not used).
WORKER_ENV = {"DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False"}
#: Time for the scheduler to listen and for the workers to connect [s].
START_TIMEOUT_S = 60.0


class ClusterError(RuntimeError):
    """The local cluster did not come up (message names the process and its log)."""


def dask_command() -> str:
    """The ``dask`` command of this Python environment (beside its interpreter)."""
    exe = Path(sys.executable).with_name("dask")
    if exe.is_file():
        return str(exe)
    found = shutil.which("dask")
    if found is None:
        raise ClusterError(f"no 'dask' command beside {sys.executable} nor on PATH (install requirements.txt)")
    return found


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _listening(host: str, port: int) -> bool:
    with contextlib.suppress(OSError), socket.create_connection((host, port), timeout=0.5):
        return True
    return False


def _alive(pid: int) -> bool:
    """Whether ``pid`` is a process that still runs (a zombie does not)."""
    import psutil

    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


class LocalDaskCluster:
    """A scheduler and ``n_workers`` workers (one process with ``threads`` threads each) on ``host``.

    Use as a context manager. ``address``: the scheduler's ``tcp://host:port``;
    ``dashboard``: its dashboard URL (None without); ``logs``: directory of the processes'
    logs; ``nanny``: workers under a nanny that restarts a worker process that died (as
    ``dask worker`` runs by default).
    """

    def __init__(self, n_workers: int = 2, threads: int = 1, host: str = "127.0.0.1", dashboard: bool = True,
                 nanny: bool = True, log_dir: str | Path | None = None) -> None:
        self.n_workers = n_workers
        self.threads = threads
        self.host = host
        self.with_dashboard = dashboard
        self.nanny = nanny
        self._own_logs = log_dir is None
        self.logs = Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix="comems4build-dask-"))
        self.address = ""
        self.dashboard: str | None = None
        self.procs: list[subprocess.Popen] = []
        self._files: list[IO[bytes]] = []
        self.start_s = 0.0

    def __enter__(self) -> LocalDaskCluster:
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _spawn(self, name: str, argv: list[str], env: dict[str, str] | None = None) -> subprocess.Popen:
        log = open(self.logs / f"{name}.log", "wb")  # noqa: SIM115 - closed in stop()
        self._files.append(log)
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                cwd=self.logs, env={**os.environ, **(env or {})}, start_new_session=True)
        self.procs.append(proc)
        return proc

    def start(self) -> None:
        """Start the scheduler, wait until it listens, start the workers, wait until all joined."""
        t0 = time.perf_counter()
        dask = dask_command()
        port = free_port(self.host)
        argv = [dask, "scheduler", "--host", self.host, "--port", str(port)]
        if self.with_dashboard:
            dash = free_port(self.host)
            argv += ["--dashboard-address", f"{self.host}:{dash}"]
        else:
            argv += ["--no-dashboard"]
        scheduler = self._spawn("scheduler", argv, SCHEDULER_ENV)
        deadline = time.monotonic() + START_TIMEOUT_S
        while not _listening(self.host, port):
            if scheduler.poll() is not None:
                raise ClusterError(f"dask scheduler ended with code {scheduler.returncode} "
                                   f"(log {self.logs / 'scheduler.log'})")
            if time.monotonic() > deadline:
                raise ClusterError(f"dask scheduler not listening after {START_TIMEOUT_S:.0f} s "
                                   f"(log {self.logs / 'scheduler.log'})")
            time.sleep(0.1)
        self.address = f"tcp://{self.host}:{port}"
        for i in range(self.n_workers):
            local = self.logs / f"worker{i}"
            local.mkdir(exist_ok=True)
            self._spawn(f"worker{i}", [dask, "worker", self.address, "--host", self.host, "--name", f"worker{i}",
                                       "--nworkers", "1", "--nthreads", str(self.threads), "--no-dashboard",
                                       "--local-directory", str(local), "--death-timeout", "60",
                                       "--nanny" if self.nanny else "--no-nanny"], WORKER_ENV)
        self._wait_for_workers(deadline)
        self.start_s = time.perf_counter() - t0

    def _wait_for_workers(self, deadline: float) -> None:
        from distributed import Client

        with Client(self.address, timeout=START_TIMEOUT_S, set_as_default=False) as client:
            while len(client.scheduler_info()["workers"]) < self.n_workers:
                dead = [p for p in self.procs if p.poll() is not None]
                if dead:
                    raise ClusterError(f"a dask process ended with code {dead[0].returncode} (logs in {self.logs})")
                if time.monotonic() > deadline:
                    raise ClusterError(f"{len(client.scheduler_info()['workers'])} of {self.n_workers} dask workers "
                                       f"joined in {START_TIMEOUT_S:.0f} s (logs in {self.logs})")
                time.sleep(0.2)
            if self.with_dashboard and "dashboard" in client.scheduler_info().get("services", {}):
                self.dashboard = client.dashboard_link

    def worker_pids(self) -> dict[str, int]:
        """Worker address -> process id of the worker process (the one that runs tasks)."""
        from distributed import Client

        with Client(self.address, timeout=START_TIMEOUT_S, set_as_default=False) as client:
            return dict(client.run(os.getpid))

    def pids(self) -> list[int]:
        """Every process of the cluster now (the started ones and their children)."""
        import psutil

        out = []
        for p in self.procs:
            with contextlib.suppress(psutil.NoSuchProcess):
                proc = psutil.Process(p.pid)
                out += [proc.pid, *(c.pid for c in proc.children(recursive=True))]
        return out

    def stop(self, grace_s: float = 10.0) -> None:
        """End the workers, then the scheduler: SIGTERM to each process group, SIGKILL after ``grace_s``."""

        workers, scheduler = self.procs[1:], self.procs[:1]
        family = self.pids()
        for group in (workers, scheduler):
            for p in group:
                if p.poll() is None:
                    with contextlib.suppress(ProcessLookupError):
                        os.killpg(p.pid, signal.SIGTERM)
            deadline = time.monotonic() + grace_s
            for p in group:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    p.wait(max(0.0, deadline - time.monotonic()))
            for p in group:  # the group: a nanny's worker process too, whether or not the nanny ended
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        self.procs = []
        deadline = time.monotonic() + grace_s
        while time.monotonic() < deadline and any(_alive(pid) for pid in family):
            time.sleep(0.1)  # a worker process whose nanny died is reaped by init
        for f in self._files:
            f.close()
        self._files = []
        if self._own_logs:
            shutil.rmtree(self.logs, ignore_errors=True)

    def info(self) -> dict[str, Any]:
        """Address, dashboard, workers and start-up time."""
        return {"address": self.address, "dashboard": self.dashboard, "workers": self.n_workers,
                "threads": self.threads, "start_s": self.start_s}
