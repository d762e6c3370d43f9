"""The values of quoted figures (:mod:`comems4build_ros.files.quoted`) from a study's stored results.

A key is ``validation:PATH|FORMAT``. ``PATH`` walks the mapping of ``validation.json``
(:func:`comems4build_ros.report.validation.evaluate`) by dotted segments; a list is entered by
the name of an item: ``study.<ambiguity>:<reading>`` for a reading of the study,
``cases.<id>`` for a case. ``FORMAT`` says how the value is written:

========== =========================================== =====================
format     value                                       shown
========== =========================================== =====================
``f0..f3`` a number                                    ``1.44``
``int``    a number                                    ``12``
``pct0/1`` a share [-]                                 ``18.9 %``
``signed0/1`` a change in per cent                     ``+83.0 %``
``of``     ``{"held": h, "cases": n}``                 ``11 of 12``
``ofpct``  the same                                    ``11 of 12 (92 %)``
``dist2``  ``{"median", "low", "high"}``               ``1.44 [1.42..1.51]``
``distpct1`` the same, shares                          ``18.9 % [17.7..21.7]``
``range2`` the same                                    ``1.42 to 1.51``
``rangepct1`` the same, shares                         ``17.7 to 21.7 %``
``signeddist0/1`` the same, changes in per cent        ``+83 % [+77..+85]``
========== =========================================== =====================

The validation writes its stored results next to the document it updates
(``docs/results/validation.json``, :data:`STORED`); ``test/test_quoted_figures.py`` compares
every quoted figure of the docs and of ``config/reproduce.yaml`` with them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: Where the stored results of each study lie, relative to the directory of the document.
STORED = {"validation": Path("results") / "validation.json"}


class QuoteError(KeyError):
    """A quoted figure's key names nothing in the stored results, or a format that does not fit."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


def _item(items: list[Any], name: str, key: str) -> Any:
    for it in items:
        if not isinstance(it, Mapping):
            continue
        if ":" in name and f"{it.get('ambiguity')}:{it.get('reading')}" == name:
            return it
        if it.get("id") == name or it.get("group") == name:
            return it
    raise QuoteError(f"{key}: no item '{name}'")


def lookup(results: Mapping[str, Any], path: str, key: str) -> Any:
    """The value at the dotted ``path`` of ``results`` (``key`` names it in errors)."""
    value: Any = results
    for seg in path.split("."):
        if isinstance(value, Mapping):
            if seg not in value:
                raise QuoteError(f"{key}: no '{seg}' (known: {', '.join(map(str, value))})")
            value = value[seg]
        elif isinstance(value, list):
            value = _item(value, seg, key)
        else:
            raise QuoteError(f"{key}: '{seg}' below a value")
    return value


def _num(value: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise QuoteError(f"{key}: not a finite number: {value!r}")
    return float(value)


def _dist(value: Any, key: str) -> tuple[float, float, float]:
    if not isinstance(value, Mapping) or not {"median", "low", "high"} <= set(value):
        raise QuoteError(f"{key}: not a distribution: {value!r}")
    return _num(value["median"], key), _num(value["low"], key), _num(value["high"], key)


def render(value: Any, fmt: str, key: str) -> str:
    """``value`` written in the format ``fmt`` (the table of the module)."""
    if fmt in ("f0", "f1", "f2", "f3"):
        return f"{_num(value, key):.{fmt[1]}f}"
    if fmt == "int":
        return f"{round(_num(value, key)):d}"
    if fmt in ("pct0", "pct1"):
        return f"{100 * _num(value, key):.{fmt[-1]}f} %"
    if fmt in ("signed0", "signed1"):
        return f"{_num(value, key):+.{fmt[-1]}f} %"
    if fmt in ("of", "ofpct"):
        if not isinstance(value, Mapping) or not {"held", "cases"} <= set(value):
            raise QuoteError(f"{key}: not a count of cases: {value!r}")
        held, cases = int(value["held"]), int(value["cases"])
        text = f"{held} of {cases}"
        return text + (f" ({100 * held / cases:.0f} %)" if fmt == "ofpct" and cases else "")
    if fmt == "dist2":
        m, lo, hi = _dist(value, key)
        return f"{m:.2f} [{lo:.2f}..{hi:.2f}]"
    if fmt == "distpct1":
        m, lo, hi = _dist(value, key)
        return f"{100 * m:.1f} % [{100 * lo:.1f}..{100 * hi:.1f}]"
    if fmt in ("signeddist0", "signeddist1"):
        m, lo, hi = _dist(value, key)
        d = fmt[-1]
        return f"{m:+.{d}f} % [{lo:+.{d}f}..{hi:+.{d}f}]"
    if fmt == "range2":
        _, lo, hi = _dist(value, key)
        return f"{lo:.2f} to {hi:.2f}"
    if fmt == "rangepct1":
        _, lo, hi = _dist(value, key)
        return f"{100 * lo:.1f} to {100 * hi:.1f} %"
    raise QuoteError(f"{key}: unknown format '{fmt}'")


def resolve(key: str, stored: Mapping[str, Mapping[str, Any]]) -> str:
    """The value of the quoted figure ``key`` from ``stored`` (study name -> its stored results).

    Raises
    ------
    QuoteError
        Naming the key, for an unknown study, path or format.
    """
    study, sep, rest = key.partition(":")
    if not sep or study not in stored:
        raise QuoteError(f"{key}: a key is <study>:<path>|<format> with a study of {', '.join(stored) or 'none'}")
    path, sep, fmt = rest.partition("|")
    if not sep:
        raise QuoteError(f"{key}: no |format")
    return render(lookup(stored[study], path, key), fmt, key)
