"""A resource that fails in the middle of a study is named, and the progress says a run failed.

The run store (``OUT/.runstore``) is made unwritable while ``sweep`` runs: immutable
(``chattr +i``: EPERM, for root too) with one worker process in the command's own process or
with a pool of two, or its file system filled up (ENOSPC on a tmpfs). A finished run whose
files cannot be stored is marked failed with the cause (the file and the operating system's
reason), the command ends with exit code 2 naming it, and no traceback is printed; before,
the pool took the store's error for a dead worker, ran the run again and ended in a
``RunFailedError`` with "0 failed" and no cause.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import mounted_tmpfs

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "comems4build_ros.app.cli"]
SWEEP = ["sweep", "--ems", "rbc", "--weeks", "2", "--no-progress", "--param", "battery.e_max_kwh=4,5,6,7,8,9"]


def _root_can_chattr(tmp: Path) -> bool:
    probe = tmp / "probe"
    probe.mkdir()
    ok = shutil.which("chattr") is not None and subprocess.run(["chattr", "+i", str(probe)],
                                                               capture_output=True).returncode == 0
    if ok:
        subprocess.run(["chattr", "-i", str(probe)], check=True)
    probe.rmdir()
    return ok


@pytest.fixture()
def small_fs(tmp_path: Path) -> Iterator[Path]:
    with mounted_tmpfs(tmp_path / "fs", "8m") as mount:
        yield mount


def _fill(mount: Path) -> None:
    fd = os.open(mount / "filler", os.O_WRONLY | os.O_CREAT, 0o600)
    try:
        while True:
            os.write(fd, b"\0" * 65536)
    except OSError:
        pass  # full
    finally:
        os.close(fd)


def _sweep_failing(out: Path, jobs: int, fail: callable, undo: callable) -> tuple[int, str]:
    """Start the sweep, make the store fail once the study holds it, return exit code and stderr."""
    proc = subprocess.Popen([*CLI, *SWEEP, "--jobs", str(jobs), "--out", str(out)], cwd=REPO,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    store = out / ".runstore"
    deadline = time.monotonic() + 300
    try:
        while not (store / ".lock").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, "the sweep ended before its store could be made to fail"
        fail(store)
        _, err = proc.communicate(timeout=600)
    finally:
        undo(store)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err


def _check_named(code: int, err: str, reason: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err and "RunFailedError" not in err, err
    failed = [line for line in err.splitlines() if "FAILED: finished, but its files could not be stored" in line]
    assert failed and reason in failed[0] and ".runstore" in failed[0], err
    counts = [int(m) for m in re.findall(r"(\d+) failed\]", failed[0])]
    assert counts and counts[-1] >= 1, failed[0]  # the progress line of the failure counts it
    assert "error: " in err and reason in err.splitlines()[-1], err


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_run_store_made_immutable_during_sweep_is_named(tmp_path: Path, jobs: int) -> None:
    """Found by probing: EPERM on the run store while the study runs."""
    if not _root_can_chattr(tmp_path):
        pytest.skip("chattr +i is not available here (needs root and a file system with attributes)")
    code, err = _sweep_failing(tmp_path / "out", jobs,
                               lambda store: subprocess.run(["chattr", "+i", str(store)], check=True),
                               lambda store: subprocess.run(["chattr", "-i", str(store)], check=False))
    _check_named(code, err, os.strerror(1))  # EPERM: "Operation not permitted"


def test_a_run_store_on_a_disk_that_fills_during_sweep_is_named(small_fs: Path) -> None:
    code, err = _sweep_failing(small_fs / "out", 2, lambda store: _fill(small_fs),
                               lambda store: (small_fs / "filler").unlink(missing_ok=True))
    _check_named(code, err, os.strerror(28))  # ENOSPC: "No space left on device"
