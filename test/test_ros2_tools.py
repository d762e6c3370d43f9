"""What a ROS 2 engineer does first, with the real ``ros2`` tools: sim time, remapping, parameters, launch, logs.

Each test drives ``ros2 run``, ``ros2 param``, ``ros2 node``, ``ros2 topic`` or ``ros2
launch`` (test/ros2_tools.py: a ROS 2 install, or the command-line tools' wheels in a
temporary overlay; skipped with the reason where neither is there) against the installed
package, as docs/ros_tools.md shows them.
"""

from __future__ import annotations

import re
import subprocess

import pytest
import yaml
from ros2_tools import (
    CLI,
    evaluate,
    node_names,
    reference,
    ros2_env,
    run_ros2,
    run_until,
    same_kpis,
    start_ros2,
    stop,
)
from waits import BUDGET_S, log_has, wait_until

pytestmark = pytest.mark.ros

LAUNCH = ["launch", "comems4build_ros", "comems4build.launch.py"]
#: Runs compared with the in-process ones: the plant waits for every command within the budget (a
#: fallback on a slow step of a loaded machine would be the machine's).
STEP_TIMEOUT_BUDGET = f"step_timeout:={BUDGET_S:g}"
#: Each ``ros2 param`` call discovers the graph anew (--no-daemon): time for it on a loaded machine.
DISCOVER = ["--spin-time", "5", "--timeout", "10"]





# ---------------------------------------------------------------------- ros2 run: bad parameters
@pytest.mark.parametrize("exe, args, says", [
    ("feed", ["-p", "weeks:=1.5"], "parameter 'weeks' = 1.5: expected an integer"),
    ("feed", ["-p", "weeks:=abc"], "parameter 'weeks' = 'abc': expected an integer"),
    ("feed", ["-p", "weeks:=40"], "parameter 'weeks' = 40: outside its range 0 .. 12 weeks: the data of scenario "
                                  "'default' hold 12"),
    ("plant_sim", ["-p", "step_timout_s:=2.0"], "parameter 'step_timout_s': not a parameter of this node (did you "
                                                "mean 'step_timeout_s'?)"),
    ("plant_sim", ["-p", "exit_when_done:=maybe"], "parameter 'exit_when_done' = 'maybe': expected true or false"),
    ("fuzzy_ems", ["-p", "wait_for_recorder:=maybe"], "parameter 'wait_for_recorder' = 'maybe': expected true or"),
    ("recorder", ["-p", "bag_path:=b", "-p", "tick_s:=0"], "parameter 'tick_s' = 0: outside its range"),
    ("rbc_ems", ["-p", "use_sim_time:=1"], "parameter 'use_sim_time' = 1: expected true or false"),
])
def test_ros2_run_refuses_a_bad_parameter_naming_it(ros2, domain_id, tmp_path, exe, args, says) -> None:
    res = run_ros2(ros2, ["run", "comems4build_ros", exe, "--ros-args", "-r", "__ns:=/bad", *args], domain_id,
                   tmp_path)
    assert res.returncode == 2, res.stdout + res.stderr
    text = res.stdout + res.stderr
    assert "refused to start:" in text and says in text, text[-2000:]
    assert "Traceback" not in text


# ---------------------------------------------------------------------- ros2 run: running nodes
#: Time-outs of the nodes that must not end or fall back by themselves during the test: an hour,
#: longer than any wait of a test (test/waits.py), so a fallback proves a time-out set at run time.
NEVER_S = "3600.0"
RUNS = {
    "plant_sim": ["-r", "__ns:=/t", "-p", f"startup_timeout_s:={NEVER_S}", "-p", f"step_timeout_s:={NEVER_S}"],
    "feed": ["-r", "__ns:=/t", "-p", "steps:=336", "-p", "weeks:=2"],  # longer than the test (0.5-s fallbacks)
    "fuzzy_ems": ["-r", "__ns:=/s", "-p", "use_sim_time:=true"],
    "recorder": ["-r", "__ns:=/r", "-p", "use_sim_time:=true"],
    "mqtt_bridge": ["-r", "__ns:=/m", "-p", "broker_url:=mqtt://127.0.0.1:9", "-p", f"startup_timeout_s:={NEVER_S}"],
}


