"""Deterministic generator of the default winter scenario (no network).

Every series is drawn from a seeded ``numpy`` generator (one independent stream per
component, derived with :class:`numpy.random.SeedSequence`), so the same settings and seed
give bit-identical arrays. The settings live in ``config/scenario.yaml`` with their
sources; docs/scenario.md compares the generated statistics with those of the measured
2022/23 winter (:mod:`comems4build_ros.core.scenario.stats`).

Method (daily latent weather drives all components so that they stay consistent):

1. Latent daily wind index ``W_d`` (AR(1), stationary N(0, 1)) plus the configured
   episode offsets (calm cold spell, windy mild New Year).
2. Daily clear-sky index ``kc_d`` from a two-state Markov chain (overcast / fair) with
   Beta draws per state, lowered on windy days. Hourly GHI = pvlib clear-sky GHI (Ineichen,
   Linke turbidity climatology of pvlib) at the middle of the hour times ``kc_d`` and an
   hourly AR(1) variation; DHI from GHI with the Erbs decomposition (``pvlib.irradiance.erbs``).
3. Daily mean temperature = climate mean + episode anomaly + wind effect + AR(1) anomaly;
   hourly temperature = daily means interpolated between noons + a diurnal cycle (half
   cosines, minimum around sunrise, maximum early afternoon) whose amplitude grows with
   ``kc_d`` (clear days have larger swings) + hourly AR(1) noise.
4. Day-ahead spot price: daily level = fuel-cost level (monthly means of the DE-LU
   day-ahead prices 2022/23 from the ENTSO-E Transparency Platform at mid-month,
   interpolated) times a residual-load factor (lower on windy, mild days, weekends and
   public holidays; AR(1) remainder); hourly price = level * (1 + s(h)) with s(h) the measured
   hour-of-day profile relative to its mean, plus AR(1) noise; negative values are
   compressed (curtailment keeps German negative prices shallow, measured min -5 EUR/MWh).
5. Appliance load: expected power = annual energy * BDEW H0 dynamisation factor * hourly
   shape (workday / off day); split into a steady base, a log-normal activity part and
   Poisson appliance cycles (washer, dryer, dishwasher) started with the shape's probability.
6. Hot-water draws: OpenDHW (the DHWCalc method: draw-off categories, probability profile
   with weekend factor and 10 % seasonal sine) per calendar year, averaged to 1 h.

richardsonpy was tried for the load (step 5): it takes about 8 s per year at 1 min, uses
the global ``random`` module and gave about 11,000 kWh/a for 4 occupants with its default
appliance set, far from the 4,000-4,500 kWh/a of a 4-person household (a synPRO family
profile sums to 4,174 kWh/a), so the load model above is ours.
"""

from __future__ import annotations

import random
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from comems4build_ros.core.config import ConfigError, SiteParams
from comems4build_ros.core.scenario.comfort import holiday_dates
from comems4build_ros.core.scenario.settings import HOURS_PER_DAY, ScenarioParams

#: Energy conversion [Wh per kWh].
WH_PER_KWH = 1000.0
#: Hours of a (non-leap) year [h].
HOURS_PER_YEAR = 8760.0
DAYS_PER_YEAR = 365
SECONDS_PER_HOUR_INT = 3600
#: Average share of off days (weekends and about 10 public holidays a year) [-].
OFF_DAY_SHARE = (2 * 52 + 10) / 365

#: Independent random streams per component (SeedSequence spawn keys).
_STREAMS = ("wind", "solar", "temperature", "price", "load", "dhw")


