"""The 4R3C as an FMI 2.0 co-simulation FMU (pythonfmu export, fmpy run) and the FMU's variable map."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml

from comems4build_ros.app.cli import main
from comems4build_ros.core.loop import exogenous_series, simulate
from comems4build_ros.core.models.building import RCBuilding
from comems4build_ros.core.models.building_fmu import FMUBuilding, FMUError, check_fmu, export_rc_fmu, load_map
from comems4build_ros.core.scenario import resolve_scenario

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")


@pytest.fixture(scope="module")
def rc_fmu(params, tmp_path_factory) -> tuple[Path, Path]:
    """The default 4R3C exported once for the module."""
    out = tmp_path_factory.mktemp("fmu") / "rc_building.fmu"
    return export_rc_fmu(params.building, out, params.simulation.t_air_init_c)


def test_export_writes_an_fmi2_cosimulation_fmu_and_its_map(rc_fmu):
    fmu, vmap = rc_fmu
    with zipfile.ZipFile(fmu) as z:
        xml = z.read("modelDescription.xml").decode()
    assert 'fmiVersion="2.0"' in xml and "<CoSimulation" in xml
    md = check_fmu(fmu, load_map(vmap))
    names = {v.name for v in md.modelVariables}
    assert {"Q_floor", "T_amb", "q_sol", "P_gains", "T_air", "T_w_in", "T_w_out"} <= names


def test_fmu_steps_equal_the_in_process_4r3c_bit_for_bit(params, rc_fmu):
    """Two weeks of a heat sequence through both: the same node temperatures to the last bit."""
    scenario = resolve_scenario("default", params, weeks=2)
    exo = exogenous_series(scenario, params)
    fmu = FMUBuilding(rc_fmu[0], load_map(rc_fmu[1]), 1.0)
    rc = RCBuilding(params.building, 1.0)
    try:
        x = fmu.initial_temperatures(21.0, 4.2)
        y = rc.initial_temperatures(21.0, 4.2)
        assert x == y
        rng = np.random.default_rng(3)
        for k in range(scenario.n_steps):
            q = float(rng.choice([0.0, 1500.0, 4000.0, -800.0]))
            x, y = fmu.step(x, q, exo[k]), rc.step(y, q, exo[k])
            assert x == y
    finally:
        fmu.close()


def test_fmu_round_trip_gives_the_rc_runs(params, rc_fmu):
    """``--building fmu:`` the exported 4R3C = ``--building rc``: T_air within 1e-6 K, every KPI equal (12 weeks)."""
    scenario = resolve_scenario("default", params)
    assert scenario.n_steps == 12 * 168
    a = simulate("fuzzy", scenario, params)
    b = simulate("fuzzy", scenario, params, building=f"fmu:{rc_fmu[0]}")
    assert np.max(np.abs(a.timeseries["t_air_c"] - b.timeseries["t_air_c"])) <= 1e-6
    assert a.weekly.equals(b.weekly)
    for key, value in a.summary.items():
        if key not in ("wall_s", "ems_s"):
            assert b.summary[key] == value, key
    assert b.summary["building"] == "fmu"


def test_a_map_naming_a_missing_variable_is_refused_naming_it_and_the_fmu(rc_fmu, tmp_path):
    data = yaml.safe_load(rc_fmu[1].read_text())
    data["outputs"]["t_air_c"] = "T_room"
    bad = tmp_path / "bad.map.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(FMUError, match=r"outputs\.t_air_c.*'T_room'.*rc_building\.fmu"):
        check_fmu(rc_fmu[0], load_map(bad))


def test_a_map_with_wrong_causality_or_missing_required_key_is_refused(rc_fmu, tmp_path):
    data = yaml.safe_load(rc_fmu[1].read_text())
    data["inputs"]["q_floor_w"] = "T_air"  # an output used as input
    bad = tmp_path / "causality.map.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(FMUError, match="causality output, input required"):
        check_fmu(rc_fmu[0], load_map(bad))
    del data["inputs"]["q_floor_w"]
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(FMUError, match=r"inputs\.q_floor_w: missing"):
        load_map(bad)


def test_cli_refuses_broken_fmu_and_bad_map_with_exit_2_before_running(rc_fmu, tmp_path, capsys):
    broken = tmp_path / "broken.fmu"
    broken.write_bytes(b"not a zip archive")
    (tmp_path / "broken.map.yaml").write_text(rc_fmu[1].read_text())
    out = tmp_path / "run"
    assert main(["simulate", "--ems", "fuzzy", "--building", f"fmu:{broken}", "--out", str(out)]) == 2
    assert "broken.fmu: the FMU does not load" in capsys.readouterr().err
    data = yaml.safe_load(rc_fmu[1].read_text())
    data["inputs"]["t_amb_c"] = "T_outside"
    bad = tmp_path / "typo.map.yaml"
    bad.write_text(yaml.safe_dump(data))
    assert main(["simulate", "--ems", "fuzzy", "--building", f"fmu:{rc_fmu[0]}", "--building-map", str(bad),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "typo.map.yaml: field inputs.t_amb_c: variable 'T_outside' is not in the FMU" in err
    assert not out.exists()
