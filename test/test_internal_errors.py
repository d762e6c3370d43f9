"""Bugs are bugs: only the input checks' errors end in exit code 2.

Any other exception (a ``ValueError`` of pandas or numpy, a ``KeyError``, a bug) prints one
line, ``internal error: ..., report with FILE``, writes the traceback to ``FILE`` (in the
output folder, under a name the output layer never counts as a result, or in the temporary
folder when there is none) and ends with exit code 70 (``EX_SOFTWARE``). Property tests
drive every command's argument parsing and checks with random inputs of the kinds its
options take and expect exit code 0, 1 or 2, never 70: each command on a path that stops
before its work (``--print-plan``, an ``--out`` under a regular file, a run of a few hours).
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import PRICES, SOLAR, TEMPERATURE, recorded_bag, run_cli  # noqa: F401 (a fixture)

from comems4build_ros.app.cli import COMMANDS, EX_SOFTWARE
from comems4build_ros.core.config import PlantParams
from comems4build_ros.files.outputs import INTERNAL_ERROR_PREFIX

FEW = settings(max_examples=12, derandomize=True, database=None, deadline=None,
               suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
LINE = re.compile(r"^comems4build (\S+): internal error: (.+), report with (\S+)$")


def _bug(monkeypatch: pytest.MonkeyPatch, exc: BaseException) -> None:
    """A defect deep in the in-process loop: the plant's step raises ``exc``."""
    from comems4build_ros.core import plant

    def broken(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(plant.Plant, "step", broken)


@pytest.mark.parametrize("exc", [ValueError("cannot convert float NaN to integer"), KeyError("t_air_c"),
                                 ZeroDivisionError("float division by zero"), TypeError("unsupported operand")],
                         ids=["ValueError", "KeyError", "ZeroDivisionError", "TypeError"])
@pytest.mark.parametrize("out_exists", [True, False])
def test_a_defect_is_an_internal_error_with_its_traceback_in_a_file(exc: BaseException, out_exists: bool,
                                                                   tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    if out_exists:
        out.mkdir()
        (out / "notes.txt").write_text("mine\n")
    _bug(monkeypatch, exc)
    code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "3", "--no-progress", "--out", out], capsys)
    assert code == EX_SOFTWARE == 70, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # one line, no traceback on the console
    m = LINE.match(lines[0])
    assert m and m.group(1) == "simulate" and type(exc).__name__ in m.group(2) and "invalid input" not in err, err
    report = Path(m.group(3))
    assert report.is_file() and report.name.startswith(INTERNAL_ERROR_PREFIX)
    text = report.read_text()
    assert "Traceback (most recent call last)" in text and "broken" in text and "simulate" in text
    if out_exists:
        assert report.parent == out and (out / "notes.txt").read_text() == "mine\n"
        # the next command on the same --out is not stopped by the report: it is no result nor foreign entry
        monkeypatch.undo()
        code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "3", "--no-progress", "--out", out], capsys)
        assert code == 0, err
    else:
        assert report.parent == Path(tempfile.gettempdir()) and not out.exists()
        report.unlink()


def test_an_input_error_from_the_checks_is_still_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "3", "--set", "battery.e_max_kwh=-1",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "internal error" not in err and "battery.e_max_kwh" in err, err


# ------------------------------------------------------------------------------ every command, random inputs
def _numeric_fields() -> list[str]:
    return [f"{s}.{n}" for s, f in PlantParams.model_fields.items() for n, g in f.annotation.model_fields.items()
            if g.annotation in (float, int)]


NUMBERS = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
                    st.integers(-10**6, 10**6).map(str),
                    st.sampled_from(["0", "5e-324", "1e308", "-1", "0.5", "1e-9", "nan", "inf", "x", ""]))
SETS = st.lists(st.tuples(st.sampled_from(_numeric_fields()), NUMBERS).map(lambda t: f"{t[0]}={t[1]}"),
                max_size=2)
