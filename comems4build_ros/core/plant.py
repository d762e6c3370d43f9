"""The plant of a house: one step of every device model and the power balance.

:class:`Plant` owns the device models of :mod:`comems4build_ros.core.models` and advances the
state by one step for any action. It clips the action to what the devices can do,
reports each clip as a bit in ``Flows.clipped`` (``CLIP_*`` in
:mod:`comems4build_ros.core.types`) and never leaves the storage bounds. Order within a step:

1. Action sanitising: non-finite or non-numeric values count as 0 (``CLIP_NONFINITE``);
   an unknown circuit switches the heat pump off (``CLIP_HP_MODE``).
2. Heat pump (``sec:hp``): modulation onto {0} U [mod_min, 1]; it serves the requested
   circuit only (space heating at 55 degC or DHW at 45 degC supply).
3. Fuel cell (``eq:molar_flows`` .. ``eq:FC_sys_efficiency``): output onto
   {0} U [P_min, zeta P_max], then reduced (or stopped below P_min) if the H2 store
   would fall below LOH_min (``eq:LOH``).
   Electrolyser (:mod:`~comems4build_ros.core.models.electrolyser`): intake onto
   {0} U [P_EL,min, P_EL,max], then reduced (or stopped below its minimal load) if the
   store would rise above LOH_max; the H2 it makes enters the store in the same step.
4. DHW tank (``eq:DHW_model``): recovered FC heat goes in first, then recovered EL heat;
   HP heat is reduced so the tank does not overflow (HP off if less than mod_min would be
   needed); recovered heat that still does not fit is dumped (``q_fc_dump_w``,
   ``q_el_dump_w``). Draws and standing losses the tank cannot serve without falling
   below V_min are unmet (``q_dhw_unmet_w``).
5. Building (``eq:state_update_bldgs``) with the space-heating heat, or minus the heat the
   cooling mode takes through the floor (:mod:`~comems4build_ros.core.models.cooling`).
6. Battery (``eq:batt_soc``): power limits and SOC bounds; one direction only.
7. Grid (``eq:power_balance`` with the EL's intake on the demand side): the residual is
   bought or sold, never both.

Without an electrolyser (``electrolyser.n_modules = 0``) and with cooling disabled (the
paper's plant), every added term is an exact 0.0 and the step is the paper's.

:meth:`Plant.step` calls one function per device of :mod:`comems4build_ros.core.models`
in that order; each is plain float arithmetic on coefficients computed once (no numpy, no
validated-parameter reads in the step). An action of finite floats and an ``int`` circuit
of {off, SH, DHW} skips the sanitising of step 1, whose result would be the same.
The building's thermal model is any
:class:`~comems4build_ros.core.models.building.BuildingModel` (the paper's 4R3C by default).
"""

from __future__ import annotations

import math
from math import isfinite

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.models import battery, grid
from comems4build_ros.core.models.building import BuildingModel, RCBuilding
from comems4build_ros.core.models.dhw import Tank
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.models.fuel_cell import FuelCell
from comems4build_ros.core.models.heat_pump import HeatPump
from comems4build_ros.core.types import (
    CLIP_BESS_POWER,
    CLIP_BESS_SOC,
    CLIP_HP_MODE,
    CLIP_NONFINITE,
    EXOGENOUS_FIELDS,
    HP_COOL,
    HP_DHW,
    HP_OFF,
    HP_SH,
    Action,
    Exogenous,
    Flows,
    PlantState,
)

#: Tolerance for state bounds checks on input states (rounding of earlier steps).
STATE_TOL = 1e-9
_NAN = float("nan")
#: Requested circuit codes of ``Action.hp_mode`` (cooling only where the plant can cool).
_MODES = {0.0: HP_OFF, 1.0: HP_SH, 2.0: HP_DHW}


