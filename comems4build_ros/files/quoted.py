"""Figures quoted in prose (docs, the reasons of ``config/reproduce.yaml``) marked with where they come from.

A quoted figure is written ``<!--fig KEY-->VALUE<!--/fig-->``: ``KEY`` names the figure in
a study's stored results (``validation:PATH|FORMAT``, resolved by
:mod:`comems4build_ros.report.quoted`), ``VALUE`` is the figure as the text shows it. The
marks are HTML comments, invisible in rendered Markdown; a text shown elsewhere (the
reasons in the reproduction's documents) has them removed by :func:`without_marks`. The
command that runs the study fills the values (:func:`fill_marks`), and a test compares every
value with the study's stored results, so a quoted figure cannot drift from the study it cites.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

#: A quoted figure: its key and its value as shown.
MARK = re.compile(r"<!--fig (?P<key>[^>]*?)-->(?P<value>.*?)<!--/fig-->", re.DOTALL)


@dataclass(frozen=True)
class Quote:
    """One quoted figure of a text: its key, its value as written, and where (1-based line)."""

    key: str
    value: str
    line: int


def quotes(text: str) -> list[Quote]:
    """Every quoted figure of ``text`` in order."""
    return [Quote(m["key"].strip(), " ".join(m["value"].split()), text.count("\n", 0, m.start()) + 1)
            for m in MARK.finditer(text)]


def without_marks(text: str) -> str:
    """``text`` with the marks of its quoted figures removed, their values kept."""
    return MARK.sub(lambda m: m["value"], text)


def fill_marks(text: str, value_of: Callable[[str], str]) -> str:
    """``text`` with every quoted figure's value replaced by ``value_of(key)``.

    Raises
    ------
    KeyError
        From ``value_of`` for a key it cannot resolve (the caller names the file).
    """
    return MARK.sub(lambda m: f"<!--fig {m['key'].strip()}-->{value_of(m['key'].strip())}<!--/fig-->", text)
