"""Bad input through the real command line: each case ends with exit code 2 and a message naming
the option, file, section or parameter, never a traceback or a silently wrong result; results
are written all or nothing.

One parametrised test per kind of input (numeric options, plant parameter files, scenario
files, output paths, data sources, damaged bags); each case fails without the check it covers.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.scenario import resolve_scenario, write_scenario_csv

FIXTURES = Path(__file__).parent / "fixtures"
PRICES = FIXTURES / "awattar_15min.json"
TEMPERATURE = FIXTURES / "dwd_10min_tt_4177.txt"
SOLAR = FIXTURES / "dwd_10min_solar_4177.txt"
REPO = Path(__file__).resolve().parents[1]


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``comems4build argv`` (argparse errors included)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def param_file(path: Path, text: str) -> Path:
    """A ROS 2 parameter file with ``text`` (YAML, indented under ros__parameters)."""
    body = "\n".join("    " + line for line in text.strip().splitlines())
    path.write_text(f"/**:\n  ros__parameters:\n{body}\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def good_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A valid 48 h scenario CSV (the beginning of the default scenario)."""
    path = tmp_path_factory.mktemp("csv") / "good.csv"
    scen = resolve_scenario("default", load_plant_params(), hours=48)
    write_scenario_csv(scen, path)
    return path


