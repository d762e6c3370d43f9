"""Studies on local worker processes and on a real Dask cluster: same results, killed workers, resume.

The cluster is real: a ``dask scheduler`` and two ``dask worker`` processes of this
environment on 127.0.0.1 (:class:`comems4build_ros.study.cluster.LocalDaskCluster`); the
studies are ``comems4build sweep`` commands in their own processes. Every cluster is
stopped at the end of its test and no process of it may be left.
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import signal
import socket
import ssl
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.study.cluster import LocalDaskCluster, _alive, free_port
from comems4build_ros.study.pool import PoolError, check_environment
from comems4build_ros.study.spec import environment

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "comems4build_ros.app.cli"]
#: Timing entries of a summary (they differ between any two runs of the same specification).
TIMING = ("wall_s", "ems_s", "task_wall_s")
#: Time limit of one study command in these tests [s].
COMMAND_TIMEOUT_S = 300


@pytest.fixture
def cluster() -> Iterator[LocalDaskCluster]:
    """A scheduler and two single-threaded workers (with nannies); none of their processes outlives the test."""
    with LocalDaskCluster(n_workers=2, threads=1) as c:
        family = c.pids()
        assert len(family) >= 5  # scheduler, two nannies, two worker processes
        yield c
    left = [pid for pid in family if _alive(pid)]
    assert not left, f"dask processes left running: {left}"


def _run(argv: list[str | Path], timeout: float = COMMAND_TIMEOUT_S,
         cluster: LocalDaskCluster | None = None) -> subprocess.CompletedProcess:
    """``comems4build argv``; with ``cluster``, with the Dask settings of its TLS certificates."""
    return subprocess.run([*CLI, *map(str, argv)], cwd=REPO, capture_output=True, text=True, timeout=timeout,
                          env=_env(cluster))


def _env(cluster: LocalDaskCluster | None) -> dict[str, str]:
    """The environment of a client process of ``cluster`` (its certificate files; this one's without)."""
    return {**os.environ, **(cluster.client_env() if cluster is not None else {})}


def _without_timing(path: Path) -> str:
    """A summary.json's text without the lines of its timing entries (the rest byte for byte)."""
    return "".join(line for line in path.read_text(encoding="utf-8").splitlines(keepends=True)
                   if not any(line.strip().startswith(f'"{k}"') for k in TIMING))


def _table_without_wall(path: Path) -> list[list[str]]:
    """sweep.csv as its cells' text, without the run wall time column."""
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))
    keep = [i for i, name in enumerate(rows[0]) if name != "wall_s"]
    assert len(keep) == len(rows[0]) - 1
    return [[row[i] for i in keep] for row in rows]


def _records(out: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text(encoding="utf-8")) for p in (out / "runs").glob("*/run.json")}


# --------------------------------------------------------------------------- same results on Dask

def test_sweep_on_a_dask_cluster_gives_the_local_results_byte_for_byte(
        tmp_path: Path, cluster: LocalDaskCluster) -> None:
    argv = ["sweep", "--param", "battery.e_max_kwh=5,10", "--ems", "fuzzy,rbc", "--weeks", "1", "--timeseries",
            "--no-progress"]
    local = _run([*argv, "--jobs", "2", "--out", tmp_path / "local"])
    assert local.returncode == 0, local.stderr
    dask = _run([*argv, "--scheduler", cluster.address, "--out", tmp_path / "dask"], cluster=cluster)
    assert dask.returncode == 0, dask.stderr
    assert f"Dask scheduler {cluster.address}: 2 workers, 2 threads; dashboard {cluster.dashboard}" in dask.stderr
    assert cluster.dashboard and cluster.dashboard.startswith("http://127.0.0.1:")
    assert "[4/4 done, 0 running, 0 failed]" in dask.stderr
    workers = set(cluster.worker_pids())
    for name, record in _records(tmp_path / "dask").items():
        assert [a["outcome"] for a in record["attempts"]] == ["finished"], name
        assert record["attempts"][0]["worker"] in workers  # ran on a worker of the cluster, not here
    for name, record in _records(tmp_path / "local").items():
        assert record["attempts"][0]["worker"].startswith("local:"), name
    assert _table_without_wall(tmp_path / "local" / "sweep.csv") == _table_without_wall(tmp_path / "dask" / "sweep.csv")
    names = sorted(p.name for p in (tmp_path / "local" / "runs").iterdir())
    assert len(names) == 4 and names == sorted(p.name for p in (tmp_path / "dask" / "runs").iterdir())
    for name in names:
        a, b = tmp_path / "local" / "runs" / name, tmp_path / "dask" / "runs" / name
        assert _without_timing(a / "summary.json") == _without_timing(b / "summary.json"), name
        for file in ("weekly.csv", "timeseries.csv"):
            assert (a / file).read_bytes() == (b / file).read_bytes(), f"{name}/{file}"
    assert not (tmp_path / "dask" / ".runstore").exists()  # the store goes once the results are in place


