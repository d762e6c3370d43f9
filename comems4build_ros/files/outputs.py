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
import errno
import os
import secrets
import shutil
import stat
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError


class OutputPathError(InputError):
    """An output path that cannot be written; the message names the option and the path."""


class LinkRefusedError(OutputPathError):
    """A symbolic link (or a second hard link) where a file or folder of comems4build's own should be."""


# ------------------------------------------------------------------------------ no file through a link
#: Flags of every descriptor the output layer opens: the last component is never followed if a link.
_NOFOLLOW = os.O_NOFOLLOW | os.O_CLOEXEC
#: Modes of what comems4build creates: a result follows the umask (``0o666``/``0o777`` less the
#: umask, as every Unix tool's); what a run reads again later (parameter files, tokens, the lock,
#: the ownership record, logs the launcher reads) is the user's alone whatever the umask.
FILE_MODE, DIR_MODE, PRIVATE_FILE_MODE, PRIVATE_DIR_MODE = 0o666, 0o777, 0o600, 0o700


def _link_refused(path: str | os.PathLike[str], what: str) -> LinkRefusedError:
    return LinkRefusedError(f"{path}: a symbolic link where {what} should be; comems4build never writes through a "
                            "link (anyone who can write into the folder could aim it at any file): remove it")


def _is_link(name: str | os.PathLike[str], dir_fd: int | None = None) -> bool:
    try:
        return stat.S_ISLNK(os.stat(name, dir_fd=dir_fd, follow_symlinks=False).st_mode)
    except OSError:
        return False


def _own(fd: int, path: str | os.PathLike[str], what: str, private: bool, directory: bool) -> None:
    """Check the opened ``fd`` is a file (folder) of this user with one name; make it private if asked."""
    st = os.fstat(fd)
    kind_ok = stat.S_ISDIR(st.st_mode) if directory else stat.S_ISREG(st.st_mode)
    if not kind_ok:
        raise OutputPathError(f"{path}: not a {'folder' if directory else 'regular file'}; {what} is expected there")
    if not directory and st.st_nlink != 1:  # a hard link to a file elsewhere: writing it would change that file
        raise LinkRefusedError(f"{path}: has {st.st_nlink} names (hard links) where {what} should be; comems4build "
                               "never writes a file that also lives elsewhere: remove it")
    if private:
        if st.st_uid != os.geteuid():
            raise OutputPathError(f"{path}: belongs to another user (uid {st.st_uid}); {what} must be this user's")
        wanted = PRIVATE_DIR_MODE if directory else PRIVATE_FILE_MODE
        if stat.S_IMODE(st.st_mode) != wanted:
            os.fchmod(fd, wanted)


