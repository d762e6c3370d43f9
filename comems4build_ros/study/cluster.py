"""A Dask cluster of this machine as real processes: ``dask scheduler`` and ``dask worker``.

:class:`LocalDaskCluster` starts the scheduler and ``n`` workers with the ``dask`` command
of this Python environment (the one ``tools/setup.sh`` installs into ``.venv``), each in
its own process group, on the loopback address and free ports; it is what ``bench study``
measures and what the tests run studies against. A cluster of several hosts is started the
same way by hand (docs/cluster.md). :meth:`LocalDaskCluster.stop` ends every process it
started (SIGTERM, then SIGKILL to the process group), so no scheduler or worker outlives it.

The cluster speaks TLS with certificates made for this cluster alone
(``distributed.Security.temporary()``: a self-signed key and certificate that serve as CA,
scheduler, worker and client certificate; Dask requires the peer's certificate on every
connection), written into a directory only the cluster's user can read; scheduler, nanny
and workers listen on the loopback address only. So another local user can neither connect
to the scheduler (to submit code that would run as the study's user) nor read or alter its
traffic. :meth:`LocalDaskCluster.client_env` gives the Dask settings a client process needs
(``comems4build ... --scheduler tls://...``).
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

from comems4build_ros.files.errors import InputError

#: Environment of the scheduler: a worker holds only the runs it executes (no second run
#: queued behind a long one while another worker is idle).
SCHEDULER_ENV = {"DASK_DISTRIBUTED__SCHEDULER__WORKER_SATURATION": "1.0"}
#: Environment of the workers: no statistical profiler sampling the task thread every
#: 10 ms (a run is pure-Python work; the samples cost it time and the profile is not used).
WORKER_ENV = {"DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False"}
#: Time for the scheduler to listen and for the workers to connect [s].
START_TIMEOUT_S = 60.0
#: Host names a local cluster may listen on: the loopback interface only.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


class ClusterError(RuntimeError):
    """The local cluster did not come up (message names the process and its log)."""


class NotASchedulerError(InputError):
    """The address of ``--scheduler`` answers, but not as a Dask scheduler (or not at all); names it."""


#: Wait for the connection and for the scheduler's handshake [s]: a scheduler answers in milliseconds.
PROBE_TIMEOUT_S = 5.0
#: Largest first message a scheduler sends (its handshake: a few hundred bytes) [bytes].
HANDSHAKE_MAX_BYTES = 1 << 20


def probe_scheduler(address: str, timeout_s: float = PROBE_TIMEOUT_S) -> None:
    """Prove that ``address`` (``tcp://HOST:PORT`` or ``tls://HOST:PORT``) is a Dask scheduler, before any work.

    A Dask server sends its handshake as soon as a connection is accepted: an 8-byte
    little-endian length, then a msgpack message with the keys ``compression``, ``python``
    and ``pickle-protocol``. The probe reads it with a short timeout from a plain socket
    (over TLS with the client certificate of the Dask configuration), so a server of
    another kind (HTTP, SSH, a closed port) is refused at once, naming the address, instead
    of Dask reading its reply as a frame length of exabytes after 20 s.

    Raises
    ------
    NotASchedulerError
        Naming the address and what it answered.
    """
    import ssl
    import struct
    from urllib.parse import urlsplit

    url = urlsplit(address)
    host, port = url.hostname or "", url.port or 0
    what = f"--scheduler {address}"
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except TimeoutError:
        raise NotASchedulerError(f"{what}: no scheduler answered within {timeout_s:g} s") from None
    except OSError as exc:
        raise NotASchedulerError(f"{what}: no scheduler answered (cannot connect: {exc.strerror or exc})") from None
    try:
        sock.settimeout(timeout_s)
        if url.scheme == "tls":
            sock = _tls_client(address).wrap_socket(sock, server_hostname=host)
        head = _read_exactly(sock, 8)
        (n,) = struct.unpack("<Q", head)
        if not 0 < n <= HANDSHAKE_MAX_BYTES:
            raise NotASchedulerError(f"{what}: answered {head!r}, not a Dask handshake (not a Dask scheduler)")
        body = _read_exactly(sock, n)
        if b"pickle-protocol" not in body or b"compression" not in body:
            raise NotASchedulerError(f"{what}: its first message is not a Dask handshake (not a Dask scheduler)")
    except TimeoutError:
        raise NotASchedulerError(f"{what}: sent no Dask handshake within {timeout_s:g} s (not a Dask "
                                 "scheduler)") from None
    except ssl.SSLError as exc:
        raise NotASchedulerError(f"{what}: TLS failed ({exc.reason or exc}): not a Dask scheduler with this "
                                 "Dask configuration's certificates") from None
    except (EOFError, OSError) as exc:
        raise NotASchedulerError(f"{what}: closed the connection before a Dask handshake ({exc}): not a Dask "
                                 "scheduler") from None
    finally:
        sock.close()


def _read_exactly(sock: socket.socket, n: int) -> bytes:
    """``n`` bytes from ``sock`` (EOFError if it closes first)."""
    out = bytearray()
    while len(out) < n:
        chunk = sock.recv(min(n - len(out), 65536))
        if not chunk:
            raise EOFError(f"{len(out)} of {n} bytes")
        out += chunk
    return bytes(out)


def _tls_client(address: str) -> Any:
    """The client TLS context of the Dask configuration (the certificates a Dask client would present)."""
    from distributed.security import Security

    ctx = Security().get_connection_args("client").get("ssl_context")
    if ctx is None:
        raise NotASchedulerError(f"--scheduler {address}: TLS without a client certificate in the Dask "
                                 "configuration (distributed.comm.tls.client.cert; docs/cluster.md)")
    return ctx


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
                 nanny: bool = True, log_dir: str | Path | None = None, tls: bool = True) -> None:
        if host not in LOOPBACK_HOSTS:
            raise InputError("a local Dask cluster listens on the loopback address only "
                             f"({', '.join(LOOPBACK_HOSTS)}), "
                             f"not {host!r}")
        self.n_workers = n_workers
        self.tls = tls
        self.security: Any = None
        self._certs: Path | None = None
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
        argv += self._tls_args()
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
        self.address = f"{'tls' if self.tls else 'tcp'}://{self.host}:{port}"
        for i in range(self.n_workers):
            local = self.logs / f"worker{i}"
            local.mkdir(exist_ok=True)
            self._spawn(f"worker{i}", [dask, "worker", self.address, "--host", self.host, "--name", f"worker{i}",
                                       "--nworkers", "1", "--nthreads", str(self.threads), "--no-dashboard",
                                       "--local-directory", str(local), "--death-timeout", "60",
                                       "--nanny" if self.nanny else "--no-nanny", *self._tls_args()], WORKER_ENV)
        self._wait_for_workers(deadline)
        self.start_s = time.perf_counter() - t0

    def _tls_args(self) -> list[str]:
        """The ``--tls-*`` options of ``dask scheduler`` and ``dask worker``: this cluster's certificate files."""
        if not self.tls:
            return []
        if self._certs is None:
            from distributed import Security

            self.security = Security.temporary()
            self._certs = Path(tempfile.mkdtemp(prefix="comems4build-dask-tls-"))  # mode 0700
            for name, text in (("ca.pem", self.security.tls_ca_file), ("cert.pem", self.security.tls_scheduler_cert),
                               ("key.pem", self.security.tls_scheduler_key)):
                fd = os.open(self._certs / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                with os.fdopen(fd, "w", encoding="ascii") as fh:
                    fh.write(text)
        return ["--tls-ca-file", str(self._certs / "ca.pem"), "--tls-cert", str(self._certs / "cert.pem"),
                "--tls-key", str(self._certs / "key.pem")]

    def client(self, timeout: float = START_TIMEOUT_S) -> Any:
        """A ``distributed.Client`` of this cluster (with its TLS certificate)."""
        from distributed import Client

        return Client(self.address, timeout=timeout, set_as_default=False, security=self.security)

    def client_env(self) -> dict[str, str]:
        """Dask's settings for a client process of this cluster (``--scheduler``): its certificate files.

        Empty for a cluster without TLS. The files stay readable by the cluster's user only.
        """
        if not self.tls or self._certs is None:
            return {}
        ca, cert, key = (str(self._certs / n) for n in ("ca.pem", "cert.pem", "key.pem"))
        return {"DASK_DISTRIBUTED__COMM__REQUIRE_ENCRYPTION": "True",
                "DASK_DISTRIBUTED__COMM__TLS__CA_FILE": ca,
                "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT": cert,
                "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY": key}

    def _wait_for_workers(self, deadline: float) -> None:
        with self.client() as client:
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
        with self.client() as client:
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
        if self._certs is not None:  # the certificates serve this cluster only
            shutil.rmtree(self._certs, ignore_errors=True)
            self._certs = None

    def info(self) -> dict[str, Any]:
        """Address, dashboard, workers and start-up time."""
        return {"address": self.address, "dashboard": self.dashboard, "workers": self.n_workers,
                "threads": self.threads, "start_s": self.start_s, "tls": self.tls}
