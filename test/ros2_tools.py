"""The real ROS 2 command-line tools for the conformance tests (not a test module).

``ros2_command`` finds ``ros2`` with ``launch_ros``: a ROS 2 install on PATH, or else the
wheels of the folder ``COMEMS4BUILD_ROS2_CLI`` (default: ``ros2-cli`` in the ``shared``
folder beside the repository) installed into a temporary overlay of this environment
(``pip install --target``, put first on ``PYTHONPATH``); it skips, saying why, where
neither is there. The package is found through ``AMENT_PREFIX_PATH`` = this environment's
prefix, as a ROS user sets it. ``conftest.py`` makes it the session fixture ``ros2``.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import pytest
from waits import BUDGET_S, Deadline, wait_until

REPO = Path(__file__).resolve().parents[1]
#: Folder of the ROS 2 CLI wheels (README, install.sh, wheels/); overridable by this variable.
ROS2_CLI_ENV = "COMEMS4BUILD_ROS2_CLI"
#: Their own PyPI dependencies (install.sh) and those of these, where this environment lacks them.
CLI_DEPENDENCIES = {"argcomplete": "argcomplete", "importlib_metadata": "importlib-metadata", "zipp": "zipp",
                    "catkin_pkg": "catkin-pkg", "osrf_pycommon": "osrf-pycommon", "docutils": "docutils",
                    "lark": "lark", "psutil": "psutil", "packaging": "packaging", "yaml": "pyyaml",
                    "dateutil": "python-dateutil", "pyparsing": "pyparsing"}


def cli_folder() -> Path:
    """Where the ROS 2 CLI wheels are looked for."""
    return Path(os.environ.get(ROS2_CLI_ENV) or REPO.parent / "shared" / "ros2-cli")


def ros2_command(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """``{"argv": [...ros2], "env": {...}}``: the ``ros2`` command and the environment it needs."""
    env = dict(os.environ, AMENT_PREFIX_PATH=sys.prefix, PYTHONUNBUFFERED="1")
    own = shutil.which("ros2")
    if own and subprocess.run([own, "launch", "--help"], capture_output=True, env=env).returncode == 0:
        return {"argv": [own], "env": env}  # a real ROS 2 install
    folder = cli_folder()
    wheels = sorted((folder / "wheels").glob("*.whl"))
    if not wheels:
        pytest.skip(f"no ROS 2 command-line tools: neither 'ros2' with launch on PATH nor the wheels in {folder} "
                    f"(set {ROS2_CLI_ENV} to the folder holding wheels/)")
    site = tmp_path_factory.mktemp("ros2_cli") / "site"
    missing = []
    for module, dist in CLI_DEPENDENCIES.items():
        if subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True).returncode != 0:
            missing.append(dist)
    res = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", "--no-deps",
                          "--target", str(site), *missing, *map(str, wheels)], capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip(f"could not install the ROS 2 command-line tools from {folder}: {res.stderr.strip()[-500:]}")
    env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [env.get("PYTHONPATH")])])
    return {"argv": [sys.executable, str(site / "bin" / "ros2")], "env": env}


def ros2_env(ros2: dict, domain: int, tmp_path: Path, **extra: str) -> dict[str, str]:
    """The environment of a ``ros2`` call of one test: its domain, logs in ``tmp_path``, this host only."""
    return dict(ros2["env"], ROS_DOMAIN_ID=str(domain), ROS_LOG_DIR=str(tmp_path / "ros_log"),
                ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **extra)


def run_ros2(ros2: dict, args: list[str], domain: int, tmp_path: Path, env: dict[str, str] | None = None,
             **kw: object) -> subprocess.CompletedProcess:
    """``ros2 <args>`` to its end (within the budget, test/waits.py): exit code, stdout and stderr."""
    return subprocess.run([*ros2["argv"], *args], env=env or ros2_env(ros2, domain, tmp_path), capture_output=True,
                          text=True, timeout=BUDGET_S, cwd=tmp_path, **kw)


def start_ros2(ros2: dict, args: list[str], domain: int, tmp_path: Path, log: Path,
               env: dict[str, str] | None = None) -> subprocess.Popen:
    """``ros2 <args>`` in the background (its own session), stdout and stderr into ``log``."""
    with open(log, "wb") as out:
        return subprocess.Popen([*ros2["argv"], *args], env=env or ros2_env(ros2, domain, tmp_path), cwd=tmp_path,
                                stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def stop(procs: list[subprocess.Popen]) -> list[int]:
    """SIGINT to each still running process group (``ros2 run`` and its node), then their exit codes
    (SIGKILL to a group still running after the budget)."""
    for p in procs:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGINT)
    codes = []
    deadline = Deadline("the processes to exit after SIGINT")
    for p in procs:
        try:
            codes.append(p.wait(timeout=deadline.left()))
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            codes.append(p.wait())
    return codes


def node_names(ros2: dict, domain: int, tmp_path: Path, env: dict[str, str] | None = None) -> set[str]:
    """``ros2 node list --no-daemon`` (no daemon to stop afterwards; the tool listens 3 s, then
    prints what it discovered: callers ask again until their node is listed)."""
    res = run_ros2(ros2, ["node", "list", "--no-daemon", "--spin-time", "3"], domain, tmp_path, env=env)
    return set(res.stdout.split())


def run_until(ros2: dict, args: list[str], domain: int, tmp_path: Path,
              ok: Callable[[subprocess.CompletedProcess], bool],
              env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """``ros2 <args>`` until ``ok(result)``, within the budget (test/waits.py): a query of a node
    just discovered, or of a topic whose endpoints are not all discovered yet, can miss them on a
    loaded machine. Returns the last result (the caller's assertion shows it)."""
    last: list[subprocess.CompletedProcess] = []

    def done() -> bool:
        last[:] = [run_ros2(ros2, args, domain, tmp_path, env=env)]
        return ok(last[0])

    try:
        wait_until(done, f"ros2 {' '.join(args)}: the answer looked for")
    except AssertionError:
        pass
    return last[0]


#: ``comems4build`` in this interpreter (the installed package's command line).
CLI = [sys.executable, "-c", "import sys; from comems4build_ros.app.cli import main; sys.exit(main())"]
#: Summary entries that differ between runs of the same figures (timing, transport).
TIMING_KEYS = ("wall_s", "ems_s", "bag_duration_s", "lost_messages")


def reference(ems: str, steps: int, seed: int | None = None) -> dict:
    """In-process summary over the window the feed builds (default scenario, first week)."""
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario.run import load_scenario

    params = load_plant_params()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate(ems, load_scenario("default", params, None, 1, seed, steps), params).summary


def same_kpis(got: dict, want: dict) -> None:
    """Every figure of the in-process summary, bit for bit (timing entries aside)."""
    keys = set(want) - set(TIMING_KEYS)
    assert keys <= set(got)
    for k in sorted(keys):
        a, b = got[k], want[k]
        assert (isinstance(a, float) and math.isnan(a) and math.isnan(b)) or a == b, k


def evaluate(bag: Path, out: Path) -> dict:
    """``comems4build evaluate BAG --out OUT``; its summary."""
    res = subprocess.run([*CLI, "evaluate", str(bag), "--out", str(out)], capture_output=True, text=True,
                         timeout=BUDGET_S)
    assert res.returncode == 0, res.stderr
    return json.loads((out / "summary.json").read_text())
