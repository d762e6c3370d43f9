"""Bad input of every class that used to surface late, quietly or as a traceback, through the real
command line: each case ends with exit code 2 and a message naming the option, file, line, column
or parameter, before anything runs or starts (a ``launch`` leaves no ``--out`` behind, so the same
``--out`` can be used again), and results stay all or nothing for ``evaluate``, ``compare`` and
``sweep``.

One parametrised test per class (EMS options, topic maps, broker URLs, plant parameters, data
sources, times, conflicting options, other options), one case per row: a new option or a new
source gets its row here and the same check.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from test_bad_input import PRICES, SOLAR, TEMPERATURE, recorded_bag, run_cli  # noqa: F401 (a fixture)

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.scenario import resolve_scenario, write_scenario_csv

FIXTURES = Path(__file__).parent / "fixtures"


def refused(argv: list, named: str, out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``argv`` (+ ``--out out``); assert exit 2, ``named`` in the message, no traceback, nothing written."""
    code, _, err = run_cli([*argv, "--out", out], capsys)
    assert code == 2, err
    assert named in err, err
    assert "Traceback" not in err
    assert not out.exists()  # nothing ran or started: the same --out can be used again
    return err


# ---------------------------------------------------------------------------- EMS options
EMS_OPTIONS = [
    ("rbc", "foo=1", "parameter 'foo': unknown parameter"),
    ("rbc", "sh_on_chi=1.0", "sh_on_chi (1.0) must be below sh_off_chi (1.0)"),
    ("rbc", "dhw_off_chi=0.1", "dhw_on_chi (0.25) must be below dhw_off_chi (0.1)"),
    ("rbc", "edf_lower_quartile=0.9", "edf_lower_quartile (0.9) must be below edf_upper_quartile"),
    ("rbc", "hp_mod_on=true", "parameter 'hp_mod_on': expected a number, got the boolean True"),
    ("rbc", "p_el_ref_t_amb_c=.inf", "parameter 'p_el_ref_t_amb_c': Input should be a finite number"),
    ("mpc", "time_limit_s=-1", "parameter 'time_limit_s'"),
    ("mpc", "threads=true", "parameter 'threads': expected a number, got the boolean True"),
    ("mpc", "foo=1", "parameter 'foo': unknown parameter"),
    ("mpc-qp", "eps_abs=0", "parameter 'eps_abs'"),
    ("fuzzy", "foo=1", "unknown option(s) foo"),
    ("fuzzy", "flex.hp.foo=1", "[flc_flex] + options: parameter 'flex.hp.foo': unknown parameter (known: update"),
    ("fuzzy", "flex.inputs.chi.foo=1", "variable 'chi': unknown parameter 'foo'"),
    ("fuzzy", "fc.fc.cap_to_demand=3", "parameter 'fc.fc.cap_to_demand': expected true or false, got 3"),
    ("fuzzy", "flex.hp.dhw_priority_chi=true", "parameter 'flex.hp.dhw_priority_chi': expected a number, got"),
    ("thermostat", "foo=1", "[thermostat] + options: parameter 'foo': unknown parameter (known: sh_on_k"),
    ("mpc", "solver=[", "--ems-option 'solver=[': the value is not valid YAML"),
]