# ---------------------------------------------------------------------------- numeric options
NUMERIC = [
    (["simulate", "--ems", "thermostat", "--weeks", "0"], "--weeks"),
    (["simulate", "--ems", "thermostat", "--weeks", "inf"], "--weeks"),
    (["simulate", "--ems", "thermostat", "--weeks", "nan"], "--weeks"),
    (["simulate", "--ems", "thermostat", "--weeks", "-1"], "--weeks"),
    (["simulate", "--ems", "thermostat", "--hours", "0"], "--hours"),
    (["simulate", "--ems", "thermostat", "--hours", "1.5"], "--hours"),
    (["simulate", "--ems", "thermostat", "--seed", "-1"], "--seed"),
    (["launch", "--ems", "fuzzy", "--weeks", "0"], "--weeks"),
    (["launch", "--ems", "fuzzy", "--weeks", "nan"], "--weeks"),
    (["launch", "--ems", "fuzzy", "--steps", "0"], "--steps"),
    (["launch", "--ems", "fuzzy", "--houses", "0"], "--houses"),
    (["launch", "--ems", "fuzzy", "--domain-id", "500"], "--domain-id"),
    (["launch", "--ems", "fuzzy", "--timeout", "inf"], "--timeout"),
    (["launch", "--ems", "fuzzy", "--step-timeout", "-1"], "--step-timeout"),
    (["compare", "--weeks", "inf"], "--weeks"),
    (["compare", "--weeks", "1", "--jobs", "0"], "--jobs"),
    (["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--weeks", "nan"], "--weeks"),
    (["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--jobs", "-2"], "--jobs"),
    (["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR, "--dhw-year", "0"],
     "--dhw-year"),
    (["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR, "--seed", "x"], "--seed"),
    (["bench", "plant", "--repeats", "0"], "--repeats"),
    (["bench", "plant", "--weeks", "inf"], "--weeks"),
    (["bench", "ems", "--weeks", "0"], "--weeks"),
    (["bench", "mpc", "--time-limit", "nan"], "--time-limit"),
    (["bench", "mpc", "--kpi-weeks", "-1"], "--kpi-weeks"),
    (["bench", "ros", "--weeks", "0"], "--weeks"),
    (["fuzzy-surface", "--chi", "2"], "--chi"),
    (["fuzzy-surface", "--dpi", "0"], "--dpi"),
]


@pytest.mark.parametrize(("argv", "option"), NUMERIC, ids=[" ".join(map(str, a)) for a, _ in NUMERIC])
def test_numeric_option_out_of_range_exits_2_naming_it(argv: list, option: str, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / ("out.csv" if argv[0] == "data" else "out")
    code, _, err = run_cli([*argv, "--out", out], capsys)
    assert code == 2
    assert f"argument {option}" in err and ("allowed" in err or "not " in err)
    assert not out.exists()  # nothing was started


# ---------------------------------------------------------------------------- run length
def test_run_longer_than_the_scenario_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "thermostat", "--weeks", "13", "--out", tmp_path / "r"], capsys)
    assert code == 2 and "only 2136" in err and "--extend synthetic" in err
    assert not (tmp_path / "r").exists()


def test_launch_longer_than_the_scenario_is_refused_before_any_node(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["launch", "--ems", "rbc", "--weeks", "13", "--out", tmp_path / "r"], capsys)
    assert code == 2 and "only 2136" in err
    assert not (tmp_path / "r").exists()


def test_extend_synthetic_is_said_in_the_summary(good_csv: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["simulate", "--ems", "thermostat", "--scenario", good_csv, "--hours", "80", "--no-progress"]
    code, _, err = run_cli([*argv, "--out", tmp_path / "no"], capsys)
    assert code == 2 and "only 72" in err  # 48 h and the 24 h look-ahead
    code, _, err = run_cli([*argv, "--extend", "synthetic", "--seed", "5", "--out", tmp_path / "yes"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "yes" / "summary.json").read_text())
    ext = summary["scenario_extended"]
    assert ext["method"] == "synthetic" and ext["seed"] == 5
    assert ext["from"] == "2022-12-04T00:00:00+01:00" and ext["run_steps_extended"] == 8
    assert ext["rows"] == 8 + 24  # the run's missing hours and its look-ahead
    assert summary["steps"] == 80 and "extended with" in err


def test_seed_and_hours_of_simulate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def load(seed: int | None, name: str) -> np.ndarray:
        argv = ["simulate", "--ems", "thermostat", "--hours", "30", "--no-progress", "--out", tmp_path / name]
        code, _, err = run_cli(argv + ([] if seed is None else ["--seed", str(seed)]), capsys)
        assert code == 0, err
        return pd.read_csv(tmp_path / name / "timeseries.csv")["p_load_w"].to_numpy()  # modelled with the seed

    default, s3, s3b = load(None, "d"), load(3, "a"), load(3, "b")
    assert len(default) == 30
    np.testing.assert_array_equal(s3, s3b)
    assert not np.allclose(s3, default)


def test_seed_with_a_csv_is_refused(good_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "thermostat", "--scenario", good_csv, "--seed", "3",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "seed" in err and "good.csv" in err


def test_partial_week_has_its_own_marked_row_and_stays_out_of_the_medians(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "thermostat", "--hours", "200", "--no-progress",
                            "--out", tmp_path / "r"], capsys)
    assert code == 0, err
    weekly = pd.read_csv(tmp_path / "r" / "weekly.csv")
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert list(weekly["full_week"]) == [True, False] and list(weekly["hours"]) == [168.0, 32.0]
    assert summary["full_weeks"] == 1 and summary["partial_week_h"] == 32.0
    assert summary["cost_eur_week_median"] == weekly["cost_eur"].iloc[0]  # not the median of 168 h and 32 h
    assert summary["buy_kwh_week_median"] == weekly["buy_kwh"].iloc[0]


# ---------------------------------------------------------------------------- plant parameters
CONFIG_CASES = [
    ("batery:\n  e_max_kwh: 10.0", "unknown section 'batery'"),
    ("mpc:\n  solver: nosuchsolver", "section 'mpc'"),
    ("battery:\n  e_max_kwh: true", "battery.e_max_kwh"),
    ("battery:\n  e_max_kwh: .inf", "battery.e_max_kwh"),
    ("hydrogen:\n  e_max_kwh: .nan", "hydrogen.e_max_kwh"),
    ("site:\n  timezone: Mars/Olympus", "Mars/Olympus"),
]


@pytest.mark.parametrize(("text", "named"), CONFIG_CASES, ids=[c[1] for c in CONFIG_CASES])
def test_config_file_problem_exits_2_naming_it(text: str, named: str, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    cfg = param_file(tmp_path / "bad.yaml", text)
    code, _, err = run_cli(["simulate", "--ems", "mpc", "--hours", "2", "--config", cfg, "--out", tmp_path / "r"],
                           capsys)
    assert code == 2 and named in err
    assert not (tmp_path / "r").exists()


SET_CASES = [
    ("simulation.time_step_h=2", "simulation.time_step_h"),
    ("simulation.time_step_h=0.25", "simulation.time_step_h"),
    ("battery.e_max_kwh=1e400", "battery.e_max_kwh"),
    ("battery.e_max_kwh=true", "battery.e_max_kwh"),
    ("batery.e_max_kwh=10", "unknown section 'batery'"),
]


@pytest.mark.parametrize(("assignment", "named"), SET_CASES, ids=[c[0] for c in SET_CASES])
@pytest.mark.parametrize("command", ["simulate", "launch"])
def test_set_problem_exits_2_naming_it(command: str, assignment: str, named: str, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli([command, "--ems", "rbc", "--weeks", "1", "--set", assignment, "--out", tmp_path / "r"],
                           capsys)
    assert code == 2 and named in err
    assert not (tmp_path / "r").exists()  # launch: refused before any node started


def test_battery_power_zero_names_the_battery_parameter(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "fuzzy", "--hours", "2", "--set", "battery.p_d_max_w=0",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2
    assert err.split("error: ", 1)[1].startswith("plant parameter battery.p_d_max_w = 0")


def test_mpc_that_never_solves_counts_its_fallbacks_and_fails(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """An "mpc" run in which the MPC decided no step exits 1 saying so (its fallback results are kept)."""
    code, _, err = run_cli(["simulate", "--ems", "mpc", "--hours", "6", "--ems-option",
                            "highs_options={simplex_iteration_limit: 0, mip_max_nodes: 0}",
                            "--ems-option", "log_fallback=false", "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 1, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["fallback_steps"] == 6 and summary["ems_fallback_steps"] == 6
    assert "warning: 6 of 6 steps ran on the safe fallback action" in err
    assert "error: the EMS decided none of the 6 steps" in err


@pytest.mark.parametrize(("causes", "code"), [
    ({"user_switch": 12}, 0),  # the building's user put every step on the fallback: their choice
    ({"user_switch": 11, "late_command": 1}, 1),  # the EMS decided none of the steps left to it
    ({"late_command": 12}, 1),
])
def test_a_run_all_on_the_fallback_fails_unless_the_user_chose_it(causes: dict, code: int,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from comems4build_ros.app.commands.simulate import warn_run

    summary = {"steps": 12, "fallback_steps": 12, "ems_fallback_steps": 0, "fallback_causes": causes}
    assert warn_run(summary, "launch") == code
    err = capsys.readouterr().err
    assert "warning: 12 of 12 steps ran on the safe fallback action" in err
    assert ("error: the EMS decided none of the 12 steps" in err) == bool(code)


def test_unmet_hot_water_is_warned_not_only_counted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A tank started near V_DHW,min cannot serve the first morning draw: the run says so."""
    code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "24", "--set", "simulation.v_dhw_init_l=41",
                            "--set", "dhw.v_max_l=120", "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["dhw_unmet_steps"] >= 1 and summary["dhw_unmet_kwh"] > 0
    assert (f"warning: the hot-water demand was not met in {summary['dhw_unmet_steps']} of 24 steps" in err
            and summary["dhw_unmet_first"] in err)


# ---------------------------------------------------------------------------- input files
def _variant(good: Path, tmp_path: Path, kind: str) -> Path:
    text = good.read_text()
    path = tmp_path / f"{kind}.csv"
    if kind == "semicolon":
        path.write_text(text.replace(",", ";"))
    elif kind == "duplicate":
        lines = text.splitlines()
        path.write_text("\n".join([lines[0] + ",t_amb_c"] + [line + ",99" for line in lines[1:]]) + "\n")
    elif kind == "binary":
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    elif kind == "gap":  # one missing value: simulate interpolates it, the ROS feed refuses it
        lines = text.splitlines()
        fields = lines[10].split(",")
        fields[1] = ""
        lines[10] = ",".join(fields)
        path.write_text("\n".join(lines) + "\n")
    return path


SCENARIO_CASES = [
    ("semicolon", "separated by ';' (semicolon)"),
    ("duplicate", "column 't_amb_c' appears twice"),
    ("binary", "binary content"),
    ("directory", "is a directory"),
    ("devnull", "is not a regular file"),
]


@pytest.mark.parametrize(("kind", "message"), SCENARIO_CASES, ids=[c[0] for c in SCENARIO_CASES])
@pytest.mark.parametrize("command", ["simulate", "launch"])
def test_bad_scenario_file_exits_2_saying_what_was_found(command: str, kind: str, message: str, good_csv: Path,
                                                         tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = {"directory": tmp_path, "devnull": Path(os.devnull)}.get(kind) or _variant(good_csv, tmp_path, kind)
    code, _, err = run_cli([command, "--ems", "rbc", "--scenario", path, "--out", tmp_path / "r"], capsys)
    assert code == 2 and message in err and str(path.name or path) in err
    assert not (tmp_path / "r").exists()  # launch: no node started


def test_launch_refuses_a_scenario_the_feed_would_refuse_before_starting(good_csv: Path, tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    gap = _variant(good_csv, tmp_path, "gap")
    code, _, err = run_cli(["launch", "--ems", "rbc", "--scenario", gap, "--out", tmp_path / "r"], capsys)
    assert code == 2 and "gap.csv" in err and "t_amb_c" in err and "refuses" in err
    assert not (tmp_path / "r").exists()


FILE_CASES = [
    (["--config", "DIR"], "--config", "is a directory"),
    (["--config", os.devnull], "--config", "is not a regular file"),
    (["--config", "BINARY"], "bin.yaml", "not UTF-8 text"),
]


@pytest.mark.parametrize(("extra", "named", "message"), FILE_CASES, ids=["config-dir", "config-devnull",
                                                                        "config-binary"])
def test_unreadable_parameter_file_is_described(extra: list[str], named: str, message: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    extra = [{"DIR": str(tmp_path), "BINARY": str(binary)}.get(a, a) for a in extra]
    code, _, err = run_cli(["simulate", "--ems", "rbc", *extra, "--out", tmp_path / "r"], capsys)
    assert code == 2 and named in err and message in err


# ---------------------------------------------------------------------------- data sources
def _dhw(path: Path, rows: list[str]) -> Path:
    path.write_text("\n".join(rows) + "\n")
    return path


def _build(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, **sources: Path) -> tuple[int, str]:
    files = {"prices": PRICES, "temperature": TEMPERATURE, "solar": SOLAR, **sources}
    argv = ["data", "build", *[x for k, v in files.items() for x in (f"--{k}", v)], "--out", tmp_path / name]
    code, _, err = run_cli(argv, capsys)
    return code, err


def test_two_column_dhwcalc_file_reads_the_draw_column(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(0)
    draws = rng.choice([0.0, 0.0, 0.0, 5.5, 12.0], 8760)
    one = _dhw(tmp_path / "one.txt", [f"{v}" for v in draws])
    two = _dhw(tmp_path / "two.txt", [f"{i};{v}" for i, v in enumerate(draws)])
    assert _build(tmp_path, capsys, "one.csv", dhw=one)[0] == 0
    assert _build(tmp_path, capsys, "two.csv", dhw=two)[0] == 0
    a = pd.read_csv(tmp_path / "one.csv")["dhw_l_per_h"]
    b = pd.read_csv(tmp_path / "two.csv")["dhw_l_per_h"]
    pd.testing.assert_series_equal(a, b)
    assert b.max() <= 12.0  # never the row index (up to 8759 l/h)
    bad = _dhw(tmp_path / "bad.txt", [f"{2 * i};{v}" for i, v in enumerate(draws)])
    code, err = _build(tmp_path, capsys, "bad.csv", dhw=bad)
    assert code == 2 and "bad.txt" in err and "step counter" in err


def test_dwd_file_with_every_value_missing_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = TEMPERATURE.read_text(encoding="latin-1").splitlines()
    col = [c.strip() for c in lines[0].split(";")].index("TT_10")
    rows = [lines[0]]
    for line in lines[1:]:
        fields = line.split(";")
        fields[col] = "-999"
        rows.append(";".join(fields))
    bad = tmp_path / "tt_missing.txt"
    bad.write_text("\n".join(rows) + "\n", encoding="latin-1")
    code, err = _build(tmp_path, capsys, "x.csv", temperature=bad)
    assert code == 2 and "tt_missing.txt" in err and "TT_10" in err and "missing" in err


def test_binary_json_and_directory_sources_are_described(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    binary = tmp_path / "prices.json"
    binary.write_bytes(b"\x1f\x8b\x08\x00" + bytes(range(200)))
    code, err = _build(tmp_path, capsys, "x.csv", prices=binary)
    assert code == 2 and "prices.json" in err and "binary" in err
    code, err = _build(tmp_path, capsys, "x.csv", temperature=tmp_path)
    assert code == 2 and "--temperature" in err and "is a directory" in err


# ---------------------------------------------------------------------------- output paths
def _command(name: str, out: Path, bag: Path) -> list:
    return {
        "simulate": ["simulate", "--ems", "thermostat", "--hours", "24", "--no-progress", "--out", out],
        "launch": ["launch", "--ems", "rbc", "--weeks", "1", "--steps", "4", "--no-progress", "--out", out],
        "data build": ["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR,
                       "--out", out],
        "evaluate": ["evaluate", bag, "--out", out],
    }[name]


@pytest.mark.parametrize("command", ["simulate", "launch", "data build", "evaluate"])
@pytest.mark.parametrize("where", ["existing file", "under a file"])
def test_out_that_cannot_be_a_result_is_refused_before_the_run(command: str, where: str, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "taken"
    blocker.write_text("keep me\n")
    if command == "data build":  # --out is a file: a directory stands in the way, or a file as its parent
        target = tmp_path if where == "existing file" else blocker / "x.csv"
    else:
        target = blocker if where == "existing file" else blocker / "run"
    code, _, err = run_cli(_command(command, target, tmp_path), capsys)
    assert code == 2 and "--out" in err, err
    assert blocker.read_text() == "keep me\n"


def _namespace_mount_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "sh", "-c",
                            "mount -t tmpfs -o size=16k tmpfs /mnt"], capture_output=True, timeout=30)
    return probe.returncode == 0


NEEDS_MOUNT = pytest.mark.skipif(not _namespace_mount_works(),
                                 reason="cannot mount a tmpfs in a user namespace here (unshare)")


def _in_small_mount(tmp_path: Path, options: str, argv: list, fill: bool = False) -> subprocess.CompletedProcess:
    """Run the CLI in a private mount namespace where ``tmp_path/mnt`` is a tmpfs with ``options``.

    ``fill``: a file takes all the space first, so that even a small result cannot be written.
    """
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    code = "import sys; from comems4build_ros.app.cli import main; sys.exit(main(sys.argv[1:]))"
    filler = 'cat /dev/zero > "$1/filler" 2>/dev/null; ' if fill else ""
    script = f'mount -t tmpfs -o {options} tmpfs "$1" && {{ {filler}true; }} && shift && exec "$@"'
    cmd = ["unshare", "--user", "--map-root-user", "--mount", "sh", "-c", script, "sh", str(mnt),
           sys.executable, "-c", code, *[str(a).replace("MNT", str(mnt)) for a in argv]]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=REPO, env=env)


@NEEDS_MOUNT
@pytest.mark.parametrize("command", ["simulate", "data build"])
def test_disk_full_leaves_no_partial_result(command: str, tmp_path: Path) -> None:
    """A real full disk: a 12 KiB tmpfs (the 24 h timeseries alone is about 18 KiB); for the small scenario
    CSV of the test sources, a tmpfs already filled up."""
    out = "MNT/run" if command == "simulate" else "MNT/scenario.csv"
    res = _in_small_mount(tmp_path, "size=12k", _command(command, out, tmp_path), fill=command == "data build")
    assert res.returncode == 2, res.stderr
    assert "No space left on device" in res.stderr and "Traceback" not in res.stderr
    assert "nothing partial" in res.stderr


@NEEDS_MOUNT
@pytest.mark.parametrize("command", ["simulate", "launch", "data build", "evaluate"])
def test_read_only_out_is_refused_before_the_run(command: str, tmp_path: Path) -> None:
    out = "MNT/scenario.csv" if command == "data build" else "MNT/run"
    res = _in_small_mount(tmp_path, "ro,size=64k", _command(command, out, tmp_path))
    assert res.returncode == 2, res.stderr
    assert "--out" in res.stderr and "not writable" in res.stderr


@contextlib.contextmanager
def _enospc_on(write_number: int) -> Iterator[None]:
    """Make the ``write_number``-th ``DataFrame.to_csv`` write half its text, then fail like a full disk."""
    real = pd.DataFrame.to_csv
    calls = {"n": 0}

    def failing(self: pd.DataFrame, path_or_buf: object = None, *args: object, **kwargs: object) -> object:
        calls["n"] += 1
        if calls["n"] != write_number:
            return real(self, path_or_buf, *args, **kwargs)
        text = real(self, None, *args, **kwargs)
        with open(path_or_buf, "w") if isinstance(path_or_buf, str | Path) else contextlib.nullcontext(
                path_or_buf) as fh:
            fh.write(text[: len(text) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    pd.DataFrame.to_csv = failing  # type: ignore[method-assign]
    try:
        yield
    finally:
        pd.DataFrame.to_csv = real  # type: ignore[method-assign]


@pytest.mark.parametrize("write_number", [1, 2])
def test_failed_write_leaves_no_partial_files(write_number: int, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """The OSError injected at the write call (timeseries.csv, then weekly.csv), wherever no tmpfs can be mounted."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    with _enospc_on(write_number):
        code, _, err = run_cli(_command("simulate", out, tmp_path), capsys)
    assert code == 2 and "No space left on device" in err and str(out) in err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]  # no partial timeseries/weekly/summary


# ---------------------------------------------------------------------------- damaged bags
def step_messages(ts: pd.DataFrame, n: int) -> list[tuple[bytes, bytes]]:
    """``(feed/truth, plant/record)`` CDR bytes of each of the first ``n`` steps of an in-process
    timeseries ``ts``, as the feed and the plant publish them (the other inputs zero)."""
    from comems4build_ros.bags.bag import typestore
    from comems4build_ros.core.loop import TIMESERIES_COLUMNS
    from comems4build_ros.wire.contract import load_contract

    contract = load_contract()
    record, truth = contract.topic("plant/record").layout({}), contract.topic("feed/truth").layout({})
    store = typestore()
    cls = store.types["std_msgs/msg/Float64MultiArray"]
    layout = store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)

    def cdr(values: object) -> bytes:
        msg = cls(layout=layout, data=np.asarray(values, dtype=float))
        return bytes(store.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray"))

    out = []
    for k in range(n):
        row = ts.iloc[k]
        time_s = pd.Timestamp(row["time"]).timestamp()
        values = {c: row[c] for c in TIMESERIES_COLUMNS[1:]}
        values.update(time_unix_s=time_s, fallback_steps=0, rejected_commands=0, wrong_step_commands=0,
                      foreign_commands=0)
        exo = dict.fromkeys(truth.index, 0.0)
        exo.update(step=k, n_steps=n, time_unix_s=time_s)
        out.append((cdr(truth.pack(exo)), cdr(record.pack(values))))
    return out


@pytest.fixture(scope="module")
def recorded_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A bag of a 400-step thermostat run written by the project's BagWriter, one chunk per 24 steps."""
    from comems4build_ros.bags.bag import BagWriter
    from comems4build_ros.core.loop import simulate

    params = load_plant_params()
    n = 400
    scen = resolve_scenario("default", params, hours=n)
    messages = step_messages(simulate("thermostat", scen, params).timeseries, n)
    bag = tmp_path_factory.mktemp("bag") / "bag"
    t0 = 1_700_000_000 * 10**9
    with BagWriter(bag) as w:
        w.add_topic("/plant/record", "std_msgs/msg/Float64MultiArray")
        w.add_topic("/feed/truth", "std_msgs/msg/Float64MultiArray")
        for k, (truth, record) in enumerate(messages):
            w.write("/feed/truth", t0 + 2 * k, truth)
            w.write("/plant/record", t0 + 2 * k + 1, record)
            if k % 24 == 23:
                w.flush_chunk()
    return bag


def _damage(bag: Path, tmp_path: Path, how: str) -> Path:
    copy = tmp_path / f"bag_{how}"
    shutil.copytree(bag, copy)
    mcap = copy / "bag.mcap"
    data = bytearray(mcap.read_bytes())
    if how == "truncated":
        mcap.write_bytes(bytes(data[: int(len(data) * 0.6)]))
    elif how == "corrupt":  # garbage over the header (opcode, length) of the first record in the 10th of 17 chunks
        from mcap.reader import make_reader

        with mcap.open("rb") as fh:
            chunk = sorted(make_reader(fh).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)[9]
        assert chunk.compression == ""  # uncompressed: its records start after a fixed 49-byte chunk header
        at = chunk.chunk_start_offset + 49
        data[at : at + 9] = b"\xab" * 9
        mcap.write_bytes(bytes(data))
    elif how == "metadata":
        (copy / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    return copy


def test_intact_bag_evaluates_complete(recorded_bag: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run_cli(["evaluate", recorded_bag, "--out", tmp_path / "e"], capsys)
    assert code == 0, err
    assert f"bag {recorded_bag}: complete" in out
    summary = json.loads((tmp_path / "e" / "summary.json").read_text())
    assert summary["steps"] == 400 and "bag_incomplete" not in summary


@pytest.mark.parametrize("how", ["truncated", "corrupt", "metadata"])
def test_damaged_bag_directory_is_salvaged_and_marked_incomplete(how: str, recorded_bag: Path, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    bag = _damage(recorded_bag, tmp_path, how)
    code, out, err = run_cli(["evaluate", bag, "--out", tmp_path / "e"], capsys)
    assert code == 0, err
    assert f"bag {bag}: incomplete" in out and ": complete" not in out
    summary = json.loads((tmp_path / "e" / "summary.json").read_text())
    weekly = pd.read_csv(tmp_path / "e" / "weekly.csv")
    inc = summary["bag_incomplete"]
    assert inc["steps_expected"] == 400 and inc["damage"]
    if how == "metadata":
        assert inc["steps_recorded"] == 400  # every record salvaged
    else:
        assert 168 <= inc["steps_recorded"] < 400 and inc["truncated_mcap"]
    assert summary["steps"] == inc["steps_recorded"] == len(pd.read_csv(tmp_path / "e" / "timeseries.csv"))
    full = weekly[weekly["full_week"]]
    assert summary["full_weeks"] == len(full) and not weekly["full_week"].iloc[-1]  # last week partial
    assert summary["cost_eur_week_median"] == pytest.approx(full["cost_eur"].median(), abs=1e-6)
