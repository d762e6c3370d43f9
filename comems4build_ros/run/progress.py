"""Progress bars for long runs: one bar per run with steps/s and ETA, on stderr.

The loops that do the work (:func:`comems4build_ros.core.loop.simulate`, the ROS launcher, the
benchmarks) never import tqdm: they take a plain :data:`ProgressCallback` ``(done, total)``
and call it as they advance. This module turns such callbacks into tqdm bars:

- :class:`ProgressBar`: one bar for one run in this process (``simulate``, ``launch``,
  a benchmark). Use it as a context manager; the object itself is the callback.
- :class:`RunProgress`: one bar per run for runs that execute in worker processes
  (``compare``, ``sweep``, and any command that spreads runs over a
  :class:`~concurrent.futures.ProcessPoolExecutor`). The parent owns the bars; each worker
  reports through a :class:`QueueReporter` over a queue handed to the pool's initializer.

Bars are shown only when their stream is a terminal (``enable=None``, the default), so
logs, pipes and test captures stay free of control characters; ``enable=False`` (a
``--no-progress`` option) hides them, ``enable=True`` forces them (tests).

Example, a pool of runs::

    with RunProgress(["rbc", "fuzzy", "mpc"]) as bars:
        with ProcessPoolExecutor(2, initializer=bars.initializer, initargs=bars.initargs) as pool:
            futures = [pool.submit(work, task, bars.reporter(i)) for i, task in enumerate(tasks)]
"""

from __future__ import annotations

import multiprocessing
import os
import queue as _queue
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import IO, Any

#: ``callback(done, total)``: steps done so far and the run's total steps (0 = not known yet).
ProgressCallback = Callable[[int, int], None]

#: Least time between two reports a worker sends to the parent [s].
REPORT_INTERVAL_S = 0.2
#: Least time between two redraws of a bar [s].
REDRAW_INTERVAL_S = 0.2
#: How often the parent's reader thread looks for reports [s].
POLL_S = 0.1
#: Size of a terminal that does not report it (a pseudo-terminal of a log): width of the
#: bars [characters] and lines that may hold bars.
DEFAULT_COLUMNS = 100
DEFAULT_ROWS = 100


def is_terminal(stream: IO[str] | None = None) -> bool:
    """Whether ``stream`` (default: ``sys.stderr``) is an interactive terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # closed or no isatty
        return False


def _shown(enable: bool | None, stream: IO[str]) -> bool:
    return is_terminal(stream) if enable is None else bool(enable)


def _terminal_columns(stream: IO[str]) -> int:
    """Width of the terminal behind ``stream`` (0 when unknown, e.g. a pseudo-terminal without a size)."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):
        return 0


def _new_bar(desc: str, unit: str, stream: IO[str], position: int | None, leave: bool) -> Any:
    from tqdm import tqdm

    sized = _terminal_columns(stream) > 0  # follow resizes; a terminal without a size gets a fixed one
    return tqdm(total=None, desc=desc, unit=unit, file=stream, position=position, leave=leave,
                mininterval=REDRAW_INTERVAL_S, dynamic_ncols=sized, ncols=None if sized else DEFAULT_COLUMNS,
                nrows=None if sized else DEFAULT_ROWS)


def echo(message: str, stream: IO[str] | None = None) -> None:
    """Print a line to ``stream`` (default stderr) above any bars shown, without breaking them."""
    from tqdm import tqdm

    tqdm.write(message, file=sys.stderr if stream is None else stream)


class _Bar:
    """A tqdm bar driven by absolute ``(done, total)`` reports (rate and ETA from tqdm).

    The bar's clock starts with the first report (not when it was drawn), and the bar is
    closed when the run reaches its total, so that its final rate is that of the run.
    """

    def __init__(self, bar: Any) -> None:
        self.bar = bar
        self.started = False
        self.closed = False

    def report(self, done: int, total: int) -> None:
        if self.closed:
            return
        bar = self.bar
        if not self.started:
            bar.reset(total=total or None)
            self.started = True
        elif total and bar.total != total:
            bar.total = total
        if done > bar.n:
            bar.update(done - bar.n)
        elif done < bar.n:
            bar.n = done
            bar.refresh()
        if total and done >= total:
            self.close()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.bar.close()


