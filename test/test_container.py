"""Container processes (layouts role and house): spec checks, parameters, closed loop equals in-process."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest
from waits import BUDGET_S

from comems4build_ros.ros.container import ContainerSpecError, load_spec, main, to_parameters


@pytest.fixture(autouse=True)
def _signals_restored():
    """The container's main, called in this process, ignores SIGINT and SIGTERM while it
    cleans up (``process.ignore_stop_signals``); restored so that no later test, nor a
    process it starts (ignored signals are inherited), runs with them ignored."""
    import signal

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, handler in saved.items():
        signal.signal(s, handler)


def _write(tmp_path: Path, obj: object) -> Path:
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return path


def test_load_spec_names_the_file_and_entry(tmp_path: Path) -> None:
    with pytest.raises(ContainerSpecError, match="spec.json.*'nodes' must be a non-empty list"):
        load_spec(_write(tmp_path, {"nodes": []}))
    with pytest.raises(ContainerSpecError, match=r"nodes\[1\]: namespace '/b' given twice"):
        load_spec(_write(tmp_path, {"nodes": [{"namespace": "/b"}, {"namespace": "/b"}]}))
    with pytest.raises(ContainerSpecError, match=r"nodes\[0\] needs a string 'namespace'"):
        load_spec(_write(tmp_path, {"nodes": [{"params": {}}]}))
    with pytest.raises(ContainerSpecError, match="spec.json"):
        load_spec(_write(tmp_path, "{not json"))
    spec = load_spec(_write(tmp_path, {"nodes": [{"namespace": "/a", "params": {"x": 1}}]}))
    assert spec["nodes"][0]["params"] == {"x": 1}
    with pytest.raises(ContainerSpecError, match=r"nodes\[0\]\.role 'broker': one of plant, feed, ems, recorder"):
        load_spec(_write(tmp_path, {"nodes": [{"namespace": "/a", "role": "broker"}]}))
    # a container runs one node per role and namespace
    both = [{"namespace": "/a", "role": "plant"}, {"namespace": "/a", "role": "feed"}]
    spec = load_spec(_write(tmp_path, {"nodes": both}))
    assert [e["role"] for e in spec["nodes"]] == ["plant", "feed"]
    with pytest.raises(ContainerSpecError, match=r"nodes\[1\]: namespace '/a' given twice"):
        load_spec(_write(tmp_path, {"nodes": [{"namespace": "/a", "role": "ems"}, {"namespace": "/a", "role": "ems"}]}))


def test_main_exit_code_2_on_bad_spec(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """(The message is a log line of rclpy's logger, written by rcutils to file descriptor 2.)"""
    assert main(["--role", "plant", "--spec", str(tmp_path / "missing.json")]) == 2
    assert "missing.json" in capfd.readouterr().err
    spec = _write(tmp_path, {"nodes": [{"namespace": "/house_0"}]})
    assert main(["--role", "container", "--spec", str(spec)]) == 2  # a container's entries name their role
    assert "node '/house_0' of a container needs a 'role'" in capfd.readouterr().err


def test_to_parameters_types() -> None:
    from rclpy.parameter import Parameter

    params = {
        p.name: p for p in to_parameters({"a": True, "b": 3, "c": 0.5, "d": "x", "e": ["u", "v"], "f": [], "g": [1.0]})
    }
    assert sorted(params) == ["a", "b", "c", "d", "e", "g"]  # empty list left out
    assert params["a"].type_ == Parameter.Type.BOOL and params["a"].value is True
    assert params["b"].type_ == Parameter.Type.INTEGER and params["b"].value == 3
    assert params["c"].type_ == Parameter.Type.DOUBLE
    assert params["d"].type_ == Parameter.Type.STRING
    assert params["e"].type_ == Parameter.Type.STRING_ARRAY and list(params["e"].value) == ["u", "v"]
    assert params["g"].type_ == Parameter.Type.DOUBLE_ARRAY


@pytest.mark.ros
def test_three_houses_in_the_role_layout_equal_in_process(tmp_path: Path) -> None:
    """3 houses, 2 per recorder process: 5 node processes, each house equals its in-process run."""
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.plan import LaunchOptions

    out = tmp_path / "run"
    launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=30, houses=3, layout="role",
                         houses_per_recorder=2, timeout_s=BUDGET_S, plant_node_params={"step_timeout_s": BUDGET_S}))
    logs = sorted(p.name for p in (out / "log").glob("*.log"))
    assert logs == ["role_ems.log", "role_feed.log", "role_plant.log", "role_recorder_0.log", "role_recorder_1.log"]
    assert_houses_equal_in_process(out, 3)


@pytest.mark.ros
def test_three_houses_in_two_containers_equal_in_process(tmp_path: Path) -> None:
    """Layout ``house``: every node of houses 0 and 2 in one container process, of
    house 1 in another; each house equals its in-process run, nothing lost, and the
    EMS and feed beside a finished recorder end at once (no linger for the recorder to leave)."""
    from comems4build_ros.ros.node import LINGER_S
    from comems4build_ros.run.launcher import launch
    from comems4build_ros.run.plan import LaunchOptions

    out = tmp_path / "run"
    res = launch(LaunchOptions(ems="fuzzy", out=out, weeks=1, steps=30, houses=3, containers=2, timeout_s=BUDGET_S,
                               plant_node_params={"step_timeout_s": BUDGET_S}))
    assert sorted(p.name for p in (out / "log").glob("*.log")) == ["container_0.log", "container_1.log"]
    log0 = (out / "log" / "container_0.log").read_text()
    for ns in ("house_0", "house_2"):
        for node in ("recorder", "fuzzy_ems", "feed", "plant_sim"):
            assert f"[{ns}.{node}]" in log0, (ns, node)
    assert_houses_equal_in_process(out, 3)
    assert res.run_s < LINGER_S  # the 30-step run did not wait out the linger for a recorder to leave


def assert_houses_equal_in_process(out: Path, n: int) -> None:
    """Each house's summary of the launch in ``out`` equals its in-process run; complete bags."""
    from comems4build_ros.bags.evaluation import lost_messages
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario.run import load_scenario
    from comems4build_ros.core.scenario.settings import load_scenario_settings
    from comems4build_ros.run.supervisor import processes_with_env

    params = load_plant_params()
    seed = load_scenario_settings().seed
    for i in range(n):
        per = json.loads((out / f"house_{i}" / "summary.json").read_text())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ref = simulate("fuzzy", load_scenario("default", params, None, 1, seed + i, 30), params).summary
        ros_only = {"wall_s", "ems_s", "bag_duration_s", "lost_messages"}
        keys = set(ref) - ros_only
        assert keys == set(per) - ros_only
        for k in sorted(keys):
            assert per[k] == ref[k] or (per[k] != per[k] and ref[k] != ref[k]), (i, k)  # NaN == NaN
        assert per["steps"] == 30
    assert (out / "bag" / f"house_{n - 1}" / "metadata.yaml").is_file()
    assert lost_messages(out / "bag") == {}  # no message lost on any topic of any house
    assert processes_with_env("ROS_LOG_DIR", str(out / "log" / "ros")) == []
