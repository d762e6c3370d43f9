"""Live inputs (comems4build_ros.core.scenario.live) against a local HTTP server serving recorded
aWATTar / forecast answers, including missing, late (timeout) and malformed ones."""

from __future__ import annotations

import http.server
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from waits import Deadline, wait_exit

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.scenario.live import (
    FetchError,
    PriceSource,
    WeatherSource,
    http_get,
    live_scenario,
    load_live_settings,
)
from comems4build_ros.core.scenario.tariff import PaperTariff  # the buy tariff of eq:costs, as the scenario builds it
from comems4build_ros.ros.interfaces import qos_profile

TZ = "Europe/Berlin"
#: The recorded day: 2022-12-01 local (aWATTar answers for today and tomorrow).
DAY0 = pd.Timestamp("2022-12-01 00:00", tz=TZ)
NOON = (DAY0 + pd.Timedelta(hours=12)).timestamp()


def awattar_answer(start: pd.Timestamp, hours: int, base: float) -> str:
    """An answer in the aWATTar /v1/marketdata format (as recorded: object, data, url)."""
    ms = int(start.tz_convert("UTC").timestamp() * 1000)
    data = [{"start_timestamp": ms + h * 3_600_000, "end_timestamp": ms + (h + 1) * 3_600_000,
             "marketprice": round(base + 10.0 * np.sin(h / 3.0), 2), "unit": "Eur/MWh"} for h in range(hours)]
    return json.dumps({"object": "list", "data": data, "url": "/de/v1/marketdata"})


class Server:
    """Local HTTP server; ``responses`` is a list of (status, body, delay_s) served in order
    (the last one repeats); every request path is logged."""

    def __init__(self) -> None:
        self.responses: list[tuple[int, str, float]] = []
        self.requests: list[str] = []
        owner = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                owner.requests.append(self.path)
                i = min(len(owner.requests) - 1, len(owner.responses) - 1)
                status, body, delay = owner.responses[i]
                time.sleep(delay)
                try:
                    self.send_response(status)
                    self.send_header("Content-Type", "application/json")
                    self.end_headers()
                    self.wfile.write(body.encode())
                except (BrokenPipeError, ConnectionResetError):
                    pass

            def log_message(self, *args: object) -> None:
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1/marketdata"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture()
def server() -> Iterator[Server]:
    s = Server()
    yield s
    s.close()


def _source(server: Server, tmp_path: Path, now: list[float], warnings: list[str]) -> PriceSource:
    settings = load_live_settings().prices.model_copy(
        update={"url": server.url, "timeout_s": 0.5, "retries": 2, "retry_delay_s": 0.0})
    return PriceSource(settings, TZ, tmp_path / "cache.json", warnings.append, now=lambda: now[0],
                       sleep=lambda s: None)


def test_valid_answer_is_used_and_cached(server, tmp_path):
    server.responses = [(200, awattar_answer(DAY0, 48, 200.0), 0.0)]
    now, warnings = [NOON], []
    src = _source(server, tmp_path, now, warnings)
    assert src.refresh() and warnings == []
    start_ms = int(DAY0.tz_convert("UTC").timestamp() * 1000)
    assert server.requests == [f"/v1/marketdata?start={start_ms}&end={start_ms + 48 * 3_600_000}"]
    hours = pd.date_range(DAY0, periods=48, freq="h")
    expected = [round(200.0 + 10.0 * np.sin(h / 3.0), 2) for h in range(48)]
    assert src.values(hours).tolist() == expected
    # a new process reads the cache: same prices without any request
    again = _source(server, tmp_path, now, warnings)
    assert again.values(hours).tolist() == expected and len(server.requests) == 1


