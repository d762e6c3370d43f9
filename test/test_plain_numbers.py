"""Numbers in text inputs: a plain decimal or a refusal naming where, whatever the reader.

Python's ``float``/``int`` and ``str.strip``/``str.splitlines`` accept more than any of the
project's text sources writes: digit groups (``1_000``), digits of other scripts, ``nan`` and
``inf`` spelled out, Unicode space and control characters around a number, and line breaks
at ``\\x1c``, ``\\x85`` or U+2028. Every reader of numbers in text (DWD products and station
files, DHWCalc, EPW, IDF, the run token file, MQTT ``number`` commands, ``--fc-efficiency``)
goes through :func:`~comems4build_ros.files.inputs.parse_decimal` / ``parse_integer`` and
:func:`~comems4build_ros.files.inputs.text_lines`; these tests feed each one such a form at
a random place and expect a refusal that names the file (or topic or option), line and field.
"""

from __future__ import annotations

import math
import re
import string
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from comems4build_ros.core.scenario import loaders as ld
from comems4build_ros.core.scenario import validation as va
from comems4build_ros.core.scenario.csvio import ScenarioError
from comems4build_ros.files.inputs import parse_decimal, parse_integer, text_lines

FIX = Path(__file__).parent / "fixtures"
QUICK = {"max_examples": 60, "deadline": None,
         "suppress_health_check": [HealthCheck.function_scoped_fixture, HealthCheck.too_slow]}

#: Characters ``str.strip`` removes that are no ASCII space, tab, CR or LF (all Latin-1, so a
#: DWD or DHWCalc file can hold them): vertical tab, form feed, the four ASCII separators,
#: NEL and the no-break space.
ODD_SPACE = "\x0b\x0c\x1c\x1d\x1e\x1f\x85\xa0"
#: Zero of digit sets other than ASCII that ``int``/``float`` read (Arabic-Indic, Devanagari, full width).
OTHER_ZEROS = (0x0660, 0x0966, 0xFF10)
WORDS = ("nan", "NaN", "inf", "-inf", "Infinity", "+nan")

plain_numbers = st.one_of(
    st.integers(-10**6, 10**6).map(str),
    st.floats(-1e6, 1e6, allow_nan=False).map(lambda v: f"{v:.3f}"),
)


@st.composite
def lenient_only(draw: st.DrawFn, latin1: bool = True) -> str:
    """A number that Python's ``float`` (after ``str.strip``) reads but no source writes."""
    text = draw(plain_numbers.filter(lambda t: sum(c.isdigit() for c in t) >= 2))
    kind = draw(st.sampled_from(["group", "script", "space", "word"] if not latin1 else ["group", "space", "word"]))
    if kind == "group":
        i = draw(st.sampled_from([k for k in range(1, len(text)) if text[k - 1].isdigit() and text[k].isdigit()]))
        out = text[:i] + "_" + text[i:]
    elif kind == "script":
        zero = draw(st.sampled_from(OTHER_ZEROS))
        out = "".join(chr(zero + int(c)) if c.isdigit() else c for c in text)
    elif kind == "space":
        odd = draw(st.sampled_from(ODD_SPACE))
        out = odd + text if draw(st.booleans()) else text + odd
    else:
        out = draw(st.sampled_from(WORDS))
    if kind != "word":
        assert math.isfinite(float(out.strip()))  # the form Python's float accepts
    return out


# --------------------------------------------------------------------------- the parsers


@given(text=st.text(max_size=12))
@settings(max_examples=500, deadline=None)
def test_an_accepted_text_is_a_plain_decimal_and_its_float(text: str) -> None:
    try:
        value = parse_decimal(text)
    except ValueError as exc:
        assert repr(text[:40]) in str(exc)
    else:
        assert set(text) <= set(string.digits + "+-.eE \t\r\n") and value == float(text)


@given(value=st.floats(allow_nan=False, allow_infinity=False), whole=st.integers(-10**18, 10**18),
       pad=st.text(alphabet=" \t\r\n", max_size=3))
def test_every_plain_number_is_read_as_python_writes_it(value: float, whole: int, pad: str) -> None:
    assert parse_decimal(pad + repr(value) + pad) == value
    assert parse_decimal(f"{value:.6e}") == float(f"{value:.6e}")
    assert parse_integer(pad + str(whole) + pad) == whole and parse_decimal(str(whole)) == float(whole)


@given(text=lenient_only(latin1=False))
def test_python_only_forms_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="is not a plain decimal"):
        parse_decimal(text)


