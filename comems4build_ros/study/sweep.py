"""Parameter sweeps: a grid of plant-parameter variations per EMS.

The runs of ``comems4build sweep``; their tables and plots are :mod:`comems4build_ros.report.sweep`.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from comems4build_ros.files.errors import InputError


@dataclass
class SweepCase:
    """One point of the grid: EMS, parameter values and run directory name."""

    ems: str
    values: dict[str, Any]
    name: str



def parse_param(text: str) -> tuple[str, list[Any]]:
    """``"battery.e_max_kwh=5,10"`` -> ``("battery.e_max_kwh", [5, 10])`` (values as YAML scalars).

    Raises
    ------
    ValueError
        If the text is not ``PATH=V1[,V2...]`` with a dotted path.
    """
    from comems4build_ros.files.inputs import InputFileError, load_yaml_text

    path, sep, vals = text.partition("=")
    path = path.strip()
    if not sep or "." not in path or not vals.strip():
        raise InputError(f"--param '{text}': expected SECTION.KEY=V1,V2,... (e.g. battery.e_max_kwh=5,10)")
    try:
        values = [load_yaml_text(v, f"--param '{text}'") for v in vals.split(",")]
    except InputFileError as exc:
        raise InputError(str(exc)) from None
    if any(v is None for v in values):
        raise InputError(f"--param '{text}': empty value")
    if len({repr(v) for v in values}) != len(values):
        raise InputError(f"--param '{text}': a value is given twice")
    return path, values



def _slug(value: Any) -> str:
    return str(value).replace("/", "_").replace(" ", "")



def grid(params: Mapping[str, Sequence[Any]], emss: Sequence[str]) -> list[SweepCase]:
    """Every EMS x every combination of the parameter values, with unique run names."""
    keys = list(params)
    cases = []
    for ems in emss:
        for combo in itertools.product(*(params[k] for k in keys)):
            values = dict(zip(keys, combo))
            name = "__".join([ems, *(f"{k}={_slug(v)}" for k, v in values.items())])
            cases.append(SweepCase(ems, values, name))
    return cases

