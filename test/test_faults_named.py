"""Faults named by their cause, with real processes (``comems4build launch``).

* the lock-step master itself paused (SIGSTOP) for longer than its step time-out: the run
  goes on without a fallback counted against the EMS, the pause is said on ``plant/events``;
* the EMS paused: the launcher says, while it waits, which process is paused, and names it
  when the run stalls;
* a bag that cannot be written: a read-only file system (as root too) and a file system
  without the room of the bag are refused before any node starts; a disk that fills during
  the run ends the recorder with exit code 5 naming the file and "No space left on device",
  no traceback.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import mounted_tmpfs
from launch_probe import pid_of, run_held
from test_run_faults import CLI, STEP_TIMEOUT, Run
from waits import BUDGET_S, wait_until

pytestmark = pytest.mark.ros


def test_a_paused_plant_is_named_paused_not_a_late_ems_command(tmp_path: Path) -> None:
    out = tmp_path / "run"
    run = Run(out, "--ems", "rbc", "--weeks", "12", "--step-timeout", STEP_TIMEOUT)
    run.wait_running("plant_sim")
    with run_held(out):  # the fault itself: paused mid-run (not after its last step), continued afterwards
        # how long it lasts is the fault, not a wait for anything: longer than the step time-out,
        # shorter than the launcher's stall limit
        time.sleep(3 * float(STEP_TIMEOUT) + 1)
    code, err = run.finish()
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fallback_steps"] == 0, summary["fallback_steps"]  # no late command counted against the EMS
    log = (out / "log" / "plant_sim.log").read_text(errors="replace")
    assert "paused" in log and "itself did not run for" in log, log[-2000:]
    assert "launcher: warning: process 'plant_sim' is paused (SIGSTOP" in err, err


def test_a_paused_ems_is_named_while_it_is_and_when_the_run_stalls(tmp_path: Path) -> None:
    out = tmp_path / "run"
    run = Run(out, "--ems", "fuzzy", "--weeks", "12", "--step-timeout", STEP_TIMEOUT)
    run.wait_running("plant_sim")
    with run_held(out):  # the run cannot end before the EMS is paused
        os.kill(pid_of(out, "fuzzy_ems"), signal.SIGSTOP)
    code, err = run.finish()
    assert code == 1, err
    assert "launcher: warning: process 'fuzzy_ems' is paused (SIGSTOP" in err, err
    assert "paused (SIGSTOP) at that time: 'fuzzy_ems'" in err, err


@pytest.fixture()
def tiny_fs(tmp_path: Path) -> Iterator[Path]:
    """A tmpfs of 24 MiB (mounting needs root; skipped where that is refused)."""
    with mounted_tmpfs(tmp_path / "fs", "24m") as mount:
        yield mount


def test_a_bag_that_cannot_be_written_is_refused_before_any_node(tiny_fs: Path, tmp_path: Path) -> None:
    for args, named in ((["--weeks", "12"], "MiB free on its file system"),  # 2016 steps do not fit in 24 MiB
                        (["--steps", "24"], "is not writable")):
        if named == "is not writable":
            subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], check=True)
        out = tmp_path / f"out_{len(args[1])}"
        res = subprocess.run([*CLI, "launch", "--ems", "rbc", *args, "--bag", str(tiny_fs / "bag"), "--out", str(out),
                              "--no-progress"], capture_output=True, text=True, timeout=BUDGET_S)
        assert res.returncode == 2 and f"--bag {tiny_fs / 'bag'}" in res.stderr and named in res.stderr, res.stderr
        assert not out.exists() and not (tiny_fs / "bag").exists()  # no node started, nothing written


def test_a_disk_that_fills_during_the_run_is_named(tiny_fs: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    run = Run(out, "--ems", "fuzzy", "--weeks", "4", "--step-timeout", STEP_TIMEOUT, "--bag", str(tiny_fs / "bag"))
    wait_until(lambda: (tiny_fs / "bag").is_dir() or run.proc.poll() is not None, "the bag")
    filler = tiny_fs / "filler"
    try:  # the rest of the file system, while the recorder writes
        with open(filler, "wb") as fh:
            while True:
                fh.write(b"\0" * 65536)
    except OSError:
        pass  # full
    code, err = run.finish()
    assert code == 1, err
    assert "exited with code 5 (could not write a file)" in err and "No space left on device" in err, err
    assert "Traceback" not in (out / "log" / "recorder.log").read_text(errors="replace")
