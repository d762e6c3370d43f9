"""Energy management systems and their table.

``config/ems.yaml`` lists every EMS once: its controller class, ROS node, information level
(``tab:level_of_information``), label, colour and relative cost per step. :func:`ems_table`
reads it; :func:`make_controller` builds a controller by name. To add an EMS: write a module
with a class implementing :class:`~comems4build_ros.core.ems.base.Controller` and add a row
to ``config/ems.yaml`` (docs/architecture.md, "How to add an EMS").
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams, config_dir, load_yaml
from comems4build_ros.core.ems.base import INFO_LEVELS, Controller
from comems4build_ros.files.errors import InputError

#: The EMS table's file in ``config/``.
EMS_TABLE_FILE = "ems.yaml"
#: The keys of a row of the table.
_ROW_KEYS = ("controller", "node", "info_level", "label", "colour", "weight", "summary")


class UnknownEMSError(InputError):
    """The requested EMS name is not in the table (or its controller class is missing)."""


@dataclass(frozen=True)
class EMSEntry:
    """One row of the EMS table.

    Attributes
    ----------
    name : EMS name (``--ems``)
    controller : ``module:Class`` of the controller
    node : ROS node name and ``ros2 run`` executable
    info_level : information level, a key of :data:`~comems4build_ros.core.ems.base.INFO_LEVELS`
    label : display name
    colour : figure colour (``#RRGGBB``)
    weight : relative cost of one step [-]
    summary : one-line description
    """

    name: str
    controller: str
    node: str
    info_level: str
    label: str
    colour: str
    weight: float
    summary: str


def parse_ems_table(doc: Any, source: str) -> dict[str, EMSEntry]:
    """The rows of an EMS table document (``{"ems": {name: row}}``), checked.

    Raises
    ------
    ConfigError
        Naming the file, the EMS and the key that is missing or invalid.
    """
    rows = doc.get("ems") if isinstance(doc, dict) else None
    if not isinstance(rows, dict) or not rows:
        raise ConfigError(f"{source}: needs a mapping 'ems' of EMS name -> row")
    table: dict[str, EMSEntry] = {}
    nodes: set[str] = set()
    for name, row in rows.items():
        where = f"{source}: ems '{name}'"
        if not isinstance(name, str) or not isinstance(row, dict):
            raise ConfigError(f"{where}: a name and a mapping of {', '.join(_ROW_KEYS)}")
        missing = [k for k in _ROW_KEYS if k not in row]
        extra = sorted(set(row) - set(_ROW_KEYS))
        if missing or extra:
            problems = ([f"missing {', '.join(missing)}"] if missing else []) + (
                [f"unknown {', '.join(extra)}"] if extra else [])
            raise ConfigError(f"{where}: " + "; ".join(problems))
        if row["info_level"] not in INFO_LEVELS:
            raise ConfigError(f"{where}: info_level '{row['info_level']}' is not one of {', '.join(INFO_LEVELS)}")
        if not isinstance(row["controller"], str) or row["controller"].count(":") != 1:
            raise ConfigError(f"{where}: controller must be 'module:Class', got {row['controller']!r}")
        if not isinstance(row["weight"], int | float) or isinstance(row["weight"], bool) or row["weight"] <= 0:
            raise ConfigError(f"{where}: weight must be a number > 0, got {row['weight']!r}")
        if not isinstance(row["node"], str) or not row["node"].isidentifier() or row["node"] in nodes:
            raise ConfigError(f"{where}: node must be a unique ROS node name, got {row['node']!r}")
        nodes.add(row["node"])
        table[name] = EMSEntry(name=name, **{k: (float(row[k]) if k == "weight" else str(row[k])) for k in _ROW_KEYS})
    return table


@functools.cache
def ems_table() -> dict[str, EMSEntry]:
    """Every EMS of ``config/ems.yaml`` by name, in the file's order."""
    path = config_dir() / EMS_TABLE_FILE
    return parse_ems_table(load_yaml(path, "the EMS table"), str(path))


def ems_names() -> tuple[str, ...]:
    """The names of every EMS (``--ems`` choices)."""
    return tuple(ems_table())


def ems_entry(name: str) -> EMSEntry:
    """The table row of the EMS ``name``.

    Raises
    ------
    UnknownEMSError
        If no EMS is called ``name``.
    """
    try:
        return ems_table()[name]
    except KeyError:
        raise UnknownEMSError(f"unknown EMS '{name}' (known: {', '.join(sorted(ems_table()))})") from None


def controller_class(name: str) -> type:
    """Class of the EMS called ``name``.

    Raises
    ------
    UnknownEMSError
        If the name is not in the table, its module or class is missing, or the class's
        ``name`` or ``info_level`` differs from its row.
    """
    entry = ems_entry(name)
    module_name, _, class_name = entry.controller.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            raise UnknownEMSError(f"EMS '{name}' is in the table but its module {module_name} is missing") from None
        raise
    cls = getattr(module, class_name, None)
    if not isinstance(cls, type) or not callable(getattr(cls, "act", None)):
        raise UnknownEMSError(f"module {module_name} defines no controller class {class_name} (EMS '{name}')")
    if getattr(cls, "name", None) != name or getattr(cls, "info_level", None) != entry.info_level:
        raise UnknownEMSError(f"{entry.controller}: name '{getattr(cls, 'name', None)}' and info_level "
                              f"'{getattr(cls, 'info_level', None)}' differ from the EMS table's '{name}' and "
                              f"'{entry.info_level}'")
    return cls


def make_controller(name: str, params: PlantParams, options: Mapping[str, Any] | None = None) -> Controller:
    """Build the EMS ``name`` for the plant ``params`` with its ``options``."""
    return controller_class(name)(params, dict(options or {}))
