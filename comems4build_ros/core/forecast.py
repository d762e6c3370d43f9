"""Forecasts with the errors a household MPC meets: ``--forecast realistic``.

The paper's MPC sees perfect forecasts (``sec:MPC``, ``tab:level_of_information``); its
conclusion (``sec:conclusion``) names imperfect forecasts as future work. This module builds
the 24-step forecasts of the ``realistic`` mode from the scenario's true series, with errors
of the kind and size published for day-ahead forecasts (every parameter's source is beside
it in ``config/forecast.yaml``):

* **Prices as published.** The next day's day-ahead prices are known only from the
  publication time of the day-ahead auction (EPEX SPOT: order book closed at 12:00,
  final results from 12:55 market time). Before it the horizon's hours of the next day
  are a forecast: the standard naive benchmark of electricity price forecasting (same hour
  of the previous day for Tuesday to Friday, of the same weekday a week earlier for
  Saturday to Monday), which uses only published prices.
* **Ambient temperature.** The error is a first-order autoregressive process over the lead
  hours (lead 0 is measured and exact):
  ``e_1 = m_1 + s_1 w_0``, ``e_(l+1) = phi e_l + m + s w_l`` with standard normal ``w``.
* **Global irradiance** (and the PV power, which follows it). Two errors: a day-level
  miss, in which with probability ``p`` the forecast shows another day's weather for the
  whole target day (the global irradiance and PV power of a day up to ``W`` days away, at
  the same hour: "forecast sun, got fog" and the reverse), and an hour-level relative error
  ``f = max(0, 1 + e)``, ``e`` a stationary AR(1) over the lead hours with standard
  deviation ``sigma`` and lag-1 correlation ``phi``. The night stays dark (the factor
  multiplies the base value, which is zero at night), so the sun's timing is kept.
* Appliance load and hot-water draw: persistence (the value 24 h earlier), as
  ``imperfect``. Comfort bounds are user-defined and exact.

Every random draw comes from a generator seeded with the forecast seed and the absolute
time (the epoch second of the issuing step; the calendar date for a day-level miss), so a
forecast depends on neither the run's start nor its length nor the call order: the
in-process loop and the ROS feed node (which builds the same
:class:`~comems4build_ros.core.loop.ObservationBuilder`) hand the MPC identical forecasts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from pydantic import Field, field_validator

from comems4build_ros.core.config import Section, known_timezone

#: Price forecast methods beyond the published horizon.
PRICE_METHODS = ("naive", "previous_day", "previous_week")
#: Weekdays (Monday = 0) whose naive price forecast is the same weekday a week earlier.
WEEKLY_NAIVE_DAYS = (0, 5, 6)
#: Seconds per hour.
SECONDS_PER_HOUR = 3600.0


class RealisticParams(Section):
    """Settings of the ``realistic`` forecasts (``forecast.realistic`` in ``config/forecast.yaml``).

    Attributes
    ----------
    price_publication_time : market time ``HH:MM`` from which the next day's day-ahead prices are known
    price_market_timezone : time zone of the market's clock (IANA name)
    price_forecast : forecast of unpublished prices: ``naive``, ``previous_day`` or ``previous_week``
    t_amb_mean_lead1_k, t_amb_sd_lead1_k : mean and standard deviation of the error at lead 1 [K]
    t_amb_phi : lag-1 autocorrelation coefficient of the AR(1) over lead hours [-]
    t_amb_mean_innovation_k, t_amb_sd_innovation_k : mean and standard deviation of its innovation [K]
    ghi_miss_probability : probability that a target day is forecast with another day's weather [-]
    ghi_miss_window_days : the other day lies at most this many days away [d]
    ghi_sd_rel : standard deviation of the hour-level relative error [-]
    ghi_phi : lag-1 autocorrelation of the hour-level relative error over lead hours [-]
    """

    price_publication_time: str = Field(pattern=r"^([01]\d|2[0-3]):[0-5]\d$")
    price_market_timezone: str = Field(min_length=1)
    price_forecast: str = Field(pattern="^(" + "|".join(PRICE_METHODS) + ")$")
    t_amb_mean_lead1_k: float = Field(ge=-10, le=10)
    t_amb_sd_lead1_k: float = Field(ge=0, le=20)
    t_amb_phi: float = Field(ge=0, lt=1)
    t_amb_mean_innovation_k: float = Field(ge=-10, le=10)
    t_amb_sd_innovation_k: float = Field(ge=0, le=20)
    ghi_miss_probability: float = Field(ge=0, le=1)
    ghi_miss_window_days: int = Field(ge=1, le=366)
    ghi_sd_rel: float = Field(ge=0, le=5)
    ghi_phi: float = Field(ge=0, lt=1)

    @field_validator("price_market_timezone")
    @classmethod
    def _known_zone(cls, value: str) -> str:
        return known_timezone(value)


def t_amb_error_moments(p: RealisticParams, leads: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation [K] of the temperature error at leads ``0 .. leads-1`` (lead 0: 0).

    From the AR(1) recursion: ``mean_(l+1) = phi mean_l + m``,
    ``var_(l+1) = phi^2 var_l + s^2``, starting at lead 1 with ``m_1`` and ``s_1^2``.
    """
    mean = np.zeros(leads)
    var = np.zeros(leads)
    for lead in range(1, leads):
        if lead == 1:
            mean[1], var[1] = p.t_amb_mean_lead1_k, p.t_amb_sd_lead1_k**2
        else:
            mean[lead] = p.t_amb_phi * mean[lead - 1] + p.t_amb_mean_innovation_k
            var[lead] = p.t_amb_phi**2 * var[lead - 1] + p.t_amb_sd_innovation_k**2
    return mean, np.sqrt(var)


