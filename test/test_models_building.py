"""4R3C building, eq:dT_i..eq:dT_wout, ZOH discretisation eq:state_update_bldgs."""

import numpy as np
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import building


@pytest.fixture(scope="module")
def bp():
    return load_plant_params().building


def _euler(b, x0, u, seconds, dt_s):
    """Integrate the ODEs written out term by term (independent of building.continuous)."""
    ta, twi, two = x0
    q, tamb, qs = u
    for _ in range(int(round(seconds / dt_s))):
        tamb_eq = tamb + b.a_sol_k_m2_per_w * qs
        d_ta = (
            (twi - ta) / b.r_w_air_k_per_w + (tamb - ta) / b.r_air_amb_k_per_w + b.g_s_m2 * qs + b.f_conv * q
        ) / b.c_air_j_per_k
        d_twi = ((ta - twi) / b.r_w_air_k_per_w + (two - twi) / b.r_w_k_per_w + (1 - b.f_conv) * q) / b.c_wall_j_per_k
        d_two = ((twi - two) / b.r_w_k_per_w + (tamb_eq - two) / b.r_w_amb_k_per_w) / b.c_wall_j_per_k
        ta, twi, two = ta + dt_s * d_ta, twi + dt_s * d_twi, two + dt_s * d_two
    return np.array([ta, twi, two])


@pytest.mark.parametrize("u", [(3000.0, -5.0, 0.0), (0.0, 10.0, 300.0), (1500.0, 2.0, 100.0)])
def test_zoh_matches_fine_euler(bp, u):
    Ad, Bd = building.discretize(bp, 1.0)
    x0 = np.array([20.0, 19.0, 8.0])
    zoh = Ad @ x0 + Bd @ np.array(u)
    euler = _euler(bp, x0, u, 3600.0, 0.5)
    np.testing.assert_allclose(zoh, euler, atol=2e-3)


def test_steady_state_is_fixed_point(bp):
    Ad, Bd = building.discretize(bp, 1.0)
    u = np.array([1200.0, 3.0, 50.0])
    x = building.steady_state_c(*u, bp)
    np.testing.assert_allclose(Ad @ x + Bd @ u, x, atol=1e-9)


def test_heat_loss_coefficient(bp):
    # H = 1/R_air,amb + 1/(R_w,air + R_w + R_w,amb) = 1/0.0275 + 1/0.01586 = 36.36 + 63.05 W/K
    h = 1.0 / bp.r_air_amb_k_per_w + 1.0 / (bp.r_w_air_k_per_w + bp.r_w_k_per_w + bp.r_w_amb_k_per_w)
    assert h == pytest.approx(1 / 0.0275 + 1 / 0.01586, rel=1e-9)
    assert h == pytest.approx(99.42, abs=0.01)
    # All heat into the air node (f_conv = 1): H * 20 K holds the air 20 K above ambient.
    conv = bp.model_copy(update={"f_conv": 1.0})
    assert building.steady_state_c(h * 20.0, 0.0, 0.0, conv)[0] == pytest.approx(20.0, rel=1e-9)
    # With f_conv = 0.4, 60 % enters the inner wall node and part of it leaves through the
    # envelope without passing the air: T_air = 20 K * (f + (1 - f) G_wa / (G_wa + G_out)),
    # G_wa = 1/0.00066 = 1515 W/K, G_out = 1/(0.00825 + 0.00695) = 65.79 W/K -> 20 * 0.975 = 19.50 K.
    g_wa, g_out = 1 / 0.00066, 1 / 0.0152
    expected = 20.0 * (0.4 + 0.6 * g_wa / (g_wa + g_out))
    assert building.steady_state_c(h * 20.0, 0.0, 0.0, bp)[0] == pytest.approx(expected, rel=1e-9)


def test_two_half_steps_equal_one_step(bp):
    Ad1, Bd1 = building.discretize(bp, 1.0)
    Ad2, Bd2 = building.discretize(bp, 0.5)
    x0 = np.array([21.0, 20.0, 5.0])
    u = np.array([2000.0, -3.0, 20.0])
    x_half = Ad2 @ (Ad2 @ x0 + Bd2 @ u) + Bd2 @ u
    np.testing.assert_allclose(Ad1 @ x0 + Bd1 @ u, x_half, atol=1e-10)


