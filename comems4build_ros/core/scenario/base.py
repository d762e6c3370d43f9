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
    name : label (``default`` or the CSV file name)
    time : tz-aware hourly index (local time of the site), start of each step
    t_amb_c : ambient temperature [degC]
    ghi_w_m2, dhi_w_m2 : global and diffuse horizontal irradiance [W/m2]
    spot_eur_per_mwh : day-ahead spot price [EUR/MWh]
    price_buy_eur_per_kwh : buy tariff [EUR/kWh]
    price_sell_eur_per_kwh : sell tariff [EUR/kWh]
    p_load_w : appliance load [W]
    dhw_l_per_h : hot-water draw at T_DHW [l/h]
    t_min_c, t_max_c : comfort bounds eq:T_min [degC]
    n_steps : steps of the run
    meta : free-form provenance (seed, source files, gap fills)
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
        n = len(self.time)
        for name in SERIES:
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (n,):
                raise ValueError(f"scenario '{self.name}': series '{name}' has shape {arr.shape}, expected ({n},)")
            setattr(self, name, arr)
        if not 0 < self.n_steps <= n:
            raise ValueError(f"scenario '{self.name}': n_steps={self.n_steps} outside 1..{n}")

    def window(self, name: str, k: int, length: int) -> np.ndarray:
        """``length`` values of series ``name`` from step ``k``, edge-padded at the end."""
        arr = getattr(self, name)
        end = k + length
        if end <= len(arr):
            return arr[k:end]
        return np.concatenate([arr[k:], np.full(end - len(arr), arr[-1])])
