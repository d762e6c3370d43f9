"""The MPC's horizon problem as a PuLP MILP (paper sec:MPC).

Built once per controller (:class:`MILPModel`) and updated each step: the right-hand
sides (initial states, forecasts, comfort bounds, LOH_min), the objective coefficients
(buy and sell prices), the bounds and the matrix coefficients that depend on the
forecast ambient temperature (COP, P_el,HP,max) are changed in place; the structure never
changes. The PuLP problem stays the source of the model: a solver backend
(:mod:`.solvers`) reads its arrays once and, before each solve, passes on what changed.

Per step ``t`` (0 = step k of the closed loop), powers in W, energies via ``dt_h``:

- ``balance_{t}`` (eq:power_balance):
  ``P_buy - P_sell + P_FC + P_d - P_ch - P_HP,SH - P_HP,DHW = P_load - P_PV``
- ``soc_{t}`` (eq:batt_soc), ``loh_{t}`` (eq:LOH, constant eta_el_mpc), ``dhw_{t}``
  (eq:DHW_model with eq:DHW_heat: HP heat at the 45 degC COP plus recovered FC heat
  ``k_fc_heat * P_FC`` minus dumped heat ``q_dump <= k_fc_heat * P_FC``; with
  ``fc_heat_dump`` off ``q_dump`` is 0, eq:DHW_heat as printed: all recovered heat enters
  the tank, so the FC runs only while the tank can take its heat), ``air_{t}``,
  ``wall_in_{t}``, ``wall_out_{t}`` (eq:state_update_bldgs with Q_h,SH = COP_55 P_HP,SH).
- Soft bounds with slack variables ``sl_*_{t}`` (heavy linear penalty): comfort
  ``comfort_lo_{t}``/``comfort_hi_{t}`` (eq:T_min), tank ``dhw_lo_{t}``/``dhw_hi_{t}``,
  battery ``soc_lo_{t}``/``soc_hi_{t}`` (eq:SOC_const), H2 ``loh_lo_{t}`` (eq:LOHmin_MPC).
- Devices (formulation ``tight``):
  HP (eq:zetas..eq:heat_flux_DHW): ``mod_min P_max s_SH <= P_HP,SH <= P_max s_SH``, the same
  for DHW, ``s_SH + s_DHW <= 1``; P_max = P_el,HP,max(T_amb[t]) is the tightest big-M.
  Battery (eq:bat_ch_dis_const, eq:s_summ): one binary ``b_ch`` (charge allowed) when the
  minimum powers are 0 (``P_ch <= P_ch,max b``, ``P_d <= P_d,max (1 - b)``), otherwise two.
  With ``relax_battery_binary`` the single ``b_ch`` is relaxed to [0, 1] in every solve
  whose sell price is >= 0: charging and discharging in the same hour is then never
  optimal (lowering both so that the SOC path stays the same frees
  ``(1 - eta_ch eta_d)`` of the charged power, which ``P_sell`` (no upper bound) takes at
  ``p_sell >= 0``, and saves lifecycle cost; once one of the two is 0 a binary ``b_ch``
  fits the same powers), so the optimum is the same; with a negative sell price ``b_ch``
  is binary again.
  FC: ``P_min s_FC <= P_FC <= zeta P_max s_FC``; start/stop (eq:on_off_logic) as continuous
  ``s_on - s_off = s_FC[t] - s_FC[t-1]`` in [0, 1] (integral at the optimum since both
  carry positive costs).
- Formulation ``paper`` (benchmark baseline): HP on binary plus s_SH and s_DHW binaries,
  the modulation eta_HP continuous and the products s_SH * eta_HP linearised with a loose
  big-M; two battery binaries with the loose big-M; start/stop binaries with the
  three-inequality AND linearisation.

Objective (eq:mpc_objective): ``sum_t dt (p_buy P_buy - p_sell P_sell) + dt (sigma_B,ch P_ch
+ sigma_B,d P_d + sigma_FC s_FC) + sigma_on s_on + sigma_off s_off`` plus the penalties.

A year-round plant (``docs/seasonal.md``; ``PlantConstants.year_round``) adds, and only then
(the paper's plant gets exactly the model above):

- electrolyser: ``P_EL,min s_EL <= P_EL <= P_EL,max s_EL`` (``s_EL`` binary), its intake on
  the demand side of ``balance``, ``eta_EL P_EL`` (rated LHV efficiency, compression
  included) into ``loh``, starts ``s_EL,on - s_EL,off = s_EL[t] - s_EL[t-1]`` at
  ``sigma_el_on_eur``; the store's upper bound ``loh_hi`` (hard);
- cooling: ``mod_min P_cool,max s_cool <= P_HP,cool <= P_cool,max s_cool`` with
  ``P_cool,max = Q_cool,max / EER(T_amb[t])``, ``s_SH + s_DHW + s_cool <= 1``, the heat
  ``- EER P_HP,cool`` into the building model's equations, the intake in ``balance``;
- the seasonal target of the store: ``loh_season_{t}``: ``LOH + sl_loh_season >= target[t]``
  (soft, ``penalty_loh_season_eur_per_h``), the FC off while the store is at or below the
  target (``P_FC`` bounded by 0; inside the heating season the target is 0), and the H2 left
  at the horizon's end valued at ``h2_value_eur_per_kwh`` (``- value E_H2,max LOH[n-1]``)
  outside the heating season (inside it, as in the paper's winter, only eq:LOHmin_MPC binds);
- ``P_sell <= P_PV + zeta P_FC,max + P_d,max``: with a buy price below the sell price (spot
  below -16 EUR/MWh occurs in the year's data) buying to sell would be unbounded.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pulp

from comems4build_ros.core.config import W_PER_KW
from comems4build_ros.core.ems.mpc.horizon import HorizonData, PlantConstants
from comems4build_ros.core.ems.mpc.solvers import MatrixForm
from comems4build_ros.core.numerics import rowdot

#: Slack variables and the unit each is reported in.
SLACKS = {
    "sl_t_lo": "K", "sl_t_hi": "K", "sl_v_lo": "l", "sl_v_hi": "l",
    "sl_soc_lo": "-", "sl_soc_hi": "-", "sl_loh": "-",
}


@dataclass
class Penalties:
    """Soft-bound penalties (``config/mpc.yaml``), per unit of slack and hour.

    Attributes
    ----------
    comfort_eur_per_kh : float
        T_air outside its bounds [EUR per K and hour].
    dhw_eur_per_lh : float
        V_DHW outside its bounds [EUR per litre and hour].
    soc_eur_per_h, loh_eur_per_h : float
        SOC outside its bounds, LOH below LOH_min [EUR per unit and hour].
    """

    comfort_eur_per_kh: float
    dhw_eur_per_lh: float
    soc_eur_per_h: float
    loh_eur_per_h: float


@dataclass
class YearTerms:
    """Costs of the year-round plant's terms (``config/mpc.yaml``; unused for the paper's plant).

    Attributes
    ----------
    penalty_loh_season_eur_per_h : float
        Deficit below the seasonal LOH target [EUR per unit LOH and hour].
    h2_value_eur_per_kwh : float
        Value of the H2 left at the horizon's end outside the heating season [EUR per kWh LHV].
    sigma_el_on_eur : float
        Start cost of the electrolyser [EUR].
    """

    penalty_loh_season_eur_per_h: float
    h2_value_eur_per_kwh: float
    sigma_el_on_eur: float


@dataclass
class SolveResult:
    """Outcome of one solve.

    Attributes
    ----------
    status : str
        PuLP solution status text (``pulp.LpSolution[prob.sol_status]``).
    has_solution : bool
        A (possibly non-optimal) feasible solution is available.
    optimal : bool
        The solver proved optimality within the gap.
    objective : float
        Objective value [EUR] (NaN without solution).
    plan : dict[str, numpy.ndarray]
        Variable prefix -> values per horizon step [unit of the variable] (empty without
        solution).
    solve_s : float
        Wall time of the solve call: passing the changes to the solver, the solve, reading
        the solution [s].
    gap : float
        Relative MIP gap reported by the solver [-] (NaN if unknown).
    """

    status: str
    has_solution: bool
    optimal: bool
    objective: float
    plan: dict[str, np.ndarray] = field(default_factory=dict)
    solve_s: float = math.nan
    gap: float = math.nan


class MILPModel:
    """The horizon MILP, built once and updated per step.

    Parameters
    ----------
    const : PlantConstants
        Plant constants of the MPC.
    penalties : Penalties
        Soft-bound penalties.
    formulation : {"tight", "paper"}
        The formulation (see the module docstring).
    big_m_loose_w : float
        Big-M of the ``paper`` formulation [W].
    integer_steps : int or None
        Steps (from t = 0) whose binaries stay binary; the binaries of later steps are
        relaxed to [0, 1] ("relaxed tail"). ``None`` or ``>= n``: all binary.
    relax_battery_binary : bool
        Relax the single battery binary while the sell price is >= 0 (formulation
        ``tight``; see the module docstring).
    year : YearTerms or None
        Terms of the year-round plant (electrolyser, seasonal H2 target); required when
        ``const.year_round``.
    fc_heat_dump : bool
        Whether recovered FC heat the tank cannot take may be dumped (``q_dump``);
        ``False`` = ``eq:DHW_heat`` as printed (see the module docstring).
    prefix : str
        Put before every variable and constraint name (several houses' models in one
        problem, :mod:`comems4build_ros.core.community.optimal`).
    h2_exchange : bool
        The house's store is an account at a shared hub: H2 moved into the account
        (``h2_in``) and out of it (``h2_out``) [W LHV, >= 0] enter ``loh``, and the account is
        bounded by ``LOH_max`` (hard); their costs are the composing problem's.

    Raises
    ------
    ValueError
        For an unknown formulation, or a year-round plant without ``year``.
    """

    def __init__(
        self,
        const: PlantConstants,
        penalties: Penalties,
        formulation: str = "tight",
        big_m_loose_w: float = 1e5,
        integer_steps: int | None = None,
        relax_battery_binary: bool = False,
        year: YearTerms | None = None,
        fc_heat_dump: bool = False,
        prefix: str = "",
        h2_exchange: bool = False,
    ) -> None:
        if formulation not in ("tight", "paper"):
            raise ValueError(f"formulation: unknown value '{formulation}' (tight, paper)")
        if const.year_round and year is None:
            raise ValueError("a year-round plant (electrolyser or cooling) needs the MPC's year terms")
        self.const = const
        self.pen = penalties
        self.formulation = formulation
        self.big_m = big_m_loose_w
        self.n = const.n
        self.integer_steps = self.n if integer_steps is None else max(0, min(int(integer_steps), self.n))
        self.relax_battery_binary = relax_battery_binary
        self.year = year
        self.fc_heat_dump = fc_heat_dump
        self.prefix = prefix
        self.h2_exchange = h2_exchange
        self.prob = pulp.LpProblem(f"{prefix}mpc_horizon", pulp.LpMinimize)
        self.v: dict[str, list[pulp.LpVariable]] = {}
        self.c: dict[str, list[pulp.LpConstraint]] = {}
        #: (constraint, variable) pairs whose coefficient update() changes
        self.mutable: list[tuple[pulp.LpConstraint, pulp.LpVariable]] = []
        self._build()
        self.two_bat = "b_dis" in self.v
        self.form = MatrixForm(self.prob, self.mutable)
        self._cols = {name: np.array([self.form.col_index[v.name] for v in vars_]) for name, vars_ in self.v.items()}

    # ----------------------------------------------------------------- building model
    def _var(self, name: str, low: float | None = 0.0, up: float | None = None, binary: bool = False) -> None:
        if binary:  # binary for t < integer_steps, relaxed to [0, 1] after
            self.v[name] = [
                pulp.LpVariable(f"{self.prefix}{name}_{t}", 0, 1,
                                pulp.LpBinary if t < self.integer_steps else pulp.LpContinuous)
                for t in range(self.n)
            ]
        else:
            self.v[name] = [pulp.LpVariable(f"{self.prefix}{name}_{t}", low, up, pulp.LpContinuous)
                            for t in range(self.n)]

    def _con(self, name: str, t: int, con: pulp.LpConstraint) -> None:
        self.c.setdefault(name, []).append(con)
        self.prob.addConstraint(con, f"{self.prefix}{name}_{t}")

    # Long on purpose: the whole horizon problem in the order of sec:MPC, one block per equation,
    # so that it reads beside the paper; splitting it would scatter the formulation.
    def _build(self) -> None:
        k, n, paper = self.const, self.n, self.formulation == "paper"
        for name in ("p_buy", "p_sell", "q_dump", "t_wall_in", "t_wall_out", "v_dhw", "soc", "loh"):
            up = 0.0 if name == "q_dump" and not self.fc_heat_dump else None  # eq:DHW_heat as printed: no dump
            self._var(name, None if name.startswith("t_") else 0.0, up)
        if self.h2_exchange:  # an account at the hub: never above its LOH_max, H2 moved in or out
            self._var("h2_in", 0.0)
            self._var("h2_out", 0.0)
            for var in self.v["loh"]:
                var.upBound = k.loh_upper
        self._var("t_air", None)
        self._var("p_ch", 0.0, k.p_ch_max_w)
        self._var("p_dis", 0.0, k.p_d_max_w)
        self._var("p_fc", 0.0, k.p_fc_max_w)
        self._var("p_hp_sh", 0.0)
        self._var("p_hp_dhw", 0.0)
        for name in SLACKS:
            self._var(name, 0.0)
        self._var("s_fc", binary=True)
        self._var("s_sh", binary=True)
        self._var("s_dhw", binary=True)
        self._var("s_fc_on", 0.0, 1.0, binary=paper)
        self._var("s_fc_off", 0.0, 1.0, binary=paper)
        two_bat = paper or k.p_ch_min_w > 0 or k.p_d_min_w > 0
        if two_bat:
            self._var("b_ch", binary=True)
            self._var("b_dis", binary=True)
        else:
            self._var("b_ch", binary=True)
        if paper:
            self._var("s_hp", binary=True)
            self._var("eta_hp", 0.0, 1.0)
        if k.el:
            self._var("p_el", 0.0, k.p_el_max_w)
            self._var("s_el", binary=True)
            self._var("s_el_on", 0.0, 1.0)
            self._var("s_el_off", 0.0, 1.0)
        if k.cooling:
            self._var("p_hp_cool", 0.0)
            self._var("s_cool", binary=True)
        if k.year_round:
            self._var("sl_loh_season", 0.0)
        V = self.v
        m_loose = self.big_m
        for t in range(n):
            def prev(name: str, t: int = t) -> pulp.LpVariable | float:
                return V[name][t - 1] if t else 0.0

            # eq:power_balance (rhs P_load - P_PV set by update)
            hp_el = V["p_hp_sh"][t] + V["p_hp_dhw"][t]
            if k.cooling:
                hp_el = hp_el + V["p_hp_cool"][t]
            if k.el:
                hp_el = hp_el + V["p_el"][t]  # the electrolyser's intake on the demand side
            self._con("balance", t, V["p_buy"][t] - V["p_sell"][t] + V["p_fc"][t] + V["p_dis"][t] - V["p_ch"][t]
                      - hp_el == 0.0)
            # eq:batt_soc
            self._con("soc", t, V["soc"][t] - prev("soc") - k.soc_per_wh_ch * k.dt_h * V["p_ch"][t]
                      + k.soc_per_wh_d * k.dt_h * V["p_dis"][t] == 0.0)
            # eq:LOH at constant eta_el_mpc
            loh_expr = V["loh"][t] - prev("loh") + k.loh_per_wh_fc * k.dt_h * V["p_fc"][t]
            if k.el:
                loh_expr = loh_expr - k.loh_per_wh_el * k.dt_h * V["p_el"][t]
            if self.h2_exchange:
                per_wh = k.dt_h / (k.params.hydrogen.e_max_kwh * W_PER_KW)
                loh_expr = loh_expr - per_wh * V["h2_in"][t] + per_wh * V["h2_out"][t]
            self._con("loh", t, loh_expr == 0.0)
            # eq:DHW_model + eq:DHW_heat; COP coefficient set by update
            cv = k.l_per_wh * k.dt_h
            self._con("dhw", t, V["v_dhw"][t] - prev("v_dhw") - cv * 1.0 * V["p_hp_dhw"][t]
                      - cv * k.k_fc_heat * V["p_fc"][t] + cv * V["q_dump"][t] == 0.0)
            self.mutable.append((self.c["dhw"][t], V["p_hp_dhw"][t]))
            self._con("fc_heat_dump", t, V["q_dump"][t] - k.k_fc_heat * V["p_fc"][t] <= 0.0)
            # eq:state_update_bldgs; COP coefficient set by update
            states = ("t_air", "t_wall_in", "t_wall_out")
            for i, (sname, cname) in enumerate(zip(states, ("air", "wall_in", "wall_out"))):
                expr = V[sname][t] - k.bd[i, 0] * 1.0 * V["p_hp_sh"][t]
                if k.cooling:  # EER coefficient set by update
                    expr += k.bd[i, 0] * 1.0 * V["p_hp_cool"][t]
                if t:
                    expr -= pulp.lpSum(k.ad[i, j] * V[states[j]][t - 1] for j in range(3) if k.ad[i, j] != 0.0)
                self._con(cname, t, expr == 0.0)
                self.mutable.append((self.c[cname][t], V["p_hp_sh"][t]))
                if k.cooling:
                    self.mutable.append((self.c[cname][t], V["p_hp_cool"][t]))
            # soft bounds
            self._con("comfort_lo", t, V["t_air"][t] + V["sl_t_lo"][t] >= 0.0)
            self._con("comfort_hi", t, V["t_air"][t] - V["sl_t_hi"][t] <= 0.0)
            self._con("dhw_lo", t, V["v_dhw"][t] + V["sl_v_lo"][t] >= k.v_min_l)
            self._con("dhw_hi", t, V["v_dhw"][t] - V["sl_v_hi"][t] <= k.v_max_l)
            self._con("soc_lo", t, V["soc"][t] + V["sl_soc_lo"][t] >= k.soc_min)
            self._con("soc_hi", t, V["soc"][t] - V["sl_soc_hi"][t] <= k.soc_max)
            self._con("loh_lo", t, V["loh"][t] + V["sl_loh"][t] >= 0.0)
            if k.year_round:
                self._con("loh_season", t, V["loh"][t] + V["sl_loh_season"][t] >= 0.0)
                self._con("loh_hi", t, V["loh"][t] <= k.loh_upper)
            if k.el:
                self._con("el_max", t, V["p_el"][t] - k.p_el_max_w * V["s_el"][t] <= 0.0)
                self._con("el_min", t, V["p_el"][t] - k.p_el_min_w * V["s_el"][t] >= 0.0)
                self._con("el_switch", t, V["s_el_on"][t] - V["s_el_off"][t] - V["s_el"][t] + prev("s_el") == 0.0)
            # FC range and start/stop (eq:on_off_logic)
            self._con("fc_max", t, V["p_fc"][t] - k.p_fc_max_w * V["s_fc"][t] <= 0.0)
            self._con("fc_min", t, V["p_fc"][t] - k.p_fc_min_w * V["s_fc"][t] >= 0.0)
            s_prev = prev("s_fc")
            if paper:  # s_on = s[t] AND NOT s[t-1]; s_off = s[t-1] AND NOT s[t]
                self._con("fc_on_a", t, V["s_fc_on"][t] - V["s_fc"][t] <= 0.0)
                self._con("fc_on_b", t, V["s_fc_on"][t] + s_prev <= 1.0)
                self._con("fc_on_c", t, V["s_fc_on"][t] - V["s_fc"][t] + s_prev >= 0.0)
                self._con("fc_off_a", t, V["s_fc_off"][t] - s_prev <= 0.0)
                self._con("fc_off_b", t, V["s_fc_off"][t] + V["s_fc"][t] <= 1.0)
                self._con("fc_off_c", t, V["s_fc_off"][t] - s_prev + V["s_fc"][t] >= 0.0)
            else:
                self._con("fc_switch", t, V["s_fc_on"][t] - V["s_fc_off"][t] - V["s_fc"][t] + s_prev == 0.0)
            # battery exclusion (eq:bat_ch_dis_const, eq:s_summ)
            # big-M = the power limit (>= 1 W so that a battery without power keeps its binary
            # in the model; the variable bounds still hold the power at 0)
            m_ch_tight, m_d_tight = max(k.p_ch_max_w, 1.0), max(k.p_d_max_w, 1.0)
            if two_bat:
                m_ch = m_loose if paper else m_ch_tight
                m_d = m_loose if paper else m_d_tight
                self._con("bat_ch_max", t, V["p_ch"][t] - m_ch * V["b_ch"][t] <= 0.0)
                self._con("bat_dis_max", t, V["p_dis"][t] - m_d * V["b_dis"][t] <= 0.0)
                if k.p_ch_min_w > 0:
                    self._con("bat_ch_min", t, V["p_ch"][t] - k.p_ch_min_w * V["b_ch"][t] >= 0.0)
                if k.p_d_min_w > 0:
                    self._con("bat_dis_min", t, V["p_dis"][t] - k.p_d_min_w * V["b_dis"][t] >= 0.0)
                self._con("bat_excl", t, V["b_ch"][t] + V["b_dis"][t] <= 1.0)
            else:
                self._con("bat_ch_max", t, V["p_ch"][t] - m_ch_tight * V["b_ch"][t] <= 0.0)
                self._con("bat_dis_max", t, V["p_dis"][t] + m_d_tight * V["b_ch"][t] <= m_d_tight)
            # heat pump (eq:zetas .. eq:heat_flux_DHW); P_max coefficients set by update
            if k.cooling:
                self._con("hp_excl", t, V["s_sh"][t] + V["s_dhw"][t] + V["s_cool"][t] <= 1.0)
                self._con("hp_cool_max", t, V["p_hp_cool"][t] - 1.0 * V["s_cool"][t] <= 0.0)
                self._con("hp_cool_min", t, V["p_hp_cool"][t] - 1.0 * V["s_cool"][t] >= 0.0)
                self.mutable += [(self.c["hp_cool_max"][t], V["s_cool"][t]), (self.c["hp_cool_min"][t], V["s_cool"][t])]
            else:
                self._con("hp_excl", t, V["s_sh"][t] + V["s_dhw"][t] <= 1.0)
            if paper:
                eta, s_hp = V["eta_hp"][t], V["s_hp"][t]
                self._con("hp_mod_min", t, eta - k.hp_mod_min * s_hp >= 0.0)
                self._con("hp_mod_max", t, eta - s_hp <= 0.0)
                self._con("hp_mode_on", t, s_hp - V["s_sh"][t] - V["s_dhw"][t] <= 0.0)
                for mode, s in (("sh", V["s_sh"][t]), ("dhw", V["s_dhw"][t])):
                    p = V[f"p_hp_{mode}"][t]
                    self._con(f"hp_{mode}_bigm", t, p - m_loose * s <= 0.0)
                    self._con(f"hp_{mode}_le", t, p - 1.0 * eta <= 0.0)  # p <= P_max eta
                    self._con(f"hp_{mode}_ge", t, p - 1.0 * eta - m_loose * s >= -m_loose)
                    self.mutable += [(self.c[f"hp_{mode}_le"][t], eta), (self.c[f"hp_{mode}_ge"][t], eta)]
            else:
                for mode, s in (("sh", V["s_sh"][t]), ("dhw", V["s_dhw"][t])):
                    p = V[f"p_hp_{mode}"][t]
                    self._con(f"hp_{mode}_max", t, p - 1.0 * s <= 0.0)
                    self._con(f"hp_{mode}_min", t, p - 1.0 * s >= 0.0)
                    self.mutable += [(self.c[f"hp_{mode}_max"][t], s), (self.c[f"hp_{mode}_min"][t], s)]
        # objective: structure now, price coefficients in update()
        c = k.costs
        obj = pulp.LpAffineExpression()
        for t in range(n):
            obj += k.dt_h * c.sigma_b_ch_eur_per_kwh / W_PER_KW * V["p_ch"][t]
            obj += k.dt_h * c.sigma_b_d_eur_per_kwh / W_PER_KW * V["p_dis"][t]
            obj += k.dt_h * c.sigma_fc_eur_per_h * V["s_fc"][t]
            obj += c.sigma_fc_on_eur * V["s_fc_on"][t] + c.sigma_fc_off_eur * V["s_fc_off"][t]
            obj += k.dt_h * self.pen.comfort_eur_per_kh * (V["sl_t_lo"][t] + V["sl_t_hi"][t])
            obj += k.dt_h * self.pen.dhw_eur_per_lh * (V["sl_v_lo"][t] + V["sl_v_hi"][t])
            obj += k.dt_h * self.pen.soc_eur_per_h * (V["sl_soc_lo"][t] + V["sl_soc_hi"][t])
            obj += k.dt_h * self.pen.loh_eur_per_h * V["sl_loh"][t]
            obj += 1e-9 * V["p_buy"][t] + 1e-9 * V["p_sell"][t]  # placeholders, set by update
            if k.el:
                obj += self.year.sigma_el_on_eur * V["s_el_on"][t]
            if k.year_round:
                obj += k.dt_h * self.year.penalty_loh_season_eur_per_h * V["sl_loh_season"][t]
        if k.year_round:  # value of the H2 left at the horizon's end
            obj += -self.year.h2_value_eur_per_kwh * k.params.hydrogen.e_max_kwh * V["loh"][n - 1]
        self.prob.setObjective(obj)

    # ----------------------------------------------------------------- updating
    def update(self, h: HorizonData) -> None:
        """Set right-hand sides, price and COP / P_max coefficients for horizon ``h``.

        Parameters
        ----------
        h : HorizonData
            The step's horizon numbers (its length must be the model's).

        Raises
        ------
        ValueError
            For a horizon of another length.
        """
        k, V, C, n = self.const, self.v, self.c, self.n
        if h.n != n:
            raise ValueError(f"horizon has {h.n} steps, the model {n}")
        paper = self.formulation == "paper"
        cv = k.l_per_wh * k.dt_h
        obj = self.prob.objective
        x0 = h.x0
        for t in range(n):
            C["balance"][t].changeRHS(float(h.p_load_w[t] - h.p_pv_w[t]))
            C["dhw"][t].changeRHS(float(-cv * (h.q_dhw_dem_w[t] + k.q_dhw_loss_w) + (h.v0_l if t == 0 else 0.0)))
            C["dhw"][t].expr[V["p_hp_dhw"][t]] = -cv * float(h.cop_dhw[t])
            exo = k.bd[:, 1] * h.t_amb_c[t] + k.bd[:, 2] * h.ghi_w_m2[t]
            if k.bd.shape[1] > 3:  # an identified model's internal gains (building.f_gains_air)
                exo = exo + k.bd[:, 3] * h.p_load_w[t]
            if t == 0:
                exo = exo + rowdot(k.ad, x0)
            for i, cname in enumerate(("air", "wall_in", "wall_out")):
                C[cname][t].changeRHS(float(exo[i]))
                C[cname][t].expr[V["p_hp_sh"][t]] = -k.bd[i, 0] * float(h.cop_sh[t])
            C["comfort_lo"][t].changeRHS(float(h.t_min_c[t]))
            C["comfort_hi"][t].changeRHS(float(h.t_max_c[t]))
            C["loh_lo"][t].changeRHS(float(h.loh_min[t]))
            pmax = float(h.p_hp_max_w[t])
            if paper:
                for mode in ("sh", "dhw"):
                    C[f"hp_{mode}_le"][t].expr[V["eta_hp"][t]] = -pmax
                    C[f"hp_{mode}_ge"][t].expr[V["eta_hp"][t]] = -pmax
            else:
                for mode in ("sh", "dhw"):
                    C[f"hp_{mode}_max"][t].expr[V[f"s_{mode}"][t]] = -pmax
                    C[f"hp_{mode}_min"][t].expr[V[f"s_{mode}"][t]] = -k.hp_mod_min * pmax
            for mode in ("sh", "dhw"):
                V[f"p_hp_{mode}"][t].upBound = pmax
            if k.cooling:
                e = float(h.eer[t])
                for i, cname in enumerate(("air", "wall_in", "wall_out")):
                    C[cname][t].expr[V["p_hp_cool"][t]] = k.bd[i, 0] * e
                pc = float(h.p_cool_max_w[t])
                C["hp_cool_max"][t].expr[V["s_cool"][t]] = -pc
                C["hp_cool_min"][t].expr[V["s_cool"][t]] = -k.hp_mod_min * pc
                V["p_hp_cool"][t].upBound = pc
            if k.year_round:
                target = h.loh_season if h.loh_season is not None else np.zeros(n)
                C["loh_season"][t].changeRHS(float(target[t]))
                # outside the heating season the FC spends only H2 above the seasonal target
                V["p_fc"][t].upBound = 0.0 if h.loh0 <= float(target[0]) else k.p_fc_max_w
            # the house exports at most what it generates: with a buy price below the sell price
            # (spot below (p_sell - a) / b = -16 EUR/MWh with the default tariff, which the year's data
            # and winters before 2022 have) buying to sell would otherwise be unbounded. The winter
            # plant gets the bound only in such steps: elsewhere it cannot bind, and a bound that
            # cannot bind still changes HiGHS's path to a solution within the gap (the paper's
            # winter, which has no such step, keeps its plans).
            if k.year_round or float(h.price_buy_eur_per_kwh[t]) < float(h.price_sell_eur_per_kwh):
                V["p_sell"][t].upBound = float(max(h.p_pv_w[t], 0.0)) + k.p_fc_max_w + k.p_d_max_w
            else:
                V["p_sell"][t].upBound = None
            obj[V["p_buy"][t]] = k.dt_h * float(h.price_buy_eur_per_kwh[t]) / W_PER_KW
            obj[V["p_sell"][t]] = -k.dt_h * float(h.price_sell_eur_per_kwh) / W_PER_KW
        C["soc"][0].changeRHS(float(h.soc0))
        C["loh"][0].changeRHS(float(h.loh0))
        fc_prev = 1.0 if h.fc_on_prev else 0.0
        if paper:
            C["fc_on_b"][0].changeRHS(1.0 - fc_prev)
            C["fc_on_c"][0].changeRHS(-fc_prev)
            C["fc_off_a"][0].changeRHS(fc_prev)
            C["fc_off_c"][0].changeRHS(fc_prev)
        else:
            C["fc_switch"][0].changeRHS(-fc_prev)
        if k.el:
            C["el_switch"][0].changeRHS(-(1.0 if h.el_on_prev else 0.0))
        if k.year_round:  # H2 left at the horizon's end: valued outside the heating season only
            outside = h.loh_season is not None and float(np.max(h.loh_season)) > 0.0
            value = self.year.h2_value_eur_per_kwh * k.params.hydrogen.e_max_kwh if outside else 0.0
            obj[V["loh"][n - 1]] = -value
        if self.relax_battery_binary and not paper and not self.two_bat:
            cat = pulp.LpContinuous if h.price_sell_eur_per_kwh >= 0 else pulp.LpInteger  # bounds stay [0, 1]
            for var in V["b_ch"][: self.integer_steps]:
                var.cat = cat

    def binary_names(self) -> list[str]:
        """List the prefixes of the variables that are binary (at least in step 0).

        PuLP stores a binary as category ``LpInteger`` with bounds [0, 1].

        Returns
        -------
        list[str]
            Variable prefixes (``s_fc``, ``b_ch``, ...).
        """
        return [name for name, vars_ in self.v.items() if vars_[0].cat in (pulp.LpInteger, pulp.LpBinary)]

    def fix_first_step(self, values: Mapping[str, float] | None) -> None:
        """Fix the step-0 binaries named in ``values``; ``None`` frees them all again.

        Parameters
        ----------
        values : Mapping[str, float] or None
            Variable prefix -> 0 or 1 (rounded).
        """
        for name in self.binary_names():
            var = self.v[name][0]
            if values is None:
                var.lowBound, var.upBound = 0, 1
            elif name in values:
                val = float(round(values[name]))
                var.lowBound, var.upBound = val, val

    def set_start(self, plan: Mapping[str, np.ndarray] | None) -> None:
        """Set the initial values of a warm start.

        Parameters
        ----------
        plan : Mapping[str, numpy.ndarray] or None
            Variable prefix -> values per step (e.g. :func:`shift_plan` of the last plan);
            None clears them.
        """
        for name, vars_ in self.v.items():
            vals = None if plan is None else plan.get(name)
            for t, var in enumerate(vars_):
                var.varValue = None if vals is None else float(vals[t])

    # ----------------------------------------------------------------- solving
    def solve(self, backend: Any) -> SolveResult:
        """Solve with a backend of :mod:`.solvers`; read the plan if a solution exists.

        The solution is also written into the PuLP variables (``varValue``).

        Parameters
        ----------
        backend : HighsBackend, GurobiBackend or PulpBackend
            The solver backend (:func:`.solvers.make_backend`).

        Returns
        -------
        SolveResult
            Status, plan, objective [EUR], solve time [s] and gap [-].
        """
        t0 = time.perf_counter()
        raw = backend.solve()
        solve_s = time.perf_counter() - t0
        if raw.error:
            self.form.set_values(None)
            return SolveResult(f"Solver error: {raw.error}", False, False, math.nan, solve_s=solve_s)
        status = pulp.LpSolution[raw.sol_status]
        x = raw.x
        if x is None or not np.all(np.isfinite(x)):
            self.form.set_values(None)
            return SolveResult(status, False, False, math.nan, solve_s=solve_s)
        self.form.set_values(x)
        plan = {name: x[cols] for name, cols in self._cols.items()}
        return SolveResult(status, True, raw.sol_status == pulp.LpSolutionOptimal, raw.objective, plan, solve_s,
                           raw.gap)


def shift_plan(plan: Mapping[str, np.ndarray], steps: int = 1) -> dict[str, np.ndarray]:
    """Shift a plan ``steps`` ahead, its last value repeated (the warm start of the next solve).

    Parameters
    ----------
    plan : Mapping[str, numpy.ndarray]
        Variable prefix -> values per horizon step.
    steps : int
        Steps to shift by.

    Returns
    -------
    dict[str, numpy.ndarray]
        The shifted plan (new arrays).
    """
    out = {}
    for name, vals in plan.items():
        vals = np.asarray(vals, dtype=float)
        out[name] = np.concatenate([vals[steps:], np.repeat(vals[-1:], steps)])
    return out
