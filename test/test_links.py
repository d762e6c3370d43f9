"""No file through a link, and what a run reads again is the user's alone.

Anyone who can write into a shared ``--out`` could put a symbolic link (or a second hard
link) where comems4build's own file should be: the lock, the ownership record, a stage, an
earlier result kept aside, a result it replaces, the run store, a token file, the folder of
the plan's parameter files. Each is refused naming it (exit code 2) and the file the link
names stays byte for byte as it was. Files and folders a run reads again later (parameter
files, logs, secrets, the lock, the record, the run store, caches) get modes 0600/0700
whatever the umask; results follow the umask as every Unix tool's do.
"""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import run_cli

from comems4build_ros.files import outputs
from comems4build_ros.files.outputs import LOCK_FILE, OWNER_FILE, LinkRefusedError, OutputDir, OutputPathError

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "comems4build_ros.app.cli"]
BOUNDED = settings(max_examples=40, derandomize=True, database=None, deadline=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture])
PRECIOUS = "precious content\n"


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.lstat().st_mode)


def _precious(tmp: Path) -> Path:
    p = tmp / "elsewhere" / "precious.txt"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(PRECIOUS)
    return p


# ------------------------------------------------------------------------------ the sample found by probing
def test_a_lock_that_is_a_link_is_refused_and_the_file_it_names_kept(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    precious = _precious(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_FILE).symlink_to(precious)
    code, _, err = run_cli(["simulate", "--ems", "thermostat", "--hours", "3", "--no-progress", "--out", out], capsys)
    assert code == 2 and f"{out / LOCK_FILE}: a symbolic link where the lock of comems4build should be" in err, err
    assert precious.read_text() == PRECIOUS
    assert not (out / "summary.json").exists()


# ------------------------------------------------------------------------------ every owned name, any target
#: Hidden entries of the output layer and an owned result, as a later command finds them.
OWNED_NAMES = [LOCK_FILE, OWNER_FILE, ".partial.x1", ".previous.x2", ".replaced.x3", "a", "d"]


@BOUNDED
@given(name=st.sampled_from(OWNED_NAMES), target=st.sampled_from(["file", "dir", "missing"]),
       in_place=st.booleans(), probe_first=st.booleans())
def test_a_link_where_an_owned_entry_should_be_is_refused_naming_it(tmp_path_factory: pytest.TempPathFactory,
                                                                   name: str, target: str, in_place: bool,
                                                                   probe_first: bool) -> None:
    tmp = tmp_path_factory.mktemp("l")
    out = tmp / "out"
    with OutputDir(out, "t", writes=("a", "d")) as o:  # an earlier result: a file and a folder, both owned
        (o.stage / "a").write_text("old")
        (o.stage / "d").mkdir()
        (o.stage / "d" / "x").write_text("old")
    precious = _precious(tmp)
    victim_dir = precious.parent
    aim = {"file": precious, "dir": victim_dir, "missing": tmp / "nowhere"}[target]
    entry = out / name
    if entry.is_dir():
        import shutil

        shutil.rmtree(entry)
    elif entry.exists():
        entry.unlink()
    entry.symlink_to(aim)
    before = sorted(p.name for p in victim_dir.iterdir())
    with pytest.raises(LinkRefusedError, match=f"{entry}: a symbolic link where"):
        if probe_first:
            OutputDir(out, "t2", writes=("a", "d"), in_place=in_place).check()
        with OutputDir(out, "t2", writes=("a", "d"), in_place=in_place) as o:
            (o.stage / "a").write_text("new")
    assert precious.read_text() == PRECIOUS
    assert sorted(p.name for p in victim_dir.iterdir()) == before
    assert entry.is_symlink()  # named, never removed nor followed


def test_a_lock_with_a_second_name_is_never_written(tmp_path: Path) -> None:
    precious = _precious(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    os.link(precious, out / LOCK_FILE)  # a hard link: the same file under the lock's name
    with pytest.raises(LinkRefusedError, match="2 names"):
        with OutputDir(out, "t", writes=("a",)):
            pass
    assert precious.read_text() == PRECIOUS


@BOUNDED
@given(text=st.text(min_size=1, max_size=200))
def test_atomic_writes_replace_a_file_never_a_link(tmp_path_factory: pytest.TempPathFactory, text: str) -> None:
    tmp = tmp_path_factory.mktemp("a")
    precious = _precious(tmp)
    dest = tmp / "doc.md"
    dest.symlink_to(precious)
    with pytest.raises(LinkRefusedError, match=f"{dest}: a symbolic link"):
        outputs.write_text_atomic(dest, text)
    assert precious.read_text() == PRECIOUS
    assert [p.name for p in tmp.iterdir() if p.name.endswith(".tmp")] == []
    dest.unlink()
    outputs.write_text_atomic(dest, text)
    assert dest.read_text(encoding="utf-8") == text


def test_a_token_file_or_secret_folder_that_is_a_link_is_refused(tmp_path: Path) -> None:
    from comems4build_ros.wire.tokens import TokenFileError, private_dir, read_token_file, write_token_file

    precious = _precious(tmp_path)
    secrets = tmp_path / "run" / ".secrets"
    secrets.parent.mkdir()
    secrets.symlink_to(precious.parent)  # the folder: chmod and unlink would act on the folder it names
    mode = _mode(precious.parent)
    with pytest.raises(OutputPathError, match="a symbolic link where a folder for run secrets should be"):
        private_dir(secrets)
    with pytest.raises(OutputPathError, match="symbolic link"):
        write_token_file(secrets / "precious.txt", 12345)
    assert precious.read_text() == PRECIOUS and _mode(precious.parent) == mode
    secrets.unlink()
    token = write_token_file(secrets / "house.token", 4242)
    assert read_token_file(token) == 4242 and _mode(token) == 0o600 and _mode(secrets) == 0o700
    # a token file that is a link to a file whose number others know is never read
    known = tmp_path / "known.token"
    known.write_text("777\n")
    known.chmod(0o600)
    (secrets / "other.token").symlink_to(known)
    with pytest.raises(TokenFileError, match="symbolic link"):
        read_token_file(secrets / "other.token")


def test_a_run_store_that_is_a_link_is_refused(tmp_path: Path) -> None:
    from comems4build_ros.study.store import RunStore

    precious = _precious(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / ".runstore").symlink_to(precious.parent)
    store = RunStore.of(out)
    with pytest.raises(LinkRefusedError, match=r"\.runstore: a symbolic link where the study's run store"):
        with store.locked():
            pass
    with pytest.raises(LinkRefusedError):
        store.save("run1", {"summary.json": b"{}"}, {"name": "run1", "spec_hash": "x"})
    assert sorted(p.name for p in precious.parent.iterdir()) == ["precious.txt"]


def test_plan_files_and_logs_are_never_written_through_a_link(tmp_path: Path) -> None:
    from comems4build_ros.run.supervisor import ProcessGroup, write_plan_files

    precious = _precious(tmp_path)
    out = tmp_path / "run"
    out.mkdir()
    (out / "params").symlink_to(precious.parent)

    class Plan:
        files = ((str(out / "params" / "precious.txt"), "attack"),)
        processes = ()

    Plan.out = out
    with pytest.raises(LinkRefusedError, match=f"{out / 'params'}: a symbolic link"):
        write_plan_files(Plan)  # type: ignore[arg-type]
    (out / "log").symlink_to(precious.parent)
    with pytest.raises(LinkRefusedError, match=f"{out / 'log'}: a symbolic link"):
        ProcessGroup({}, out / "log")
    assert precious.read_text() == PRECIOUS


# ------------------------------------------------------------------------------ private whatever the umask
@pytest.mark.parametrize("umask", [0o000, 0o002, 0o022, 0o077])
def test_what_is_read_again_is_private_and_results_follow_the_umask(tmp_path: Path, umask: int) -> None:
    from comems4build_ros.study.store import RunStore
    from comems4build_ros.wire.tokens import write_token_file

    old = os.umask(umask)
    try:
        out = tmp_path / "out"
        with OutputDir(out, "t", writes=("r.txt",)) as o:
            (o.stage / "r.txt").write_text("result")
            assert _mode(out / LOCK_FILE) == 0o600
        outputs.write_text_atomic(tmp_path / "result.md", "x")
        store = RunStore.of(tmp_path / "study")
        store.save("run1", {"summary.json": b"{}"}, {"name": "run1", "spec_hash": "x"})
        token = write_token_file(tmp_path / "run" / ".secrets" / "t.token", 99)
    finally:
        os.umask(old)
    assert _mode(out / OWNER_FILE) == 0o600
    assert _mode(out / "r.txt") == 0o666 & ~umask
    assert _mode(tmp_path / "result.md") == 0o666 & ~umask
    assert _mode(store.root) == 0o700
    assert _mode(token) == 0o600 and _mode(token.parent) == 0o700


def test_launch_under_umask_000_keeps_params_and_logs_private(tmp_path: Path) -> None:
    """Found by probing: ``umask 000; comems4build launch ...`` made ``params/`` and ``log/`` 0777."""
    out = tmp_path / "run"
    res = subprocess.run([*CLI, "launch", "--ems", "rbc", "--steps", "3", "--no-progress", "--out", str(out)],
                         cwd=REPO, capture_output=True, text=True, timeout=600, preexec_fn=lambda: os.umask(0))
    assert res.returncode == 0, res.stderr[-3000:]
    for d in (out / "params", out / "log"):
        assert _mode(d) == 0o700, (d, oct(_mode(d)))
    assert _mode(out / "params" / "plant.yaml") == 0o600
    assert all(_mode(f) == 0o600 for f in (out / "log").glob("*.log"))
    assert _mode(out / "summary.json") == 0o666  # a result: the umask's (none here)
    assert json.loads((out / "summary.json").read_text())["steps"] == 3