@pytest.mark.parametrize(
    ("response", "reason"),
    [
        ((404, "not found", 0.0), "HTTP 404"),  # missing
        ((200, json.dumps({"object": "list", "data": []}), 0.0), "'data' is empty"),  # missing (empty)
        ((200, awattar_answer(DAY0, 48, 999.0), 2.0), "timeout"),  # late: beyond timeout_s
        ((200, '{"object": "list", "data": [', 0.0), "invalid JSON"),  # malformed
        ((200, json.dumps({"data": [{"start_timestamp": 0, "marketprice": "high"}]}), 0.0),
         "field 'end_timestamp' missing"),  # malformed entry
        ((200, awattar_answer(DAY0 - pd.Timedelta(days=3), 24, 999.0), 0.0), "no price for today"),  # stale data
    ],
)
def test_missing_late_or_malformed_answers_keep_the_last_valid_prices_and_warn(server, tmp_path, response, reason):
    server.responses = [(200, awattar_answer(DAY0, 48, 200.0), 0.0)]
    now, warnings = [NOON], []
    src = _source(server, tmp_path, now, warnings)
    assert src.refresh()
    hours = pd.date_range(DAY0, periods=72, freq="h")
    before = src.values(hours)
    server.responses.append(response)
    assert not src.refresh(force=True)
    assert len(warnings) == 1 and reason in warnings[0] and "using the last valid prices" in warnings[0]
    assert np.array_equal(src.values(hours), before)
    # the third day has no live price: the last valid day's profile by local hour
    assert np.array_equal(before[48:], before[24:48])
    cached = json.loads((tmp_path / "cache.json").read_text())
    assert len(cached["prices"]) == 48


def test_schedule_on_start_daily_after_publication_and_retry_later(server, tmp_path):
    server.responses = [(200, awattar_answer(DAY0, 48, 200.0), 0.0)]
    now, warnings = [(DAY0 + pd.Timedelta(hours=9)).timestamp()], []
    src = _source(server, tmp_path, now, warnings)
    assert src.refresh()  # on start
    assert not src.refresh() and len(server.requests) == 1
    assert src.next_due() == (DAY0 + pd.Timedelta(hours=14)).timestamp()  # publication time, same day
    now[0] = (DAY0 + pd.Timedelta(hours=14, minutes=1)).timestamp()
    server.responses = [(500, "", 0.0)]
    assert not src.refresh() and len(warnings) == 1  # due, failed (2 attempts)
    assert len(server.requests) == 3
    assert src.next_due() == now[0] + src.settings.retry_later_s
    server.responses = [(200, awattar_answer(DAY0 + pd.Timedelta(days=1), 48, 150.0), 0.0)]
    now[0] += src.settings.retry_later_s
    assert src.refresh()
    assert src.next_due() == (DAY0 + pd.Timedelta(days=1, hours=14)).timestamp()


def test_http_get_names_every_attempt(server):
    server.responses = [(503, "busy", 0.0)]
    with pytest.raises(FetchError, match=r"3 attempt\(s\) failed: attempt 1: HTTP 503.*attempt 3: HTTP 503"):
        http_get(server.url, 1.0, 3, 0.0)
    with pytest.raises(FetchError, match="attempt 1: .*refused"):
        http_get("http://127.0.0.1:9/none", 1.0, 1, 0.0)


def test_weather_forecast_and_live_scenario(server, tmp_path):
    from comems4build_ros.core.scenario.run import load_scenario

    hours = pd.date_range(DAY0, periods=24, freq="h")
    answer = {"hourly": {"time": [t.strftime("%Y-%m-%dT%H:%M") for t in hours],
                         "temperature_2m": [-2.0 + 0.25 * h for h in range(24)],
                         "shortwave_radiation": [max(0.0, 300.0 - 30.0 * abs(h - 12)) for h in range(24)]}}
    server.responses = [(200, awattar_answer(DAY0, 48, 200.0), 0.0), (200, json.dumps(answer), 0.0),
                        (200, json.dumps({"hourly": {"time": ["x"]}}), 0.0)]
    warnings: list[str] = []
    now = [NOON]
    prices = _source(server, tmp_path, now, warnings)
    assert prices.refresh()
    settings = load_live_settings().weather.model_copy(update={"url": server.url, "retries": 1})
    weather = WeatherSource(settings, TZ, tmp_path / "w.json", warnings.append, now=lambda: now[0])
    assert weather.refresh()
    assert weather.values(hours, "t_amb_c").tolist() == answer["hourly"]["temperature_2m"]
    assert not weather.refresh(force=True) and "key 'hourly.temperature_2m' missing" in warnings[-1]
    assert weather.values(hours, "t_amb_c").tolist() == answer["hourly"]["temperature_2m"]

    params = load_plant_params()
    base = load_scenario("default", params, None, 1, None, 30)
    live = live_scenario(base, params, DAY0 + pd.Timedelta(minutes=20), prices, weather)
    assert live.time[0] == DAY0 and live.n_steps == base.n_steps and len(live.time) == len(base.time)
    assert live.spot_eur_per_mwh[:48].tolist() == prices.values(live.time[:48]).tolist()
    tariff = PaperTariff(params).prices(live.time, live.spot_eur_per_mwh)[0]
    assert np.array_equal(live.price_buy_eur_per_kwh, tariff)  # eq:costs
    assert live.t_amb_c[:24].tolist() == answer["hourly"]["temperature_2m"]
    assert live.t_amb_c[24:30].tolist() == base.t_amb_c[24:30].tolist()  # beyond the forecast: the scenario
    assert np.all(live.dhi_w_m2 <= live.ghi_w_m2)
    assert live.p_load_w.tolist() == base.p_load_w.tolist()


