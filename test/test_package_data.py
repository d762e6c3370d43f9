"""The measured data shipped as package data: unchanged files with their provenance beside them."""

import hashlib

import numpy as np
import pandas as pd
import pytest

from comems4build_ros.core.scenario.measured import data_dir

#: SHA-256 of each shipped data file (sources in comems4build_ros/data/README.md).
CHECKSUMS = {
    "DE_LU_day_ahead_EURperMWh_2022-12-01_2023-02-28_hourly.csv":
        "7067e5caaba2a6d0a5c053cfa7bd0abcc9b6a152774c59e9bed5670c4a9be92a",
    "DWD_04177_Rheinstetten_tu_stunde_2022110100_2023021423.txt":
        "5858bd724324d29d184ce666aace58e9352c850e17c9553e115c6f0bbcb533cd",
    "DE_LU_day_ahead_EURperMWh_2022-03-01_2023-02-28_hourly.csv":
        "f8aba6a88b5fca3217475ddd1f43692dcc47e2ed221eab5689a474c860fce150",
    "DWD_04177_Rheinstetten_tu_stunde_2022022823_2023021423.txt":
        "089f6303eba42ed8251bff6da4f547f2a70360be1b56bd1ea0527b410d8744e6",
    "OpenDHW_DHWcalc_200L_60min_4cat_sf_nods_max1200.txt":
        "52192ec1aedda0324945f65d98cfcfef8f3cb72032428e5730427f8e1fb1fa34",
    "OpenDHW_DHWcalc_200L_60min_4cat_sf_nods_max1200_log.txt":
        "d8eb7072a66e8e5479bb5ec4114312531a4e0c249e77cdf06d84d5bc1dffcaa5",
    "DE_day_ahead_EURperMWh_winters_2015-2024_validation.csv":
        "17ff15b1a3e14e5b6511a2a42b772b4d9537776c3c93c4ff856876c92d817fed",
    "DWD_01262_Muenchen-Flughafen_tu_sd_stunde_winters_2015-2024.csv":
        "b3142287d7ec59c76ca94239f975433950689555f1aa703b83eab0cee582e838",
    "DWD_01975_Hamburg-Fuhlsbuettel_tu_sd_stunde_winters_2015-2024.csv":
        "94467d29005fdf45f054bf221cf8610fd73d7d10b754e831bc496b17eb75c708",
}
#: Largest tracked file [bytes].
MAX_BYTES = 5 * 1024 * 1024


@pytest.mark.parametrize("name", sorted(CHECKSUMS))
def test_checksum(name):
    assert hashlib.sha256((data_dir() / name).read_bytes()).hexdigest() == CHECKSUMS[name]


def test_shapes():
    lines = (data_dir() / "DE_LU_day_ahead_EURperMWh_2022-12-01_2023-02-28_hourly.csv").read_text().splitlines()
    assert lines[0] == "utc_start,local_start_Europe_Berlin,price_EUR_per_MWh" and len(lines) == 2161
    dwd = (data_dir() / "DWD_04177_Rheinstetten_tu_stunde_2022110100_2023021423.txt").read_text().splitlines()
    assert dwd[0] == "STATIONS_ID;MESS_DATUM;QN_9;TT_TU;RF_TU;eor" and len(dwd) == 1 + 106 * 24
    year = (data_dir() / "DE_LU_day_ahead_EURperMWh_2022-03-01_2023-02-28_hourly.csv").read_text().splitlines()
    assert year[0] == lines[0] and len(year) == 8761 and set(lines[1:]) <= set(year[1:])
    dwd_year = (data_dir() / "DWD_04177_Rheinstetten_tu_stunde_2022022823_2023021423.txt").read_text().splitlines()
    assert dwd_year[0] == dwd[0] and len(dwd_year) == 1 + 8425
    dhw = np.loadtxt(data_dir() / "OpenDHW_DHWcalc_200L_60min_4cat_sf_nods_max1200.txt")
    assert dhw.shape == (8760,) and dhw.mean() * 24 == pytest.approx(200.0, abs=0.5)


def test_validation_files_hold_the_winters():
    """Prices of 8 winters (1 Dec to 1 Mar local; 2021/22 held back at the source), station hours of 9."""
    prices = pd.read_csv(data_dir() / "DE_day_ahead_EURperMWh_winters_2015-2024_validation.csv")
    assert list(prices.columns) == ["utc_start", "local_start_Europe_Berlin", "price_EUR_per_MWh"]
    local = pd.to_datetime(prices["utc_start"], utc=True).dt.tz_convert("Europe/Berlin")
    winters = (local.dt.year - (local.dt.month < 6)).value_counts().sort_index()
    assert winters.index.tolist() == [2015, 2016, 2017, 2018, 2019, 2020, 2022, 2023]
    leap = {2015: 24, 2019: 24, 2023: 24}  # February 2016, 2020 and 2024 have 29 days
    assert all(n == 90 * 24 + leap.get(y, 0) for y, n in winters.items())
    assert local.iloc[0].isoformat() == "2015-12-01T00:00:00+01:00"
    for name in ("DWD_01262_Muenchen-Flughafen_tu_sd_stunde_winters_2015-2024.csv",
                 "DWD_01975_Hamburg-Fuhlsbuettel_tu_sd_stunde_winters_2015-2024.csv"):
        st = pd.read_csv(data_dir() / name, sep=";", dtype={"MESS_DATUM": str})
        assert list(st.columns) == ["MESS_DATUM", "TT_TU", "RF_TU", "SD_SO"] and len(st) == 19944
        assert (st["TT_TU"] != -999).all() and st["SD_SO"].dropna().between(0, 60).all()


def test_every_data_file_under_5_mb():
    assert all((p.stat().st_size < MAX_BYTES) for p in data_dir().iterdir())


def test_provenance_and_licences_beside_the_data():
    text = (data_dir() / "README.md").read_text(encoding="utf-8")
    for name in CHECKSUMS:
        if not name.endswith("_log.txt"):
            assert f"`{name}`" in text
    for source in ("ENTSO-E Transparency Platform", "Deutscher Wetterdienst", "CC BY 4.0", "OpenDHW", "MIT"):
        assert source in text
