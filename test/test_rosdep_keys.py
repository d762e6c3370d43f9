"""Every ``package.xml`` key resolves with rosdep on Ubuntu 24.04 (noble) for ROS 2 Jazzy.

rosdep resolves a dependency name if it is a ROS package released for Jazzy (rosdistro's
``jazzy/distribution.yaml``) or a key of its ``rosdep/base.yaml`` or ``rosdep/python.yaml`` with
an installer entry for Ubuntu noble (a Debian package, or pip); anything else makes ``rosdep
install`` fail ("Cannot locate rosdep definition"). The three files are read from the folder
``COMEMS4BUILD_ROSDEP`` (default: ``rosdep`` in the ``shared`` folder beside the repository, copies
of rosdistro's files); the test skips, saying why, where they are absent.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
#: Folder of rosdistro's key files; overridable by this variable.
ROSDEP_ENV = "COMEMS4BUILD_ROSDEP"
KEY_FILES = ("base.yaml", "python.yaml", "jazzy-distribution.yaml")
#: Ubuntu release of ROS 2 Jazzy (REP 2000).
CODENAME = "noble"
#: The tags of package.xml (format 3) that name dependencies rosdep resolves.
DEPEND_TAGS = ("depend", "build_depend", "build_export_depend", "buildtool_depend", "exec_depend", "test_depend",
               "doc_depend")
#: rosdep's installers whose entries name packages (``apt`` is Ubuntu's default).
INSTALLERS = ("apt", "pip")


def key_folder() -> Path:
    """Where rosdistro's key files are looked for."""
    return Path(os.environ.get(ROSDEP_ENV) or REPO.parent / "shared" / "rosdep")


@pytest.fixture(scope="module")
def key_files() -> dict[str, Any]:
    """The three key files, parsed (the test skips without them)."""
    folder = key_folder()
    missing = [name for name in KEY_FILES if not (folder / name).is_file()]
    if missing:
        pytest.skip(f"rosdep's key files {', '.join(missing)} are not in {folder} (set {ROSDEP_ENV} to a folder "
                    "holding rosdistro's rosdep/base.yaml, rosdep/python.yaml and jazzy/distribution.yaml as "
                    f"{', '.join(KEY_FILES)})")
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # the C parser: the files are large
    return {name: yaml.load((folder / name).read_text(encoding="utf-8"), Loader=loader) for name in KEY_FILES}


def jazzy_packages(distribution: dict[str, Any]) -> set[str]:
    """The ROS packages released for Jazzy: each repository's released packages (the repository's
    own name when its release lists none)."""
    out: set[str] = set()
    for name, repo in (distribution.get("repositories") or {}).items():
        release = (repo or {}).get("release")
        if release:
            out.update(release.get("packages") or [name])
    return out


def names_packages(entry: Any) -> bool:
    """Whether an installer entry names something to install: a non-empty list of packages, or a
    mapping of an installer (``apt``, ``pip``) or ``packages`` to one."""
    if isinstance(entry, list):
        return bool(entry)
    if isinstance(entry, dict):
        if "packages" in entry:
            return names_packages(entry["packages"])
        return any(names_packages(entry[i]) for i in INSTALLERS if i in entry)
    return False


def resolves_on_ubuntu(rule: Any, codename: str = CODENAME) -> bool:
    """Whether a key's rule installs something on Ubuntu ``codename``: its ``ubuntu`` entry is a
    package list or installer mapping, or maps ``codename`` (else ``*``) to one (null: none)."""
    ubuntu = rule.get("ubuntu") if isinstance(rule, dict) else None
    if ubuntu is None:
        return False
    if isinstance(ubuntu, dict) and not any(k in ubuntu for k in (*INSTALLERS, "packages")):
        return names_packages(ubuntu[codename] if codename in ubuntu else ubuntu.get("*"))
    return names_packages(ubuntu)


def package_keys() -> list[str]:
    """The dependency names of package.xml."""
    root = ET.parse(REPO / "package.xml").getroot()
    return [e.text.strip() for tag in DEPEND_TAGS for e in root.iter(tag) if e.text]


def test_every_package_xml_key_resolves_on_noble_for_jazzy(key_files: dict[str, Any]) -> None:
    ros = jazzy_packages(key_files["jazzy-distribution.yaml"])
    rules = {**key_files["base.yaml"], **key_files["python.yaml"]}
    keys = package_keys()
    assert keys, "package.xml names no dependency"
    unresolved = [k for k in keys if k not in ros and not resolves_on_ubuntu(rules.get(k))]
    assert not unresolved, (f"rosdep cannot resolve {unresolved} on Ubuntu {CODENAME} for Jazzy; a Python "
                            "package without a key goes to the pip command of docs/ros_tools.md instead")


@pytest.mark.parametrize("rule, ok", [
    ({"ubuntu": ["python3-x"]}, True),
    ({"ubuntu": {"pip": {"packages": ["x"]}}}, True),
    ({"ubuntu": {"*": ["python3-x"], "bionic": None}}, True),
    ({"ubuntu": {"*": ["python3-x"], "noble": None}}, False),
    ({"ubuntu": {"focal": ["python3-x"]}}, False),
    ({"ubuntu": {"noble": {"pip": ["x"]}, "*": None}}, True),
    ({"debian": ["python3-x"]}, False),
    ({"ubuntu": []}, False),
    (None, False),
])
def test_the_rule_reading_follows_rosdeps_formats(rule: Any, ok: bool) -> None:
    """The rule shapes of rosdep's key files: a list, an installer mapping, a codename mapping with
    ``*`` and null entries; another platform's rule only, or none, does not resolve."""
    assert resolves_on_ubuntu(rule) is ok
