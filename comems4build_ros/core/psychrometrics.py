"""Moist-air relations for the cooling supply limit (no package imports: config reads it).

Dew point by the Magnus formula with the coefficients of Alduchov and Eskridge (1996,
J. Appl. Meteorol. 35, 601-609): ``b = 17.625``, ``c = 243.04 degC``, valid over water for
-40..50 degC within about 0.1 K.
"""

from __future__ import annotations

import math

#: Magnus coefficients over water (Alduchov and Eskridge 1996).
MAGNUS_B = 17.625
MAGNUS_C_C = 243.04


def dew_point_c(t_air_c: float, rh: float) -> float:
    """Dew point of moist air by the Magnus formula (Alduchov and Eskridge 1996).

    ``gamma = ln(rh) + b * t / (c + t)``, ``t_dew = c * gamma / (b - gamma)`` with
    :data:`MAGNUS_B` and :data:`MAGNUS_C_C`.

    Parameters
    ----------
    t_air_c : float
        Air temperature [degC].
    rh : float
        Relative humidity, in (0, 1] [-].

    Returns
    -------
    float
        Dew point [degC].

    Raises
    ------
    ValueError
        If ``rh`` is outside (0, 1].
    """
    if not 0.0 < rh <= 1.0:
        raise ValueError(f"relative humidity {rh} outside (0, 1]")
    gamma = math.log(rh) + MAGNUS_B * t_air_c / (MAGNUS_C_C + t_air_c)
    return MAGNUS_C_C * gamma / (MAGNUS_B - gamma)
