"""The one output layer (files/outputs.py) and every command that writes through it.

Each command's output is checked before anything runs (not empty or ambiguous, not an input,
not inside one, replacing none), locked while the command writes, never written over what
comems4build did not write, and all or nothing: the fault-injection tests interrupt each
command at every rename it makes (and the in-place ``launch`` with Ctrl-C) and find the
earlier result and every input byte for byte as they were.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from launch_probe import records_on_disk, run_held
from test_bad_input import PRICES, SOLAR, TEMPERATURE, recorded_bag, run_cli  # noqa: F401 (a fixture)
from waits import log_has, wait_exit, wait_until

from comems4build_ros.files import outputs
from comems4build_ros.files.outputs import (
    LOCK_FILE,
    OWNER_FILE,
    OutputDir,
    OutputFile,
    OutputInUseError,
    OutputPathError,
    check_out_text,
)

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "comems4build_ros.app.cli"]
#: Bounded, reproducible property tests (no example database; the same examples every run).
BOUNDED = settings(max_examples=60, derandomize=True, database=None, deadline=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture])


def snapshot(*roots: Path) -> dict[str, bytes]:
    """Every file under ``roots`` (a file root: itself) by path, without the study store and the lock."""
    out: dict[str, bytes] = {}
    for root in roots:
        files = [root] if root.is_file() else [p for p in root.rglob("*") if p.is_file()]
        for p in files:
            if ".runstore" in p.parts or p.name == LOCK_FILE:
                continue
            out[str(p)] = p.read_bytes()
    return out


# ---------------------------------------------------------------------------------------- paths
@pytest.mark.parametrize("text", ["", " ", "\t", "runs/x ", " runs/x", "a\nb", "~/runs", "$OUT/x", "runs/$X"])
def test_empty_or_ambiguous_out_is_refused(text: str) -> None:
    with pytest.raises(OutputPathError, match="--out"):
        check_out_text(text)


@BOUNDED
@given(st.text(min_size=1, max_size=40))
def test_any_out_text_is_a_path_or_refused_naming_the_option(text: str) -> None:
    try:
        path = check_out_text(text, "--out")
    except OutputPathError as exc:
        assert str(exc).startswith("--out ")
    else:
        assert str(path) and text.strip() == text and "$" not in text


@pytest.mark.parametrize("command", ["simulate", "sweep", "size", "compare", "reproduce", "validate", "evaluate",
                                     "launch", "fuzzy-surface", "cosim-study", "identify", "export-fmu"])
def test_an_unset_shell_variable_as_out_writes_nothing(command: str, tmp_path: Path, recorded_bag: Path,  # noqa: F811
                                                       capsys: pytest.CaptureFixture[str],
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """``--out "$UNSET"`` is ``--out ""``: refused (it would be the current directory), the directory untouched."""
    (tmp_path / "figures").mkdir()
    (tmp_path / "runs").mkdir()
    (tmp_path / "figures" / "mine.png").write_bytes(b"mine")
    monkeypatch.chdir(tmp_path)
    before = snapshot(tmp_path)
    argv = {"simulate": ["simulate", "--ems", "rbc", "--hours", "2"],
            "sweep": ["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--weeks", "1"],
            "size": ["size", "--ems", "rbc", "--weeks", "1"],
            "compare": ["compare", "--ems", "rbc", "--weeks", "1"],
            "reproduce": ["reproduce", "--no-study", "--weeks", "1"],
            "validate": ["validate", "--cases", "paper-s57", "--ems", "rbc", "--weeks", "1"],
            "evaluate": ["evaluate", recorded_bag],
            "launch": ["launch", "--ems", "rbc", "--steps", "2"],
            "fuzzy-surface": ["fuzzy-surface"],
            "cosim-study": ["cosim-study", "--weeks", "1"],
            "identify": ["identify", "--building", "energyplus"],
            "export-fmu": ["export-fmu"]}[command]
    code, _, err = run_cli([*argv, "--out", ""], capsys)
    assert code == 2 and "--out '': empty" in err, err
    assert snapshot(tmp_path) == before and sorted(p.name for p in tmp_path.iterdir()) == ["figures", "runs"]


def test_output_that_is_inside_or_replaces_an_input_is_refused(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    (data / "in.csv").write_text("x")
    for out, text in ((data, "is the input"), (data / "sub", "lies inside the input"),
                      (tmp_path, "contains the input")):
        with pytest.raises(OutputPathError, match=text):
            OutputDir(out, "t", inputs={"--scenario": [data]}).check()
    OutputDir(tmp_path, "t", inputs={"--scenario": [data]}, writes=("runs",)).check()  # 'data' is not written
    with pytest.raises(OutputPathError, match="is the input --prices"):
        OutputFile(data / "in.csv", "t", inputs={"--prices": [data / "in.csv"]}).check()
    link = tmp_path / "link"
    link.symlink_to(data)
    with pytest.raises(OutputPathError, match="is the input"):  # through a symbolic link
        OutputDir(link, "t", inputs={"--scenario": [data]}).check()


def test_foreign_entries_are_never_replaced(tmp_path: Path) -> None:
    out = tmp_path / "o"
    with OutputDir(out, "t", writes=("a", "b")) as o:
        (o.stage / "a").write_text("1")
    (out / "b").write_text("mine")
    with pytest.raises(OutputPathError, match=r"o/b is in the way and not written by comems4build"):
        with OutputDir(out, "t", writes=("a", "b")) as o:
            pass
    with OutputDir(out, "t", writes=("a",)) as o:  # 'b' is not this command's: left alone
        (o.stage / "a").write_text("2")
    assert (out / "a").read_text() == "2" and (out / "b").read_text() == "mine"
    assert json.loads((out / OWNER_FILE).read_text())["entries"] == ["a"]


def test_a_second_command_on_the_same_out_is_refused_at_once(tmp_path: Path) -> None:
    first = OutputDir(tmp_path / "o", "first", writes=("a",))
    first.__enter__()
    try:
        t0 = time.monotonic()
        with pytest.raises(OutputInUseError, match=r"in use by comems4build first \(pid"):
            OutputDir(tmp_path / "o", "second", writes=("a",)).check()
        with pytest.raises(OutputInUseError):
            with OutputDir(tmp_path / "o", "second", writes=("a",)):
                pass
        assert time.monotonic() - t0 < 1.0
    finally:
        first.__exit__(None, None, None)
    with OutputDir(tmp_path / "o", "third", writes=("a",)):  # free again
        pass


@BOUNDED
@given(st.integers(min_value=1, max_value=12), st.booleans())
def test_interrupted_at_any_rename_the_earlier_result_stays(tmp_path_factory: pytest.TempPathFactory, k: int,
                                                            in_place: bool) -> None:
    """Model of every command: an earlier result, a new one interrupted at its k-th rename."""
    out = tmp_path_factory.mktemp("o") / "out"
    with OutputDir(out, "t", writes=("a", "d", "s.json"), in_place=in_place) as o:
        (o.stage / "a").write_text("old")
        (o.stage / "d").mkdir()
        (o.stage / "d" / "x").write_text("old")
    before = snapshot(out)
    with pytest.MonkeyPatch.context() as mp:
        calls = _fault_points(mp, k)
        try:
            with OutputDir(out, "t", writes=("a", "d", "s.json"), in_place=in_place) as o:
                (o.stage / "a").write_text("new")
                (o.stage / "d").mkdir()
                (o.stage / "d" / "y").write_text("new")
                outputs.write_text_atomic(o.stage / "s.json", "{}")
        except KeyboardInterrupt:
            interrupted = True
        else:
            interrupted = False
    if interrupted:
        assert snapshot(out) == before
    else:
        assert calls[0] < k and (out / "a").read_text() == "new" and not (out / "d" / "x").exists()
    assert not [p for p in out.iterdir() if p.name.startswith((".partial", ".previous", ".replaced"))]


# ---------------------------------------------------------------------------------------- commands
def _fault_points(monkeypatch: pytest.MonkeyPatch, fail_at: int) -> list[int]:
    """Make the ``fail_at``-th ``os.replace`` (every rename of the output layer) a Ctrl-C; the calls so far."""
    real, calls = os.replace, [0]

    def replace(src: object, dst: object, **dir_fds: int) -> None:
        calls[0] += 1
        if calls[0] == fail_at:
            raise KeyboardInterrupt
        real(src, dst, **dir_fds)

    monkeypatch.setattr(os, "replace", replace)
    return calls


def _commands(tmp_path: Path, bag: Path) -> dict[str, tuple[list, list, list[Path]]]:
    """command -> (argv of the earlier result, argv of the interrupted one, its inputs) (``--out`` added later)."""
    csv = tmp_path / "in" / "s.csv"
    csv.parent.mkdir(exist_ok=True)
    build = ["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR]
    return {
        "simulate": (["simulate", "--ems", "rbc", "--hours", "30", "--no-progress"],
                     ["simulate", "--ems", "rbc", "--hours", "40", "--no-progress"], []),
        "evaluate": (["evaluate", bag], ["evaluate", bag, "--no-timeseries"], [bag]),
        "fuzzy-surface": (["fuzzy-surface", "--dpi", "10"], ["fuzzy-surface", "--dpi", "12", "--chi", "0.3"], []),
        "data build": ([*build, "--seed", "1"], [*build, "--seed", "2"], [PRICES, TEMPERATURE, SOLAR]),
        "sweep": (["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--weeks", "0.25", "--jobs", "1",
                   "--no-progress"],
                  ["sweep", "--param", "battery.e_max_kwh=6", "--ems", "rbc", "--weeks", "0.25", "--jobs", "1",
                   "--no-progress"], []),
        "compare": (["compare", "--ems", "rbc", "--fc-efficiency", "0.75", "--weeks", "0.25", "--jobs", "1",
                     "--no-progress"],
                    ["compare", "--ems", "thermostat", "--fc-efficiency", "0.75", "--weeks", "0.25", "--jobs", "1",
                     "--no-progress"], []),
        "size": (["size", "--ems", "rbc", "--weeks", "0.25", "--jobs", "1", "--no-progress"],
                 ["size", "--ems", "rbc", "--weeks", "0.25", "--pv-kwp", "4", "--jobs", "1", "--no-progress"], []),
        "reproduce": (["reproduce", "--no-study", "--weeks", "0.25", "--seeds", "57", "--no-figures", "--jobs", "1",
                       "--no-progress"],
                      ["reproduce", "--no-study", "--weeks", "0.5", "--seeds", "57", "--no-figures", "--jobs", "1",
                       "--no-progress"], []),
        "validate": (["validate", "--cases", "paper-s57", "--ems", "rbc", "--weeks", "0.25", "--no-figures",
                      "--jobs", "1", "--no-progress"],
                     ["validate", "--cases", "household-101", "--ems", "rbc", "--weeks", "0.25", "--no-figures",
                      "--jobs", "1", "--no-progress"], []),
    }


#: Renames tried per command: every one for the quick commands, the first, a middle and the last for the others.
QUICK = ("simulate", "evaluate", "data build")


@pytest.mark.parametrize("command", ["simulate", "evaluate", "fuzzy-surface", "data build", "sweep", "compare",
                                     "size", "reproduce", "validate"])
def test_each_command_interrupted_at_any_point_keeps_the_earlier_result_and_its_inputs(
        command: str, tmp_path: Path, recorded_bag: Path, capsys: pytest.CaptureFixture[str],  # noqa: F811
        monkeypatch: pytest.MonkeyPatch) -> None:
    # the result cache off: a cache file written by the counting run only (a cold cache) would
    # change the number of renames between the runs
    monkeypatch.setenv("COMEMS4BUILD_CACHE_DIR", "off")
    first, second, inputs = _commands(tmp_path, recorded_bag)[command]
    out = tmp_path / "o" / "out.csv" if command == "data build" else tmp_path / "out"
    where = out.parent if command == "data build" else out  # the directory the result is in
    code, _, err = run_cli([*first, "--out", out], capsys)
    assert code == 0, err
    before = snapshot(where, *inputs)
    with monkeypatch.context() as m:  # count the renames of an uninterrupted second run (into a copy)
        copy = tmp_path / "copy"
        shutil.copytree(where, copy)
        calls = _fault_points(m, 10**9)
        code, _, err = run_cli([*second, "--out", copy / out.relative_to(where) if out != where else copy], capsys)
        assert code == 0, err
        total = calls[0]
    points = (range(1, total + 1) if command in QUICK else [max(1, total // 2)] if command == "fuzzy-surface"
              else sorted({1, total // 2, total}))  # drawing the 3D maps takes seconds: one point in their commit
    for k in points:
        with monkeypatch.context() as m:
            _fault_points(m, k)
            code, _, err = run_cli([*second, "--out", out], capsys)
        assert code == 130 and "interrupted" in err, (k, total, err)
        assert snapshot(where, *inputs) == before, f"rename {k} of {total}"
        shutil.rmtree(out / ".runstore", ignore_errors=True)  # the finished runs kept for --resume: start over
    code, _, err = run_cli([*second, "--out", out], capsys)  # uninterrupted: the new result replaces the old
    assert code == 0, err
    assert snapshot(where, *inputs) != before
    assert snapshot(*inputs) == {k: v for k, v in before.items() if any(k == str(p) or k.startswith(f"{p}/")
                                                                        for p in inputs)}


def test_evaluate_out_at_or_in_its_bag_is_refused_and_the_bag_kept(tmp_path: Path, recorded_bag: Path,  # noqa: F811
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "x" / "house_0"
    shutil.copytree(recorded_bag, bag)
    before = snapshot(bag)
    for out, text in ((bag, "is the input BAG"), (bag / "e", "lies inside the input BAG"),
                      (bag.parent, "contains the input BAG")):  # house_* is what evaluate writes
        code, _, err = run_cli(["evaluate", bag, "--out", out], capsys)
        assert code == 2 and text in err, err
        assert snapshot(bag) == before
    two = tmp_path / "X" / "bag"  # the bags of a two-house run: bag/house_0/, bag/house_1/
    for house in ("house_0", "house_1"):
        shutil.copytree(recorded_bag, two / house)
    before = snapshot(two)
    code, _, err = run_cli(["evaluate", two, "--out", two], capsys)  # once replaced the bags by the results
    assert code == 2 and "is the input BAG" in err, err
    assert snapshot(two) == before and len(list(two.rglob("*.mcap"))) == 2
    code, _, err = run_cli(["evaluate", recorded_bag, "--out", recorded_bag.parent], capsys)  # beside it: fine
    assert code == 0, err


def test_the_cosimulation_commands_write_through_the_output_layer(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """identify, export-fmu and house refuse an output that is another command's file or a foreign one."""
    foreign = tmp_path / "mine.fmu"
    foreign.write_bytes(b"not written by comems4build")
    code, _, err = run_cli(["export-fmu", "--out", str(foreign)], capsys)
    assert code == 2 and "mine.fmu" in err and foreign.read_bytes() == b"not written by comems4build", err
    code, _, err = run_cli(["export-fmu", "--out", str(tmp_path / "rc.fmu")], capsys)
    assert code == 0 and (tmp_path / "rc.fmu").is_file() and (tmp_path / "rc.map.yaml").is_file(), err
    code, _, err = run_cli(["export-fmu", "--out", str(tmp_path / "rc.fmu")], capsys)  # its own: replaced
    assert code == 0, err
    (tmp_path / "house.json").write_text("{}", encoding="utf-8")
    code, _, err = run_cli(["house", "--json", str(tmp_path / "house.json")], capsys)
    assert code == 2 and "house.json" in err and (tmp_path / "house.json").read_text() == "{}", err


