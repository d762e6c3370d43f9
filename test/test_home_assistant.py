"""A building owner's Home Assistant around ``launch --plant mqtt``: the real one, headless.

Debian's Mosquitto with persistence and logins, Home Assistant 2025.4.4 in its own Python
3.13 venv (``bash tools/home_assistant.sh install``, which ``tools/test.sh`` runs) with the
MQTT integration and discovery, read through its REST API
(``tools/home_assistant_check.py`` holds the pieces). One session of one broker and one
Home Assistant, as a user has them:

1. retained state of earlier runs on the broker (an older release's plain step number, a
   cut wall-clock run's start time); the first run clears it, says so, and completes;
2. two lock-step runs back to back: every entity exists with the classes of its
   discovery config and its final state equals ``summary.json`` (totals with the last
   step, the gross purchase cost, ``last_reset`` at the run's start);
3. the user turns "Forced fallback" on in Home Assistant during a run: the steps after it
   run on the fallback, counted as the user's (``fallback_causes``) and said so by the
   launcher; the next run (a new bridge) keeps the user's choice from its first step;
   turned off while no bridge runs (a retained command), the run after it is the EMS's;
4. a wall-clock run cut by SIGINT, then a wall-clock run whose broker is killed for 1.4 s
   mid-run: the second completes with every step, and each step that ran on held
   set-points or on the fallback is listed in its summary;
5. Home Assistant's log has no warning about the EMS's entities.
"""

from __future__ import annotations

import importlib.util
import json
import secrets
import signal
import subprocess
import time
from pathlib import Path

import pytest
from waits import BUDGET_S

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("home_assistant_check", ROOT / "tools" / "home_assistant_check.py")
assert _spec is not None and _spec.loader is not None
hac = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hac)

pytestmark = pytest.mark.ros


def _launch(out: Path, broker: object, topic_map: Path, steps: int, clock: str = "sim") -> subprocess.Popen[str]:
    cmd = hac.launch_cmd(out, broker.url, topic_map, steps, clock)  # type: ignore[attr-defined]
    return subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _finish(proc: subprocess.Popen[str]) -> str:
    text, _ = proc.communicate(timeout=BUDGET_S)
    assert proc.returncode == 0, text[-4000:]
    return text


@pytest.fixture(scope="module")
def house(tmp_path_factory: pytest.TempPathFactory):
    python = hac.ha_python()
    if python is None:
        pytest.skip("no Home Assistant venv: it needs a Python 3.13 (python3.13 or pyenv) and "
                    "'bash tools/home_assistant.sh install' (tools/test.sh runs it)")
    if hac.mosquitto_binary() is None:
        pytest.skip("Debian's mosquitto is not installed ('bash tools/home_assistant.sh install')")
    work = tmp_path_factory.mktemp("ha")
    pw = {hac.HA_USER: secrets.token_hex(12), hac.EMS_USER: secrets.token_hex(12)}
    broker = hac.Mosquitto(work / "mosquitto", pw)
    broker.start()
    ha = hac.HomeAssistant(python, work / "ha_config", broker.port, pw[hac.HA_USER])
    try:
        print(f"Home Assistant up with MQTT in {ha.start():.1f} s")
        yield broker, ha, hac.ems_topic_map(work, pw[hac.EMS_USER]), pw, work
    finally:
        ha.stop()
        broker.stop()


def _publish(broker: object, pw: dict, topic: str, payload: str, retain: bool = True) -> None:
    port = str(broker.port)  # type: ignore[attr-defined]
    subprocess.run(["mosquitto_pub", "-p", port, "-u", hac.EMS_USER, "-P", pw[hac.EMS_USER], "-t", topic, "-m", payload,
                    *(["-r"] if retain else [])], check=True, timeout=BUDGET_S)


