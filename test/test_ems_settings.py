"""The controllers' settings: one class per controller, read from its file and the options in one place.

Each EMS of the table is built from its settings class (``core/ems/settings.py``); the
defaults are the files' values; every field is documented with its unit; the options
are checked by the one rule of the parameter sections (property tests over every field
of every controller: booleans are no numbers, numbers no booleans, inf and NaN refused,
an unknown key named with the known ones).
"""

from __future__ import annotations

import math
import typing
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from comems4build_ros.core.config import ConfigError, config_dir, load_plant_params, read_ros_params
from comems4build_ros.core.ems import controller_class, ems_settings, ems_table, make_controller
from comems4build_ros.core.ems.settings import (
    ControllerSettings,
    FuzzySettings,
    MILPSettings,
    RBCSettings,
    Settings,
    ThermostatSettings,
    load_settings,
)

PARAMS = load_plant_params()
CLASSES = {name: controller_class(name).settings_class for name in ems_table()}
QUICK = {"max_examples": 40, "deadline": None}


def _scalar_fields(model: type[BaseModel], prefix: str = "") -> list[tuple[str, Any]]:
    """(option key, annotation) of every scalar field below ``model``, nested groups included."""
    out = []
    for name, field in model.model_fields.items():
        ann = field.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            out += _scalar_fields(ann, f"{prefix}{name}.")
        elif ann in (bool, int, float):
            out.append((f"{prefix}{name}", ann))
    return out


FIELDS = [(ems, key, ann) for ems, cls in CLASSES.items() for key, ann in _scalar_fields(cls)]
NUMBERS = [(e, k) for e, k, a in FIELDS if a in (int, float)]
FLOATS = [(e, k) for e, k, a in FIELDS if a is float]
BOOLS = [(e, k) for e, k, a in FIELDS if a is bool]


def _models(model: type[BaseModel]) -> list[type[BaseModel]]:
    found = [model]
    for field in model.model_fields.values():
        for t in (field.annotation, *typing.get_args(field.annotation)):
            if isinstance(t, type) and issubclass(t, BaseModel):
                found += _models(t)
    return found


def test_every_ems_is_built_from_its_settings_class() -> None:
    assert set(CLASSES) == set(ems_table()) and len(CLASSES) >= 5
    for name, cls in CLASSES.items():
        assert issubclass(cls, ControllerSettings) and cls.FILES, name
        ctrl = make_controller(name, PARAMS)
        assert ctrl.settings == ems_settings(name) == load_settings(cls), name


@pytest.mark.parametrize("cls", [ThermostatSettings, RBCSettings, MILPSettings], ids=lambda c: c.__name__)
def test_the_defaults_are_the_files_values(cls: type[ControllerSettings]) -> None:
    where = cls.FILES[""]
    data = read_ros_params(config_dir() / where.name, node=where.node)
    assert load_settings(cls).model_dump() == (data[where.section] if where.section else data)


def test_the_fuzzy_defaults_are_the_rule_files_sections() -> None:
    s = load_settings(FuzzySettings)
    for key, where in FuzzySettings.FILES.items():
        path = config_dir() / where.name
        assert getattr(s, f"{key}_file") == str(path)
        file_section = read_ros_params(path)[where.section]
        dumped = getattr(s, key).model_dump()
        assert {k: dumped[k] for k in file_section} == file_section, key


@pytest.mark.parametrize("name", sorted(CLASSES))
def test_every_field_says_what_it_is_and_every_number_its_unit(name: str) -> None:
    for model in _models(CLASSES[name]):
        assert issubclass(model, Settings) and (model.__doc__ or "").strip(), model
        for field_name, field in model.model_fields.items():
            text = field.description or ""
            assert len(text) > 15, f"{model.__name__}.{field_name}"
            if field.annotation in (int, float):
                assert "[" in text, f"{model.__name__}.{field_name}: no unit in {text!r}"


@settings(**QUICK)
@given(st.sampled_from(NUMBERS))
def test_a_boolean_is_no_number_in_any_option(case: tuple[str, str]) -> None:
    ems, key = case
    with pytest.raises(ConfigError, match=rf"\+ options: parameter '{key}': expected a number, got the boolean"):
        make_controller(ems, PARAMS, {key: True})


