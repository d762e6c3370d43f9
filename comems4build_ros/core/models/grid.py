"""The grid connection: the house's power balance, ``eq:power_balance``.

    P_PV + P_buy + P_FC + P_d = P_sell + P_load + P_el,HP + P_ch (+ P_EL, the electrolyser)

The residual of the other flows is bought when positive and sold when negative, never both
in one step.
"""

from __future__ import annotations


def exchange(p_load_w: float, p_hp_w: float, p_ch_w: float, p_el_w: float, p_pv_w: float, p_fc_w: float,
             p_dis_w: float) -> tuple[float, float, float]:
    """Balance the house at the grid connection (``eq:power_balance``).

    Parameters
    ----------
    p_load_w, p_hp_w, p_ch_w, p_el_w : float
        Demand: appliances P_el,load, heat pump P_el,HP, battery charging P_ch, electrolyser [W].
    p_pv_w, p_fc_w, p_dis_w : float
        Supply: PV P_PV, fuel cell P_el,FC, battery discharging P_d [W].

    Returns
    -------
    p_buy_w, p_sell_w : float
        Power bought and sold [W] (one of them 0).
    residual_w : float
        Left side minus right side of ``eq:power_balance`` [W] (0 up to rounding).
    """
    net = (p_load_w + p_hp_w + p_ch_w + p_el_w) - (p_pv_w + p_fc_w + p_dis_w)
    if net > 0.0:
        p_buy, p_sell = net, 0.0
    else:
        p_buy, p_sell = 0.0, -net
    residual = (p_pv_w + p_buy + p_fc_w + p_dis_w) - (p_sell + p_load_w + p_hp_w + p_ch_w + p_el_w)
    return p_buy, p_sell, residual
