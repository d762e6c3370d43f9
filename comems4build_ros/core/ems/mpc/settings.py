"""Options of the MPC controllers (``config/mpc.yaml``) and the lifecycle costs.

The options are read from the ``mpc`` (MILP) or ``mpc_qp`` (OSQP) section of
``config/mpc.yaml`` merged over its ``/**`` section, then overridden by the mapping passed
to the controller constructor, and validated; a bad value raises
:class:`~comems4build_ros.core.config.ConfigError` naming the source and the option.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import Field

from comems4build_ros.core.config import (
    W_PER_KW,
    ConfigError,
    Phys,
    PlantParams,
    Section,
    config_dir,
    read_ros_params,
    validate,
)

#: Shortest time limit of one solve [s]: below the solve time of the 24-h horizon (median 33 ms on a
#: quiet machine, docs/mpc.md), no solve finishes and the MPC decides nothing.
MIN_SOLVE_S = 0.1
SOLVE_WHY = "the 24-h horizon's solves take a median 33 ms on a quiet machine (docs/mpc.md); less decides nothing"


class _MPCParams(Section):
    loh_min_mode: Literal["day", "step"] = "day"
    fc_lifecycle_eta: Literal["eta_el_mpc", "eta_sys", "one"] = "one"
    fc_heat_dump: bool = False
    penalty_comfort_eur_per_kh: float = Field(default=100.0, gt=0)
    penalty_dhw_eur_per_lh: float = Field(default=1.0, gt=0)
    penalty_soc_eur_per_h: float = Field(default=1000.0, gt=0)
    penalty_loh_eur_per_h: float = Field(default=10000.0, gt=0)
    slack_report_tol: float = Field(default=1e-4, gt=0)


class MILPParams(_MPCParams):
    """Options of the MILP controller (``mpc`` section)."""

    solver: Literal["highs", "highs_pulp", "cbc", "gurobi"] = "highs"
    mip_rel_gap: float = Field(default=0.005, ge=0, lt=1)
    time_limit_s: float = Phys(MIN_SOLVE_S, 86400.0, SOLVE_WHY, default=10.0)
    threads: int = Field(default=1, ge=1)
    warm_start: bool = True
    formulation: Literal["tight", "paper"] = "tight"
    integer_steps: int = Field(default=24, ge=1)
    relax_battery_binary: bool = False
    big_m_loose_w: float = Field(default=1e5, gt=0)
    log_fallback: bool = True
    highs_options: dict[str, bool | int | float | str] = Field(default_factory=dict)
    gurobi_options: dict[str, bool | int | float | str] = Field(default_factory=dict)
    # year-round plant (electrolyser, cooling): the seasonal target of the store
    loh_season_target: float = Field(default=0.9, ge=0, le=1)
    penalty_loh_season_eur_per_h: float = Field(default=5.0, ge=0)
    h2_value_eur_per_kwh: float = Field(default=0.15, ge=0)
    sigma_el_on_eur: float = Field(default=0.04, ge=0)
    # the building's wall nodes: read from the plant (the paper) or estimated from T_air (a detailed building)
    observer: Literal["measured", "kalman"] = "measured"


class QPParams(_MPCParams):
    """Options of the OSQP controller (``mpc_qp`` section)."""

    w_fc_smooth_eur_per_kw2: float = Field(default=0.05, ge=0)
    w_comfort_track_eur_per_k2: float = Field(default=0.02, ge=0)
    comfort_margin_k: float = Field(default=0.3, ge=0)
    w_reg_eur_per_kw2: float = Field(default=1e-2, gt=0)
    eps_abs: float = Field(default=1e-3, gt=0)
    eps_rel: float = Field(default=1e-3, gt=0)
    max_iter: int = Field(default=20000, gt=0)
    polish: bool = True
    time_limit_s: float = Phys(MIN_SOLVE_S, 86400.0, SOLVE_WHY, default=5.0)


def default_mpc_file() -> Path:
    """Path of the default ``config/mpc.yaml``."""
    return config_dir() / "mpc.yaml"


def load_options(
    model: type[_MPCParams], section: str, options: Mapping[str, Any] | None, path: str | Path | None = None
) -> _MPCParams:
    """Read ``section`` of ``config/mpc.yaml`` (or ``path``), apply ``options``, validate.

    ``options`` may hold a ``config`` key naming another parameter file to read instead.
    """
    opts = dict(options or {})
    path = Path(opts.pop("config", None) or path or default_mpc_file())
    data = read_ros_params(path, node=section)
    data.update(opts)
    source = f"{path} [{section}]" + (" + options" if opts else "")
    return validate(model, data, source)


@dataclass(frozen=True)
class LifecycleCosts:
    """Utilisation costs of eq:batt_andFC_operation_degradation (tab:degradation_HESS).

    Attributes
    ----------
    sigma_b_ch_eur_per_kwh, sigma_b_d_eur_per_kwh : battery cost per kWh charged / discharged [EUR/kWh]
    sigma_fc_eur_per_h : FC cost per operating hour [EUR/h]
    sigma_fc_on_eur, sigma_fc_off_eur : cost of one FC start / stop [EUR]
    l_b_ch_h, l_b_d_h : battery lifespans of eq:batt_lifecycle [h]
    """

    sigma_b_ch_eur_per_kwh: float
    sigma_b_d_eur_per_kwh: float
    sigma_fc_eur_per_h: float
    sigma_fc_on_eur: float
    sigma_fc_off_eur: float
    l_b_ch_h: float
    l_b_d_h: float


def lifecycle_costs(params: PlantParams, fc_eta: str = "eta_el_mpc") -> LifecycleCosts:
    """Lifecycle costs from eq:batt_andFC_operation_degradation and eq:batt_lifecycle.

    ``sigma_i = (sigma_in,i / L_i + sigma_om,i) / eta_i`` [EUR/h at rated power]; for the
    battery ``L_B = E_max / P_i * N_B`` [h], so per kWh moved
    ``sigma_B,i = (sigma_in,B / (E_max N_B) + sigma_om,B / P_i) / eta_i`` [EUR/kWh].
    For the FC ``sigma_FC = (sigma_in,FC / L_FC + sigma_om,FC) / eta_FC`` [EUR/h] with
    ``eta_FC`` chosen by ``fc_eta`` (``eta_el_mpc``, ``eta_sys`` or ``one``).
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