def test_ros2_param_on_running_nodes(ros2, domain_id, tmp_path) -> None:
    """``ros2 run`` of every node (two with ``use_sim_time:=true``); ``ros2 param dump`` prints
    all parameters of each, a read-only one is refused with the reason, a live one takes
    effect (the plant without an EMS falls back at once instead of after an hour), and
    ``use_sim_time`` set at run time returns and the node goes on, stamping its log with
    the simulated time of ``/clock``."""
    args = dict(RUNS, recorder=[*RUNS["recorder"], "-p", f"bag_path:={tmp_path / 'bag'}"])
    procs = {exe: start_ros2(ros2, ["run", "comems4build_ros", exe, "--ros-args", *a], domain_id, tmp_path,
                             tmp_path / f"{exe}.log") for exe, a in args.items()}
    nodes = {"plant_sim": "/t/plant_sim", "feed": "/t/feed", "fuzzy_ems": "/s/fuzzy_ems", "recorder": "/r/recorder",
             "mqtt_bridge": "/m/mqtt_bridge"}
    try:
        wait_until(lambda: set(nodes.values()) <= node_names(ros2, domain_id, tmp_path) or any(
            p.poll() is not None for p in procs.values()), "every node up")
        assert all(p.poll() is None for p in procs.values()), {e: (tmp_path / f"{e}.log").read_text()[-800:]
                                                               for e, p in procs.items() if p.poll() is not None}
        for exe, node in nodes.items():
            # --no-daemon: each call discovers the graph anew; on a loaded machine give it time
            dump = run_until(ros2, ["param", "dump", node, "--no-daemon", "--spin-time", "5", "--timeout", "10"],
                             domain_id, tmp_path, lambda r: "ros__parameters" in r.stdout)
            listed = run_until(ros2, ["param", "list", node, "--no-daemon", "--spin-time", "5"], domain_id, tmp_path,
                               lambda r: "config_files" in r.stdout or "bag_path" in r.stdout)
            assert "ros__parameters" in dump.stdout, (node, dump.stdout[-1500:], dump.stderr[-1500:])
            values = yaml.safe_load(dump.stdout)[node]["ros__parameters"]

            def flat(d: dict, prefix: str = "") -> set[str]:
                return {n for k, v in d.items() for n in (flat(v, f"{prefix}{k}.") if isinstance(v, dict)
                                                           else {f"{prefix}{k}"})}

            names = {n.strip() for n in listed.stdout.splitlines() if n.strip() and not n.strip().endswith(":")}
            assert flat(values) == names and len(names) > 15, (exe, dump.stdout[-500:], listed.stdout[-500:])
            if exe != "recorder":
                assert values["config_files"] == [] and values["battery"]["e_max_kwh"] == 6.5, exe
        refused = run_until(ros2, ["param", "set", "/t/plant_sim", "battery.e_max_kwh", "3.0", "--no-daemon",
                                   *DISCOVER], domain_id, tmp_path,
                            lambda r: "Setting parameter" in r.stdout + r.stderr)
        assert "Setting parameter failed: Trying to set a read-only parameter: battery.e_max_kwh" in refused.stderr
        for name in ("startup_timeout_s", "step_timeout_s"):
            ok = run_until(ros2, ["param", "set", "/t/plant_sim", name, "0.5", "--no-daemon", *DISCOVER], domain_id,
                           tmp_path, lambda r: "Set parameter" in r.stdout)
            assert "Set parameter successful" in ok.stdout, ok.stdout + ok.stderr
        # a fallback at all: the hour given at the start has not passed
        wait_until(lambda: log_has(tmp_path / "plant_sim.log", "fallback"), "a fallback step after the new time-outs")
        plant_log = (tmp_path / "plant_sim.log").read_text()
        assert plant_log.index("parameter 'startup_timeout_s' = 0.5 from now on") < plant_log.index("fallback")
        live = run_until(ros2, ["param", "set", "/t/plant_sim", "use_sim_time", "true", "--no-daemon", *DISCOVER],
                         domain_id, tmp_path, lambda r: "Set parameter" in r.stdout)
        assert "Set parameter successful" in live.stdout, live.stdout + live.stderr
        run_ros2(ros2, ["topic", "pub", "--once", "/clock", "rosgraph_msgs/msg/Clock", "{clock: {sec: 1669849200}}"],
                 domain_id, tmp_path)
        run_until(ros2, ["param", "set", "/s/fuzzy_ems", "use_sim_time", "true", "--no-daemon", *DISCOVER], domain_id,
                  tmp_path, lambda r: "Set parameter" in r.stdout)
        wait_until(lambda: log_has(tmp_path / "fuzzy_ems.log", "[sim "), "a log line with the sim time")
        assert all(p.poll() is None for p in procs.values()), {e: (tmp_path / f"{e}.log").read_text()[-800:]
                                                               for e, p in procs.items() if p.poll() is not None}
    finally:
        codes = stop(list(procs.values()))
    logs = {e: (tmp_path / f"{e}.log").read_text() for e in procs}
    assert all("Traceback" not in text for text in logs.values()), logs
    assert "parameter 'step_timeout_s' = 0.5 from now on" in logs["plant_sim"]
    assert codes == [0 if e == "recorder" else 3 for e in procs] or all(c in (0, 3) for c in codes), codes


