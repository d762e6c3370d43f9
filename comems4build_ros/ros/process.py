"""The main loop of a node process: init, the executor, a clean shutdown with an exit code.

:func:`run_node` is the body of every node's ``main()`` (and :mod:`comems4build_ros.ros.container`
does the same for several nodes): the lean single-threaded executor
(:mod:`comems4build_ros.ros.executor`), clean shutdown on Ctrl-C / SIGTERM (executor
shutdown, destroy node, ``rclpy.try_shutdown``) and the exit codes the supervisor reads
(:data:`~comems4build_ros.wire.exits.EXIT_CODES`): 0 only once the node's part of the run is complete, a distinct code
for bad input, for a signal before the end of the run and for a stalled run.

Signals: rclpy's own SIGINT/SIGTERM handlers are not installed (:func:`init_rclpy`). Their
handler does work in signal context (it logs through rcutils and wakes a helper thread), and
a node process stopped by one signal was seen to hang for good, every thread waiting on a
lock. Here the signals go to Python's handlers, which only set a flag (async-signal-safe);
the executor never waits longer than :data:`SIGNAL_POLL_S`, so the main thread sees the
KeyboardInterrupt within that time and the clean-up runs in the normal order.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.task import Future

from comems4build_ros.core.config import ConfigError
from comems4build_ros.ros.log import process_logger
from comems4build_ros.ros.package_node import refuse_undeclared
from comems4build_ros.wire.contract import ContractError
from comems4build_ros.wire.exits import CAUSE_TAG, CLEANUP_TAG, EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_WRITE_FAILED

#: Environment variable choosing the executor of the node processes: ``lean`` (default,
#: :class:`comems4build_ros.ros.executor.LeanExecutor`) or ``single`` (rclpy's
#: ``SingleThreadedExecutor``, for comparison: ``comems4build bench ros`` measures both).
EXECUTOR_ENV = "COMEMS4BUILD_EXECUTOR"
EXECUTORS = ("lean", "single")


def make_executor() -> Any:
    """The executor of a node process, chosen by :data:`EXECUTOR_ENV` (default ``lean``).

    Raises
    ------
    ValueError
        For an unknown executor name.
    """
    import os

    name = os.environ.get(EXECUTOR_ENV, "lean") or "lean"
    if name == "single":
        return SingleThreadedExecutor()
    if name == "lean":
        from comems4build_ros.ros.executor import LeanExecutor

        return LeanExecutor()
    raise ValueError(f"environment variable {EXECUTOR_ENV}={name!r}: one of {', '.join(EXECUTORS)}")




#: Longest single wait of a node's executor [s]: a SIGINT or SIGTERM is acted on within this.
SIGNAL_POLL_S = 0.25


def init_rclpy(args: list[str] | None, name: str = "") -> None:
    """``rclpy.init`` without rclpy's signal handlers; SIGINT and SIGTERM raise
    ``KeyboardInterrupt`` in the main thread instead (see the module's docstring).

    Both are installed even when the process started with SIGINT ignored (a background job of
    a shell script), as rclpy does: a node must stop on the signal ``ros2 launch`` sends.
    The log file under ``ROS_LOG_DIR`` is named after the node (:func:`with_log_file_name`;
    ``name``: the node's or the process's own name).
    """
    import signal
    import threading

    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=with_log_file_name(list(sys.argv if args is None else args), name),
               signal_handler_options=SignalHandlerOptions.NO)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _stop_on_signal)
        signal.signal(signal.SIGTERM, _stop_on_signal)


def with_log_file_name(argv: list[str], name: str) -> list[str]:
    """``argv`` with ``--log-file-name`` after the node: ``<namespace>_<node>`` of its remapping
    (``-r __ns:=/house_0 -r __node:=plant_sim``: ``house_0_plant_sim``), ``name`` without one.

    rcl names a process's log file after its executable, which is the Python interpreter for
    every node of the package (``python_<pid>_<time>.log``); rcl appends ``_<pid>_<time>.log`` to
    the name given. An argument list that names the file itself is left as it is.
    """
    if "--log-file-name" in argv or not name:
        return argv
    ns, node = "", name
    for flag, value in zip(argv, argv[1:]):
        if flag not in ("-r", "--remap"):
            continue
        target, _, new = value.rpartition(":=")
        target = target.rpartition(":")[2]  # node-specific remapping: 'node:__ns'
        if target == "__node" and new:
            node = new
        elif target == "__ns":
            ns = new.strip("/")
    label = "_".join(p for p in (ns.replace("/", "_"), node) if p)
    return [*argv, "--ros-args", "--log-file-name", label]


#: The stop signal (SIGINT or SIGTERM) this process received, None before one came.
_stop_signal: int | None = None
#: When it came (``time.monotonic()``) [s].
_stop_at = 0.0
#: A stop signal this soon after the first is the same stop delivered twice (Ctrl-C reaches the
#: terminal's whole process group, and ``ros2 launch`` passes it on): ignored [s].
REPEATED_SIGNAL_S = 1.0


def _stop_on_signal(signum: int, frame: Any) -> None:
    """SIGINT and SIGTERM handler: note the signal (:func:`stop_signalled`), stop like Ctrl-C.

    A second stop signal within :data:`REPEATED_SIGNAL_S` is ignored: a KeyboardInterrupt
    raised again while the first is being handled would cut the orderly end short.
    """
    import time

    global _stop_signal, _stop_at
    now = time.monotonic()
    if _stop_signal is not None and now - _stop_at < REPEATED_SIGNAL_S:
        return
    _stop_signal = signum
    _stop_at = now
    raise KeyboardInterrupt(f"signal {signum}")


def stop_signalled() -> bool:
    """Whether a stop signal came. The KeyboardInterrupt of :func:`_stop_on_signal` can be
    raised while rclpy's pybind11 code converts an argument in Python (``take_message``);
    pybind11 then reports it as ``RuntimeError: Unable to convert call argument`` (seen
    once: a container stopped by SIGTERM exited 1 instead of 3). A RuntimeError after a
    stop signal is that interruption."""
    return _stop_signal is not None


def spin_until_done(executor: Any, future: Future) -> None:
    """Spin ``executor`` until ``future`` is done or rclpy shuts down, waiting at most
    :data:`SIGNAL_POLL_S` at a time so that a pending signal is seen."""
    context = getattr(executor, "_context", None) or rclpy.get_default_context()
    while context.ok() and not future.done() and not future.cancelled():
        executor.spin_once(timeout_sec=SIGNAL_POLL_S)


def run_node(make_node: Callable[[], Node], args: list[str] | None = None, name: str = "node",
             end_process: bool = True) -> int:
    """Create a node, spin it on :func:`make_executor`'s executor and always shut down cleanly.

    The node may expose ``finished: rclpy.task.Future``; spinning stops when it
    completes (its result is the exit code, default 0). Ctrl-C and SIGTERM
    (KeyboardInterrupt, :func:`init_rclpy`; ExternalShutdownException or rclpy's error on a
    context shut down from elsewhere) end the spin with exit code 0 if the node's part of the
    run is complete (:func:`run_complete`), else :data:`EXIT_INTERRUPTED`. A
    :class:`ConfigError`, :class:`ContractError`, ``ValueError`` (a bad parameter, also one the
    node does not have: :meth:`~comems4build_ros.ros.package_node.NodeParameters.refuse_undeclared`)
    or a missing or existing file raised while the node is created is logged as an error
    (``refused to start: ...``) with exit code :data:`EXIT_BAD_INPUT`.
    The clean-up (:func:`clean_up`) ends the process with the exit code (``end_process``;
    False returns it, for a caller that goes on).
    """
    init_rclpy(args, name)
    executor = make_executor()
    node: Node | None = None
    code = 0
    try:
        node = make_node()
        refuse_undeclared(node)
        executor.add_node(node)
        finished: Future | None = getattr(node, "finished", None)
        if finished is None:
            finished = Future()  # never done: spin until a signal or rclpy's shutdown
        spin_until_done(executor, finished)
        if finished.done():
            code = int(finished.result() or 0)
        else:  # the spin ended because the context was shut down (no exception)
            code = interrupted_code([node], name)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = interrupted_code([node], name)
    except RuntimeError:
        # a context shut down from elsewhere between the executor's check and its next wait
        # set makes rclpy raise RCLError (a RuntimeError: "the given context is not valid")
        # instead of ExternalShutdownException. That is the same clean external shutdown; so
        # is a stop signal that pybind11 turned into a RuntimeError (stop_signalled).
        if rclpy.ok() and not stop_signalled():
            raise
        code = interrupted_code([node], name)
    except (ConfigError, ContractError, ValueError, FileNotFoundError, FileExistsError) as exc:
        logger = node.get_logger() if node is not None else process_logger(name)
        logger.error(f"{REFUSED_TAG} {exc}")
        code = EXIT_BAD_INPUT
    except OSError as exc:  # a file the node writes during its run (a full disk, a read-only file system)
        label = node.get_name() if node is not None else name
        report_cause(label, f"cannot write {exc.filename or 'a file'}: {exc.strerror or exc}")
        code = EXIT_WRITE_FAILED
    except Exception:  # a bug: its traceback in the log, exit code 1 (the process ends in clean_up)
        code = log_crash(name)
    finally:
        clean_up(executor, [node] if node is not None else [], name, code, end_process)
    return code


def log_crash(label: str) -> int:
    """Log the exception being handled with its traceback (an error of ``label``'s logger); exit code 1."""
    import traceback

    process_logger(label).error(f"crashed:\n{traceback.format_exc().rstrip()}")
    return 1


#: Start of the error line of a node that refused to start (bad parameter, scenario, contract).
REFUSED_TAG = "refused to start:"
#: Seconds the DDS side of the clean-up (the participant leaving the graph) may take before the
#: process ends without it (:func:`clean_up`).
TEARDOWN_TIMEOUT_S = 2.0


def clean_up(executor: Any, nodes: list[Any], label: str, code: int, end_process: bool = True) -> None:
    """End a node process with ``code``, in the order of the rclpy examples, every part bounded.

    Executor shutdown and the nodes' destruction (a recorder closes its bag there) within
    :func:`cleanup_deadline`; then rclpy's shutdown and the context's destruction (the DDS
    participant leaves the graph) within :data:`TEARDOWN_TIMEOUT_S`; then, with
    ``end_process``, ``os._exit(code)``. The run's outcome is decided before all this, and
    nothing after it needs the interpreter's own teardown: it took 0.5 to 1 s of a node's
    end on the loaded 2-core machine, and a participant's teardown left to it after a peer
    was SIGKILLed held one process under ``ros2 launch`` until launch's SIGKILL 10 s later.
    """
    ignore_stop_signals()  # a second Ctrl-C or the supervisor's signals must not cut the clean-up short
    watchdog = cleanup_deadline(label, code)
    executor.shutdown()
    for node in nodes:
        node_name = node.get_name()  # not to be asked once its destruction was requested
        try:
            node.destroy_node()
        except OSError as exc:  # a file closed at the end (the recorder's bag) on a full disk
            report_cause(node_name, f"cannot write {exc.filename or 'a file'}: {exc.strerror or exc}")
            code = EXIT_WRITE_FAILED
    print_cpu(label)
    watchdog.cancel()
    watchdog = cleanup_deadline(label, code, timeout_s=TEARDOWN_TIMEOUT_S, what="the DDS teardown")
    context = rclpy.get_default_context()
    rclpy.try_shutdown()
    context.destroy()
    watchdog.cancel()
    if end_process:
        import os

        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def run_over(node: Any) -> bool:
    """Whether ``node``'s run is over (a master's last step done, ``plant/done`` seen by the feed
    or the EMS) though the node may still wait for the recorder to leave: its ``run_end``
    helper's ``over`` (:class:`~comems4build_ros.ros.lockstep.LockStep`,
    :class:`~comems4build_ros.ros.node.RunEnd`), else a ``run_over`` attribute."""
    end = getattr(node, "run_end", None)
    return bool(end.over) if end is not None else bool(getattr(node, "run_over", False))


def run_complete(node: Any) -> bool:
    """Whether ``node``'s part of the run is complete, so that a signal now is a normal end.

    A node says so with its ``run_end`` helper's ``complete`` (the lock-step master after its
    last step, the EMS and the feed once they saw ``plant/done``, each once the recorder has
    left) or a ``run_complete`` attribute (the recorder once every plant is done); a node with
    none of these nor a ``finished`` future has no run (always complete); otherwise its
    ``finished`` future must be done. A node that was never created (None) has not run.
    """
    if node is None:
        return False
    end = getattr(node, "run_end", None)
    if end is not None:
        return bool(end.complete)
    flag = getattr(node, "run_complete", None)
    if flag is not None:
        return bool(flag)
    finished = getattr(node, "finished", None)
    return finished is None or finished.done()


def interrupted_code(nodes: list[Any], label: str) -> int:
    """Exit code after SIGINT/SIGTERM: 0 if every node's run is complete, else
    :data:`EXIT_INTERRUPTED` (with a :func:`report_cause` line, of the node's logger when the
    process runs one node)."""
    if nodes and all(run_complete(n) for n in nodes):
        return 0
    logger = nodes[0].get_logger() if len(nodes) == 1 and nodes[0] is not None else None
    if nodes and all(run_complete(n) or run_over(n) for n in nodes):
        # plant/done came, the node was waiting for the recorder to leave: after a complete
        # run that is the supervisor's clean-up; otherwise its last messages may be unrecorded
        report_cause(label, "stopped by a signal after the end of the run, before the recorder had left", logger)
    else:
        report_cause(label, "stopped by a signal before the end of its run", logger)
    return EXIT_INTERRUPTED


def report_cause(label: str, text: str, logger: Any = None) -> None:
    """``cause: <text>``, an error of the node's logger (or of ``label``'s): why it ends the run early.

    The supervisor puts the last such line of a node's log first in its error message.
    """
    (logger or process_logger(label)).error(f"{CAUSE_TAG} {text}")


#: Seconds the clean-up after a run (executor shutdown, node destruction, rclpy shutdown) may
#: take before the process exits without it (:func:`cleanup_deadline`).
CLEANUP_TIMEOUT_S = 20.0


#: Seconds after :data:`CLEANUP_TIMEOUT_S` at which the C-level backstop of
#: :func:`cleanup_deadline` ends a clean-up that holds the interpreter.
CLEANUP_BACKSTOP_S = 10.0


class _Deadline:
    """The two watchdogs of :func:`cleanup_deadline`; ``cancel()`` stops both."""

    def __init__(self, timer: Any) -> None:
        self.timer = timer

    def cancel(self) -> None:
        import faulthandler

        self.timer.cancel()
        faulthandler.cancel_dump_traceback_later()


def cleanup_deadline(label: str, code: int, timeout_s: float = CLEANUP_TIMEOUT_S,
                     backstop_s: float = CLEANUP_BACKSTOP_S, what: str = "clean-up") -> Any:
    """Start a watchdog that ends the process with ``code`` if the clean-up hangs; returns it.

    A SIGINT that lands while rclpy holds one of its locks has been seen to leave the
    clean-up waiting forever (the process then never exits and holds its DDS ports). The
    run's outcome is decided by then, so after ``timeout_s`` the watchdog says so on stderr
    and exits with the same code without the clean-up. ``cancel()`` it once the clean-up
    is done.

    That watchdog is a Python thread: a clean-up stuck inside native code that holds the
    interpreter lock stops it too (seen once: a recorder that had closed its bag ignored
    it, and SIGINT and SIGTERM too; only the launcher's SIGKILL, about 100 s after the end of
    the run, ended it). :data:`CLEANUP_BACKSTOP_S` later,
    ``faulthandler``'s C-level watchdog writes the stack of every thread to stderr (the
    node's log: where it hung) and exits with code 1 (``backstop_s`` after ``timeout_s``).
    Its first line, ``[<label>] cleaning up: exit code <code>``, tells the supervisor what
    the run had decided (:meth:`comems4build_ros.run.supervisor.Child.decided_before_hang`).
    """
    import faulthandler
    import os
    import threading

    logger = process_logger(label)

    def expire() -> None:
        logger.warning(f"{what} did not finish within {timeout_s:g} s; exiting with code {code} without it")
        sys.stderr.flush()
        os._exit(code)

    timer = threading.Timer(timeout_s, expire)
    timer.daemon = True
    timer.start()
    if what == "clean-up":
        logger.info(f"{CLEANUP_TAG} exit code {code}")
    faulthandler.dump_traceback_later(timeout_s + backstop_s, exit=True, file=sys.stderr)
    return _Deadline(timer)


def ignore_stop_signals() -> None:
    """Ignore SIGINT and SIGTERM from now on (main thread only): the process is already
    shutting down, and a KeyboardInterrupt (:func:`init_rclpy`) inside the clean-up would cut
    it short (a recorder closes its bag there). A process whose clean-up hangs still ends:
    by :func:`cleanup_deadline`, or the supervisor's SIGKILL."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def print_cpu(label: str) -> None:
    """``cpu_s user=<s> sys=<s>``, an info line of ``label``'s logger: CPU time of this process [s]."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_SELF)
    process_logger(label).info(f"cpu_s user={ru.ru_utime:.2f} sys={ru.ru_stime:.2f}")
