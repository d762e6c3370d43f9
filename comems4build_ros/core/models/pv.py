"""Photovoltaic array, ``eq:power_pv``.

The paper computes the AC output of the array as

    P_PV = n_module * a_module * G * eta_STC * eta_L&T
           * [1 - eta_T * (T_amb + (NOCT - 20 degC) / (800 W/m2) * G - T_STC)]

with ``G`` the irradiance on the tilted module plane. ``G`` is obtained here from the
measured (or generated) global and diffuse horizontal irradiance with pvlib: solar
position (``pvlib.solarposition.get_solarposition``), direct normal irradiance from
GHI, DHI and the zenith angle (``pvlib.irradiance.dni``: ``(GHI - DHI) / cos(zenith)``,
set to zero when the sun is less than 2 degrees high and capped at 1.1 times the
Ineichen clear-sky DNI below 10 degrees, where the division blows up)
and transposition to the plane (``pvlib.irradiance.get_total_irradiance``).

Hourly values are means over the hour starting at ``time``; the sun position is taken
at the middle of the hour (``time + 30 min``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PVParams, SiteParams

#: Reference irradiance of the NOCT definition [W/m2] (``eq:power_pv``).
NOCT_IRRADIANCE_W_M2 = 800.0
#: Reference ambient temperature of the NOCT definition [degC] (``eq:power_pv``).
NOCT_AMBIENT_C = 20.0
#: Zenith angle above which DNI is set to zero [deg] (pvlib's default guard, sun < 2 deg high).
ZENITH_DNI_ZERO_DEG = 88.0
#: Offset from the start of an hourly step to the time of the solar position [min].
MID_STEP_MINUTES = 30


def power_from_irradiance_w(g_poa_w_m2, t_amb_c, pv: PVParams) -> np.ndarray:
    """Compute the PV output ``eq:power_pv`` for a given plane-of-array irradiance.

    Parameters
    ----------
    g_poa_w_m2 : numeric
        Irradiance on the tilted module plane G [W/m2].
    t_amb_c : numeric
        Ambient air temperature [degC].
    pv : PVParams
        Module count, area [m2], efficiencies [-], temperature coefficient [1/K],
        NOCT and T_STC [degC].

    Returns
    -------
    numpy.ndarray
        AC power P_PV [W], never negative.
    """
    g = np.asarray(g_poa_w_m2, dtype=float)
    t_amb = np.asarray(t_amb_c, dtype=float)
    t_cell = t_amb + (pv.noct_c - NOCT_AMBIENT_C) / NOCT_IRRADIANCE_W_M2 * g
    derate = 1.0 - pv.eta_t_per_k * (t_cell - pv.t_stc_c)
    p = pv.n_modules * pv.a_module_m2 * g * pv.eta_stc * pv.eta_lt * derate
    return np.maximum(p, 0.0)


def poa_irradiance_w_m2(time, ghi_w_m2, dhi_w_m2, pv: PVParams, site: SiteParams) -> np.ndarray:
    """Transpose horizontal global and diffuse irradiance onto the module plane, G of ``eq:power_pv``.

    Solar position, DNI = (GHI - DHI) / cos(zenith) limited by the Ineichen clear sky
    (``pvlib.irradiance.dni``) and the sky-diffuse transposition are pvlib's, at the middle of
    each hour.

    Parameters
    ----------
    time : pandas.DatetimeIndex (tz-aware) or sequence of timestamps
        Start of each hourly step.
    ghi_w_m2, dhi_w_m2 : array-like
        Global and diffuse horizontal irradiance (hourly means) [W/m2].
    pv : PVParams
        Tilt and azimuth [deg] (pvlib convention: 180 = south), ground albedo [-],
        sky diffuse model (``sky_model``).
    site : SiteParams
        Latitude, longitude [deg], altitude [m].

    Returns
    -------
    numpy.ndarray
        Plane-of-array global irradiance [W/m2] (0 where the inputs give none).

    Raises
    ------
    ValueError
        If the arrays differ in length, the times are not tz-aware, or an irradiance
        is negative or not finite.
    """
    index = pd.DatetimeIndex(time)
    if index.tz is None:
        raise ValueError("pv: time must be timezone-aware (local time with UTC offset)")
    ghi = np.asarray(ghi_w_m2, dtype=float)
    dhi = np.asarray(dhi_w_m2, dtype=float)
    if ghi.shape != (len(index),) or dhi.shape != (len(index),):
        raise ValueError(f"pv: ghi ({ghi.shape}) and dhi ({dhi.shape}) must match time ({len(index)},)")
    for name, arr in (("ghi_w_m2", ghi), ("dhi_w_m2", dhi)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"pv: {name} contains NaN or inf")
        if np.any(arr < 0):
            raise ValueError(f"pv: {name} contains negative irradiance")
    # Diffuse cannot exceed global (measurement noise): cap it.
    dhi = np.minimum(dhi, ghi)
    mid = index + pd.Timedelta(minutes=MID_STEP_MINUTES)
    # the pvlib steps are cached on disk (comems4build_ros.core.result_cache): a hit skips pvlib's import
    from comems4build_ros.core.result_cache import PVLIB_DISTS, cached

    geometry = {"site": site.model_dump(), "tilt_deg": pv.tilt_deg, "azimuth_deg": pv.azimuth_deg,
                "albedo": pv.albedo, "sky_model": pv.sky_model}
    (poa,) = cached("pvlib-poa", geometry, [mid.asi8, ghi, dhi],
                    lambda: (_poa_from_horizontal_quiet(mid, ghi, dhi, pv, site),),
                    dists=PVLIB_DISTS, shape=(len(index),))
    return poa


def _poa_from_horizontal_quiet(mid: pd.DatetimeIndex, ghi: np.ndarray, dhi: np.ndarray, pv: PVParams,
                               site: SiteParams) -> np.ndarray:
    with warnings.catch_warnings():
        # pvlib 0.16 still uses pandas attributes deprecated in pandas 3 (dayofyear).
        warnings.filterwarnings("ignore", category=DeprecationWarning, module="pvlib")
        return _poa_from_horizontal(mid, ghi, dhi, pv, site)


def _poa_from_horizontal(mid: pd.DatetimeIndex, ghi: np.ndarray, dhi: np.ndarray, pv: PVParams, site: SiteParams):
    """Run the pvlib steps of :func:`poa_irradiance_w_m2` for checked inputs at mid-step times."""
    import pvlib  # here, not at the top: node processes that build no scenario skip its ~1 s import

    solpos = pvlib.solarposition.get_solarposition(mid, site.latitude_deg, site.longitude_deg, site.altitude_m)
    zenith = solpos["apparent_zenith"]
    location = pvlib.location.Location(site.latitude_deg, site.longitude_deg, altitude=site.altitude_m)
    dni_clear = location.get_clearsky(mid, model="ineichen", solar_position=solpos)["dni"]
    # pvlib.irradiance.dni indexes by boolean masks: pass aligned Series, not bare arrays.
    dni = pvlib.irradiance.dni(
        pd.Series(ghi, index=mid),
        pd.Series(dhi, index=mid),
        zenith,
        dni_clear=dni_clear,
        zenith_threshold_for_zero_dni=ZENITH_DNI_ZERO_DEG,
    )
    dni = np.nan_to_num(np.asarray(dni, dtype=float), nan=0.0)
    dni_extra = pvlib.irradiance.get_extra_radiation(mid).to_numpy()
    total = pvlib.irradiance.get_total_irradiance(
        surface_tilt=pv.tilt_deg,
        surface_azimuth=pv.azimuth_deg,
        solar_zenith=zenith.to_numpy(),
        solar_azimuth=solpos["azimuth"].to_numpy(),
        dni=dni,
        ghi=ghi,
        dhi=dhi,
        dni_extra=dni_extra,
        albedo=pv.albedo,
        model=pv.sky_model,
    )
    poa = np.nan_to_num(np.asarray(total["poa_global"], dtype=float), nan=0.0)
    return np.maximum(poa, 0.0)


def pv_power_w(time, ghi_w_m2, dhi_w_m2, t_amb_c, pv: PVParams, site: SiteParams) -> np.ndarray:
    """Compute the PV AC output per hourly step, ``eq:power_pv`` with G from pvlib's transposition.

    Parameters
    ----------
    time : pandas.DatetimeIndex (tz-aware)
        Start of each hourly step.
    ghi_w_m2, dhi_w_m2 : array_like
        Global and diffuse horizontal irradiance [W/m2].
    t_amb_c : array_like
        Ambient temperature [degC].
    pv : PVParams
        The array (:func:`power_from_irradiance_w`, :func:`poa_irradiance_w_m2`).
    site : SiteParams
        Latitude, longitude [deg], altitude [m].

    Returns
    -------
    numpy.ndarray
        P_PV [W] per step.

    Raises
    ------
    ValueError
        If the inputs differ in length or hold NaN, inf or negative irradiance.
    """
    g = poa_irradiance_w_m2(time, ghi_w_m2, dhi_w_m2, pv, site)
    t_amb = np.asarray(t_amb_c, dtype=float)
    if t_amb.shape != g.shape:
        raise ValueError(f"pv: t_amb_c ({t_amb.shape}) must match time ({g.shape})")
    if not np.all(np.isfinite(t_amb)):
        raise ValueError("pv: t_amb_c contains NaN or inf")
    return power_from_irradiance_w(g, t_amb, pv)
