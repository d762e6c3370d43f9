"""The plant's steps per second side by side with other revisions, in one run.

Each revision named on the command line is exported from git (``git archive``: the package and
its ``config/``) into a temporary folder; then, for ``--rounds`` rounds, the workload of
``comems4build bench plant`` (``comems4build_ros/app/bench/plant_workload.py`` of this
checkout: the default scenario stepped with random valid actions) runs once per contender,
each in a fresh process with that contender's package first on ``PYTHONPATH``. The order of
the contenders turns by one each round, so no one always runs first. It prints each
contender's median steps per second (wall clock and CPU time of the process) and the
median over the rounds of the ratio this checkout / revision (> 1: this checkout is faster).
The CPU-time figures move less with other processes on the machine; "best CPU" is the
fastest single run through the weeks of any of the contender's processes (the one least
disturbed). The load average is printed before and after.

    .venv/bin/python tools/bench_plant_against.py 85b18d1^ main --rounds 7

The contender "this" is the package of this checkout's working tree (uncommitted changes
included).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORKLOAD = ROOT / "comems4build_ros" / "app" / "bench" / "plant_workload.py"
#: What a revision needs to run the workload: the package and its parameter files.
EXPORTED = ("comems4build_ros", "config")


def git(*args: str) -> str:
    """Output of a git command in this checkout (exit 2 with git's message if it fails)."""
    done = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    if done.returncode != 0:
        print(f"bench_plant_against: git {' '.join(args)}: {done.stderr.strip()}", file=sys.stderr)
        raise SystemExit(2)
    return done.stdout.strip()


def export(rev: str, into: Path) -> str:
    """Write the package and config of ``rev`` under ``into``; return its short commit id."""
    sha = git("rev-parse", "--verify", f"{rev}^{{commit}}")
    data = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", sha, *EXPORTED],
                          capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(into, filter="data")
    return sha[:7]


def measure(root: Path, weeks: int, repeats: int, seed: int) -> dict[str, float]:
    """One fresh process timing the workload against the package under ``root``."""
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, "-P", str(WORKLOAD), "--weeks", str(weeks), "--repeats", str(repeats),
           "--seed", str(seed)]
    done = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        print(f"bench_plant_against: the workload failed under {root}:\n{done.stderr}", file=sys.stderr)
        raise SystemExit(1)
    return json.loads(done.stdout.strip().splitlines()[-1])


def load() -> str:
    """The 1, 5 and 15 minute load averages."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv: list[str] | None = None) -> int:
    """Parse the options, run the rounds and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("revs", nargs="+", metavar="REV", help="git revision to compare with (commit, branch, rev^)")
    parser.add_argument("--rounds", type=int, default=5, help="rounds, each one process per contender (default 5)")
    parser.add_argument("--weeks", type=int, default=12, help="run length [weeks] (default 12)")
    parser.add_argument("--repeats", type=int, default=20, help="runs through the weeks per process (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random actions (default 0)")
    args = parser.parse_args(argv)
    if min(args.rounds, args.weeks, args.repeats) < 1 or args.seed < 0:
        parser.error("--rounds, --weeks and --repeats must be >= 1, --seed >= 0")
    with tempfile.TemporaryDirectory(prefix="bench_plant_") as tmp:
        contenders = [("this", "working tree", ROOT)]
        for i, rev in enumerate(args.revs):
            into = Path(tmp) / str(i)
            contenders.append((rev, export(rev, into), into))
        load_before = load()
        runs: list[list[dict[str, float]]] = [[] for _ in contenders]
        order = list(range(len(contenders)))
        for r in range(args.rounds):
            turn = r % len(contenders)
            for i in order[turn:] + order[:turn]:
                runs[i].append(measure(contenders[i][2], args.weeks, args.repeats, args.seed))
        load_after = load()
    steps = int(runs[0][0]["steps"]) // args.repeats
    print(f"plant step side by side: {steps} steps x {args.repeats} repeats per process, {args.rounds} rounds, "
          "contenders alternating in fresh processes")
    print(f"load average (1, 5, 15 min): {load_before} before, {load_after} after; {os.cpu_count()} CPUs")
    print(f"{'contender':<12} {'commit':<13} {'steps/s wall':>13} {'steps/s CPU':>12} {'best CPU':>9} "
          f"{'this/it wall':>13} {'this/it CPU':>12}")
    for (name, commit, _), mine in zip(contenders, runs):
        wall = statistics.median(x["steps_per_s"] for x in mine)
        cpu = statistics.median(x["steps_per_cpu_s"] for x in mine)
        ratio_wall = statistics.median(a["steps_per_s"] / b["steps_per_s"] for a, b in zip(runs[0], mine))
        ratio_cpu = statistics.median(a["steps_per_cpu_s"] / b["steps_per_cpu_s"] for a, b in zip(runs[0], mine))
        best = max(x.get("steps_per_cpu_s_best", 0.0) for x in mine)
        print(f"{name:<12} {commit:<13} {wall:>13,.0f} {cpu:>12,.0f} {best:>9,.0f} {ratio_wall:>13.3f} "
              f"{ratio_cpu:>12.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
