"""Progress bars: one bar per run with rate and ETA, quiet off a terminal, fed by plain callbacks."""

from __future__ import annotations

import io
import re
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.run import progress as pg
from comems4build_ros.study.runner import RunTask, run_tasks


class FakeTerminal(io.StringIO):
    """A text stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def _count(q: pg.ProgressCallback | None, n: int) -> int:
    """Worker: report ``n`` steps one by one, as a run would."""
    for k in range(1, n + 1):
        if q is not None:
            q(k, n)
    return n


def test_bar_shows_count_rate_and_eta() -> None:
    out = FakeTerminal()
    with pg.ProgressBar("simulate rbc", unit="h", stream=out) as bar:
        for k in range(1, 51):
            bar(k, 50)
    text = out.getvalue()
    assert "simulate rbc" in text
    assert "50/50" in text
    assert re.search(r"h/s\]|s/h\]", text)  # rate
    assert re.search(r"\d\d:\d\d<\d\d:\d\d", text)  # elapsed < remaining (ETA)


def test_bar_quiet_off_a_terminal_and_when_disabled() -> None:
    plain = io.StringIO()  # not a terminal
    with pg.ProgressBar("x", stream=plain) as bar:
        bar(1, 2)
        bar(2, 2)
    assert plain.getvalue() == ""
    tty = FakeTerminal()
    with pg.ProgressBar("x", enable=False, stream=tty) as bar:
        bar(1, 1)
    assert tty.getvalue() == ""


def test_unknown_total_then_known() -> None:
    out = FakeTerminal()
    with pg.ProgressBar("launch", stream=out) as bar:
        bar(0, 0)
        bar(3, 0)
        bar(5, 10)
        bar(10, 10)
    assert "10/10" in out.getvalue()


def test_run_progress_one_bar_per_run_from_worker_processes() -> None:
    out = FakeTerminal()
    names = ["rbc", "fuzzy", "mpc"]
    with pg.RunProgress(names, stream=out) as bars:
        assert bars.initializer is pg.init_worker
        with ProcessPoolExecutor(2, initializer=bars.initializer, initargs=bars.initargs) as pool:
            done = [f.result() for f in [pool.submit(_count, bars.reporter(i), 40 + i) for i in range(3)]]
    assert done == [40, 41, 42]
    text = out.getvalue()
    for i, name in enumerate(names):  # each run had its bar (removed once the run was done)
        assert re.search(rf"{name}\s*:\s*\d+%.*\d+/{40 + i} \[", text), name


def test_run_progress_shows_only_running_runs() -> None:
    out = FakeTerminal()
    with pg.RunProgress(["a", "b", "c"], stream=out) as bars:
        report = [bars.callback(i) for i in range(3)]
        report[0](1, 10)
        assert set(bars._bars) == {0}  # a bar appears with the run's first report
        report[0](10, 10)
        report[1](5, 10)
        assert set(bars._bars) == {1}  # ... and goes when the run is done
        report[0](10, 10)  # late reports of a finished run change nothing
        assert set(bars._bars) == {1}
    assert bars._bars == {}


def test_run_progress_hidden_costs_nothing() -> None:
    with pg.RunProgress(["a", "b"], stream=io.StringIO()) as bars:
        assert bars.initializer is None and bars.initargs == ()
        assert bars.reporter(0) is None and bars.callback(0) is None


def test_queue_reporter_is_silent_without_a_queue() -> None:
    rep = pg.QueueReporter(0)
    rep(1, 2)  # no worker queue in this process: nothing happens, nothing raised


def test_simulate_calls_the_callback_every_step() -> None:
    params = load_plant_params()
    scenario = resolve_scenario("default", params, weeks=0.25)
    seen: list[tuple[int, int]] = []
    simulate("thermostat", scenario, params, progress=lambda d, t: seen.append((d, t)))
    n = scenario.n_steps
    assert seen == [(k, n) for k in range(1, n + 1)]


def test_run_tasks_bars_on_a_terminal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = FakeTerminal()
    monkeypatch.setattr(sys, "stderr", out)
    tasks = [RunTask(ems=e, out_dir=str(tmp_path / e), weeks=0.25, timeseries=False) for e in ("thermostat", "rbc")]
    summaries = run_tasks(tasks, jobs=2)
    assert [s["ems"] for s in summaries] == ["thermostat", "rbc"]
    text = out.getvalue()
    for e in ("thermostat", "rbc"):
        assert re.search(rf"{e}\s*:\s*\d+%.*\d+/42 \[.*step/s\]", text), e


def test_compare_quiet_when_stderr_is_not_a_terminal(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["compare", "--ems", "thermostat", "--weeks", "0.25", "--fc-efficiency", "0.75",
                 "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "thermostat: finished" in err
    assert "\r" not in err and "step/s" not in err
