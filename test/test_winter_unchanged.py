"""The paper's winter is unchanged by the electrolyser, cooling and the year scenario.

The fixtures in ``test/fixtures/winter_reference`` are the summaries and weekly tables of the
default 12-week runs made before those parts existed; the default runs of the three EMS must
give them bit for bit (wall-clock keys aside), and the winter plant has no electrolyser and
no cooling, so their flows are exactly zero. The core's arithmetic does not depend on the
CPU's BLAS kernels (test_models_building), and the MPC solves the same problem on every CPU
(its horizon rounded by ``horizon.same_on_every_cpu``, test_mpc_solvers) and stops at its gap, not
at a wall-clock limit (checked here), so the same files hold on every machine.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.loop import simulate, write_run
from comems4build_ros.core.scenario import resolve_scenario

REF = Path(__file__).parent / "fixtures" / "winter_reference"
WALL_KEYS = ("wall_s", "ems_s")


def _same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


@pytest.mark.parametrize("ems", ["fuzzy", "rbc", "mpc"])
def test_default_winter_runs_are_bit_identical(ems: str, tmp_path: Path) -> None:
    params = load_plant_params()
    result = simulate(ems, resolve_scenario("default", params), params)
    write_run(result, tmp_path, timeseries=False)
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    for key in WALL_KEYS:
        summary.pop(key)
    ref = json.loads((REF / f"{ems}_summary.json").read_text(encoding="utf-8"))
    assert sorted(summary) == sorted(ref)
    diff = {k: (summary[k], ref[k]) for k in ref if not _same(summary[k], ref[k])}
    assert not diff
    assert (tmp_path / "weekly.csv").read_text(encoding="utf-8") == (REF / f"{ems}_weekly.csv").read_text(
        encoding="utf-8")
    ts = result.timeseries
    if ems == "mpc":  # a reference run: every plan is the first within the gap, none cut by the wall clock
        cut = list(ts.index[ts["ems_status"] != 1])
        assert not cut, f"steps stopped by the time limit: {cut}"
    for col in ("p_el_w", "p_h2_el_w", "q_cool_w", "q_el_rec_w"):
        assert (ts[col] == 0.0).all(), col
    assert not ts["el_on"].any()
    assert not (ts["hp_mode"] == 3).any()


def test_winter_plant_has_no_electrolyser_nor_cooling() -> None:
    params = load_plant_params()
    assert params.electrolyser.n_modules == 0
    assert params.cooling.enabled is False