def test_remapped_node_and_topic_names_keep_the_contract(ros2, domain_id, tmp_path) -> None:
    """``-r __node:=`` and ``-r from:=to`` on plant_sim, feed and fuzzy_ems: each runs under the
    name given, its endpoints where the remapping puts them, checked by role, type and QoS."""
    runs = {
        "plant_sim": ["-r", "__node:=myplant", "-r", "ems/command:=ems/command_raw"],
        "feed": ["-r", "__node:=weather", "-r", "feed/truth:=inputs/truth", "-p", "steps:=24", "-p", "weeks:=1"],
        "fuzzy_ems": ["-r", "__node:=shadow", "-r", "ems/command:=ems/command_raw"],
    }
    procs = [start_ros2(ros2, ["run", "comems4build_ros", exe, "--ros-args", "-r", "__ns:=/x", *a], domain_id,
                        tmp_path, tmp_path / f"{exe}.log") for exe, a in runs.items()]
    try:
        want = {"/x/myplant", "/x/weather", "/x/shadow"}
        wait_until(lambda: want <= node_names(ros2, domain_id, tmp_path) or any(p.poll() is not None for p in procs),
                   "the remapped nodes up")
        assert all(p.poll() is None for p in procs), [(tmp_path / f"{e}.log").read_text()[-800:] for e in runs]
        info = run_until(ros2, ["topic", "info", "/x/ems/command_raw", "--no-daemon"], domain_id, tmp_path,
                         lambda r: "Publisher count: 1" in r.stdout and "Subscription count: 1" in r.stdout)
        assert "Publisher count: 1" in info.stdout and "Subscription count: 1" in info.stdout, info.stdout
        truth = run_until(ros2, ["topic", "info", "/x/inputs/truth", "--no-daemon"], domain_id, tmp_path,
                          lambda r: "Publisher count: 1" in r.stdout)
        assert "Publisher count: 1" in truth.stdout, truth.stdout
    finally:
        stop(procs)