@dataclass(frozen=True)
class GeneratedSeries:
    """Raw hourly series of the generator (local, tz-aware ``time``).

    Attributes
    ----------
    time : pandas.DatetimeIndex
        Start of each hour, tz-aware in the site's zone.
    t_amb_c : numpy.ndarray
        Ambient temperature [degC].
    ghi_w_m2, dhi_w_m2 : numpy.ndarray
        Global and diffuse horizontal irradiance, hourly means [W/m2].
    spot_eur_per_mwh : numpy.ndarray
        Day-ahead spot price [EUR/MWh].
    p_load_w : numpy.ndarray
        Appliance load, hourly mean [W].
    dhw_l_per_h : numpy.ndarray
        Hot-water draws [l/h].
    off_day : numpy.ndarray of bool
        The hour lies on a weekend day or public holiday.
    kc_day : numpy.ndarray
        Daily clear-sky index, one per day [-].
    wind_day : numpy.ndarray
        Latent daily wind index, one per day [-].
    """

    time: pd.DatetimeIndex
    t_amb_c: np.ndarray
    ghi_w_m2: np.ndarray
    dhi_w_m2: np.ndarray
    spot_eur_per_mwh: np.ndarray
    p_load_w: np.ndarray
    dhw_l_per_h: np.ndarray
    off_day: np.ndarray
    kc_day: np.ndarray
    wind_day: np.ndarray


def _streams(seed: int) -> dict[str, np.random.Generator]:
    """Return one independent generator per component of :data:`_STREAMS`."""
    children = np.random.SeedSequence(seed).spawn(len(_STREAMS))
    return {name: np.random.default_rng(child) for name, child in zip(_STREAMS, children)}


def _ar1(rng: np.random.Generator, n: int, phi: float, sigma: float, stationary: bool = True) -> np.ndarray:
    """AR(1) series ``x[i] = phi x[i-1] + sigma e[i]``; stationary start if requested."""
    e = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = sigma * e[0] / np.sqrt(1.0 - phi**2) if stationary else sigma * e[0]
    for i in range(1, n):
        x[i] = phi * x[i - 1] + sigma * e[i]
    return x


def _episode_profile(days: pd.DatetimeIndex, settings: ScenarioParams) -> tuple[np.ndarray, np.ndarray]:
    """Return the daily temperature anomaly [K] and wind offset of the configured episodes (ramped)."""
    t = settings.temperature
    anomaly = np.zeros(len(days))
    wind = np.zeros(len(days))
    ramp = t.episode_ramp_days
    day_num = (days - days[0]).days.to_numpy().astype(float)
    for ep in t.episodes:
        s = (pd.Timestamp(ep.start) - days[0].tz_localize(None)).days
        e = (pd.Timestamp(ep.end) - days[0].tz_localize(None)).days
        # weight 1 inside [s, e], linear ramps of `ramp` days on both sides
        if ramp > 0:
            w = np.clip(1.0 - np.maximum(s - day_num, day_num - e) / (ramp + 1), 0.0, 1.0)
            w[(day_num >= s) & (day_num <= e)] = 1.0
        else:
            w = ((day_num >= s) & (day_num <= e)).astype(float)
        anomaly += w * ep.anomaly_k
        wind += w * ep.wind
    return anomaly, wind


def _daily_kc(rng: np.random.Generator, n_days: int, wind: np.ndarray, settings: ScenarioParams) -> np.ndarray:
    """Draw the daily clear-sky index from a two-state Markov chain with Beta draws [-]."""
    s = settings.solar
    p_fair = s.p_overcast_to_fair / (s.p_overcast_to_fair + s.p_fair_to_overcast)
    u = rng.random(n_days)
    fair = np.empty(n_days, dtype=bool)
    fair[0] = u[0] < p_fair
    for i in range(1, n_days):
        fair[i] = (u[i] >= s.p_fair_to_overcast) if fair[i - 1] else (u[i] < s.p_overcast_to_fair)
    mean = np.where(fair, s.fair_kc_mean, s.overcast_kc_mean)
    kc = rng.beta(mean * s.kc_concentration, (1.0 - mean) * s.kc_concentration)
    return np.clip(kc - s.wind_kc * wind, 0.05, s.kc_max)


def _diurnal_shape(hour: np.ndarray, t_min_hour: float, t_max_hour: float) -> np.ndarray:
    """Return the diurnal temperature shape in [-0.5, 0.5] with zero daily mean (two half cosines)."""
    rise = t_max_hour - t_min_hour
    fall = HOURS_PER_DAY - rise
    x = (hour - t_min_hour) % HOURS_PER_DAY
    return np.where(x <= rise, -0.5 * np.cos(np.pi * x / rise), 0.5 * np.cos(np.pi * (x - rise) / fall))