@pytest.mark.parametrize(("ems", "option", "named"), EMS_OPTIONS, ids=[f"{e}-{o}" for e, o, _ in EMS_OPTIONS])
@pytest.mark.parametrize("command", ["simulate", "launch"])
def test_ems_option_is_checked_by_the_controller_before_anything_starts(
        command: str, ems: str, option: str, named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    length = ["--hours", "2"] if command == "simulate" else ["--steps", "2"]
    refused([command, "--ems", ems, *length, "--ems-option", option], named, tmp_path / "r", capsys)


# ---------------------------------------------------------------------------- topic map
def _map_edit(edit: Callable[[dict], object]) -> Callable[[Path], Path]:
    """A topic map: the default ``config/mqtt.yaml`` with ``edit`` applied to its ``mqtt`` section."""
    def write(path: Path) -> Path:
        from comems4build_ros.mqtt.topicmap import default_map_file

        doc = yaml.safe_load(default_map_file().read_text(encoding="utf-8"))
        edit(doc["/**"]["ros__parameters"]["mqtt"])
        path.write_text(yaml.safe_dump(doc), encoding="utf-8")
        return path
    return write


def _map_text(text: str) -> Callable[[Path], Path]:
    """A file with ``text`` (a topic map or any other source)."""
    def write(path: Path) -> Path:
        path.write_text(text, encoding="utf-8")
        return path
    return write


TOPIC_MAPS = [
    ("malformed YAML", _map_text("/**:\n  ros__parameters:\n    mqtt: [unclosed\n"), "invalid YAML"),
    ("missing soc", _map_edit(lambda m: m["measurements"].pop("soc")), "measurement(s) ['soc'] missing"),
    ("scale as text", _map_edit(lambda m: m["measurements"]["soc"].update(scale="percent")),
     "parameter 'measurements.soc.scale'"),
    ("scale 0", _map_edit(lambda m: m["measurements"]["soc"].update(scale=0)), "parameter 'measurements.soc.scale'"),
    ("reversed range", _map_edit(lambda m: m["measurements"]["t_air_c"].update(range=[40, 0])),
     "parameter 'measurements.t_air_c.range'"),
    ("empty topic", _map_edit(lambda m: m["measurements"]["soc"].update(topic="")),
     "parameter 'measurements.soc.topic'"),
    ("wildcard topic", _map_edit(lambda m: m["measurements"]["soc"].update(topic="bat/#")), "not a plain MQTT topic"),
    ("topic twice", _map_edit(lambda m: m["setpoints"]["hp_mod"].update(topic=m["setpoints"]["p_fc_w"]["topic"])),
     "topic(s) used twice"),
    ("unknown QoS", _map_edit(lambda m: m["broker"].update(qos=3)), "parameter 'broker.qos'"),
    ("incomplete hp_mode values", _map_edit(lambda m: m["setpoints"]["hp_mode"]["values"].pop("2")),
     "setpoints.hp_mode.values must map '0', '1' and '2'"),
    ("empty file", _map_text(""), "expected '<node>: ros__parameters: ...' at the top level"),
    ("misspelt key", _map_edit(lambda m: m["measurements"]["soc"].update(sacle=0.01)),
     "parameter 'measurements.soc.sacle': unknown parameter"),
    ("port out of range in the map", _map_edit(lambda m: m["broker"].update(url="mqtt://127.0.0.1:99999")),
     "port 99999 is not a number in 1..65535"),
]


@pytest.mark.parametrize(("kind", "write", "named"), TOPIC_MAPS, ids=[k for k, _, _ in TOPIC_MAPS])
def test_whole_topic_map_is_checked_before_any_node_starts(kind: str, write: Callable[[Path], Path], named: str,
                                                            tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path / "map.yaml")
    err = refused(["launch", "--ems", "rbc", "--steps", "2", "--plant", "mqtt", "--topic-map", path], named,
                  tmp_path / "r", capsys)
    assert "map.yaml" in err


# ---------------------------------------------------------------------------- broker URL
BROKERS = [
    ("mqtt://localhost:99999", "port 99999 is not a number in 1..65535"),
    ("mqtt://localhost:0", "port 0 is not a number in 1..65535"),
    ("mqtt://user:secret@localhost:1883", "no credentials in the URL"),
    ("tcp://localhost:1883", "is not mqtt://host[:port] or mqtts://host[:port]"),
    ("mqtt://localhost:1883/base", "is not mqtt://host[:port] or mqtts://host[:port]"),
]


@pytest.mark.parametrize(("url", "named"), BROKERS, ids=[u for u, _ in BROKERS])
def test_broker_url_is_checked_by_one_rule_before_any_node_starts(url: str, named: str, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(["launch", "--ems", "rbc", "--steps", "2", "--plant", "mqtt", "--broker", url], named,
                  tmp_path / "r", capsys)
    assert "argument --broker" in err and "secret" not in err  # a password is never echoed
    # the same rule in a topic map's broker.url
    path = _map_edit(lambda m: m["broker"].update(url=url))(tmp_path / "map.yaml")
    refused(["launch", "--ems", "rbc", "--steps", "2", "--plant", "mqtt", "--topic-map", path],
            "parameter 'broker.url'", tmp_path / "r", capsys)


# ---------------------------------------------------------------------------- plant parameters
PLANT = [
    ("thermostat", "comfort.holidays_country=XX", "holidays_country 'XX': no holiday calendar"),
    ("thermostat", "comfort.holidays_country=de", "did you mean DE"),
    ("thermostat", "comfort.holidays_subdivision=ZZ", "holidays_subdivision 'ZZ' is not a subdivision of DE"),
    ("mpc", "simulation.horizon_h=12", "simulation.horizon_h = 12"),
    ("rbc", "grid.buy_spot_factor=1e308", "parameter 'grid.buy_spot_factor': Input should be less than or equal to 10"),
    ("rbc", "battery.e_max_kwh=[1", "--set 'battery.e_max_kwh=[1': the value is not valid YAML"),
]


@pytest.mark.parametrize(("ems", "assignment", "named"), PLANT, ids=[a for _, a, _ in PLANT])
@pytest.mark.parametrize("command", ["simulate", "launch"])
def test_plant_parameter_problem_is_named_before_anything_starts(
        command: str, ems: str, assignment: str, named: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    length = ["--hours", "2"] if command == "simulate" else ["--steps", "2"]
    refused([command, "--ems", ems, *length, "--set", assignment], named, tmp_path / "r", capsys)


def test_holiday_calendar_in_a_config_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "site.yaml"
    cfg.write_text("/**:\n  ros__parameters:\n    comfort:\n      holidays_subdivision: Mars\n", encoding="utf-8")
    err = refused(["simulate", "--ems", "rbc", "--hours", "2", "--config", cfg], "holidays_subdivision 'Mars'",
                  tmp_path / "r", capsys)
    assert "site.yaml" in err


# ---------------------------------------------------------------------------- data sources
def _dwd(src: Path, line: int, column: str, value: str) -> Callable[[Path], Path]:
    """A copy of the DWD file ``src`` with ``value`` in ``column`` of file line ``line``."""
    def write(path: Path) -> Path:
        lines = src.read_text(encoding="latin-1").splitlines()
        header = [c.strip() for c in lines[0].split(";")]
        fields = lines[line - 1].split(";")
        fields[header.index(column)] = value
        lines[line - 1] = ";".join(fields)
        path.write_text("\n".join(lines) + "\n", encoding="latin-1")
        return path
    return write


def _diffuse_above_global(path: Path) -> Path:
    """The first hour's six 10-minute rows with diffuse 12 J/cm2 above global 6 J/cm2."""
    lines = SOLAR.read_text(encoding="latin-1").splitlines()
    for n in range(1, 7):
        fields = lines[n].split(";")
        fields[3] = "12.000"  # DS_10
        lines[n] = ";".join(fields)
    path.write_text("\n".join(lines) + "\n", encoding="latin-1")
    return path


def _awattar(price: object) -> Callable[[Path], Path]:
    def write(path: Path) -> Path:
        doc = json.loads(PRICES.read_text(encoding="utf-8"))
        doc["data"][2]["marketprice"] = price
        path.write_text(json.dumps(doc), encoding="utf-8")
        return path
    return write


def _load(column: str, values: np.ndarray) -> Callable[[Path], Path]:
    """A 15-minute load CSV over the fixtures' hours (40 rows) with ``values`` in ``column``."""
    def write(path: Path) -> Path:
        times = pd.date_range("2022-12-01T01:00+01:00", periods=len(values), freq="15min")
        rows = [f"{t.isoformat()},{v:g}" for t, v in zip(times, values)]
        path.write_text("\n".join([f"time,{column}", *rows]) + "\n", encoding="utf-8")
        return path
    return write


SOURCES = [
    ("temperature 99 degC in 10 min", "temperature", _dwd(TEMPERATURE, 5, "TT_10", "  99.0"),
     "line 5, column 'TT_10': value 99 outside the plausible range -60..60 degC"),
    ("GHI -833 W/m2", "solar", _dwd(SOLAR, 4, "GS_10", "-50.000"), "line 4, column 'GS_10'"),
    ("GHI 15000 W/m2", "solar", _dwd(SOLAR, 4, "GS_10", "900.000"), "value 15000 outside the plausible range"),
    ("diffuse above global", "solar", _diffuse_above_global, "column 'DS_10' above 'GS_10': diffuse 200 W/m2"),
    ("price 1e15", "prices", _awattar(1e15), "data[2], field 'marketprice': value 1e+15 outside"),
    ("price true", "prices", _awattar(True), "data[2], field 'marketprice': true is not a number"),
    ("load in kW read as W", "load", _load("p_w", np.linspace(0.3, 0.7, 40)),
     "column 'p_w' (read as W): all values below 20 W, this looks like kW read as W"),
    ("load in W read as kW", "load", _load("p_kw", np.linspace(300.0, 700.0, 40)),
     "line 2, column 'p_kw' (read as kW): value 300000 outside the plausible range 0..100000 W"),
    ("load time not ISO 8601", "load", _map_text("time,p_w\n01.12.2022 01:00+01:00,300\n"),
     "line 2, column 'time': '01.12.2022 01:00+01:00' is not an ISO 8601 date/time"),
    ("DHW draw 1e9 l/h", "dhw", _map_text("\n".join(["1e9"] + ["0"] * 8759) + "\n"),
     "line 1, column 1 (l/h): value 1e+09 outside the plausible range"),
]


@pytest.mark.parametrize(("case", "option", "write", "named"), SOURCES, ids=[c for c, _, _, _ in SOURCES])
def test_data_build_applies_the_scenario_ranges_naming_file_line_and_column(
        case: str, option: str, write: Callable[[Path], Path], named: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    bad = write(tmp_path / f"bad_{option}.txt")
    files = {"prices": PRICES, "temperature": TEMPERATURE, "solar": SOLAR, option: bad}
    err = refused(["data", "build", *[x for k, v in files.items() for x in (f"--{k}", v)]], named,
                  tmp_path / "scenario.csv", capsys)
    assert bad.name in err


# ---------------------------------------------------------------------------- times
@pytest.fixture(scope="module")
def good_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A valid 48 h scenario CSV (the beginning of the default scenario)."""
    path = tmp_path_factory.mktemp("csv") / "good.csv"
    write_scenario_csv(resolve_scenario("default", load_plant_params(), hours=48), path)
    return path


GAP = "2023-03-26T02:30"  # Europe/Berlin: the clocks jump from 02:00 to 03:00
TWICE = "2022-10-30T02:30"  # Europe/Berlin: 02:00 .. 03:00 passes twice
BUILD = ["data", "build", "--prices", PRICES, "--temperature", TEMPERATURE, "--solar", SOLAR]
TIMES = [
    (["simulate", "--ems", "rbc", "--scenario", "synthetic", "--hours", "2", "--start", GAP],
     "--start: '2023-03-26T02:30' does not exist in Europe/Berlin"),
    (["simulate", "--ems", "rbc", "--scenario", "synthetic", "--hours", "2", "--start", TWICE],
     "--start: '2022-10-30T02:30' occurs twice in Europe/Berlin (end of daylight saving time); give the UTC offset: "
     "2022-10-30T02:30:00+02:00 or 2022-10-30T02:30:00+01:00"),
    (["simulate", "--ems", "rbc", "--hours", "2", "--start", "12/01/2022"],
     "--start: '12/01/2022' is not an ISO 8601 date/time"),
    (["launch", "--ems", "rbc", "--scenario", "synthetic", "--steps", "2", "--start", GAP], "--start: '2023-03-26"),
    (["compare", "--ems", "rbc", "--scenario", "synthetic", "--weeks", "1", "--start", GAP], "--start: '2023-03-26"),
    (["sweep", "--param", "battery.e_max_kwh=5", "--ems", "rbc", "--scenario", "synthetic", "--weeks", "1",
      "--start", GAP], "--start: '2023-03-26"),
    ([*BUILD, "--start", GAP], "--start: '2023-03-26T02:30' does not exist"),
    ([*BUILD, "--end", "tomorrow"], "--end: 'tomorrow' is not an ISO 8601 date/time"),
    (["data", "fetch-prices", "--start", "1.12.2022", "--end", "2022-12-02"],
     "--start: '1.12.2022' is not an ISO 8601 date/time"),
]


@pytest.mark.parametrize(("argv", "named"), TIMES, ids=[" ".join(map(str, a[:1] + a[-2:])) for a, _ in TIMES])
def test_time_option_names_the_option_instead_of_pandas(argv: list, named: str, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / ("x.json" if argv[0] == "data" else "r")
    err = refused(argv, named, out, capsys)
    assert "nonexistent" not in err and "Try using" not in err  # pandas' own words


CSV_CELLS = [
    ("time", 3, "2022/12/01 01:00:00+01:00", "line 3, column 'time': '2022/12/01 01:00:00+01:00' is not an ISO 8601"),
    ("time", 2, "01.12.2022 00:00+01:00", "line 2, column 'time': '01.12.2022 00:00+01:00' is not an ISO 8601"),
    ("time", 2, "2022-12-01T00:00:00", "line 2, column 'time': '2022-12-01T00:00:00' has no UTC offset"),
    ("t_amb_c", 6, "inf", "line 6, column 't_amb_c': 'inf' is not a finite number"),
]


@pytest.mark.parametrize(("column", "line", "value", "named"), CSV_CELLS, ids=[c[3][:40] for c in CSV_CELLS])
@pytest.mark.parametrize("command", ["simulate", "launch"])
def test_scenario_csv_cell_is_named_by_file_line_and_column(command: str, column: str, line: int, value: str,
                                                             named: str, good_csv: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    df = pd.read_csv(good_csv, dtype=str)
    df.loc[line - 2, column] = value
    bad = tmp_path / "cell.csv"
    df.to_csv(bad, index=False)
    err = refused([command, "--ems", "rbc", "--scenario", bad], named, tmp_path / "r", capsys)
    assert "cell.csv" in err


# ---------------------------------------------------------------------------- other options
OTHERS = [
    (["launch", "--ems", "rbc", "--steps", "2", "--network", "netns", "--netem", "delay 5ms lose 1%"],
     "argument --netem: 'lose' is not a netem parameter"),
    (["launch", "--ems", "rbc", "--steps", "2", "--network", "netns", "--netem", "loss 150%"],
     "argument --netem: 'loss' needs [random] PERCENT"),
    (["launch", "--ems", "rbc", "--houses", "100000"], "argument --houses: 100000 is outside the allowed range"),
    (["bench", "ros", "--houses", "1,100000"], "--houses 1,100000: 100000 is outside the allowed range"),
    (["bench", "mpc", "--configs", "nosuchconfig"], "--configs nosuchconfig: nosuchconfig matches no configuration"),
    (["compare", "--ems", "rbc,rbc", "--weeks", "1"], "--ems rbc,rbc: 'rbc' given twice"),
    (["sweep", "--param", "battery.e_max_kwh=5", "--ems", ",", "--weeks", "1"], "--ems ',': no EMS given"),
    (["compare", "--ems", "rbc", "--weeks", "1", "--set", "fuel_cell.eta_sys=0.8", "--fc-efficiency", "0.75"],
     "--fc-efficiency 0.75 and --set fuel_cell.eta_sys=0.8 both set the FC system efficiency"),
    (["fuzzy-surface", "--config", "NOFILE"], "--config NOFILE: no such file"),
]


@pytest.mark.parametrize(("argv", "named"), OTHERS, ids=[" ".join(a[:1] + a[-2:]) for a, _ in OTHERS])
def test_other_option_is_refused_before_any_work(argv: list, named: str, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    refused(argv, named, tmp_path / "r", capsys)


def test_compare_runs_the_efficiency_given_by_set(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--set fuel_cell.eta_sys is not overridden by the default --fc-efficiency 0.75,0.90: it is the one run."""
    out = tmp_path / "cmp"
    code, _, err = run_cli(["compare", "--ems", "rbc", "--weeks", "1", "--set", "fuel_cell.eta_sys=0.8",
                            "--no-progress", "--out", out], capsys)
    assert code == 0, err
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["rbc"]
    assert json.loads((out / "runs" / "rbc" / "summary.json").read_text())["eta_sys"] == 0.8
    assert json.loads((out / "compare.json").read_text())["base_eta"] == 0.8


# ---------------------------------------------------------------------------- all or nothing
def test_evaluate_without_timeseries_leaves_no_older_timeseries(recorded_bag: Path, tmp_path: Path,  # noqa: F811
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "e"
    assert run_cli(["evaluate", recorded_bag, "--out", out], capsys)[0] == 0
    (out / "notes.txt").write_text("mine\n")
    code, _, err = run_cli(["evaluate", recorded_bag, "--no-timeseries", "--out", out], capsys)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["notes.txt", "summary.json",
                                                                                   "weekly.csv"]


def _interrupt_at(monkeypatch: pytest.MonkeyPatch, n: int) -> None:
    """A Ctrl-C (KeyboardInterrupt) in the ``n``-th run of a comparison or sweep, after the earlier ones wrote."""
    from comems4build_ros.study import runner

    real, calls = runner.run_task, {"n": 0}

    def run_task(task: runner.RunTask, progress: object = None) -> dict:
        calls["n"] += 1
        if calls["n"] == n:
            raise KeyboardInterrupt
        return real(task, progress)

    monkeypatch.setattr(runner, "run_task", run_task)


JOBS = {
    "compare": ["compare", "--ems", "rbc,thermostat", "--weeks", "1", "--jobs", "1", "--no-progress"],
    "sweep": ["sweep", "--param", "battery.e_max_kwh=5,10", "--ems", "rbc", "--weeks", "1", "--jobs", "1",
              "--no-progress"],
}


@pytest.mark.parametrize("command", list(JOBS))
def test_interrupted_comparison_or_sweep_keeps_the_older_results_whole(
        command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    code, _, err = run_cli([*JOBS[command], "--out", out], capsys)
    assert code == 0, err
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    shutil.copytree(out, tmp_path / "copy")
    _interrupt_at(monkeypatch, 2)
    argv = [*JOBS[command], "--out", out, "--seed", "7"]  # another result, were it finished
    code, _, err = run_cli(argv, capsys)
    assert code == 130 and "interrupted" in err
    store = out / ".runstore"  # the run that finished is kept for --resume, beside the results
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file() and store not in p.parents}
    assert after == before  # no partial runs/<name>/, no temporary directory, the old results byte for byte
    assert len([p for p in store.iterdir() if not p.name.startswith(".")]) == 1
    assert "1 finished run(s) are kept" in err