def test_simulate_and_stability(bp):
    Ad, Bd = building.discretize(bp, 1.0)
    assert np.max(np.abs(np.linalg.eigvals(Ad))) < 1.0
    xs = building.simulate([20.0, 20.0, 20.0], np.tile([0.0, 0.0, 0.0], (2000, 1)), Ad, Bd)
    assert xs.shape == (2001, 3) and np.all(np.diff(xs[:, 0]) <= 1e-12)


def test_invalid_step_raises(bp):
    with pytest.raises(ValueError, match="dt_h"):
        building.discretize(bp, 0.0)


#: OpenBLAS kernels (``OPENBLAS_CORETYPE``) and the x86 CPU flags (``/proc/cpuinfo``) each needs;
#: a kernel forced on a CPU without them dies with SIGILL.
BLAS_KERNELS = {
    "Prescott": {"pni"},  # SSE3
    "Sandybridge": {"avx"},
    "Haswell": {"avx2", "fma"},
    "SkylakeX": {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl"},
    "Cooperlake": {"avx512f", "avx512cd", "avx512bw", "avx512dq", "avx512vl", "avx512_bf16"},
}
#: What the child prints: the kernel OpenBLAS runs (its own name for it) and a digest of the results.
BLAS_PROBE = (
    "import ctypes, glob, hashlib, os, numpy as np\n"
    "from comems4build_ros.core.config import load_plant_params\n"
    "from comems4build_ros.core.models import building\n"
    "from comems4build_ros.core.ems.fuzzy.controller import load_flcs\n"
    "name = 'unknown'\n"
    "for lib in glob.glob(os.path.join(os.path.dirname(np.__file__) + '.libs', '*openblas*.so*')):\n"
    "    for sym in ('scipy_openblas_get_corename64_', 'openblas_get_corename64_', 'openblas_get_corename'):\n"
    "        f = getattr(ctypes.CDLL(lib), sym, None)\n"
    "        if f is not None:\n"
    "            f.restype = ctypes.c_char_p\n"
    "            name = f().decode()\n"
    "p = load_plant_params()\n"
    "ad, bd = building.discretize(p.building, 1.0)\n"
    "flc = load_flcs(p)['fc'][0]\n"
    "x = np.random.default_rng(1).uniform(0, 1, (500, len(flc.input_names)))\n"
    "lo = np.array([v.lo for v in flc.inputs]); hi = np.array([v.hi for v in flc.inputs])\n"
    "y = flc.evaluate(lo + x * (hi - lo))\n"
    "print(name, hashlib.sha1(ad.tobytes() + bd.tobytes() + y.tobytes()).hexdigest())\n"
)


def cpu_flags() -> set[str]:
    """The CPU's feature flags (``/proc/cpuinfo``; empty where there is none)."""
    from pathlib import Path

    try:
        text = Path("/proc/cpuinfo").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return set()
    return next((set(line.split(":", 1)[1].split()) for line in text.splitlines() if line.startswith("flags")), set())


def blas_kernels_of_this_cpu(flags: set[str]) -> list[str]:
    """The kernels of :data:`BLAS_KERNELS` this CPU can run."""
    return [kernel for kernel, needs in BLAS_KERNELS.items() if needs <= flags]


@pytest.mark.parametrize("flags, kernels", [
    ({"pni", "ssse3", "sse4_1", "sse4_2", "avx", "avx2", "fma"}, ["Prescott", "Sandybridge", "Haswell"]),
    ({"pni", "avx"}, ["Prescott", "Sandybridge"]),  # an AVX machine: no AVX2 kernel
    ({"pni", "ssse3", "sse4_1", "sse4_2", "avx", "avx2", "fma", "avx512f", "avx512cd", "avx512bw", "avx512dq",
      "avx512vl"}, ["Prescott", "Sandybridge", "Haswell", "SkylakeX"]),
    (set(), []),  # no /proc/cpuinfo (or not x86)
])
def test_the_blas_kernels_follow_the_cpus_flags(flags, kernels):
    assert blas_kernels_of_this_cpu(flags) == kernels


def test_discretisation_and_fuzzy_inference_do_not_depend_on_the_blas_kernel(bp, tmp_path):
    """Ad, Bd and a fuzzy controller's outputs are the same bit for bit with every OpenBLAS kernel
    this CPU can run (OPENBLAS_CORETYPE; the kernels differ in the last bits of matrix products):
    at least two different kernels, named in the output (``-s``) and in any failure."""
    import os
    import subprocess
    import sys

    flags = cpu_flags()
    forced = blas_kernels_of_this_cpu(flags)
    if len(forced) < 2:
        pytest.skip(f"fewer than two OpenBLAS kernels known to run on this CPU (flags: {sorted(flags)[:20]})")
    runs: dict[str, tuple[str, str]] = {}
    for core in forced:
        env = {**os.environ, "OPENBLAS_CORETYPE": core, "COMEMS4BUILD_CACHE_DIR": "off"}
        run = subprocess.run([sys.executable, "-c", BLAS_PROBE], env=env, capture_output=True, text=True,
                             timeout=120, cwd=tmp_path)
        assert run.returncode == 0, (core, run.returncode, run.stderr)
        used, digest = run.stdout.split()
        runs[core] = (used, digest)
    used = sorted({u for u, _ in runs.values()})
    said = ", ".join(f"{core} (OpenBLAS ran {u})" for core, (u, _) in runs.items())
    print(f"compared the OpenBLAS kernels {said}")
    if used == ["unknown"]:
        pytest.skip("numpy's BLAS is not OpenBLAS (no corename): OPENBLAS_CORETYPE chooses nothing")
    assert len(used) >= 2, f"forced {said}: fewer than two different kernels ran"
    assert len({d for _, d in runs.values()}) == 1, {core: d for core, (_, d) in runs.items()}


# ------------------------------------------------------------------ the building model of the plant step
def test_rc_building_step_is_eq_state_update_bldgs(bp):
    """RCBuilding.step equals x[k+1] = A_d x[k] + B_d u[k] of the discretised model."""
    from comems4build_ros.core.types import Exogenous

    model = building.RCBuilding(bp, 1.0)
    assert isinstance(model, building.BuildingModel) and model.name == "rc"
    x = (20.5, 19.0, 8.0)
    exo = Exogenous(t_amb_c=-3.0, ghi_w_m2=250.0, p_pv_w=0.0, p_load_w=400.0, dhw_l_per_h=0.0,
                    price_buy_eur_per_kwh=0.3, price_sell_eur_per_kwh=0.08, t_min_c=21.0, t_max_c=24.0)
    ad, bd = building.discretize(bp, 1.0)
    expected = ad @ np.array(x) + bd @ np.array([3000.0, -3.0, 250.0])
    assert np.allclose(model.step(x, 3000.0, exo), expected, rtol=0, atol=1e-10)


def test_rc_building_starts_on_the_steady_profile_without_sun(bp):
    """The initial walls are the equilibrium of a house held at T_air,init by heat into the air, without sun."""
    air_heated = bp.model_copy(update={"f_conv": 1.0})
    model = building.RCBuilding(air_heated, 1.0)
    t_air, t_wi, t_wo = model.initial_temperatures(21.0, 4.2)
    assert t_air == 21.0 and 4.2 < t_wo < t_wi < 21.0
    lo, hi = 0.0, 20000.0  # the heat that holds the air at 21 degC, by bisection
    for _ in range(100):
        q = 0.5 * (lo + hi)
        lo, hi = (q, hi) if building.steady_state_c(q, 4.2, 0.0, air_heated)[0] < 21.0 else (lo, q)
    x = building.steady_state_c(0.5 * (lo + hi), 4.2, 0.0, air_heated)
    assert x == pytest.approx([21.0, t_wi, t_wo], abs=1e-6)