def test_home_assistant_sees_every_run_as_the_summary_says(house) -> None:
    broker, ha, topic_map, pw, work = house
    # 1. what earlier runs left: an older release's plain step, a cut wall-clock run's start
    _publish(broker, pw, "comems4build/step", "57")
    _publish(broker, pw, "comems4build/run", json.dumps({"clock": "wall:3600", "t0_unix_s": time.time() - 900,
                                                         "period_s": 1.0}))
    # 2. two lock-step runs back to back; in the second the user sets a battery power limit
    for i in range(2):
        out = work / f"sim_{i}"
        t_start = time.time()
        proc = _launch(out, broker, topic_map, 24 if i == 0 else 48)
        if i == 1:
            assert hac.wait_for(lambda: hac.live_step(ha) >= 3, BUDGET_S, 0.1), "the run did not get going"
            ha.post("/api/services/number/set_value", {"entity_id": "number.comems4build_battery_power_limit",
                                                       "value": 300})
        text = _finish(proc)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["steps"] == (24 if i == 0 else 48) and summary["fallback_steps"] == 0, text[-2000:]
        assert summary["mqtt"]["retained_cleared"] >= (2 if i == 0 else 1)  # the last run's step at least
        run_start = time.strftime("%Y-%m-%dT%H:%M", time.gmtime(t_start))
        assert hac.wait_for(lambda s=summary: not hac.check_entities(ha.states(), s), BUDGET_S), \
            hac.check_entities(ha.states(), summary)
        states = ha.states()
        # the gross purchase cost, as summary.json's cost_eur_total (the net is not what it shows)
        cost = states["sensor.comems4build_grid_cost_eur"]
        assert float(cost["state"]) == summary["cost_eur_total"] and cost["attributes"]["state_class"] == "total"
        assert cost["attributes"]["last_reset"][:16] in (run_start, time.strftime("%Y-%m-%dT%H:%M",
                                                                                  time.gmtime(t_start + 60)))
        assert states["sensor.comems4build_hp_mode"]["attributes"]["options"] == ["off", "heating", "dhw"]
        # live values are unavailable once the bridge is gone; the totals stay
        assert states["sensor.comems4build_soc_pct"]["state"] == "unavailable"
    # 3. the user's switch, during a run, across a restart of the bridge, and while no bridge runs
    out = work / "switch_on"
    proc = _launch(out, broker, topic_map, 48)
    assert hac.wait_for(lambda: hac.live_step(ha) >= 3, BUDGET_S, 0.1), "the run did not get going"
    ha.switch("comems4build_forced_fallback", True)
    text = _finish(proc)
    summary = json.loads((out / "summary.json").read_text())
    user = summary["fallback_causes"]["user_switch"]
    assert 1 <= user == summary["fallback_steps"] < 48 and summary["fallback_causes"]["late_command"] == 0
    assert "because the user switched the EMS off or the fallback on" in text
    assert "no valid command of the EMS came in time" not in text
    bridge_log = (work / "sim_1" / "log" / "mqtt_bridge.log").read_text()
    assert "setting battery_power_limit 300 (p_bess_w within [-300, 300])" in bridge_log
    out = work / "switch_kept"
    text = _finish(_launch(out, broker, topic_map, 12))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fallback_causes"]["user_switch"] == summary["fallback_steps"] == 12, text[-2000:]
    # the user's setting, too, is applied by a new bridge (Home Assistant's retained command)
    assert "setting battery_power_limit 300 (p_bess_w within [-300, 300])" in \
        (out / "log" / "mqtt_bridge.log").read_text()
    ha.post("/api/services/mqtt/publish", {"topic": "comems4build/switch/fallback/set", "payload": "OFF",
                                           "retain": True})  # an automation, while no bridge runs
    out = work / "switch_off"
    _finish(_launch(out, broker, topic_map, 12))
    assert json.loads((out / "summary.json").read_text())["fallback_steps"] == 0
    # 4. a wall-clock run cut, then one whose broker is killed for 1.4 s mid-run
    cut = _launch(work / "wall_cut", broker, topic_map, 48, "wall:3600")
    assert hac.wait_for(lambda: hac.live_step(ha) >= 3, BUDGET_S, 0.1), "the wall-clock run did not get going"
    cut.send_signal(signal.SIGINT)
    cut.communicate(timeout=BUDGET_S)
    out = work / "wall_restart"
    proc = _launch(out, broker, topic_map, 36, "wall:3600")
    assert hac.wait_for(lambda: hac.live_step(ha) >= 8, BUDGET_S, 0.1), "the wall-clock run did not get going"
    broker.kill()
    time.sleep(1.4)  # the fault: the broker down for 1.4 s
    broker.start()
    text = _finish(proc)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 36 and summary["lost_messages"] == {}, text[-2000:]
    mqtt = summary["mqtt"]
    assert mqtt["reconnects"] >= 1
    # what the outage cost is listed step by step (none, if the records bridged it)
    assert len(mqtt.get("setpoints_held_at", [])) == mqtt["setpoints_held"]
    assert len(mqtt.get("fallback_at", [])) == summary["fallback_steps"]
    print("broker restart:", {k: summary.get(k) for k in ("fallback_steps", "fallback_causes", "mqtt")})
    assert hac.wait_for(lambda s=summary: not hac.check_entities(ha.states(), s), BUDGET_S), \
        hac.check_entities(ha.states(), summary)
    # 5. Home Assistant's own view: no warning about the EMS's entities (the lost connection is the test's)
    problems = [p for p in ha.problems_in_log() if "The connection was lost" not in p]
    assert problems == [], problems
