"""The resumable store of a study's finished runs.

A study writing into ``OUT`` keeps each run that finishes in ``OUT/.runstore/<name>/``:
the run's files (``summary.json``, ``weekly.csv``, ``timeseries.csv``, ``bag/``) and
``run.json``, the run's record: its name, full specification and hash
(:mod:`comems4build_ros.study.spec`), its summary, and its attempts (worker, host, process,
start and end times in UTC, outcome). A run enters the store whole (written beside it,
then renamed), so a study interrupted at any moment leaves only finished runs there.

``--resume`` takes a stored run whose specification hash equals the one the study would
run now instead of running it again; a stored run of the same name whose specification
differs is refused, naming what differs. The command removes the store once its results
are in place; until then a second command on the same ``OUT`` is refused (a lock), and
one without ``--resume`` is told what the store holds rather than discarding it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import load_json_file

#: Name of the store directory inside a study's output directory.
STORE_DIR = ".runstore"
#: The run's record, in the store and in the run's output directory.
RECORD = "run.json"
_LOCK = ".lock"


class StoreError(InputError):
    """The store cannot be used as asked (locked, another study's runs, not resumed); names the store."""


@dataclass
class StoredRun:
    """A finished run in the store: its directory and its record (``run.json``)."""

    name: str
    path: Path
    record: dict[str, Any]

    @property
    def spec_hash(self) -> str:
        """Hash of the run's full specification."""
        return str(self.record.get("spec_hash", ""))


class RunStore:
    """The finished runs of one study in ``root`` (normally ``OUT/.runstore``)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self._lock_fd: int | None = None

    @classmethod
    def of(cls, out_dir: str | Path) -> RunStore:
        """The store of a study writing into ``out_dir``."""
        return cls(Path(out_dir) / STORE_DIR)

    # ---------------------------------------------------------------- one study at a time
    @contextlib.contextmanager
    def locked(self) -> Iterator[RunStore]:
        """Hold the store's lock for the block (another command on the same output is refused)."""
        self.make()
        try:
            fd = os.open(self.root / _LOCK, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise StoreError(f"{self.root / _LOCK}: a symbolic link where the store's lock should be; "
                                 "never opened through a link: remove it") from None
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StoreError(f"{self.root}: another study is running into this output directory") from None
        self._lock_fd = fd
        try:
            yield self
        finally:
            self._lock_fd = None
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def make(self) -> None:
        """Create the store's folder (its parents as ``mkdir -p``): mode 0700 whatever the umask (a
        resumed study reads its runs again), never through a link (refused, named)."""
        from comems4build_ros.files.outputs import open_dir

        os.close(open_dir(self.root, create=True, private=True, what="the study's run store"))

    # ---------------------------------------------------------------- reading
    def finished(self) -> tuple[dict[str, StoredRun], list[str]]:
        """The stored runs by name, and a note per entry that is not a readable finished run."""
        runs: dict[str, StoredRun] = {}
        notes: list[str] = []
        if not self.root.is_dir():
            return runs, notes
        for path in sorted(self.root.iterdir()):
            if path.name.startswith(".") or not path.is_dir():
                continue
            try:
                record = load_json_file(path / RECORD, "a run record")
                if not isinstance(record, dict) or record.get("name") != path.name or "spec_hash" not in record:
                    raise ValueError("not a run record of this directory")
            except (OSError, ValueError) as exc:
                notes.append(f"{path}: not a finished run ({exc}); it is run again")
                continue
            runs[path.name] = StoredRun(path.name, path, record)
        return runs, notes

    # ---------------------------------------------------------------- writing
    def save(self, name: str, files: Mapping[str, bytes], record: Mapping[str, Any]) -> StoredRun:
        """Store a finished run whole: its files and ``run.json`` (an older entry of the name is replaced)."""
        self.make()
        tmp = Path(tempfile.mkdtemp(prefix=f".tmp.{name}.", dir=self.root))
        try:
            write_run_files(tmp, files, record)
            final = self.root / name
            if final.exists():
                old = Path(tempfile.mkdtemp(prefix=f".old.{name}.", dir=self.root))
                os.replace(final, old / name)
                shutil.rmtree(old, ignore_errors=True)
            os.replace(tmp, final)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return StoredRun(name, final, dict(record))

    def remove(self) -> None:
        """Remove the store (the study's results are in place)."""
        shutil.rmtree(self.root, ignore_errors=True)


def write_run_files(dest: Path, files: Mapping[str, bytes], record: Mapping[str, Any]) -> None:
    """Write a run's files (relative path -> bytes) and its ``run.json`` into the directory ``dest``."""
    for rel, data in files.items():
        rel_path = Path(rel)
        if rel_path.is_absolute() or ".." in rel_path.parts or rel == RECORD:
            raise ValueError(f"run {record.get('name')}: file name {rel!r} is not a run file")
        target = dest / rel_path
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    (dest / RECORD).write_text(json.dumps(dict(record), indent=2, default=str) + "\n", encoding="utf-8")


def place(out_dir: str | Path, files: Mapping[str, bytes], record: Mapping[str, Any]) -> Path:
    """Write a run's files and record into ``out_dir``, replacing what was there whole (all or nothing)."""
    from comems4build_ros.files.outputs import atomic_dir

    with atomic_dir(out_dir, replaces=("*",)) as stage:
        write_run_files(stage, files, record)
    return Path(out_dir)


def materialize(run: StoredRun, out_dir: str | Path) -> Path:
    """Copy a stored run into ``out_dir``, replacing what was there whole (all or nothing)."""
    from comems4build_ros.files.outputs import atomic_dir

    with atomic_dir(out_dir, replaces=("*",)) as stage:
        for entry in run.path.iterdir():
            if entry.is_dir():
                shutil.copytree(entry, stage / entry.name)
            else:
                shutil.copy2(entry, stage / entry.name)
    return Path(out_dir)