def _market_clock(times: pd.DatetimeIndex, tz: str) -> pd.DatetimeIndex:
    """Wall-clock times (naive) of ``times`` in the market's time zone ``tz``."""
    try:
        return times.tz_convert(tz).tz_localize(None)
    except Exception as exc:  # an unknown zone name: pandas raises several types
        raise ValueError(f"forecast.realistic.price_market_timezone: unknown time zone '{tz}' ({exc})") from None


def published_until(times: pd.DatetimeIndex, publication: str, tz: str) -> np.ndarray:
    """For each step, the index of the first step whose day-ahead price is not yet published.

    A step at market time ``t`` on day ``D`` knows the prices of ``D`` (published the day
    before) and, from the publication time on, those of ``D + 1``. Steps are identified by
    their start; a step starting exactly at the publication time knows the next day.

    Parameters
    ----------
    times : tz-aware start of each step (the whole padded series)
    publication : ``HH:MM`` market time of the publication
    tz : the market's time zone
    """
    wall = _market_clock(times, tz)
    hour, minute = (int(x) for x in publication.split(":"))
    day = wall.normalize()
    published = wall >= day + pd.Timedelta(hours=hour, minutes=minute)
    end = day + pd.to_timedelta(np.where(published, 2, 1), unit="D")
    return np.searchsorted(wall.to_numpy(), end.to_numpy(), side="left")


def price_sources(times: pd.DatetimeIndex, method: str, tz: str, steps_per_day: int) -> np.ndarray:
    """For each step, the step whose price forecasts it once it is beyond the published horizon.

    ``naive``: the same hour of the previous day for Tuesday to Friday and of the same
    weekday a week earlier for Saturday to Monday (market days); ``previous_day`` and
    ``previous_week`` use one of the two for every day. A source before the first step falls
    back to the previous day, then to the first step.
    """
    weekday = _market_clock(times, tz).day_of_week.to_numpy()
    idx = np.arange(len(times))
    if method == "previous_day":
        weekly = np.zeros(len(times), dtype=bool)
    elif method == "previous_week":
        weekly = np.ones(len(times), dtype=bool)
    elif method == "naive":
        weekly = np.isin(weekday, WEEKLY_NAIVE_DAYS)
    else:
        raise ValueError(f"forecast.realistic.price_forecast: unknown method '{method}' ({', '.join(PRICE_METHODS)})")
    src = np.where(weekly, idx - 7 * steps_per_day, idx - steps_per_day)
    src = np.where(src < 0, idx - steps_per_day, src)
    return np.maximum(src, 0)


def miss_days(days: Sequence[int], p: RealisticParams, seed: int) -> dict[int, int]:
    """Target days (date ordinals) forecast with another day's weather: day -> the other day.

    Each day draws from its own generator (seed, date), so whether a day is missed does not
    depend on which days the run holds; the other day is drawn ``1 .. W`` days before or
    after among the days present (mirrored when it falls outside them).
    """
    present = set(days)
    out: dict[int, int] = {}
    for d in sorted(present):
        rng = np.random.default_rng([seed, 1, d])
        u, offset, sign = rng.random(), int(rng.integers(1, p.ghi_miss_window_days + 1)), rng.random() < 0.5
        if u >= p.ghi_miss_probability:
            continue
        for other in ((d - offset, d + offset) if sign else (d + offset, d - offset)):
            if other in present:
                out[d] = other
                break
    return out