def test_log_level_and_rosout(ros2, domain_id, tmp_path) -> None:
    """``--log-level warn`` keeps the error naming a bad parameter and drops the info lines;
    a node's messages reach ``/rosout``; ``--log-level debug`` shows the lock-step lines."""
    res = run_ros2(ros2, ["run", "comems4build_ros", "plant_sim", "--ros-args", "--log-level", "warn", "-r",
                          "__ns:=/w", "-p", "wait_for_recorder:=maybe"], domain_id, tmp_path)
    text = res.stdout + res.stderr
    assert "[ERROR]" in text and "parameter 'wait_for_recorder'" in text and "[INFO]" not in text, text
    plant = start_ros2(ros2, ["run", "comems4build_ros", "plant_sim", "--ros-args", "-r", "__ns:=/w"], domain_id,
                       tmp_path, tmp_path / "plant.log")
    echo = None
    try:
        wait_until(lambda: "/w/plant_sim" in node_names(ros2, domain_id, tmp_path), "plant_sim up")
        # /rosout is transient local (rcl's profile): a reader asking for that gets the node's
        # lines from before it matched too, but only those of the last 10 s (the profile's
        # lifespan): on a loaded machine the start-up line can be older than that when the
        # reader comes, so what is awaited is a line of the node at all, then a new one
        echo = start_ros2(ros2, ["topic", "echo", "/rosout", "rcl_interfaces/msg/Log", "--qos-durability",
                                 "transient_local", "--qos-reliability", "reliable"], domain_id, tmp_path,
                          tmp_path / "rosout.log")
        wait_until(lambda: log_has(tmp_path / "rosout.log", "name: w.plant_sim"), "a line of the node on /rosout")
        res = run_until(ros2, ["param", "set", "/w/plant_sim", "step_timeout_s", "4.5", "--no-daemon", *DISCOVER],
                        domain_id, tmp_path, lambda r: "Set parameter" in r.stdout)
        assert "Set parameter successful" in res.stdout, res.stdout + res.stderr
        wait_until(lambda: log_has(tmp_path / "rosout.log", "parameter 'step_timeout_s' = 4.5 from now on"),
                   "the node's log line on /rosout")
    finally:
        stop([plant, *([echo] if echo else [])])
    out = tmp_path / "run"
    launched = run_ros2(ros2, [*LAUNCH, "ems:=rbc", "weeks:=1", "steps:=3", "log_level:=debug", f"out:={out}"],
                        domain_id, tmp_path)
    assert launched.returncode == 0, launched.stdout[-3000:]
    for line in ("step 0: announced", "step 0: command accepted", "step 0: stepped", "step 0: decided and sent",
                 "plant/step 0: inputs of steps 0..2 published"):  # steps:=3: the feed has steps 0..2
        assert line in launched.stdout, line


# ---------------------------------------------------------------------- ros2 launch
@pytest.mark.parametrize("args, says", [
    (["weeks:=abc"], "weeks:=abc: 'abc' is not a finite number"),
    (["clock:=wall"], "clock:=wall needs plant:=mqtt; broker:= and topic_map:= need plant:=mqtt"),
    (["plant:=mqtt", "houses:=2"], "plant:=mqtt runs one house (houses:=1)"),
    (["use_sim_time:=maybe"], "use_sim_time:=maybe: expected true or false"),
    (["print_plan:=yes"], "print_plan:=yes: expected true or false"),
    (["log_level:=loud"], "log_level:=loud: one of debug, info, warn, error, fatal"),
    (["network:=netns"], "network:=netns needs 'comems4build launch --network netns'"),
])
def test_ros2_launch_refuses_in_launch_words(ros2, domain_id, tmp_path, args, says) -> None:
    res = run_ros2(ros2, [*LAUNCH, *args, f"out:={tmp_path / 'run'}"], domain_id, tmp_path)
    assert res.returncode == 2, res.stdout + res.stderr
    assert f"comems4build.launch.py: error: {says}" in res.stderr, res.stderr
    assert "usage:" not in res.stderr and "--weeks" not in res.stderr and not (tmp_path / "run").exists()