def test_data_build_onto_one_of_its_inputs_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for name, src in (("prices", PRICES), ("temperature", TEMPERATURE), ("solar", SOLAR)):
        copy = tmp_path / Path(src).name
        shutil.copy2(src, copy)
        argv = ["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR]
        argv[argv.index(f"--{name}") + 1] = copy
        code, _, err = run_cli([*argv, "--out", copy], capsys)
        assert code == 2 and f"is the input --{name}" in err, err
        assert copy.read_bytes() == Path(src).read_bytes()


def test_reproduce_from_json_of_a_wrong_document_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cases = {"list.json": "[1, 2]", "empty.json": "{}", "deep.json": "[" * 5000 + "]" * 5000,
             "figure.json": None}
    for name, text in cases.items():
        path = tmp_path / name
        if text is None:
            from comems4build_ros.report.reproduce_doc import REPORT_KEYS

            doc = {k: (None if type(None) in t else t[0]()) for k, t in REPORT_KEYS.items()}
            doc.update(seeds=[57], figures={"x": "../../etc/passwd"})
            text = json.dumps(doc)
        path.write_text(text)
        code, _, err = run_cli(["reproduce", "--from-json", path, "--out", tmp_path / "r"], capsys)
        assert code == 2 and str(path) in err and "Traceback" not in err, err
        assert not (tmp_path / "r").exists()


# ---------------------------------------------------------------------------------------- launch
def _launch(out: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([*CLI, "launch", "--no-progress", "--out", str(out), *args], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _under_way(run: subprocess.Popen, out: Path) -> bool:
    """The launch writing into ``out`` has recorded steps (or has ended: the caller's assertion says so)."""
    return run.poll() is not None or records_on_disk(out / "bag")


def test_two_launches_on_one_out_the_second_is_refused_at_once(tmp_path: Path) -> None:
    """The second launch is refused while the first runs (held in progress: its plant paused),
    without waiting for it; the first then ends as if nothing had happened."""
    out = tmp_path / "run"
    first = _launch(out, "--ems", "rbc", "--weeks", "12")  # long enough to be held before its last step
    wait_until(lambda: _under_way(first, out), "the first launch recording")
    assert log_has(out / LOCK_FILE, f"comems4build launch (pid {first.pid})"), "the first launch holds no lock"
    with run_held(out):  # the first run cannot end meanwhile
        second = _launch(out, "--ems", "rbc", "--weeks", "1")
        wait_exit(second, "the second launch refused")
        assert first.poll() is None  # refused at once: it did not wait for the first to end
    err2 = second.communicate()[1]
    assert second.returncode == 2 and f"--out {out}: in use by comems4build launch" in err2, err2
    wait_exit(first, "the first launch to its end")
    err1 = first.communicate()[1]
    assert first.returncode == 0, err1  # the first run is not cut
    assert json.loads((out / "summary.json").read_text())["steps"] == 2016


def test_launch_interrupted_keeps_the_earlier_run(tmp_path: Path) -> None:
    """Ctrl-C while a run writes in place over an earlier one (the run held in progress: its plant
    paused, so the interrupt provably comes before its end): exit 130, the earlier run byte for byte."""
    out = tmp_path / "run"
    done = _launch(out, "--ems", "rbc", "--steps", "24")
    assert wait_exit(done, "the earlier run") == 0, done.communicate()[1]
    before = snapshot(out)
    run = _launch(out, "--ems", "fuzzy", "--weeks", "12")
    # the new run writes in place (its bag is there while it runs), the earlier one aside
    wait_until(lambda: run.poll() is not None or (any(out.glob(".previous.*")) and records_on_disk(out / "bag")),
               "the new run recording in place, the earlier one aside")
    with run_held(out):
        assert run.poll() is None, run.communicate()[1]
        run.send_signal(signal.SIGINT)
        wait_exit(run, "the interrupted launch")  # it continues (SIGCONT) the nodes it stops
    err = run.communicate()[1]
    assert run.returncode == 130, err
    assert snapshot(out) == before
    assert not [p for p in out.iterdir() if p.name.startswith((".previous", ".partial", ".secrets"))]
