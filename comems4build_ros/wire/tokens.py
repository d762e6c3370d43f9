"""Run tokens of ``ems/command``: which EMS a command comes from (no rclpy here).

Every command carries, as its last element, a token of the EMS that sent it; the lock-step
master applies the commands of one EMS only and counts every other command as foreign.
Two modes:

* **run secret** (what the launcher uses): one secret per house, drawn by
  :func:`new_token` and given to that house's EMS and plant in a token file
  (:func:`write_token_file`: mode 0600 in a directory of mode 0700; parameters
  ``run_token_file`` and ``ems_token_file``), never on a command line, in a parameter
  value, a log line or a world-readable file. The token of each command is then its authentication code
  (:func:`command_mac`: HMAC-SHA256 of the command's other elements under the secret, 48
  bits), so a command seen on the wire (DDS carries it in clear) authorises nothing but
  itself: another step or other values need the secret.
* **plain token** (by hand, ``run_token`` / ``ems_token``, or none): the same number in
  every command; the plant applies ``ems_token`` or else the token of the run's first
  valid command. This keeps a second EMS from steering the plant by mistake, not an
  adversary (the number is on the command line and in every command). An EMS started
  without any token derives one from its node name, so a restarted EMS keeps its token.
"""

from __future__ import annotations

import contextlib
import errno
import hmac
import os
import secrets
import stat
import zlib
from array import array
from collections.abc import Sequence
from pathlib import Path

from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import parse_integer


class TokenFileError(InputError):
    """A run token file that cannot be trusted or read; names the file."""


#: Tokens are integers in 1 .. MAX_TOKEN - 1 (exact in float64).
MAX_TOKEN = 2**53


#: Bytes of the authentication code a command carries in run-secret mode (48 bits: exact in float64).
MAC_BYTES = 6


def command_mac(secret: bytes, values: bytes) -> float:
    """Compute the authentication code of a command (run-secret mode).

    The first :data:`MAC_BYTES` of HMAC-SHA256 of ``values`` under ``secret``.

    Parameters
    ----------
    secret : bytes
        HMAC key (:func:`secret_key`).
    values : bytes
        The float64 bytes of every element of the command but the token.

    Returns
    -------
    float
        The code as a token: an integer in 1 .. 2^48 - 1, exact in float64.
    """
    code = int.from_bytes(hmac.digest(secret, values, "sha256")[:MAC_BYTES], "big")
    return float(code or 1)


def secret_key(token: int) -> bytes:
    """Return the HMAC key of a run secret read from a token file.

    Parameters
    ----------
    token : int
        The run secret.

    Returns
    -------
    bytes
        Its decimal digits in ASCII.
    """
    return str(int(token)).encode("ascii")


def default_token(fully_qualified_name: str) -> int:
    """Return the token of an EMS started without one: CRC-32 of its fully qualified node name + 1.

    Parameters
    ----------
    fully_qualified_name : str
        The node's name with its namespace.

    Returns
    -------
    int
        The token, 1 .. 2^32.
    """
    return zlib.crc32(fully_qualified_name.encode("utf-8")) + 1


def new_token() -> int:
    """Draw a random run secret for one house of a launch.

    Returns
    -------
    int
        The secret, 1 .. 2^53 - 1 (from :mod:`secrets`).
    """
    return secrets.randbelow(MAX_TOKEN - 1) + 1


def private_dir(path: str | Path) -> Path:
    """Create ``path`` (and parents) if needed and make it accessible to this user only (mode 0700).

    The folder itself is never followed if it is a symbolic link (refused, named).

    Parameters
    ----------
    path : str or pathlib.Path
        The directory.

    Returns
    -------
    pathlib.Path
        The directory.

    Raises
    ------
    ValueError
        If it exists and belongs to another user, or is a link
        (:class:`~comems4build_ros.files.outputs.OutputPathError`).
    """
    from comems4build_ros.files.outputs import open_dir

    p = Path(path)
    os.close(open_dir(p, create=True, private=True, what="a folder for run secrets"))
    return p


def write_token_file(path: str | Path, token: int) -> Path:
    """Write a token to a file readable by this user only, in a :func:`private_dir`.

    The file has mode 0600 from its creation on: never world-readable, not even for a
    moment. It is created new (``O_EXCL``, never through a link): an earlier file of the
    name is removed first.

    Parameters
    ----------
    path : str or pathlib.Path
        The token file (replaced if present).
    token : int
        The token.

    Returns
    -------
    pathlib.Path
        The token file.
    """
    from comems4build_ros.files.outputs import open_dir, write_new_file

    p = Path(path)
    private_dir(p.parent)
    dfd = open_dir(p.parent, private=True, what="a folder for run secrets")
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(p.name, dir_fd=dfd)  # the name only (a link is removed, not what it names)
    finally:
        os.close(dfd)
    write_new_file(p, f"{int(token)}\n", private=True, what="a run token file")
    return p


def read_token_file(path: str | Path) -> int:
    """Read the token in a token file (see :func:`write_token_file`).

    Parameters
    ----------
    path : str or pathlib.Path
        The token file.

    Returns
    -------
    int
        The token, 1 .. 2^53 - 1.

    Raises
    ------
    TokenFileError
        Naming the file: a link, another user's, unreadable, readable or writable by group or others (a secret
        others can read protects nothing), or not an integer in 1 .. 2^53 - 1.
    """
    p = Path(path)
    try:  # the file itself, never what a link names (a link could hand over a token others know)
        fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError as exc:
        why = "a symbolic link (a token file is never read through a link)" if exc.errno == errno.ELOOP else exc
        raise TokenFileError(f"token file {p}: {why}") from None
    try:
        with os.fdopen(fd, "rb") as fh:
            st = os.fstat(fh.fileno())
            mode = st.st_mode
            text = fh.read(64).decode("ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise TokenFileError(f"token file {p}: {exc}") from None
    if st.st_uid != os.geteuid():
        raise TokenFileError(f"token file {p}: belongs to another user (uid {st.st_uid}); a run secret must be this "
                             "user's")
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise TokenFileError(f"token file {p}: mode {stat.filemode(mode)} lets other users read or change it; "
                         "give it mode 0600")
    try:
        token = parse_integer(text)
    except ValueError:
        raise TokenFileError(f"token file {p}: not an integer") from None
    if not 0 < token < MAX_TOKEN:
        raise TokenFileError(f"token file {p}: not in 1 .. 2^53-1")
    return token


def sign(key: bytes | None, values: array) -> array:
    """Append the token to ``values`` (float64, every element but the token).

    The token is the authentication code under ``key`` (:func:`command_mac`), or 0 without a
    key (nodes started by hand without a secret). The messages between a community's
    coordinator and its houses (``hub/*``) are signed so, each under its house's hub secret.
    """
    out = array("d", values)
    out.append(command_mac(key, values.tobytes()) if key is not None else 0.0)
    return out


def authentic(key: bytes | None, data: Sequence[float]) -> bool:
    """Tell whether the message ``data`` (its token last) carries the authentication code of the rest.

    The code is taken under ``key``; without a key every message is authentic.
    """
    if key is None:
        return True
    return data[-1] == command_mac(key, array("d", data[:-1]).tobytes())