def test_ros2_launch_honours_the_launchers_arguments(ros2, domain_id, tmp_path) -> None:
    """plant:=mqtt clock:=wall print_plan:=true prints the MQTT plan as ``comems4build launch`` does;
    an argument the file does not have is named, with the nearest one."""
    res = run_ros2(ros2, [*LAUNCH, "plant:=mqtt", "clock:=wall:3600", "print_plan:=true", "wekks:=1",
                          "out:=run", "domain:=9"], domain_id, tmp_path)
    assert res.returncode == 0, res.stderr
    assert "process mqtt_bridge [plant" in res.stdout and "process broker [broker" in res.stdout
    assert "clock:=\"wall:3600\"" in res.stdout and "--clock wall:3600" in res.stdout
    assert "launch argument 'wekks' is not one of comems4build.launch.py (did you mean 'weeks'?)" in res.stderr
    cli = subprocess.run([*CLI, "launch", "--ems", "fuzzy", "--plant", "mqtt", "--clock", "wall:3600", "--out",
                          "run", "--domain-id", "9", "--print-plan"], capture_output=True, text=True, cwd=tmp_path,
                         timeout=BUDGET_S)
    assert cli.returncode == 0, cli.stderr

    def plan(text: str) -> list[str]:  # the plan as printed, the broker's free port and the run's id masked
        lines = [ln for ln in text[text.index("run plan:"):].splitlines() if not ln.startswith("[INFO]")]
        masked = [re.sub(r"(127\.0\.0\.1:|--port )\d+", r"\1P", ln) for ln in lines]
        return [re.sub(r"(--run-id |run_id:=\\?\"?)[0-9a-f]+", r"\1ID", ln) for ln in masked]

    assert plan(res.stdout) == plan(cli.stdout)


@pytest.mark.parametrize("layout", ["node", "house"])
def test_use_sim_time_on_every_node_gives_the_same_run(ros2, domain_id, tmp_path, layout) -> None:
    """``use_sim_time:=true`` (a launch-wide SetParameter; for the container layout on the
    container's command line): the KPIs equal the in-process run bit for bit, the nodes log
    the simulated time, the bag's stamps are simulated times, no ``.secrets`` is left."""
    from rosbags.highlevel import AnyReader

    steps = 30
    out = tmp_path / "run"
    res = run_ros2(ros2, [*LAUNCH, "ems:=fuzzy", "weeks:=1", f"steps:={steps}", "houses:=2", f"layout:={layout}",
                          "use_sim_time:=true", STEP_TIMEOUT_BUDGET, f"out:={out}"], domain_id, tmp_path)
    assert res.returncode == 0, res.stdout[-3000:]
    # a container's output goes to its launch log file (the progress lines), a node's to the screen
    logs = res.stdout + "".join(f.read_text(errors="replace") for f in (tmp_path / "ros_log").rglob("*.log"))
    assert re.search(r"\[sim 2022-1[12]-\d\dT\d\d:00:00Z\]", logs)  # 2022-12-01 00:00 CET = 2022-11-30T23:00Z
    assert not (out / ".secrets").exists()
    from comems4build_ros.core.scenario.settings import load_scenario_settings

    summary = evaluate(out / "bag", tmp_path / "eval")
    seed = load_scenario_settings().seed
    for i in range(2):
        got = summary["houses"][f"house_{i}"]
        assert got["lost_messages"] == {} and got["steps"] == steps
        same_kpis(got, reference("fuzzy", steps, seed + i))
    with AnyReader([out / "bag" / "house_0"]) as reader:
        stamps = sorted(t for _c, t, _raw in reader.messages())
        clocks = [c for c in reader.connections if c.topic == "/clock"]
    # simulated times, whole hours of the run: from the start of its first step (2022-12-01T00:00+01:00;
    # or the end of it, when the time source's depth-1 reader kept only the later of two early ticks)
    # to the end of its last
    start_ns, hour_ns = 1669849200 * 10**9, 3600 * 10**9
    assert stamps[0] in (start_ns, start_ns + hour_ns) and stamps[-1] == start_ns + steps * hour_ns
    assert all((t - start_ns) % hour_ns == 0 for t in stamps)
    assert len(clocks) == 1  # one clock per run, in the first house's bag
    with AnyReader([out / "bag" / "house_1"]) as reader:
        assert not [c for c in reader.connections if c.topic == "/clock"]


