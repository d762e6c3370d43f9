"""The one input layer: every file format the project reads, fed crafted and mutated files.

For each format (parameter file, cost file, topic map, live-input settings, scenario CSV,
aWATTar JSON, DWD temperature and radiation, DHWCalc, load CSV, a bag's ``run_info.json``,
``reproduce.json``, bags) a property test (hypothesis, derandomized, a bounded number of
examples, no example database) feeds random bytes and mutations of a valid file to the
reader the commands use: it returns valid data or raises a ``ValueError`` naming the file,
never another exception, never runs past :data:`CALL_LIMIT_S`, and the YAML and JSON loaders
never allocate more than :data:`MEMORY_LIMIT_B`. The crafted YAML documents of the issue class
(recursive alias, alias chains, deep nesting, a key twice, keys that are no strings) are
tried in each of the places that read YAML.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import tracemalloc
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import PRICES, SOLAR, TEMPERATURE, recorded_bag, run_cli  # noqa: F401 (a fixture)

from comems4build_ros.core.config import config_dir, load_plant_params
from comems4build_ros.files.inputs import InputFileError, load_json_text, load_yaml_text

FIXTURES = Path(__file__).parent / "fixtures"
DATA = Path(__file__).resolve().parents[1] / "comems4build_ros" / "data"
#: Longest one read may take [s]: far beyond any valid file here; a hang ends the test.
CALL_LIMIT_S = 30
#: Most memory one YAML or JSON document of at most 64 kB may allocate while it is read [bytes].
MEMORY_LIMIT_B = 64 * 2**20


def bounded(n: int) -> settings:
    """Reproducible, bounded property tests: ``n`` examples, derandomized, no example database."""
    return settings(max_examples=n, derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


@contextlib.contextmanager
def time_limit(seconds: int = CALL_LIMIT_S) -> Iterator[None]:
    """Fail (not hang) when the block runs longer than ``seconds``."""
    def alarm(signum: int, frame: Any) -> None:
        raise TimeoutError(f"a read took longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@st.composite
def mutated(draw: st.DrawFn, base: bytes) -> bytes:
    """``base`` with a few edits (a slice deleted, replaced, duplicated, random bytes put in), or random bytes."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=2000))
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 3))):
        n = len(data)
        i = draw(st.integers(0, n))
        j = draw(st.integers(i, min(n, i + 40)))
        kind = draw(st.sampled_from(["delete", "replace", "insert", "duplicate", "token"]))
        if kind == "delete":
            del data[i:j]
        elif kind == "replace":
            data[i:j] = draw(st.binary(min_size=1, max_size=12))
        elif kind == "insert":
            data[i:i] = draw(st.binary(min_size=1, max_size=12))
        elif kind == "duplicate":
            data[i:i] = data[i:j]
        else:  # a token that means something in these formats
            data[i:j] = draw(st.sampled_from([b"nan", b"inf", b"-1e308", b"1e999", b"true", b"null", b"&a ", b"*a",
                                              b"[", b"{", b'"', b",", b"\n", b":", b"-", b"0", b"\xff", b"\x00",
                                              b"2022-12-01T06:30:00+01:00", b"1e-300"]))
    return bytes(data)


def accepts_or_names(read: Callable[[Path], Any], path: Path, errors: tuple[type[BaseException], ...] = (ValueError,),
                     names: str | None = None) -> Any:
    """``read(path)``: a result, or one of ``errors`` whose message names the file (``names``: this text instead)."""
    with time_limit():
        try:
            return read(path)
        except errors as exc:
            text = str(exc)
            assert (names or path.name) in text, f"{type(exc).__name__} not naming {path.name}: {text}"
            assert "Traceback" not in text
            return None


# ---------------------------------------------------------------------------- the loaders themselves
CRAFTED = {
    "recursive alias": ("a: &a [1, *a]\n", "recursive alias"),
    "alias chain": ("a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdef", "bcdefg")), "aliases expanded"),
    "deep nesting": ("a: " + "[" * 5000 + "]" * 5000 + "\n", "nested more than"),
    "a key twice": ("battery:\n  e_max_kwh: 6.5\nbattery:\n  e_max_kwh: 10\n", "given twice"),
    "a number as key": ("battery:\n  1: 6.5\n", "is not a string"),
    "null as key": ("battery:\n  ~: 6.5\n", "is not a string"),
    "two documents": ("a: 1\n---\na: 2\n", "more than one YAML document"),
}


@pytest.mark.parametrize("case", list(CRAFTED))
def test_crafted_yaml_is_refused_with_line_and_column(case: str) -> None:
    text, named = CRAFTED[case]
    tracemalloc.start()
    try:
        with time_limit(5), pytest.raises(InputFileError, match=rf"f\.yaml:\d+:\d+: .*{named}"):
            load_yaml_text(text, "f.yaml")
        assert tracemalloc.get_traced_memory()[1] < MEMORY_LIMIT_B
    finally:
        tracemalloc.stop()


def _param_section(text: str) -> str:
    """``text`` (YAML) as a ROS 2 parameter file's ``/**: ros__parameters:`` body."""
    body = "\n".join("    " + line for line in text.splitlines())
    return f"/**:\n  ros__parameters:\n{body}\n"


