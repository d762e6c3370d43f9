"""The tariff of each year (config/tariffs.yaml) and how a validation case names its tariff."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from comems4build_ros.core.config import ConfigError, config_dir, load_plant_params
from comems4build_ros.core.scenario import ScenarioError, default_scenario, resolve_scenario
from comems4build_ros.core.scenario import tariff as tf
from comems4build_ros.core.scenario import validation as va

TABLES = tf.load_tariffs()
SETTINGS = va.load_validation_settings()
PARAMS = load_plant_params()
BERLIN = "Europe/Berlin"


def _hours(*stamps: str) -> pd.DatetimeIndex:
    return pd.DatetimeIndex([pd.Timestamp(s, tz=BERLIN) for s in stamps])


def _household(commissioned: int = 2018, tables: tf.Tables = TABLES) -> tf.HouseholdTariff:
    return tf.HouseholdTariff(tables, BERLIN, commissioned)


# --------------------------------------------------------------------------- the data


def test_every_value_names_a_published_source():
    """Each component, share, feed-in rate and published average of every year names a source
    of ``sources`` that gives a URL; only a published average may be left out, and then its
    source says it was not found."""
    data = TABLES.data
    assert data.years and data.sources
    for year, entry in data.years.items():
        for name, item in entry.sourced().items():
            assert item.source in data.sources, (year, name)
            if item.known:
                assert "http" in data.sources[item.source], (year, name)
            else:
                assert name.endswith("average_gross_eur_per_kwh") and "not found" in data.sources[item.source]
        for name in tf.NET_COMPONENTS + ("spot_surcharge_share", "vat_share"):
            assert getattr(entry, name).known, (year, name)


def test_every_winter_of_the_validation_set_has_its_years_and_feed_in_rate():
    """A household winter needs the components of its two calendar years and the feed-in rate of its December."""
    for case in va.validation_cases(SETTINGS):
        if case.tariff != tf.HOUSEHOLD:
            continue
        for year in (case.winter, case.winter + 1):
            assert str(year) in TABLES.data.years, case.id
        assert TABLES.data.years[str(case.winter)].feed_in_dec_eur_per_kwh is not None, case.id


def test_the_years_changes_of_the_law_are_in_the_data():
    """EEG surcharge 3.723 ct/kWh until 30 June 2022 and 0 after (and from 2023); VAT 16 % in H2 2020."""
    y2022, y2020 = TABLES.data.years["2022"], TABLES.data.years["2020"]
    assert y2022.eeg_eur_per_kwh.halves == (0.03723, 0.0)
    assert TABLES.data.years["2023"].eeg_eur_per_kwh.halves == (0.0, 0.0)
    assert y2020.vat_share.halves == (0.19, 0.16)
    assert all(TABLES.data.years[y].vat_share.halves == (0.19, 0.19) for y in TABLES.data.years if y != "2020")


# --------------------------------------------------------------------------- the formula


def test_composition_by_hand_for_2018():
    """2018-01-15 12:00 at 50 EUR/MWh: 1.19 * (1.03 * 0.050 + 0.015 + 0.0729 + 0.06792 + 0.00345 + 0.00370
    + 0.00037 + 0.00011 + 0.0205 + 0.0166) = 1.19 * 0.25205 = 0.2999395 EUR/kWh; sold at December 2018's
    11.59 ct/kWh."""
    buy, sell = _household(2018).prices(_hours("2018-01-15 12:00"), np.array([50.0]))
    by_hand = 1.19 * (1.03 * 0.050 + 0.015 + 0.0729 + 0.06792 + 0.00345 + 0.00370 + 0.00037 + 0.00011 + 0.0205
                      + 0.0166)
    assert buy[0] == pytest.approx(by_hand, rel=1e-12)
    assert buy[0] == pytest.approx(0.2999395, abs=1e-9)
    assert sell[0] == 0.1159


def test_each_hour_takes_its_calendar_year_and_half_year():
    """A winter's December takes the first year's components, January the next year's; July 2022 drops the
    EEG surcharge, July 2020 lowers VAT to 16 % (hours in local time: 2022-12-31 23:00 is still 2022)."""
    spot = np.zeros(6)
    buy = tf.HouseholdTariff(TABLES, BERLIN, 2022).prices(
        _hours("2022-06-30 23:00", "2022-07-01 00:00", "2022-12-31 23:00", "2023-01-01 00:00", "2020-06-30 23:00",
               "2020-07-01 00:00"), spot)[0]
    assert buy[0] - buy[1] == pytest.approx(1.19 * 0.03723)
    assert buy[2] == pytest.approx(tf.non_energy_gross(TABLES.data.years["2022"], 12))
    assert buy[3] == pytest.approx(tf.non_energy_gross(TABLES.data.years["2023"], 1))
    assert buy[4] / buy[5] == pytest.approx(1.19 / 1.16)
    utc = _hours("2022-12-31 23:00").tz_convert("UTC")  # 22:00 UTC: the same hour, the same year
    assert tf.HouseholdTariff(TABLES, BERLIN, 2022).prices(utc, np.zeros(1))[0][0] == buy[2]


YEARS = sorted(int(y) for y in TABLES.data.years)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(year=st.sampled_from(YEARS), month=st.integers(1, 12),
       spot=st.floats(0.0, 3000.0, allow_nan=False), extra=st.floats(0.0, 500.0, allow_nan=False))
def test_buy_price_is_at_least_the_non_energy_components(year: int, month: int, spot: float, extra: float):
    """For any day-ahead price in 0..3,500 EUR/MWh (EPEX's cap was 3,000 until 2022) the buy price is at
    least the gross sum of the components without the energy price (equal at 0) and rises with the spot
    price."""
    hours = _hours(f"{year}-{month:02d}-15 12:00", f"{year}-{month:02d}-15 13:00")
    buy, sell = _household(YEARS[0]).prices(hours, np.array([spot, spot + extra]))
    floor = tf.non_energy_gross(TABLES.data.years[str(year)], month)
    assert buy[0] >= floor - 1e-12
    assert buy[1] >= buy[0] - 1e-12
    assert buy[0] > sell[0]  # at a spot price >= 0 no hour is sold dearer than bought
    if spot == 0.0:
        assert buy[0] == pytest.approx(floor)


def test_paper_tariff_is_the_grid_formula():
    """The paper's tariff: a + b * spot / 1000 and the constant 7.94 ct/kWh (config/plant.yaml grid)."""
    buy, sell = tf.PaperTariff(PARAMS).prices(_hours("2023-01-10 08:00", "2023-01-10 09:00"), np.array([100.0, -5.0]))
    g = PARAMS.grid
    assert buy.tolist() == [g.buy_offset_eur_per_kwh + g.buy_spot_factor * 0.1,
                            g.buy_offset_eur_per_kwh + g.buy_spot_factor * -5.0 / 1000.0]
    assert sell.tolist() == [0.0794, 0.0794]


# --------------------------------------------------------------------------- the cases


def test_cases_name_their_tariff_and_the_papers_winter_keeps_the_papers():
    cases = va.validation_cases(SETTINGS)
    paper_winter = default_scenario(PARAMS, weeks=1).time[0].year
    for c in cases:
        assert c.tariff == (tf.PAPER if c.winter == paper_winter else SETTINGS.tariff), c.id
    assert {c.tariff for c in cases if c.kind == va.HOUSEHOLD} == {tf.PAPER}
    assert SETTINGS.tariff == tf.HOUSEHOLD


def test_a_winter_case_is_priced_by_its_years_tariff():
    """hamburg-2020-21: December 2020 at 16 % VAT and 2020's components, January 2021 at 19 % and 2021's;
    sold at the feed-in rate of December 2020 in every hour; the tariff recorded in the scenario's meta."""
    case = va.case_of("hamburg-2020-21", SETTINGS)
    params = load_plant_params(overrides=case.plant_overrides(SETTINGS))
    sc = resolve_scenario(case.scenario, params, weeks=6)
    local = sc.time.tz_convert(BERLIN)
    spot = sc.spot_eur_per_mwh / 1000.0
    for i in (0, 500, len(sc.time) - 1):
        entry = TABLES.data.years[str(local[i].year)]
        assert sc.price_buy_eur_per_kwh[i] == pytest.approx(
            tf.composed_buy(entry, np.array([local[i].month]), np.array([spot[i]]))[0], rel=1e-12)
    assert local[0].year == 2020 and local[-1].year == 2021
    assert np.all(sc.price_sell_eur_per_kwh == 0.0832)
    assert sc.meta["tariff"]["name"] == "household" and sc.meta["tariff"]["pv_commissioned"] == "2020-12"
    assert (sc.price_buy_eur_per_kwh > 0).all() and (sc.price_buy_eur_per_kwh > sc.price_sell_eur_per_kwh).all()


def test_the_papers_winter_cases_keep_the_papers_prices():
    """A 2022/23 winter case and a household case are priced as the default scenario: a + b * spot, 7.94 ct/kWh."""
    ref = default_scenario(PARAMS, weeks=2)
    hh = resolve_scenario("validation/household-102", PARAMS, weeks=2)
    assert np.array_equal(hh.price_buy_eur_per_kwh, ref.price_buy_eur_per_kwh)
    assert np.array_equal(hh.price_sell_eur_per_kwh, ref.price_sell_eur_per_kwh)
    assert "tariff" not in hh.meta and "tariff" not in ref.meta
    case = va.case_of("muenchen-2022-23", SETTINGS)
    sc = resolve_scenario(case.scenario, load_plant_params(overrides=case.plant_overrides(SETTINGS)), weeks=2)
    g = PARAMS.grid
    assert np.array_equal(sc.price_buy_eur_per_kwh,
                          g.buy_offset_eur_per_kwh + g.buy_spot_factor * sc.spot_eur_per_mwh / 1000.0)


def test_no_winter_prices_below_zero_or_below_the_feed_in_rate():
    """The artefacts of the paper's tariff on cheap winters are gone: over every winter's run hours."""
    rows = va.winter_prices(PARAMS, SETTINGS)
    assert [r.winter for r in rows] == SETTINGS.winters
    for r in rows:
        assert r.negative_h == 0 and r.below_sell_h == 0, r.winter
        if r.tariff == tf.HOUSEHOLD:
            assert r.buy_mean == r.household_mean and 0.2 < r.buy_mean < 0.5


def test_an_extension_is_priced_by_the_cases_tariff():
    """A run longer than the winter's data (extend synthetic) prices the generated March hours by the
    household tariff of their year too."""
    case = va.case_of("muenchen-2019-20", SETTINGS)
    params = load_plant_params(overrides=case.plant_overrides(SETTINGS))
    sc = resolve_scenario(case.scenario, params, weeks=14, extend="synthetic")
    assert sc.meta["extended"]["rows"] > 0
    local = sc.time.tz_convert(BERLIN)
    last = len(sc.time) - 1
    assert local[last].month == 3 and local[last].year == 2020
    expect = tf.composed_buy(TABLES.data.years["2020"], np.array([3]), np.array([sc.spot_eur_per_mwh[last] / 1e3]))
    assert sc.price_buy_eur_per_kwh[last] == pytest.approx(expect[0], rel=1e-12)


# --------------------------------------------------------------------------- bad data


def _file(tmp_path, old: str, new: str) -> tf.Tables:
    text = (config_dir() / tf.TARIFF_FILE).read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "t.yaml"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return tf.load_tariffs(path)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("eeg_eur_per_kwh: {value: 0.06170, source: netztransparenz_eeg}",
     "eeg_eur_per_kwh: {value: 0.06170, source: nowhere}",
     r"t.yaml: years.2015.eeg_eur_per_kwh.source: 'nowhere' is not among the sources \(netztransparenz_eeg, "),
    ("vat_share: {jan_jun: 0.19, jul_dec: 0.16, source: vat}", "vat_share: {jan_jun: 0.19, source: vat}",
     r"t.yaml: parameter 'years.2020.vat_share': give both 'jan_jun' and 'jul_dec'"),
    ("network_eur_per_kwh: {value: 0.0674, source: network_bdew}",
     "network_eur_per_kwh: {value: 67.4, source: network_bdew}",
     r"t.yaml: parameter 'years.2015': network_eur_per_kwh: 67.4 is outside"),
    ('"2016":', '"16":', r"t.yaml: years.16: a year is four digits"),
    ("kwkg_eur_per_kwh: {value: 0.00254, source: kwkg_2015}", "kwkg_eur_per_kwh: {value: 0.00254}",
     r"t.yaml: parameter 'years.2015.kwkg_eur_per_kwh.source': Field required"),
    ("concession_fee_eur_per_kwh: {value: 0.0166, source: concession_bdew}",
     "concession_fee_eur_per_kwh: {value: 0.0166, source: not_found}",
     r"t.yaml: years.2015.concession_fee_eur_per_kwh.source: sources.not_found names no URL"),
    ("spot_surcharge_share: {value: 0.03, source: awattar}", "spot_surcharge_share: {value: 3, source: awattar}",
     r"spot_surcharge_share: 3 is outside \[0, 1\]"),
])
def test_bad_tariff_data_is_refused_naming_the_file_and_field(tmp_path, old, new, message):
    with pytest.raises(ConfigError, match=message):
        _file(tmp_path, old, new)


