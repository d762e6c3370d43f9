"""The EMS node of docs/own_ems_node.md, taken from the page as it stands, in a run of
``plant_sim``, ``feed`` and ``recorder`` started with the real ``ros2 run`` (test/ros2_tools.py).

The node needs nothing of the package: it runs with this environment's Python and rclpy only.
The run's bag is complete, no step fell back, and the plant applied exactly the commands the
node sent. The nodes' log files under ``ROS_LOG_DIR`` are named after the nodes.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest
from ros2_tools import CLI, ros2_env, start_ros2, stop, wait_for

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "own_ems_node.md"
STEPS = 48
#: Wall-time budget of the run on a loaded 2-core machine [s] (a condition is waited for, not a time).
RUN_BUDGET_S = 150.0


def page_node() -> str:
    """The node's code: the page's one ``python`` block."""
    blocks = re.findall(r"^```python\n(.*?)^```", PAGE.read_text(encoding="utf-8"), flags=re.S | re.M)
    assert len(blocks) == 1, "docs/own_ems_node.md: one python block, the node"
    return blocks[0]


def test_the_pages_node_is_complete_and_short() -> None:
    code = page_node()
    assert len(code.splitlines()) < 80
    assert "comems4build" not in re.sub(r'""".*?"""', "", code, flags=re.S).replace("comems4build_ros", "")
    compile(code, "my_ems.py", "exec")


def test_the_pages_node_runs_a_house_started_with_ros2_run(ros2, domain_id, tmp_path) -> None:
    import subprocess

    from comems4build_ros.bags.bag import decode, iter_messages

    node = tmp_path / "my_ems.py"
    node.write_text(page_node(), encoding="utf-8")
    bag = tmp_path / "my_bag"
    env = ros2_env(ros2, domain_id, tmp_path)
    logs = tmp_path / "out"
    logs.mkdir()
    run = [["run", "comems4build_ros", "recorder", "--ros-args", "-p", f"bag_path:={bag}"],
           ["run", "comems4build_ros", "plant_sim", "--ros-args", "-p", "wait_for_recorder:=true"],
           ["run", "comems4build_ros", "feed", "--ros-args", "-p", "wait_for_recorder:=true", "-p", "weeks:=1",
            "-p", f"steps:={STEPS}"]]
    procs = [start_ros2(ros2, args, domain_id, tmp_path, logs / f"{args[2]}.log") for args in run]
    with open(logs / "my_ems.log", "wb") as out:
        ems = subprocess.Popen([sys.executable, str(node)], env=env, cwd=tmp_path, stdout=out,
                               stderr=subprocess.STDOUT, start_new_session=True)
    procs.append(ems)
    try:
        def ended() -> bool:
            return all(p.poll() is not None for p in procs)

        wait_for(ended, RUN_BUDGET_S, "every node ended with the run", period=0.2)
    finally:
        codes = stop(procs)
    text = {p.name: p.read_text(errors="replace")[-3000:] for p in logs.iterdir()}
    assert codes == [0, 0, 0, 0], text
    res = subprocess.run([*CLI, "evaluate", str(bag), "--out", str(tmp_path / "eval"), "--strict"],
                         capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    summary = json.loads((tmp_path / "eval" / "summary.json").read_text())
    assert summary["steps"] == STEPS and summary["fallback_steps"] == 0 and summary["lost_messages"] == {}
    assert "ros_faults" not in summary  # no rejected, wrong-step or foreign command
    sent: dict[int, list[float]] = {}
    applied: dict[int, list[float]] = {}
    for topic, msgtype, _t, raw in iter_messages(bag):
        data = list(decode(msgtype, raw).data) if topic in ("/ems/command", "/plant/record") else []
        if topic == "/ems/command":
            assert sent.setdefault(int(data[0]), data) == data  # a step answered again with the same command
        elif topic == "/plant/record":
            applied[int(data[0])] = data
    from comems4build_ros.wire.contract import load_contract

    index = load_contract().topic("plant/record").layout({}).index
    fields = ("cmd_hp_mod", "cmd_hp_mode", "cmd_p_fc_w", "cmd_p_bess_w", "cmd_p_el_w")
    assert sorted(sent) == sorted(applied) == list(range(STEPS))
    for k, record in applied.items():
        assert [record[index[f]] for f in fields] == sent[k][1:6], k
    assert {c[2] for c in sent.values()} >= {1.0}, "the rules heated at least once"
    # the log files of ROS_LOG_DIR are named after the nodes, not after the Python interpreter
    names = {p.name.split("_")[0] for p in (tmp_path / "ros_log").rglob("*.log")}
    for name in ("plant", "feed", "recorder"):
        assert name in names, sorted(p.name for p in (tmp_path / "ros_log").rglob("*.log"))
    assert any(p.name.startswith("plant_sim_") for p in (tmp_path / "ros_log").rglob("*.log"))