def _places(tmp_path: Path, recorded: Path) -> dict[str, Callable[[Path], Any]]:
    """Each place that reads YAML -> a reader of a YAML file there, as the commands read it."""
    from comems4build_ros.bags.evaluation import evaluate_bag
    from comems4build_ros.core.economics import load_costs
    from comems4build_ros.core.scenario.live import load_live_settings
    from comems4build_ros.mqtt.topicmap import load_topic_map

    def bag_naming(path: Path) -> Any:  # a bag whose run_info.json names the file as its parameter file
        bag = tmp_path / f"bag_{path.stem}"
        if not bag.exists():
            shutil.copytree(recorded, bag)
        (bag / "run_info.json").write_text(json.dumps({"config_files": [str(path)]}))
        return evaluate_bag(bag, tmp_path / f"e_{path.stem}")

    return {"--config": lambda p: load_plant_params([p]), "--costs": lambda p: load_costs([p]),
            "--topic-map": load_topic_map, "--live-config": load_live_settings, "run_info.json": bag_naming}


@pytest.mark.parametrize("case", list(CRAFTED))
def test_crafted_yaml_in_every_place_that_reads_yaml(case: str, tmp_path: Path, recorded_bag: Path,  # noqa: F811
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    text, named = CRAFTED[case]
    for place, read in _places(tmp_path, recorded_bag).items():
        path = tmp_path / f"{place.strip('-').replace('.', '_')}.yaml"
        path.write_text(_param_section(text) if case not in ("two documents",) else text)
        with time_limit(10), pytest.raises(ValueError, match=rf"{path.name}:\d+:\d+: .*{named}"):
            read(path)
    item = text.replace("\n", " ") if case in ("recursive alias", "deep nesting") else None
    if item:  # --set values are YAML too
        code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "2", "--set", f"battery.e_max_kwh={item}",
                                "--out", tmp_path / "r"], capsys)
        assert code == 2 and named in err and "--set" in err, err


@bounded(150)
@given(st.binary(max_size=3000) | st.text(max_size=3000).map(str.encode))
def test_any_bytes_are_yaml_data_or_refused_within_bounds(data: bytes) -> None:
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return  # read_text refuses it before the loader (tested with the formats below)
    tracemalloc.start()
    try:
        with time_limit(10):
            with contextlib.suppress(InputFileError):
                load_yaml_text(text, "f.yaml")
            with contextlib.suppress(InputFileError):
                load_json_text(text, "f.json")
        assert tracemalloc.get_traced_memory()[1] < MEMORY_LIMIT_B
    finally:
        tracemalloc.stop()


@bounded(60)
@given(st.recursive(st.none() | st.booleans() | st.floats() | st.text(max_size=5),
                    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=3), c, max_size=3),
                    max_leaves=30), st.integers(0, 200))
def test_json_nested_any_depth_is_data_or_refused(doc: Any, depth: int) -> None:
    text = "[" * depth + json.dumps(doc) + "]" * depth
    try:
        load_json_text(text, "f.json")
    except InputFileError as exc:
        assert depth > 50 and "nested more than" in str(exc)


# ---------------------------------------------------------------------------- each format
def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


