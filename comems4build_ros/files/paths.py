"""Where the package's own files are: its folder, and the data files installed beside it.

In a source checkout the parameter files (``config/``), the topic contract (``msg_defs/``)
and the launch files (``launch_scripts/``) sit next to the package folder; installed (``pip
install .``, or a ROS 2 install) they are under ``<prefix>/share/comems4build_ros/``.
:func:`shared_path` looks in the checkout first, then in the install.
"""

from __future__ import annotations

import sys
from pathlib import Path

#: Name of the ROS 2 package and of the Python package.
PACKAGE = "comems4build_ros"
#: The Python package's folder (``.../comems4build_ros``).
PACKAGE_DIR = Path(__file__).resolve().parents[1]
#: The folder holding the package folder: the checkout, or ``site-packages`` when installed.
SOURCE_ROOT = PACKAGE_DIR.parent


def shared_path(source_dir: str, installed_dir: str, name: str = "") -> Path | None:
    """A data file or folder of the package, or None where there is none.

    Parameters
    ----------
    source_dir : folder of the checkout (``config``, ``msg_defs``, ``launch_scripts``)
    installed_dir : the same folder under ``<prefix>/share/comems4build_ros/``
    name : a file inside it ("" for the folder itself)
    """
    for base in (SOURCE_ROOT / source_dir, Path(sys.prefix) / "share" / PACKAGE / installed_dir):
        path = base / name if name else base
        if path.exists():
            return path
    return None


def installed_from_source() -> bool:
    """True when the package runs from a checkout (not from ``site-packages``)."""
    return SOURCE_ROOT.name not in ("site-packages", "dist-packages")