STARTS = st.sampled_from([None, "2022-12-05", "2022-12-05T10:00", "2023-03-26T02:30", "2030-01-01", "yesterday",
                          "2022-12-01T00:00+01:00"])
EMS = st.sampled_from(["thermostat", "rbc", "fuzzy", "mpc", "nosuch"])


def _flags(**opts: object) -> list[str]:
    out: list[str] = []
    for k, v in opts.items():
        if v is None or v is False:
            continue
        out += [f"--{k.replace('_', '-')}"] if v is True else [f"--{k.replace('_', '-')}", str(v)]
    return out


def _sets(sets: list[str]) -> list[str]:
    return [a for s in sets for a in ("--set", s)]


def _never_70(argv: list, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(argv, capsys)
    assert code in (0, 1, 2), (argv, code, err[-2000:])
    assert "internal error" not in err and "Traceback" not in err, (argv, err[-2000:])


@pytest.fixture(scope="module")
def blocked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An ``--out`` under a regular file: every check before the output's runs, then exit 2."""
    f = tmp_path_factory.mktemp("blocked") / "a-file"
    f.write_text("x")
    return f / "out"


@FEW
@given(ems=EMS, hours=st.integers(1, 3), sets=SETS, start=STARTS, seed=st.none() | st.integers(-1, 2**33))
def test_simulate_random_inputs_never_end_in_an_internal_error(tmp_path_factory: pytest.TempPathFactory,
                                                               capsys: pytest.CaptureFixture[str], ems: str,
                                                               hours: int, sets: list[str], start: str | None,
                                                               seed: int | None) -> None:
    out = tmp_path_factory.mktemp("s") / "r"
    _never_70(["simulate", "--ems", ems, "--hours", hours, *_sets(sets), *_flags(start=start, seed=seed),
               "--no-progress", "--out", out], capsys)


@FEW
@given(ems=EMS, houses=st.integers(0, 5), layout=st.sampled_from([None, "node", "role", "house"]),
       clock=st.sampled_from(["sim", "wall", "wall:3600", "wall:1e308", "wall:0.5", "wall:x"]),
       plant=st.sampled_from(["sim", "mqtt"]), steps=st.none() | st.integers(0, 10**6), sets=SETS,
       namespace=st.none() | st.text(alphabet="/ab_1", max_size=6), start=STARTS)
def test_launch_plans_from_random_inputs_never_end_in_an_internal_error(
        tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], ems: str, houses: int,
        layout: str | None, clock: str, plant: str, steps: int | None, sets: list[str], namespace: str | None,
        start: str | None) -> None:
    out = tmp_path_factory.mktemp("l") / "r"
    _never_70(["launch", "--ems", ems, "--houses", houses, "--clock", clock, "--plant", plant, *_sets(sets),
               *_flags(layout=layout, steps=steps, namespace=namespace, start=start), "--print-plan",
               "--out", out], capsys)


@FEW
@given(ems=st.lists(EMS, min_size=1, max_size=3).map(",".join), weeks=NUMBERS, sets=SETS,
       etas=st.none() | st.lists(NUMBERS, min_size=1, max_size=2).map(",".join),
       scenario=st.sampled_from(["default", "synthetic", "year", "nosuch.csv"]), jobs=st.none() | st.integers(0, 4))
def test_compare_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str],
                                                              ems: str, weeks: str, sets: list[str], etas: str | None,
                                                              scenario: str, jobs: int | None) -> None:
    _never_70(["compare", "--ems", ems, "--weeks", weeks, *_sets(sets), "--scenario", scenario,
               *_flags(fc_efficiency=etas, jobs=jobs), "--no-progress", "--out", blocked], capsys)


@FEW
@given(ems=st.lists(EMS, min_size=1, max_size=2).map(",".join), param=st.sampled_from(_numeric_fields()),
       values=st.lists(NUMBERS, min_size=1, max_size=3).map(",".join), weeks=NUMBERS)