# --------------------------------------------------------------------------- a worker killed mid-run

@pytest.mark.parametrize("where", ["local", "dask"])
def test_a_worker_killed_mid_run_costs_only_its_run(tmp_path: Path, where: str,
                                                    request: pytest.FixtureRequest) -> None:
    """SIGKILL to the process running the first run: that run runs again, the study completes with every run."""
    out = tmp_path / "sweep"
    argv = ["sweep", "--param", "battery.e_max_kwh=4,7,10", "--ems", "mpc", "--weeks", "0.25", "--no-progress",
            "--out", out]
    c = None
    if where == "dask":
        c = request.getfixturevalue("cluster")
        argv += ["--scheduler", c.address]
        workers = set(c.pids())
    else:
        argv += ["--jobs", "2"]
    proc = subprocess.Popen([*CLI, *map(str, argv)], cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=_env(c))
    killed: tuple[str, int] | None = None
    err = []
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            err.append(line)
            m = re.search(r"\] (\S+): started on (\S+) \(host \S+, pid (\d+)\)", line)
            if m and killed is None:
                pid = int(m[3])
                if where == "dask":
                    assert pid in workers  # a worker process of the cluster
                else:
                    assert psutil.Process(pid).ppid() == proc.pid  # a worker process of the command
                os.kill(pid, signal.SIGKILL)
                killed = (m[1], pid)
        code = proc.wait(COMMAND_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = "".join(err)
    assert code == 0, text
    assert killed is not None, text
    assert "[3/3 done, 0 running, 0 failed]" in text
    assert "it runs again" in text
    records = _records(out)
    assert len(records) == 3
    lost = records[killed[0]]["attempts"]
    assert len(lost) == 2, lost
    assert lost[0]["pid"] == killed[1] and lost[0]["outcome"].startswith("lost:"), lost
    assert lost[1]["outcome"] == "finished" and lost[1]["pid"] != killed[1], lost
    for name, record in records.items():  # no other run was run twice
        if name != killed[0]:
            assert [a["outcome"] for a in record["attempts"]] == ["finished"], name
    rows = _table_without_wall(out / "sweep.csv")
    assert len(rows) == 4


# --------------------------------------------------------------------------- interrupted and resumed

@pytest.mark.parametrize(("where", "sig"), [("local", signal.SIGINT), ("dask", signal.SIGTERM)])
def test_an_interrupted_study_resumes_without_running_its_finished_runs_again(
        tmp_path: Path, where: str, sig: signal.Signals, request: pytest.FixtureRequest) -> None:
    """Interrupted after two runs finished; --resume (on local processes) takes the stored runs as they are."""
    out = tmp_path / "sweep"

    def sweep(weeks: str = "52") -> list[str | Path]:  # a year per run (some seconds): time to interrupt
        return ["sweep", "--param", "battery.e_max_kwh=4,5,6,7,8,9", "--ems", "fuzzy", "--scenario", "year",
                "--weeks", weeks, "--no-progress", "--out", out]

    argv = sweep()
    c = request.getfixturevalue("cluster") if where == "dask" else None
    first = [*argv, "--scheduler", c.address] if c is not None else [*argv, "--jobs", "2"]
    # SIGINT and SIGTERM as by default in the child: an ignored signal of this process is inherited
    proc = subprocess.Popen([*CLI, *map(str, first)], cwd=REPO, stderr=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=_env(c), preexec_fn=lambda: [signal.signal(s, signal.SIG_DFL)
                                                           for s in (signal.SIGINT, signal.SIGTERM)])
    err = []
    try:
        assert proc.stderr is not None
        for line in proc.stderr:
            err.append(line)
            if "[2/6 done" in line:
                proc.send_signal(sig)
                break
        _, rest = proc.communicate(timeout=COMMAND_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = "".join(err) + (rest or "")
    assert proc.returncode == 130 and "interrupted" in text, text
    assert not (out / "sweep.csv").exists() and not (out / "runs").exists()  # no result in place
    store = out / ".runstore"
    stored = {p.name: json.loads((p / "run.json").read_text(encoding="utf-8"))
              for p in store.iterdir() if not p.name.startswith(".")}
    assert 2 <= len(stored) <= 4, sorted(stored)
    assert f"{len(stored)} finished run(s) are kept in {store}" in text
    first_study = {r["study"] for r in stored.values()}
    assert len(first_study) == 1

    again = _run([*argv, "--jobs", "2"])  # without --resume: refused, the store is kept
    assert again.returncode == 2 and "--resume" in again.stderr and store.is_dir()
    other = _run([*sweep("51"), "--resume"])
    assert other.returncode == 2, other.stderr
    assert "another specification" in other.stderr and "weeks: 52.0 -> 51.0" in other.stderr

    resumed = _run([*argv, "--jobs", "2", "--resume"])
    assert resumed.returncode == 0, resumed.stderr
    assert f"6 runs, {len(stored)} taken from {store}; {6 - len(stored)} to run" in resumed.stderr
    finished = len(re.findall(r": finished in ", resumed.stderr))
    assert finished == 6 - len(stored)  # only the runs not stored ran
    records = _records(out)
    assert len(records) == 6
    for name, record in records.items():
        if name in stored:  # the stored run as it was: same study, same attempt (start and end times)
            assert record["study"] in first_study and record["attempts"] == stored[name]["attempts"], name
            assert record["spec_hash"] == stored[name]["spec_hash"]
        else:
            assert record["study"] not in first_study, name
    assert len(_table_without_wall(out / "sweep.csv")) == 7
    assert not store.exists()


# --------------------------------------------------------------------------- refused before any run

def test_study_pool_options_checked_before_any_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--weeks", "1", "--no-progress"]
    for url, message in (("http://127.0.0.1:8786", "tcp://HOST:PORT"), ("tcp://127.0.0.1", "tcp://HOST:PORT"),
                         ("tcp://127.0.0.1:0", "outside 1..65535"), ("tcp://u:p@127.0.0.1:8786", "tcp://HOST:PORT")):
        with pytest.raises(SystemExit) as exc:
            main([*base, "--scheduler", url, "--out", str(tmp_path / "x")])
        assert exc.value.code == 2
        assert message in capsys.readouterr().err, url
    out = tmp_path / "y"
    assert main([*base, "--scheduler", "tcp://127.0.0.1:8786", "--jobs", "2", "--out", str(out)]) == 2
    assert "--jobs and --scheduler exclude each other" in capsys.readouterr().err
    port = free_port()
    t0 = time.monotonic()
    assert main([*base, "--scheduler", f"tcp://127.0.0.1:{port}", "--out", str(out)]) == 2
    assert f"--scheduler tcp://127.0.0.1:{port}: no scheduler answered" in capsys.readouterr().err
    assert time.monotonic() - t0 < 60
    assert not out.exists()  # nothing written


def test_a_worker_of_another_environment_is_named() -> None:
    mine = environment()
    check_environment({"tcp://a:1": dict(mine)}, "tcp://s:1")
    other = {**mine, "numpy": "0.0.1"}
    with pytest.raises(PoolError, match=r"worker tcp://b:2: numpy: \"[^\"]+\" -> \"0.0.1\""):
        check_environment({"tcp://a:1": dict(mine), "tcp://b:2": other}, "tcp://s:1")


# --------------------------------------------------------------------------- bench study

def _dask_processes() -> set[int]:
    """Processes of this environment's ``dask`` command and the processes such ones spawn.

    A dask scheduler or worker (``.venv/bin/dask ...``), a nanny's worker process and its
    resource tracker (``python -c from multiprocessing...``) of this environment's Python;
    other checkouts' environments are not counted.
    """
    dask, python = str(Path(sys.executable).with_name("dask")), str(Path(sys.executable))
    out = set()
    for p in psutil.process_iter(["cmdline"]):
        cmd = p.info["cmdline"] or []
        spawned = bool(cmd) and cmd[0] == python and any("from multiprocessing" in c for c in cmd)
        if (dask in cmd or spawned) and p.pid != os.getpid():
            out.add(p.pid)
    return out


def test_bench_study_prints_the_three_ways_and_leaves_no_dask_process() -> None:
    before = _dask_processes()
    proc = _run(["bench", "study", "--runs", "2", "--ems", "rbc", "--weeks", "0.25", "--repeats", "1"])
    assert proc.returncode == 0, proc.stderr + proc.stdout
    out = proc.stdout
    for way in ("1 local worker", "2 local workers", "Dask, 2 workers"):
        assert re.search(rf"^{re.escape(way)}\s+\d+\.\d\d\s+\d+\.\d\d \.\. \d+\.\d\d", out, re.M), way
    assert re.search(r"Dask, 2 workers: parallel efficiency \d+\.\d %", out)
    assert "summaries identical across the ways (timing entries aside): yes" in out
    assert out.count("load average") >= 7  # beside every measurement
    deadline = time.monotonic() + 10
    while (left := {pid for pid in _dask_processes() - before if _alive(pid)}) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, [psutil.Process(pid).cmdline() for pid in left]


# --------------------------------------------------------------------------- no one else at the controls

def test_a_local_cluster_takes_only_clients_with_its_certificate(cluster: LocalDaskCluster) -> None:
    """TLS with per-cluster certificates, loopback only: a client without the certificate (any other local
    user, who cannot read the cluster's key) is refused, plain TCP is refused, the key is private."""
    from distributed import Client, Security

    assert cluster.address.startswith("tls://127.0.0.1:")
    for conn in psutil.Process(cluster.procs[0].pid).net_connections(kind="inet"):
        if conn.status == psutil.CONN_LISTEN:
            assert conn.laddr.ip in ("127.0.0.1", "::1"), conn
    certs = Path(cluster.client_env()["DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY"])
    assert certs.stat().st_mode & 0o077 == 0 and certs.parent.stat().st_mode & 0o077 == 0
    host, port = cluster.address.removeprefix("tls://").rsplit(":", 1)
    ctx = ssl.create_default_context()
    ctx.check_hostname, ctx.verify_mode = False, ssl.CERT_NONE  # trusts any server, has no certificate of its own
    with socket.create_connection((host, int(port)), timeout=10) as raw:
        with pytest.raises((ssl.SSLError, ConnectionError)):  # no client certificate: the scheduler ends the handshake
            with ctx.wrap_socket(raw) as tls:
                if not tls.recv(1):  # TLS 1.3: the refusal arrives with the first read
                    raise ConnectionResetError("closed by the scheduler")
    with pytest.raises((OSError, TimeoutError)):  # a certificate of another cluster: refused
        Client(cluster.address, timeout=5, set_as_default=False, security=Security.temporary()).close()
    with pytest.raises((OSError, TimeoutError)):  # plain TCP on the TLS port
        Client(cluster.address.replace("tls://", "tcp://"), timeout=5, set_as_default=False).close()
    with cluster.client() as client:  # the cluster's own certificate
        assert len(client.scheduler_info()["workers"]) == 2


def test_a_local_cluster_refuses_a_host_other_than_loopback() -> None:
    with pytest.raises(ValueError, match="loopback"):
        LocalDaskCluster(host="0.0.0.0")
