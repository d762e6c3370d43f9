"""The EMS interface: what a controller may observe, and the protocol it implements.

``tab:level_of_information`` of the paper fixes which inputs each scheduler may use. An
:class:`Observation` carries only the fields of its controller's information level;
reading any other field raises :class:`InformationError`, so a controller that uses an
input it is not allowed to see fails loudly (in-process and in the ROS nodes alike, since
the nodes subscribe only to the topics of their level).

Observation fields (units in the names; state values are those at the end of the
previous step, i.e. ``x[k-1]``; ``*_24h`` tuples start at the current step ``k``):

Common to every level ("measured" by any EMS):
    step, day_index, hour_of_day, weekday (0 = Monday), is_weekend (weekend or holiday),
    t_air_c, v_dhw_l, soc, loh, hp_mod_prev,
    p_pv_w, p_load_w (current measured PV output and appliance load),
    t_min_c, t_max_c (current comfort bounds),
    price_buy_eur_per_kwh, price_sell_eur_per_kwh (current tariffs),
    prices_buy_24h (day-ahead buy prices k .. k+23, not a forecast: published in advance)
Fuzzy (ComEMS4Build) adds:
    t_min_5h_c (lower bounds k .. k+5), ghi_w_m2 (current radiation),
    dloh_per_day (eq:deltaLOH, fraction of the store per day), fc_on_prev,
    and, for the electrolyser of a year-round plant (not in the paper's table):
    el_on_prev (the electrolyser produced in step k-1, as s_on/off of the FC),
    days_to_heating_season (days from step k to the next heating season, 0 inside it),
    heating_season_days_left (days left in the heating season, 0 outside it); both are
    calendar figures of ``simulation.heating_season_start/end``
MPC adds:
    t_amb_c (current), t_wall_in_c, t_wall_out_c (model states),
    forecast: mapping of 24-step tuples starting at k with keys t_amb_c, ghi_w_m2,
    p_pv_w, p_load_w, dhw_l_per_h, t_min_c, t_max_c, price_buy_eur_per_kwh
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

from comems4build_ros.core.config import ConfigError
from comems4build_ros.core.types import Action

#: Steps shown in the price window and forecasts (h at 1 h steps), ``eq:EDF_prices``.
PRICE_WINDOW = 24
#: Comfort look-ahead of ComEMS4Build, ``eq:s_sh`` (k .. k+5).
BOUNDS_AHEAD = 5


def check_mpc_horizon(horizon_h: float, time_step_h: float) -> None:
    """Refuse a plant ``simulation.horizon_h`` other than the :data:`PRICE_WINDOW` steps a run's observation carries.

    The loop (in-process or the ROS feed) gives the MPC level :data:`PRICE_WINDOW` steps of
    day-ahead prices and forecasts, over which the MPC plans (``sec:MPC``: a 24 h horizon);
    another horizon would stop the run at its first step.

    Parameters
    ----------
    horizon_h : float
        The plant's ``simulation.horizon_h`` [h].
    time_step_h : float
        The plant's ``simulation.time_step_h`` [h].

    Raises
    ------
    ValueError
        Naming the parameter and the horizon it must be.
    """
    if round(horizon_h / time_step_h) != PRICE_WINDOW:
        raise ConfigError(f"plant parameter simulation.horizon_h = {horizon_h:g}: a run's observation carries "
                         f"{PRICE_WINDOW} steps of day-ahead prices and forecasts, the MPC's horizon (sec:MPC); it "
                         f"must be {PRICE_WINDOW * time_step_h:g} h")

COMMON_FIELDS = frozenset(
    {
        "step",
        "day_index",
        "hour_of_day",
        "weekday",
        "is_weekend",
        "t_air_c",
        "v_dhw_l",
        "soc",
        "loh",
        "hp_mod_prev",
        "p_pv_w",
        "p_load_w",
        "t_min_c",
        "t_max_c",
        "price_buy_eur_per_kwh",
        "price_sell_eur_per_kwh",
        "prices_buy_24h",
    }
)
FUZZY_FIELDS = COMMON_FIELDS | {"t_min_5h_c", "ghi_w_m2", "dloh_per_day", "fc_on_prev", "el_on_prev",
                                "days_to_heating_season", "heating_season_days_left"}
MPC_FIELDS = FUZZY_FIELDS | {"t_amb_c", "t_wall_in_c", "t_wall_out_c", "forecast"}

#: Information level name -> fields it may read (tab:level_of_information).
INFO_LEVELS: dict[str, frozenset[str]] = {
    "basic": COMMON_FIELDS,  # RBC and thermostat
    "fuzzy": FUZZY_FIELDS,
    "mpc": MPC_FIELDS,
}

#: Keys of the MPC forecast mapping.
FORECAST_KEYS = (
    "t_amb_c",
    "ghi_w_m2",
    "p_pv_w",
    "p_load_w",
    "dhw_l_per_h",
    "t_min_c",
    "t_max_c",
    "price_buy_eur_per_kwh",
)


class InformationError(AttributeError):
    """A controller read an input its information level does not include."""


class Observation:
    """Read-only view of the inputs one controller may use for one step.

    Parameters
    ----------
    level : str
        Information level name (a key of :data:`INFO_LEVELS`, ``tab:level_of_information``).
    data : Mapping[str, Any]
        Field -> value (units in the field names, see the module docstring); must contain
        every field of the level (extra fields are dropped, missing ones raise ``ValueError``).

    Raises
    ------
    ValueError
        For an unknown level or a missing field.
    """

    __slots__ = ("_level", "_data")

    def __init__(self, level: str, data: Mapping[str, Any]) -> None:
        try:
            allowed = INFO_LEVELS[level]
        except KeyError:
            raise ValueError(f"unknown information level '{level}' (known: {', '.join(INFO_LEVELS)})") from None
        missing = allowed.difference(data)
        if missing:
            raise ValueError(f"observation for level '{level}' lacks: {', '.join(sorted(missing))}")
        object.__setattr__(self, "_level", level)
        object.__setattr__(self, "_data", {k: data[k] for k in allowed})

    def __getattr__(self, name: str) -> Any:
        """Return the field ``name``; :class:`InformationError` if the level does not include it."""
        data = object.__getattribute__(self, "_data")
        try:
            return data[name]
        except KeyError:
            level = object.__getattribute__(self, "_level")
            raise InformationError(
                f"input '{name}' is not available to a controller of information level "
                f"'{level}' (tab:level_of_information)"
            ) from None

    def __setattr__(self, name: str, value: Any) -> None:
        """Refuse every assignment (an observation is read-only)."""
        raise AttributeError("Observation is read-only")

    @property
    def level(self) -> str:
        """Information level name."""
        return object.__getattribute__(self, "_level")

    def as_dict(self) -> dict[str, Any]:
        """Copy the fields.

        Returns
        -------
        dict[str, Any]
            Field -> value, a new dict.
        """
        return dict(object.__getattribute__(self, "_data"))


@runtime_checkable
class Controller(Protocol):
    """An EMS: observation in, action out.

    Implementations set ``name``, ``info_level`` and ``settings_class`` (their
    :class:`~comems4build_ros.core.ems.settings.ControllerSettings`) as class attributes and
    are built as ``Cls(params, options)`` with the checked :class:`~..config.PlantParams` and
    their options mapping (``--ems-option KEY=VALUE`` as parsed, may be empty), which they
    apply over their settings file with :func:`~comems4build_ros.core.ems.settings.load_settings`.
    """

    name: str
    info_level: str
    settings_class: type

    def reset(self) -> None:
        """Forget internal memory before a new run."""

    def act(self, obs: Observation) -> Action:
        """Decide the step described by ``obs``.

        Parameters
        ----------
        obs : Observation
            The inputs of the controller's information level for step k.

        Returns
        -------
        Action
            The set-points of step k (the plant clips what its devices cannot do).
        """
