"""All or nothing under ENOSPC, EFBIG and EIO: an earlier result stays byte for byte.

A later command into the same ``--out`` that fails for any reason (a full file system at any
fill level, a file size limit, an I/O error at any write or rename) leaves the earlier
result, the ownership record and the folder's listing exactly as they were (no lock, stage
or temporary file left behind), names the cause, and prints no traceback; a command that
succeeds leaves its whole new result.

The full file system is real: a tmpfs mounted for the test (root), filled up to leave a
drawn number of KiB free; the file size limit is ``RLIMIT_FSIZE`` in a child process (any
user); the I/O error is raised at the n-th write or rename of the output layer.
"""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import mounted_tmpfs
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import PRICES, SOLAR, TEMPERATURE, recorded_bag, run_cli  # noqa: F401 (a fixture)

REPO = Path(__file__).resolve().parents[1]
FEW = settings(max_examples=8, derandomize=True, database=None, deadline=None,
               suppress_health_check=[HealthCheck.function_scoped_fixture])


def everything(root: Path) -> dict[str, bytes | None]:
    """Every entry under ``root`` (hidden ones too): files with their bytes, folders as None."""
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None) for p in sorted(root.rglob("*"))}


@pytest.fixture(scope="module")
def tmpfs(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A real 4 MiB file system (tmpfs; mounting needs root: skipped where refused)."""
    with mounted_tmpfs(tmp_path_factory.mktemp("fs") / "mnt", "4m") as mount:
        yield mount


def _clear(mount: Path) -> None:
    import shutil

    for p in mount.iterdir():
        shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()


def _fill(mount: Path, free_kib: int) -> None:
    """Leave about ``free_kib`` KiB free on ``mount`` (a filler file takes the rest)."""
    filler = mount / "filler"
    avail = os.statvfs(mount).f_bavail * os.statvfs(mount).f_frsize
    with open(filler, "wb") as fh:
        left = max(0, avail - free_kib * 1024)
        while left > 0:
            n = min(left, 1 << 16)
            try:
                fh.write(b"\0" * n)
                fh.flush()
            except OSError:
                break
            left -= n


def _earlier_then_later(mount: Path, capsys: pytest.CaptureFixture[str], free_kib: int, earlier: list,
                        later: list, out_name: str = "out") -> tuple[int, str, dict, Path]:
    _clear(mount)
    out = mount / out_name
    code, _, err = run_cli([*earlier, "--out", out], capsys)
    assert code == 0, err
    before = everything(mount)
    _fill(mount, free_kib)
    code, _, err = run_cli([*later, "--out", out], capsys)
    (mount / "filler").unlink()
    return code, err, before, out


def _check(code: int, err: str, before: dict, mount: Path, complete: callable, kept: str = "") -> None:
    assert "Traceback" not in err and "internal error" not in err, err
    if code == 0:
        assert complete(), "a command that succeeded left an incomplete result"
        return
    assert code == 2, err
    assert "No space left on device" in err and "nothing partial was kept" in err, err
    after = {k: v for k, v in everything(mount).items() if not (kept and f"/{kept}" in f"/{k}")}
    assert after == before  # byte for byte, hidden entries included (no lock or stage left)


# ------------------------------------------------------------------------------ the sample found by probing
@FEW
@given(free_kib=st.integers(min_value=0, max_value=44))
def test_simulate_over_an_earlier_result_on_a_full_disk(tmpfs: Path, capsys: pytest.CaptureFixture[str],
                                                        free_kib: int) -> None:
    run = ["simulate", "--ems", "thermostat", "--no-progress"]
    code, err, before, out = _earlier_then_later(tmpfs, capsys, free_kib, [*run, "--hours", "24"],
                                                 [*run, "--hours", "30"])
    _check(code, err, before, tmpfs, lambda: json.loads((out / "summary.json").read_text())["steps"] == 30)


# ------------------------------------------------------------------------------ further commands
@pytest.mark.parametrize("free_kib", [0, 8, 40])
def test_data_build_over_an_earlier_file_on_a_full_disk(tmpfs: Path, capsys: pytest.CaptureFixture[str],
                                                        free_kib: int) -> None:
    build = ["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR]
    code, err, before, out = _earlier_then_later(tmpfs, capsys, free_kib, [*build, "--seed", "1"],
                                                 [*build, "--seed", "2"], "scenario.csv")
    _check(code, err, before, tmpfs, lambda: out.stat().st_size > 0)


@pytest.mark.parametrize("free_kib", [0, 16, 64])
def test_evaluate_over_an_earlier_result_on_a_full_disk(tmpfs: Path, capsys: pytest.CaptureFixture[str],
                                                        recorded_bag: Path, free_kib: int) -> None:  # noqa: F811
    code, err, before, out = _earlier_then_later(tmpfs, capsys, free_kib, ["evaluate", recorded_bag, "--no-timeseries"],
                                                 ["evaluate", recorded_bag])
    _check(code, err, before, tmpfs, lambda: (out / "timeseries.csv").is_file())


@pytest.mark.parametrize("free_kib", [0, 24, 200])
def test_fuzzy_surface_over_earlier_figures_on_a_full_disk(tmpfs: Path, capsys: pytest.CaptureFixture[str],
                                                           free_kib: int) -> None:
    code, err, before, out = _earlier_then_later(tmpfs, capsys, free_kib, ["fuzzy-surface", "--dpi", "10"],
                                                 ["fuzzy-surface", "--dpi", "12", "--chi", "0.3"])
    _check(code, err, before, tmpfs, lambda: any(out.glob("*.png")))


@pytest.mark.parametrize("free_kib", [0, 60])
def test_sweep_over_an_earlier_study_on_a_full_disk(tmpfs: Path, capsys: pytest.CaptureFixture[str],
                                                    free_kib: int) -> None:
    sweep = ["sweep", "--ems", "rbc", "--weeks", "0.25", "--jobs", "1", "--no-progress"]
    code, err, before, out = _earlier_then_later(tmpfs, capsys, free_kib, [*sweep, "--param", "battery.e_max_kwh=5"],
                                                 [*sweep, "--param", "battery.e_max_kwh=6"])
    # the finished runs stay in the study's run store for --resume (said on stderr); the results are as they were
    _check(code, err, before, tmpfs, lambda: (out / "sweep.json").is_file(), kept=".runstore")
    assert code == 0 or not any((out / ".runstore").glob("rbc*")) or "--resume" in err, err


# ------------------------------------------------------------------------------ any user: a file size limit
@FEW
@given(limit_kib=st.integers(min_value=1, max_value=40))
def test_a_file_size_limit_leaves_the_earlier_result(tmp_path_factory: pytest.TempPathFactory,
                                                     limit_kib: int) -> None:
    """``RLIMIT_FSIZE`` in the child: a write beyond it fails with EFBIG (SIGXFSZ ignored)."""
    tmp = tmp_path_factory.mktemp("f")
    out = tmp / "out"
    code = ("import resource, signal, sys; signal.signal(signal.SIGXFSZ, signal.SIG_IGN); "
            "n = int(sys.argv[1]); resource.setrlimit(resource.RLIMIT_FSIZE, (n, n)) if n else None; "
            "from comems4build_ros.app.cli import main; sys.exit(main(sys.argv[2:]))")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    run = ["simulate", "--ems", "thermostat", "--no-progress", "--out", str(out)]
    first = subprocess.run([sys.executable, "-c", code, "0", *run, "--hours", "24"], capture_output=True, text=True,
                           env=env, cwd=REPO, timeout=300)
    assert first.returncode == 0, first.stderr
    before = everything(tmp)
    res = subprocess.run([sys.executable, "-c", code, str(limit_kib * 1024), *run, "--hours", "30"],
                         capture_output=True, text=True, env=env, cwd=REPO, timeout=300)
    assert "Traceback" not in res.stderr, res.stderr
    if res.returncode == 0:
        assert json.loads((out / "summary.json").read_text())["steps"] == 30
    else:
        assert res.returncode == 2 and "File too large" in res.stderr, res.stderr
        assert everything(tmp) == before


# ------------------------------------------------------------------------------ an I/O error anywhere
@FEW
@given(call=st.sampled_from(["fsync", "replace", "write", "ftruncate"]), n=st.integers(min_value=1, max_value=8),
       err=st.sampled_from([errno.EIO, errno.ENOSPC, errno.EDQUOT, errno.EROFS]))
def test_an_io_error_at_any_write_or_rename_leaves_the_earlier_result(tmp_path_factory: pytest.TempPathFactory,
                                                                      call: str, n: int, err: int) -> None:
    from comems4build_ros.files.outputs import OutputDir

    out = tmp_path_factory.mktemp("e") / "out"
    with OutputDir(out, "t", writes=("a", "d", "s.json")) as o:
        (o.stage / "a").write_text("old")
        (o.stage / "d").mkdir()
        (o.stage / "d" / "x").write_text("old")
    before = everything(out.parent)
    real, calls = getattr(os, call), [0]

    def failing(*args: object, **kwargs: object) -> object:
        calls[0] += 1
        if calls[0] == n:
            raise OSError(err, os.strerror(err))
        return real(*args, **kwargs)

    from comems4build_ros.files import outputs

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(os, call, failing)
        try:
            with OutputDir(out, "t", writes=("a", "d", "s.json")) as o:
                (o.stage / "a").write_text("new")
                (o.stage / "d").mkdir()
                outputs.write_text_atomic(o.stage / "s.json", "{}")
        except OSError as exc:
            assert exc.errno == err
            failed = True
        else:
            failed = False
    if failed:
        assert everything(out.parent) == before
    else:
        assert (out / "a").read_text() == "new" and not (out / "d" / "x").exists()