def _as_float(value) -> float:
    """Return ``float(value)``, or NaN for anything that is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return _NAN


def _finite_or_zero(value) -> tuple[float, int]:
    """Return a set-point as a finite float (NaN, inf and non-numbers count as 0) and its clip bit."""
    x = _as_float(value)
    return (x, 0) if math.isfinite(x) else (0.0, CLIP_NONFINITE)


class Plant:
    """The simulated building with PV, BESS, H2 system, heat pump, DHW tank and its building model.

    Parameters
    ----------
    params : PlantParams
        Validated plant parameters (:func:`comems4build_ros.core.config.load_plant_params`).
    building : BuildingModel, optional
        The thermal model of the rooms; default the paper's 4R3C of ``params.building``.

    Attributes
    ----------
    params : PlantParams
        The parameters it was built from.
    dt_h : float
        Step t_s [h].
    battery : Battery
        The battery's parameters as plain attributes (:mod:`~comems4build_ros.core.models.battery`).
    fuel_cell : FuelCell
        Fuel cell and H2 store (:mod:`~comems4build_ros.core.models.fuel_cell`).
    heat_pump : HeatPump
        Heat pump (:mod:`~comems4build_ros.core.models.heat_pump`).
    el_table : ElectrolyserTable
        Electrolyser modules (:mod:`~comems4build_ros.core.models.electrolyser`), none by default.
    tank : Tank
        DHW tank (:mod:`~comems4build_ros.core.models.dhw`).
    building : BuildingModel
        Thermal model of the rooms.

    Raises
    ------
    ValueError
        If the fuel-cell polarization curve cannot deliver ``fuel_cell.p_max_w``.
    """

    def __init__(self, params: PlantParams, building: BuildingModel | None = None) -> None:
        self.params = params
        self.dt_h = float(params.simulation.time_step_h)
        self._b = params.battery
        self.battery = battery.Battery(params.battery)
        self.fuel_cell = FuelCell(params.fuel_cell, params.hydrogen)
        self.heat_pump = HeatPump(params.heat_pump, params.cooling)
        self.el_table = ElectrolyserTable(params.electrolyser)
        self.tank = Tank(params.dhw, self.dt_h)
        self.building = building if building is not None else RCBuilding(params.building, self.dt_h)
        self._cool_on = bool(params.cooling.enabled)
        b, fc, tank = self._b, self.fuel_cell, self.tank
        self._bounds = (b.soc_min - STATE_TOL, b.soc_max + STATE_TOL, fc.loh_min - STATE_TOL, fc.loh_max + STATE_TOL,
                        tank.v_min_l - STATE_TOL, tank.v_max_l + STATE_TOL)
        self._el_n = self.el_table.n
        self._loh_max, self._e_h2_wh = fc.loh_max, fc.e_h2_wh

    # ------------------------------------------------------------------ state
    def initial_state(self, t_amb_c: float | None = None) -> PlantState:
        """Return the state at the start of a run (``simulation`` section of the parameters).

        The building model gives the node temperatures for the air at T_air,init and the
        ambient temperature ``t_amb_c``; the 4R3C's walls start on the steady-state profile
        between the two, as if the house had been held at T_air,init without sun.

        Parameters
        ----------
        t_amb_c : float, optional
            Ambient temperature before the run [degC] (default ``building.t_amb_init_c``).

        Returns
        -------
        PlantState
            SOC, LOH and DHW volume of the ``simulation`` section, node temperatures [degC],
            heat pump, fuel cell and electrolyser off.

        Raises
        ------
        ValueError
            If the initial SOC, LOH or volume lies outside its bounds.
        """
        sim = self.params.simulation
        t_amb = self.params.building.t_amb_init_c if t_amb_c is None else float(t_amb_c)
        t_air, t_wall_in, t_wall_out = self.building.initial_temperatures(sim.t_air_init_c, t_amb)
        state = PlantState(soc=sim.soc_init, loh=sim.loh_init, t_air_c=t_air, t_wall_in_c=t_wall_in,
                           t_wall_out_c=t_wall_out, v_dhw_l=sim.v_dhw_init_l, hp_mod=0.0, fc_on=False, el_on=False)
        self.check_state(state)
        return state

    def check_state(self, state: PlantState) -> None:
        """Raise ValueError if a state is not finite or outside the storage bounds.

        Parameters
        ----------
        state : PlantState
            SOC within [SOC_min, SOC_max] (``eq:SOC_const``), LOH within [LOH_min, LOH_max],
            DHW volume within [V_min, V_max] [l] (``eq:DHW_model``), each up to
            :data:`STATE_TOL`; finite node temperatures [degC].

        Raises
        ------
        ValueError
            Naming the first field out of bounds or not finite.
        """
        b, fc, tank = self._b, self.fuel_cell, self.tank
        checks = (
            ("soc", state.soc, b.soc_min, b.soc_max),
            ("loh", state.loh, fc.loh_min, fc.loh_max),
            ("v_dhw_l", state.v_dhw_l, tank.v_min_l, tank.v_max_l),
        )
        for name, value, lo, hi in checks:
            if not lo - STATE_TOL <= value <= hi + STATE_TOL:
                raise ValueError(f"plant state: {name} = {value} outside [{lo}, {hi}]")
        for name in ("t_air_c", "t_wall_in_c", "t_wall_out_c"):
            if not math.isfinite(getattr(state, name)):
                raise ValueError(f"plant state: {name} is not finite")

    # ------------------------------------------------------------------- step
    def step(self, state: PlantState, action: Action, exo: Exogenous) -> tuple[PlantState, Flows]:
        """Advance the plant by one step: the devices in the order of the module docstring.

        Parameters
        ----------
        state : PlantState
            State at the end of the previous step (within bounds).
        action : Action
            Any set-points (NaN, inf, out of range, unknown mode): clipped here.
        exo : Exogenous
            Weather, loads, PV output and prices of the step (finite, loads >= 0).

        Returns
        -------
        state : PlantState
            State at the end of the step.
        flows : Flows
            Everything that flowed in it (powers [W], heat flows [W], the clip bits).

        Raises
        ------
        ValueError
            If ``state`` is outside its bounds or ``exo`` holds a non-finite or negative
            load/irradiance value.
        """
        t_amb, q_s, p_pv, p_load = exo.t_amb_c, exo.ghi_w_m2, exo.p_pv_w, exo.p_load_w
        dhw_lph, price_buy, price_sell = exo.dhw_l_per_h, exo.price_buy_eur_per_kwh, exo.price_sell_eur_per_kwh
        if not (isfinite(t_amb + q_s + p_pv + p_load + dhw_lph + price_buy) and isfinite(price_sell)
                and q_s >= 0.0 and p_pv >= 0.0 and p_load >= 0.0 and dhw_lph >= 0.0):
            self._raise_exo(exo)
        soc, loh, v_dhw = state.soc, state.loh, state.v_dhw_l
        temps = (state.t_air_c, state.t_wall_in_c, state.t_wall_out_c)
        soc_lo, soc_hi, loh_lo, loh_hi, v_lo, v_hi = self._bounds
        if not (soc_lo <= soc <= soc_hi and loh_lo <= loh <= loh_hi and v_lo <= v_dhw <= v_hi
                and isfinite(temps[0] + temps[1] + temps[2])):
            self.check_state(state)
        hp_mod, mode, p_fc_req, p_bess_req, p_el_req = (action.hp_mod, action.hp_mode, action.p_fc_w,
                                                         action.p_bess_w, action.p_el_w)
        # the usual action (floats, a heating circuit) needs no sanitising; anything else goes through _command
        if (type(hp_mod) is float and type(p_fc_req) is float and type(p_bess_req) is float
                and type(p_el_req) is float and isfinite(hp_mod + p_fc_req + p_bess_req + p_el_req)
                and type(mode) is int and HP_OFF <= mode <= HP_DHW):
            clipped = 0
        else:
            hp_mod, mode, p_fc_req, p_bess_req, p_el_req, clipped = self._command(action)
        dt_h = self.dt_h
        mode, mod, cop, p_el_max, p_hp, q_hp, hp_clip = self.heat_pump.run(hp_mod, mode, t_amb)
        p_fc, p_h2, eta_fc, q_rec, loh, fc_clip = self.fuel_cell.run(p_fc_req, loh, dt_h)
        if p_el_req == 0.0 and not self._el_n:  # no electrolyser and none asked for: its terms are 0
            p_el, p_h2_el, el_on, q_el_rec, el_clip = p_el_req, 0.0, False, 0.0, 0
        else:
            p_el, p_h2_el, el_on, q_el_rec, loh, el_clip = self.el_table.run(p_el_req, loh, state.el_on, dt_h,
                                                                             self._loh_max, self._e_h2_wh)
        tank = self.tank
        q_dem = tank.demand_w(dhw_lph)
        room_w = tank.room_w(v_dhw, q_dem)
        if mode == HP_DHW:
            q_hp_dhw, q_sh, q_cool = q_hp, 0.0, 0.0
            if q_hp > room_w - (q_rec + q_el_rec):
                mod, p_hp, q_hp_dhw, full = self.heat_pump.fit_heat(room_w - (q_rec + q_el_rec), cop, p_el_max)
                hp_clip |= full
                if mod == 0.0:
                    mode, cop = HP_OFF, 0.0
        else:
            q_hp_dhw = 0.0
            q_sh = q_hp if mode == HP_SH else 0.0
            q_cool = q_hp if mode == HP_COOL else 0.0
        v_dhw, q_fc_in, q_dump, q_el_in, q_el_dump, q_unmet = tank.step(v_dhw, q_hp_dhw, q_rec, q_el_rec, q_dem,
                                                                         room_w)
        t_air, t_wi, t_wo = self.building.step(temps, q_sh - q_cool, exo)
        p_ch, p_dis, soc, power_clip, soc_clip = battery.step(p_bess_req, soc, self.battery, dt_h)
        p_buy, p_sell, residual = grid.exchange(p_load, p_hp, p_ch, p_el, p_pv, p_fc, p_dis)
        clipped |= hp_clip | fc_clip | el_clip
        if power_clip:
            clipped |= CLIP_BESS_POWER
        if soc_clip:
            clipped |= CLIP_BESS_SOC
        fc_on, fc_was_on, el_was_on = p_fc > 0.0, state.fc_on, state.el_on
        return (PlantState(soc, loh, t_air, t_wi, t_wo, v_dhw, mod, fc_on, el_on),
                Flows(p_pv, p_load, p_hp, mode, mod, cop, q_sh, q_hp_dhw, p_fc, fc_on, fc_on and not fc_was_on,
                      fc_was_on and not fc_on, p_h2, eta_fc, q_fc_in, q_dump, p_ch, p_dis, p_buy, p_sell, q_dem,
                      tank.q_loss_w, q_unmet, price_buy, price_sell, residual, clipped, p_el, el_on,
                      el_on and not el_was_on, p_h2_el, q_el_in, q_el_dump, q_cool))

    def _command(self, action: Action) -> tuple[float, int, float, float, float, int]:
        """Return the action's set-points as finite floats and a known circuit, with their clip bits.

        Non-finite or non-numeric values count as 0 (``CLIP_NONFINITE``); an unknown circuit
        (cooling where the plant cannot cool) switches the heat pump off (``CLIP_HP_MODE``).
        """
        p_el, c_el = _finite_or_zero(action.p_el_w)
        hp_mod, c_mod = _finite_or_zero(action.hp_mod)
        p_fc, c_fc = _finite_or_zero(action.p_fc_w)
        p_bess, c_bess = _finite_or_zero(action.p_bess_w)
        clipped = c_el | c_mod | c_fc | c_bess
        mode_f = _as_float(action.hp_mode)
        mode = _MODES.get(mode_f)
        if mode is None:
            if mode_f == 3.0 and self._cool_on:
                mode = HP_COOL
            else:
                if not math.isfinite(mode_f):
                    clipped |= CLIP_NONFINITE
                clipped |= CLIP_HP_MODE
                mode = HP_OFF
        return hp_mod, mode, p_fc, p_bess, p_el, clipped

    @staticmethod
    def _raise_exo(exo: Exogenous) -> None:
        """Raise ValueError naming the first non-finite or negative field of ``exo``."""
        for name in EXOGENOUS_FIELDS:
            value = getattr(exo, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"exogenous input '{name}' is not a finite number: {value!r}")
        for name in ("ghi_w_m2", "p_pv_w", "p_load_w", "dhw_l_per_h"):
            if getattr(exo, name) < 0.0:
                raise ValueError(f"exogenous input '{name}' is negative: {getattr(exo, name)!r}")
        raise ValueError(f"exogenous input invalid: {exo!r}")  # pragma: no cover
