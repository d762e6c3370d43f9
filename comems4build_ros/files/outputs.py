"""Result files: output paths checked before a run, and atomic writes.

A run's results are either written completely or not at all: every file goes to a
temporary name beside its destination and is renamed into place only after it was written
and flushed (:func:`atomic_write`, :func:`atomic_dir`); a failure on the way (a full disk,
a removed directory) removes the temporary file and leaves the destination as it was.
:func:`check_out_dir` and :func:`check_out_file` refuse an output path that cannot work
(an existing file where a directory is needed, a path under a file, a read-only
directory) before any computation starts.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path


class OutputPathError(ValueError):
    """An output path that cannot be written; the message names the option and the path."""


def check_out_dir(path: str | Path, option: str = "--out") -> Path:
    """Check that ``path`` is, or can be created as, a writable directory.

    Raises
    ------
    OutputPathError
        If ``path`` is an existing file, lies under a file, or its nearest existing
        ancestor is not a writable directory.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputPathError(f"{option} {p}: exists and is not a directory")
    _check_ancestor(p, p, option)
    return p


def check_out_file(path: str | Path, option: str = "--out") -> Path:
    """Check that the file ``path`` can be written (not a directory, in a writable directory).

    Raises
    ------
    OutputPathError
        Naming the option, the path and the problem.
    """
    p = Path(path)
    if p.is_dir():
        raise OutputPathError(f"{option} {p}: is a directory (a file name is needed)")
    if p.exists() and not os.access(p, os.W_OK):
        raise OutputPathError(f"{option} {p}: the file is not writable")
    _check_ancestor(p.parent, p, option)
    return p


def _check_ancestor(start: Path, target: Path, option: str) -> None:
    node = start
    while not node.exists() and node != node.parent:
        node = node.parent
    if not node.is_dir():
        raise OutputPathError(f"{option} {target}: {node} is a file, not a directory")
    if not os.access(node, os.W_OK | os.X_OK):
        raise OutputPathError(f"{option} {target}: directory {node} is not writable")


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", encoding: str | None = "utf-8") -> Iterator:
    """Open a temporary file beside ``path``; rename it to ``path`` when the block succeeds.

    On any error (e.g. ``OSError`` ENOSPC from a full disk) the temporary file is removed
    and ``path`` keeps its previous content (or stays absent).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode, encoding=None if "b" in mode else encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise _named(exc, path) from exc
        raise


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_write`."""
    with atomic_write(path) as fh:
        fh.write(text)
    return Path(path)


@contextlib.contextmanager
def atomic_dir(path: str | Path, replaces: Iterable[str] = ()) -> Iterator[Path]:
    """A temporary directory inside ``path`` whose entries replace those of ``path`` when the block succeeds.

    The caller writes every result (files and directories) into the yielded directory.
    Only when all of them are written does each top-level entry replace the entry of the
    same name in ``path`` (a directory as a whole, so no file of an older result stays
    inside it), and the entries matching a pattern of ``replaces`` (``fnmatch``, e.g.
    ``timeseries.csv``, ``house_*``) that the block did not write are removed: the
    result in ``path`` is the new one, whole, beside the entries of ``path`` that are no
    result. Renames within one file system need no space, so a failure or an interruption
    while writing leaves ``path`` as it was (and removes it again if it created it and it
    is empty); the temporary directory is removed in any case. A process killed while
    writing leaves only the hidden ``.partial.*`` directory.
    """
    path = Path(path)
    created = not path.exists()
    path.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".partial.", dir=path))
    try:
        yield tmp
        _replace_entries(tmp, path, tuple(replaces))
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if created:
            with contextlib.suppress(OSError):
                path.rmdir()  # only if still empty
        if isinstance(exc, OSError):
            raise _named(exc, path) from exc
        raise
    shutil.rmtree(tmp, ignore_errors=True)


def _replace_entries(new: Path, path: Path, replaces: tuple[str, ...]) -> None:
    """Move each entry of ``new`` into ``path`` over the old one; old entries matching ``replaces`` go."""
    import fnmatch

    names = sorted(p.name for p in new.iterdir())
    stale = [p.name for p in path.iterdir() if p.name not in names and not p.name.startswith(".partial.")
             and any(fnmatch.fnmatchcase(p.name, pattern) for pattern in replaces)]
    trash = Path(tempfile.mkdtemp(prefix=".replaced.", dir=path))
    try:
        for name in names:
            src, dest = new / name, path / name
            if (dest.is_dir() and not dest.is_symlink()) or (src.is_dir() and dest.exists()):
                os.replace(dest, trash / name)  # a directory is replaced whole
            os.replace(src, dest)
        for name in stale:
            os.replace(path / name, trash / name)
    finally:
        shutil.rmtree(trash, ignore_errors=True)


def _named(exc: OSError, path: Path) -> OSError:
    """``exc`` naming the destination ``path`` instead of no file or a temporary one."""
    name = str(exc.filename or "")
    if name and ".partial." not in name and not Path(name).name.endswith(".tmp"):
        return exc
    return OSError(exc.errno, exc.strerror or str(exc), str(path))
