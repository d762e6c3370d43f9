"""Sizing study: a design of component sizes per EMS over the year, and the plant of each point.

The runs of ``comems4build size``; their costs, tables and Pareto front are
:mod:`comems4build_ros.report.sizing`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from comems4build_ros.files.errors import InputError


@dataclass(frozen=True)
class Axis:
    """One size axis: its key, command-line option, unit, whether integer, and label."""

    key: str
    option: str
    unit: str
    integer: bool
    label: str



#: The sized components, in table order.
AXES: tuple[Axis, ...] = (
    Axis("pv_kwp", "--pv-kwp", "kWp", False, "PV"),
    Axis("battery_kwh", "--battery-kwh", "kWh", False, "battery"),
    Axis("el_modules", "--el-modules", "-", True, "electrolyser modules (EL 2.1)"),
    Axis("fc_kw", "--fc-kw", "kW", False, "fuel cell, nominal"),
    Axis("h2_kwh", "--h2-kwh", "kWh", False, "H2 store, LHV"),
)
#: The keys of the axes, in order.
AXIS_KEYS = tuple(a.key for a in AXES)



def plant_sizes(plant: Any) -> dict[str, float]:
    """The sizes of a plant (its parameters as loaded): PV kWp at STC, battery kWh, EL modules,
    FC nominal kW, H2 store kWh (LHV)."""
    return {
        "pv_kwp": plant.pv.n_modules * plant.pv.a_module_m2 * plant.pv.eta_stc,  # 1 kW/m2 at STC
        "battery_kwh": plant.battery.e_max_kwh,
        "el_modules": plant.electrolyser.n_modules,
        "fc_kw": plant.fuel_cell.p_nom_w / 1000.0,
        "h2_kwh": plant.hydrogen.e_max_kwh,
    }



def size_overrides(sizes: Mapping[str, float], plant: Any) -> tuple[dict[str, Any], dict[str, float]]:
    """Plant-parameter overrides realising ``sizes`` on ``plant``, and the sizes as realised.

    - PV: a whole number of the plant's modules, ``round(kWp / (A_module eta_STC))``;
    - battery: capacity, with the charging and discharging power scaled alike (the plant's
      C-rate kept: more modules of the same battery) and its investment of
      ``tab:degradation_HESS`` (which the MPC's degradation weight uses) in proportion;
    - electrolyser: the number of EL 2.1 modules;
    - FC: a whole number of cells of the plant's stack (``n_cells``), P_max, P_nom and P_min
      scaled by the cell ratio (the same cell polarisation), its investment in proportion;
    - H2 store: its LHV energy.

    Raises
    ------
    ValueError
        Naming the option when a size cannot be realised (a PV of no module, an FC of no cell).
    """
    pv, bat, fc, deg = plant.pv, plant.battery, plant.fuel_cell, plant.degradation
    kwp_per_module = pv.a_module_m2 * pv.eta_stc
    n_pv = round(sizes["pv_kwp"] / kwp_per_module)
    if n_pv < 1:
        raise InputError(f"--pv-kwp {sizes['pv_kwp']}: less than half a module of {kwp_per_module:.3f} kWp")
    ratio_b = sizes["battery_kwh"] / bat.e_max_kwh
    n_cells = round(fc.n_cells * sizes["fc_kw"] * 1000.0 / fc.p_nom_w)
    if n_cells < 1:
        raise InputError(f"--fc-kw {sizes['fc_kw']}: less than one cell of the stack "
                         f"({fc.p_nom_w / fc.n_cells:.0f} W nominal per cell)")
    ratio_fc = n_cells / fc.n_cells
    overrides = {
        "pv.n_modules": n_pv,
        "battery.e_max_kwh": sizes["battery_kwh"],
        "battery.p_ch_max_w": bat.p_ch_max_w * ratio_b,
        "battery.p_d_max_w": bat.p_d_max_w * ratio_b,
        "degradation.sigma_in_b_eur": deg.sigma_in_b_eur * ratio_b,
        "electrolyser.n_modules": int(sizes["el_modules"]),
        "fuel_cell.n_cells": n_cells,
        "fuel_cell.p_max_w": fc.p_max_w * ratio_fc,
        "fuel_cell.p_nom_w": fc.p_nom_w * ratio_fc,
        "fuel_cell.p_min_w": fc.p_min_w * ratio_fc,
        "degradation.sigma_in_fc_eur": deg.sigma_in_fc_eur * ratio_fc,
        "hydrogen.e_max_kwh": sizes["h2_kwh"],
    }
    realised = {"pv_kwp": round(n_pv * kwp_per_module, 3), "battery_kwh": float(sizes["battery_kwh"]),
                "el_modules": int(sizes["el_modules"]), "fc_kw": round(fc.p_nom_w * ratio_fc / 1000.0, 3),
                "h2_kwh": float(sizes["h2_kwh"])}
    return overrides, realised



def grid_points(values: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """Every combination of the axis values (axes in :data:`AXES` order)."""
    keys = [a.key for a in AXES]
    return [dict(zip(keys, combo)) for combo in itertools.product(*(values[k] for k in keys))]



def sampled_points(values: Mapping[str, Sequence[float]], n: int, seed: int) -> list[dict[str, float]]:
    """``n`` points of a Latin hypercube (``scipy.stats.qmc``, seeded) between the smallest and
    the largest value of each axis; integer axes rounded; points made equal by rounding once."""
    from scipy.stats import qmc

    free = [a for a in AXES if min(values[a.key]) != max(values[a.key])]
    if not free:
        raise InputError("--sample needs at least one size option with two different values (its range)")
    unit = qmc.LatinHypercube(d=len(free), seed=seed).random(n)
    points, seen = [], set()
    for row in unit:
        p = {a.key: float(min(values[a.key])) for a in AXES}
        for a, u in zip(free, row):
            lo, hi = float(min(values[a.key])), float(max(values[a.key]))
            v = lo + u * (hi - lo)
            p[a.key] = int(round(v)) if a.integer else round(v, 3)
        key = tuple(p[k] for k in AXIS_KEYS)
        if key not in seen:
            seen.add(key)
            points.append(p)
    return points



def point_name(ems: str, sizes: Mapping[str, float]) -> str:
    """Run directory name of a point: ``<ems>__pv9.6_bat6.5_el1_fc2_h21800``."""
    def num(v: float) -> str:
        return f"{v:g}"

    return (f"{ems}__pv{num(sizes['pv_kwp'])}_bat{num(sizes['battery_kwh'])}_el{int(sizes['el_modules'])}"
            f"_fc{num(sizes['fc_kw'])}_h2{num(sizes['h2_kwh'])}")

