"""Report documents: table alignment and units, table of contents, figure links."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt

from comems4build_ros.report import document as dm
from comems4build_ros.report.style import figsize, save_figure, styled

ROWS = [["MPC", "12.96", "0 of 12", "never"], ["RBC (basic)", "43.10", "2 of 12 (0.68 and 2.14 Kh)", "16.0"],
        ["ComEMS4Build", "-", "23.44..123.08", "+48.44"]]


def test_numbers_right_text_left() -> None:
    assert dm.column_alignment(ROWS, 4) == ["left", "right", "right", "right"]
    assert dm.column_alignment([["week 1", "2022-12-01"]], 2) == ["left", "left"]
    assert dm.column_alignment([["-"], ["n/a"]], 1) == ["left"]  # placeholders only: text
    for number in ("0", "-3.25", "−0.5", "1,164", "48.4 %", "1.6e-14", "5..10"):
        assert dm.is_number(number), number
    for text in ("held", "not held", "2022-12-01", "yes", "rbc 1.40 Kh/week"):
        assert not dm.is_number(text), text


def test_html_table_units_in_headers_and_alignment() -> None:
    html = dm.render_table(ROWS, ["EMS", "cost", "weeks", "days"], units=[None, "EUR/week", None, "d"])
    head = re.search(r"<thead>(.*)</thead>", html).group(1)
    assert "<th>EMS</th>" in head and '<th class="num">cost [EUR/week]</th>' in head
    assert '<th class="num">days [d]</th>' in head
    first = re.search(r"<tbody>\n<tr>(.*?)</tr>", html).group(1)
    assert first.startswith("<td>MPC</td>") and '<td class="num">12.96</td>' in first


def test_markdown_table_alignment_row() -> None:
    md = dm.markdown_table(ROWS, ["EMS", "cost", "weeks", "days"], units=[None, "EUR", None, None])
    lines = md.splitlines()
    assert lines[0] == "| EMS | cost [EUR] | weeks | days |"
    assert lines[1] == "|:---|---:|---:|---:|"
    assert len(lines) == 2 + len(ROWS)


@styled
def _fig() -> plt.Figure:
    fig, ax = plt.subplots(figsize=figsize("single", 40))
    ax.plot([0, 1], [0, 1])
    return fig


def test_document_toc_anchors_and_figure_links(tmp_path: Path) -> None:
    png = save_figure(_fig(), tmp_path / "figures" / "line")
    doc = dm.Document("Title")
    doc.p("intro")
    a1 = doc.h(2, "Run summary")
    doc.table(["quantity", "MPC"], [["cost", "1.00"]], units=[None, "EUR"])
    a2 = doc.h(3, "MPC (mpc), FC system efficiency 75 %")
    a3 = doc.h(2, "Run summary")  # a second heading of the same text gets its own anchor
    doc.figure(png, "figures", "A line.")
    assert (a1, a2, a3) == ("run-summary", "mpc-mpc-fc-system-efficiency-75-", "run-summary-1")
    html = doc.html()
    md = doc.markdown()
    for anchor in (a1, a2, a3):
        assert f'href="#{anchor}"' in html and f'id="{anchor}"' in html
        assert f"(#{anchor})" in md
    assert html.index('<nav class="toc">') < html.index('id="run-summary"')
    for ext in ("pdf", "svg", "png"):
        assert f'href="figures/line.{ext}"' in html
        assert f"(figures/line.{ext})" in md
    assert 'src="data:image/png;base64,' in html
    assert 'style="width:90mm"' in html  # shown at its printed width
    assert "*Figure 1.* A line." in md


def test_html_tags_are_balanced(tmp_path: Path) -> None:
    from html.parser import HTMLParser

    containers = {"ul", "li", "nav", "table", "thead", "tbody", "tr", "td", "th", "figure", "figcaption", "p"}

    class Checker(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.stack: list[str] = []

        def handle_starttag(self, tag: str, attrs: object) -> None:
            if tag in containers:
                self.stack.append(tag)

        def handle_endtag(self, tag: str) -> None:
            if tag in containers:
                assert self.stack and self.stack[-1] == tag, (tag, self.stack)
                self.stack.pop()

    doc = dm.Document("T")
    for level, text in ((3, "orphan"), (2, "A"), (3, "a1"), (3, "a2"), (2, "B"), (2, "C"), (3, "c1")):
        doc.h(level, text)
        doc.table(["x", "y"], [["1", "a"]])
    doc.figure(save_figure(_fig(), tmp_path / "f"), ".", "caption")
    checker = Checker()
    checker.feed(doc.html())
    assert checker.stack == []
