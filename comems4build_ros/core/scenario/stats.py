"""Statistics of the embedded scenarios next to reference figures (for docs/scenario.md and tests).

The reference figures are statistics of the measured data of the paper's winter: ENTSO-E
day-ahead prices DE-LU (2022-12-01..2023-02-28; the 12-week mean 170 EUR/MWh), DWD hourly
air temperature of station 4177 Rheinstetten (2022-12-01..2023-02-14), the DHWcalc
settings (200 l/day, weekend draws 120 % of weekdays) and the appliance energy of a
4-person family (4,000-4,500 kWh/a; a synPRO family profile has 4,174 kWh/a).

``python -m comems4build_ros.core.scenario.stats`` prints the Markdown table of the default
(measured) and the synthetic scenario; ``--rank-seeds N`` ranks the synthetic generator's
seeds 0..N-1 by their misfit to the reference statistics (how its seed in
config/scenario.yaml was chosen).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np
import pandas as pd

from comems4build_ros.core.scenario.base import Scenario
from comems4build_ros.core.scenario.generator import dynamisation_factor

#: The reference temperature statistics cover 2022-12-01 .. 2023-02-14 (DWD Rheinstetten).
TEMPERATURE_END = "2023-02-15"
#: ENTSO-E DE-LU hour-of-day mean spot price 00..23 local, 2022-12-01..2023-02-28 [EUR/MWh].
REFERENCE_HOUR_PROFILE = (133, 126, 123, 118, 119, 129, 153, 182, 199, 197, 190, 185,
                      178, 173, 178, 185, 193, 210, 210, 198, 180, 163, 154, 137)
HOURS_PER_YEAR = 8760.0
KWH_PER_WH = 1e-3
DAYS_PER_WEEK = 7


@dataclass(frozen=True)
class Stat:
    """One statistic of the scenario table and its reference figure.

    Attributes
    ----------
    key : str
        Key in :func:`scenario_stats`.
    label : str
        Row label of the table.
    unit : str
        Unit of the value and the reference.
    ref : float or None
        Reference value (ENTSO-E, DWD, DHWcalc, household figures), None if there is none.
    ref_text : str
        The reference as printed.
    scale : float or None
        Misfit scale (about one standard deviation across seeds), in ``unit``; None = not
        in the misfit.
    tol : float or None
        Acceptance band of the synthetic generator in the tests, ``|generated - ref| <= tol``,
        in ``unit``.
    """

    key: str
    label: str
    unit: str
    ref: float | None
    ref_text: str
    scale: float | None = None  # misfit scale (about the spread across seeds); None = not in the misfit
    tol: float | None = None  # acceptance band of the synthetic generator in the tests: |generated - ref| <= tol


#: The compared statistics. ``scale`` is about one standard deviation across 24 seeds;
#: ``tol`` the band the tests accept for the default seed.
STATS: tuple[Stat, ...] = (
    Stat("spot_mean", "spot price mean (12 weeks)", "EUR/MWh", 170, "170", 10, 20),
    Stat("spot_std", "spot price std", "EUR/MWh", 118, "118", 12, 25),
    Stat("spot_min", "spot price min", "EUR/MWh", -5, "-5", 5, 15),
    Stat("spot_max", "spot price max", "EUR/MWh", 665, "665", 60, 150),
    Stat("spot_neg_h", "hours with negative spot price", "h", 43, "43", 40, 60),
    Stat("spot_dec", "spot mean December", "EUR/MWh", 252, "252", 25, 40),
    Stat("spot_jan", "spot mean January", "EUR/MWh", 118, "118", 15, 30),
    Stat("spot_feb", "spot mean February (to Feb 22)", "EUR/MWh", 128, "128 (whole Feb)", 20, 40),
    Stat("spot_workday", "spot mean workdays", "EUR/MWh", 179, "179", 14, 25),
    Stat("spot_offday", "spot mean weekends + holidays", "EUR/MWh", 139, "139 (weekends)", 14, 25),
    Stat("spot_spread_med", "daily max-min spread, median", "EUR/MWh", 99, "99", 10, 20),
    Stat("spot_spread_p10", "daily spread p10", "EUR/MWh", 53, "53", None, 25),
    Stat("spot_spread_p90", "daily spread p90", "EUR/MWh", 212, "212", None, 50),
    Stat("spot_daily_min", "daily mean, min", "EUR/MWh", -1, "-1", 8, 25),
    Stat("spot_daily_max", "daily mean, max", "EUR/MWh", 444, "444", 40, 100),
    Stat("spot_hour_corr", "hour-of-day profile, correlation with ENTSO-E", "-", 1.0, "1", None, 0.05),
    Stat("buy_mean", "buy price mean (a + b * spot)", "EUR/kWh", 0.384, "0.384 (paper, H2 value)", None, 0.03),
    Stat("t_mean", "temperature mean (to Feb 14)", "degC", 4.2, "4.2", 0.5, 1.0),
    # known bias: no extra radiative cooling in clear cold nights, the generated minimum is
    # about 1.5-3.5 K too mild (ensemble mean -10.6 degC); the band says so openly
    Stat("t_min", "temperature min", "degC", -12.2, "-12.2", 1.3, 4.0),
    Stat("t_max", "temperature max", "degC", 18.7, "18.7", 1.7, 3.5),
    Stat("t_amp_med", "daily amplitude, median", "K", 4.4, "4.4", 0.3, 0.8),
    Stat("t_daily_min", "daily mean, min", "degC", -7.2, "-7.2", 1.0, 3.0),
    Stat("t_daily_max", "daily mean, max", "degC", 16.0, "16.0", 1.0, 3.0),
    Stat("t_daily_std", "daily mean, std", "K", 4.8, "4.8", 0.5, 1.0),
    Stat("t_cold_spell_max", "warmest daily mean Dec 10-19", "degC", 0.0, "0.9 (cold spell)"),
    Stat("t_new_year_max", "warmest daily mean Dec 28 - Jan 7", "degC", None, "mild"),
    Stat("ghi_dec", "GHI December", "kWh/m2/d", None, "-"),
    Stat("ghi_jan", "GHI January", "kWh/m2/d", None, "-"),
    Stat("ghi_feb", "GHI February (to Feb 22)", "kWh/m2/d", None, "-"),
    Stat("diffuse_share", "diffuse share of GHI (energy)", "-", None, "-"),
    Stat("load_kwh", "appliance energy (12 weeks)", "kWh", None, "-"),
    Stat("load_annual_kwh", "appliance energy, annual equivalent", "kWh/a", 4250, "4,000-4,500", None, 250),
    Stat("load_morning_peak_h", "load peak hour 05-11 (mean profile)", "h", None, "morning peak"),
    Stat("load_evening_peak_h", "load peak hour 16-23 (mean profile)", "h", None, "evening peak"),
    Stat("dhw_l_per_day", "DHW draw per day", "l/d", 200, "200 (annual mean)", None, 30),
    Stat("dhw_offday_ratio", "DHW off day / workday", "-", 1.2, "1.2", None, 0.25),
)


def scenario_stats(scenario: Scenario, off_day: np.ndarray | None = None,
                   dynamisation_coef: list[float] | None = None) -> dict[str, float]:
    """Compute :data:`STATS` over the run (``n_steps``) of a scenario.

    Parameters
    ----------
    scenario : Scenario
        The scenario (local time index).
    off_day : numpy.ndarray of bool, optional
        Weekend-or-holiday flag per row, computed by the caller with
        :func:`comems4build_ros.core.scenario.is_off_day`; default: no off days.
    dynamisation_coef : list of float, optional
        BDEW H0 polynomial for the annual equivalent of the load; default: the plain mean.

    Returns
    -------
    dict of str to float
        Key of :data:`STATS` -> value in that statistic's unit.
    """
    n = scenario.n_steps
    time = scenario.time[:n]
    off = np.zeros(n, dtype=bool) if off_day is None else np.asarray(off_day[:n], dtype=bool)
    out = {**_price_stats(scenario, time, off), **_temperature_stats(scenario, time),
           **_radiation_stats(scenario, time), **_demand_stats(scenario, time, off, dynamisation_coef)}
    return {k: float(v) for k, v in out.items()}


def _price_stats(scenario: Scenario, time: pd.DatetimeIndex, off: np.ndarray) -> dict[str, float]:
    """Compute the spot and buy price statistics of :data:`STATS` [EUR/MWh, EUR/kWh, h]."""
    spot = pd.Series(scenario.spot_eur_per_mwh[:len(time)], index=time)
    daily = spot.groupby(pd.Index(time.date))
    spread = daily.max() - daily.min()
    month = spot.groupby(time.month).mean()
    hour = spot.groupby(time.hour).mean().reindex(range(24)).to_numpy()
    return {
        "spot_mean": spot.mean(),
        "spot_std": spot.std(),
        "spot_min": spot.min(),
        "spot_max": spot.max(),
        "spot_neg_h": float((spot < 0).sum()),
        "spot_dec": month.get(12, np.nan),
        "spot_jan": month.get(1, np.nan),
        "spot_feb": month.get(2, np.nan),
        "spot_workday": spot[~off].mean(),
        "spot_offday": spot[off].mean(),
        "spot_spread_med": spread.median(),
        "spot_spread_p10": spread.quantile(0.1),
        "spot_spread_p90": spread.quantile(0.9),
        "spot_daily_min": daily.mean().min(),
        "spot_daily_max": daily.mean().max(),
        "spot_hour_corr": float(np.corrcoef(hour, REFERENCE_HOUR_PROFILE)[0, 1]),
        "buy_mean": float(np.mean(scenario.price_buy_eur_per_kwh[:len(time)])),
    }


def _temperature_stats(scenario: Scenario, time: pd.DatetimeIndex) -> dict[str, float]:
    """Compute the ambient temperature statistics of :data:`STATS`, up to :data:`TEMPERATURE_END` [degC, K]."""
    t_end = pd.Timestamp(TEMPERATURE_END).tz_localize(time.tz)
    sel = time < t_end
    temp = pd.Series(scenario.t_amb_c[:len(time)][sel], index=time[sel])
    tdaily = temp.groupby(pd.Index(temp.index.date))
    tmean = tdaily.mean()
    tmean.index = pd.DatetimeIndex(tmean.index)
    return {
        "t_mean": temp.mean(),
        "t_min": temp.min(),
        "t_max": temp.max(),
        "t_amp_med": (tdaily.max() - tdaily.min()).median(),
        "t_daily_min": tmean.min(),
        "t_daily_max": tmean.max(),
        "t_daily_std": tmean.std(),
        "t_cold_spell_max": tmean["2022-12-10":"2022-12-19"].max(),
        "t_new_year_max": tmean["2022-12-28":"2023-01-07"].max(),
    }


def _radiation_stats(scenario: Scenario, time: pd.DatetimeIndex) -> dict[str, float]:
    """Compute the monthly GHI [kWh/m2/d] and the diffuse share [-] of :data:`STATS`."""
    n = len(time)
    ghi = pd.Series(scenario.ghi_w_m2[:n], index=time)
    ghi_month = ghi.groupby(time.month).mean() * 24 * KWH_PER_WH
    return {
        "ghi_dec": ghi_month.get(12, np.nan),
        "ghi_jan": ghi_month.get(1, np.nan),
        "ghi_feb": ghi_month.get(2, np.nan),
        "diffuse_share": float(np.sum(scenario.dhi_w_m2[:n]) / max(np.sum(scenario.ghi_w_m2[:n]), 1e-9)),
    }


def _demand_stats(scenario: Scenario, time: pd.DatetimeIndex, off: np.ndarray,
                  dynamisation_coef: list[float] | None) -> dict[str, float]:
    """Compute the appliance load [kWh, kWh/a, h] and hot-water draw [l/d, -] statistics of :data:`STATS`."""
    n = len(time)
    date = pd.Index(time.date)
    load = pd.Series(scenario.p_load_w[:n], index=time)
    prof = load.groupby(time.hour).mean()
    out = {"load_kwh": load.sum() * KWH_PER_WH}
    if dynamisation_coef is not None:
        year_mean = dynamisation_factor(np.arange(1, 366), dynamisation_coef).mean()
        window_mean = dynamisation_factor(np.minimum(time.day_of_year.to_numpy(), 365), dynamisation_coef).mean()
        out["load_annual_kwh"] = load.mean() / (window_mean / year_mean) * HOURS_PER_YEAR * KWH_PER_WH
    else:
        out["load_annual_kwh"] = load.mean() * HOURS_PER_YEAR * KWH_PER_WH
    out["load_morning_peak_h"] = float(prof.loc[5:11].idxmax())
    out["load_evening_peak_h"] = float(prof.loc[16:23].idxmax())
    dhw = pd.Series(scenario.dhw_l_per_h[:n], index=time).groupby(date).sum()
    off_daily = pd.Series(off, index=time).groupby(date).first()
    out["dhw_l_per_day"] = dhw.mean()
    out["dhw_offday_ratio"] = dhw[off_daily.to_numpy()].mean() / dhw[~off_daily.to_numpy()].mean()
    return out


def misfit(stats: dict[str, float]) -> float:
    """Sum the squared, scaled deviations from the reference figures (statistics with a ``scale``).

    Parameters
    ----------
    stats : dict of str to float
        Output of :func:`scenario_stats`.

    Returns
    -------
    float
        ``sum(((value - ref) / scale) ** 2)`` [-].
    """
    return float(sum(((stats[s.key] - s.ref) / s.scale) ** 2 for s in STATS if s.scale is not None))


def _stats_of(sc: Scenario, params) -> dict[str, float]:
    """Compute :func:`scenario_stats` with the off days and load polynomial of the configuration."""
    from comems4build_ros.core.scenario import is_off_day, load_scenario_settings

    coef = load_scenario_settings().load.dynamisation_coef
    return scenario_stats(sc, is_off_day(sc.time, params.comfort), coef)


def synthetic_stats(params=None, seed: int | None = None) -> dict[str, float]:
    """Compute the statistics of the synthetic scenario (plant parameters and settings from config/).

    Parameters
    ----------
    params : PlantParams, optional
        Plant parameters (default ``config/plant.yaml``).
    seed : int, optional
        Generator seed (default ``config/scenario.yaml``).

    Returns
    -------
    dict of str to float
        As :func:`scenario_stats`.
    """
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.scenario import load_scenario_settings, synthetic_scenario

    params = params or load_plant_params()
    settings = load_scenario_settings()
    return _stats_of(synthetic_scenario(params, weeks=settings.weeks, seed=seed, settings=settings), params)


def default_stats(params=None, seed: int | None = None) -> dict[str, float]:
    """Compute the statistics of the embedded default scenario (measured data).

    Parameters
    ----------
    params, seed : optional
        Plant parameters (default ``config/plant.yaml``) and the seed of the modelled
        radiation and load (default ``config/scenario.yaml``).

    Returns
    -------
    dict of str to float
        As :func:`scenario_stats`.
    """
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.scenario import default_scenario

    params = params or load_plant_params()
    return _stats_of(default_scenario(params, seed=seed), params)


def _fmt(value: float) -> str:
    """Format a statistic with a precision that suits its size (``-`` if not finite)."""
    if not np.isfinite(value):
        return "-"
    if float(value).is_integer():
        return f"{value:.0f}"
    if abs(value) >= 100:
        return f"{value:.0f}"
    if abs(value) >= 10:
        return f"{value:.1f}"
    return f"{value:.2f}"


def markdown_table(default: dict[str, float], synthetic: dict[str, float]) -> str:
    """Format the default (measured) and synthetic scenario's statistics next to the reference figures.

    Parameters
    ----------
    default, synthetic : dict of str to float
        Outputs of :func:`scenario_stats`.

    Returns
    -------
    str
        A Markdown table, one row per entry of :data:`STATS`.
    """
    lines = [
        "| statistic | unit | default (measured) | synthetic | reference |",
        "|---|---|---:|---:|---|",
    ]
    for s in STATS:
        lines.append(f"| {s.label} | {s.unit} | {_fmt(default[s.key])} | {_fmt(synthetic[s.key])} | {s.ref_text} |")
    return "\n".join(lines)


DOC_BEGIN = "<!-- stats:begin -->"
DOC_END = "<!-- stats:end -->"


def update_doc(path: str, table: str) -> None:
    """Replace the text between :data:`DOC_BEGIN` and :data:`DOC_END` in a Markdown file.

    Parameters
    ----------
    path, table : str
        The Markdown file and the new text between its markers.

    Raises
    ------
    InputFileError
        If the file cannot be read as text or the markers are not found.
    """
    from comems4build_ros.files.inputs import between_markers, read_text
    from comems4build_ros.files.outputs import write_text_atomic

    head, tail = between_markers(read_text(path, "a document with the statistics table"), DOC_BEGIN, DOC_END, path)

    write_text_atomic(path, f"{head}{DOC_BEGIN}\n{table}\n{DOC_END}{tail}")


def rank_seeds(n: int, params=None) -> list[tuple[int, float]]:
    """Rank the synthetic generator's seeds by their misfit to the reference figures.

    Parameters
    ----------
    n : int
        Seeds ``0..n-1`` are tried.
    params : PlantParams, optional
        Plant parameters (default ``config/plant.yaml``).

    Returns
    -------
    list of tuple of (int, float)
        ``(seed, misfit)``, best first.
    """
    return sorted(((seed, misfit(synthetic_stats(params, seed))) for seed in range(n)), key=lambda x: x[1])


def main(argv: list[str] | None = None) -> int:
    """Print the statistics table of the embedded scenarios, or rank the generator's seeds.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit code 0.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=None, help="synthetic seed (default: config/scenario.yaml)")
    parser.add_argument("--rank-seeds", type=int, default=0, metavar="N", help="rank synthetic seeds 0..N-1 by misfit")
    parser.add_argument("--update-doc", metavar="MD", help="replace the table between the stats markers of MD")
    args = parser.parse_args(argv)
    if args.update_doc:  # its markers before the work
        from comems4build_ros.files.inputs import check_markers

        check_markers(args.update_doc, DOC_BEGIN, DOC_END, "--update-doc")
    if args.rank_seeds:
        ranked = rank_seeds(args.rank_seeds)
        for seed, m in ranked[:10]:
            print(f"seed {seed:6d}  misfit {m:8.2f}")
        print(f"median misfit over {len(ranked)} seeds: {np.median([m for _, m in ranked]):.2f}")
        return 0
    synthetic = synthetic_stats(seed=args.seed)
    table = markdown_table(default_stats(), synthetic)
    print(table)
    if args.update_doc:
        update_doc(args.update_doc, table)
        print(f"updated {args.update_doc}")
    print(f"\nmisfit of the synthetic scenario to the reference: {misfit(synthetic):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