def _solar(
    rng: np.random.Generator, time: pd.DatetimeIndex, day: np.ndarray, kc_day: np.ndarray,
    settings: ScenarioParams, site: SiteParams,
) -> tuple[np.ndarray, np.ndarray]:
    """Return hourly mean GHI and DHI [W/m2] (clear-sky at the middle of the hour times kc).

    The pvlib part is cached on disk (:mod:`comems4build_ros.core.result_cache`): a hit gives the
    same arrays without importing pvlib.
    """
    from comems4build_ros.core.result_cache import PVLIB_DISTS, cached

    s = settings.solar
    mid = time + pd.Timedelta(minutes=30)
    kc_h = kc_day[day] * (1.0 + _ar1(rng, len(time), s.hourly_phi, s.hourly_sigma * np.sqrt(1 - s.hourly_phi**2)))
    kc_h = np.clip(kc_h, 0.02, s.kc_max)
    params = {"site": site.model_dump(), "clearsky_model": s.clearsky_model}
    ghi, dhi = cached("pvlib-solar", params, [mid.asi8, kc_h], lambda: _solar_pvlib(mid, kc_h, s.clearsky_model, site),
                      dists=PVLIB_DISTS, shape=(len(time),))
    return ghi, dhi


def _solar_pvlib(
    mid: pd.DatetimeIndex, kc_h: np.ndarray, model: str, site: SiteParams
) -> tuple[np.ndarray, np.ndarray]:
    """Compute GHI and DHI [W/m2] at the times ``mid`` with hourly clear-sky index ``kc_h`` [-] (pvlib)."""
    import pvlib

    loc = pvlib.location.Location(site.latitude_deg, site.longitude_deg, tz=site.timezone, altitude=site.altitude_m)
    with warnings.catch_warnings():  # pandas deprecation notices from inside pvlib
        warnings.simplefilter("ignore", DeprecationWarning)
        ghi_cs = loc.get_clearsky(mid, model=model)["ghi"].to_numpy()
        ghi = np.where(ghi_cs > 0, ghi_cs * kc_h, 0.0)
        zenith = loc.get_solarposition(mid)["apparent_zenith"].to_numpy()
        dhi = pvlib.irradiance.erbs(ghi, zenith, mid)["dhi"].to_numpy()
    dhi = np.clip(np.nan_to_num(dhi), 0.0, ghi)
    return ghi, dhi


def _temperature(
    rng: np.random.Generator, time: pd.DatetimeIndex, day: np.ndarray, kc_day: np.ndarray,
    wind_day: np.ndarray, anomaly_day: np.ndarray, settings: ScenarioParams,
) -> tuple[np.ndarray, np.ndarray]:
    """Return the hourly ambient temperature [degC] and the daily means behind it."""
    t = settings.temperature
    n_days = len(kc_day)
    daily = t.mean_c + anomaly_day + t.wind_k * wind_day + _ar1(rng, n_days, t.ar_phi, t.ar_sigma_k)
    hours_since = (time - time[0].normalize()) / pd.Timedelta(hours=1)
    baseline = np.interp(hours_since.to_numpy(), np.arange(n_days) * HOURS_PER_DAY + 12.0, daily)
    amp = t.amp_overcast_k + t.amp_clear_k * kc_day
    shape = _diurnal_shape(np.asarray(time.hour, dtype=float), t.t_min_hour, t.t_max_hour)
    noise = _ar1(rng, len(time), t.noise_phi, t.noise_sigma_k)
    return baseline + amp[day] * shape + noise, daily


