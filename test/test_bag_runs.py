"""A bag is one run's record or is refused: ``evaluate`` never summarises two runs as one.

Bags are written here with the project's BagWriter from in-process runs (their
``plant/record`` rows and ``feed/truth``), so the cases are exact: records of two plants on
one topic, the same run recorded twice, two feeds' ``feed/info``, a ``feed/info`` of another
run than the bag's ``run_info.json``; runs in namespaces of their own are evaluated each.
``--strict`` turns an incomplete or damaged bag into exit code 1; a topic without any message
is named as such, not as "lost".
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_bad_input import step_messages

from comems4build_ros.bags.evaluation import MixedRunsError, read_bag_set
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate
from comems4build_ros.core.scenario import resolve_scenario
from comems4build_ros.wire.cdr import string_cdr

CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
STEPS = 12
T0_NS = 1_700_000_000 * 10**9


def _timeseries(ems: str, seed: int | None = None) -> pd.DataFrame:
    params = load_plant_params()
    return simulate(ems, resolve_scenario("default", params, hours=STEPS, seed=seed), params).timeseries


TS = {"rbc": _timeseries("rbc"), "fuzzy": _timeseries("fuzzy"), "rbc7": _timeseries("rbc", seed=7)}


MESSAGES = {name: step_messages(ts, STEPS) for name, ts in TS.items()}  # (feed/truth, plant/record)


def write_bag(path: Path, runs: list[dict], run_id: str | None = "run-a", silent: tuple[str, ...] = ()) -> Path:
    """A bag of ``runs`` (each: ``ns``, ``run`` (a key of :data:`TS`), optional ``steps`` (those
    recorded), ``feed_info`` (a ``feed/info`` document, None: none)), with a ``run_info.json``
    naming ``run_id``; ``silent``: further per-step topics of the first namespace with a channel and
    no message."""
    from comems4build_ros.bags.bag import BagWriter

    with BagWriter(path) as w:
        for ns in dict.fromkeys(r["ns"] for r in runs):
            for name in ("plant/record", "feed/truth"):
                w.add_topic(f"{ns.rstrip('/')}/{name}", "std_msgs/msg/Float64MultiArray")
            w.add_topic(f"{ns.rstrip('/')}/feed/info", "std_msgs/msg/String")
        for name in silent:
            w.add_topic(f"{runs[0]['ns'].rstrip('/')}/{name}", "std_msgs/msg/Float64MultiArray")
        t = T0_NS
        for run in runs:
            ns = run["ns"].rstrip("/")
            if run.get("feed_info") is not None:
                w.write(f"{ns}/feed/info", t, string_cdr(json.dumps(run["feed_info"])))
            for k in run.get("steps", range(STEPS)):
                t += 2
                w.write(f"{ns}/feed/truth", t, MESSAGES[run["run"]][k][0])
                w.write(f"{ns}/plant/record", t + 1, MESSAGES[run["run"]][k][1])
    if run_id is not None:
        (path / "run_info.json").write_text(json.dumps({"ems": "rbc", "run_id": run_id}))
    return path


def feed_info(run_id: str | None = "run-a", for_ems: str | None = None) -> dict:
    return {"scenario": "default", "n_steps": STEPS, "run_id": run_id, "for_ems": for_ems}


def evaluate(bag: Path, out: Path, *options: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, "evaluate", str(bag), "--out", str(out), *options], capture_output=True, text=True,
                          timeout=180)


def test_two_plants_records_on_one_topic_are_refused(tmp_path: Path) -> None:
    """The RBC's and the fuzzy EMS's house recorded in one namespace (two inclusions of the launch
    file without namespaces): exit 2 naming the topic, and no summary written."""
    bag = write_bag(tmp_path / "bag", [{"ns": "/", "run": "rbc", "feed_info": feed_info()},
                                       {"ns": "/", "run": "fuzzy", "feed_info": feed_info()}])
    res = evaluate(bag, tmp_path / "out")
    assert res.returncode == 2, res.stderr
    assert "topic '/plant/record' carries records of more than one plant: 12 step(s) recorded twice (0-11)" \
        in res.stderr and "with different values" in res.stderr
    assert not (tmp_path / "out" / "summary.json").exists()


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(foreign=st.sets(st.integers(0, STEPS - 1), min_size=1), other=st.sampled_from(["fuzzy", "rbc7", "rbc"]))
def test_any_step_of_another_plant_in_the_record_is_refused(tmp_path: Path, foreign: set[int], other: str) -> None:
    """However few steps of another plant (another EMS, another seed, or the very same run
    recorded twice) reach the topic, the namespace is refused, never summarised."""
    bag = write_bag(Path(tempfile.mkdtemp(dir=tmp_path)) / "bag",
                    [{"ns": "/h", "run": "rbc"}, {"ns": "/h", "run": other, "steps": sorted(foreign)}])
    with pytest.raises(MixedRunsError, match=rf"{len(foreign)} step\(s\) recorded twice"):
        read_bag_set(bag, "UTC")


def test_two_feeds_or_another_runs_feed_are_refused(tmp_path: Path) -> None:
    """Two different feed/info documents in one namespace; a feed/info naming another run than
    run_info.json: both refused, naming the run ids."""
    two = write_bag(tmp_path / "two", [{"ns": "/", "run": "rbc", "feed_info": feed_info("run-a")},
                                       {"ns": "/", "run": "rbc", "feed_info": feed_info("run-b"), "steps": []}])
    with pytest.raises(MixedRunsError, match="2 different scenario descriptions .*run-a, run-b"):
        read_bag_set(two, "UTC")
    other = write_bag(tmp_path / "other", [{"ns": "/", "run": "rbc", "feed_info": feed_info("run-b")}],
                      run_id="run-a")
    with pytest.raises(MixedRunsError, match="names run 'run-b', the bag's run_info.json run 'run-a'"):
        read_bag_set(other, "UTC")


def test_runs_in_namespaces_of_their_own_are_each_evaluated(tmp_path: Path) -> None:
    """Two runs, each in its own namespace, in one bag: each evaluates to its own in-process figures."""
    bag = write_bag(tmp_path / "bag", [{"ns": "/a", "run": "rbc", "feed_info": feed_info()},
                                       {"ns": "/b", "run": "fuzzy", "feed_info": feed_info()}])
    runs, _ = read_bag_set(bag, "UTC")
    for ns, ems in (("/a", "rbc"), ("/b", "fuzzy")):
        got = runs[ns].timeseries
        want = TS[ems]
        assert runs[ns].complete and list(got["p_buy_w"]) == list(want["p_buy_w"])


def test_strict_fails_an_incomplete_bag_and_passes_a_complete_one(tmp_path: Path) -> None:
    """A bag with 8 of 12 steps: evaluated (exit 0), with --strict exit 1 naming what is missing;
    a complete bag passes --strict."""
    cut = write_bag(tmp_path / "cut", [{"ns": "/", "run": "rbc", "steps": range(8), "feed_info": feed_info()}])
    assert evaluate(cut, tmp_path / "o1").returncode == 0
    res = evaluate(cut, tmp_path / "o2", "--strict")
    assert res.returncode == 1, res.stderr
    assert "--strict: bag" in res.stderr and "8 of 12 steps recorded" in res.stderr
    assert (tmp_path / "o2" / "summary.json").is_file()
    whole = write_bag(tmp_path / "whole", [{"ns": "/", "run": "rbc", "feed_info": feed_info()}])
    res = evaluate(whole, tmp_path / "o3", "--strict")
    assert res.returncode == 0, res.stderr


def test_a_topic_without_any_message_is_named_as_such(tmp_path: Path) -> None:
    """No forecast/* message from a feed serving the RBC (feed/info's for_ems): nothing missing, the
    bag evaluates; no feed/prices message although the RBC reads it: refused, saying it has no
    message at all (not published or never received), and --accept-gaps with --strict exits 1."""
    unread = write_bag(tmp_path / "unread", [{"ns": "/", "run": "rbc", "feed_info": feed_info(for_ems="rbc_ems")}],
                       silent=("forecast/p_pv_w", "feed/t_amb"))
    res = evaluate(unread, tmp_path / "o1", "--strict")
    assert res.returncode == 0, res.stderr
    silent = write_bag(tmp_path / "silent", [{"ns": "/", "run": "rbc", "feed_info": feed_info(for_ems="rbc_ems")}],
                       silent=("feed/prices",))
    res = evaluate(silent, tmp_path / "o2")
    assert res.returncode == 2
    assert "/feed/prices: no message at all (12 step(s)): not published in this run, or never received" in res.stderr
    assert "lost" not in res.stderr
    res = evaluate(silent, tmp_path / "o3", "--accept-gaps", "--strict")
    assert res.returncode == 1 and "messages missing on /feed/prices (12 step(s))" in res.stderr, res.stderr
