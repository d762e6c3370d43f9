"""Plain thermostat baseline (``--ems thermostat``).

Not a controller of the paper: a reference that exercises the loop. Hot water first
(on below half of the usable tank, off when full), then space heating as an on/off
thermostat around the lower comfort bound; no battery, no fuel cell.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from comems4build_ros.core.config import ConfigError, PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action

#: Room heating switches on below T_min + ON_K and off above T_min + OFF_K [K].
ON_K = 0.3
OFF_K = 1.0
#: Tank heating switches on below this fraction of the usable range [-].
DHW_ON_FRACTION = 0.5


class Thermostat:
    """Hysteresis thermostat for both circuits, DHW priority.

    Parameters
    ----------
    params : plant parameters (tank volumes)
    options : none (the common constructor signature); any option is refused
    """

    name = "thermostat"
    info_level = "basic"

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None) -> None:
        if options:
            raise ConfigError(f"thermostat EMS: unknown option(s) {', '.join(map(str, options))} (it takes none)")
        self._v_min = params.dhw.v_min_l
        self._v_max = params.dhw.v_max_l
        self.reset()

    def reset(self) -> None:
        """Both circuits off."""
        self._dhw_on = False
        self._sh_on = False

    def act(self, obs: Observation) -> Action:
        """On/off heating decision for the step."""
        fill = (obs.v_dhw_l - self._v_min) / (self._v_max - self._v_min)
        if fill < DHW_ON_FRACTION:
            self._dhw_on = True
        elif fill >= 0.99:
            self._dhw_on = False
        if obs.t_air_c < obs.t_min_c + ON_K:
            self._sh_on = True
        elif obs.t_air_c > obs.t_min_c + OFF_K:
            self._sh_on = False
        if self._dhw_on:
            return Action(hp_mod=1.0, hp_mode=HP_DHW)
        if self._sh_on:
            return Action(hp_mod=1.0, hp_mode=HP_SH)
        return Action(hp_mod=0.0, hp_mode=HP_OFF)
