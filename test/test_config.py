"""Parameter files: loading, merging, overrides and the messages of a bad file."""

from __future__ import annotations

from pathlib import Path

import pytest

from comems4build_ros.core.config import ConfigError, load_plant_params, read_ros_params


def test_defaults_load_with_paper_values() -> None:
    p = load_plant_params()
    # tab:parameters_PV_batt_dhw_h2 and tab:degradation_HESS
    assert p.battery.e_max_kwh == 6.5 and p.battery.soc_min == 0.1 and p.battery.soc_max == 0.9
    assert p.fuel_cell.p_max_w == 2441.6 and p.fuel_cell.zeta == 0.8 and p.fuel_cell.eta_sys == 0.75
    assert p.hydrogen.e_max_kwh == 1800.0 and p.simulation.loh_init == 1.0
    assert p.dhw.v_max_l == 300.0 and p.dhw.v_min_l == 40.0 and p.dhw.q_loss_w == 35.0
    assert p.grid.price_sell_eur_per_kwh == pytest.approx(0.0794)
    assert p.degradation.sigma_fc_on_eur == 0.10 and p.degradation.n_b_cycles == 6000


def test_file_merge_and_overrides(tmp_path: Path) -> None:
    f = tmp_path / "big_battery.yaml"
    f.write_text("/**:\n  ros__parameters:\n    battery:\n      e_max_kwh: 13.0\n")
    p = load_plant_params([f], {"fuel_cell.eta_sys": 0.9})
    assert p.battery.e_max_kwh == 13.0
    assert p.battery.p_ch_max_w == 1000.0  # untouched keys keep their defaults
    assert p.fuel_cell.eta_sys == 0.9


@pytest.mark.parametrize(
    ("override", "fragment"),
    [
        ({"battery.e_max_kwh": -1.0}, "battery.e_max_kwh"),
        ({"battery.soc_min": 0.95}, "soc_min (0.95) must be below soc_max"),
        ({"battery.colour": "red"}, "battery.colour': unknown parameter"),
        ({"dhw.v_min_l": 400.0}, "v_min_l (400.0) must be below v_max_l"),
        ({"hydrogen.loh_min": 1.0}, "loh_min"),
        ({"fuel_cell.p_min_w": 3000.0}, "p_min_w"),
        ({"heat_pump.cop_45c": [1.0, 0.5]}, "COP values must exceed 1"),
        ({"comfort.home_hours_weekday": [8, 6]}, "start < end"),
        ({"nonsense.x": 1}, "unknown section"),
    ],
)
def test_invalid_values_name_parameter_and_rule(override: dict, fragment: str) -> None:
    with pytest.raises(ConfigError, match=None) as err:
        load_plant_params(overrides=override)
    assert fragment in str(err.value)


def test_bad_files_are_named(tmp_path: Path) -> None:
    missing = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError, match="nope.yaml"):
        load_plant_params([missing])
    bad = tmp_path / "bad.yaml"
    bad.write_text("battery: {e_max_kwh: 3}\n")
    with pytest.raises(ConfigError, match="bad.yaml: section 'battery' has no 'ros__parameters'"):
        read_ros_params(bad)
    broken = tmp_path / "broken.yaml"
    broken.write_text("/**:\n  ros__parameters: [\n")
    with pytest.raises(ConfigError, match=r"broken.yaml:\d+:\d+: invalid YAML"):
        read_ros_params(broken)
    neg = tmp_path / "neg.yaml"
    neg.write_text("/**:\n  ros__parameters:\n    battery:\n      p_ch_max_w: -5.0\n")
    with pytest.raises(ConfigError, match=r"neg.yaml.*battery.p_ch_max_w.*-5.0 is neither 0 \(none\) nor at least 1"):
        load_plant_params([neg])


def test_node_sections_merge_over_wildcard(tmp_path: Path) -> None:
    f = tmp_path / "nodes.yaml"
    f.write_text(
        "/**:\n  ros__parameters:\n    a: 1\n    b: {c: 2}\n"
        "plant_sim:\n  ros__parameters:\n    b: {c: 3}\n"
        "feed:\n  ros__parameters:\n    a: 9\n"
    )
    assert read_ros_params(f, node="plant_sim") == {"a": 1, "b": {"c": 3}}
    assert read_ros_params(f, node="feed") == {"a": 9, "b": {"c": 2}}
