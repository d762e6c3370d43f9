"""ComEMS4Build fuzzy EMS: Mamdani engine, rule-base files and the controller."""

from comems4build_ros.core.ems.fuzzy.controller import FuzzyEMS, load_flcs
from comems4build_ros.core.ems.fuzzy.engine import FuzzySystem, build_system, device_quantities, flc_system

__all__ = ["FuzzyEMS", "FuzzySystem", "build_system", "device_quantities", "flc_system", "load_flcs"]
