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
in that order; each is plain float arithmetic on precomputed coefficients (no numpy), for
speed (``comems4build bench plant``). The building's thermal model is any
:class:`~comems4build_ros.core.models.building.BuildingModel` (the paper's 4R3C by default).
"""

from __future__ import annotations

import math

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
    """``float(value)``, or NaN for anything that is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return _NAN


def _finite_or_zero(value) -> tuple[float, int]:
    """A set-point as a finite float (NaN, inf and non-numbers count as 0) and its clip bit."""
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

    Raises
    ------
    ValueError
        If the fuel-cell polarization curve cannot deliver ``fuel_cell.p_max_w``.
    """

    def __init__(self, params: PlantParams, building: BuildingModel | None = None) -> None:
        self.params = params
        self.dt_h = float(params.simulation.time_step_h)
        self._b = params.battery
        self.fuel_cell = FuelCell(params.fuel_cell, params.hydrogen)
        self.heat_pump = HeatPump(params.heat_pump, params.cooling)
        self.el_table = ElectrolyserTable(params.electrolyser)
        self.tank = Tank(params.dhw, self.dt_h)
        self.building = building if building is not None else RCBuilding(params.building, self.dt_h)
        self._cool_on = bool(params.cooling.enabled)

    # ------------------------------------------------------------------ state
    def initial_state(self, t_amb_c: float | None = None) -> PlantState:
        """State at the start of a run (``simulation`` section of the parameters).

        The building model gives the node temperatures for the air at T_air,init and the
        ambient temperature ``t_amb_c`` (default ``building.t_amb_init_c``); the 4R3C's walls
        start on the steady-state profile between the two, as if the house had been held at
        T_air,init without sun.
        """
        sim = self.params.simulation
        t_amb = self.params.building.t_amb_init_c if t_amb_c is None else float(t_amb_c)
        t_air, t_wall_in, t_wall_out = self.building.initial_temperatures(sim.t_air_init_c, t_amb)
        state = PlantState(soc=sim.soc_init, loh=sim.loh_init, t_air_c=t_air, t_wall_in_c=t_wall_in,
                           t_wall_out_c=t_wall_out, v_dhw_l=sim.v_dhw_init_l, hp_mod=0.0, fc_on=False, el_on=False)
        self.check_state(state)
        return state

    def check_state(self, state: PlantState) -> None:
        """Raise ValueError if a state is not finite or outside the storage bounds."""
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
        (PlantState, Flows)
            State at the end of the step and everything that flowed in it.

        Raises
        ------
        ValueError
            If ``state`` is outside its bounds or ``exo`` holds a non-finite or negative
            load/irradiance value.
        """
        self._check_inputs(state, exo)
        dt_h = self.dt_h
        hp_mod, mode, p_fc_req, p_bess_req, p_el_req, clipped = self._command(action)
        mode, mod, cop, p_el_max, p_hp, q_hp, clip = self.heat_pump.run(hp_mod, mode, exo.t_amb_c)
        p_fc, p_h2, eta_fc, q_rec, loh, fc_clip = self.fuel_cell.run(p_fc_req, state.loh, dt_h)
        p_el, p_h2_el, el_on, q_el_rec, loh, el_clip = self._electrolyser(p_el_req, loh, state.el_on)
        tank = self.tank
        q_dem = tank.demand_w(exo.dhw_l_per_h)
        room_w = tank.room_w(state.v_dhw_l, q_dem)
        if mode == HP_DHW and q_hp > room_w - (q_rec + q_el_rec):
            mod, p_hp, q_hp, full = self.heat_pump.fit_heat(room_w - (q_rec + q_el_rec), cop, p_el_max)
            clip |= full
            if mod == 0.0:
                mode, cop = HP_OFF, 0.0
        q_hp_dhw = q_hp if mode == HP_DHW else 0.0
        v_new, q_fc_in, q_dump, q_el_in, q_el_dump, q_unmet = tank.step(state.v_dhw_l, q_hp_dhw, q_rec, q_el_rec,
                                                                        q_dem, room_w)
        q_sh = q_hp if mode == HP_SH else 0.0
        q_cool = q_hp if mode == HP_COOL else 0.0
        t_air, t_wi, t_wo = self.building.step((state.t_air_c, state.t_wall_in_c, state.t_wall_out_c),
                                               q_sh - q_cool, exo)
        p_ch, p_dis, soc_new, power_clip, soc_clip = battery.step(p_bess_req, state.soc, self._b, dt_h)
        clipped |= clip | fc_clip | el_clip | (CLIP_BESS_POWER if power_clip else 0)
        clipped |= CLIP_BESS_SOC if soc_clip else 0
        p_buy, p_sell, residual = grid.exchange(exo.p_load_w, p_hp, p_ch, p_el, exo.p_pv_w, p_fc, p_dis)
        fc_on, prev_on = p_fc > 0.0, state.fc_on
        new_state = PlantState(soc_new, loh, t_air, t_wi, t_wo, v_new, mod, fc_on, el_on)
        flows = Flows(exo.p_pv_w, exo.p_load_w, p_hp, mode, mod, cop, q_sh, q_hp_dhw, p_fc, fc_on,
                      fc_on and not prev_on, prev_on and not fc_on, p_h2, eta_fc, q_fc_in, q_dump, p_ch, p_dis,
                      p_buy, p_sell, q_dem, tank.q_loss_w, q_unmet, exo.price_buy_eur_per_kwh,
                      exo.price_sell_eur_per_kwh, residual, clipped, p_el, el_on, el_on and not state.el_on,
                      p_h2_el, q_el_in, q_el_dump, q_cool)
        return new_state, flows

    def _command(self, action: Action) -> tuple[float, int, float, float, float, int]:
        """The action's set-points as finite floats and a known circuit, with their clip bits.

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

    def _electrolyser(self, p_req_w: float, loh: float, was_on: bool) -> tuple[float, float, bool, float, float, int]:
        """The electrolyser's step after the fuel cell's draw (nothing without modules and request)."""
        if p_req_w == 0.0 and not self.el_table.n:
            return p_req_w, 0.0, False, 0.0, loh, 0
        fc = self.fuel_cell
        return self.el_table.run(p_req_w, loh, was_on, self.dt_h, fc.loh_max, fc.e_h2_wh)

    def _check_inputs(self, state: PlantState, exo: Exogenous) -> None:
        """Raise ValueError for a non-finite or negative input or a state outside its bounds (fast path first)."""
        if not (
            math.isfinite(exo.t_amb_c + exo.ghi_w_m2 + exo.p_pv_w + exo.p_load_w + exo.dhw_l_per_h
                          + exo.price_buy_eur_per_kwh)
            and math.isfinite(exo.price_sell_eur_per_kwh)
            and exo.ghi_w_m2 >= 0.0
            and exo.p_pv_w >= 0.0
            and exo.p_load_w >= 0.0
            and exo.dhw_l_per_h >= 0.0
        ):
            self._raise_exo(exo)
        b, fc, tank = self._b, self.fuel_cell, self.tank
        if not (
            b.soc_min - STATE_TOL <= state.soc <= b.soc_max + STATE_TOL
            and fc.loh_min - STATE_TOL <= state.loh <= fc.loh_max + STATE_TOL
            and tank.v_min_l - STATE_TOL <= state.v_dhw_l <= tank.v_max_l + STATE_TOL
            and math.isfinite(state.t_air_c + state.t_wall_in_c + state.t_wall_out_c)
        ):
            self.check_state(state)

    @staticmethod
    def _raise_exo(exo: Exogenous) -> None:
        for name in EXOGENOUS_FIELDS:
            value = getattr(exo, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"exogenous input '{name}' is not a finite number: {value!r}")
        for name in ("ghi_w_m2", "p_pv_w", "p_load_w", "dhw_l_per_h"):
            if getattr(exo, name) < 0.0:
                raise ValueError(f"exogenous input '{name}' is negative: {getattr(exo, name)!r}")
        raise ValueError(f"exogenous input invalid: {exo!r}")  # pragma: no cover
