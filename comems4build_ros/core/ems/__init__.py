"""Energy management systems and their table.

``config/ems.yaml`` lists every EMS once: its controller class, ROS node, information level
(``tab:level_of_information``), label, colour and relative cost per step. :func:`ems_table`
reads it; :func:`make_controller` builds a controller by name. To add an EMS: write a module
with a class implementing :class:`~comems4build_ros.core.ems.base.Controller` and add a row
to ``config/ems.yaml`` (docs/architecture.md, "How to add an EMS").
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams, config_dir, load_yaml, table_class, table_rows
from comems4build_ros.core.ems.base import INFO_LEVELS, Controller
from comems4build_ros.core.ems.settings import ControllerSettings, load_settings
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
    name : str
        EMS name (``--ems``).
    controller : str
        ``module:Class`` of the controller.
    node : str
        ROS node name and ``ros2 run`` executable.
    info_level : str
        Information level, a key of :data:`~comems4build_ros.core.ems.base.INFO_LEVELS`
        (``tab:level_of_information``).
    label : str
        Display name.
    colour : str
        Figure colour (``#RRGGBB``).
    weight : float
        Relative cost of one step [-] (how a study orders its runs).
    summary : str
        One-line description.
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
    """Check an EMS table document (``{"ems": {name: row}}``) and return its rows.

    Parameters
    ----------
    doc : Any
        The parsed YAML document.
    source : str
        Its file (for messages).

    Returns
    -------
    dict[str, EMSEntry]
        EMS name -> row, in the document's order.

    Raises
    ------
    ConfigError
        Naming the file, the EMS and the key that is missing or invalid.
    """
    table: dict[str, EMSEntry] = {}
    nodes: set[str] = set()
    for name, row, where in table_rows(doc, "ems", _ROW_KEYS, "controller", source, "ems"):
        if row["info_level"] not in INFO_LEVELS:
            raise ConfigError(f"{where}: info_level '{row['info_level']}' is not one of {', '.join(INFO_LEVELS)}")
        if not isinstance(row["weight"], int | float) or isinstance(row["weight"], bool) or row["weight"] <= 0:
            raise ConfigError(f"{where}: weight must be a number > 0, got {row['weight']!r}")
        if not isinstance(row["node"], str) or not row["node"].isidentifier() or row["node"] in nodes:
            raise ConfigError(f"{where}: node must be a unique ROS node name, got {row['node']!r}")
        nodes.add(row["node"])
        table[name] = EMSEntry(name=name, **{k: (float(row[k]) if k == "weight" else str(row[k])) for k in _ROW_KEYS})
    return table


@functools.cache
def ems_table() -> dict[str, EMSEntry]:
    """Read every EMS of ``config/ems.yaml`` (once per process).

    Returns
    -------
    dict[str, EMSEntry]
        EMS name -> row, in the file's order.
    """
    path = config_dir() / EMS_TABLE_FILE
    return parse_ems_table(load_yaml(path, "the EMS table"), str(path))


def ems_names() -> tuple[str, ...]:
    """Return the names of every EMS.

    Returns
    -------
    tuple[str, ...]
        The ``--ems`` choices, in the table's order.
    """
    return tuple(ems_table())


def ems_entry(name: str) -> EMSEntry:
    """Return the table row of the EMS ``name``.

    Parameters
    ----------
    name : str
        EMS name (``--ems``).

    Returns
    -------
    EMSEntry
        Its row of ``config/ems.yaml``.

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
    """Import the controller class of the EMS called ``name``.

    Parameters
    ----------
    name : str
        EMS name.

    Returns
    -------
    type
        The class (``Cls(params, options)`` builds the controller).

    Raises
    ------
    UnknownEMSError
        If the name is not in the table, its module or class is missing, or the class's
        ``name`` or ``info_level`` differs from its row.
    """
    entry = ems_entry(name)
    cls = table_class(entry.controller, ("act",), "controller", f"EMS '{name}'", UnknownEMSError)
    if getattr(cls, "name", None) != name or getattr(cls, "info_level", None) != entry.info_level:
        raise UnknownEMSError(f"{entry.controller}: name '{getattr(cls, 'name', None)}' and info_level "
                              f"'{getattr(cls, 'info_level', None)}' differ from the EMS table's '{name}' and "
                              f"'{entry.info_level}'")
    return cls


def make_controller(name: str, params: PlantParams, options: Mapping[str, Any] | None = None) -> Controller:
    """Build the EMS ``name`` for the plant ``params`` with its ``options``.

    Parameters
    ----------
    name : str
        EMS name (a key of ``config/ems.yaml``).
    params : PlantParams
        The checked plant parameters.
    options : Mapping[str, Any], optional
        The controller's options (``--ems-option KEY=VALUE`` as parsed), applied over its
        settings file by :func:`~comems4build_ros.core.ems.settings.load_settings`.

    Returns
    -------
    Controller
        The controller, its options checked.
    """
    return controller_class(name)(params, dict(options or {}))


def ems_settings(name: str, options: Mapping[str, Any] | None = None) -> ControllerSettings:
    """Read the settings the EMS ``name`` is built with: its settings file with ``options`` applied.

    Parameters
    ----------
    name : str
        EMS name.
    options : Mapping[str, Any], optional
        Its options, as for :func:`make_controller`.

    Returns
    -------
    ControllerSettings
        The checked settings (the class is the controller's ``settings_class``).
    """
    return load_settings(controller_class(name).settings_class, options)