def _prices(
    rng: np.random.Generator, time: pd.DatetimeIndex, days: pd.DatetimeIndex, day: np.ndarray,
    wind_day: np.ndarray, t_daily: np.ndarray, off_day_daily: np.ndarray, settings: ScenarioParams,
) -> np.ndarray:
    """Return the hourly day-ahead spot price [EUR/MWh]."""
    p = settings.price
    n_days = len(days)
    anchor_x = np.array([(pd.Timestamp(d) - days[0].tz_localize(None)).days for d in p.level_dates], dtype=float)
    fuel = np.interp(np.arange(n_days, dtype=float), anchor_x, p.level_eur_per_mwh)
    # Residual-load factor, centred so that E[R_d] = 1 for W ~ N(0, 1) and the average
    # share of off days: the fuel-cost level is then the expected price level.
    def wind_effect(w: np.ndarray) -> np.ndarray:
        """Return the saturated wind (or calm) effect on the residual load [-]."""
        sat = p.wind_saturation * np.tanh(w / p.wind_saturation)
        return np.where(w > 0, p.wind_coef, p.calm_coef) * sat

    nodes, weights = np.polynomial.hermite_e.hermegauss(40)
    wind_mean = float(np.sum(weights * wind_effect(nodes)) / np.sqrt(2.0 * np.pi))
    resid = (
        1.0
        - (wind_effect(wind_day) - wind_mean)
        - p.temp_coef * (t_daily - settings.temperature.mean_c)
        + p.offday_coef * (off_day_daily - OFF_DAY_SHARE)
        + _ar1(rng, n_days, p.ar_phi, p.ar_sigma)
    )
    level = fuel * resid
    profile = np.asarray(p.hour_profile_eur_per_mwh, dtype=float)
    rel = profile / profile.mean() - 1.0
    hour = np.asarray(time.hour)
    noise = _ar1(rng, len(time), p.noise_phi, np.sqrt(1 - p.noise_phi**2))
    noise_std = p.noise_abs_eur_per_mwh + p.noise_rel * np.abs(level[day])
    price = level[day] * (1.0 + p.shape_gain * rel[hour]) + noise_std * noise
    return np.where(price < 0, price * p.negative_compression, price)


def dynamisation_factor(day_of_year: np.ndarray, coef: list[float]) -> np.ndarray:
    """Compute the BDEW H0 dynamisation factor ``F(d) = sum_i c_i d^i`` of the standard load profile.

    Parameters
    ----------
    day_of_year : numpy.ndarray
        Day of the year d, 1..365.
    coef : list of float
        Polynomial coefficients c_0, c_1, ... (BDEW; ``config/scenario.yaml``).

    Returns
    -------
    numpy.ndarray
        F(d) [-].
    """
    d = np.asarray(day_of_year, dtype=float)
    return sum(c * d**i for i, c in enumerate(coef))


def expected_load_w(time: pd.DatetimeIndex, off_day: np.ndarray, settings: ScenarioParams) -> np.ndarray:
    """Return the expected appliance load per hour: annual energy * dynamisation * day-type shape.

    The dynamisation factor (BDEW H0) is normalised to a year mean of 1, each hourly shape
    (workday, off day) to a mean of 1.

    Parameters
    ----------
    time : pandas.DatetimeIndex
        Start of each hour, local time.
    off_day : numpy.ndarray of bool
        The hour lies on a weekend day or public holiday.
    settings : ScenarioParams
        Generator settings (``load``: ``annual_kwh`` [kWh/a], shapes, coefficients).

    Returns
    -------
    numpy.ndarray
        Expected load [W].
    """
    ld = settings.load
    year_mean = dynamisation_factor(np.arange(1, DAYS_PER_YEAR + 1), ld.dynamisation_coef).mean()
    dyn = dynamisation_factor(np.minimum(time.day_of_year.to_numpy(), DAYS_PER_YEAR), ld.dynamisation_coef) / year_mean
    work = np.asarray(ld.shape_workday) / np.mean(ld.shape_workday)
    off = np.asarray(ld.shape_offday) / np.mean(ld.shape_offday)
    hour = np.asarray(time.hour)
    shape = np.where(off_day, off[hour], work[hour])
    return ld.annual_kwh * WH_PER_KWH / HOURS_PER_YEAR * dyn * shape


