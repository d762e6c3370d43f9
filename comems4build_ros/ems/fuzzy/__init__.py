"""ComEMS4Build fuzzy EMS: Mamdani engine, rule-base files and the controller."""

from .controller import FuzzyEMS, load_flcs
from .engine import FuzzySystem, build_system, device_quantities, load_system

__all__ = ["FuzzyEMS", "FuzzySystem", "build_system", "device_quantities", "load_flcs", "load_system"]
