"""The installed package carries its data files (what a fresh `pip install .` user gets)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_installed_copy_has_every_package_data_file(tmp_path: Path) -> None:
    """Every non-Python file inside the package source is also in the installed package."""
    code = "import comems4build_ros, pathlib; print(pathlib.Path(comems4build_ros.__file__).parent)"
    # run outside the repo so the installed copy (not the source tree) is imported
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True)
    installed = Path(out.stdout.strip())
    assert installed != REPO / "comems4build_ros", "the package is not installed (run tools/setup.sh)"
    src = REPO / "comems4build_ros"
    data = [p.relative_to(src) for p in src.rglob("*") if p.is_file() and p.suffix not in (".py", ".pyc")]
    missing = [str(p) for p in data if not (installed / p).is_file()]
    assert not missing, f"package data not installed: {missing}"