def open_dir(path: str | os.PathLike[str], root: str | os.PathLike[str] | None = None, create: bool = False,
             private: bool = False, what: str = "a folder of comems4build") -> int:
    """A descriptor of the folder ``path``; no component below ``root`` is followed if it is a link.

    Parameters
    ----------
    path : the folder
    root : the folder the walk starts from, followed as given (the user's ``--out``; default:
        ``path``'s parent, so that only ``path`` itself must not be a link)
    create : make ``path`` and the missing folders between ``root`` and it (``root`` as ``mkdir -p``)
    private : the folders made, and ``path``, get mode 0700 and must be this user's
    what : what the folder is, for messages

    Raises
    ------
    LinkRefusedError
        If a component below ``root`` is a symbolic link (named).
    OSError
        As ``open``/``mkdir`` raise it (a missing folder without ``create``, no permission).
    """
    path = Path(path)
    base = Path(root) if root is not None else path.parent
    try:
        parts = path.relative_to(base).parts
    except ValueError:
        base, parts = path.parent, (path.name,)
    if create:
        base.mkdir(parents=True, exist_ok=True)
    fd = os.open(base, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        for i, name in enumerate(parts):
            here = base.joinpath(*parts[: i + 1])
            made = False
            if create:
                try:
                    os.mkdir(name, PRIVATE_DIR_MODE if private else DIR_MODE, dir_fd=fd)
                    made = True
                except FileExistsError:
                    pass
            try:
                sub = os.open(name, os.O_RDONLY | os.O_DIRECTORY | _NOFOLLOW, dir_fd=fd)
            except OSError as exc:
                if exc.errno in (errno.ELOOP, errno.ENOTDIR) and _is_link(name, fd):
                    raise _link_refused(here, what) from None
                raise OSError(exc.errno, exc.strerror, str(here)) from None
            os.close(fd)
            fd = sub
            if private and (made or i == len(parts) - 1):
                _own(fd, here, what, True, True)
        return fd
    except BaseException:
        os.close(fd)
        raise


def create_file(path: str | os.PathLike[str], root: str | os.PathLike[str] | None = None, private: bool = False,
                exclusive: bool = True, what: str = "a file of comems4build") -> int:
    """Create the file ``path`` for writing (``O_NOFOLLOW``, relative to its folder's descriptor).

    ``exclusive``: the file must not exist (``O_EXCL``); else an existing file of this user with
    one name is truncated. ``private``: mode 0600 (its folders made 0700), whatever the umask;
    else ``0o666`` less the umask. Folders between ``root`` and the file are made as by
    :func:`open_dir`. Returns the descriptor, opened for writing.

    Raises
    ------
    LinkRefusedError
        If ``path`` or a folder below ``root`` is a symbolic link, or ``path`` a second name of a file.
    OutputPathError
        If ``exclusive`` and ``path`` exists.
    """
    path = Path(path)
    dfd = open_dir(path.parent, root if root is not None else path.parent, create=True, private=private, what=what)
    try:
        flags = os.O_WRONLY | os.O_CREAT | _NOFOLLOW | (os.O_EXCL if exclusive else 0)
        try:
            fd = os.open(path.name, flags, PRIVATE_FILE_MODE if private else FILE_MODE, dir_fd=dfd)
        except FileExistsError:
            if _is_link(path.name, dfd):
                raise _link_refused(path, what) from None
            raise OutputPathError(f"{path}: exists; {what} is only ever created new there (remove it)") from None
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise _link_refused(path, what) from None
            raise OSError(exc.errno, exc.strerror, str(path)) from None
    finally:
        os.close(dfd)
    try:
        _own(fd, path, what, private, False)
        if not exclusive:
            os.ftruncate(fd, 0)
    except BaseException:
        os.close(fd)
        raise
    return fd


def write_new_file(path: str | os.PathLike[str], data: str | bytes, root: str | os.PathLike[str] | None = None,
                   private: bool = False, exclusive: bool = True, what: str = "a file of comems4build") -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` through :func:`create_file`."""
    fd = create_file(path, root, private=private, exclusive=exclusive, what=what)
    with os.fdopen(fd, "wb") as fh:
        fh.write(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


def read_private(path: str | os.PathLike[str], limit: int = 1024 * 1024, what: str = "a file of comems4build") -> bytes:
    """The first ``limit`` bytes of ``path``, opened without following a link (refused, named)."""
    try:
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise _link_refused(path, what) from None
        raise
    with os.fdopen(fd, "rb") as fh:
        return fh.read(limit)


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
    try:  # a read-only file system, or a directory its mode bars to others than root: tried, not asked
        fd, probe = tempfile.mkstemp(prefix=".comems4build-probe.", dir=node)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(f"{option} {target}: directory {node} is not writable ({exc.strerror})") from None


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", encoding: str | None = "utf-8", private: bool = False) -> Iterator:
    """Open a temporary file beside ``path``; rename it to ``path`` when the block succeeds.

    On any error (e.g. ``OSError`` ENOSPC from a full disk) the temporary file is removed
    and ``path`` keeps its previous content (or stays absent). Nothing goes through a link:
    the temporary file is created new (``O_EXCL | O_NOFOLLOW``) and renamed relative to the
    folder's descriptor; a symbolic link at ``path`` is refused (:class:`LinkRefusedError`).
    ``private``: mode 0600 whatever the umask (a file a run reads again); else the umask's.
    """
    path = Path(path)
    dfd = open_dir(path.parent, create=True)
    tmp = f".{path.name}.{secrets.token_hex(6)}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW,
                     PRIVATE_FILE_MODE if private else FILE_MODE, dir_fd=dfd)
    except OSError as exc:
        os.close(dfd)
        raise _named(exc, path) from exc
    try:
        with os.fdopen(fd, mode, encoding=None if "b" in mode else encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        if _is_link(path.name, dfd):
            raise _link_refused(path, "the file to write")
        os.replace(tmp, path.name, src_dir_fd=dfd, dst_dir_fd=dfd)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp, dir_fd=dfd)
        if isinstance(exc, OSError):
            raise _named(exc, path) from exc
        raise
    finally:
        os.close(dfd)


def write_text_atomic(path: str | Path, text: str, private: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_write` (``private``: mode 0600)."""
    with atomic_write(path, private=private) as fh:
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
            if dest.is_symlink():
                raise _link_refused(dest, "a result of comems4build")
            if dest.is_dir() or (src.is_dir() and dest.exists()):
                os.replace(dest, trash / name)  # a directory is replaced whole
            os.replace(src, dest)
        for name in stale:
            os.replace(path / name, trash / name)
    finally:
        shutil.rmtree(trash, ignore_errors=True)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM held back while the block runs (in the main thread; elsewhere nothing).

    The renames that put a result in place take milliseconds; a Ctrl-C among them is
    delivered right after, so the result is in place whole or not at all.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _remove(path: Path) -> None:
    """Remove the file, link or directory tree ``path``."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _named(exc: OSError, path: Path) -> OSError:
    """``exc`` naming the destination ``path`` instead of no file or a temporary one."""
    name = str(exc.filename or "")
    if name and ".partial." not in name and not Path(name).name.endswith(".tmp"):
        return exc
    return OSError(exc.errno, exc.strerror or str(exc), str(path))


#: Bytes a bag takes per step and house, an upper estimate: about twice the 8.6 kB per step of a fuzzy
#: run recording every EMS input (``launch --ems fuzzy --all-inputs --steps 48``, then ``du -sb`` of its
#: bag: 412500 bytes).
BAG_BYTES_PER_STEP = 16 * 1024
#: Room kept free beyond a bag's estimate (metadata, logs, the evaluation's tables) [bytes].
SPARE_BYTES = 8 * 1024 * 1024


def check_free_space(path: str | Path, needed: int, option: str, what: str) -> None:
    """Refuse an output whose file system lacks the room for ``needed`` bytes (and :data:`SPARE_BYTES`).

    Checked before a run starts (``launch``: its bag), where the size can be estimated;
    a disk that fills during the run is named by the node that cannot write.

    Raises
    ------
    OutputPathError
        Naming ``option``, the path, the free and the needed space.
    """
    node = Path(path)
    while not node.exists() and node != node.parent:
        node = node.parent
    free = shutil.disk_usage(node).free
    if free < needed + SPARE_BYTES:
        raise OutputPathError(f"{option} {path}: {free / 2**20:.1f} MiB free on its file system; {what} needs about "
                              f"{(needed + SPARE_BYTES) / 2**20:.1f} MiB (a full disk would cut the run)")


# ------------------------------------------------------------------------------ one output layer
#: The record in each output directory of what comems4build wrote there (JSON: the command,
#: the time, the entries). Only an entry named in it may be replaced or removed by a later
#: command; anything else in the way is refused, naming it.
OWNER_FILE = ".comems4build-output.json"
#: The lock of an output directory (``flock``): one command writes into it at a time.
LOCK_FILE = ".comems4build.lock"
#: Prefix of the temporary directories a command writes its results into before they are renamed into place.
STAGE_PREFIX = ".partial."
#: Prefix of the directory that keeps an earlier result while an in-place command writes its own.
PREVIOUS_PREFIX = ".previous."
#: Prefix of the report of an internal error (a defect's traceback) a command leaves in its output folder;
#: never a result, never an entry in the way of a later command.
INTERNAL_ERROR_PREFIX = ".comems4build-internal-error."


def write_internal_report(out: str | os.PathLike[str] | None, text: str) -> Path:
    """Write ``text`` (a defect's traceback) to a new private file in the output folder ``out`` (if it is
    an existing folder that takes it), else in the temporary folder; returns its path.

    The name starts with :data:`INTERNAL_ERROR_PREFIX` and carries the time and the process id;
    the file is created new (``O_EXCL``, never through a link), mode 0600 (it names paths).
    """
    stamp = f"{time.strftime('%Y%m%dT%H%M%S')}.{os.getpid()}"
    if out is not None and str(out) and Path(out).is_dir() and not Path(out).is_symlink():
        target = Path(out) / f"{INTERNAL_ERROR_PREFIX}{stamp}.txt"
        try:
            return write_new_file(target, text, private=True, what="the report of an internal error")
        except (OSError, OutputPathError):
            pass  # a read-only or full output folder: the temporary folder takes it
    fd, name = tempfile.mkstemp(prefix=f"{INTERNAL_ERROR_PREFIX}{stamp}.", suffix=".txt")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    return Path(name)


class OutputInUseError(OutputPathError):
    """Another command writes into the same output directory now."""


def check_out_text(text: str | os.PathLike[str], option: str = "--out") -> Path:
    """``text`` as an output path, unless it is empty or ambiguous.

    Refused: an empty or blank value (an unset shell variable: ``--out "$OUT"`` would write
    into the current directory), leading or trailing blanks, control characters (a newline,
    a tab), a leading ``~`` (a tilde the shell did not expand) and a ``$`` (a variable the
    shell did not expand).

    Raises
    ------
    OutputPathError
        Naming ``option`` and the value.
    """
    s = os.fspath(text)
    if not s.strip():
        raise OutputPathError(f"{option} '{s}': empty (an unset shell variable?); give a directory, '.' for the "
                              "current one")
    if s != s.strip():
        raise OutputPathError(f"{option} '{s}': leading or trailing blanks")
    if any(ord(c) < 32 or ord(c) == 127 for c in s):
        raise OutputPathError(f"{option} {s!r}: control characters in the path")
    if s.startswith("~"):
        raise OutputPathError(f"{option} '{s}': a '~' the shell did not expand (write $HOME/... or a full path)")
    if "$" in s:
        raise OutputPathError(f"{option} '{s}': a '$' (a shell variable that was not expanded?)")
    return Path(s)


def _real(path: str | os.PathLike[str]) -> Path:
    """``path`` absolute with every symbolic link resolved (as far as it exists)."""
    return Path(os.path.realpath(os.fspath(path)))


def _inside(inner: Path, outer: Path) -> bool:
    """Whether ``inner`` is ``outer`` or lies inside it (both resolved)."""
    return inner == outer or outer in inner.parents


def check_not_input(out: Path, inputs: Mapping[str, Iterable[str | os.PathLike[str]]], option: str = "--out",
                    writes: Iterable[str] | None = None) -> None:
    """Refuse an output that is, lies inside or would replace an input.

    Parameters
    ----------
    out : the output directory
    inputs : option or role (``--config``, ``BAG``) -> the paths it names
    writes : ``fnmatch`` patterns of the entries the command writes into ``out``; an input
        inside ``out`` is refused if it lies in such an entry (None: any input inside ``out``)

    Raises
    ------
    OutputPathError
        Naming both options and the paths.
    """
    import fnmatch

    real_out = _real(out)
    for role, paths in inputs.items():
        for p in paths:
            if p is None or os.fspath(p) == "":
                continue
            real_in = _real(p)
            if _inside(real_out, real_in):
                what = "is" if real_out == real_in else "lies inside"
                raise OutputPathError(f"{option} {out} {what} the input {role} {p}: the results would overwrite it; "
                                      "choose another output")
            if real_out in real_in.parents:
                entry = real_in.relative_to(real_out).parts[0]
                if writes is None or any(fnmatch.fnmatchcase(entry, pat) for pat in writes):
                    raise OutputPathError(f"{option} {out} contains the input {role} {p} in '{entry}', which the "
                                          "results would replace; choose another output")


def read_owner(path: Path) -> dict[str, Any]:
    """The ownership record of the output directory ``path`` (``{}`` without one, or unreadable).

    Raises
    ------
    LinkRefusedError
        If the record is a symbolic link (it is never read or written through one).
    """
    import json

    try:
        doc = json.loads(read_private(path / OWNER_FILE, what="comems4build's record of its outputs"))
    except LinkRefusedError:
        raise
    except (OSError, ValueError, RecursionError):
        return {}
    if not isinstance(doc, dict) or not isinstance(doc.get("entries"), list):
        return {}
    return doc


class OutputDir:
    """One command's output directory: checked, locked, written all or nothing, never over foreign files.

    Use as a context manager; write every result into :attr:`stage`. On entry:

    1. the path is checked (:func:`check_out_text`: not empty or ambiguous;
       :func:`check_out_dir`: writable; :func:`check_not_input`: not an input, not inside one,
       and no input in an entry it writes);
    2. the directory is created and locked (``flock`` on :data:`LOCK_FILE`): a second command on
       the same directory is refused at once (:class:`OutputInUseError`), never racing the first;
       temporary directories a killed command left are removed;
    3. every existing entry that matches ``writes`` must be named in the directory's
       ownership record (:data:`OWNER_FILE`), i.e. written by an earlier comems4build
       command; anything else in the way is refused, naming it.

    On a normal exit each top-level entry of :attr:`stage` replaces the entry of the same name
    (a directory whole), the owned entries matching ``replaces`` that this command did not
    write are removed, and the ownership record is updated. On an error or an interruption
    the stage is removed and the directory is left as it was (removed again if this command
    created it). Renames within one file system need no space, so a full disk while writing
    costs only the new result.

    Parameters
    ----------
    path : the output directory (``--out``)
    command : the command, named in the record and in the message to a second command
    option : the option that named ``path`` (for messages)
    inputs : role -> paths of every input of the command (:func:`check_not_input`)
    writes : ``fnmatch`` patterns of the top-level entries the command writes (``*``: any)
    replaces : patterns of owned entries removed when this command did not write them
        (``timeseries.csv`` after ``--no-timeseries``, ``house_*`` of a run with more houses)
    in_place : the command writes into ``path`` itself (:attr:`stage` is ``path``), so that its
        files can be watched where they end up while it runs (``launch``: the nodes' logs and the
        bag). The earlier result (the owned entries matching ``writes``) is moved aside into a
        hidden :data:`PREVIOUS_PREFIX` directory first; on an error or an interruption what this
        command wrote is removed and the earlier result moved back, on success the earlier
        result goes. A command killed meanwhile (SIGKILL) leaves the earlier result aside; the
        next command on the directory puts it back before it starts.
    """

    def __init__(self, path: str | os.PathLike[str], command: str, option: str = "--out",
                 inputs: Mapping[str, Iterable[str | os.PathLike[str]]] | None = None,
                 writes: Iterable[str] = ("*",), replaces: Iterable[str] = (), in_place: bool = False) -> None:
        self.path = check_out_text(path, option)
        self.in_place = in_place
        self._previous: Path | None = None
        self.command = command
        self.option = option
        self.inputs = {k: [p for p in v if p is not None] for k, v in (inputs or {}).items()}
        self.writes = tuple(writes)
        self.replaces = tuple(replaces)
        self.stage = Path()
        self._lock_fd: int | None = None
        self._created = False
        self._committed = False
        self.lock_name = LOCK_FILE

    # -- checks
    def check(self) -> None:
        """The checks of entry without creating or locking anything (:class:`OutputPathError`)."""
        check_out_dir(self.path, self.option)
        check_not_input(self.path, self.inputs, self.option, self.writes)
        self._check_no_links()
        self._probe_lock()
        self._check_owned(self._existing(self.writes))

    def _probe_lock(self) -> None:
        """:class:`OutputInUseError` if another command holds the lock now (nothing is created)."""
        import fcntl

        try:
            fd = os.open(self.path / self.lock_name, os.O_RDONLY | _NOFOLLOW)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise _link_refused(self.path / self.lock_name, "the lock of comems4build") from None
            return  # no lock file: nobody writes here
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 512).decode("utf-8", "replace").strip() or "another command"
            raise OutputInUseError(f"{self.option} {self.path}: in use by {holder}; wait until it ends or choose "
                                   f"another {self.option}") from None
        finally:
            os.close(fd)

    def _existing(self, patterns: tuple[str, ...]) -> list[str]:
        import fnmatch

        if not self.path.is_dir():
            return []
        return sorted(p.name for p in self.path.iterdir() if p.name not in (OWNER_FILE, LOCK_FILE)
                      and not p.name.startswith((STAGE_PREFIX, PREVIOUS_PREFIX, ".replaced.", INTERNAL_ERROR_PREFIX))
                      and not p.name.endswith(".comems4build.lock")
                      and any(fnmatch.fnmatchcase(p.name, pat) for pat in patterns))

    def _check_owned(self, names: Iterable[str]) -> None:
        owned = set(read_owner(self.path).get("entries", []))
        names = list(names)
        self._check_no_links(names)
        foreign = [n for n in names if n not in owned]
        if foreign:
            shown = ", ".join(str(self.path / n) for n in foreign[:5]) + (" ..." if len(foreign) > 5 else "")
            raise OutputPathError(f"{self.option} {self.path}: {shown} {'is' if len(foreign) == 1 else 'are'} in the "
                                  "way and not written by comems4build (no entry in "
                                  f"{self.path / OWNER_FILE}); it is never replaced: move it away or choose another "
                                  f"{self.option}")

    def _check_no_links(self, names: Iterable[str] = ()) -> None:
        """Refuse a symbolic link among ``names`` (entries comems4build writes or replaces) or the
        hidden entries of the output layer (its record, lock, stages, earlier results)."""
        if not self.path.is_dir():
            return
        hidden = [p.name for p in self.path.iterdir()
                  if p.name in (OWNER_FILE, self.lock_name)
                  or p.name.startswith((STAGE_PREFIX, PREVIOUS_PREFIX, ".replaced."))]
        for name in [*hidden, *names]:
            if (self.path / name).is_symlink():
                raise _link_refused(self.path / name, self._what(name))

    def _what(self, name: str) -> str:
        """What the entry ``name`` of the output folder is, for messages."""
        if name == self.lock_name:
            return "the lock of comems4build"
        if name == OWNER_FILE:
            return "comems4build's record of its outputs"
        if name.startswith(STAGE_PREFIX):
            return "a result comems4build is writing"
        if name.startswith(PREVIOUS_PREFIX):
            return "an earlier result comems4build kept aside"
        if name.startswith(".replaced."):
            return "an earlier result comems4build is removing"
        return "a result of comems4build"

    # -- lock
    def _lock(self) -> None:
        import fcntl

        lock = self.path / self.lock_name
        dfd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            self._lock_at(dfd, lock, fcntl)
        finally:
            os.close(dfd)

    def _lock_at(self, dfd: int, lock: Path, fcntl: Any) -> None:
        """:meth:`_lock` with the output folder's descriptor: the lock file is opened relative to it,
        never through a link, mode 0600, and only a file of this user with one name is written."""
        for _ in range(100):
            try:
                fd = os.open(self.lock_name, os.O_RDWR | os.O_CREAT | _NOFOLLOW, PRIVATE_FILE_MODE, dir_fd=dfd)
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    raise _link_refused(lock, "the lock of comems4build") from None
                raise
            try:
                for attempt in range(5):  # another command's check (_probe_lock) holds it for microseconds
                    try:
                        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                        break
                    except BlockingIOError:
                        if attempt == 4:
                            raise
                        time.sleep(0.01)
            except BlockingIOError:
                try:
                    holder = os.read(fd, 512).decode("utf-8", "replace").strip() or "another command"
                finally:
                    os.close(fd)
                raise OutputInUseError(f"{self.option} {self.path}: in use by {holder}; wait until it ends or choose "
                                       f"another {self.option}") from None
            try:  # not a lock file its holder just removed
                same = os.fstat(fd).st_ino == os.stat(self.lock_name, dir_fd=dfd, follow_symlinks=False).st_ino
            except FileNotFoundError:
                same = False
            if same:
                try:
                    _own(fd, lock, "the lock of comems4build", True, False)
                except BaseException:
                    os.close(fd)
                    raise
                self._lock_fd = fd  # held: removed again by _unlock, even if the line below finds the disk full
                os.ftruncate(fd, 0)
                os.write(fd, f"comems4build {self.command} (pid {os.getpid()})\n".encode())
                return
            os.close(fd)
        raise OutputInUseError(f"{self.option} {self.path}: its lock {lock} keeps changing")

    def _unlock(self) -> None:
        if self._lock_fd is None:
            return
        with contextlib.suppress(OSError):
            if os.fstat(self._lock_fd).st_ino == os.stat(self.path / self.lock_name, follow_symlinks=False).st_ino:
                os.unlink(self.path / self.lock_name)
        os.close(self._lock_fd)
        self._lock_fd = None

    # -- context
    def __enter__(self) -> OutputDir:
        check_out_dir(self.path, self.option)
        check_not_input(self.path, self.inputs, self.option, self.writes)
        self._created = not self.path.exists()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self._lock()
            self._check_no_links()
            for stale in [*self.path.glob(f"{STAGE_PREFIX}*"), *self.path.glob(".replaced.*")]:  # of a killed command
                shutil.rmtree(stale, ignore_errors=True)
            self._restore_killed()
            self._check_owned(self._existing(self.writes))
            if self.in_place:
                previous = Path(tempfile.mkdtemp(prefix=PREVIOUS_PREFIX, dir=self.path))
                aside = self._existing(self.writes)
                try:
                    with _signals_held():
                        for name in aside:  # owned (checked): the earlier result, kept aside
                            os.replace(self.path / name, previous / name)
                        self._write_owner(set(read_owner(self.path).get("entries", [])) - set(aside))
                except BaseException:
                    for entry in list(previous.iterdir()):
                        os.replace(entry, self.path / entry.name)
                    shutil.rmtree(previous, ignore_errors=True)
                    raise
                self._previous = previous
                self.stage = self.path
            else:
                self.stage = Path(tempfile.mkdtemp(prefix=STAGE_PREFIX, dir=self.path))
        except BaseException as exc:
            self._abandon()
            if isinstance(exc, OSError) and not isinstance(exc, OutputPathError):
                raise _named(exc, self.path) from exc
            raise
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if exc_type is not None:
            self._abandon()
            if isinstance(exc, OSError) and not isinstance(exc, OutputPathError):
                raise self._named(exc) from exc  # a full disk while writing the stage: named as its destination
            return
        self.commit()
        self._unlock()

    def _named(self, exc: OSError) -> OSError:
        """``exc`` naming the file of the result it was writing (not the stage), or the output folder."""
        name = str(exc.filename or "")
        stage = str(self.stage)
        if name and self.stage != Path() and not self.in_place and name.startswith(stage + os.sep):
            return OSError(exc.errno, exc.strerror or str(exc), str(self.path / name[len(stage) + 1:]))
        return _named(exc, self.path)

    def commit(self) -> None:
        """Put the stage's entries in place now (once; the lock is kept until the block ends)."""
        if self._committed:
            return
        try:
            self._commit()
        except BaseException as err:
            self._abandon()
            if isinstance(err, OSError) and not isinstance(err, OutputPathError):
                raise _named(err, self.path) from err
            raise
        self._committed = True

    def previous_entries(self, pattern: str = "*") -> list[Path]:
        """The entries of the earlier result an in-place command keeps aside (matching ``pattern``)."""
        if self._previous is None:
            return []
        return sorted(self._previous.glob(pattern))

    def _restore_killed(self) -> None:
        """Put back an earlier result that an in-place command killed meanwhile had moved aside.

        What that command wrote is not in the ownership record (it never finished): it goes.
        """
        owned = set(read_owner(self.path).get("entries", []))
        previous_dirs = sorted(self.path.glob(f"{PREVIOUS_PREFIX}*"))
        for previous in previous_dirs:
            # this user's folder, opened without following a link: its entries move back by descriptor
            pfd = open_dir(previous, private=True, what="an earlier result comems4build kept aside")
            try:
                for name in sorted(os.listdir(pfd)):
                    dest = self.path / name
                    if (dest.exists() or dest.is_symlink()) and name not in owned:
                        _remove(dest)
                    if not (dest.exists() or dest.is_symlink()):
                        os.replace(name, dest, src_dir_fd=pfd)
                        owned.add(name)
            finally:
                os.close(pfd)
            shutil.rmtree(previous, ignore_errors=True)
        if previous_dirs:
            self._write_owner(owned)

    def _write_owner(self, entries: Iterable[str]) -> None:
        """Write the ownership record: ``entries`` (as far as they exist)."""
        import json

        present = set(self._existing(("*",)))
        owned = sorted(set(entries) & present)
        if not owned and self._created:  # a directory this command made and leaves empty: no record either
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path / OWNER_FILE)
            return
        record = {"written_by": f"comems4build {self.command}", "entries": owned,
                  "note": "entries comems4build wrote here and may replace; nothing else is touched"}
        write_text_atomic(self.path / OWNER_FILE, json.dumps(record, indent=1) + "\n", private=True)

    def _abandon(self) -> None:
        """Remove the stage (and the directory if this command created it and it is empty); unlock."""
        if self.in_place and self._previous is not None and not self._committed:
            for name in self._existing(self.writes):  # written by this command (the earlier result is aside)
                _remove(self.path / name)
            back = [entry.name for entry in self._previous.iterdir()]
            for name in back:
                os.replace(self._previous / name, self.path / name)
            shutil.rmtree(self._previous, ignore_errors=True)
            self._previous = None
            self._write_owner(set(read_owner(self.path).get("entries", [])) | set(back))
        elif self.stage != Path() and not self._committed and not self.in_place:
            shutil.rmtree(self.stage, ignore_errors=True)
        self._unlock()
        if self._created:
            with contextlib.suppress(OSError):
                self.path.rmdir()  # only if empty

    def _commit(self) -> None:

        if self.in_place:
            self._write_owner(set(self._existing(self.writes)) | set(read_owner(self.path).get("entries", [])))
            if self._previous is not None:  # the new result stands: the earlier one goes
                shutil.rmtree(self._previous, ignore_errors=True)
                self._previous = None
            return

        names = sorted(p.name for p in self.stage.iterdir())
        self._check_owned([n for n in names if (self.path / n).exists() or (self.path / n).is_symlink()])
        check_not_input(self.path, self.inputs, self.option, names or ("",))
        owned = set(read_owner(self.path).get("entries", []))
        stale = [n for n in self._existing(self.replaces) if n not in names and n in owned]
        trash = Path(tempfile.mkdtemp(prefix=".replaced.", dir=self.path))
        placed: list[tuple[str, bool]] = []  # (name, an older entry went to the trash)
        removed: list[str] = []
        try:
            with _signals_held():  # Ctrl-C waits for the few renames; any other failure undoes them
                for name in names:
                    src, dest = self.stage / name, self.path / name
                    had = dest.exists() or dest.is_symlink()
                    if had:
                        os.replace(dest, trash / name)  # a directory is replaced whole
                    placed.append((name, had))
                    os.replace(src, dest)
                for name in stale:
                    os.replace(self.path / name, trash / name)
                    removed.append(name)
                self._write_owner((owned | set(names)) - set(stale))
        except BaseException:
            for name in removed:
                os.replace(trash / name, self.path / name)
            for name, had in reversed(placed):
                dest = self.path / name
                if not (self.stage / name).exists() and (dest.exists() or dest.is_symlink()):
                    os.replace(dest, self.stage / name)  # the new entry out again
                if had:
                    os.replace(trash / name, dest)
            raise
        finally:
            shutil.rmtree(trash, ignore_errors=True)
        shutil.rmtree(self.stage, ignore_errors=True)