class RealisticForecast:
    """The ``realistic`` forecasts of one scenario (see the module's description).

    Parameters
    ----------
    series : the padded true series by :data:`~comems4build_ros.core.ems.base.FORECAST_KEYS`
    params : the mode's settings
    seed : the forecast seed (``forecast.seed``)
    times : tz-aware start of the scenario's steps (extended hourly to the series' length)
    steps_per_day : steps of one day
    horizon : steps of one forecast window
    """

    def __init__(self, series: Mapping[str, Sequence[float]], params: RealisticParams, seed: int,
                 times: pd.DatetimeIndex, steps_per_day: int, horizon: int) -> None:
        self._s = {k: np.asarray(v, dtype=float) for k, v in series.items()}
        self._p = params
        self._seed = int(seed)
        self._day = int(steps_per_day)
        self._h = int(horizon)
        n = len(self._s["price_buy_eur_per_kwh"])
        self.times = extend_times(times, n)
        self._epoch_s = (self.times.asi8 // 1_000_000_000).astype(np.int64)
        self.known_until = published_until(self.times, params.price_publication_time, params.price_market_timezone)
        self.price_source = price_sources(self.times, params.price_forecast, params.price_market_timezone, self._day)
        ordinals = np.array([d.toordinal() for d in self.times.date])  # local dates of the site
        self.day_of_step = ordinals
        self.missed = miss_days(sorted(set(ordinals.tolist())), params, self._seed)
        self._base_ghi, self._base_pv = self._irradiance_base()

    def _irradiance_base(self) -> tuple[np.ndarray, np.ndarray]:
        """GHI and PV power the forecast starts from: the true ones, another day's on a missed day."""
        ghi, pv = self._s["ghi_w_m2"].copy(), self._s["p_pv_w"].copy()
        n = len(ghi)
        for d, other in self.missed.items():
            steps = np.flatnonzero(self.day_of_step == d)
            src = np.clip(steps + (other - d) * self._day, 0, n - 1)
            ghi[steps] = self._s["ghi_w_m2"][src]
            pv[steps] = self._s["p_pv_w"][src]
        return ghi, pv

    def _rng(self, k: int) -> np.random.Generator:
        return np.random.default_rng([self._seed, 0, int(self._epoch_s[k]) % (2**63)])

    def t_amb_error(self, k: int) -> np.ndarray:
        """Return the temperature error [K] of the window issued at step ``k`` (lead 0: 0)."""
        p = self._p
        w = self._rng(k).standard_normal((2, self._h))[0]
        e = np.zeros(self._h)
        if self._h > 1:
            e[1] = p.t_amb_mean_lead1_k + p.t_amb_sd_lead1_k * w[1]
        for lead in range(2, self._h):
            e[lead] = p.t_amb_phi * e[lead - 1] + p.t_amb_mean_innovation_k + p.t_amb_sd_innovation_k * w[lead]
        return e

    def ghi_error(self, k: int) -> np.ndarray:
        """Return the hour-level relative irradiance error of the window issued at step ``k`` (lead 0: 0)."""
        p = self._p
        w = self._rng(k).standard_normal((2, self._h))[1]
        e = np.zeros(self._h)
        if self._h > 1:
            e[1] = p.ghi_sd_rel * w[1]
        innovation = p.ghi_sd_rel * math.sqrt(1.0 - p.ghi_phi**2)
        for lead in range(2, self._h):
            e[lead] = p.ghi_phi * e[lead - 1] + innovation * w[lead]
        return e

    def prices(self, k: int) -> np.ndarray:
        """Buy prices of the window issued at step ``k``: published ones, the forecast beyond them."""
        true = self._s["price_buy_eur_per_kwh"]
        out = true[k : k + self._h].copy()
        known = int(self.known_until[k])
        for i in range(max(known - k, 0), self._h):
            src = int(self.price_source[k + i])
            while src >= known and src > 0:  # a source not yet published: forecast it the same way
                src = int(self.price_source[src])
            out[i] = true[min(src, known - 1)] if known > 0 else true[k]
        return out

    def window(self, k: int) -> dict[str, tuple[float, ...]]:
        """Forecast of every key for steps ``k .. k+horizon-1`` (lead 0 exact)."""
        s, h, day = self._s, self._h, self._day
        out: dict[str, Any] = {key: s[key][k : k + h] for key in s}
        for key in ("p_load_w", "dhw_l_per_h"):
            vals = s[key]
            out[key] = np.array([vals[k]] + [vals[max(k + i - day, 0)] for i in range(1, h)])
        out["t_amb_c"] = s["t_amb_c"][k : k + h] + self.t_amb_error(k)
        factor = np.maximum(1.0 + self.ghi_error(k), 0.0)
        for key, base in (("ghi_w_m2", self._base_ghi), ("p_pv_w", self._base_pv)):
            f = base[k : k + h] * factor
            f[0] = s[key][k]
            out[key] = f
        out["price_buy_eur_per_kwh"] = self.prices(k)
        return {key: tuple(float(x) for x in v) for key, v in out.items()}


def extend_times(times: pd.DatetimeIndex, n: int) -> pd.DatetimeIndex:
    """Continue ``times`` at its step (one hour if it has a single entry) to ``n`` entries."""
    times = pd.DatetimeIndex(times)
    if len(times) >= n:
        return times[:n]
    step = times[1] - times[0] if len(times) > 1 else pd.Timedelta(hours=1)
    more = pd.date_range(times[-1] + step, periods=n - len(times), freq=step, tz=times.tz)
    return times.append(more)


def error_statistics(window: Any, series: Mapping[str, Sequence[float]], steps: int,
                     steps_per_day: int, horizon: int, known_until: Sequence[int] | None = None) -> dict[str, float]:
    """Return what the forecasts of a run got wrong, over its ``steps`` issuing steps.

    Parameters
    ----------
    window : ``window(k)`` of a forecast model
    series : the padded true series
    steps, steps_per_day, horizon : issuing steps, steps per day and window length
    known_until : per step, the first step whose price is not published (None: every price is)

    Returns
    -------
    dict
        ``t_amb_rmse_k_lead1`` and ``t_amb_rmse_k_lead_last`` [K], ``t_amb_lag1_corr`` (of the
        errors at consecutive leads, pooled) [-], ``ghi_rrmse`` (RMSE over daylight hours at
        leads >= 1 relative to their mean true GHI) [-], ``ghi_skill_vs_persistence``
        (1 - RMSE / RMSE of the same hour one day earlier) [-], ``price_unpublished_share``
        (share of the window's hours, leads >= 1, whose price was not yet published) [-] and
        ``price_mae_eur_per_kwh`` (mean absolute error of the buy price over those hours) [EUR/kWh].
    """
    true = {k: np.asarray(v, dtype=float) for k, v in series.items()}
    t_err, g_err, g_true, g_pers, p_diff, p_unknown = [], [], [], [], [], []
    for k in range(steps):
        w = window(k)
        sl = slice(k, k + horizon)
        t_err.append(np.asarray(w["t_amb_c"]) - true["t_amb_c"][sl])
        g = np.asarray(w["ghi_w_m2"])[1:]
        gt = true["ghi_w_m2"][k + 1 : k + horizon]
        gp = true["ghi_w_m2"][np.maximum(np.arange(k + 1, k + horizon) - steps_per_day, 0)]
        lit = (gt > 0) | (g > 0) | (gp > 0)
        g_err.append((g - gt)[lit])
        g_true.append(gt[lit])
        g_pers.append((gp - gt)[lit])
        p_diff.append(np.asarray(w["price_buy_eur_per_kwh"])[1:] - true["price_buy_eur_per_kwh"][k + 1 : k + horizon])
        lead_step = np.arange(k + 1, k + horizon)
        p_unknown.append(lead_step >= known_until[k] if known_until is not None else np.zeros(horizon - 1, bool))
    te = np.array(t_err)
    ge, gt_all, gp_all = np.concatenate(g_err), np.concatenate(g_true), np.concatenate(g_pers)
    pd_all, unknown = np.concatenate(p_diff), np.concatenate(p_unknown)
    rmse = float(np.sqrt(np.mean(ge**2))) if ge.size else 0.0
    rmse_p = float(np.sqrt(np.mean(gp_all**2))) if gp_all.size else 0.0
    a, b = te[:, 1:-1].ravel(), te[:, 2:].ravel()
    corr = float(np.corrcoef(a, b)[0, 1]) if a.size > 1 and a.std() > 0 and b.std() > 0 else 0.0
    return {
        "t_amb_rmse_k_lead1": float(np.sqrt(np.mean(te[:, 1] ** 2))) if horizon > 1 else 0.0,
        "t_amb_rmse_k_lead_last": float(np.sqrt(np.mean(te[:, -1] ** 2))),
        "t_amb_lag1_corr": corr,
        "ghi_rrmse": rmse / float(np.mean(gt_all)) if gt_all.size and np.mean(gt_all) > 0 else 0.0,
        "ghi_skill_vs_persistence": 1.0 - rmse / rmse_p if rmse_p > 0 else 0.0,
        "price_unpublished_share": float(np.mean(unknown)) if unknown.size else 0.0,
        "price_mae_eur_per_kwh": float(np.mean(np.abs(pd_all[unknown]))) if unknown.any() else 0.0,
    }
