"""Fuel cell: polarization curve, Faraday (eq:molar_flows), eq:efficiency_FC, eq:FC_sys_efficiency."""

import numpy as np
import pytest

from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.models import fuel_cell
from comems4build_ros.core.types import CLIP_FC_H2, CLIP_FC_RANGE

F = 96485.33212  # C/mol
LHV = 241.8e3  # J/mol


@pytest.fixture(scope="module")
def fc():
    return load_plant_params().fuel_cell


def test_lhv_voltage():
    # LHV / (2 F) = 241800 / 192970.66 = 1.2530 V (FACTS)
    assert fuel_cell.V_LHV_V == pytest.approx(1.25304, abs=1e-5)


def test_datasheet_point(fc):
    # FACTS: 48 cells, 28.8 V at 70 A -> 0.600 V per cell, 2016 W.
    assert float(fuel_cell.cell_voltage_v(70.0, fc)) == pytest.approx(0.6, abs=1e-6)
    assert float(fuel_cell.stack_power_w(70.0, fc)) == pytest.approx(2016.0, abs=1e-2)
    # Faraday: n = 48 * 70 A / (2 * 96485.33 C/mol) = 0.0174119 mol/s
    n = 48 * 70.0 / (2 * F)
    assert float(fuel_cell.h2_molar_flow_mol_s(70.0, fc)) == pytest.approx(n, rel=1e-12)
    p_h2, eta = fuel_cell.operating_point(2016.0, fc)
    assert p_h2 == pytest.approx(n * LHV, rel=1e-6)  # 4210.2 W
    # eta_el = V_cell / 1.253 V = 0.6 / 1.25304 = 0.47883
    assert eta == pytest.approx(0.6 / (LHV / (2 * F)), rel=1e-6)
    assert eta == pytest.approx(0.47883, abs=1e-5)


def test_h2_flow_in_litres_matches_datasheet(fc):
    # FACTS: about 26 l/min at full power; molar volume at 25 degC, 1 atm = 24.47 l/mol
    i = float(fuel_cell.current_for_power_a(2016.0, fc))
    l_per_min = float(fuel_cell.h2_molar_flow_mol_s(i, fc)) * 24.47 * 60
    assert 24.0 < l_per_min < 27.0


def test_efficiency_falls_with_load(fc):
    p = np.linspace(fc.p_min_w, fc.p_max_w, 50)
    p_h2, eta = fuel_cell.operating_point(p, fc)
    assert np.all(np.diff(eta) < 0)
    assert np.all(np.diff(p_h2) > 0)
    # Efficiency equals V_cell(i) / 1.253 V at the solved current.
    i = fuel_cell.current_for_power_a(p, fc)
    np.testing.assert_allclose(eta, fuel_cell.cell_voltage_v(i, fc) / fuel_cell.V_LHV_V, rtol=1e-9)
    np.testing.assert_allclose(fuel_cell.stack_power_w(i, fc), p, atol=1e-6)


def test_current_on_monotone_branch(fc):
    i_mpp, p_mpp = fuel_cell.max_power_point(fc)
    assert p_mpp > fc.p_max_w
    i = float(fuel_cell.current_for_power_a(fc.p_max_w, fc))
    assert 0 < i < i_mpp


def test_zero_power(fc):
    assert fuel_cell.operating_point(0.0, fc) == (0.0, 0.0)


def test_invalid_requests_raise(fc):
    with pytest.raises(ValueError, match="finite"):
        fuel_cell.operating_point(-1.0, fc)
    with pytest.raises(ValueError, match="finite"):
        fuel_cell.operating_point(np.nan, fc)
    with pytest.raises(ValueError, match="maximum power"):
        fuel_cell.operating_point(1e6, fc)


def test_table_matches_exact(fc):
    table = fuel_cell.FuelCellTable(fc)
    p = np.linspace(fc.p_min_w, fc.p_max_w, 997)
    exact, _ = fuel_cell.operating_point(p, fc)
    approx = np.array([table.h2_power_w(x) for x in p])
    np.testing.assert_allclose(approx, exact, rtol=1e-6)
    back = np.array([table.el_power_w(x) for x in approx])
    np.testing.assert_allclose(back, p, rtol=1e-9)


def test_table_rejects_weak_stack(fc):
    weak = fc.model_copy(update={"r_ohm_ohm": 0.005})
    with pytest.raises(ValueError, match="peaks at"):
        fuel_cell.FuelCellTable(weak)


def test_mpc_constant_is_the_p_nom_efficiency(fc):
    _, eta_nom = fuel_cell.operating_point(fc.p_nom_w, fc)
    assert fc.eta_el_mpc == pytest.approx(eta_nom, abs=5e-4)


def test_efficiency_summary(fc):
    s = fuel_cell.efficiency_summary(fc)
    assert s["eta_el_p_min"] > s["eta_el_mean_operating_range"] > s["eta_el_zeta_p_max"]
    assert s["eta_el_datasheet_70a"] == pytest.approx(0.47883, abs=1e-5)


# ------------------------------------------------------------------ the device of the plant step
@pytest.fixture(scope="module")
def cell(params):
    return fuel_cell.FuelCell(params.fuel_cell, params.hydrogen)


def test_run_is_the_operating_point_and_eq_fc_sys_efficiency(cell, fc):
    """At 1 kW: P_H2 from the polarization curve, Q_hr = eta_sys * P_H2 - P_el, LOH down by P_H2 t_s / E."""
    p_fc, p_h2, eta, q_rec, loh, clip = cell.run(1000.0, 0.5, 1.0)
    p_h2_exact, eta_exact = fuel_cell.operating_point(1000.0, fc)
    assert p_fc == 1000.0 and clip == 0
    assert p_h2 == pytest.approx(p_h2_exact, rel=1e-6) and eta == pytest.approx(eta_exact, rel=1e-6)
    assert q_rec == pytest.approx(0.75 * p_h2 - 1000.0)
    assert loh == pytest.approx(0.5 - p_h2 / 1.8e6)


@pytest.mark.parametrize(("request_w", "expected_w", "clip"), [
    (0.0, 0.0, 0), (-5.0, 0.0, CLIP_FC_RANGE), (300.0, 399.2, CLIP_FC_RANGE), (150.0, 0.0, CLIP_FC_RANGE),
    (2441.6, 0.8 * 2441.6, CLIP_FC_RANGE),  # zeta * P_max
])
def test_run_onto_zero_or_p_min_to_zeta_p_max(cell, request_w, expected_w, clip):
    p_fc, *_, c = cell.run(request_w, 0.5, 1.0)
    assert p_fc == pytest.approx(expected_w) and c == clip


def test_run_limited_by_the_store(cell):
    """With 1.5 kWh of H2 left the cell delivers what that H2 gives and empties the store."""
    p_fc, p_h2, _, _, loh, clip = cell.run(1500.0, 1500.0 / 1.8e6, 1.0)
    assert clip == CLIP_FC_H2 and p_h2 == pytest.approx(1500.0, rel=1e-9) and loh == pytest.approx(0.0, abs=1e-12)
    assert 399.2 < p_fc < 1500.0
    p_fc, p_h2, *_ = cell.run(1500.0, 500.0 / 1.8e6, 1.0)  # too little H2 for P_min: off
    assert (p_fc, p_h2) == (0.0, 0.0)
