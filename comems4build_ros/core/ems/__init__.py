"""Energy management systems and their registry.

``make_controller(name, params, options)`` builds a controller by name. Each entry of
:data:`REGISTRY` names the module holding the controller class; the class is the one
whose ``name`` attribute equals the registry key. To add an EMS: write a module with a
class implementing :class:`~comems4build_ros.core.ems.base.Controller` and add a line here.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Mapping
from typing import Any

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.ems.base import Controller

#: EMS name -> module defining the controller class (class attribute ``name`` = key).
REGISTRY: dict[str, str] = {
    "thermostat": "comems4build_ros.core.ems.thermostat",
    "rbc": "comems4build_ros.core.ems.rbc",
    "fuzzy": "comems4build_ros.core.ems.fuzzy",
    "mpc": "comems4build_ros.core.ems.mpc",
    "mpc-qp": "comems4build_ros.core.ems.mpc",
}


class UnknownEMSError(ValueError):
    """The requested EMS name is not registered (or its module is missing)."""


def controller_class(name: str) -> type:
    """Class of the EMS called ``name``.

    Raises
    ------
    UnknownEMSError
        If the name is not registered or its module does not define it.
    """
    try:
        module_name = REGISTRY[name]
    except KeyError:
        raise UnknownEMSError(f"unknown EMS '{name}' (known: {', '.join(sorted(REGISTRY))})") from None
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            raise UnknownEMSError(f"EMS '{name}' is registered but its module {module_name} is missing") from None
        raise
    for _, obj in inspect.getmembers(module, inspect.isclass):
        if getattr(obj, "name", None) == name and callable(getattr(obj, "act", None)):
            return obj
    raise UnknownEMSError(f"module {module_name} defines no controller class with name '{name}'")


def make_controller(name: str, params: PlantParams, options: Mapping[str, Any] | None = None) -> Controller:
    """Build the EMS ``name`` for the plant ``params`` with its ``options``."""
    return controller_class(name)(params, dict(options or {}))
