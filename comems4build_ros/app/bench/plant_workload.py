"""The workload of ``comems4build bench plant``: the default scenario stepped with random valid actions.

It uses only :mod:`comems4build_ros.core` APIs that older revisions share (``Plant``,
``Action``, ``load_plant_params``, ``default_scenario``, ``exogenous_series``), so that
``tools/bench_plant_against.py`` can run this file, unchanged, against the package of another
revision in a fresh process (``python -P plant_workload.py`` with that revision on
``PYTHONPATH``): both sides then time the same loop over the same steps and actions.

Run as a script it prints one JSON object: the figures of :func:`time_plant`.
"""

from __future__ import annotations

import argparse
import json
import random
import time


def random_actions(params, n: int, seed: int) -> list:
    """Random valid actions.

    Parameters
    ----------
    params : PlantParams
        The plant's parameters (the heat pump's ``mod_min`` [-], the fuel cell's ``p_min_w``,
        ``p_max_w`` [W] and ``zeta`` [-], the battery's ``p_ch_max_w`` and ``p_d_max_w`` [W]).
    n : int
        Number of actions.
    seed : int
        Seed of the random generator.

    Returns
    -------
    list of Action
        Heat pump off or on one circuit at a modulation in [mod_min, 1]; fuel cell off or in
        [P_min, zeta P_max] [W]; battery power within its ratings [W].
    """
    from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action

    rng = random.Random(seed)
    hp, fc, b = params.heat_pump, params.fuel_cell, params.battery
    out = []
    for _ in range(n):
        mode = rng.choice((HP_OFF, HP_SH, HP_SH, HP_DHW))
        mod = 0.0 if mode == HP_OFF else rng.uniform(hp.mod_min, 1.0)
        p_fc = 0.0 if rng.random() < 0.5 else rng.uniform(fc.p_min_w, fc.zeta * fc.p_max_w)
        p_b = rng.uniform(-b.p_d_max_w, b.p_ch_max_w)
        out.append(Action(hp_mod=mod, hp_mode=mode, p_fc_w=p_fc, p_bess_w=p_b))
    return out


def time_plant(plant, exo: list, actions: list, repeats: int) -> dict[str, float]:
    """Step the plant ``repeats`` times through ``exo`` from its initial state.

    Parameters
    ----------
    plant : Plant
        The plant to step.
    exo : list of Exogenous
        The inputs of the steps.
    actions : list of Action
        One action per step.
    repeats : int
        Times the steps are run through.

    Returns
    -------
    dict
        ``steps``; ``steps_per_s`` (wall clock) and ``steps_per_cpu_s`` (the process's CPU
        time, less sensitive to other processes on the machine) [1/s]; ``steps_per_cpu_s_best``,
        of the run with the least CPU time [1/s]; ``run_s_mean`` and ``run_s_best``, the wall
        time of one run through ``exo`` [s]; ``max_residual_w``,
        the largest power-balance residual of the last steps of the runs [W].
    """
    step = plant.step
    n = len(exo)
    best = float("inf")
    total = 0.0
    total_cpu = 0.0
    best_cpu = float("inf")
    max_residual = 0.0
    for _ in range(repeats):
        state = plant.initial_state()
        c0 = time.process_time()
        t0 = time.perf_counter()
        for k in range(n):
            state, flows = step(state, actions[k], exo[k])
        dt = time.perf_counter() - t0
        cpu = time.process_time() - c0
        total_cpu += cpu
        best_cpu = min(best_cpu, cpu)
        total += dt
        best = min(best, dt)
        max_residual = max(max_residual, abs(flows.balance_residual_w))
    return {
        "steps": float(n * repeats),
        "steps_per_s": n * repeats / total,
        "steps_per_cpu_s": n * repeats / total_cpu if total_cpu > 0.0 else float("inf"),
        "steps_per_cpu_s_best": n / best_cpu if best_cpu > 0.0 else float("inf"),
        "run_s_mean": total / repeats,
        "run_s_best": best,
        "max_residual_w": max_residual,
    }


def workload(params, weeks: int, seed: int) -> tuple:
    """The plant, the inputs and the actions of the benchmark.

    Parameters
    ----------
    params : PlantParams
        The plant's parameters.
    weeks : int
        Length of the default scenario [weeks].
    seed : int
        Seed of the random actions.

    Returns
    -------
    (Plant, Scenario, list of Exogenous, list of Action)
    """
    from comems4build_ros.core.loop import exogenous_series
    from comems4build_ros.core.plant import Plant
    from comems4build_ros.core.scenario import default_scenario

    scenario = default_scenario(params, weeks=weeks)
    exo = exogenous_series(scenario, params)[: scenario.n_steps]
    return Plant(params), scenario, exo, random_actions(params, len(exo), seed)


def main(argv: list[str] | None = None) -> int:
    """Time the workload once (after a warm-up run) and print its figures as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--weeks", type=int, default=12)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    from comems4build_ros.core.config import load_plant_params

    plant, _, exo, actions = workload(load_plant_params([]), args.weeks, args.seed)
    time_plant(plant, exo, actions, 1)  # warm-up
    print(json.dumps(time_plant(plant, exo, actions, args.repeats)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
