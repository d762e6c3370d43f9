"""Shipped text cites only what a reader can open: the paper and outside sources.

No issue numbers, no project-internal notes (``FACTS``, ``TOOLCHAIN``) and no paths under
``shared/`` in the package (code and package data), config/, msg_defs/, docs/, README.md,
lib_scripts/, launch_scripts/, tools/ and the packaging files, nor in what ``compare``
writes (report, findings, paper table, figure texts).
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.report import figures as rf
from comems4build_ros.report.build import read_report_inputs

ROOT = Path(__file__).resolve().parents[1]
#: Directories and files whose text ships with the project.
SHIPPED = ("comems4build_ros", "config", "msg_defs", "docs", "README.md", "lib_scripts", "launch_scripts", "tools",
           "setup.py", "setup.cfg", "package.xml", "pyproject.toml", "requirements.txt", "resource")
#: Shipped files not checked, each with the reason (none today).
NOT_CHECKED: dict[str, str] = {}
#: Citations a reader cannot follow.
FORBIDDEN = (
    ("an issue number", re.compile(r"\bissues?\s*#?\s*\d+", re.IGNORECASE)),
    ("a path under shared/", re.compile(r"\bshared/")),
    ("the project notes FACTS", re.compile(r"\bFACTS\b")),
    ("the project notes TOOLCHAIN", re.compile(r"\bTOOLCHAIN\b")),
)
#: Suffixes of binary files (not text).
BINARY = {".png", ".pdf", ".mcap", ".pyc", ".gz", ".zip", ".db3"}


def citations(text: str) -> list[str]:
    """Every forbidden citation in ``text`` as ``what: 'match'``."""
    return [f"{what}: {m.group(0)!r}" for what, rx in FORBIDDEN for m in rx.finditer(text)]


def shipped_files() -> list[Path]:
    out = []
    for name in SHIPPED:
        path = ROOT / name
        files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
        out += [p for p in files if p.suffix not in BINARY and "__pycache__" not in p.parts]
    return out


def test_the_patterns_catch_what_they_should() -> None:
    for bad in ("see issue 3", "Issue #12", "issues 3 and 4", "issue 4 §3", "shared/FACTS.md", "TOOLCHAIN facts",
                "(FACTS table)"):
        assert citations(bad), bad
    for ok in ("an issue with the solver", "the shared daily weather index", "facts from the datasheet",
               "paper sec:results", "toolchain"):
        assert not citations(ok), ok


def test_exceptions_exist() -> None:
    for rel in NOT_CHECKED:
        assert (ROOT / rel).is_file(), f"{rel}: listed in NOT_CHECKED but gone; remove it from the list"


def test_shipped_files_cite_no_issue_or_internal_note() -> None:
    files = shipped_files()
    assert any(p.name == "paper_results.yaml" for p in files)  # package data is included
    found = []
    for path in files:
        rel = path.relative_to(ROOT).as_posix()
        if rel in NOT_CHECKED:
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for n, line in enumerate(text.splitlines(), start=1):
            found += [f"{rel}:{n}: {c}" for c in citations(line)]
    assert found == [], "\n".join(found)


@pytest.fixture(scope="module")
def short_comparison(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cmp")
    assert main(["compare", "--ems", "rbc,fuzzy", "--weeks", "0.5", "--fc-efficiency", "0.75",
                 "--out", str(out)]) == 0
    return out


def test_compare_output_cites_no_issue_or_internal_note(short_comparison: Path) -> None:
    found = []
    for name in ("report.md", "report.html", "findings.json", "paper_comparison.csv", "compare.json"):
        text = (short_comparison / name).read_text(encoding="utf-8")
        text = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]+", "", text)  # embedded images are not text
        found += [f"{name}: {c}" for c in citations(text)]
    assert found == [], "\n".join(found)


def test_figure_texts_cite_no_issue_or_internal_note(short_comparison: Path) -> None:
    found = []
    for key, fig in rf.iter_figures(read_report_inputs(short_comparison).figures):
        texts = [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text") and hasattr(a, "set_text"))]
        found += [f"{key}: {c}" for t in texts for c in citations(t)]
        plt.close(fig)
    assert found == [], "\n".join(found)