def test_sweep_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str],
                                                            ems: str, param: str, values: str, weeks: str) -> None:
    _never_70(["sweep", "--ems", ems, "--param", f"{param}={values}", "--weeks", weeks, "--no-progress",
               "--out", blocked], capsys)


@FEW
@given(ems=st.lists(EMS, min_size=1, max_size=2).map(",".join),
       axis=st.sampled_from(["--pv-kwp", "--battery-kwh", "--el-modules", "--fc-kw", "--h2-kwh"]),
       values=st.lists(NUMBERS, min_size=1, max_size=3).map(",".join), sample=st.none() | st.integers(-1, 20),
       weeks=NUMBERS)
def test_size_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str], ems: str,
                                                           axis: str, values: str, sample: int | None,
                                                           weeks: str) -> None:
    _never_70(["size", "--ems", ems, axis, values, "--weeks", weeks, *_flags(sample=sample), "--no-progress",
               "--out", blocked], capsys)


#: The shipped community file, for the community commands' random inputs.
COMMUNITY_FILE = str(Path(__file__).resolve().parents[1] / "config" / "community" / "default.yaml")
COORDINATORS = st.sampled_from(["rule", "fuzzy", "central", "distributed", "nosuch"])
COORDINATOR_OPTIONS = st.sampled_from(["rule.h2_split=need", "rule.need_days=0", "fuzzy.rules=no_such.yaml",
                                       "central.max_houses=1", "distributed.rho_eur_per_kw2=-1", "rule.x=1",
                                       "h2_split=need", "nosuch.x=1"])


@FEW
@given(kwh=st.lists(NUMBERS, min_size=1, max_size=2).map(",".join),
       modules=st.lists(st.integers(-2, 40).map(str) | NUMBERS, min_size=1, max_size=2).map(",".join),
       weeks=NUMBERS, coordinator=COORDINATORS, option=st.none() | COORDINATOR_OPTIONS)
def test_size_community_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str],
                                                                     kwh: str, modules: str, weeks: str,
                                                                     coordinator: str, option: str | None) -> None:
    _never_70(["size", "--community", COMMUNITY_FILE, "--hub-kwh", kwh, "--hub-modules", modules, "--weeks", weeks,
               "--coordinator", coordinator, *(["--coordinator-option", option] if option else []), "--no-progress",
               "--out", blocked], capsys)


@FEW
@given(coordinator=COORDINATORS, option=st.none() | COORDINATOR_OPTIONS, steps=st.integers(-1, 6).map(str) | NUMBERS,
       ems=EMS)
def test_launch_community_random_inputs_never_end_in_an_internal_error(blocked: Path,
                                                                       capsys: pytest.CaptureFixture[str],
                                                                       coordinator: str, option: str | None,
                                                                       steps: str, ems: str) -> None:
    _never_70(["launch", "--community", COMMUNITY_FILE, "--ems", ems, "--coordinator", coordinator,
               *(["--coordinator-option", option] if option else []), "--steps", steps, "--out", blocked], capsys)


@FEW
@given(weeks=NUMBERS, seeds=st.lists(st.integers(-5, 2**33).map(str) | NUMBERS, min_size=1, max_size=3).map(",".join),
       only=st.none() | st.sampled_from(["rbc", "x,y", ""]))
def test_reproduce_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str],
                                                                weeks: str, seeds: str, only: str | None) -> None:
    _never_70(["reproduce", "--no-study", "--weeks", weeks, "--seeds", seeds, *_flags(only=only), "--no-figures",
               "--no-progress", "--out", blocked], capsys)


@FEW
@given(weeks=NUMBERS, cases=st.sampled_from(["paper-s57", "household-101", "nosuch", ""]),
       ems=st.lists(EMS, min_size=1, max_size=2).map(",".join))
def test_validate_random_inputs_never_end_in_an_internal_error(blocked: Path, capsys: pytest.CaptureFixture[str],
                                                               weeks: str, cases: str, ems: str) -> None:
    _never_70(["validate", "--cases", cases, "--ems", ems, "--weeks", weeks, "--no-figures", "--no-progress",
               "--out", blocked], capsys)


