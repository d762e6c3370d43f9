"""A run's full specification, its hash, and the environment the run depends on.

A stored run belongs to a study when its specification hash equals the hash of the run the
study would make now. The specification is everything that decides a run's outputs: the
run's own settings (EMS, scenario, window, seed, overrides, options), the contents of the
files it reads from outside the package (``--config`` files, a scenario CSV, by SHA-256),
and the :func:`environment` record: the package version, a digest of the package's code,
data and default parameter files (``config/``), and the versions of Python and of the
numerical libraries. So a change of code, of a shipped parameter or of a library makes the
stored runs another study's, and :func:`differences` says which part changed.

The same record decides whether a Dask worker may run a study's runs: a worker whose
environment differs from the client's would give other results
(:func:`comems4build_ros.study.pool.check_environment`).
"""

from __future__ import annotations

import functools
import hashlib
import json
import platform
import sys
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

from comems4build_ros.files.paths import PACKAGE_DIR

#: Libraries whose version is part of the environment record (numerical results depend on them).
LIBRARIES = ("numpy", "scipy", "pandas", "scikit-fuzzy", "PuLP", "highspy", "osqp", "pvlib", "holidays")
#: File suffixes left out of the code digest (byte code differs between installs of the same source).
SKIPPED_SUFFIXES = (".pyc", ".pyo")


def _tree_digest(root: Path) -> str:
    """SHA-256 over the relative paths and contents of every file under ``root`` (sorted)."""
    h = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.is_file()):
        rel = path.relative_to(root)
        if "__pycache__" in rel.parts or path.suffix in SKIPPED_SUFFIXES:
            continue
        h.update(rel.as_posix().encode())
        h.update(b"\0")
        h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def environment() -> dict[str, Any]:
    """The record of what a run's results depend on besides its own settings (cached per process).

    ``package``: version of comems4build_ros; ``code``: digest of the package directory
    (modules and shipped data); ``config``: digest of the default parameter files
    (:func:`comems4build_ros.core.config.config_dir`); ``python``: major.minor version; one entry
    per library of :data:`LIBRARIES`: its version.
    """
    from comems4build_ros import __version__
    from comems4build_ros.core.config import config_dir

    record: dict[str, Any] = {
        "package": __version__,
        "code": _tree_digest(PACKAGE_DIR),
        "config": _tree_digest(config_dir()),
        "python": ".".join(platform.python_version_tuple()[:2]),
        "implementation": sys.implementation.name,
    }
    record.update({lib: _version(lib) for lib in LIBRARIES})
    return record


def file_digest(data: bytes) -> str:
    """SHA-256 of a file's contents (hex)."""
    return hashlib.sha256(data).hexdigest()


def spec_hash(spec: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of a specification (sorted keys, no spaces)."""
    text = json.dumps(spec, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def differences(stored: Mapping[str, Any], now: Mapping[str, Any], prefix: str = "") -> list[str]:
    """The entries where two specifications differ, as ``key: stored -> now`` (nested keys dotted)."""
    out = []
    for key in sorted(set(stored) | set(now), key=str):
        name = f"{prefix}{key}"
        a, b = stored.get(key, "<absent>"), now.get(key, "<absent>")
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            out += differences(a, b, f"{name}.")
        elif a != b:
            out.append(f"{name}: {_short(a)} -> {_short(b)}")
    return out


def _short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, default=str)
    return text if len(text) <= 60 else text[:57] + "..."