@pytest.mark.ros
def test_feed_node_live_inputs_publishes_warning_and_uses_last_valid_prices(server, tmp_path):
    """The feed process with inputs:=live: the cache holds valid prices, the server answers
    garbage -> a warning on feed/events and feed/prices carry the cached prices."""
    import os
    import signal
    import subprocess
    import sys

    import rclpy
    import yaml
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import Float64MultiArray, String, UInt32

    from comems4build_ros.core.config import config_dir
    from comems4build_ros.run.plan import ros_args
    from comems4build_ros.run.supervisor import acquire_domain_id
    from comems4build_ros.wire.contract import load_contract

    now = pd.Timestamp.now(tz=TZ).floor("h")
    day = now.normalize()
    warnings_: list[str] = []
    # a valid fetch fills the cache (as a run on an earlier day would have done)
    server.responses = [(200, awattar_answer(day, 48, 200.0), 0.0)]
    src = _source(server, tmp_path, [now.timestamp()], warnings_)
    assert src.refresh()
    server.responses = [(200, '{"object": "list", "data": [{"start_timestamp": ', 0.0)]
    doc = yaml.safe_load((config_dir() / "live_inputs.yaml").read_text())
    doc["/**"]["ros__parameters"]["live_inputs"]["prices"].update(url=server.url, retries=1, timeout_s=2.0,
                                                                   cache_file=str(tmp_path / "cache.json"))
    cfg = tmp_path / "live.yaml"
    cfg.write_text(yaml.safe_dump(doc))
    contract = load_contract()
    params = load_plant_params()
    with acquire_domain_id() as did:
        env = {**os.environ, "ROS_DOMAIN_ID": str(did), "ROS_LOG_DIR": str(tmp_path / "ros_log"),
               "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
        with open(tmp_path / "feed.log", "w") as fh:
            proc = subprocess.Popen([sys.executable, "-m", "comems4build_ros.ros.nodes.feed", *ros_args("", {
                "weeks": 1, "steps": 24, "inputs": "live", "live_config": str(cfg),
                "live_cache_dir": str(tmp_path)})], env=env, stdout=fh, stderr=subprocess.STDOUT,
                start_new_session=True)
        ctx = Context()
        rclpy.init(context=ctx, domain_id=did)
        node = Node("test_observer", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        events: list[str] = []
        prices: dict[int, list[float]] = {}
        node.create_subscription(String, "feed/events", lambda m: events.append(m.data),
                                 qos_profile(contract.topic("feed/events")))
        node.create_subscription(Float64MultiArray, "feed/prices", lambda m: prices.setdefault(int(m.data[0]),
                                 list(m.data)), qos_profile(contract.topic("feed/prices")))
        step_pub = node.create_publisher(UInt32, "plant/step", qos_profile(contract.topic("plant/step")))
        try:
            deadline = Deadline("the feed's prices of step 0 and its events")
            while not deadline.passed() and not (0 in prices and events):
                ex.spin_once(timeout_sec=0.05)
                step_pub.publish(UInt32(data=0))
            assert 0 in prices and events, (tmp_path / "feed.log").read_text()[-2000:]
        finally:
            proc.send_signal(signal.SIGINT)
            wait_exit(proc, "the feed to stop on SIGINT")
            ex.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
    assert any(" warning day-ahead prices: " in e and "invalid JSON" in e and "using the last valid prices" in e
               for e in events), events
    # step 0 is the current hour; its buy price comes from the cached spot price
    spot0 = src.values(pd.DatetimeIndex([now]))[0]
    assert prices[0][1] == PaperTariff(params).prices(pd.DatetimeIndex([]), np.array([spot0]))[0][0]
