"""The end of a node process: a hung clean-up still ends it, and the launcher reads why.

Real processes: each case runs a Python child that starts ``process.cleanup_deadline`` and
then hangs, once in Python (the watchdog thread runs) and once inside native code that
holds the interpreter lock (``ctypes.PyDLL`` keeps it during the call, as rclpy's clean-up
was seen to; only ``faulthandler``'s C-level backstop can act then).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from comems4build_ros.run.supervisor import ProcessGroup, exit_code

HANG = {
    # the watchdog thread can run: it exits with the decided code
    "python": "time.sleep(60)",
    # native code holding the interpreter lock: the watchdog thread cannot run
    "native": "ctypes.PyDLL(None).sleep(60)",
}


def _child(kind: str, code: int) -> list[str]:
    script = textwrap.dedent(f"""
        import ctypes, time
        from comems4build_ros.ros.process import cleanup_deadline
        cleanup_deadline("node", {code}, timeout_s=0.5, backstop_s=1.0)
        {HANG[kind]}
    """)
    return [sys.executable, "-c", script]


@pytest.mark.parametrize(("kind", "code", "exits", "says"), [
    ("python", 0, 0, "[node]: clean-up did not finish within 0.5 s; exiting with code 0 without it"),
    ("python", 3, 3, "exiting with code 3 without it"),
    ("native", 0, 1, "Timeout (0:00:01.500000)!"),
])
def test_a_hung_clean_up_still_ends_the_process(kind: str, code: int, exits: int, says: str) -> None:
    t0 = time.monotonic()
    res = subprocess.run(_child(kind, code), capture_output=True, text=True, timeout=30)
    assert time.monotonic() - t0 < 20  # not the 60 s of the hang
    assert res.returncode == exits, res.stderr
    assert f"[node]: cleaning up: exit code {code}" in res.stderr and says in res.stderr, res.stderr
    if kind == "native":  # where it hung: the stack of the main thread
        assert "most recent call first" in res.stderr and "<string>" in res.stderr, res.stderr


@pytest.mark.parametrize(("code", "counts_as"), [(0, 0), (3, 1)])
def test_the_launcher_counts_a_hang_after_a_complete_run_as_done(tmp_path: Path, code: int, counts_as: int,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Exit 1 by the backstop after the run had decided 0 counts as 0 (with a warning naming
    the log); after any other decision it stays 1, as does a plain exit 1."""
    with ProcessGroup({}, tmp_path / "log") as group:
        hung = group.start("recorder", "recorder", _child("native", code), finishes=True)
        plain = group.start("feed", "feed", [sys.executable, "-c", "raise SystemExit(1)"], finishes=True)
        for c in (hung, plain):
            c.proc.wait(timeout=30)
        assert hung.proc.returncode == 1
        assert exit_code(hung) == counts_as and exit_code(plain) == 1
        assert exit_code(hung) == counts_as  # asked again: the same, said once
    err = capsys.readouterr().err
    assert err.count("clean-up hung") == (1 if counts_as == 0 else 0), err
    if counts_as == 0:
        assert str(hung.log_path) in err


def test_a_stop_signal_that_rclpy_turned_into_a_runtime_error_is_a_stop() -> None:
    """SIGTERM's KeyboardInterrupt raised inside rclpy's pybind11 argument conversion comes out
    as ``RuntimeError: Unable to convert call argument``: the node still ends as stopped by a
    signal (exit 3, with its cause line), not with a traceback and exit 1."""
    from comems4build_ros.wire.exits import EXIT_INTERRUPTED

    script = textwrap.dedent("""
        import os, signal, sys, time
        from comems4build_ros.ros.process import run_node

        def make():
            try:  # what pybind11 makes of the signal's KeyboardInterrupt in take_message
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)
            except KeyboardInterrupt:
                raise RuntimeError("Unable to convert call argument '0' to Python object") from None

        sys.exit(run_node(make, [], "node"))
    """)
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert res.returncode == EXIT_INTERRUPTED, res.stderr
    assert "Traceback" not in res.stderr and "[node]: cause: stopped by a signal" in res.stderr, res.stderr


@pytest.fixture(scope="module")
def hung_outputs() -> dict[tuple[str, int], str]:
    """The real stderr of a child whose clean-up hung, per (kind, decided code)."""
    return {(kind, code): subprocess.run(_child(kind, code), capture_output=True, text=True, timeout=30).stderr
            for kind, code in (("native", 0), ("native", 3), ("python", 0))}


@given(cuts=st.lists(st.integers(0, 4000), max_size=12), noise=st.text(max_size=200))
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_ros2_launch_reads_the_decision_from_stderr_in_any_chunks(hung_outputs: dict, cuts: list[int],
                                                                  noise: str) -> None:
    """What ``ros2 launch`` sees of a process (its stderr in chunks of any size, after other
    output) gives the same decision as the launcher's log: 0 or 3 after a backstop, None
    when the watchdog thread ended it (its own exit code stands) or nothing hung."""
    from comems4build_ros.wire.exits import HangWatch, decided_before_hang

    for (kind, code), text in hung_outputs.items():
        watch = HangWatch()
        full = noise + text
        bounds = sorted({0, len(full), *(c for c in cuts if c < len(full))})
        for a, b in zip(bounds, bounds[1:]):
            watch.feed(full[a:b])
        expect = code if kind == "native" else None
        assert watch.decided() == decided_before_hang(full) == expect, (kind, code, full[-300:])
    watch = HangWatch()
    watch.feed(noise)
    assert watch.decided() is None
