"""Wall time of one set of study runs on 1 and 2 local workers and on a local Dask cluster of 2 workers.

``comems4build bench study`` makes the same runs (``--runs`` of them: the EMS of ``--ems``
in turn, each on the seeds from ``--seed`` on, ``--weeks`` of ``--scenario``) through the
study pool (:mod:`comems4build_ros.study.pool`), with each run stored as it
finishes as a study does, three ways: in this process (t1), on 2 local worker processes
(t2) and on a Dask cluster of a scheduler and 2 single-threaded workers started by the
command as separate processes (``dask scheduler``, ``dask worker``; t2 Dask, measured
after the cluster is up and has imported the simulation). It prints the wall times, the
parallel efficiencies t1 / (2 t2) (target of the project: at least 80 % on 2 workers),
the load average before and after each measurement (other jobs on the cores lower the
figures), the runs' own times summed and the share of the workers' time spent in runs
(what the pool itself leaves idle, hardly touched by other jobs), and whether the
three ways gave the same summaries (timing entries aside).
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from comems4build_ros.app.bench.mpc import load_text
from comems4build_ros.app.commands.options import COUNT, SEED, add_scenario_options

#: Parallel efficiency the project aims at on 2 workers against 1 (reported, not enforced).
TARGET_EFFICIENCY = 0.80
#: First seed of the runs when ``--seed`` is not given.
SEED_DEFAULT = 1
#: Summary entries that are timings (they differ between any two runs).
TIMING_KEYS = ("wall_s", "ems_s", "task_wall_s")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench study``."""
    parser.add_argument("--ems", metavar="NAME[,NAME...]", default="fuzzy,rbc",
                        help="EMS of the runs, taken in turn (default fuzzy,rbc)")
    parser.add_argument("--runs", metavar="N", type=COUNT, default=8,
                        help="runs in the set, integer >= 1 (default 8: each EMS on 8 / len(EMS) seeds)")
    add_scenario_options(parser, hours=False, seed=False)
    parser.add_argument("--seed", metavar="N", type=SEED, default=SEED_DEFAULT,
                        help=f"first seed of the modelled inputs, 0..2^32-1 (default {SEED_DEFAULT}; the runs of one "
                             "EMS take the seeds from it on; none for a scenario CSV, whose data are all measured)")
    parser.add_argument("--repeats", metavar="N", type=COUNT, default=3,
                        help="measurements of each way, integer >= 1; the median is reported (default 3)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="parameter file merged over config/plant.yaml (repeatable)")
    parser.add_argument("--no-dask", action="store_true", help="only the local ways (no cluster started)")


def run_set(args: argparse.Namespace, emss: list[str], out: Path) -> list[Any]:
    """The runs of the benchmark, writing into ``out/<name>``: EMS in turn, seeds from ``--seed`` on."""
    from comems4build_ros.core.scenario import EMBEDDED
    from comems4build_ros.study.runner import RunTask

    config = [str(Path(c).resolve()) for c in args.config]
    embedded = args.scenario in EMBEDDED
    scenario = args.scenario if embedded else str(Path(args.scenario).resolve())
    tasks = []
    for i in range(args.runs):
        ems, k = emss[i % len(emss)], i // len(emss)
        seed = int(args.seed) + k if embedded else None
        name = f"{ems}_s{seed}" if embedded else f"{ems}_{k}"
        tasks.append(RunTask(ems=ems, out_dir=str(out / name), scenario=scenario, start=args.start,
                             weeks=args.weeks, seed=seed, extend=args.extend, config=config))
    return tasks


def _measure(label: str, tasks_of: Any, backend: Any, repeats: int,
             work: Path) -> tuple[list[float], list[Any], list[float]]:
    """Wall times of ``repeats`` studies of the run set on ``backend``, the last one's summaries, and per
    study the runs' own times summed (``task_wall_s``: how long each run took where it ran)."""
    from comems4build_ros.study.pool import StudyPool, run_jobs
    from comems4build_ros.study.store import RunStore

    walls, summaries, busy = [], [], []
    for r in range(repeats):
        where = work / f"{label.replace(' ', '_')}_{r}"
        tasks = tasks_of(where / "runs")
        before = load_text()
        with StudyPool(backend, RunStore.of(where)) as ex:
            t0 = time.perf_counter()
            summaries = run_jobs(tasks, ex, progress=False, quiet=True)
            walls.append(time.perf_counter() - t0)
            ex.complete()
        busy.append(sum(float(x["task_wall_s"]) for x in summaries))
        print(f"  {label:<26} repeat {r + 1}: {walls[-1]:7.2f} s, runs' own times summed {busy[-1]:7.2f} s   "
              f"({before}; after: {load_text()})", flush=True)
    return walls, summaries, busy


def _same(a: list[dict[str, Any]], b: list[dict[str, Any]]) -> bool:
    def strip(s: dict[str, Any]) -> str:
        return json.dumps({k: v for k, v in s.items() if k not in TIMING_KEYS}, sort_keys=True)

    return [strip(s) for s in a] == [strip(s) for s in b]


def run(args: argparse.Namespace) -> int:
    """Measure the three ways and print the table."""
    from comems4build_ros.app.commands.options import check_config_files, ems_names, load_params, scenario_of
    from comems4build_ros.core.scenario import EMBEDDED
    from comems4build_ros.study.cluster import LocalDaskCluster
    from comems4build_ros.study.pool import DaskBackend, LocalBackend

    emss = ems_names(args.ems)
    check_config_files(args.config)
    check = argparse.Namespace(**{**vars(args), "seed": args.seed if args.scenario in EMBEDDED else None})
    scenario_of(check, load_params(args.config))  # the scenario and the run length, checked before any run
    with tempfile.TemporaryDirectory(prefix="comems4build-bench-study-") as tmp:
        work = Path(tmp)
        tasks_of = lambda out: run_set(args, emss, out)  # noqa: E731
        names = [Path(t.out_dir).name for t in tasks_of(work)]
        weeks = f"{args.weeks:g} weeks" if args.weeks else "the whole"
        print(f"bench study: {len(names)} runs ({', '.join(names)}), {weeks} of scenario "
              f"{args.scenario}; {args.repeats} repeat(s) per way; {load_text()}", flush=True)
        results: dict[str, tuple[list[float], list[Any], list[float]]] = {}
        results["1 local worker"] = _measure("1 local worker", tasks_of, LocalBackend(1), args.repeats, work)
        results["2 local workers"] = _measure("2 local workers", tasks_of, LocalBackend(2), args.repeats, work)
        if not args.no_dask:
            with LocalDaskCluster(n_workers=2, threads=1) as cluster:
                print(f"  Dask cluster up in {cluster.start_s:.1f} s: scheduler {cluster.address}, 2 workers of 1 "
                      f"thread, dashboard {cluster.dashboard}", flush=True)
                backend = DaskBackend(cluster.address, security=cluster.security)
                results["Dask, 2 workers"] = _measure("Dask, 2 workers", tasks_of, backend, args.repeats, work)
    t1 = statistics.median(results["1 local worker"][0])
    print(f"\n{'way':<18}{'median wall [s]':>16}{'range [s]':>18}{'efficiency t1/(2 t2)':>22}"
          f"{'runs summed [s]':>17}{'workers busy':>14}")
    for label, (walls, _, busy) in results.items():
        med = statistics.median(walls)
        n = 1 if label.startswith("1 ") else 2
        eff = "" if n == 1 else f"{100 * t1 / (2 * med):.1f} %"
        share = statistics.median(b / (n * w) for b, w in zip(busy, walls))
        print(f"{label:<18}{med:>16.2f}{f'{min(walls):.2f} .. {max(walls):.2f}':>18}{eff:>22}"
              f"{statistics.median(busy):>17.2f}{f'{100 * share:.0f} %':>14}")
    print("(runs summed: each run's own time where it ran, above the 1-worker figure when runs at once slow each "
          "other, e.g. with other jobs on the cores; workers busy: runs summed / (workers x wall), what the "
          "pool leaves idle is the rest)")
    ref = results["1 local worker"][1]
    same = all(_same(ref, s) for _, s, _ in results.values())
    for label, (walls, _, _) in results.items():
        if label.startswith("1 "):
            continue
        eff = t1 / (2 * statistics.median(walls))
        print(f"{label}: parallel efficiency {100 * eff:.1f} % "
              f"({'meets' if eff >= TARGET_EFFICIENCY else 'MISSES'} the {100 * TARGET_EFFICIENCY:.0f} % target)")
    print(f"summaries identical across the ways (timing entries aside): {'yes' if same else 'NO'}")
    print(load_text())
    return 0 if same else 1
