"""Inputs checked for what they mean, before anything starts.

Physics that refuses the impossible (every range's lower bound is the smallest real value,
named with its reason; relations between parameters), options whose derived quantity
overflows (a clock factor's step period, a run's end), files and peers checked for what
they mean (topic maps, live-input settings, a ``--scheduler`` that is no Dask scheduler,
``--update-doc`` markers). Each class: the samples found by probing, then hypothesis
properties over further cases. A refusal is exit code 2 naming the option, file or
parameter; nothing is written and no node or run starts.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import run_cli

from comems4build_ros.core.config import ConfigError, PlantParams, load_plant_params

REPO = Path(__file__).resolve().parents[1]
BOUNDED = settings(max_examples=40, derandomize=True, database=None, deadline=None,
                   suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _phys_fields() -> list[tuple[str, float, bool]]:
    """``(section.key, least, off)`` of every plant parameter with a physical lower bound above 0."""
    out = []
    for section, field in PlantParams.model_fields.items():
        for name, f in field.annotation.model_fields.items():
            extra = f.json_schema_extra
            if isinstance(extra, dict) and extra.get("least", 0) > 0:
                out.append((f"{section}.{name}", float(extra["least"]), bool(extra["off"])))
    return out


PHYS = _phys_fields()


# ------------------------------------------------------------------------------ impossible physics: the samples
def test_a_battery_of_5e_324_kwh_is_refused_naming_the_smallest_real_size(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "rbc", "--hours", "3", "--set", "battery.e_max_kwh=5e-324",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "battery.e_max_kwh': 5e-324 is below 0.1, the smallest real value" in err, err
    assert not (tmp_path / "r").exists()


def test_fc_efficiency_5e_324_is_refused_naming_the_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["compare", "--ems", "rbc", "--weeks", "0.25", "--fc-efficiency", "5e-324",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "--fc-efficiency 5e-324" in err and "fuel_cell.eta_sys" in err, err
    assert not (tmp_path / "r").exists()


def test_fc_system_efficiency_below_its_electrical_efficiency_is_refused() -> None:
    eta_el = load_plant_params().fuel_cell.eta_el_max()
    for eta_sys in (0.5, 0.6, round(eta_el - 0.001, 3)):
        with pytest.raises(ConfigError, match=r"eta_sys \(.*\) is below the electrical efficiency 0\.630"):
            load_plant_params(None, {"fuel_cell.eta_sys": eta_sys})
    with pytest.raises(ConfigError, match=r"eta_sys \(0\.45\) is below eta_el_mpc \(0\.48\)"):
        load_plant_params(None, {"fuel_cell.eta_sys": 0.45, "fuel_cell.p_min_w": 1500.0})


def test_an_mpc_time_limit_of_5e_324_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "mpc", "--hours", "2", "--ems-option", "time_limit_s=5e-324",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "'time_limit_s': 5e-324 is below 0.1, the smallest real value" in err, err
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------------------ impossible physics: any parameter
@BOUNDED
@given(field=st.sampled_from(PHYS), share=st.floats(min_value=0.0, max_value=1.0, exclude_max=True),
       tiny=st.booleans())
def test_any_value_below_a_physical_bound_is_refused_naming_it(field: tuple[str, float, bool], share: float,
                                                               tiny: bool) -> None:
    """Between 0 and the smallest real value (5e-324 included), every parameter refuses, naming that value."""
    name, least, off = field
    value = 5e-324 if tiny else least * share
    if value == 0.0 and off:
        return  # 0 means none there
    with pytest.raises(ConfigError) as info:
        load_plant_params(None, {name: value})
    text = str(info.value)
    assert name.split(".")[0] in text, text
    if name in text:  # refused by its own range (a relation may refuse first: it names the section)
        assert f"{least:g}, the smallest real value" in text, text


@BOUNDED
@given(p_max=st.floats(min_value=500, max_value=2441.6), over=st.floats(min_value=1.0001, max_value=5))
def test_inverted_fuel_cell_limits_are_refused(p_max: float, over: float) -> None:
    with pytest.raises(ConfigError, match="p_nom_w .* must not exceed p_max_w"):
        load_plant_params(None, {"fuel_cell.p_max_w": p_max, "fuel_cell.p_nom_w": p_max * over,
                                 "fuel_cell.p_min_w": 100.0})


@BOUNDED
@given(v_min=st.floats(min_value=5, max_value=200), usable=st.floats(min_value=0.01, max_value=39.99))
def test_a_tank_smaller_than_one_draw_is_refused(v_min: float, usable: float) -> None:
    with pytest.raises(ConfigError, match="holds less than one shower draw"):
        load_plant_params(None, {"dhw.v_min_l": v_min, "dhw.v_max_l": v_min + usable,
                                 "simulation.v_dhw_init_l": v_min})


@BOUNDED
@given(lo=st.floats(min_value=0, max_value=0.99), hi=st.floats(min_value=0.01, max_value=1))
def test_inverted_battery_state_limits_are_refused(lo: float, hi: float) -> None:
    if lo < hi:
        return
    with pytest.raises(ConfigError, match="soc_min .* must be below soc_max"):
        load_plant_params(None, {"battery.soc_min": lo, "battery.soc_max": hi})


# ------------------------------------------------------------------------------ derived quantities of options
@pytest.mark.parametrize("factor", ["1e308", "5e-324"])
def test_a_clock_factor_whose_step_period_is_impossible_is_refused(factor: str, tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["launch", "--ems", "fuzzy", "--plant", "mqtt", "--clock", f"wall:{factor}", "--print-plan",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and f"--clock: clock 'wall:{factor}': a step of 1 h would take" in err, err


def test_a_run_ending_after_any_calendar_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["simulate", "--ems", "thermostat", "--hours", "100000000", "--extend", "synthetic",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and "--hours" in err and "OverflowError" not in err, err


@BOUNDED
@given(factor=st.floats(min_value=5e-324, max_value=1e308))
def test_any_clock_factor_gives_a_step_period_in_range_or_is_refused(factor: float) -> None:
    from comems4build_ros.mqtt.clock import MAX_PERIOD_S, MIN_PERIOD_S, ClockError, parse_clock

    for step_h in (0.25, 1.0, 24.0):
        try:
            clock = parse_clock(f"wall:{factor!r}", step_h)
        except ClockError as exc:
            assert "would take" in str(exc)
            continue
        assert MIN_PERIOD_S <= clock.period_s <= MAX_PERIOD_S and math.isfinite(clock.first_boundary(time.time()))


@BOUNDED
@given(hours=st.integers(min_value=-10, max_value=10**15), weeks=st.floats(allow_nan=True, allow_infinity=True))
def test_any_run_length_is_in_range_or_refused_naming_the_option(hours: int, weeks: float) -> None:
    import argparse

    from comems4build_ros.app.commands.options import HOURS, MAX_RUN_HOURS, WEEKS

    for parse, text, ok in ((HOURS, str(hours), 1 <= hours <= MAX_RUN_HOURS),
                            (WEEKS, repr(weeks), 1 / 168 <= weeks <= MAX_RUN_HOURS / 168)):
        try:
            value = parse(text)
        except argparse.ArgumentTypeError as exc:
            assert not ok, (text, exc)
            continue
        assert ok and math.isfinite(value), text


# ------------------------------------------------------------------------------ topic maps
def _topic_map(tmp_path: Path, edit: Callable[[dict], object], name: str = "map.yaml") -> Path:
    from comems4build_ros.mqtt.topicmap import default_map_file

    doc = yaml.safe_load(default_map_file().read_text(encoding="utf-8"))
    edit(doc["/**"]["ros__parameters"]["mqtt"])
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


def _set(path: str, value: object) -> Callable[[dict], None]:
    def edit(m: dict) -> None:
        node = m
        keys = path.split(".")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    return edit


TOPIC_MAP_SAMPLES = [
    (_set("setpoints.hp_mode.values", {"0": "off", "1": "off", "2": "dhw"}), "modes 0 and 1 both map to 'off'"),
    (_set("setpoints.hp_mode.values", {"0": "standby", "1": "off", "2": "dhw"}),
     "mode 1 (space heating) maps to 'off'"),
    (_set("setpoints.hp_mod.limits", [1.0, 0.2]), "must be [low, high] with low < high"),
    (_set("broker.username", "ems"), "username 'ems' without password_file or password_env"),
    (_set("base_topic", "#"), "'#' is not a plain MQTT topic"),
]


@pytest.mark.parametrize(("edit", "named"), TOPIC_MAP_SAMPLES, ids=[n for _, n in TOPIC_MAP_SAMPLES])
def test_a_topic_map_that_means_the_wrong_thing_is_refused_before_any_node(
        edit: Callable[[dict], None], named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _topic_map(tmp_path, edit)
    code, _, err = run_cli(["launch", "--ems", "fuzzy", "--plant", "mqtt", "--topic-map", path, "--print-plan",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and str(path) in err and named in err, err


def test_a_missing_password_file_is_named(tmp_path: Path) -> None:
    from comems4build_ros.mqtt.topicmap import load_topic_map

    path = _topic_map(tmp_path, lambda m: m["broker"].update(username="ems", password_file=str(tmp_path / "no")))
    with pytest.raises(ConfigError, match=r"parameter 'broker.password_file': .*/no: no such file"):
        load_topic_map(path)
    path = _topic_map(tmp_path, lambda m: m["broker"].update(username="ems", password_env="COMEMS4BUILD_NO_SUCH"),
                      "env.yaml")
    with pytest.raises(ConfigError, match="COMEMS4BUILD_NO_SUCH is not set"):
        load_topic_map(path)


WORDS = st.sampled_from(["off", "OFF", "heating", "heat", "dhw", "hot_water", "on", "no", "standby", "auto", ""])


@BOUNDED
@given(w0=WORDS, w1=WORDS, w2=WORDS)
def test_any_mode_map_is_one_to_one_and_meaningful_or_refused(tmp_path_factory: pytest.TempPathFactory,
                                                              w0: str, w1: str, w2: str) -> None:
    from comems4build_ros.mqtt.topicmap import OFF_WORDS, load_topic_map

    path = _topic_map(tmp_path_factory.mktemp("m"), _set("setpoints.hp_mode.values", {"0": w0, "1": w1, "2": w2}))
    words = [w.strip().lower() for w in (w0, w1, w2)]
    good = all(words) and len(set(words)) == 3 and words[0] in OFF_WORDS and not {words[1], words[2]} & OFF_WORDS
    try:
        tmap = load_topic_map(path)
    except ConfigError as exc:
        assert not good and "setpoints.hp_mode.values" in str(exc) and str(path) in str(exc), str(exc)
        return
    assert good, words
    spec = tmap.setpoints["hp_mode"]
    assert [spec.decode(spec.encode(m))[0] for m in (0, 1, 2)] == [0.0, 1.0, 2.0]


@BOUNDED
@given(topic=st.text(alphabet="ab/+#", min_size=0, max_size=8), where=st.sampled_from(["base_topic",
                                                                                         "discovery_prefix"]))
def test_any_wildcard_or_empty_level_topic_is_refused(tmp_path_factory: pytest.TempPathFactory, topic: str,
                                                      where: str) -> None:
    from comems4build_ros.mqtt.topicmap import load_topic_map

    path = _topic_map(tmp_path_factory.mktemp("t"), _set(where, topic))
    plain = bool(topic) and not set(topic) & set("+#") and "//" not in topic and not topic.startswith("/") \
        and not topic.endswith("/")
    try:
        load_topic_map(path)
    except ConfigError as exc:
        assert not plain and where in str(exc), str(exc)
        return
    assert plain, topic


@BOUNDED
@given(lo=st.floats(-2, 2), hi=st.floats(-2, 2))
def test_any_modulation_limits_are_ordered_within_0_1_or_refused(tmp_path_factory: pytest.TempPathFactory,
                                                                  lo: float, hi: float) -> None:
    from comems4build_ros.mqtt.topicmap import load_topic_map

    path = _topic_map(tmp_path_factory.mktemp("l"), _set("setpoints.hp_mod.limits", [lo, hi]))
    try:
        load_topic_map(path)
    except ConfigError as exc:
        assert not (0 <= lo < hi <= 1) and "hp_mod" in str(exc), str(exc)
        return
    assert 0 <= lo < hi <= 1


# ------------------------------------------------------------------------------ live inputs
def _live(tmp_path: Path, section: str, **values: object) -> Path:
    doc = yaml.safe_load((REPO / "config" / "live_inputs.yaml").read_text(encoding="utf-8"))
    doc["/**"]["ros__parameters"]["live_inputs"][section].update(values)
    path = tmp_path / "live.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize(("section", "values", "named"), [
    ("prices", {"url": "https://user:pw@api.awattar.de/v1/marketdata"}, "no credentials in the URL"),
    ("prices", {"retries": 1000000000}, "prices.retries"),
    ("weather", {"url": "http://me:secret@example.org/forecast"}, "no credentials in the URL"),
])
def test_live_inputs_with_credentials_or_unbounded_retries_are_refused(section: str, values: dict, named: str,
                                                                        tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = _live(tmp_path, section, **values)
    code, _, err = run_cli(["launch", "--ems", "rbc", "--inputs", "live", "--live-config", path, "--print-plan",
                            "--out", tmp_path / "r"], capsys)
    assert code == 2 and str(path) in err and named in err and "pw@" not in err.replace("...@", ""), err


@BOUNDED
@given(retries=st.integers(1, 10**9), timeout=st.floats(0.01, 1e6), delay=st.floats(0, 1e6))
def test_any_fetch_is_bounded_by_an_hour_or_refused(tmp_path_factory: pytest.TempPathFactory, retries: int,
                                                    timeout: float, delay: float) -> None:
    from comems4build_ros.core.scenario.live import MAX_FETCH_S, load_live_settings

    path = _live(tmp_path_factory.mktemp("f"), "weather", retries=retries, timeout_s=timeout, retry_delay_s=delay)
    try:
        w = load_live_settings(path).weather
    except ConfigError as exc:
        assert "weather" in str(exc), str(exc)
        return
    assert w.retries <= 10 and w.retries * w.timeout_s + (w.retries - 1) * w.retry_delay_s <= MAX_FETCH_S


# ------------------------------------------------------------------------------ a peer that is not a scheduler
@pytest.fixture()
def fake_server() -> Iterator[Callable[[bytes | None], int]]:
    """A TCP server on the loopback that answers each connection with ``reply`` (None: says nothing)."""
    servers: list[socket.socket] = []

    def start(reply: bytes | None) -> int:
        srv = socket.socket()
        srv.bind(("127.0.0.1", 0))
        srv.listen(4)
        servers.append(srv)

        def serve() -> None:
            while True:
                try:
                    conn, _ = srv.accept()
                except OSError:
                    return
                if reply is not None:
                    conn.sendall(reply)
                time.sleep(0.5 if reply is not None else 6)
                conn.close()

        threading.Thread(target=serve, daemon=True).start()
        return srv.getsockname()[1]

    yield start
    for srv in servers:
        srv.close()


@pytest.mark.parametrize("reply", [b"HTTP/1.1 400 Bad Request\r\n\r\n", b"SSH-2.0-OpenSSH_9.6\r\n",
                                   b"\x01\x00\x00\x00\x00\x00\x00\x00garbage", None],
                         ids=["http", "ssh", "short-frame", "silent"])
def test_a_scheduler_that_is_not_dask_is_refused_before_any_work(reply: bytes | None, fake_server: Callable,
                                                                 tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from comems4build_ros.study.cluster import PROBE_TIMEOUT_S, NotASchedulerError, probe_scheduler

    port = fake_server(reply)
    address = f"tcp://127.0.0.1:{port}"
    t0 = time.monotonic()
    with pytest.raises(NotASchedulerError, match=f"--scheduler {address}: .*not a Dask scheduler"):
        probe_scheduler(address)
    assert time.monotonic() - t0 < PROBE_TIMEOUT_S + 3  # at once, or after the probe's short wait (not Dask's 20 s)
    code, _, err = run_cli(["sweep", "--ems", "rbc", "--weeks", "0.25", "--param", "battery.e_max_kwh=5",
                            "--scheduler", address, "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 2 and f"--scheduler {address}" in err and "Traceback" not in err, err
    assert not (tmp_path / "r").exists()


def test_a_closed_port_as_scheduler_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code, _, err = run_cli(["sweep", "--ems", "rbc", "--weeks", "0.25", "--param", "battery.e_max_kwh=5",
                            "--scheduler", f"tcp://127.0.0.1:{port}", "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 2 and "no scheduler answered (cannot connect" in err, err


# ------------------------------------------------------------------------------ --update-doc markers
@pytest.mark.parametrize("text", ["no markers at all\n",
                                  "<!-- reproduce:end -->\n<!-- reproduce:begin -->\n",
                                  "<!-- reproduce:begin -->\n<!-- reproduce:begin -->\n<!-- reproduce:end -->\n"],
                         ids=["missing", "inverted", "twice"])
def test_update_doc_markers_are_checked_before_the_first_run(text: str, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    doc = tmp_path / "calibration.md"
    doc.write_text(text)
    t0 = time.monotonic()
    code, _, err = run_cli(["reproduce", "--no-study", "--weeks", "0.25", "--seeds", "57", "--no-figures",
                            "--update-doc", doc, "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 2 and f"--update-doc {doc}: " in err and "reproduce:begin" in err, err
    assert time.monotonic() - t0 < 20 and not (tmp_path / "r").exists()  # no run was made
    assert doc.read_text() == text


def test_validate_update_doc_markers_are_checked_before_the_first_run(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    doc = tmp_path / "validation.md"
    doc.write_text("# Validation\n")
    code, _, err = run_cli(["validate", "--cases", "paper-s57", "--ems", "rbc", "--weeks", "0.25", "--no-figures",
                            "--update-doc", doc, "--no-progress", "--out", tmp_path / "r"], capsys)
    assert code == 2 and f"--update-doc {doc}: markers" in err, err
    assert not (tmp_path / "r").exists()