def test_the_discovery_server_graph_is_reachable_as_printed(ros2, domain_id, tmp_path) -> None:
    """houses:=2 layout:=node runs behind a discovery server: the launch prints its address, and
    ``ros2 node list`` as a super client (the printed setting) lists every node."""
    out = tmp_path / "run"
    log = tmp_path / "launch.log"
    # the MPC over 12 weeks: a run far longer than the look at its graph (stopped after it)
    launch = start_ros2(ros2, [*LAUNCH, "ems:=mpc", "weeks:=12", "houses:=2", "layout:=node", f"out:={out}"],
                        domain_id, tmp_path, log)
    try:
        wait_until(lambda: log_has(log, "ROS_SUPER_CLIENT=TRUE"), "the server's address printed")
        m = re.search(r"ROS_DISCOVERY_SERVER=(\S+) ROS_SUPER_CLIENT=TRUE", log.read_text())
        assert m is not None
        env = ros2_env(ros2, domain_id, tmp_path, ROS_DISCOVERY_SERVER=m.group(1), ROS_SUPER_CLIENT="TRUE")
        want = {f"/house_{i}/{n}" for i in range(2) for n in ("plant_sim", "feed", "mpc_ems", "recorder")}
        seen: set[str] = set()

        def listed() -> bool:
            seen.update(node_names(ros2, domain_id, tmp_path, env))
            assert launch.poll() is None, f"the launch ended first (listed: {seen}): {log.read_text()[-3000:]}"
            return want <= seen

        wait_until(listed, "every node in the super client's node list")
        plain = node_names(ros2, domain_id, tmp_path)  # without the setting: the graph is hidden
        assert not want & plain, plain
    finally:
        stop([launch])


def test_bench_cut_kills_a_node_under_both_launchers_and_leaves_nothing(ros2, tmp_path) -> None:
    """``comems4build bench cut`` (one run per launcher): plant_sim SIGKILLed mid-run, each launch
    ends with an error, no process of the run is left and no run token either (the time it
    took is the benchmark's figure, not asserted here)."""
    cmd = " ".join(ros2["argv"])
    res = subprocess.run([*CLI, "bench", "cut", "--runs", "1", "--ros2", cmd, "--out", str(tmp_path / "cut")],
                         capture_output=True, text=True, timeout=BUDGET_S, env=ros2["env"])
    assert res.returncode == 0, res.stdout + res.stderr
    for via in ("launch", "ros2"):
        line = next(ln for ln in res.stdout.splitlines() if ln.startswith(f"{via} run 0:"))
        assert "exit code 1, 0 process(es) left, .secrets gone" in line, res.stdout
        assert re.search(rf"^{via}: 1 run\(s\), median \d+\.\d\d s", res.stdout, re.M), res.stdout


@pytest.mark.parametrize(("message", "says"), [
    ("--clock wall needs --plant mqtt or --community", "clock:=wall needs plant:=mqtt"),
    ("--weeks or --steps, not both", "weeks:= or steps:=, not both"),  # both offered: kept
    ("give --houses or --layout-file or --steps", "give houses:= or steps:="),  # only the one not offered goes
])
def test_in_launch_words_leaves_out_what_the_launch_file_does_not_offer(message: str, says: str) -> None:
    from comems4build_ros.app.ros2_launch import in_launch_words

    assert in_launch_words(message, {"clock": "wall"}) == says
