"""Which defaults a study ran: the commit of the source tree and content hashes of the code and parameters.

A validation step records what it judged (:func:`defaults_identity`): the git commit of the
checkout the package runs from (with whether its code or ``config/`` had uncommitted
changes), and, whether or not the code is in git, a content hash of the simulation code
(``comems4build_ros/core``, the plant, the EMS and the scenarios) and one of the default
parameters (``config/``). The parameter hash leaves out what does not change a run: the
comments of every file (the files are hashed as parsed), the prose of the reproduction study
(``title``, ``source``, ``reason``, ``text``) and the evaluation's own settings (the
validation's ``criteria``, the reproduction's ``targets``); so a reworded reason or a changed
check keeps the hash of the defaults it judges.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

#: Keys of ``config/reproduce.yaml`` that are prose, not a setting of any run.
PROSE_KEYS = frozenset({"title", "source", "reason", "text"})
#: Per parameter file, the sections that only the evaluation reads.
EVALUATION_SECTIONS = {"validation.yaml": ("validation", "criteria"), "reproduce.yaml": ("reproduce", "targets")}


def _strip(value: Any, prose: bool) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _strip(v, prose) for k, v in value.items() if not (prose and k in PROSE_KEYS)}
    if isinstance(value, list):
        return [_strip(v, prose) for v in value]
    return value


def _drop(data: Any, path: tuple[str, ...]) -> Any:
    """``data`` without the section ``path`` (looked for under every top-level key, as the ROS 2 form nests it)."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    if len(path) == 1:
        out.pop(path[0], None)
        return out
    for k, v in out.items():
        if k == path[0]:
            out[k] = _drop(v, path[1:])
        elif isinstance(v, dict):
            out[k] = _drop(v, path)
    return out


def parameters_sha256(config: Path) -> str:
    """SHA-256 of the default parameters under ``config`` as parsed, without prose and evaluation settings."""
    h = hashlib.sha256()
    for path in sorted(p for p in config.rglob("*") if p.is_file()):
        rel = path.relative_to(config).as_posix()
        h.update(rel.encode() + b"\0")
        if path.suffix in (".yaml", ".yml"):
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
            data = _strip(data, prose=path.name == "reproduce.yaml")
            if path.name in EVALUATION_SECTIONS:
                data = _drop(data, EVALUATION_SECTIONS[path.name])
            h.update(json.dumps(data, sort_keys=True, default=str).encode())
        else:
            h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def code_sha256(package: Path) -> str:
    """SHA-256 of the Python files of the simulation code (``core/``) of the package at ``package``."""
    h = hashlib.sha256()
    core = package / "core"
    for path in sorted(core.rglob("*.py")):
        h.update(path.relative_to(core).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def _git(root: Path, *args: str) -> str | None:
    try:
        res = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return res.stdout.strip() if res.returncode == 0 else None


def defaults_identity() -> dict[str, Any]:
    """What the runs of this process are made with.

    Returns
    -------
    dict
        ``git_commit`` (the checkout's HEAD, None when the package is installed or git is
        missing), ``git_dirty`` (uncommitted changes to ``comems4build_ros/`` or ``config/``;
        None without git), ``code_sha256`` (:func:`code_sha256`), ``parameters_sha256``
        (:func:`parameters_sha256`) and ``config_dir``.
    """
    import comems4build_ros
    from comems4build_ros.core.config import SOURCE_ROOT, config_dir

    package = Path(comems4build_ros.__file__).resolve().parent
    config = config_dir()
    commit = dirty = None
    if (Path(SOURCE_ROOT) / ".git").exists() and package.parent == Path(SOURCE_ROOT).resolve():
        commit = _git(Path(SOURCE_ROOT), "rev-parse", "HEAD")
        status = _git(Path(SOURCE_ROOT), "status", "--porcelain", "--", "comems4build_ros", "config")
        dirty = None if status is None else bool(status)
    return {"git_commit": commit, "git_dirty": dirty, "code_sha256": code_sha256(package),
            "parameters_sha256": parameters_sha256(config), "config_dir": str(config)}


def same_defaults(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> bool:
    """Two identities describe the same runs: the same simulation code and default parameters."""
    return bool(a and b and a.get("code_sha256") == b.get("code_sha256")
                and a.get("parameters_sha256") == b.get("parameters_sha256"))