def test_a_year_or_feed_in_rate_the_data_lack_is_named(tmp_path):
    tables = _file(tmp_path, "          feed_in_dec_eur_per_kwh: {value: 0.1159, source: feedin_2018}\n", "")
    with pytest.raises(ScenarioError, match=r"t.yaml: years.2018.feed_in_dec_eur_per_kwh is not given; needed for "
                                            r"the feed-in rate of a PV system commissioned in December 2018"):
        _household(2018, tables).prices(_hours("2018-12-01 00:00"), np.zeros(1))
    with pytest.raises(ScenarioError, match=r"tariffs.yaml: no tariff for 2025 \(the file holds 2015, .*2024\); "
                                            r"needed for the hour 2025-01-01T00:00:00\+01:00"):
        _household(2018).prices(_hours("2024-12-31 23:00", "2025-01-01 00:00"), np.zeros(2))
    with pytest.raises(ScenarioError, match="unknown tariff 'flat'"):
        tf.make_tariff("flat", PARAMS)


# --------------------------------------------------------------------------- the documentation


def test_the_docs_table_is_the_commands_output():
    """docs/validation.md holds what `comems4build data tariffs` prints, between its markers."""
    from comems4build_ros.core.config import SOURCE_ROOT
    from comems4build_ros.report.tariffs import DOC_BEGIN, DOC_END, tariff_section

    text = (SOURCE_ROOT / "docs" / "validation.md").read_text(encoding="utf-8")
    block = text.split(DOC_BEGIN, 1)[1].split(DOC_END, 1)[0].strip()
    assert block == tariff_section(va.winter_prices(PARAMS, SETTINGS), TABLES).strip()


def test_data_tariffs_command(tmp_path, capsys):
    from comems4build_ros.app.cli import main

    assert main(["data", "tariffs"]) == 0
    out = capsys.readouterr().out
    assert "| 2015/16 | household |" in out and "| 2022/23 | paper |" in out
    doc = tmp_path / "d.md"
    doc.write_text("# x\n<!-- tariffs:begin -->\nold\n<!-- tariffs:end -->\ntail\n", encoding="utf-8")
    assert main(["data", "tariffs", "--update-doc", str(doc)]) == 0
    new = doc.read_text(encoding="utf-8")
    assert "\nold\n" not in new and "| 2019/20 | household |" in new and new.endswith("tail\n")
    (tmp_path / "none.md").write_text("no markers\n", encoding="utf-8")
    assert main(["data", "tariffs", "--update-doc", str(tmp_path / "none.md")]) == 2
    err = capsys.readouterr().err
    assert f"--update-doc {tmp_path / 'none.md'}: markers <!-- tariffs:begin --> / <!-- tariffs:end --> must " \
           "each stand once" in err and "<!-- tariffs:begin --> missing" in err, err
