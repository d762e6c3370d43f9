"""Plain thermostat baseline (``--ems thermostat``).

Not a controller of the paper: a reference that exercises the loop. Hot water first
(on below half of the usable tank, off when full), then space heating as an on/off
thermostat around the lower comfort bound; no battery, no fuel cell. The switch points
are :class:`~comems4build_ros.core.ems.settings.ThermostatSettings` (``config/thermostat.yaml``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.ems.base import Observation
from comems4build_ros.core.ems.settings import ThermostatSettings, load_settings
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH, Action


class Thermostat:
    """Hysteresis thermostat for both circuits, DHW priority.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (the tank's usable volume V_DHW,min .. V_DHW,max [l]).
    options : Mapping[str, Any], optional
        Overrides of ``config/thermostat.yaml`` (:class:`~..settings.ThermostatSettings`).
    """

    name = "thermostat"
    info_level = "basic"
    settings_class = ThermostatSettings

    def __init__(self, params: PlantParams, options: Mapping[str, Any] | None = None) -> None:
        self.settings = load_settings(ThermostatSettings, options)
        self._v_min = params.dhw.v_min_l
        self._v_max = params.dhw.v_max_l
        self.reset()

    def reset(self) -> None:
        """Both circuits off."""
        self._dhw_on = False
        self._sh_on = False

    def act(self, obs: Observation) -> Action:
        """Decide the step: hot water first, then the room, each by its hysteresis.

        Parameters
        ----------
        obs : Observation
            The step's inputs (basic level: T_air [degC], V_DHW [l], T_air,min [degC]).

        Returns
        -------
        Action
            Full heat pump power on the tank or the room, or off.
        """
        s = self.settings
        fill = (obs.v_dhw_l - self._v_min) / (self._v_max - self._v_min)
        if fill < s.dhw_on_fill:
            self._dhw_on = True
        elif fill >= s.dhw_off_fill:
            self._dhw_on = False
        if obs.t_air_c < obs.t_min_c + s.sh_on_k:
            self._sh_on = True
        elif obs.t_air_c > obs.t_min_c + s.sh_off_k:
            self._sh_on = False
        if self._dhw_on:
            return Action(hp_mod=1.0, hp_mode=HP_DHW)
        if self._sh_on:
            return Action(hp_mod=1.0, hp_mode=HP_SH)
        return Action(hp_mod=0.0, hp_mode=HP_OFF)
