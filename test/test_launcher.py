"""``comems4build launch`` / ``evaluate``: closed loop over DDS equals in-process; faults leave no process."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from launch_probe import netns_available, pid_of, records_on_disk, run_held
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from waits import BUDGET_S, wait_until

from comems4build_ros.bags.evaluation import lost_messages
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate
from comems4build_ros.run.launcher import launch
from comems4build_ros.run.plan import LaunchOptions
from comems4build_ros.run.supervisor import processes_with_env

pytestmark = pytest.mark.ros
#: Runs compared with the in-process ones: the plant waits for every command within the budget (a
#: fallback on a slow step of a loaded machine would be the machine's).
WAIT = {"step_timeout_s": BUDGET_S}
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")  # not in in-process summaries
#: ``comems4build`` of this tree (``-m comems4build_ros.app.cli`` would define a second UsageError class).
CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]


def _reference(ems: str, steps: int, seed: int | None = None, forecast: str | None = None) -> dict:
    """In-process summary over the same scenario window as the feed builds it."""
    from comems4build_ros.core.loop import load_forecast_settings
    from comems4build_ros.core.scenario.run import load_scenario

    params = load_plant_params()
    scenario = load_scenario("default", params, None, 1, seed, steps)
    fs = load_forecast_settings(mode=forecast) if forecast else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate(ems, scenario, params, forecast=fs).summary


def _same(a: dict, b: dict) -> None:
    keys = set(a) - set(TIMING_KEYS)
    assert keys == set(b) - set(TIMING_KEYS)
    for k in sorted(keys):
        va, vb = a[k], b[k]
        if isinstance(va, float) and isinstance(vb, float) and math.isnan(va):
            assert math.isnan(vb), k
        else:
            assert va == vb, k


def test_launch_fuzzy_equals_in_process_and_bag_opens(tmp_path: Path) -> None:
    out = tmp_path / "run"
    seen: list[tuple[int, int]] = []  # progress reports (recorded steps, total steps; 0 = not known yet)
    res = launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=36, timeout_s=BUDGET_S, plant_node_params=WAIT,
                               on_progress=lambda r, n: seen.append((r, n))))
    assert seen and all(n in (0, 36) and 0 <= r <= 36 for r, n in seen)
    assert [r for r, _ in seen] == sorted(r for r, _ in seen)
    summary = json.loads((out / "summary.json").read_text())
    _same(summary, _reference("fuzzy", 36))
    assert summary["steps"] == 36 and summary["ems"] == "fuzzy" and summary["ems_s"] is None
    assert summary["lost_messages"] == {}
    assert (out / "weekly.csv").read_text().count("\n") == 2  # header + one (partial) week
    with AnyReader([res.bag]) as reader:
        assert sum(1 for c in reader.connections if c.topic == "/plant/record") == 1
        n_records = sum(1 for _ in reader.messages([c for c in reader.connections if c.topic == "/plant/record"]))
    assert n_records == 36
    with (res.bag / "bag.mcap").open("rb") as fh:
        stats = make_reader(fh).get_summary().statistics
    assert stats.message_count > 36 * 20
    assert lost_messages(res.bag) == {}
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []


def test_launch_mpc_with_realistic_forecasts_equals_in_process(tmp_path: Path) -> None:
    """The feed node builds the realistic forecasts (published prices, correlated weather errors,
    misplaced days) the in-process loop builds: the MPC's run over DDS is the in-process one, and it
    is not the perfect-forecast run."""
    out = tmp_path / "run"
    launch(LaunchOptions(ems="mpc", out=out, weeks=1, steps=36, forecast="realistic", timeout_s=300))
    summary = json.loads((out / "summary.json").read_text())
    ref = _reference("mpc", 36, forecast="realistic")
    assert ref.pop("forecast_errors")["price_unpublished_share"] > 0  # in-process only: the errors it met
    _same(summary, ref)
    assert summary["forecast"] == "realistic"
    assert summary["cost_eur_total"] != _reference("mpc", 36)["cost_eur_total"]


def test_two_houses_under_namespaces_with_seeds(tmp_path: Path) -> None:
    from comems4build_ros.core.scenario.settings import load_scenario_settings

    out = tmp_path / "run"
    launch(LaunchOptions(ems="rbc", out=out, weeks=1, steps=24, houses=2, timeout_s=BUDGET_S, plant_node_params=WAIT))
    # more than one house: container processes, one per core, at most one per house (docs/ros_tools.md)
    assert sorted(p.name for p in (out / "log").glob("*.log")) == [
        f"container_{j}.log" for j in range(min(2, os.cpu_count() or 1))]
    combined = json.loads((out / "summary.json").read_text())["houses"]
    assert sorted(combined) == ["house_0", "house_1"]
    seed = load_scenario_settings().seed
    for i in range(2):
        per = json.loads((out / f"house_{i}" / "summary.json").read_text())
        _same(per, _reference("rbc", 24, seed + i))
    assert combined["house_0"]["cost_eur_total"] != combined["house_1"]["cost_eur_total"]
    with AnyReader([out / "bag" / "house_0", out / "bag" / "house_1"]) as reader:  # one bag per house
        topics = {c.topic for c in reader.connections}
    assert {"/house_0/plant/record", "/house_1/ems/command"} <= topics
    assert lost_messages(out / "bag") == {}


# ---------------------------------------------------------------------- faults
def _cli(out: Path, *extra: str) -> subprocess.Popen:
    cmd = [*CLI, "launch", "--ems", "fuzzy", "--weeks", "12", "--out", str(out),
           "--no-progress", *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _recording(proc: subprocess.Popen, out: Path) -> bool:
    """The launch in ``out`` is under way: closed chunks with plant/record in its bag (or it ended:
    the caller's assertions say so)."""
    return proc.poll() is not None or records_on_disk(out / "bag")


def _finish(proc: subprocess.Popen, out: Path) -> tuple[int, str]:
    try:
        stdout, err = proc.communicate(timeout=BUDGET_S)
        proc.stdout_text = stdout  # type: ignore[attr-defined]  # for the assertion messages
    finally:
        if proc.poll() is None:
            proc.kill()
    marker = str(out / "log" / "ros")
    try:  # the launcher's processes end with it; a /proc entry may outlive its exit for a moment
        wait_until(lambda: not processes_with_env("ROS_LOG_DIR", marker), "no process of the launch left")
    finally:
        left = processes_with_env("ROS_LOG_DIR", marker)
        for pid in left:  # never leave anything behind, even when the assertion fails
            os.kill(pid, signal.SIGKILL)
    return proc.returncode, err


def _default_stop_signals() -> None:
    """In the child before exec: SIGINT and SIGTERM as by default (a signal ignored in the test
    process would be inherited, and an interpreter started with SIGINT ignored never raises
    KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def test_ctrl_c_stops_every_node_and_closes_the_bag(tmp_path: Path) -> None:
    out = tmp_path / "run"
    # the launcher picks and locks a free domain id; the run is held in progress (its plant
    # paused) when Ctrl-C comes, however late this process sees its start
    proc = subprocess.Popen([*CLI, "launch", "--ems", "fuzzy", "--weeks", "12", "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_stop_signals)
    wait_until(lambda: _recording(proc, out), "the run recording")
    with run_held(out):
        assert proc.poll() is None
        proc.send_signal(signal.SIGINT)
        code, err = _finish(proc, out)  # every node stopped (none left behind), the recorder last
    assert code == 130, (err, getattr(proc, "stdout_text", ""))
    assert not out.exists()  # all or nothing: an interrupted run leaves no partial result (nor its bag)


def test_ems_crash_stops_the_launch(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _cli(out)
    wait_until(lambda: _recording(proc, out), "the run recording")
    with run_held(out):  # the run cannot end before the EMS dies
        os.kill(pid_of(out, "fuzzy_ems"), signal.SIGKILL)
        code, err = _finish(proc, out)
    assert code == 1
    assert "node 'fuzzy_ems' exited with code -9" in err
    assert (out / "bag" / "metadata.yaml").is_file()


def test_recorder_sigkill_then_evaluate_reads_the_cut_bag(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _cli(out)
    wait_until(lambda: _recording(proc, out), "closed chunks with plant/record (1 s chunk period)")
    with run_held(out):  # the run cannot end before the recorder dies
        os.kill(pid_of(out, "recorder"), signal.SIGKILL)
        code, err = _finish(proc, out)
    assert code == 1 and "node 'recorder' exited with code -9" in err
    assert not (out / "bag" / "metadata.yaml").exists()
    ev = tmp_path / "eval"
    res = subprocess.run([*CLI, "evaluate", str(out / "bag"), "--out", str(ev)],
                         capture_output=True, text=True, timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr
    summary = json.loads((ev / "summary.json").read_text())
    inc = summary["bag_incomplete"]
    assert inc["steps_expected"] == 2016 and 0 < inc["steps_recorded"] < 2016
    assert inc["metadata_yaml"] is False
    assert summary["steps"] == inc["steps_recorded"] and summary["ems"] == "fuzzy"


def test_evaluate_refuses_a_missing_bag(tmp_path: Path) -> None:
    res = subprocess.run([*CLI, "evaluate", str(tmp_path / "nope"), "--out",
                          str(tmp_path / "e")], capture_output=True, text=True, timeout=BUDGET_S)
    assert res.returncode == 2 and "nope" in res.stderr


def test_a_paused_recorder_cannot_hang_the_launcher(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGSTOP on the recorder once the run is under way, never continued: the launcher still ends, by
    its default overall time limit (made short here), with an error, and leaves no process behind.

    The recorder is paused only once the feed publishes (its writers matched the recorder's
    readers; a feed still waiting for that would stall the plant first) in a run long enough to be
    under way then, whose plant is never held back by the paused recording (a record window
    longer than the run)."""
    import threading

    from comems4build_ros.run import plan
    from comems4build_ros.run.supervisor import LaunchError

    # the overall limit must leave the run time to get under way on a loaded machine (the nodes'
    # start-up), and is what ends the launch: the test lasts this long
    monkeypatch.setattr(plan, "TIME_LIMIT_START_S", 60.0)
    monkeypatch.setattr(plan, "TIME_LIMIT_PER_STEP_S", 0.0)
    out = tmp_path / "run"
    outcome: list[BaseException | None] = []

    def run() -> None:
        try:  # no timeout_s: the default applies
            launch(LaunchOptions(ems="rbc", out=out, weeks=12, plant_node_params={"record_window_steps": 100_000}))
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - reported below
            outcome.append(exc)

    def feed_publishes() -> bool:
        log = out / "log" / "feed.log"
        return log.exists() and "matched the recorder's readers" in log.read_text(errors="replace")

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    marker = str(out / "log" / "ros")
    try:
        wait_until(lambda: feed_publishes() or not thread.is_alive(), "the feed publishing")
        assert thread.is_alive(), f"the launch ended before the run was under way: {outcome}"
        os.kill(pid_of(out, "recorder"), signal.SIGSTOP)
        wait_until(lambda: not thread.is_alive(), "the launcher to return")
    finally:
        left = processes_with_env("ROS_LOG_DIR", marker)
        for pid in left:  # never leave anything behind, even when the assertions fail
            os.kill(pid, signal.SIGKILL)
    assert isinstance(outcome[0], LaunchError) and "time limit" in str(outcome[0])
    assert left == []


def test_two_network_namespaces_give_the_in_process_kpis(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """Plant + feed and EMS + recorder on two 'hosts' (network namespaces, veth, UDP, unicast
    discovery), netem 5 ms delay and 1 % loss where the kernel has it: the KPIs of the run equal
    the in-process run exactly."""
    reason = netns_available()
    if reason:
        pytest.skip(f"network namespaces unavailable: {reason}")
    out = tmp_path / "run"
    res = launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=30, network="netns",
                               netem="delay 5ms loss 1%", timeout_s=BUDGET_S, plant_node_params=WAIT))
    summary = json.loads((out / "summary.json").read_text())
    _same(summary, _reference("fuzzy", 30))
    assert summary["lost_messages"] == {} and summary["fallback_steps"] == 0
    err = capfd.readouterr().err
    netem = "netem" not in err  # the launcher says so when the kernel has no netem
    print(f"netem applied: {netem}; round trip over the veth link: wall {res.wall_s:.1f} s")
    ns_list = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert f"c4b{res.domain_id}p" not in ns_list and f"c4b{res.domain_id}e" not in ns_list  # torn down
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []
