"""The building plant: one step of every device model and the power balance.

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

Everything in :meth:`Plant.step` is plain float arithmetic on precomputed coefficients
(no numpy), for speed (``comems4build bench plant``).
"""

from __future__ import annotations

import bisect
import math

from comems4build_ros.core.config import SECONDS_PER_HOUR, W_PER_KW, PlantParams
from comems4build_ros.core.models import battery, building, dhw, fuel_cell
from comems4build_ros.core.models.electrolyser import ElectrolyserTable
from comems4build_ros.core.models.heat_pump import T_SUPPLY_TABLE_C
from comems4build_ros.core.types import (
    CLIP_BESS_POWER,
    CLIP_BESS_SOC,
    CLIP_EL_H2,
    CLIP_EL_RANGE,
    CLIP_FC_H2,
    CLIP_FC_RANGE,
    CLIP_HP_DHW_FULL,
    CLIP_HP_MOD,
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


def _as_float(value) -> float:
    """``float(value)``, or NaN for anything that is not a number."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return _NAN


class _PiecewiseLinear:
    """Scalar piecewise-linear interpolation, held constant outside the table."""

    __slots__ = ("xs", "ys")

    def __init__(self, xs, ys) -> None:
        self.xs = [float(x) for x in xs]
        self.ys = [float(y) for y in ys]

    def __call__(self, x: float) -> float:
        xs = self.xs
        if x <= xs[0]:
            return self.ys[0]
        if x >= xs[-1]:
            return self.ys[-1]
        j = bisect.bisect_right(xs, x) - 1
        y0 = self.ys[j]
        return y0 + (x - xs[j]) * (self.ys[j + 1] - y0) / (xs[j + 1] - xs[j])


class Plant:
    """The simulated building with PV, BESS, H2 system, heat pump, DHW tank and 4R3C envelope.

    Parameters
    ----------
    params : PlantParams
        Validated plant parameters (:func:`comems4build_ros.core.config.load_plant_params`).

    Raises
    ------
    ValueError
        If the fuel-cell polarization curve cannot deliver ``fuel_cell.p_max_w``.
    """

    def __init__(self, params: PlantParams) -> None:
        self.params = params
        self.dt_h = float(params.simulation.time_step_h)
        dt_s = self.dt_h * SECONDS_PER_HOUR

        b = params.battery
        self._e_b_wh = b.e_max_kwh * W_PER_KW
        self._b = b

        fc = params.fuel_cell
        self.fc_table = fuel_cell.FuelCellTable(fc)
        self._fc_p_min = float(fc.p_min_w)
        self._fc_p_top = float(fc.zeta * fc.p_max_w)
        self._eta_sys = float(fc.eta_sys)

        h2 = params.hydrogen
        self._e_h2_wh = h2.e_max_kwh * W_PER_KW
        self._loh_min = float(h2.loh_min)
        self._loh_max = float(h2.loh_max)

        hp = params.heat_pump
        self._mod_min = float(hp.mod_min)
        self._cop45 = _PiecewiseLinear(hp.cop_t_amb_c, hp.cop_45c)
        self._cop55 = _PiecewiseLinear(hp.cop_t_amb_c, hp.cop_55c)
        self._p_el_max = _PiecewiseLinear(hp.p_el_max_t_amb_c, hp.p_el_max_w)
        lo, hi = T_SUPPLY_TABLE_C

        def weight(t_supply: float) -> float:
            return min(1.0, max(0.0, (t_supply - lo) / (hi - lo)))

        self._w_supply = {HP_SH: weight(hp.t_supply_sh_c), HP_DHW: weight(hp.t_supply_dhw_c)}

        self.el_table = ElectrolyserTable(params.electrolyser)
        self._el_n = self.el_table.n
        cool = params.cooling
        self._cool_on = bool(cool.enabled)
        self._eer = _PiecewiseLinear(cool.eer_t_amb_c, cool.eer)
        self._q_cool_max = float(cool.q_cool_max_w)

        d = params.dhw
        self._j_per_l = dhw.heat_per_litre_j(d)
        self._l_per_w = dt_s / self._j_per_l  # litres per W held over the step
        self._w_per_l_per_h = self._j_per_l / SECONDS_PER_HOUR
        self._v_min = float(d.v_min_l)
        self._v_max = float(d.v_max_l)
        self._q_loss = float(d.q_loss_w)

        Ad, Bd = building.discretize(params.building, self.dt_h)
        self.Ad, self.Bd = Ad, Bd
        self._ad = [[float(v) for v in row] for row in Ad]
        self._bd = [[float(v) for v in row] for row in Bd]

    # ------------------------------------------------------------------ state
    def initial_state(self, t_amb_c: float | None = None) -> PlantState:
        """State at the start of a run (``simulation`` section of the parameters).

        The wall nodes start on the steady-state profile between T_air,init and the
        ambient temperature ``t_amb_c`` (default ``building.t_amb_init_c``), i.e. as if
        the house had been held at T_air,init without sun.
        """
        sim = self.params.simulation
        t_amb = self.params.building.t_amb_init_c if t_amb_c is None else float(t_amb_c)
        b = self.params.building
        r_chain = b.r_w_air_k_per_w + b.r_w_k_per_w + b.r_w_amb_k_per_w
        dt = sim.t_air_init_c - t_amb
        state = PlantState(
            soc=sim.soc_init,
            loh=sim.loh_init,
            t_air_c=sim.t_air_init_c,
            t_wall_in_c=sim.t_air_init_c - dt * b.r_w_air_k_per_w / r_chain,
            t_wall_out_c=sim.t_air_init_c - dt * (b.r_w_air_k_per_w + b.r_w_k_per_w) / r_chain,
            v_dhw_l=sim.v_dhw_init_l,
            hp_mod=0.0,
            fc_on=False,
            el_on=False,
        )
        self.check_state(state)
        return state

    def check_state(self, state: PlantState) -> None:
        """Raise ValueError if a state is not finite or outside the storage bounds."""
        b = self._b
        checks = (
            ("soc", state.soc, b.soc_min, b.soc_max),
            ("loh", state.loh, self._loh_min, self._loh_max),
            ("v_dhw_l", state.v_dhw_l, self._v_min, self._v_max),
        )
        for name, value, lo, hi in checks:
            if not lo - STATE_TOL <= value <= hi + STATE_TOL:
                raise ValueError(f"plant state: {name} = {value} outside [{lo}, {hi}]")
        for name in ("t_air_c", "t_wall_in_c", "t_wall_out_c"):
            if not math.isfinite(getattr(state, name)):
                raise ValueError(f"plant state: {name} is not finite")

    # ------------------------------------------------------------------- step
    def step(self, state: PlantState, action: Action, exo: Exogenous) -> tuple[PlantState, Flows]:
        """Advance the plant by one step.

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
        dt_h = self.dt_h
        clipped = 0

        # --- inputs ---------------------------------------------------------------
        t_amb = exo.t_amb_c
        q_s = exo.ghi_w_m2
        p_pv = exo.p_pv_w
        p_load = exo.p_load_w
        dhw_lph = exo.dhw_l_per_h
        if not (
            math.isfinite(t_amb + q_s + p_pv + p_load + dhw_lph + exo.price_buy_eur_per_kwh)
            and math.isfinite(exo.price_sell_eur_per_kwh)
            and q_s >= 0.0
            and p_pv >= 0.0
            and p_load >= 0.0
            and dhw_lph >= 0.0
        ):
            self._raise_exo(exo)
        soc = state.soc
        loh = state.loh
        v = state.v_dhw_l
        b = self._b
        if not (
            b.soc_min - STATE_TOL <= soc <= b.soc_max + STATE_TOL
            and self._loh_min - STATE_TOL <= loh <= self._loh_max + STATE_TOL
            and self._v_min - STATE_TOL <= v <= self._v_max + STATE_TOL
            and math.isfinite(state.t_air_c + state.t_wall_in_c + state.t_wall_out_c)
        ):
            self.check_state(state)

        hp_mod = _as_float(action.hp_mod)
        mode_f = _as_float(action.hp_mode)
        p_fc = _as_float(action.p_fc_w)
        p_bess = _as_float(action.p_bess_w)
        p_el = _as_float(action.p_el_w)
        if not math.isfinite(p_el):
            p_el = 0.0
            clipped |= CLIP_NONFINITE
        if not math.isfinite(hp_mod):
            hp_mod = 0.0
            clipped |= CLIP_NONFINITE
        if not math.isfinite(p_fc):
            p_fc = 0.0
            clipped |= CLIP_NONFINITE
        if not math.isfinite(p_bess):
            p_bess = 0.0
            clipped |= CLIP_NONFINITE
        if mode_f == 0.0:
            mode = HP_OFF
        elif mode_f == 1.0:
            mode = HP_SH
        elif mode_f == 2.0:
            mode = HP_DHW
        elif mode_f == 3.0 and self._cool_on:
            mode = HP_COOL
        else:
            if not math.isfinite(mode_f):
                clipped |= CLIP_NONFINITE
            clipped |= CLIP_HP_MODE
            mode = HP_OFF

        # --- heat pump (sec:hp) ---------------------------------------------------
        mod_min = self._mod_min
        if mode == HP_OFF:
            if hp_mod != 0.0:
                clipped |= CLIP_HP_MOD
            mod = 0.0
        elif hp_mod <= 0.0:
            if hp_mod < 0.0:
                clipped |= CLIP_HP_MOD
            mod = 0.0
        elif hp_mod > 1.0:
            mod = 1.0
            clipped |= CLIP_HP_MOD
        elif hp_mod < mod_min:
            mod = mod_min if hp_mod >= 0.5 * mod_min else 0.0
            clipped |= CLIP_HP_MOD
        else:
            mod = hp_mod
        if mod == 0.0:
            mode = HP_OFF
            cop = 0.0
            p_el_max = 0.0
        elif mode == HP_COOL:
            cop = self._eer(t_amb)  # EER
            p_el_max = self._q_cool_max / cop
        else:
            w = self._w_supply[mode]
            c45 = self._cop45(t_amb)
            cop = c45 + w * (self._cop55(t_amb) - c45)
            p_el_max = self._p_el_max(t_amb)
        p_hp = mod * p_el_max
        q_hp = cop * p_hp

        # --- fuel cell and H2 store (eq:molar_flows .. eq:FC_sys_efficiency, eq:LOH) ---
        p_min = self._fc_p_min
        if p_fc <= 0.0:
            if p_fc < 0.0:
                clipped |= CLIP_FC_RANGE
            p_fc = 0.0
        elif p_fc < p_min:
            p_fc = p_min if p_fc >= 0.5 * p_min else 0.0
            clipped |= CLIP_FC_RANGE
        elif p_fc > self._fc_p_top:
            p_fc = self._fc_p_top
            clipped |= CLIP_FC_RANGE
        p_h2 = 0.0
        if p_fc > 0.0:
            table = self.fc_table
            p_h2 = table.h2_power_w(p_fc)
            h2_avail = (loh - self._loh_min) * self._e_h2_wh / dt_h
            if p_h2 > h2_avail:
                clipped |= CLIP_FC_H2
                p_fc = table.el_power_w(h2_avail)
                if p_fc < p_min:
                    p_fc = 0.0
                    p_h2 = 0.0
                else:
                    p_h2 = min(table.h2_power_w(p_fc), h2_avail)
        if p_fc > 0.0:
            eta_fc = p_fc / p_h2
            q_rec = self._eta_sys * p_h2 - p_fc
            if q_rec < 0.0:
                q_rec = 0.0
        else:
            eta_fc = 0.0
            q_rec = 0.0
        fc_on = p_fc > 0.0
        loh_new = loh - p_h2 * dt_h / self._e_h2_wh
        if loh_new < self._loh_min:
            loh_new = self._loh_min

        # --- electrolyser (models/electrolyser.py) -----------------------------------
        el_on = False
        p_h2_el = 0.0
        q_el_rec = 0.0
        if p_el != 0.0 or self._el_n:
            p_el, p_h2_el, el_on, q_el_rec, el_clip = self._electrolyser(p_el, loh_new, state.el_on, dt_h)
            clipped |= el_clip
            if p_h2_el > 0.0:
                loh_new = loh_new + p_h2_el * dt_h / self._e_h2_wh
                if loh_new > self._loh_max:
                    loh_new = self._loh_max

        # --- DHW tank (eq:DHW_model, eq:DHW_heat) ---------------------------------
        l_per_w = self._l_per_w
        q_dem = dhw_lph * self._w_per_l_per_h
        q_loss = self._q_loss
        room_w = (self._v_max - v) / l_per_w + q_dem + q_loss  # largest net inflow that fits
        q_hp_dhw = 0.0
        q_rec_all = q_rec + q_el_rec
        if mode == HP_DHW:
            cap_hp = room_w - q_rec_all
            if q_hp > cap_hp:
                clipped |= CLIP_HP_DHW_FULL
                mod_fit = cap_hp / (cop * p_el_max) if cap_hp > 0.0 else 0.0
                if mod_fit < mod_min:
                    mode = HP_OFF
                    mod = 0.0
                    cop = 0.0
                    p_hp = 0.0
                    q_hp = 0.0
                else:
                    mod = mod_fit
                    p_hp = mod * p_el_max
                    q_hp = cop * p_hp
            q_hp_dhw = q_hp
        q_fc_in = q_rec
        q_dump = 0.0
        q_el_in = q_el_rec
        q_el_dump = 0.0
        if q_rec_all + q_hp_dhw > room_w:
            avail = room_w - q_hp_dhw
            if avail < 0.0:
                avail = 0.0
            if q_el_rec > 0.0:  # FC heat first, then EL heat
                q_fc_in = q_rec if q_rec < avail else avail
                q_el_in = min(q_el_rec, avail - q_fc_in)
                q_el_dump = q_el_rec - q_el_in
            else:
                q_fc_in = avail
            q_dump = q_rec - q_fc_in
        v_new = v + (q_hp_dhw + q_fc_in + q_el_in - q_dem - q_loss) * l_per_w
        q_unmet = 0.0
        if v_new < self._v_min:
            q_unmet = (self._v_min - v_new) / l_per_w
            v_new = self._v_min
        elif v_new > self._v_max:
            v_new = self._v_max

        # --- building (eq:state_update_bldgs) ---------------------------------------
        q_sh = q_hp if mode == HP_SH else 0.0
        q_cool = q_hp if mode == HP_COOL else 0.0
        q_floor = q_sh - q_cool
        x0, x1, x2 = state.t_air_c, state.t_wall_in_c, state.t_wall_out_c
        a0, a1, a2 = self._ad
        b0, b1, b2 = self._bd
        t_air = a0[0] * x0 + a0[1] * x1 + a0[2] * x2 + b0[0] * q_floor + b0[1] * t_amb + b0[2] * q_s
        t_wi = a1[0] * x0 + a1[1] * x1 + a1[2] * x2 + b1[0] * q_floor + b1[1] * t_amb + b1[2] * q_s
        t_wo = a2[0] * x0 + a2[1] * x1 + a2[2] * x2 + b2[0] * q_floor + b2[1] * t_amb + b2[2] * q_s

        # --- battery (eq:batt_soc, eq:SOC_const, eq:bat_ch_dis_const) ----------------
        p_ch, p_dis, power_clip, soc_clip = battery.split_power(p_bess, soc, b, dt_h)
        if power_clip:
            clipped |= CLIP_BESS_POWER
        if soc_clip:
            clipped |= CLIP_BESS_SOC
        soc_new = soc + (b.eta_ch * p_ch - p_dis / b.eta_d) * dt_h / self._e_b_wh
        if soc_new > b.soc_max:
            soc_new = b.soc_max
        elif soc_new < b.soc_min:
            soc_new = b.soc_min

        # --- grid (eq:power_balance) -------------------------------------------------
        net = (p_load + p_hp + p_ch + p_el) - (p_pv + p_fc + p_dis)
        if net > 0.0:
            p_buy = net
            p_sell = 0.0
        else:
            p_buy = 0.0
            p_sell = -net
        residual = (p_pv + p_buy + p_fc + p_dis) - (p_sell + p_load + p_hp + p_ch + p_el)

        prev_on = state.fc_on
        new_state = PlantState(soc_new, loh_new, t_air, t_wi, t_wo, v_new, mod, fc_on, el_on)
        flows = Flows(
            p_pv,
            p_load,
            p_hp,
            mode,
            mod,
            cop,
            q_sh,
            q_hp_dhw,
            p_fc,
            fc_on,
            fc_on and not prev_on,
            prev_on and not fc_on,
            p_h2,
            eta_fc,
            q_fc_in,
            q_dump,
            p_ch,
            p_dis,
            p_buy,
            p_sell,
            q_dem,
            q_loss,
            q_unmet,
            exo.price_buy_eur_per_kwh,
            exo.price_sell_eur_per_kwh,
            residual,
            clipped,
            p_el,
            el_on,
            el_on and not state.el_on,
            p_h2_el,
            q_el_in,
            q_el_dump,
            q_cool,
        )
        return new_state, flows

    def _electrolyser(self, p_req: float, loh: float, was_on: bool, dt_h: float
                      ) -> tuple[float, float, bool, float, int]:
        """The EL's step: (intake [W], H2 made [W LHV], on, recoverable heat [W], clip bits).

        ``p_req`` is the requested intake, ``loh`` the level after the FC's draw. Off, the
        modules draw their standby power.
        """
        table = self.el_table
        clip = 0
        if self._el_n == 0:
            return 0.0, 0.0, False, 0.0, (CLIP_EL_RANGE if p_req != 0.0 else 0)
        p_min, p_max = table.p_min_w, table.p_max_w
        if p_req <= 0.0:
            if p_req < 0.0:
                clip |= CLIP_EL_RANGE
            return table.p_standby_w, 0.0, False, 0.0, clip
        if p_req < p_min:
            clip |= CLIP_EL_RANGE
            if p_req < 0.5 * p_min:
                return table.p_standby_w, 0.0, False, 0.0, clip
            p_req = p_min
        elif p_req > p_max:
            clip |= CLIP_EL_RANGE
            p_req = p_max
        x = table.load_of_power(p_req)
        f_prod = 1.0 if was_on else max(0.0, 1.0 - table.start_lost_h / dt_h)
        room_w = (self._loh_max - loh) * self._e_h2_wh / dt_h
        h2 = table.h2_w(x) * f_prod
        if h2 > room_w:
            clip |= CLIP_EL_H2
            x_fit = room_w / (table.h2_w(1.0) * f_prod) if f_prod > 0.0 else 0.0
            if x_fit < table.x_min:
                return table.p_standby_w, 0.0, False, 0.0, clip
            x = x_fit
            h2 = min(table.h2_w(x) * f_prod, room_w)
        p_el = table.p_total_w(x)
        waste = table.p_stack_w(x) - h2
        q_rec = table.heat_recovery * waste if waste > 0.0 else 0.0
        return p_el, h2, True, q_rec, clip

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
