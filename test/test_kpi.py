"""KPIs on hand-made series with known answers (eq:discomfort, eq:costs, eq:consumed_grid, ...)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core import kpi


def make_ts(n: int, **cols: object) -> pd.DataFrame:
    """A timeseries of ``n`` hourly steps with zero flows unless given."""
    base = {name: np.zeros(n) for name in kpi.REQUIRED_COLUMNS if name != "time"}
    base["time"] = [t.isoformat() for t in pd.date_range("2022-12-01", periods=n, freq="h", tz="Europe/Berlin")]
    base["t_air_c"] = np.full(n, 21.0)
    base["t_min_c"] = np.full(n, 18.0)
    base["t_max_c"] = np.full(n, 24.0)
    base["loh"] = np.ones(n)
    for key, value in cols.items():
        base[key] = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy() if key != "time" else value
    return pd.DataFrame(base)


def test_discomfort_hand_computed() -> None:
    t_air = np.array([17.0, 18.5, 25.0, 21.0])
    t_min = np.array([18.0, 21.0, 18.0, 21.0])
    t_max = np.full(4, 24.0)
    # violations 1.0 + 2.5 + 1.0 + 0 = 4.5 K over 1 h steps
    assert kpi.discomfort_kh(t_air, t_min, t_max, 1.0) == pytest.approx(4.5)
    assert kpi.discomfort_kh(t_air, t_min, t_max, 0.25) == pytest.approx(1.125)
    assert kpi.discomfort_hours(t_air, t_min, t_max, 1.0) == 3.0


def test_cost_and_energy_hand_computed() -> None:
    # 2 kW bought for 3 h at 0.30, 0.40, 0.50 EUR/kWh -> 0.6 + 0.8 + 1.0 = 2.4 EUR
    price = np.array([0.30, 0.40, 0.50])
    p_buy = np.array([2000.0, 2000.0, 2000.0])
    assert kpi.cost_eur(price, p_buy, 1.0) == pytest.approx(2.4)
    ts = make_ts(3, price_buy_eur_per_kwh=price, p_buy_w=p_buy, p_sell_w=[0, 500, 0],
                 price_sell_eur_per_kwh=0.0794)
    w = kpi.weekly_kpis(ts, 1.0)
    assert len(w) == 1
    assert w.loc[0, "cost_eur"] == pytest.approx(2.4)
    assert w.loc[0, "buy_kwh"] == pytest.approx(6.0)
    assert w.loc[0, "sell_kwh"] == pytest.approx(0.5)
    assert w.loc[0, "reimbursement_eur"] == pytest.approx(0.5 * 0.0794)


def test_fc_hours_toggles_and_mean_load() -> None:
    on = [0, 1, 1, 0, 1, 0]
    start = [0, 1, 0, 0, 1, 0]
    p_fc = [0, 1000, 1500, 0, 500, 0]
    ts = make_ts(6, fc_on=on, fc_start=start, p_fc_w=p_fc, p_h2_w=np.array(p_fc) * 2, eta_fc_el=[0, .5, .4, 0, .6, 0])
    w = kpi.weekly_kpis(ts, 1.0)
    assert w.loc[0, "fc_working_hours"] == 3.0
    assert w.loc[0, "fc_toggles"] == 2.0
    assert w.loc[0, "fc_kwh"] == pytest.approx(3.0)
    assert w.loc[0, "h2_kwh"] == pytest.approx(6.0)
    assert w.loc[0, "fc_mean_load_w"] == pytest.approx(1000.0)
    s = kpi.summarize(ts, w, loh_min=0.0)
    assert s["fc_mean_eta_el"] == pytest.approx(0.5)
    assert s["fc_toggles"] == 2


def test_heat_recovery_dhw_and_unmet() -> None:
    ts = make_ts(4, q_fc_rec_w=[1000, 0, 0, 0], q_fc_dump_w=[0, 500, 0, 0],
                 q_dhw_demand_w=[2000, 0, 0, 0], q_dhw_loss_w=35, q_dhw_unmet_w=[0, 0, 250, 0])
    w = kpi.weekly_kpis(ts, 1.0)
    assert w.loc[0, "heat_recovered_kwh"] == pytest.approx(1.5)
    assert w.loc[0, "heat_recovered_used_kwh"] == pytest.approx(1.0)
    assert w.loc[0, "dhw_demand_kwh"] == pytest.approx(2.0 + 4 * 0.035)
    assert w.loc[0, "dhw_unmet_kwh"] == pytest.approx(0.25)


def test_dhw_unmet_steps_and_first_step() -> None:
    """Steps above the tolerance count; the first is named by its start time."""
    ts = make_ts(6, q_dhw_unmet_w=[0, kpi.DHW_UNMET_TOL_W / 2, 0, 250, 0, 40])
    s = kpi.summarize(ts, kpi.weekly_kpis(ts, 1.0), loh_min=0.0)
    assert s["dhw_unmet_steps"] == 2
    assert s["dhw_unmet_first"] == pd.Timestamp("2022-12-01 03:00", tz="Europe/Berlin").isoformat()
    assert s["dhw_unmet_kwh"] == pytest.approx(0.29, abs=1e-6)
    ok = make_ts(3)
    s0 = kpi.summarize(ok, kpi.weekly_kpis(ok, 1.0), loh_min=0.0)
    assert s0["dhw_unmet_steps"] == 0 and s0["dhw_unmet_first"] is None


def test_weeks_split_and_partial_week() -> None:
    n = 168 * 2 + 24
    t_air = np.full(n, 21.0)
    t_air[200] = 17.0  # 1 K below 18 in week 2
    ts = make_ts(n, t_air_c=t_air)
    w = kpi.weekly_kpis(ts, 1.0)
    assert list(w["week"]) == [1, 2, 3]
    assert list(w["hours"]) == [168.0, 168.0, 24.0]
    assert list(w["discomfort_kh"]) == [0.0, 1.0, 0.0]
    s = kpi.summarize(ts, w, loh_min=0.0)
    assert s["discomfort_weeks_nonzero"] == 1
    assert s["weeks"] == 3 and s["steps"] == n


def test_weekly_equals_whole_run_totals() -> None:
    """Computing KPIs week by week sums to computing them once over the run (BOPTEST-style)."""
    rng = np.random.default_rng(1)
    n = 168 * 3
    ts = make_ts(n, p_buy_w=rng.uniform(0, 3000, n), price_buy_eur_per_kwh=rng.uniform(0.1, 0.6, n),
                 t_air_c=rng.uniform(16, 26, n), t_min_c=np.where(rng.random(n) < 0.5, 18.0, 21.0))
    w = kpi.weekly_kpis(ts, 1.0)
    s = kpi.summarize(ts, w, loh_min=0.0)
    assert w["cost_eur"].sum() == pytest.approx(s["cost_eur_total"])
    assert w["discomfort_kh"].sum() == pytest.approx(s["discomfort_kh_total"])
    assert w["buy_kwh"].sum() == pytest.approx(s["buy_kwh_total"])
    assert s["cost_eur_week_median"] == pytest.approx(float(np.median(w["cost_eur"])))


def test_h2_empty_at_and_residual() -> None:
    loh = np.linspace(0.5, 0.0, 10)
    ts = make_ts(10, loh=loh, balance_residual_w=[0, -2e-7, 1e-7, 0, 0, 0, 0, 0, 0, 0])
    w = kpi.weekly_kpis(ts, 1.0)
    s = kpi.summarize(ts, w, loh_min=0.0)
    # LOH reaches 0 in the last step (index 9), whose end is 10 h after the start
    assert s["h2_empty_at"] == pd.Timestamp("2022-12-01 10:00", tz="Europe/Berlin").isoformat()
    assert s["max_balance_residual_w"] == pytest.approx(2e-7)
    s2 = kpi.summarize(ts, w, loh_min=-0.1)
    assert s2["h2_empty_at"] is None


def test_missing_column_is_named() -> None:
    ts = make_ts(3).drop(columns=["p_buy_w"])
    with pytest.raises(ValueError, match="p_buy_w"):
        kpi.weekly_kpis(ts, 1.0)


def test_h2_value_net_cost_and_mean_price_hand_computed() -> None:
    # LOH ends at 0.1414 of a 1800 kWh store (the paper's ComEMS4Build); mean buy price
    # (0.30 + 0.468) / 2 = 0.384 EUR/kWh -> 0.1414 * 1800 * 0.384 = 97.74 EUR (paper 97.75)
    ts = make_ts(2, price_buy_eur_per_kwh=[0.30, 0.468], p_buy_w=[1000.0, 0.0], p_sell_w=[0.0, 1000.0],
                 price_sell_eur_per_kwh=0.0794, loh=[0.5, 0.1414], p_fc_w=[500.0, 700.0], p_h2_w=[1000.0, 1500.0])
    w = kpi.weekly_kpis(ts, 1.0)
    s = kpi.summarize(ts, w, loh_min=0.0, e_h2_max_kwh=1800.0)
    assert s["price_buy_mean_eur_per_kwh"] == pytest.approx(0.384)
    assert s["h2_left_kwh"] == pytest.approx(254.52)
    assert s["h2_left_value_eur"] == pytest.approx(0.1414 * 1800 * 0.384)
    # cost 0.30 EUR, reimbursement 0.0794 EUR
    assert s["cost_net_eur_total"] == pytest.approx(0.30 - 0.0794 - 0.1414 * 1800 * 0.384)
    assert s["price_paid_mean_eur_per_kwh"] == pytest.approx(0.30)
    # weekly H2 use: FC electrical 1.2 kWh, LHV 2.5 kWh
    assert (s["fc_kwh_week_min"], s["fc_kwh_week_max"]) == (pytest.approx(1.2), pytest.approx(1.2))
    assert (s["h2_kwh_week_min"], s["h2_kwh_week_max"]) == (pytest.approx(2.5), pytest.approx(2.5))
    # the usable H2 is counted above LOH_min
    assert kpi.h2_left_value_eur(0.25, 0.05, 1000.0, 0.4) == pytest.approx(0.2 * 1000 * 0.4)
    assert kpi.h2_left_value_eur(0.02, 0.05, 1000.0, 0.4) == 0.0
    assert "h2_left_value_eur" not in kpi.summarize(ts, w, loh_min=0.0)


@pytest.mark.parametrize("sample, expected", [("end", 1.0), ("start", 3.0), ("mean", 2.0)])
def test_discomfort_sample_within_the_step(sample, expected) -> None:
    # T_min 21 degC all along; T_air 19 before the first step, 20, 21, 21 at the ends of steps 0..2.
    # end: 20, 21, 21 -> 1 Kh; start: 19, 20, 21 -> 2 + 1 = 3 Kh; mean: 19.5, 20.5, 21 -> 1.5 + 0.5 = 2 Kh
    ts = make_ts(3, t_air_c=[20.0, 21.0, 21.0], t_min_c=21.0)
    w = kpi.weekly_kpis(ts, 1.0, discomfort_sample=sample, t_air_init_c=19.0)
    assert w.loc[0, "discomfort_kh"] == pytest.approx(expected)
    t = kpi.comfort_sample_c(ts, sample, t_air_init_c=19.0)
    s = kpi.summarize(ts, w, loh_min=0.0, t_comfort=t)
    assert s["discomfort_kh_total"] == pytest.approx(expected)
    with pytest.raises(ValueError, match="unknown discomfort sample"):
        kpi.comfort_sample_c(ts, "middle")


def test_kpis_are_reported_at_the_stated_resolution() -> None:
    """Float noise (1.6e-14 K*h of "discomfort") is 0 at the resolution every summary states."""
    t_air = np.full(168, 21.0)
    t_min = np.full(168, 18.0)
    t_air[5] = 18.0 - 1.6e-14
    ts = make_ts(168, t_air_c=t_air, t_min_c=t_min, p_buy_w=1e-7, price_buy_eur_per_kwh=0.3)
    w = kpi.weekly_kpis(ts, 1.0)
    s = kpi.summarize(ts, w, loh_min=0.0)
    assert w.loc[0, "discomfort_kh"] == 0.0 and s["discomfort_kh_week_median"] == 0.0
    assert s["discomfort_kh_total"] == 0.0 and s["buy_kwh_total"] == 0.0 and s["cost_eur_total"] == 0.0
    assert s["kpi_resolution"] == kpi.KPI_RESOLUTION and kpi.KPI_RESOLUTION["K*h"] == 1e-6
    assert kpi.at_resolution("discomfort_kh", 0.1234567891) == 0.123457
    assert kpi.at_resolution("loh_end", 0.1234567891234) == 0.123456789
    assert kpi.at_resolution("fc_toggles", 3) == 3 and kpi.at_resolution("h2_empty_at", None) is None


def test_medians_over_full_weeks_only() -> None:
    """A last partial week has its own row, marked, and stays out of the weekly medians and extremes."""
    n = 168 * 3 + 10
    p_buy = np.concatenate([np.full(168, 100.0), np.full(168, 200.0), np.full(168, 300.0), np.full(10, 5000.0)])
    ts = make_ts(n, p_buy_w=p_buy, price_buy_eur_per_kwh=1.0, p_h2_w=p_buy)
    w = kpi.weekly_kpis(ts, 1.0)
    assert list(w["full_week"]) == [True, True, True, False]
    s = kpi.summarize(ts, w, loh_min=0.0)
    assert s["buy_kwh_week_median"] == pytest.approx(33.6)  # median of 16.8, 33.6, 50.4: not of four rows
    assert s["h2_kwh_week_max"] == pytest.approx(50.4) and s["h2_kwh_week_min"] == pytest.approx(16.8)
    assert s["weeks"] == 4 and s["full_weeks"] == 3 and s["partial_week_h"] == 10.0
    assert s["week_medians_over"] == "3 full week(s)"
    short = make_ts(30)
    s_short = kpi.summarize(short, kpi.weekly_kpis(short, 1.0), loh_min=0.0)
    assert s_short["full_weeks"] == 0 and "shorter than a week" in s_short["week_medians_over"]


def test_fallback_steps_count_the_ems_and_the_plant() -> None:
    ts = make_ts(6)
    ts["fallback"] = [False, True, False, False, False, False]
    ts["ems_fallback"] = [0.0, 1.0, 1.0, 1.0, 0.0, 0.0]
    s = kpi.summarize(ts, kpi.weekly_kpis(ts, 1.0), loh_min=0.0)
    assert s["fallback_steps"] == 3 and s["ems_fallback_steps"] == 3