@pytest.mark.parametrize("text", ["1.0", "1e3", "0x10", "1_0", "\u0661\u0662", "12\x1c", ""])
def test_an_integer_is_digits_only(text: str) -> None:
    with pytest.raises(ValueError, match="is not a plain decimal integer"):
        parse_integer(text)


@given(lines=st.lists(st.text(alphabet=st.characters(blacklist_characters="\n\r"), max_size=8), min_size=1, max_size=6),
       crlf=st.booleans())
def test_lines_are_numbered_at_line_feeds_only(lines: list[str], crlf: bool) -> None:
    text = ("\r\n" if crlf else "\n").join(lines) + ("\r\n" if crlf else "\n")
    assert text_lines(text) == lines


# --------------------------------------------------------------------------- the readers


@given(text=lenient_only(), row=st.integers(2, 9))
@settings(**QUICK)
def test_dwd_product_names_line_and_column(tmp_path: Path, text: str, row: int) -> None:
    lines = (FIX / "dwd_10min_tt_4177.txt").read_text().splitlines()
    fields = lines[row - 1].split(";")
    col = lines[0].split(";").index("TT_10")
    fields[col] = text
    lines[row - 1] = ";".join(fields)
    path = tmp_path / "tt.txt"
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    with pytest.raises(ScenarioError) as exc:
        ld.read_dwd_temperature(path)
    assert f"{path}: line {row}, column 'TT_10'" in str(exc.value)