def _load(
    rng: np.random.Generator, time: pd.DatetimeIndex, day: np.ndarray, off_day: np.ndarray,
    settings: ScenarioParams,
) -> np.ndarray:
    """Draw the hourly appliance load [W] (base + log-normal activity + appliance cycles)."""
    ld = settings.load
    expected = expected_load_w(time, off_day, settings)
    daily_kwh = ld.annual_kwh / DAYS_PER_YEAR
    cycle_share = ld.cycles_per_day * ld.cycle_kwh / daily_kwh
    activity_share = 1.0 - ld.base_share - cycle_share
    if activity_share <= 0:
        raise ConfigError(
            f"scenario.load: base_share ({ld.base_share}) + cycle energy share ({cycle_share:.2f}) must stay below 1"
        )
    n = len(time)
    n_days = int(day.max()) + 1
    day_mean = np.bincount(day, weights=expected, minlength=n_days) / np.maximum(np.bincount(day, minlength=n_days), 1)
    base = ld.base_share * day_mean[day]
    z = _ar1(rng, n, ld.noise_phi, ld.noise_sigma * np.sqrt(1 - ld.noise_phi**2))
    activity = activity_share * expected * np.exp(z - 0.5 * ld.noise_sigma**2)
    cycles = np.zeros(n)
    p_cycle = ld.cycle_kwh * WH_PER_KWH / ld.cycle_hours
    n_cycles = rng.poisson(ld.cycles_per_day, n_days)
    for d in range(n_days):
        hours = np.flatnonzero(day == d)
        if n_cycles[d] == 0 or len(hours) == 0:
            continue
        w = expected[hours] / expected[hours].sum()
        for k in rng.choice(hours, size=n_cycles[d], p=w):
            cycles[k : k + ld.cycle_hours] += p_cycle
    return base + activity + cycles


def appliance_load_w(time: pd.DatetimeIndex, off_day: np.ndarray, settings: ScenarioParams, seed: int) -> np.ndarray:
    """Return the appliance load model of step 5 with its own stream of ``seed``, on the hours ``time`` [W].

    Another seed gives another household of the same model (a neighbour), with the same
    calendar (``off_day``: weekends and public holidays per hour).
    """
    local_dates = time.normalize().tz_localize(None)
    day = ((local_dates - local_dates[0]).days).to_numpy()
    return _load(_streams(seed)["load"], time, day, np.asarray(off_day, dtype=bool), settings)


def opendhw_offday_mass_ratio(step_s: int) -> float:
    """Return the daily probability mass of OpenDHW's off-day profile over its workday profile.

    OpenDHW 0.2.9 (building type SFH) multiplies its ``weekend_weekday_factor`` onto base
    profiles whose off-day mass is already about 1.22 times the workday mass, so a factor
    of 1.2 gives off-day draws about 1.46 times the workday draws. Dividing the wanted
    factor (DHWCalc meaning: off-day volume / workday volume, 1.2 in DHWCalc's single-family
    profile) by this ratio gives the DHWCalc ratio in expectation.

    Parameters
    ----------
    step_s : int
        Time step of the OpenDHW profile [s].

    Returns
    -------
    float
        Off-day mass over workday mass [-].
    """
    import OpenDHW

    off = OpenDHW.generate_daily_probability_step_function(mode="off-day", s_step=step_s, building_type="SFH")
    work = OpenDHW.generate_daily_probability_step_function(mode="work-day", s_step=step_s, building_type="SFH")
    return float(np.sum(off) / np.sum(work))