@pytest.fixture(scope="module")
def scenario_csv(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    from comems4build_ros.core.scenario import resolve_scenario, write_scenario_csv

    path = tmp_path_factory.mktemp("csv") / "s.csv"
    write_scenario_csv(resolve_scenario("default", load_plant_params(), hours=30), path)
    return path.read_bytes()


FORMATS: dict[str, tuple[Path | None, str, int]] = {
    # format: (valid file to mutate, file name, examples)
    "parameter file": (config_dir() / "plant.yaml", "p.yaml", 40),
    "cost file": (config_dir() / "costs.yaml", "c.yaml", 40),
    "topic map": (config_dir() / "mqtt.yaml", "m.yaml", 40),
    "live-input settings": (config_dir() / "live_inputs.yaml", "l.yaml", 40),
    "aWATTar JSON": (PRICES, "a.json", 60),
    "DWD temperature": (TEMPERATURE, "t.txt", 60),
    "DWD radiation": (SOLAR, "r.txt", 60),
    "load CSV": (FIXTURES / "load_15min.csv", "load.csv", 60),
    "DHWCalc": (DATA / "OpenDHW_DHWcalc_200L_60min_4cat_sf_nods_max1200.txt", "d.txt", 25),
}


def _reader(fmt: str) -> Callable[[Path], Any]:
    from comems4build_ros.core.economics import load_costs
    from comems4build_ros.core.scenario import loaders
    from comems4build_ros.core.scenario.live import load_live_settings
    from comems4build_ros.mqtt.topicmap import load_topic_map

    return {
        "parameter file": lambda p: load_plant_params([p]),
        "cost file": lambda p: load_costs([p]),
        "topic map": load_topic_map,
        "live-input settings": load_live_settings,
        "aWATTar JSON": loaders.read_awattar_json,
        "DWD temperature": loaders.read_dwd_temperature,
        "DWD radiation": loaders.read_dwd_solar,
        "load CSV": lambda p: loaders.read_load_csv(p),
        "DHWCalc": lambda p: loaders.read_dhwcalc(p, 2022, "Europe/Berlin"),
    }[fmt]


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_each_format_reads_valid_data_or_names_the_file(fmt: str, tmp_path: Path) -> None:
    source, name, n = FORMATS[fmt]
    assert source is not None
    base = source.read_bytes()
    read = _reader(fmt)
    assert accepts_or_names(read, _write(tmp_path, name, base)) is not None  # the valid file reads

    @bounded(n)
    @given(mutated(base))
    def check(data: bytes) -> None:
        accepts_or_names(read, _write(tmp_path, name, data))

    check()


def test_scenario_csv_reads_valid_data_or_names_the_file(scenario_csv: bytes, tmp_path: Path) -> None:
    from comems4build_ros.core.scenario import resolve_scenario

    params = load_plant_params()

    def read(path: Path) -> Any:
        return resolve_scenario(str(path), params, hours=6)

    assert accepts_or_names(read, _write(tmp_path, "s.csv", scenario_csv)) is not None

    @bounded(60)
    @given(mutated(scenario_csv))
    def check(data: bytes) -> None:
        accepts_or_names(read, _write(tmp_path, "s.csv", data))

    check()


def test_run_info_reads_valid_data_or_names_the_file(recorded_bag: Path, tmp_path: Path) -> None:  # noqa: F811
    from comems4build_ros.bags.evaluation import read_run_info

    bag = tmp_path / "bag"
    shutil.copytree(recorded_bag, bag)
    valid = json.dumps({"ems": "thermostat", "scenario": "default", "forecast": None, "config_files": [],
                        "overrides": {"battery.e_max_kwh": 6.5}}).encode()

    def read(path: Path) -> Any:
        return read_run_info(bag)

    @bounded(60)
    @given(mutated(valid) | st.recursive(st.none() | st.integers() | st.text(max_size=4),
                                         lambda c: st.lists(c, max_size=3)
                                         | st.dictionaries(st.sampled_from(["config_files", "overrides", "ems", "x"]),
                                                           c, max_size=4), max_leaves=12)
           .map(lambda d: json.dumps(d).encode()))
    def check(data: bytes) -> None:
        info = accepts_or_names(read, _write(bag, "run_info.json", data))
        if info is not None:  # what the evaluation reads has its type
            assert isinstance(info, dict) and all(isinstance(f, str) for f in info.get("config_files") or [])
            assert isinstance(info.get("overrides") or {}, dict)

    check()


def test_reproduce_json_is_checked_before_use(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from comems4build_ros.report.reproduce_doc import REPORT_KEYS, ReportFileError, check_report

    valid = {k: (None if type(None) in t else t[0]()) for k, t in REPORT_KEYS.items()}
    valid.update(seeds=[57], figures={"fig": "figures/fig.png"}, weeks=12)
    assert check_report(valid, "r.json") is valid

    @bounded(80)
    @given(st.dictionaries(st.sampled_from(sorted(REPORT_KEYS)), st.none() | st.integers() | st.floats()
                           | st.text(max_size=5) | st.lists(st.integers(), max_size=2)
                           | st.dictionaries(st.text(max_size=3), st.text(max_size=8), max_size=2), max_size=6)
           | st.lists(st.integers(), max_size=3) | st.text(max_size=5))
    def check(edit: Any) -> None:
        doc = {**valid, **edit} if isinstance(edit, dict) else edit
        try:
            check_report(doc, "r.json")
        except ReportFileError as exc:
            assert str(exc).startswith("r.json: ")

    check()
    path = tmp_path / "bad.json"
    for doc in ([1], {"runs_made": "x"}, {**valid, "figures": {"x": "/etc/passwd"}}):
        path.write_text(json.dumps(doc))
        code, _, err = run_cli(["reproduce", "--from-json", path, "--out", tmp_path / "r"], capsys)
        assert code == 2 and str(path) in err, err


def test_bags_evaluate_or_are_refused_naming_them(recorded_bag: Path, tmp_path: Path,  # noqa: F811
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    base = (recorded_bag / "bag.mcap").read_bytes()
    seen: set[int] = set()

    @bounded(12)
    @given(st.integers(0, len(base) - 1), st.integers(1, 64), st.sampled_from(["cut", "garbage", "zero"]))
    def check(at: int, n: int, how: str) -> None:
        bag = tmp_path / f"bag{len(seen)}"
        seen.add(len(seen))
        shutil.copytree(recorded_bag, bag)
        data = bytearray(base)
        if how == "cut":
            data = data[:at]
        else:
            data[at:at + n] = (b"\xab" if how == "garbage" else b"\x00") * len(data[at:at + n])
        (bag / "bag.mcap").write_bytes(bytes(data))
        with time_limit():
            code, _, err = run_cli(["evaluate", bag, "--out", tmp_path / f"e{len(seen)}", "--accept-gaps"], capsys)
        assert code in (0, 2), err
        assert "Traceback" not in err and (code == 0 or str(bag) in err), err

    check()
