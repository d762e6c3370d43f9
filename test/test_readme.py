"""The README is a front door, and every page or section the shipped text names exists.

The README holds what the project is, the two Quick start commands, a figure, the command
table and links; the reference lives in ``docs/``. A text that names ``docs/PAGE.md`` or
``docs/PAGE.md "Section"`` (README, docs, code, config, tools) must name a page that exists
and a heading or bold paragraph of it, so that moving a section cannot leave a stale pointer.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: Where shipped text names pages of docs/.
SHIPPED = ("README.md", "docs", "comems4build_ros", "config", "tools", "launch_scripts")
#: Suffixes of text files that may name a page.
TEXT = {".md", ".py", ".yaml", ".sh"}
#: ``docs/PAGE.md`` with an optional ``"Section"`` after it (backticks, a closing link or a comma between).
REFERENCE = re.compile(r"(docs/[A-Za-z0-9_]+\.md)`?\)?,?(?:\s+\"([^\"\n]+(?:\n[^\"\n]+)?)\")?")
#: Most lines of the README.
MAX_LINES = 250


def _words(text: str) -> str:
    return " ".join(text.replace("`", "").split())


def sections(page: Path) -> list[str]:
    """The headings and bold paragraph titles of a Markdown page, without markup."""
    text = page.read_text(encoding="utf-8")
    heads = [re.sub(r"^#+\s*", "", line) for line in text.splitlines() if line.startswith("#")]
    return [_words(t) for t in heads + re.findall(r"\*\*([^*]+?)\*\*", text)]


def stale_references(text: str, root: Path) -> list[str]:
    """Every ``docs/PAGE.md`` of ``text`` that does not exist under ``root``, and every
    ``"Section"`` after one that is no heading or bold title of that page."""
    out = []
    for m in REFERENCE.finditer(text):
        page = root / m.group(1)
        if not page.is_file():
            out.append(m.group(1))
        elif m.group(2) and not any(_words(m.group(2)) in s for s in sections(page)):
            out.append(f'{m.group(1)} "{_words(m.group(2))}"')
    return out


def shipped_texts() -> list[Path]:
    files = []
    for name in SHIPPED:
        path = ROOT / name
        files += [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.suffix in TEXT)
    return [p for p in files if "__pycache__" not in p.parts]


def test_the_checker_finds_what_it_should(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("# A\n\n## Exit codes and faults\n\n**Under 5 s, today.** x\n")
    good = ['see `docs/a.md` "Exit codes and\n  faults"', 'docs/a.md "Under 5 s"', "[docs/a.md](docs/a.md)",
            '(`docs/a.md`, "Exit codes")', "docs/a.md alone"]
    for text in good:
        assert stale_references(text, tmp_path) == [], text
    assert stale_references("`docs/b.md`", tmp_path) == ["docs/b.md"]
    assert stale_references('docs/a.md "Faults and exit codes"', tmp_path) == ['docs/a.md "Faults and exit codes"']
    assert stale_references('[x](docs/gone.md) and docs/a.md "Nope"', tmp_path) == ["docs/gone.md", 'docs/a.md "Nope"']


def test_every_named_page_and_section_exists() -> None:
    files = shipped_texts()
    assert README in files and ROOT / "docs" / "benchmarks.md" in files
    found = [f"{p.relative_to(ROOT)}: {r}" for p in files
             for r in stale_references(p.read_text(encoding="utf-8"), ROOT)]
    assert found == [], "\n".join(found)


def test_readme_is_a_front_door() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) < MAX_LINES
    quick = text.split("## Quick start\n", 1)[1].split("\n## ", 1)[0]
    for command in ("bash tools/setup.sh ", "bash tools/test.sh ", "bash tools/test.sh --quick"):
        assert command in quick, command
    assert "<!-- commands:begin -->" in text and "<!-- commands:end -->" in text
    figures = re.findall(r"!\[[^]]*\]\(([^)]+)\)", text)
    assert figures and all((ROOT / f).is_file() for f in figures), figures


@pytest.mark.parametrize("page", sorted(p.name for p in (ROOT / "docs").glob("*.md")))
def test_every_docs_page_is_linked_from_the_readme(page: str) -> None:
    assert f"[docs/{page}](docs/{page})" in README.read_text(encoding="utf-8")
