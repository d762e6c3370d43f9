"""The lifecycle costs of the battery and the fuel cell in the MPC's objective (``eq:mpc_objective``).

The MPC's options are :class:`~comems4build_ros.core.ems.settings.MILPSettings` and
:class:`~comems4build_ros.core.ems.settings.QPSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass

from comems4build_ros.core.config import W_PER_KW, ConfigError, PlantParams


@dataclass(frozen=True)
class LifecycleCosts:
    """Utilisation costs of ``eq:batt_andFC_operation_degradation`` (``tab:degradation_HESS``).

    Attributes
    ----------
    sigma_b_ch_eur_per_kwh, sigma_b_d_eur_per_kwh : float
        Battery cost per kWh charged / discharged [EUR/kWh].
    sigma_fc_eur_per_h : float
        FC cost per operating hour [EUR/h].
    sigma_fc_on_eur, sigma_fc_off_eur : float
        Cost of one FC start / stop [EUR].
    l_b_ch_h, l_b_d_h : float
        Battery lifespans of ``eq:batt_lifecycle`` [h].
    """

    sigma_b_ch_eur_per_kwh: float
    sigma_b_d_eur_per_kwh: float
    sigma_fc_eur_per_h: float
    sigma_fc_on_eur: float
    sigma_fc_off_eur: float
    l_b_ch_h: float
    l_b_d_h: float


def lifecycle_costs(params: PlantParams, fc_eta: str = "eta_el_mpc") -> LifecycleCosts:
    """Compute the lifecycle costs of ``eq:batt_andFC_operation_degradation`` and ``eq:batt_lifecycle``.

    ``sigma_i = (sigma_in,i / L_i + sigma_om,i) / eta_i`` [EUR/h at rated power]; for the
    battery ``L_B = E_max / P_i * N_B`` [h], so per kWh moved
    ``sigma_B,i = (sigma_in,B / (E_max N_B) + sigma_om,B / P_i) / eta_i`` [EUR/kWh].
    For the FC ``sigma_FC = (sigma_in,FC / L_FC + sigma_om,FC) / eta_FC`` [EUR/h].

    Parameters
    ----------
    params : PlantParams
        Plant parameters (battery, fuel cell and the ``degradation`` section,
        ``tab:degradation_HESS``).
    fc_eta : {"eta_el_mpc", "eta_sys", "one"}
        The FC efficiency eta_FC dividing its cost.

    Returns
    -------
    LifecycleCosts
        The costs.

    Raises
    ------
    ConfigError
        For an unknown ``fc_eta``.
    """
    b, d, fc = params.battery, params.degradation, params.fuel_cell
    if fc_eta not in ("eta_el_mpc", "eta_sys", "one"):
        raise ConfigError(f"fc_lifecycle_eta: unknown value '{fc_eta}' (eta_el_mpc, eta_sys, one)")

    def per_kwh(p_max_w: float, eta: float) -> tuple[float, float]:
        if p_max_w <= 0:
            return 0.0, float("inf")
        p_kw = p_max_w / W_PER_KW
        life_h = b.e_max_kwh / p_kw * d.n_b_cycles  # eq:batt_lifecycle
        sigma_per_h = (d.sigma_in_b_eur / life_h + d.sigma_om_b_eur_per_h) / eta  # at rated power
        return sigma_per_h / p_kw, life_h

    s_ch, l_ch = per_kwh(b.p_ch_max_w, b.eta_ch)
    s_d, l_d = per_kwh(b.p_d_max_w, b.eta_d)
    eta_fc = {"eta_el_mpc": fc.eta_el_mpc, "eta_sys": fc.eta_sys, "one": 1.0}[fc_eta]
    s_fc = (d.sigma_in_fc_eur / d.l_fc_h + d.sigma_om_fc_eur_per_h) / eta_fc
    return LifecycleCosts(s_ch, s_d, s_fc, d.sigma_fc_on_eur, d.sigma_fc_off_eur, l_ch, l_d)
