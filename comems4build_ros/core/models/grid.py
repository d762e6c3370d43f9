"""The grid connection: the house's power balance, ``eq:power_balance``.

    P_PV + P_buy + P_FC + P_d = P_sell + P_load + P_el,HP + P_ch (+ P_EL, the electrolyser)

The residual of the other flows is bought when positive and sold when negative, never both
in one step.
"""

from __future__ import annotations


def exchange(p_load_w: float, p_hp_w: float, p_ch_w: float, p_el_w: float, p_pv_w: float, p_fc_w: float,
             p_dis_w: float) -> tuple[float, float, float]:
    """Power bought and sold, and the balance's residual.

    Parameters
    ----------
    p_load_w, p_hp_w, p_ch_w, p_el_w : demand: appliances, heat pump, battery charging, electrolyser [W]
    p_pv_w, p_fc_w, p_dis_w : supply: PV, fuel cell, battery discharging [W]

    Returns
    -------
    (P_buy [W], P_sell [W], left side minus right side of ``eq:power_balance`` [W])
    """
    net = (p_load_w + p_hp_w + p_ch_w + p_el_w) - (p_pv_w + p_fc_w + p_dis_w)
    if net > 0.0:
        p_buy, p_sell = net, 0.0
    else:
        p_buy, p_sell = 0.0, -net
    residual = (p_pv_w + p_buy + p_fc_w + p_dis_w) - (p_sell + p_load_w + p_hp_w + p_ch_w + p_el_w)
    return p_buy, p_sell, residual