@FEW
@given(no_ts=st.booleans(), gaps=st.booleans(), sets=SETS)
def test_evaluate_random_inputs_never_end_in_an_internal_error(tmp_path_factory: pytest.TempPathFactory,
                                                               recorded_bag: Path,  # noqa: F811
                                                               capsys: pytest.CaptureFixture[str], no_ts: bool,
                                                               gaps: bool, sets: list[str]) -> None:
    out = tmp_path_factory.mktemp("e") / "r"
    _never_70(["evaluate", recorded_bag, *_flags(no_timeseries=no_ts, accept_gaps=gaps), "--out", out], capsys)


@FEW
@given(seed=st.integers(-1, 2**33), dhw_year=st.none() | st.integers(1800, 2300), start=STARTS)
def test_data_build_random_inputs_never_end_in_an_internal_error(tmp_path_factory: pytest.TempPathFactory,
                                                                 capsys: pytest.CaptureFixture[str], seed: int,
                                                                 dhw_year: int | None, start: str | None) -> None:
    out = tmp_path_factory.mktemp("d") / "s.csv"
    _never_70(["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR, "--seed", seed,
               *_flags(dhw_year=dhw_year), "--out", out], capsys)


@FEW
@given(chi=NUMBERS, dpi=st.integers(-5, 5000))
def test_fuzzy_surface_random_inputs_never_end_in_an_internal_error(blocked: Path,
                                                                    capsys: pytest.CaptureFixture[str], chi: str,
                                                                    dpi: int) -> None:
    _never_70(["fuzzy-surface", "--chi", chi, "--dpi", dpi, "--out", blocked], capsys)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_with_no_or_unknown_options_ends_in_usage_not_an_internal_error(
        command: str, capsys: pytest.CaptureFixture[str]) -> None:
    for argv in ([command, "--no-such-option"], [command, "--out"]):
        code, _, err = run_cli(argv, capsys)
        assert code in (0, 2) and "internal error" not in err, (argv, err[-1000:])


@FEW
@given(weeks=NUMBERS, seed=st.integers(-1, 2**33), sets=SETS)
def test_export_identify_house_cosim_random_inputs_never_end_in_an_internal_error(
        blocked: Path, capsys: pytest.CaptureFixture[str], weeks: str, seed: int, sets: list[str]) -> None:
    for argv in (["export-fmu", *_sets(sets), "--out", blocked / "rc.fmu"],
                 ["identify", "--seed", seed, "--out", blocked / "id.yaml"],
                 ["house", "--weeks", weeks, "--json", blocked / "house.json"],
                 ["cosim-study", "--weeks", weeks, "--no-progress", "--out", blocked]):
        _never_70(argv, capsys)


#: Each benchmark's numeric options: parsed and checked, then ``--help`` (argparse checks the values given before it).
BENCH_NUMERIC = {"plant": ("--weeks", "--repeats", "--seed"), "ems": ("--weeks", "--skfuzzy-steps"),
                 "mpc": ("--loop-weeks", "--weeks", "--days-per-kind", "--time-limit", "--kpi-weeks"),
                 "ros": ("--weeks", "--containers", "--timeout"), "cut": ("--runs",),
                 "study": ("--runs", "--seed", "--repeats"), "year": ("--weeks", "--timeout"), "cosim": ("--weeks",),
                 "coordinators": ("--houses", "--hours", "--every", "--central-max")}


@FEW
@given(bench=st.sampled_from(sorted(BENCH_NUMERIC)), data=st.data())
def test_bench_options_from_random_numbers_never_end_in_an_internal_error(capsys: pytest.CaptureFixture[str],
                                                                         bench: str, data: st.DataObject) -> None:
    argv: list[object] = ["bench", bench]
    for option in BENCH_NUMERIC[bench]:
        argv += [option, data.draw(NUMBERS)]
    _never_70([*argv, "--help"], capsys)
