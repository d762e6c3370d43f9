"""On-disk cache of results that need a heavy library: pvlib, SciPy's ``expm``, ``holidays``.

Each of these results takes milliseconds to compute, but the library behind it takes much
longer to import, and every node process, study worker and ``simulate`` call paid that
import again:

* the modelled radiation (:func:`comems4build_ros.core.scenario.generator._solar`: Ineichen clear
  sky, solar position, Erbs decomposition) and the plane-of-array irradiance of the PV array
  (:func:`comems4build_ros.core.models.pv.poa_irradiance_w_m2`: DNI, Perez transposition):
  importing pvlib takes 0.5 to 0.8 s (it imports all of its subpackages, among them SciPy's
  ``integrate``), the longest part of a ``feed`` node's start-up;
* the building's zero-order-hold discretisation (:func:`comems4build_ros.core.models.building.discretize`,
  ``eq:state_update_bldgs``): SciPy's ``linalg`` takes about 0.1 s to import, in ``plant_sim``;
* the check that the ``holidays`` library knows the comfort calendar
  (:func:`comems4build_ros.core.config.check_holiday_calendar`): ``holidays`` imports every
  country's calendar to find one (0.1 s), in every process that checks the plant
  parameters.

:func:`cached` stores a result under a key that covers everything it depends on: the input
arrays (bytes), the parameters, the versions of the libraries it comes from and of this
package, and :data:`CACHE_FORMAT`. A hit returns bit-identical arrays (tests check them
against the libraries). Only results are stored: a failing computation (an unknown holiday
calendar) raises each time.

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
import zipfile
from collections.abc import Callable, Sequence
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from comems4build_ros.files.outputs import atomic_write, open_dir

#: Environment variable of the cache directory (``off``: no cache).
CACHE_ENV = "COMEMS4BUILD_CACHE_DIR"
#: Raised when a computation behind a cached result changes, so that old files are not used.
CACHE_FORMAT = 3
_OFF = ("off", "0", "no", "none", "")
#: Distributions a pvlib result depends on.
PVLIB_DISTS = ("pvlib", "numpy", "pandas")


def cache_dir() -> Path | None:
    """Return the directory of the cache files.

    Returns
    -------
    pathlib.Path or None
        ``$COMEMS4BUILD_CACHE_DIR``, else ``$XDG_CACHE_HOME/comems4build_ros`` (default
        ``~/.cache/comems4build_ros``); None when the cache is switched off.
    """
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in _OFF else Path(value)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "comems4build_ros"


@cache
def versions(dists: tuple[str, ...]) -> tuple[str, ...]:
    """Return the installed versions of the distributions a result depends on.

    Parameters
    ----------
    dists : tuple of str
        Distribution names (e.g. :data:`PVLIB_DISTS`).

    Returns
    -------
    tuple of str
        ``name=version`` of each distribution in ``dists`` and of this package, ``name=?``
        for one that is not installed.
    """
    out = []
    for dist in (*dists, "comems4build_ros"):
        try:
            out.append(f"{dist}={metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            out.append(f"{dist}=?")
    return tuple(out)


def key_of(kind: str, params: dict[str, Any], inputs: Sequence[np.ndarray], dists: Sequence[str] = ()) -> str:
    """Return the key of a result: a digest of everything the result depends on.

    Parameters
    ----------
    kind : str
        Name of the computation (also the cache file's prefix).
    params : dict
        Its parameters (JSON-serialisable; other values by ``str``).
    inputs : sequence of numpy.ndarray
        Its input arrays (dtype, shape and bytes enter the key).
    dists : sequence of str, optional
        Distributions whose versions the result depends on (see :func:`versions`).

    Returns
    -------
    str
        SHA-256 hex digest of :data:`CACHE_FORMAT`, ``kind``, ``params``, the versions and
        the arrays.
    """
    head = json.dumps({"format": CACHE_FORMAT, "kind": kind, "params": params, "versions": versions(tuple(dists))},
                      sort_keys=True, default=str)
    h = hashlib.sha256(head.encode())
    for arr in inputs:
        a = np.ascontiguousarray(arr)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _path(kind: str, key: str) -> Path | None:
    """Return the file of ``key``, or None when the cache is off."""
    d = cache_dir()
    return None if d is None else d / f"{kind}-{key[:40]}.npz"


def load(kind: str, key: str, shape: tuple[int, ...] | None = None) -> tuple[np.ndarray, ...] | None:
    """Read the arrays stored under a key.

    Parameters
    ----------
    kind : str
        Name of the computation.
    key : str
        Key from :func:`key_of`.
    shape : tuple of int, optional
        Shape every array must have; a file with another shape counts as a miss.

    Returns
    -------
    tuple of numpy.ndarray or None
        The stored float arrays, or None when there is no file, it holds another key or
        shape, or it is damaged.
    """
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
    if shape is not None and any(a.shape != shape for a in out):
        return None
    return out


def store(kind: str, key: str, arrays: Sequence[np.ndarray]) -> bool:
    """Write arrays under a key atomically (a reader never sees half a file).

    Parameters
    ----------
    kind, key : str
        As for :func:`load`.
    arrays : sequence of numpy.ndarray
        Results, stored as float arrays.

    Returns
    -------
    bool
        True if written; False when the cache is off or its directory cannot be written.
    """
    path = _path(kind, key)
    if path is None:
        return False
    named = {f"a{i}": np.asarray(a, dtype=float) for i, a in enumerate(arrays)}
    try:
        os.close(open_dir(path.parent, create=True, private=True, what="the result cache"))
        with atomic_write(path, "wb", private=True) as fh:
            np.savez(fh, key=np.array(key), count=np.array(len(arrays)), **named)
    except OSError:
        return False
    return True


def cached(kind: str, params: dict[str, Any], inputs: Sequence[np.ndarray],
           compute: Callable[[], Sequence[np.ndarray]], *, dists: Sequence[str] = (),
           shape: tuple[int, ...] | None = None) -> tuple[np.ndarray, ...]:
    """Return a computation's result from the cache, computing and storing it on a miss.

    Parameters
    ----------
    kind : str
        Name of the computation.
    params : dict
        Its parameters (part of the key).
    inputs : sequence of numpy.ndarray
        Its input arrays (part of the key).
    compute : callable
        Computes the result when it is not cached: a sequence of arrays.
    dists : sequence of str, optional
        Distributions whose versions the result depends on.
    shape : tuple of int, optional
        Shape every array must have.

    Returns
    -------
    tuple of numpy.ndarray
        ``compute()`` as float arrays, or the same result stored earlier for the same
        ``kind``, ``params``, ``inputs`` and versions (bit-identical).
    """
    key = key_of(kind, params, inputs, dists)
    hit = load(kind, key, shape)
    if hit is not None:
        return hit
    result = tuple(np.asarray(a, dtype=float) for a in compute())
    store(kind, key, result)
    return result