class OutputFile(OutputDir):
    """One output file written all or nothing through an :class:`OutputDir` of its directory.

    The file's directory gets the ownership record (the file is its one entry this command
    writes); the lock is the file's own (``.<name>.comems4build.lock``), so commands writing
    other files of the same directory do not wait for each other. Write to :attr:`file`.
    """

    def __init__(self, path: str | os.PathLike[str], command: str, option: str = "--out",
                 inputs: Mapping[str, Iterable[str | os.PathLike[str]]] | None = None) -> None:
        target = check_out_text(path, option)
        check_out_file(target, option)
        super().__init__(target.parent, command, option, inputs, writes=(target.name,))
        self.target = target
        self.lock_name = f".{target.name}.comems4build.lock"

    @property
    def file(self) -> Path:
        """Where to write the file (inside the stage)."""
        return self.stage / self.target.name

    def check(self) -> None:
        """The checks of entry without creating or locking anything (:class:`OutputPathError`)."""
        check_out_file(self.target, self.option)
        self._check_inputs()
        super().check()

    def _check_inputs(self) -> None:
        real = _real(self.target)
        for role, paths in self.inputs.items():
            for p in paths:
                if _real(p) == real:
                    raise OutputPathError(f"{self.option} {self.target} is the input {role} {p}: the result would "
                                          "overwrite it; choose another output file")

    def __enter__(self) -> OutputFile:
        check_out_file(self.target, self.option)
        self._check_inputs()
        super().__enter__()
        return self
