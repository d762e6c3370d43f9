"""On-disk cache of the results of pvlib (the only parts of a scenario that need it).

Two steps of building a scenario call pvlib: the modelled radiation
(:func:`comems4build_ros.scenario.generator._solar`: Ineichen clear sky, solar position,
Erbs decomposition) and the plane-of-array irradiance of the PV array
(:func:`comems4build_ros.models.pv.poa_irradiance_w_m2`: DNI, Perez transposition). Each
takes about 0.1 s, but importing pvlib takes 0.5 to 0.8 s (it imports all of its
subpackages, among them SciPy's ``integrate``). That import was the longest part of a
``feed`` node's start-up, and every node process, study worker and ``simulate`` call that
builds a scenario paid it again.

:func:`cached` stores a result under a key that covers everything it depends on: the input
arrays (bytes), the parameters (site, PV array, model names), the versions of pvlib, NumPy,
pandas and this package, and :data:`CACHE_FORMAT`. A hit returns bit-identical arrays (a
test checks it against pvlib).

Location: the environment variable ``COMEMS4BUILD_CACHE_DIR``; without it
``$XDG_CACHE_HOME/comems4build_ros`` (default ``~/.cache/comems4build_ros``, the directory
of the live-input cache too). ``COMEMS4BUILD_CACHE_DIR=off`` switches the cache off. A
damaged or foreign file is ignored and written anew; a directory that cannot be written only
means that each call computes again: no result depends on the cache.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import zipfile
from collections.abc import Callable, Sequence
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

#: Environment variable of the cache directory (``off``: no cache).
CACHE_ENV = "COMEMS4BUILD_CACHE_DIR"
#: Raised when a computation behind a cached result changes, so that old files are not used.
CACHE_FORMAT = 1
_OFF = ("off", "0", "no", "none", "")


def cache_dir() -> Path | None:
    """Directory of the cache files, or None when the cache is switched off."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in _OFF else Path(value)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "comems4build_ros"


@cache
def _versions() -> tuple[str, ...]:
    out = []
    for dist in ("pvlib", "numpy", "pandas", "comems4build_ros"):
        try:
            out.append(f"{dist}={metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            out.append(f"{dist}=?")
    return tuple(out)


def key_of(kind: str, params: dict[str, Any], inputs: Sequence[np.ndarray]) -> str:
    """Hex digest naming the result of ``kind`` for ``params`` and the arrays ``inputs``."""
    head = json.dumps({"format": CACHE_FORMAT, "kind": kind, "params": params, "versions": _versions()},
                      sort_keys=True, default=str)
    h = hashlib.sha256(head.encode())
    for arr in inputs:
        a = np.ascontiguousarray(arr)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _path(kind: str, key: str) -> Path | None:
    d = cache_dir()
    return None if d is None else d / f"pvlib-{kind}-{key[:40]}.npz"


def load(kind: str, key: str, n: int) -> tuple[np.ndarray, ...] | None:
    """The cached arrays of ``key`` (each of length ``n``), or None (no file, a different
    key, a damaged file)."""
    path = _path(kind, key)
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"]) != key:
                return None
            count = int(data["count"])
            out = tuple(np.array(data[f"a{i}"], dtype=float) for i in range(count))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if any(a.shape != (n,) for a in out):
        return None
    return out


def store(kind: str, key: str, arrays: Sequence[np.ndarray]) -> bool:
    """Write ``arrays`` under ``key`` atomically (a reader never sees half a file); False when
    the cache is off or its directory cannot be written."""
    path = _path(kind, key)
    if path is None:
        return False
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".pvlib-{kind}-", suffix=".npz", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                named = {f"a{i}": np.asarray(a, dtype=float) for i, a in enumerate(arrays)}
                np.savez(fh, key=np.array(key), count=np.array(len(arrays)), **named)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError:
        return False
    return True


def cached(kind: str, params: dict[str, Any], inputs: Sequence[np.ndarray], n: int,
           compute: Callable[[], tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    """``compute()`` (arrays of length ``n``), or its result stored earlier for the same
    ``kind``, ``params`` and ``inputs``."""
    key = key_of(kind, params, inputs)
    hit = load(kind, key, n)
    if hit is not None:
        return hit
    result = tuple(np.asarray(a, dtype=float) for a in compute())
    store(kind, key, result)
    return result
