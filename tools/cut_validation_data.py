"""Cut the validation set's package data from the ten-year source files (run once; documented in the data README).

The sources are the ten years of ENTSO-E day-ahead prices and the hourly DWD station
files of München-Flughafen (01262) and Hamburg-Fuhlsbüttel (01975) described in
``comems4build_ros/data/README.md``. The validation set needs the winters only: for every
winter from 2015/16 to 2023/24 the prices from 1 December 00:00 to 1 March 00:00 local
time and the station hours from 30 November 00 UTC to 1 March 23 UTC. The files keep
the sources' columns and rows unchanged (a cut, no conversion). A winter the price file
does not cover (2021/22 is held back there) is left out of the price file.

Usage::

    python tools/cut_validation_data.py SOURCE_DIR comems4build_ros/data
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

#: First winters (the year of December) of the validation set.
WINTERS = range(2015, 2024)
PRICES_IN = "DE_day_ahead_EURperMWh_2015-01-05_2024-12-19_hourly_validation.csv"
PRICES_OUT = "DE_day_ahead_EURperMWh_winters_2015-2024_validation.csv"
STATIONS = {
    "DWD_01262_Muenchen-Flughafen_tu_sd_stunde_2015010100_2024121723.csv":
        "DWD_01262_Muenchen-Flughafen_tu_sd_stunde_winters_2015-2024.csv",
    "DWD_01975_Hamburg-Fuhlsbuettel_tu_sd_stunde_2015010100_2024121723.csv":
        "DWD_01975_Hamburg-Fuhlsbuettel_tu_sd_stunde_winters_2015-2024.csv",
}


def cut_prices(src: Path, dst: Path) -> int:
    """Rows of the winters' local December to February; the number of rows written."""
    lines = src.read_text(encoding="utf-8").splitlines()
    frame = pd.read_csv(src, dtype=str)
    local = pd.to_datetime(frame["utc_start"], utc=True).dt.tz_convert("Europe/Berlin")
    keep = pd.Series(False, index=frame.index)
    for y in WINTERS:
        t0 = pd.Timestamp(f"{y}-12-01", tz="Europe/Berlin")
        t1 = pd.Timestamp(f"{y + 1}-03-01", tz="Europe/Berlin")
        keep |= (local >= t0) & (local < t1)
    rows = [lines[0]] + [lines[i + 1] for i in keep[keep].index]
    dst.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return len(rows) - 1


def cut_station(src: Path, dst: Path) -> int:
    """Rows of the winters' 30 November 00 UTC to 1 March 23 UTC; the number of rows written."""
    lines = src.read_text(encoding="utf-8").splitlines()
    stamps = [line.split(";", 1)[0] for line in lines[1:]]
    keep = []
    for i, s in enumerate(stamps):
        y, md = int(s[:4]), s[4:8]
        winter = y if md >= "1130" else y - 1
        if winter in WINTERS and (md >= "1130" or md <= "0301"):
            keep.append(i)
    rows = [lines[0]] + [lines[i + 1] for i in keep]
    dst.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return len(rows) - 1


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    src, dst = Path(argv[0]), Path(argv[1])
    print(PRICES_OUT, cut_prices(src / PRICES_IN, dst / PRICES_OUT))
    for name, out in STATIONS.items():
        print(out, cut_station(src / name, dst / out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
