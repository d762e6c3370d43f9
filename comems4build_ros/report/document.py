"""A report as a list of blocks, rendered to Markdown and to one self-contained HTML file.

:class:`Document` collects headings, paragraphs, tables and figures; :meth:`Document.markdown`
and :meth:`Document.html` render the same blocks, so both files hold the same numbers.
Both start with a table of contents (links to every level-2 and level-3 heading). Tables
(:func:`render_table`, :func:`markdown_table`) put the unit of a column in its header
(``name [unit]``), align text columns left and number columns right
(:func:`column_alignment`). The HTML embeds each figure's PNG (no other file needed to
read it) and links its vector versions (PDF, SVG) and the PNG next to the report.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.report.style import figure_files

#: Cells that say "no value" and do not decide a column's alignment.
PLACEHOLDERS = frozenset({"", "-", "–", "n/a", "never", "not run", "none"})
#: A number as printed in the reports: sign, digits, decimals, optional percent or a
#: range ``a..b`` or a count ``n of m`` (with an optional remark in parentheses).
NUMBER = re.compile(
    r"^[+\-−]?\d[\d,]*(\.\d+)?(e[+\-]?\d+)?( ?%)?"
    r"((\.\.|–| to )[+\-−]?\d[\d,]*(\.\d+)?( ?%)?| of \d+)?( \(.*\))?$"
)
#: Style sheet of the HTML report.
CSS = (
    "body{font-family:system-ui,sans-serif;max-width:1250px;margin:2em auto;padding:0 1em;line-height:1.45}"
    "nav.toc{border:1px solid #ccc;background:#fafafa;padding:0.4em 1.2em;margin:1em 0 2em;display:inline-block}"
    "nav.toc ul{margin:0.2em 0;padding-left:1.2em}"
    "table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.88em}"
    "th,td{border:1px solid #bbb;padding:3px 7px;vertical-align:top}"
    "th{background:#eee;text-align:left}th.num{text-align:right}"
    "td{text-align:left}td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}"
    "figure{margin:1.5em 0}img{max-width:100%;height:auto}"
    "figcaption{margin-top:0.4em;max-width:60em}.files{font-size:0.9em;color:#444}"
)


def is_number(text: str) -> bool:
    """Whether a cell reads as a number (see :data:`NUMBER`)."""
    return bool(NUMBER.match(text.strip()))


def column_alignment(rows: Sequence[Sequence[Any]], n_columns: int) -> list[str]:
    """``"right"`` for columns whose cells are all numbers (placeholders aside), else ``"left"``."""
    out = []
    for j in range(n_columns):
        cells = [str(r[j]).strip() for r in rows if j < len(r)]
        values = [c for c in cells if c.lower() not in PLACEHOLDERS]
        out.append("right" if values and all(is_number(c) for c in values) else "left")
    return out


def header_cells(columns: Sequence[str], units: Sequence[str | None] | None = None) -> list[str]:
    """Column names with their units in brackets (``None`` or ``""``: no unit)."""
    units = list(units) if units is not None else [None] * len(columns)
    if len(units) != len(columns):
        raise ValueError(f"{len(columns)} columns but {len(units)} units")
    return [f"{c} [{u}]" if u else str(c) for c, u in zip(columns, units)]


def render_table(
    rows: Sequence[Sequence[Any]],
    columns: Sequence[str],
    units: Sequence[str | None] | None = None,
    align: Sequence[str] | None = None,
) -> str:
    """An HTML table: units in the headers, text columns left-aligned, number columns right-aligned.

    Parameters
    ----------
    rows : cells, one sequence per row (printed with ``str``)
    columns : column names
    units : one unit per column (None = none), shown as ``name [unit]``
    align : ``"left"``/``"right"`` per column (default :func:`column_alignment`)
    """
    e = html.escape
    head = header_cells(columns, units)
    align = list(align) if align is not None else column_alignment(rows, len(head))
    cls = [' class="num"' if a == "right" else "" for a in align]
    out = ["<table><thead><tr>" + "".join(f"<th{c}>{e(h)}</th>" for c, h in zip(cls, head)) + "</tr></thead>",
           "<tbody>"]
    for row in rows:
        out.append("<tr>" + "".join(f"<td{c}>{e(str(v))}</td>" for c, v in zip(cls, row)) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def markdown_table(
    rows: Sequence[Sequence[Any]],
    columns: Sequence[str],
    units: Sequence[str | None] | None = None,
    align: Sequence[str] | None = None,
) -> str:
    """The same table in Markdown (alignment in the separator row: ``---:`` right, ``:---`` left)."""
    head = header_cells(columns, units)
    align = list(align) if align is not None else column_alignment(rows, len(head))

    def esc(v: Any) -> str:
        return str(v).replace("|", "\\|")

    lines = ["| " + " | ".join(esc(h) for h in head) + " |",
             "|" + "|".join("---:" if a == "right" else ":---" for a in align) + "|"]
    lines += ["| " + " | ".join(esc(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def slug(text: str) -> str:
    """Anchor of a heading as GitHub makes it (lower case, punctuation dropped, spaces to hyphens)."""
    s = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return s.replace(" ", "-")


@dataclass
class _Figure:
    png: Path
    rel_dir: str
    caption: str
    number: int


@dataclass
class Document:
    """Blocks rendered to Markdown and HTML alike (see the module docstring)."""

    title: str
    blocks: list[tuple[Any, ...]] = field(default_factory=list)
    _anchors: dict[str, int] = field(default_factory=dict)
    _figures: int = 0

    def h(self, level: int, text: str) -> str:
        """Add a heading (level 2 and 3 go into the table of contents); returns its anchor."""
        base = slug(text)
        n = self._anchors.get(base, 0)
        self._anchors[base] = n + 1
        anchor = base if n == 0 else f"{base}-{n}"
        self.blocks.append(("h", level, text, anchor))
        return anchor

    def p(self, text: str) -> None:
        """Add a paragraph (plain text)."""
        self.blocks.append(("p", text))

    def table(self, columns: Sequence[str], rows: Sequence[Sequence[Any]],
              units: Sequence[str | None] | None = None) -> None:
        """Add a table (see :func:`render_table`)."""
        self.blocks.append(("table", list(columns), [list(r) for r in rows], units))

    def figure(self, png: Path, rel_dir: str, caption: str) -> None:
        """Add a figure written by :func:`~comems4build_ros.report.style.save_figure`.

        ``png`` is the PNG on disk (embedded in the HTML); ``rel_dir`` the directory of the
        figure files relative to the report (for the links to the PDF, SVG and PNG).
        """
        self._figures += 1
        self.blocks.append(("figure", _Figure(Path(png), rel_dir.rstrip("/"), caption, self._figures)))

    def _toc(self) -> list[tuple[int, str, str]]:
        return [(b[1], b[2], b[3]) for b in self.blocks if b[0] == "h" and b[1] in (2, 3)]

    @staticmethod
    def _files(fig: _Figure) -> dict[str, str]:
        """The figure's files beside its PNG (format -> path relative to the report); the PNG always."""
        return {fmt: f"{fig.rel_dir}/{p.name}" for fmt, p in figure_files(fig.png).items()
                if fmt == "png" or p.is_file()}

    @staticmethod
    def _links(files: Mapping[str, str]) -> list[tuple[str, str]]:
        """(label, path) of each file, vector formats first; the PNG at print resolution only beside them."""
        labels = {"pdf": "PDF", "svg": "SVG", "png": "PNG, 300 dpi" if len(files) > 1 else "PNG"}
        return [(labels[k], files[k]) for k in ("pdf", "svg", "png") if k in files]

    def markdown(self) -> str:
        """The document in Markdown (GitHub flavour)."""
        out = [f"# {self.title}", ""]
        toc = self._toc()
        if toc:
            out.append("Contents:")
            out.append("")
            out.extend(f"{'  ' * (lvl - 2)}- [{text}](#{anchor})" for lvl, text, anchor in toc)
            out.append("")
        for b in self.blocks:
            if b[0] == "h":
                out.append("#" * b[1] + " " + b[2])
            elif b[0] == "p":
                out.append(b[1])
            elif b[0] == "table":
                out.append(markdown_table(b[2], b[1], b[3]))
            elif b[0] == "figure":
                f: _Figure = b[1]
                files = self._files(f)
                links = ", ".join(f"[{label}]({path})" for label, path in self._links(files))
                out.append(f"![Figure {f.number}]({files['png']})\n\n*Figure {f.number}.* {f.caption} "
                           f"Files: {links}.")
            out.append("")
        return "\n".join(out)

    def html(self) -> str:
        """The document as one HTML file with the figures embedded (base64 PNG)."""
        e = html.escape
        parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
                 f"<title>{e(self.title)}</title>", f"<style>{CSS}</style></head><body>", f"<h1>{e(self.title)}</h1>"]
        toc = self._toc()
        if toc:
            parts.append('<nav class="toc"><strong>Contents</strong><ul>')
            nested = False  # inside the <ul> of a level-2 item
            for i, (lvl, text, anchor) in enumerate(toc):
                nxt = toc[i + 1][0] if i + 1 < len(toc) else 2
                item = f'<li><a href="#{e(anchor)}">{e(text)}</a>'
                if lvl == 2 and nxt == 3:
                    parts.append(item + "<ul>")  # the following level-3 headings nest in this item
                    nested = True
                elif nested and nxt == 2:
                    parts.append(item + "</li></ul></li>")
                    nested = False
                else:
                    parts.append(item + "</li>")
            parts.append("</ul></nav>")
        for b in self.blocks:
            if b[0] == "h":
                parts.append(f'<h{b[1]} id="{e(b[3])}">{e(b[2])}</h{b[1]}>')
            elif b[0] == "p":
                parts.append(f"<p>{e(b[1])}</p>")
            elif b[0] == "table":
                parts.append(render_table(b[2], b[1], b[3]))
            elif b[0] == "figure":
                parts.append(self._html_figure(b[1]))
        parts.append("</body></html>")
        return "\n".join(parts)

    def _html_figure(self, f: _Figure) -> str:
        e = html.escape
        files = self._files(f)
        data = base64.b64encode(f.png.read_bytes()).decode("ascii")
        width = _png_width_mm(f.png)
        size = f' style="width:{width:.0f}mm"' if width else ""
        links = " · ".join(f'<a href="{e(path)}">{label}</a>' for label, path in self._links(files))
        return (f'<figure id="figure-{f.number}"><img alt="Figure {f.number}: {e(f.caption)}"{size} '
                f'src="data:image/png;base64,{data}"><figcaption><strong>Figure {f.number}.</strong> '
                f'{e(f.caption)} <span class="files">Files: {links}</span></figcaption></figure>')


def _png_width_mm(path: Path) -> float | None:
    """Printed width of a PNG from its size and resolution (pHYs chunk) [mm], or None."""
    data = path.read_bytes()[:4096]
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        return None
    width_px = int.from_bytes(data[16:20], "big")
    i = data.find(b"pHYs")
    if i < 0:
        return None
    ppu = int.from_bytes(data[i + 4:i + 8], "big")
    if data[i + 12] != 1 or ppu <= 0:  # unit 1 = metre
        return None
    return width_px / ppu * 1000.0 if ppu else None