@given(text=lenient_only(latin1=False), row=st.integers(2, 5), col=st.sampled_from(["TT_TU", "SD_SO"]))
@settings(**QUICK)
def test_station_file_names_line_and_column(tmp_path: Path, text: str, row: int, col: str) -> None:
    rows = [f"20160101{h:02d};1.5;90.0;{10 * h}" for h in range(4)]
    header = ["MESS_DATUM", "TT_TU", "RF_TU", "SD_SO"]
    fields = rows[row - 2].split(";")
    fields[header.index(col)] = text
    rows[row - 2] = ";".join(fields)
    path = tmp_path / "station.csv"
    path.write_text(";".join(header) + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    with pytest.raises(ScenarioError) as exc:
        va.read_station_hourly(path)
    assert f"{path}: line {row}, column '{col}'" in str(exc.value)


@given(text=lenient_only(), row=st.integers(1, 8760))
@settings(**QUICK)
def test_dhwcalc_names_the_line(tmp_path: Path, text: str, row: int) -> None:
    values = [f"{v:g}" for v in np.full(8760, 5.0)]
    values[row - 1] = text
    path = tmp_path / "dhw.txt"
    path.write_text("Water_LperH\n" + "\n".join(values) + "\n", encoding="latin-1")
    with pytest.raises(ScenarioError) as exc:
        ld.read_dhwcalc(path, 2022, "Europe/Berlin")
    assert f"{path}: line {row + 1}, column 1" in str(exc.value)


def test_a_separator_character_does_not_shift_the_line_named(tmp_path: Path) -> None:
    """A \x1c or NEL in a column that is not read, and a bad value three lines further named at its own line."""
    lines = (FIX / "dwd_10min_tt_4177.txt").read_text().splitlines()
    lines[2] = lines[2].replace("  90.0;", "\x1c90.0\x85;")  # RF_10, not read: no line break there
    lines[5] = lines[5].replace("   1.8", "  warm")
    path = tmp_path / "tt.txt"
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    with pytest.raises(ScenarioError, match=re.escape(f"{path}: line 6, column 'TT_10': 'warm'")):
        ld.read_dwd_temperature(path)


@given(text=lenient_only(latin1=False), record=st.integers(0, 23), field=st.sampled_from([0, 1, 2, 3, 6]))
@settings(**QUICK)
def test_epw_names_the_line(tmp_path: Path, params, text: str, record: int, field: int) -> None:
    import pandas as pd

    from comems4build_ros.core.models.epw import EPWError, Weather, epw_hours, write_epw

    time = pd.date_range("2022-12-01", periods=24, freq="h", tz=params.site.timezone)
    path = write_epw(tmp_path / "w.epw", Weather(time, np.zeros(24), np.zeros(24), np.zeros(24)), params.site)
    lines = path.read_text(encoding="utf-8").split("\n")
    parts = lines[8 + record].split(",")
    parts[field] = text
    lines[8 + record] = ",".join(parts)
    path.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(EPWError, match=re.escape(f"{path}: line {9 + record}: field")):
        epw_hours(path)


@given(text=lenient_only(latin1=False), where=st.sampled_from(["timestep", "vertex", "capacity"]))
@settings(**QUICK)
def test_idf_numbers_name_the_object(tmp_path: Path, text: str, where: str) -> None:
    from comems4build_ros.core.models import house_idf as house
    from comems4build_ros.core.models.building_energyplus import IDFError, check_idf

    idf = house.idf_text()
    if where == "timestep":
        idf, message = idf.replace("Timestep,\n  4;", f"Timestep,\n  {text};"), "object Timestep"
    elif where == "vertex":
        m = re.search(r"BuildingSurface:Detailed,\n  (GF Floor)[^;]*?\n  (-?[0-9.]+),", idf)
        assume(m is not None)
        idf = idf[:m.start(2)] + text + idf[m.end(2):]
        message = "object BuildingSurface:Detailed"
    else:
        m = re.search(r"ZoneHVAC:LowTemperatureRadiant:Electric,(?:\n[^\n]*){5}\n  ([0-9.]+),", idf)
        assume(m is not None)
        idf = idf[:m.start(1)] + text + idf[m.end(1):]
        message = "object ZoneHVAC:LowTemperatureRadiant:Electric"
    assert idf != house.idf_text()
    path = tmp_path / "house.idf"
    path.write_text(idf, encoding="utf-8")
    with pytest.raises(IDFError) as exc:
        check_idf(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


def test_idf_comment_after_a_line_separator_stays_a_comment(tmp_path: Path) -> None:
    """``str.splitlines`` would end the comment at U+2028 and read ``Timestep, 1;`` as an object."""
    from comems4build_ros.core.models import house_idf as house
    from comems4build_ros.core.models.building_energyplus import check_idf

    idf = house.idf_text().replace("Timestep,\n  4;", "Timestep,\n  4;  ! four steps\u2028Timestep, 1;", 1)
    path = tmp_path / "house.idf"
    path.write_text(idf, encoding="utf-8")
    assert check_idf(path).timesteps_per_hour == 4


@given(text=lenient_only())
@settings(**QUICK)
def test_token_file_is_a_plain_integer(tmp_path: Path, text: str) -> None:
    from comems4build_ros.wire.tokens import read_token_file

    path = tmp_path / "token"
    path.write_text(text.replace(".", ""), encoding="latin-1")
    path.chmod(0o600)
    with pytest.raises(ValueError, match=re.escape(f"token file {path}")):
        read_token_file(path)


@given(text=lenient_only(latin1=False))
@settings(**QUICK)
def test_fc_efficiency_option_is_plain(text: str) -> None:
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.compare import parse_etas

    with pytest.raises(UsageError, match="--fc-efficiency"):
        parse_etas("0.8," + text)


@given(text=lenient_only(latin1=False))
def test_mqtt_setting_is_plain(text: str) -> None:
    from comems4build_ros.mqtt.safety import SettingError, parse_setting

    topic = "comems4build/setting/battery_power_limit/set"
    with pytest.raises(SettingError, match=re.escape(f"topic '{topic}'")):
        parse_setting(topic, text.encode(), -1e7, 1e7)


@given(text=lenient_only(latin1=False), as_json=st.booleans(), where=st.sampled_from(["value", "step"]))
def test_mqtt_measurement_is_plain(text: str, as_json: bool, where: str) -> None:
    """A house measurement (plain or JSON ``{"value": ..., "step": ...}``) and its step tag."""
    import json

    from comems4build_ros.mqtt.topicmap import MeasurementSpec, PayloadError

    spec = MeasurementSpec(topic="zone/t", range=(-1e9, 1e9), json_key="value" if as_json else "",
                           step_key="step" if as_json else "")
    if not as_json:
        payload = text.encode()
    else:
        doc = {"value": text, "step": "3"} if where == "value" else {"value": "21.5", "step": text.replace(".", "")}
        payload = json.dumps(doc).encode()
    with pytest.raises(PayloadError, match=re.escape("topic 'zone/t'")):
        spec.decode(payload)


@given(value=st.floats(-1e6, 1e6, allow_nan=False), scale=st.sampled_from([1.0, 0.01, 1000.0]))
def test_mqtt_measurement_of_any_plain_number_is_read(value: float, scale: float) -> None:
    from comems4build_ros.mqtt.topicmap import MeasurementSpec

    spec = MeasurementSpec(topic="zone/t", scale=scale, range=(-1e12, 1e12))
    assert spec.decode(spec.encode(value)) == (value, None)