def _dhw(seed_int: int, time: pd.DatetimeIndex, settings: ScenarioParams, country: str, subdiv: str) -> np.ndarray:
    """Draw hourly hot-water draws [l/h] from OpenDHW, one profile per calendar year.

    OpenDHW draws with the global ``random`` module; its state is saved and restored.
    Local times past day 365 (31 Dec of leap years) reuse day 365.
    """
    import OpenDHW

    d = settings.dhw
    lib_factor = d.weekend_weekday_factor / opendhw_offday_mass_ratio(d.step_s)
    local = time.tz_localize(None) if time.tz is not None else time
    out = np.empty(len(time))
    steps_per_hour = SECONDS_PER_HOUR_INT // d.step_s
    state = random.getstate()
    try:
        for i, year in enumerate(range(int(local.year.min()), int(local.year.max()) + 1)):
            random.seed(seed_int + i)
            hol = sorted(
                x.timetuple().tm_yday for x in holiday_dates(country, subdiv, (year,)) if x.timetuple().tm_yday <= 365
            )
            with warnings.catch_warnings():  # pandas deprecation notices from inside OpenDHW
                warnings.simplefilter("ignore", DeprecationWarning)
                df = OpenDHW.generate_dhw_profile(
                    s_step=d.step_s,
                    categories=d.categories,
                    mean_drawoff_vol_per_day=d.litres_per_day,
                    occupancy=1,
                    holidays=hol,
                    building_type="SFH",
                    weekend_weekday_factor=lib_factor,
                    initial_day=pd.Timestamp(year, 1, 1).day_of_week,
                )
            hourly = np.asarray(df["Water_LperH"], dtype=float).reshape(-1, steps_per_hour).mean(axis=1)
            sel = local.year == year
            doy = np.minimum(local[sel].day_of_year.to_numpy(), DAYS_PER_YEAR)
            out[sel] = hourly[(doy - 1) * HOURS_PER_DAY + local[sel].hour.to_numpy()]
    finally:
        random.setstate(state)
    return out


def generate(
    settings: ScenarioParams, site: SiteParams, country: str, subdivision: str, hours: int, seed: int,
    start: pd.Timestamp | None = None,
) -> GeneratedSeries:
    """Generate ``hours`` hourly values of every series from ``start`` (default: settings.start).

    The method is in the module docstring.

    Parameters
    ----------
    settings : ScenarioParams
        Generator settings (``config/scenario.yaml``).
    site : SiteParams
        Location and time zone (solar geometry, local calendar).
    country, subdivision : str
        Public-holiday calendar (off days for prices, load and DHW).
    hours : int
        Number of hourly steps [h].
    seed : int
        Random seed.
    start : pandas.Timestamp, optional
        Local start time (naive local or tz-aware); midnight recommended.

    Returns
    -------
    GeneratedSeries
        The hourly series.

    Raises
    ------
    ConfigError
        If the load settings leave no share for the activity part.
    """
    start = pd.Timestamp(settings.start if start is None else start)
    start = start.tz_localize(site.timezone) if start.tzinfo is None else start.tz_convert(site.timezone)
    time = pd.date_range(start, periods=hours, freq="h", name="time")
    local_dates = time.normalize().tz_localize(None)
    first = local_dates[0]
    day = ((local_dates - first).days).to_numpy()
    n_days = int(day.max()) + 1
    days = pd.date_range(first, periods=n_days, freq="D").tz_localize(site.timezone)
    years = tuple(range(first.year, int(local_dates.year.max()) + 1))
    hol = holiday_dates(country, subdivision, years)
    off_daily = np.array([(d.day_of_week >= 5) or (d.date() in hol) for d in days])
    rng = _streams(seed)
    anomaly, wind_offset = _episode_profile(days, settings)
    wind = _ar1(rng["wind"], n_days, settings.wind.ar_phi, np.sqrt(1 - settings.wind.ar_phi**2)) + wind_offset
    kc = _daily_kc(rng["solar"], n_days, wind, settings)
    ghi, dhi = _solar(rng["solar"], time, day, kc, settings, site)
    t_amb, t_daily = _temperature(rng["temperature"], time, day, kc, wind, anomaly, settings)
    spot = _prices(rng["price"], time, days, day, wind, t_daily, off_daily.astype(float), settings)
    off = off_daily[day]
    load = _load(rng["load"], time, day, off, settings)
    dhw_seed = int(rng["dhw"].integers(0, 2**31 - 1))
    dhw = _dhw(dhw_seed, time, settings, country, subdivision)
    return GeneratedSeries(
        time=time, t_amb_c=t_amb, ghi_w_m2=ghi, dhi_w_m2=dhi, spot_eur_per_mwh=spot,
        p_load_w=load, dhw_l_per_h=dhw, off_day=off, kc_day=kc, wind_day=wind,
    )
