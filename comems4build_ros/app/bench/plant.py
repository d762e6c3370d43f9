"""Plant steps per second in-process over the default 12-week run, and the H2 sizing check.

``comems4build bench plant`` times :meth:`comems4build_ros.core.plant.Plant.step` on the default
scenario (2016 hourly steps for 12 weeks, repeated) with random but valid actions, and
prints the steps per second (wall clock and the process's CPU time) and the time one
12-week run of the plant takes. Target: at least 200,000 steps/s on a quiet machine.
``tools/bench_plant_against.py`` runs the same workload side by side with other revisions.

It then prints the paper's sizing rule for the default house (``sec:parameters``):
the full H2 store at the FC's mean electrical efficiency should cover about half of the
winter electricity demand of heat pump and appliances. The demand is estimated twice:
an ideal heater that keeps T_air exactly at T_air,min (least heat, DHW demand and losses
at COP(T_amb, 45 degC)), and a run of the thermostat baseline through the plant.
"""

from __future__ import annotations

import argparse
import os
from typing import Any

from comems4build_ros.app.bench.plant_workload import time_plant, workload
from comems4build_ros.app.commands.options import COUNT, SEED, WHOLE_WEEKS

#: Speed target of the project on a quiet machine [steps/s] (reported, not enforced).
TARGET_STEPS_PER_S = 200_000.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``comems4build bench plant``."""
    parser.add_argument("--weeks", metavar="N", type=WHOLE_WEEKS, default=12,
                        help="run length [weeks], integer, 1 .. 30 years (default 12)")
    parser.add_argument("--repeats", metavar="N", type=COUNT, default=20,
                        help="times the run is stepped through, >= 1 (default 20)")
    parser.add_argument("--seed", metavar="N", type=SEED, default=0,
                        help="seed of the random actions, 0 .. 2^32-1 (default 0)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE", help="extra plant parameter file")
    parser.add_argument("--no-sizing", action="store_true", help="skip the H2 sizing check")


def sizing_check(params, scenario, exo: list) -> dict[str, Any]:
    """The paper's H2 sizing rule for the configured house and scenario.

    Returns energies over the run [kWh] and the share of the HP + appliance electricity
    that the full store covers at the FC's mean electrical efficiency (mean of eta_el over
    [P_min, zeta P_max]) and at the MPC's constant ``eta_el_mpc``.
    """
    import numpy as np

    from comems4build_ros.core.config import W_PER_KW
    from comems4build_ros.core.loop import make_controller, simulate
    from comems4build_ros.core.models import building, dhw, fuel_cell, heat_pump

    n = scenario.n_steps
    dt_h = params.simulation.time_step_h
    t_amb = np.asarray(scenario.t_amb_c[:n])
    q_s = np.asarray(scenario.ghi_w_m2[:n])
    t_min = np.asarray(scenario.t_min_c[:n])
    Ad, Bd = building.discretize(params.building, dt_h)
    hp = params.heat_pump
    cap = heat_pump.heat_capacity_w(t_amb, hp.t_supply_sh_c, hp)
    from comems4build_ros.core.plant import Plant

    x = np.array([getattr(Plant(params).initial_state(), k) for k in ("t_air_c", "t_wall_in_c", "t_wall_out_c")])
    q_sh = np.zeros(n)
    for k in range(n):
        free = Ad @ x + Bd[:, 1] * t_amb[k] + Bd[:, 2] * q_s[k]
        q = min(max(0.0, (t_min[k] - free[0]) / Bd[0, 0]), cap[k])
        q_sh[k] = q
        x = free + Bd[:, 0] * q
    wh = dt_h / W_PER_KW  # W per step -> kWh
    e_sh_heat = float(q_sh.sum() * wh)
    e_sh_el = float((q_sh / heat_pump.cop(t_amb, hp.t_supply_sh_c, hp)).sum() * wh)
    q_dhw = dhw.heat_w_from_l_per_h(np.asarray(scenario.dhw_l_per_h[:n]), params.dhw) + params.dhw.q_loss_w
    e_dhw_el = float((q_dhw / heat_pump.cop(t_amb, hp.t_supply_dhw_c, hp)).sum() * wh)
    e_load = float(np.asarray(scenario.p_load_w[:n]).sum() * wh)

    run = simulate(make_controller("thermostat", params), scenario, params)
    ts = run.timeseries
    e_hp_thermo = float(ts["p_hp_el_w"].sum() * wh)

    eff = fuel_cell.efficiency_summary(params.fuel_cell)
    eta_mean = eff["eta_el_mean_operating_range"]
    e_h2_kwh = params.hydrogen.e_max_kwh
    ideal = e_sh_el + e_dhw_el + e_load
    thermo = e_hp_thermo + e_load
    return {
        "weeks": n * dt_h / (7 * 24),
        "t_amb_mean_c": float(t_amb.mean()),
        "ghi_mean_w_m2": float(q_s.mean()),
        "sh_heat_kwh": e_sh_heat,
        "sh_el_kwh": e_sh_el,
        "dhw_el_kwh": e_dhw_el,
        "load_kwh": e_load,
        "demand_ideal_kwh": ideal,
        "demand_thermostat_kwh": thermo,
        "eta_el_mean": eta_mean,
        "eta_el_mpc": params.fuel_cell.eta_el_mpc,
        "h2_el_kwh_mean": e_h2_kwh * eta_mean,
        "share_ideal": e_h2_kwh * eta_mean / ideal,
        "share_thermostat": e_h2_kwh * eta_mean / thermo,
        "share_ideal_eta_mpc": e_h2_kwh * params.fuel_cell.eta_el_mpc / ideal,
    }


def run(args: argparse.Namespace) -> int:
    """Print plant steps per second and the sizing check."""
    from comems4build_ros.app.cli import UsageError
    from comems4build_ros.app.commands.options import load_params

    if args.weeks < 1 or args.repeats < 1:
        raise UsageError("bench plant: --weeks and --repeats must be >= 1")
    params = load_params(args.config)
    plant, scenario, exo, actions = workload(params, args.weeks, args.seed)
    time_plant(plant, exo, actions, 1)  # warm-up
    r = time_plant(plant, exo, actions, args.repeats)
    weeks = len(exo) * plant.dt_h / (7 * 24)
    ok = "meets" if r["steps_per_s"] >= TARGET_STEPS_PER_S else "MISSES"
    print(f"plant step: {len(exo)} steps ({weeks:g} weeks) x {args.repeats} repeats, random valid actions")
    print(f"  steps per second      : {r['steps_per_s']:,.0f}  "
          f"({ok} the target of {TARGET_STEPS_PER_S:,.0f} on a quiet machine)")
    print(f"  steps per CPU second  : {r['steps_per_cpu_s']:,.0f}")
    print(f"  time per step         : {1e6 / r['steps_per_s']:.2f} us")
    print(f"  one {weeks:g}-week run     : {r['run_s_mean'] * 1e3:.1f} ms mean, {r['run_s_best'] * 1e3:.1f} ms best")
    print(f"  max |balance residual|: {r['max_residual_w']:.2e} W")
    print(f"  load average          : {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min) after the run")
    if not args.no_sizing:
        s = sizing_check(params, scenario, exo)
        print(
            f"H2 sizing rule ({s['weeks']:g} weeks, T_amb mean {s['t_amb_mean_c']:.1f} degC, "
            f"GHI mean {s['ghi_mean_w_m2']:.0f} W/m2):"
        )
        print(
            f"  ideal heating to T_min: SH heat {s['sh_heat_kwh']:.0f} kWh, SH el {s['sh_el_kwh']:.0f} kWh, "
            f"DHW el {s['dhw_el_kwh']:.0f} kWh, appliances {s['load_kwh']:.0f} kWh -> {s['demand_ideal_kwh']:.0f} kWh"
        )
        print(f"  thermostat baseline   : HP + appliances {s['demand_thermostat_kwh']:.0f} kWh")
        print(
            f"  full store at mean eta_el {s['eta_el_mean']:.3f}: {s['h2_el_kwh_mean']:.0f} kWh electricity = "
            f"{s['share_ideal']:.2f} of the ideal demand, {s['share_thermostat']:.2f} of the thermostat demand "
            f"(paper: about 0.5)"
        )
        print(f"  at eta_el_mpc {s['eta_el_mpc']:.3f}: {s['share_ideal_eta_mpc']:.2f} of the ideal demand")
    return 0
