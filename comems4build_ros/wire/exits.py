"""Exit codes of the node processes and how a node names why it ended a run early (no rclpy here).

The supervisor (:mod:`comems4build_ros.run.supervisor`) reads them: exit code 0 means the
process's part of the run is complete (a node exits 0 only after ``plant/done``, a
lock-step master only after its last step); every other code while the run is in
progress fails the launch, named by :data:`EXIT_CODES` and by the last
``[<node>] cause: ...`` line of the process's log (:data:`CAUSE_TAG`).
"""

from __future__ import annotations

#: Exit code of a node that refused to start (bad parameters, scenario or contract).
EXIT_BAD_INPUT = 2
#: Exit code of a node stopped by SIGINT or SIGTERM before its part of the run was
#: complete (:func:`comems4build_ros.ros.process.run_complete`); after it, a signal ends the node with 0.
EXIT_INTERRUPTED = 3
#: Exit code of a lock-step master that ended the run because another party fell silent
#: (:meth:`comems4build_ros.ros.lockstep.LockStep.stall`).
EXIT_STALLED = 4
#: Exit code of a node that could not write a file during its run (a full disk, a file system
#: turned read-only): the recorder's bag, a cache.
EXIT_WRITE_FAILED = 5
#: What each non-zero exit code of a node process means (the supervisor's messages).
EXIT_CODES = {
    1: "error",
    EXIT_BAD_INPUT: "bad input",
    EXIT_INTERRUPTED: "stopped by a signal before the end of its run",
    EXIT_STALLED: "run stalled",
    EXIT_WRITE_FAILED: "could not write a file",
}
#: Prefix of the one line on stderr that names why a node ended a run early (read by the
#: supervisor from the node's log: :func:`comems4build_ros.ros.process.report_cause`).
CAUSE_TAG = "cause:"
#: Prefix of the line on stderr with which a node process starts its clean-up, followed by
#: the exit code its run decided (:func:`comems4build_ros.ros.process.cleanup_deadline`).
CLEANUP_TAG = "cleaning up:"
#: First line of what :mod:`faulthandler` writes when the C-level backstop of a hung
#: clean-up fires (``Timeout (0:00:30)!``, then the stack of every thread); it then exits 1.
BACKSTOP_MARK = "Timeout ("


def exit_meaning(code: int) -> str:
    """Words for a process's exit code (a negative code is the signal that killed it)."""
    import signal

    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return EXIT_CODES.get(code, "error")


def decided_before_hang(output: str) -> int | None:
    """The exit code a node process's run had decided when its clean-up hung and the C-level
    backstop ended it with code 1, read from the process's output (its log, or what ``ros2
    launch`` saw on its stderr): a ``cleaning up: exit code N`` line (:data:`CLEANUP_TAG`),
    then the backstop's :data:`BACKSTOP_MARK`; None if that is not what happened."""
    _, tag, rest = output.rpartition(f"{CLEANUP_TAG} exit code ")
    if not tag or BACKSTOP_MARK not in rest:
        return None
    from comems4build_ros.files.inputs import parse_integer

    try:  # str.isdigit would pass "²", which int refuses
        return parse_integer(rest.split(maxsplit=1)[0] if rest.split() else "")
    except ValueError:
        return None


class HangWatch:
    """Follows a process's output in chunks and keeps only what :func:`decided_before_hang`
    needs: the text from the last ``cleaning up:`` line on (at most ``limit`` characters),
    whatever the chunks' boundaries."""

    def __init__(self, limit: int = 65536) -> None:
        self.limit = limit
        self.text = ""

    def feed(self, chunk: str) -> None:
        """Add a chunk of output [text]."""
        text = self.text + chunk
        at = text.rfind(CLEANUP_TAG)
        if at >= 0:
            self.text = text[at:][: self.limit]
        else:  # no clean-up yet: only what may be the start of a line cut between chunks
            self.text = text[-len(CLEANUP_TAG) + 1:]

    def decided(self) -> int | None:
        """:func:`decided_before_hang` of what was fed."""
        return decided_before_hang(self.text)
