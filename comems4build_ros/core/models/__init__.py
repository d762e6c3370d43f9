"""Device models of the house: PV, battery, fuel cell and H2 store, electrolyser, heat pump, DHW tank, building.

Each module implements one device of the paper's ``sec:model`` (or an addition to it) with
its equations, and the plant (:mod:`comems4build_ros.core.plant`) calls one function or
class per device per step.
"""
