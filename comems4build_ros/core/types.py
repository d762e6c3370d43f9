"""Core data records shared by the plant, the controllers, the KPIs and the ROS nodes.

Time convention (the paper's): the action of step ``k`` acts over the hour
``[t_k, t_k + 1 h)``; the state reported for step ``k`` is the state at the *end* of that
hour (``SOC[k]`` in ``eq:batt_soc``); a controller deciding step ``k`` observes the state
of step ``k - 1``. Powers are mean values over the step in W, temperatures in degC,
volumes in litres, SOC and LOH as fractions of their capacity.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

#: Forecast modes of ``--forecast`` (``config/forecast.yaml`` ``mode``): the paper's perfect
#: forecasts, and the forecasts with errors of :mod:`comems4build_ros.core.forecast`.
FORECAST_MODES = ("perfect", "imperfect", "realistic")

#: Heat-pump circuits (``eq:zetas``): off, space heating, domestic hot water; and cooling of
#: the rooms through the underfloor system (reversible heat pump, only where
#: ``cooling.enabled``).
HP_OFF = 0
HP_SH = 1
HP_DHW = 2
HP_COOL = 3


@dataclass(slots=True)
class PlantState:
    """Plant state at the end of a step.

    Attributes
    ----------
    soc : float
        Battery state of charge SOC (``eq:batt_soc``) [-].
    loh : float
        Level of hydrogen LOH, fraction of the store's LHV energy (``eq:LOH``) [-].
    t_air_c, t_wall_in_c, t_wall_out_c : float
        Node temperatures of the building model: room air, inner and outer wall
        (``eq:state_update_bldgs``) [degC].
    v_dhw_l : float
        Usable hot-water volume at T_DHW (``eq:DHW_model``) [l].
    hp_mod : float, default 0.0
        Heat-pump modulation eta_HP applied in the step (``sec:hp``) [-].
    fc_on : bool, default False
        The fuel cell was on in the step (s_FC of ``eq:working_hours``).
    el_on : bool, default False
        The electrolyser was on (producing) in the step.
    """

    soc: float
    loh: float
    t_air_c: float
    t_wall_in_c: float
    t_wall_out_c: float
    v_dhw_l: float
    hp_mod: float = 0.0
    fc_on: bool = False
    el_on: bool = False

    def copy(self) -> PlantState:
        """Return an independent copy of the state.

        Returns
        -------
        PlantState
            A new record with the same field values.
        """
        return PlantState(*(getattr(self, f.name) for f in fields(self)))


@dataclass(slots=True)
class Action:
    """Set-points an EMS sends for one step (any values: the plant clips them).

    Attributes
    ----------
    hp_mod : float, default 0.0
        Heat-pump modulation eta_HP, physically {0} U [mod_min, 1] (``sec:hp``) [-].
    hp_mode : int, default HP_OFF
        Heat-pump circuit (s_SH, s_DHW of ``eq:zetas``): :data:`HP_OFF`, :data:`HP_SH`, :data:`HP_DHW`
        or :data:`HP_COOL`.
    p_fc_w : float, default 0.0
        Requested fuel-cell electrical output, 0 or [P_min, zeta * P_max] (``sec:h2``) [W].
    p_bess_w : float, default 0.0
        Battery power, > 0 charging, < 0 discharging (``eq:batt_soc``) [W].
    p_el_w : float, default 0.0
        Requested electrolyser electrical intake, 0 or [P_EL,min, P_EL,max] [W].
    """

    hp_mod: float = 0.0
    hp_mode: int = HP_OFF
    p_fc_w: float = 0.0
    p_bess_w: float = 0.0
    p_el_w: float = 0.0


@dataclass(slots=True)
class Exogenous:
    """Uncontrolled inputs of one step (mean values over the step).

    Attributes
    ----------
    t_amb_c : float
        Ambient air temperature [degC].
    ghi_w_m2 : float
        Global horizontal irradiance q_s [W/m2].
    p_pv_w : float
        PV AC output (``eq:power_pv``) [W].
    p_load_w : float
        Appliance load P_el,load [W].
    dhw_l_per_h : float
        Hot-water draw at T_DHW [l/h].
    price_buy_eur_per_kwh, price_sell_eur_per_kwh : float
        Buying and selling tariffs (``eq:costs``) [EUR/kWh].
    t_min_c, t_max_c : float
        Comfort bounds (``eq:T_min``) [degC].
    """

    t_amb_c: float
    ghi_w_m2: float
    p_pv_w: float
    p_load_w: float
    dhw_l_per_h: float
    price_buy_eur_per_kwh: float
    price_sell_eur_per_kwh: float
    t_min_c: float
    t_max_c: float


# Bit flags of Flows.clipped: which part of an action the plant had to change.
CLIP_HP_MODE = 1  # unknown hp_mode -> off
CLIP_HP_MOD = 2  # modulation outside {0} U [mod_min, 1] (or NaN)
CLIP_HP_DHW_FULL = 4  # DHW heating reduced so the tank does not overflow
CLIP_FC_RANGE = 8  # FC request outside {0} U [P_min, zeta P_max]
CLIP_FC_H2 = 16  # FC reduced or stopped by the H2 store's lower bound
CLIP_BESS_POWER = 32  # battery power beyond its limits
CLIP_BESS_SOC = 64  # battery power reduced by the SOC bounds
CLIP_NONFINITE = 128  # NaN or inf in the action (treated as 0)
CLIP_EL_RANGE = 256  # EL request outside {0} U [P_EL,min, P_EL,max] (or no EL installed)
CLIP_EL_H2 = 512  # EL reduced or stopped by the H2 store's upper bound


@dataclass(slots=True)
class Flows:
    """Everything that happened in one step (mean powers [W], energies via t_s).

    The power balance ``eq:power_balance`` reads
    ``p_pv_w + p_buy_w + p_fc_w + p_dis_w = p_sell_w + p_load_w + p_hp_el_w + p_ch_w + p_el_w``
    (the electrolyser's intake ``p_el_w`` added to the paper's demand side);
    ``balance_residual_w`` is left side minus right side. In cooling mode ``cop`` is the
    EER and the heat taken from the rooms is ``q_cool_w`` (``q_hp_sh_w`` is 0).

    Attributes
    ----------
    p_pv_w : float
        PV AC output (``eq:power_pv``) [W].
    p_load_w : float
        Appliance load [W].
    p_hp_el_w : float
        Heat-pump electrical intake [W].
    hp_mode : int
        Circuit the heat pump served after clipping (``HP_*``).
    hp_mod : float
        Modulation applied after clipping [-].
    cop : float
        Coefficient of performance of the step (EER in cooling; 0 when off) [-].
    q_hp_sh_w, q_hp_dhw_w : float
        Heat-pump heat to space heating and to the hot-water tank [W].
    p_fc_w : float
        Fuel-cell electrical output [W].
    fc_on, fc_start, fc_stop : bool
        The fuel cell ran in the step, was switched on at its start, was switched off
        (s_FC,on and s_FC,off of ``eq:on_off_logic``).
    p_h2_w : float
        Hydrogen consumed by the fuel cell, LHV power (``eq:molar_flows``) [W].
    eta_fc_el : float
        Fuel-cell electrical efficiency of the step (``eq:efficiency_FC``) [-].
    q_fc_rec_w, q_fc_dump_w : float
        Recovered fuel-cell heat delivered to the hot-water tank, and recoverable heat the
        full tank could not take (``eq:FC_sys_efficiency``, ``eq:DHW_heat``) [W].
    p_ch_w, p_dis_w : float
        Battery charging and discharging power (``eq:batt_soc``) [W].
    p_buy_w, p_sell_w : float
        Power bought from and sold to the grid (``eq:power_balance``) [W].
    q_dhw_demand_w, q_dhw_loss_w, q_dhw_unmet_w : float
        Hot-water draw as heat, the tank's standing loss, and the part of both the tank
        could not serve (``eq:DHW_model``) [W].
    price_buy_eur_per_kwh, price_sell_eur_per_kwh : float
        Tariffs of the step [EUR/kWh].
    balance_residual_w : float
        Left side minus right side of the power balance [W].
    clipped : int
        Bit set of the ``CLIP_*`` flags: what the plant changed in the action.
    p_el_w : float, default 0.0
        Electrolyser intake incl. compression and standby [W].
    el_on, el_start : bool, default False
        The electrolyser produced in the step; it was switched on at its start.
    p_h2_el_w : float, default 0.0
        Hydrogen produced by the electrolyser, LHV power [W].
    q_el_rec_w, q_el_dump_w : float, default 0.0
        Recovered electrolyser heat delivered to the tank, and what the full tank could not
        take [W].
    q_cool_w : float, default 0.0
        Heat taken from the rooms by cooling [W].
    """

    p_pv_w: float
    p_load_w: float
    p_hp_el_w: float
    hp_mode: int
    hp_mod: float
    cop: float
    q_hp_sh_w: float
    q_hp_dhw_w: float
    p_fc_w: float
    fc_on: bool
    fc_start: bool
    fc_stop: bool
    p_h2_w: float  # hydrogen consumed, LHV power [W]
    eta_fc_el: float
    q_fc_rec_w: float  # recovered FC heat delivered to the DHW tank [W]
    q_fc_dump_w: float  # recoverable FC heat the full tank could not take [W]
    p_ch_w: float
    p_dis_w: float
    p_buy_w: float
    p_sell_w: float
    q_dhw_demand_w: float
    q_dhw_loss_w: float
    q_dhw_unmet_w: float
    price_buy_eur_per_kwh: float
    price_sell_eur_per_kwh: float
    balance_residual_w: float
    clipped: int
    p_el_w: float = 0.0  # electrolyser intake incl. compression and standby [W]
    el_on: bool = False
    el_start: bool = False
    p_h2_el_w: float = 0.0  # hydrogen produced, LHV power [W]
    q_el_rec_w: float = 0.0  # recovered EL heat delivered to the DHW tank [W]
    q_el_dump_w: float = 0.0  # recoverable EL heat the full tank could not take [W]
    q_cool_w: float = 0.0  # heat taken from the rooms by cooling [W]

    def as_dict(self) -> dict[str, float]:
        """Return the record as a plain dictionary.

        Returns
        -------
        dict of str to float
            Field name -> value, units as in the attributes.
        """
        return asdict(self)


STATE_FIELDS = tuple(f.name for f in fields(PlantState))
ACTION_FIELDS = tuple(f.name for f in fields(Action))
EXOGENOUS_FIELDS = tuple(f.name for f in fields(Exogenous))
FLOW_FIELDS = tuple(f.name for f in fields(Flows))
#: End-of-step state columns of the timeseries (hp_mod and fc_on come with the flows).
STATE_COLUMNS = ("soc", "loh", "t_air_c", "t_wall_in_c", "t_wall_out_c", "v_dhw_l")
