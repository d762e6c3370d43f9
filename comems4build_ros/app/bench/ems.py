"""Time per control step of the fuzzy EMS or the RBC, and the 12-week in-process run.

``comems4build bench ems --ems fuzzy`` runs the EMS through the default scenario once
(``comems4build_ros.core.loop.simulate``, plant included) and prints its wall time; a second
run records every observation and the time of each ``act`` call (median and p99). For
the fuzzy EMS it then replays the first ``--skfuzzy-steps`` observations through the same
controller with its three FLCs evaluated by ``skfuzzy.control`` systems built from the
same rule-base files, prints their per-step times, the ratio of the medians and the
largest difference of the set-points. Targets of the project: all three FLCs at most
0.2 ms per step, at least 50 times faster than skfuzzy.control, the 12-week fuzzy run
under 2 s including the plant.
"""

from __future__ import annotations

import argparse
import time
import warnings
from typing import Any

from comems4build_ros.app.commands.options import WHOLE_WEEKS, integer

#: Speed targets of the project (reported, not enforced).
TARGET_STEP_MS = 0.2
TARGET_RATIO = 50.0
TARGET_RUN_S = 2.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench ems``."""
    parser.add_argument("--ems", choices=("fuzzy", "rbc"), default="fuzzy", help="controller to time (default fuzzy)")
    parser.add_argument("--weeks", metavar="N", type=WHOLE_WEEKS, default=12,
                        help="run length [weeks], integer, 1 .. 30 years (default 12)")
    parser.add_argument(
        "--skfuzzy-steps", metavar="N", type=integer(0), default=300,
        help="steps replayed with skfuzzy.control for the comparison, integer >= 0 (fuzzy only, default 300)",
    )
    parser.add_argument("--config", action="append", default=[], metavar="FILE", help="extra plant parameter file")


class _Recorder:
    """Wraps a controller: records each observation and the time of each ``act`` [s]."""

    def __init__(self, ctrl: Any) -> None:
        self.ctrl = ctrl
        self.name = ctrl.name
        self.info_level = ctrl.info_level
        self.observations: list[Any] = []
        self.times_s: list[float] = []
        self.actions: list[Any] = []

    def reset(self) -> None:
        self.ctrl.reset()

    def act(self, obs: Any) -> Any:
        t0 = time.perf_counter()
        action = self.ctrl.act(obs)
        self.times_s.append(time.perf_counter() - t0)
        self.observations.append(obs)
        self.actions.append(action)
        return action


class SkfuzzyFLC:
    """One FLC evaluated by ``skfuzzy.control`` with the call signature of ``FuzzySystem``."""

    def __init__(self, system: Any) -> None:
        from skfuzzy import control as ctrl

        self.names = [v.name for v in system.inputs]
        self.lo = [v.lo for v in system.inputs]
        self.hi = [v.hi for v in system.inputs]
        self.out = system.output.name
        self.sim = ctrl.ControlSystemSimulation(system.to_skfuzzy())

    def __call__(self, *values: float) -> float:
        for name, lo, hi, v in zip(self.names, self.lo, self.hi, values):
            self.sim.input[name] = min(hi, max(lo, float(v)))
        self.sim.compute()
        return float(self.sim.output[self.out])


def _pct(values: list[float], q: float) -> float:
    import numpy as np

    return float(np.percentile(np.asarray(values), q))


def run(args: argparse.Namespace) -> int:
    """Print the figures; exit code 0 (targets are reported, not enforced)."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import load_params
    from comems4build_ros.core.ems import make_controller
    from comems4build_ros.core.loop import simulate
    from comems4build_ros.core.scenario import default_scenario

    if args.weeks < 1:
        raise UsageError("--weeks must be at least 1")
    params = load_params(args.config)
    scenario = default_scenario(params, weeks=args.weeks)
    print(f"bench ems: {args.ems} on the default scenario, {scenario.n_steps} steps ({args.weeks} weeks)")

    # 1) the in-process run as `comems4build simulate` does it (EMS + plant + KPIs)
    t0 = time.perf_counter()
    result = simulate(args.ems, scenario, params)
    wall = time.perf_counter() - t0
    print(f"  {args.weeks}-week in-process run: wall {wall:.3f} s (EMS {result.summary['ems_s']:.3f} s)", end="")
    verdict = "ok" if wall < TARGET_RUN_S else "MISSED"
    print(f"  [target < {TARGET_RUN_S:.0f} s: {verdict}]" if args.ems == "fuzzy" else "")

    # 2) per-step times of act() over the same run
    rec = _Recorder(make_controller(args.ems, params))
    simulate(rec, scenario, params)
    med_ms = _pct(rec.times_s, 50) * 1e3
    p99_ms = _pct(rec.times_s, 99) * 1e3
    label = "all three FLCs + features" if args.ems == "fuzzy" else "rules + features"
    print(f"  per control step ({label}): median {med_ms:.4f} ms, p99 {p99_ms:.4f} ms", end="")
    print(f"  [target <= {TARGET_STEP_MS} ms: {'ok' if med_ms <= TARGET_STEP_MS else 'MISSED'}]"
          if args.ems == "fuzzy" else "")
    if args.ems != "fuzzy":
        return 0

    # 3) the same controller with skfuzzy.control doing the inference, same observations
    n = min(args.skfuzzy_steps, len(rec.observations))
    sk = make_controller("fuzzy", params)
    sk.flex, sk.fc, sk.battery = SkfuzzyFLC(sk.flex), SkfuzzyFLC(sk.fc), SkfuzzyFLC(sk.battery)
    sk.reset()
    sk_times: list[float] = []
    max_diff = {"hp_mod": 0.0, "p_fc_w": 0.0, "p_bess_w": 0.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        for obs, ref in zip(rec.observations[:n], rec.actions[:n]):
            t0 = time.perf_counter()
            action = sk.act(obs)
            sk_times.append(time.perf_counter() - t0)
            for key in max_diff:
                max_diff[key] = max(max_diff[key], abs(getattr(action, key) - getattr(ref, key)))
    sk_med = _pct(sk_times, 50) * 1e3
    ratio = sk_med / med_ms
    ours_first = _pct(rec.times_s[:n], 50) * 1e3
    print(f"  skfuzzy.control, same rule bases, first {n} steps: median {sk_med:.3f} ms, "
          f"p99 {_pct(sk_times, 99) * 1e3:.3f} ms (numpy engine on these steps: median {ours_first:.4f} ms)")
    print(f"  speed-up numpy / skfuzzy.control (medians): {ratio:.0f}x  "
          f"[target >= {TARGET_RATIO:.0f}x: {'ok' if ratio >= TARGET_RATIO else 'MISSED'}]")
    print(f"  largest set-point difference on those steps: hp_mod {max_diff['hp_mod']:.2e}, "
          f"p_fc {max_diff['p_fc_w']:.2e} W, p_bess {max_diff['p_bess_w']:.2e} W")
    return 0
