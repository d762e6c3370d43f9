"""The scenario record: hourly exogenous series of one run."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

#: Columns of a scenario CSV (see docs/scenario.md "Scenario CSV"); order of the written file.
CSV_COLUMNS = (
    "time",
    "t_amb_c",
    "ghi_w_m2",
    "dhi_w_m2",
    "spot_eur_per_mwh",
    "p_load_w",
    "dhw_l_per_h",
)
OPTIONAL_CSV_COLUMNS = ("price_buy_eur_per_kwh",)

#: Array attributes of :class:`Scenario`, all of the same length.
SERIES = (
    "t_amb_c",
    "ghi_w_m2",
    "dhi_w_m2",
    "spot_eur_per_mwh",
    "price_buy_eur_per_kwh",
    "price_sell_eur_per_kwh",
    "p_load_w",
    "dhw_l_per_h",
    "t_min_c",
    "t_max_c",
)


@dataclass
class Scenario:
    """Hourly inputs of a run.

    The arrays may be longer than the run (``n_steps``): the rows after it are the
    look-ahead used for the 24 h price window and forecasts at the end of the run.
    Look-ahead beyond the last row repeats the last row (edge padding).

    Attributes
    ----------
    name : str
        Label (``default`` or the CSV file name).
    time : pandas.DatetimeIndex
        Tz-aware hourly index (local time of the site), start of each step.
    t_amb_c : numpy.ndarray
        Ambient temperature [degC].
    ghi_w_m2, dhi_w_m2 : numpy.ndarray
        Global and diffuse horizontal irradiance [W/m2].
    spot_eur_per_mwh : numpy.ndarray
        Day-ahead spot price [EUR/MWh].
    price_buy_eur_per_kwh : numpy.ndarray
        Buy tariff p_buy (``eq:costs``) [EUR/kWh].
    price_sell_eur_per_kwh : numpy.ndarray
        Sell tariff p_sell [EUR/kWh].
    p_load_w : numpy.ndarray
        Appliance load P_el,load [W].
    dhw_l_per_h : numpy.ndarray
        Hot-water draw at T_DHW [l/h].
    t_min_c, t_max_c : numpy.ndarray
        Comfort bounds (``eq:T_min``) [degC].
    n_steps : int
        Steps of the run, 1 .. ``len(time)``.
    meta : dict
        Free-form provenance (seed, source files, gap fills).

    Raises
    ------
    ValueError
        If a series of :data:`SERIES` does not have the length of ``time`` or ``n_steps``
        is outside 1 .. ``len(time)``.
    """

    name: str
    time: pd.DatetimeIndex
    t_amb_c: np.ndarray
    ghi_w_m2: np.ndarray
    dhi_w_m2: np.ndarray
    spot_eur_per_mwh: np.ndarray
    price_buy_eur_per_kwh: np.ndarray
    price_sell_eur_per_kwh: np.ndarray
    p_load_w: np.ndarray
    dhw_l_per_h: np.ndarray
    t_min_c: np.ndarray
    t_max_c: np.ndarray
    n_steps: int
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Check the lengths and convert every series to a float array."""
        n = len(self.time)
        for name in SERIES:
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (n,):
                raise ValueError(f"scenario '{self.name}': series '{name}' has shape {arr.shape}, expected ({n},)")
            setattr(self, name, arr)
        if not 0 < self.n_steps <= n:
            raise ValueError(f"scenario '{self.name}': n_steps={self.n_steps} outside 1..{n}")

    def window(self, name: str, k: int, length: int) -> np.ndarray:
        """Return ``length`` values of a series from step ``k``, edge-padded at the end.

        Parameters
        ----------
        name : str
            A series of :data:`SERIES`.
        k : int
            First step.
        length : int
            Number of values.

        Returns
        -------
        numpy.ndarray
            The values, in the series' unit; past the last row the last value repeats.
        """
        arr = getattr(self, name)
        end = k + length
        if end <= len(arr):
            return arr[k:end]
        return np.concatenate([arr[k:], np.full(end - len(arr), arr[-1])])
