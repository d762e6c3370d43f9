"""The one time budget of the tests that start ROS nodes, and the waits that use it (not a test module).

Every wait in those tests is for its condition itself: a node in the graph, then its
endpoints; a line in a log; a file on disk; a process's exit. None sleeps for a fixed time
in the hope that the condition holds by then. Each wait returns as soon as its condition
holds, and fails naming what it waited for once :data:`BUDGET_S` has passed without it.

The budget is the only number: a test does not choose its own time-out. A condition that a
quiet machine meets in more than 30 s belongs to a benchmark, not to a test (docs/testing.md
lists the tests that come near).
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

#: How long any one wait of a test may last before the test fails [s]. A condition of a test
#: comes within 30 s on a quiet machine (a longer one is a benchmark); on this 2-core machine
#: with two CPU-bound processes and other test runs beside it (load average 12 to 16) a
#: process gets an eighth of a core, so a condition may take 8 x 30 = 240 s; 300 s leaves a
#: margin. A passing test never waits for the budget, it only bounds how long a failing one hangs.
BUDGET_S = 300.0
#: How often a condition is checked [s] (a polling period, not a wait for anything).
POLL_S = 0.05

T = TypeVar("T")


class Deadline:
    """The budget of one wait, started now.

    Parameters
    ----------
    what : the condition waited for, in words (for the failure message)
    """

    def __init__(self, what: str) -> None:
        self.what = what
        self.end = time.monotonic() + BUDGET_S

    def left(self) -> float:
        """Seconds of the budget left (0 once it has passed) [s]."""
        return max(0.0, self.end - time.monotonic())

    def passed(self) -> bool:
        """Whether the budget has passed."""
        return time.monotonic() >= self.end

    def fail(self, detail: str = "") -> AssertionError:
        """The error of a wait whose budget passed (raise it)."""
        return AssertionError(f"not within the budget of {BUDGET_S:g} s: {self.what}" + (f" ({detail})" if detail
                                                                                          else ""))


def wait_until(cond: Callable[[], T], what: str, poll_s: float = POLL_S) -> T:
    """Wait until ``cond()`` is true; return its value.

    Parameters
    ----------
    cond : the condition (checked at once, then every ``poll_s``)
    what : the condition in words (for the failure message)
    poll_s : checking period [s]

    Raises
    ------
    AssertionError
        Naming ``what``, when :data:`BUDGET_S` passed without the condition.
    """
    deadline = Deadline(what)
    while True:
        value = cond()
        if value:
            return value
        if deadline.passed():
            raise deadline.fail()
        time.sleep(poll_s)


def wait_exit(proc: subprocess.Popen, what: str) -> int:
    """Wait for ``proc`` to exit; its exit code.

    Raises
    ------
    AssertionError
        Naming ``what``, when :data:`BUDGET_S` passed and the process still runs (it is left
        running; the caller's clean-up stops it).
    """
    try:
        return proc.wait(timeout=BUDGET_S)
    except subprocess.TimeoutExpired:
        raise Deadline(what).fail("the process still runs") from None


def log_has(path: str | Path, text: str) -> bool:
    """Whether the file ``path`` exists and holds ``text`` (a log line a wait looks for)."""
    p = Path(path)
    return p.exists() and text in p.read_text(errors="replace")