class ProgressBar:
    """One progress bar on ``stream`` (default stderr); call it as a :data:`ProgressCallback`.

    Parameters
    ----------
    desc : text before the bar (e.g. ``"simulate fuzzy"``)
    unit : name of one step in the rate (``step`` -> ``step/s``)
    enable : None = shown when ``stream`` is a terminal; True / False = always / never
    stream : where the bar is drawn (default ``sys.stderr``)

    A disabled bar costs one attribute test per call and imports nothing.
    """

    def __init__(self, desc: str, unit: str = "step", enable: bool | None = None,
                 stream: IO[str] | None = None) -> None:
        stream = sys.stderr if stream is None else stream
        self.shown = _shown(enable, stream)
        self._bar = _Bar(_new_bar(desc, unit, stream, None, leave=True)) if self.shown else None

    def __call__(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar.report(done, total)

    def close(self) -> None:
        """Draw the last state and release the terminal line."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ------------------------------------------------------------- runs in worker processes

#: The queue of this worker process (set by :func:`init_worker`); None in the parent.
_WORKER_QUEUE: Any = None


def init_worker(q: Any) -> None:
    """Pool initializer: remember the queue the :class:`QueueReporter` objects report to."""
    global _WORKER_QUEUE
    _WORKER_QUEUE = q


class QueueReporter:
    """Picklable :data:`ProgressCallback` for a run in a worker process.

    Sends ``(slot, done, total)`` to the queue set by :func:`init_worker`, at most every
    :data:`REPORT_INTERVAL_S` and always for the last step; does nothing in a process
    without a queue.
    """

    def __init__(self, slot: int) -> None:
        self.slot = slot
        self._last = 0.0

    def __call__(self, done: int, total: int) -> None:
        q = _WORKER_QUEUE
        if q is None:
            return
        now = time.monotonic()
        if now - self._last < REPORT_INTERVAL_S and not (total and done >= total):
            return
        self._last = now
        try:
            q.put_nowait((self.slot, int(done), int(total)))
        except (_queue.Full, OSError, ValueError):  # the parent is gone or closed the queue
            pass

    def __getstate__(self) -> dict[str, Any]:
        return {"slot": self.slot, "_last": 0.0}


class RunProgress:
    """One bar per run for runs spread over worker processes (a context manager).

    Parameters
    ----------
    names : one bar label per run (the run's slot is its index)
    unit : name of one step in the rate
    enable : None = shown when ``stream`` is a terminal; True / False = always / never
    stream : where the bars are drawn (default ``sys.stderr``)

    A run's bar appears with its first report and is removed when the run reaches its
    total, so a study of many runs shows the running ones only (print a line per finished
    run with :func:`echo`). For a :class:`~concurrent.futures.ProcessPoolExecutor` pass
    :attr:`initializer` and :attr:`initargs`, and hand each run :meth:`reporter`
    (picklable). Runs executed in this process take :meth:`callback` instead. When the
    bars are hidden no queue or thread is created and both return None.
    """

    def __init__(self, names: Sequence[str], unit: str = "step", enable: bool | None = None,
                 stream: IO[str] | None = None) -> None:
        self.names = list(names)
        self.unit = unit
        self.stream = sys.stderr if stream is None else stream
        self.shown = _shown(enable, self.stream) and bool(self.names)
        self._width = max((len(n) for n in self.names), default=0)
        self._bars: dict[int, _Bar] = {}
        self._finished: set[int] = set()
        self._queue: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def __enter__(self) -> RunProgress:
        if self.shown:
            self._queue = multiprocessing.get_context().Queue()
            self._thread = threading.Thread(target=self._read, name="progress-reader", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._drain()
            self._queue.close()
            self._queue.join_thread()
            self._thread = None
        with self._lock:
            for bar in self._bars.values():
                bar.close()
            self._bars = {}

    @property
    def initializer(self) -> Callable[[Any], None] | None:
        """Pool initializer (None when the bars are hidden)."""
        return init_worker if self._queue is not None else None

    @property
    def initargs(self) -> tuple[Any, ...]:
        """Arguments of :attr:`initializer`."""
        return (self._queue,) if self._queue is not None else ()

    def reporter(self, slot: int) -> QueueReporter | None:
        """Callback of run ``slot`` for a worker process (None when the bars are hidden)."""
        return QueueReporter(slot) if self._queue is not None else None

    def callback(self, slot: int) -> ProgressCallback | None:
        """Callback of run ``slot`` executed in this process (None when the bars are hidden)."""
        if not self.shown:
            return None

        def report(done: int, total: int) -> None:
            self._report(slot, done, total)

        return report

    def _report(self, slot: int, done: int, total: int) -> None:
        if not 0 <= slot < len(self.names):
            return
        with self._lock:
            if slot in self._finished:
                return
            bar = self._bars.get(slot)
            if bar is None:
                bar = _Bar(_new_bar(self.names[slot].ljust(self._width), self.unit, self.stream, None, leave=False))
                self._bars[slot] = bar
            bar.report(done, total)
            if bar.closed:
                del self._bars[slot]
                self._finished.add(slot)

    def _drain(self) -> None:
        while True:
            try:
                slot, done, total = self._queue.get_nowait()
            except (_queue.Empty, OSError, ValueError, EOFError):
                return
            self._report(slot, done, total)

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                slot, done, total = self._queue.get(timeout=POLL_S)
            except _queue.Empty:
                continue
            except (OSError, ValueError, EOFError):
                return
            self._report(slot, done, total)
