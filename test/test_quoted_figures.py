"""Every figure the docs and config/reproduce.yaml quote from the validation study is the study's stored figure.

``comems4build validate ... --update-doc docs/validation.md --update-doc config/reproduce.yaml``
writes the study's results beside the document (``docs/results/validation.json``), its
generated tables between the markers, and the value of every quoted figure
(``<!--fig KEY-->VALUE<!--/fig-->``), so a quoted reason cannot drift from the study it cites.
These tests check the marks' handling: keys, formats, filling and round trips. (The
validation study has not been run again on the yearly tariffs yet, so docs/validation.md
holds no marks and no stored results to compare.)
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from comems4build_ros.files.quoted import MARK, fill_marks, quotes, without_marks
from comems4build_ros.report import validation_doc as vd
from comems4build_ros.report.quoted import QuoteError, render, resolve
from comems4build_ros.study.reproduce import load_study

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "validation.md"
QUOTING = (DOC, ROOT / "config" / "reproduce.yaml", ROOT / "docs" / "calibration.md")


def test_reasons_are_shown_without_their_marks():
    for a in load_study().ambiguities:
        assert "<!--" not in a.reason and "-->" not in a.reason, a.key


@pytest.mark.parametrize("key, message", [
    ("validation:subsets.nowhere.cases|int", "no 'nowhere'"),
    ("validation:study.fc_rules:nothing.default|int", "no item 'fc_rules:nothing'"),
    ("validation:weeks|pct9", "unknown format"),
    ("validation:weeks", "no |format"),
    ("reproduce:weeks|int", "a key is <study>:<path>|<format>"),
    ("validation:subsets.calibration|f2", "not a finite number"),
])
def test_a_key_the_results_do_not_hold_is_named(key, message):
    stored = {"validation": {"weeks": 12.0, "subsets": {"calibration": {"cases": 5}},
                             "study": [{"ambiguity": "fc_rules", "reading": "battery_supports", "default": True}]}}
    with pytest.raises(QuoteError, match=message) as err:
        resolve(key, stored)
    assert key.split("|")[0].split(":")[0] in str(err.value)


@pytest.mark.parametrize("value, fmt, shown", [
    (0.1887, "pct1", "18.9 %"), (0.1887, "pct0", "19 %"), (83.04, "signed0", "+83 %"), (-1.84, "signed1", "-1.8 %"),
    ({"held": 11, "cases": 12}, "of", "11 of 12"), ({"held": 11, "cases": 12}, "ofpct", "11 of 12 (92 %)"),
    ({"median": 1.44, "low": 1.42, "high": 1.51}, "dist2", "1.44 [1.42..1.51]"),
    ({"median": 0.189, "low": 0.177, "high": 0.217}, "rangepct1", "17.7 to 21.7 %"), (12.0, "int", "12"),
    ({"median": 83.04, "low": 77.0, "high": 84.6}, "signeddist0", "+83 % [+77..+85]"),
])
def test_formats(value, fmt, shown):
    assert render(value, fmt, "k") == shown


def test_update_fills_every_quote_and_names_a_bad_one(tmp_path):
    stored = {"weeks": 12.0, "subsets": {}}
    good = tmp_path / "reasons.yaml"
    good.write_text("reason: >-\n  over <!--fig validation:weeks|int-->?<!--/fig--> weeks\n", encoding="utf-8")
    assert vd.update_doc(good, stored) == good
    assert good.read_text(encoding="utf-8") == "reason: >-\n  over <!--fig validation:weeks|int-->12<!--/fig--> weeks\n"
    bad = tmp_path / "bad.yaml"
    bad.write_text("a\nb <!--fig validation:nothing|int-->1<!--/fig-->\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad.yaml:2: quoted figure validation:nothing\|int: no 'nothing'"):
        vd.update_doc(bad, stored)


TEXT = st.text(st.characters(blacklist_characters="<>"), max_size=60)
KEY = st.builds(lambda path, fmt: f"validation:{path}|{fmt}",
                st.text(st.sampled_from("abcdefghij_.-:"), min_size=1, max_size=20),
                st.sampled_from(["f2", "int", "pct1", "of", "dist2"]))


@given(TEXT, KEY, TEXT, TEXT)
def test_marks_round_trip(before, key, value, after):
    text = f"{before}<!--fig {key}-->{value}<!--/fig-->{after}"
    assert without_marks(text) == before + value + after
    assert [q.key for q in quotes(text)] == [key]
    filled = fill_marks(text, lambda k: f"[{k}]")
    assert without_marks(filled) == f"{before}[{key}]{after}"


@given(TEXT)
def test_text_without_marks_is_left_alone(text):
    assert MARK.search(text) is None
    assert without_marks(text) == text and fill_marks(text, lambda k: "x") == text and quotes(text) == []