@settings(**QUICK)
@given(st.sampled_from(BOOLS), st.one_of(st.integers(-3, 3), st.floats(allow_nan=False), st.sampled_from(
    ["true", "yes", "on", "1"])))
def test_a_number_or_text_is_no_boolean_in_any_option(case: tuple[str, str], value: Any) -> None:
    ems, key = case
    with pytest.raises(ConfigError, match=rf"parameter '{key}': expected true or false, got"):
        make_controller(ems, PARAMS, {key: value})


@settings(**QUICK)
@given(st.sampled_from(FLOATS), st.sampled_from([math.inf, -math.inf, math.nan]))
def test_inf_and_nan_are_refused_in_every_number(case: tuple[str, str], value: float) -> None:
    ems, key = case
    with pytest.raises(ConfigError, match=rf"parameter '{key}': Input should be a finite number"):
        make_controller(ems, PARAMS, {key: value})


@settings(**QUICK)
@given(st.sampled_from(sorted({(e, k.rpartition(".")[0]) for e, k, _ in FIELDS})),
       st.from_regex(r"[a-z]{3,12}_x", fullmatch=True))
def test_an_unknown_option_is_named_with_the_known_ones(case: tuple[str, str], name: str) -> None:
    ems, group = case
    key = f"{group}.{name}" if group else name
    with pytest.raises(ConfigError, match=rf"parameter '{key}': unknown parameter \(.*known: "):
        make_controller(ems, PARAMS, {key: 1.0})


def test_a_misspelt_option_gets_the_closest_name() -> None:
    with pytest.raises(ConfigError, match=r"flex.yaml \[flc_flex\] \+ options: parameter 'flex.hp.updte': unknown "
                                          r"parameter \(did you mean 'update'\? known: update, "):
        make_controller("fuzzy", PARAMS, {"flex.hp.updte": "level"})


def test_options_reach_the_settings_and_ranges_hold() -> None:
    t = load_settings(ThermostatSettings, {"sh_on_k": 0.5, "dhw_off_fill": 0.9})
    assert (t.sh_on_k, t.dhw_off_fill, t.sh_off_k) == (0.5, 0.9, load_settings(ThermostatSettings).sh_off_k)
    with pytest.raises(ConfigError, match=r"thermostat.yaml \[thermostat\] \+ options: sh_on_k \(2.0\) must be "
                                          r"below sh_off_k"):
        load_settings(ThermostatSettings, {"sh_on_k": 2.0})
    with pytest.raises(ConfigError, match=r"parameter 'dhw_on_fill': Input should be less than or equal to 1"):
        load_settings(ThermostatSettings, {"dhw_on_fill": 1.5})
    f = load_settings(FuzzySettings, {"fc.fc.h2_allowance": "fixed", "battery.load_scale_w": 5000})
    assert (f.fc.fc.h2_allowance, f.battery.load_scale_w) == ("fixed", 5000.0)
    with pytest.raises(ConfigError, match=r"parameter 'fc.fc.h2_allowance': Input should be 'fixed' or 'rolling'"):
        load_settings(FuzzySettings, {"fc.fc.h2_allowance": "daily"})


def test_a_mapping_option_of_the_mpc_is_replaced_or_reached_into() -> None:
    shipped = load_settings(MILPSettings).highs_options
    assert len(shipped) >= 2
    assert load_settings(MILPSettings, {"highs_options": {}}).highs_options == {}
    one = load_settings(MILPSettings, {"highs_options.presolve": "off"}).highs_options
    assert one == {**shipped, "presolve": "off"}
    with pytest.raises(ConfigError, match=r"mpc.yaml \[mpc\] \+ options: parameter 'solver.x': 'solver' is not a "
                                          "section"):
        load_settings(MILPSettings, {"solver.x": 1})


def test_another_file_is_read_instead_and_a_missing_value_is_named(tmp_path: Path) -> None:
    path = tmp_path / "rbc.yaml"
    text = (config_dir() / "rbc.yaml").read_text(encoding="utf-8").replace("loh_reserve: 0.1", "loh_reserve: 0.2")
    path.write_text(text, encoding="utf-8")
    assert load_settings(RBCSettings, {"config": str(path)}).loh_reserve == 0.2
    path.write_text(text.replace("      hp_mod_on: 1.0", ""), encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"{path} \[rbc\]: parameter 'hp_mod_on': Field required"):
        load_settings(RBCSettings, {"config": str(path)})
