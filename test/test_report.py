"""Report house from run directories: figures, numbers parsed back, findings, bad run directories.

One short comparison (1 week; thermostat, RBC and fuzzy at 75 % and 90 % FC system
efficiency, in-process) is run once per module through the ``compare`` command; the tests
read what it wrote. The paper's windows, hysteresis counting and the heat-recovery cover are
checked on hand-made series.
"""

from __future__ import annotations

import json
import re
import shutil
from dataclasses import replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.report import figures as rf
from comems4build_ros.report import findings as fd
from comems4build_ros.report.build import SUMMARY_TABLE, WEEKLY_TABLE, build_report, read_report_inputs, weekly_rows
from comems4build_ros.report.figures import CAPTIONS
from comems4build_ros.report.paper import Windows, load_paper_results, paper_windows
from comems4build_ros.report.runs import RunData, RunDirError, RunSpec, read_run
from comems4build_ros.report.style import layout_problems, paper_style

EMS = ("thermostat", "rbc", "fuzzy")
FIGURES = (
    "quality_indicators_occupants",
    "HESS_usage",
    "working_hours_FC",
    "hydrogen_timeseries",
    "grid_usage",
    "heat_recovery",
    "performance_comparison",
    "performance_comparison_highSolar",
    "heatmap_comparison",
    "level_of_information",
)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def comparison(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("compare")
    rc = main(["compare", "--ems", ",".join(EMS), "--weeks", "1", "--fc-efficiency", "0.75,0.90",
               "--out", str(out)])
    assert rc == 0
    return out


def _summary(root: Path, name: str) -> dict:
    return json.loads((root / "runs" / name / "summary.json").read_text())


def _md_table(md: str, heading: str) -> list[list[str]]:
    """Rows (header first) of the first Markdown table after ``heading``."""
    part = md[md.index(heading):]
    lines = []
    for line in part.splitlines()[1:]:
        if line.startswith("|"):
            lines.append([c.strip() for c in line.strip().strip("|").split(" | ")])
        elif lines:
            break
    return [lines[0], *lines[2:]]


def test_run_directories_written(comparison: Path) -> None:
    for ems in EMS:
        for name in (ems, f"{ems}_eta90"):
            d = comparison / "runs" / name
            for f in ("timeseries.csv", "weekly.csv", "summary.json"):
                assert (d / f).stat().st_size > 0, d / f
    assert _summary(comparison, "rbc")["eta_sys"] == 0.75
    assert _summary(comparison, "rbc_eta90")["eta_sys"] == 0.90
    # the 90 % variant recovers 0.90/0.75 times the heat of the same FC operation at most
    base, hi = _summary(comparison, "rbc"), _summary(comparison, "rbc_eta90")
    if base["heat_recovered_kwh_total"] > 0:
        assert hi["heat_recovered_kwh_total"] > base["heat_recovered_kwh_total"]


def test_every_figure_written_as_pdf_svg_and_300_dpi_png(comparison: Path) -> None:
    from PIL import Image

    for key in FIGURES:
        png = comparison / "figures" / f"{key}.png"
        data = png.read_bytes()
        assert data[:8] == PNG_MAGIC, png
        assert len(data) > 5000, png
        with Image.open(png) as im:
            assert im.info["dpi"] == pytest.approx((300, 300), abs=0.5), png
        assert (comparison / "figures" / f"{key}.pdf").read_bytes()[:5] == b"%PDF-", key
        assert b"<svg" in (comparison / "figures" / f"{key}.svg").read_bytes()[:2000], key


def test_every_figure_passes_the_layout_check(comparison: Path) -> None:
    """Nothing clipped or overlapping, no raw names or LaTeX labels, legends off the data, dates flat."""
    with paper_style():
        for key, fig in rf.iter_figures(read_report_inputs(comparison).figures):
            assert layout_problems(fig) == [], key
            plt.close(fig)


def test_html_is_self_contained_and_links_the_vector_figures(comparison: Path) -> None:
    text = (comparison / "report.html").read_text()
    assert text.count('src="data:image/png;base64,') == len(FIGURES)
    assert 'src="figures/' not in text
    for key in FIGURES:
        for ext in ("pdf", "svg", "png"):
            assert f'href="figures/{key}.{ext}"' in text, (key, ext)
    # same numbers as the Markdown: the cost median of every EMS appears in both
    md = (comparison / "report.md").read_text()
    for ems in EMS:
        value = f"{_summary(comparison, ems)['cost_eur_week_median']:.2f}"
        assert value in md and value in text


def test_summary_table_equals_summaries(comparison: Path) -> None:
    md = (comparison / "report.md").read_text()
    rows = _md_table(md, "## Run summary")
    header = rows[0]
    assert header[2:] == ["ComEMS4Build", "RBC", "Thermostat"]  # paper order (MPC, fuzzy, RBC), others after
    assert header[1] == "unit"
    by_label = {r[0]: r[2:] for r in rows[1:]}
    units = {r[0]: r[1] for r in rows[1:]}
    names = ["fuzzy", "rbc", "thermostat"]
    for key, lab, unit, digits in SUMMARY_TABLE:
        assert units[lab] == (unit or "")
        for col, ems in enumerate(names):
            value = _summary(comparison, ems).get(key)
            printed = by_label[lab][col]
            if value is None:
                assert printed == "-"
            elif digits is None:
                assert printed == str(value)
            else:
                assert float(printed) == pytest.approx(round(float(value), digits), abs=0.5 * 10**-digits), (key, ems)


def test_weekly_tables_equal_weekly_csv(comparison: Path) -> None:
    md = (comparison / "report.md").read_text()
    for ems, heading in (("rbc", "### RBC (rbc)"), ("fuzzy", "### ComEMS4Build (fuzzy)")):
        rows = _md_table(md, heading)
        weekly = pd.read_csv(comparison / "runs" / ems / "weekly.csv")
        assert len(rows) == 1 + len(weekly) + 1  # header, weeks, median
        s = _summary(comparison, ems)
        assert "cost [EUR]" in rows[0] and "FC hours [h]" in rows[0]  # units in the headers
        median = dict(zip(rows[0], rows[-1]))
        assert float(median["cost [EUR]"]) == pytest.approx(s["cost_eur_week_median"], abs=0.005)
        assert float(median["bought [kWh]"]) == pytest.approx(s["buy_kwh_week_median"], abs=0.005)
        assert float(median["discomfort [Kh]"]) == pytest.approx(s["discomfort_kh_week_median"], abs=0.005)
        first = dict(zip(rows[0], rows[1]))
        for col, head, unit, digits in WEEKLY_TABLE:
            assert float(first[f"{head} [{unit}]"]) == pytest.approx(weekly[col].iloc[0],
                                                                   abs=0.5 * 10**-digits + 1e-9)


def test_paper_table_measured_values(comparison: Path) -> None:
    md = (comparison / "report.md").read_text()
    rows = _md_table(md, "## The paper's stated figures")
    header = rows[0]
    assert header == ["quantity", "unit", "source", "EMS", "paper", "measured", "error"]
    by = {(r[0], r[3]): dict(zip(header, r)) for r in rows[1:]}
    cost = by[("electricity cost, weekly median", "ComEMS4Build")]
    assert cost["paper"] == "25.02"
    measured = _summary(comparison, "fuzzy")["cost_eur_week_median"]
    assert float(cost["measured"]) == pytest.approx(measured, abs=0.005)
    assert cost["error"] == f"{100 * abs(measured - 25.02) / 25.02:.1f} %"
    assert by[("electricity cost, weekly median", "MPC")]["measured"] == "not run"
    loh = by[("LOH left after the 12 weeks", "RBC")]
    assert float(loh["measured"]) == pytest.approx(100 * _summary(comparison, "rbc")["loh_end"], abs=0.005)
    # the heat recovered at 90 % is measured on the runs at 90 %
    heat = by[("heat recovered from the FC in week 5 (90 %)", "MPC")]
    assert heat["measured"] == "not run"  # a one-week run has no week 5, and no MPC ran
    # a figure locating a window is shown, not compared
    trough = next(r for r in rows[1:] if r[0].startswith("lowest buy price in the high-PV window"))
    assert trough[6] == "locates the window"


def test_findings_follow_the_summaries(comparison: Path) -> None:
    found = {f["key"]: f for f in json.loads((comparison / "findings.json").read_text())}
    assert len(found) == len(fd.FINDINGS)
    rbc, fuzzy = _summary(comparison, "rbc"), _summary(comparison, "fuzzy")
    expect = "held" if fuzzy["cost_eur_week_median"] < rbc["cost_eur_week_median"] else "not held"
    assert found["fuzzy_cheaper_than_rbc"]["verdict"] == expect
    expect = "held" if fuzzy["fc_mean_load_w"] < rbc["fc_mean_load_w"] else "not held"
    assert found["fuzzy_fc_lower_load"]["verdict"] == expect
    assert found["mpc_cheapest"]["verdict"] == "n/a"  # no MPC run
    # H2 spent evenly: the LOH's largest distance from the straight line to its end level, per run
    # (one week is enough); ComEMS4Build's within a week's allowance and the closest of the EMS with H2
    import pandas as pd

    from comems4build_ros.core.config import load_plant_params

    params = load_plant_params()
    dev = {}
    for e in ("rbc", "fuzzy"):  # the thermostat has no H2 system to spend
        loh = pd.read_csv(comparison / "runs" / e / "timeseries.csv")["loh"].to_numpy(dtype=float)
        loh0 = params.simulation.loh_init
        line = loh0 + (loh[-1] - loh0) * np.arange(1, loh.size + 1) / loh.size
        dev[e] = float(np.max(np.abs(loh - line)))
    tol = fd.h2_even_tolerance(params)
    even = dev["fuzzy"] <= tol and all(dev["fuzzy"] < v for e, v in dev.items() if e != "fuzzy")
    assert found["fuzzy_h2_even"]["verdict"] == ("held" if even else "not held"), dev
    # the evidence quotes the figures
    assert f"{fuzzy['cost_eur_week_median']:.2f}" in found["fuzzy_cheaper_than_rbc"]["evidence"]
    md = (comparison / "report.md").read_text()
    rows = _md_table(md, "## Findings of the paper")
    assert [r[3] for r in rows[1:]] == [f["verdict"] for f in json.loads((comparison / "findings.json").read_text())]


def test_level_of_information_table(comparison: Path) -> None:
    md = (comparison / "report.md").read_text()
    rows = _md_table(md, "## Inputs each EMS may use")
    table = {r[0]: dict(zip(rows[0], r)) for r in rows[1:]}
    assert table["RBC (basic)"]["24 h-ahead el. tariffs"] == "yes"
    assert table["RBC (basic)"]["solar radiation q_s"] == "-"
    assert table["ComEMS4Build (fuzzy)"]["solar radiation q_s"] == "yes"
    assert table["ComEMS4Build (fuzzy)"]["forecasts (models and profiles)"] == "-"


def test_report_from_runs_matches(comparison: Path, tmp_path: Path) -> None:
    rep = build_report(comparison, tmp_path / "again")
    assert rep.markdown.read_text() == (comparison / "report.md").read_text()


def _copy(comparison: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "copy"
    shutil.copytree(comparison, dst, ignore=shutil.ignore_patterns("figures", "report.*"))
    return dst


def test_missing_run_directory(comparison: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    root = _copy(comparison, tmp_path)
    shutil.rmtree(root / "runs" / "fuzzy_eta90")
    with pytest.raises(RunDirError, match=re.escape(str(root / "runs" / "fuzzy_eta90")) + ": run directory missing"):
        build_report(root)
    assert main(["compare", "--from-runs", str(root)]) == 2
    assert "fuzzy_eta90" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("file", "content", "message"),
    [
        ("summary.json", '{"weeks": 1, "steps"', "summary.json: not valid JSON"),
        ("summary.json", '{"weeks": 1}', "summary.json: lacks key"),
        ("weekly.csv", "week,start\n1,x\n", "weekly.csv: lacks column"),
        ("timeseries.csv", "", "timeseries.csv: not a readable CSV"),
    ],
)
def test_corrupt_run_files(comparison: Path, tmp_path: Path, file: str, content: str, message: str) -> None:
    root = _copy(comparison, tmp_path)
    (root / "runs" / "rbc" / file).write_text(content)
    with pytest.raises(RunDirError, match=re.escape(str(root / "runs" / "rbc" / message.split(":")[0]))
                       + re.escape(message[message.index(":"):])):
        build_report(root)


def test_non_numeric_summary_and_short_timeseries(comparison: Path, tmp_path: Path) -> None:
    root = _copy(comparison, tmp_path)
    path = root / "runs" / "rbc" / "summary.json"
    data = json.loads(path.read_text())
    data["loh_end"] = "full"
    path.write_text(json.dumps(data))
    with pytest.raises(RunDirError, match="key 'loh_end' is not a finite number"):
        read_run(root / "runs" / "rbc")
    ts = root / "runs" / "fuzzy" / "timeseries.csv"
    lines = ts.read_text().splitlines()
    ts.write_text("\n".join(lines[:-3]) + "\n")
    with pytest.raises(RunDirError, match="timeseries.csv has 165 rows but summary.json says 168 steps"):
        read_run(root / "runs" / "fuzzy")


def test_missing_manifest(tmp_path: Path) -> None:
    with pytest.raises(RunDirError, match="does not exist"):
        build_report(tmp_path / "nowhere")
    tmp_path.joinpath("x").mkdir()
    with pytest.raises(RunDirError, match=re.escape(str(tmp_path / "x" / "compare.json")) + ": manifest missing"):
        build_report(tmp_path / "x")
    (tmp_path / "x" / "compare.json").write_text("{not json")
    with pytest.raises(RunDirError, match="corrupt manifest"):
        build_report(tmp_path / "x")


def test_paper_results_file() -> None:
    """Every statement names its source and sentence; at least 35 figures have a relative error."""
    data = load_paper_results()
    assert "sec:results" in data.source and "abstract" in data.source
    numeric = 0
    for st in data.statements:
        assert st.where.startswith(("sec:", "abstract", "fig:")), st.key
        assert st.quote, st.key
        numeric += sum(not isinstance(v, dict | list) and float(v) != 0.0 for v in st.paper.values())
    assert numeric >= 35
    assert data.get("cost").paper == {"mpc": 12.96, "fuzzy": 25.02, "rbc": 43.10}
    assert data.get("cost").table and not data.get("cost_increase").table
    assert data.windows.start == "2022-12-03T00:00"


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["statements"][0]["measure"].update(of="nope"), "measure.of must be one of"),
    (lambda d: d["statements"][0]["paper"].update(thermostat=1.0), "paper values for thermostat"),
    (lambda d: d["statements"][0]["paper"].update(mpc=True), "must be a number"),
    (lambda d: d["statements"][1].update(key="cost"), "key given twice"),
    (lambda d: d["statements"][0].pop("quote"), "lacks quote"),
    (lambda d: d.pop("windows"), "needs keys"),
])
def test_bad_paper_results_file_is_named(tmp_path: Path, edit, message: str) -> None:
    import yaml

    from comems4build_ros.report.paper import PAPER_RESULTS_FILE

    data = yaml.safe_load(PAPER_RESULTS_FILE.read_text(encoding="utf-8"))
    edit(data)
    path = tmp_path / "paper_results.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ValueError, match=re.escape(message)):
        load_paper_results(path)


# ---------------------------------------------------------------- hand-made series


def _series(days: int, start: str = "2023-01-02 00:00", tz: str = "Europe/Berlin") -> RunData:
    time = pd.date_range(start, periods=24 * days, freq="h", tz=tz).tz_convert("UTC")
    ts = pd.DataFrame({"time": time, "price_buy_eur_per_kwh": 0.3, "t_amb_c": 5.0, "ghi_w_m2": 50.0})
    return RunData(RunSpec("x", "rbc", 0.75), Path("."), {}, pd.DataFrame(), ts)


WINDOWS = Windows(start="2022-12-03T00:00", days=3, after_days=4, trough=0.23, trough_tol=0.01)


def test_paper_windows_hand_made() -> None:
    """The first window starts on the paper's date; the second is the sunniest with the paper's price trough."""
    run = _series(12, start="2022-12-01 00:00")
    ts = run.timeseries
    ts.loc[24 * 5:24 * 8 - 1, "ghi_w_m2"] = 300.0  # days 5-7 sunny, but no trough of 0.23 ...
    ts.loc[24 * 8:24 * 11 - 1, "ghi_w_m2"] = 200.0  # days 8-10 less sunny, with the trough
    ts.loc[24 * 10 + 3, "price_buy_eur_per_kwh"] = 0.232  # only windows from days 8, 9, 10 contain it
    w = paper_windows(run, "Europe/Berlin", WINDOWS)
    assert w["performance_comparison"] == (48, 120)  # 2022-12-03 00:00 local
    assert w["high_pv"] == (24 * 8, 24 * 11)
    ts.loc[24 * 10 + 3, "price_buy_eur_per_kwh"] = 0.3  # no window with the trough: the sunniest late one
    assert paper_windows(run, "Europe/Berlin", WINDOWS)["high_pv"] == (24 * 5, 24 * 8)


def test_paper_windows_other_period_and_short_run() -> None:
    run = _series(10)
    run.timeseries.loc[48:48 + 72 - 1, "price_buy_eur_per_kwh"] = 0.6  # days 2-4 expensive
    w = paper_windows(run, "Europe/Berlin", WINDOWS)
    assert w["performance_comparison"] == (48, 120)  # no 2022-12-03: the dearest days
    assert paper_windows(_series(2), "Europe/Berlin", WINDOWS) == {"performance_comparison": (0, 48),
                                                                    "high_pv": (0, 48)}


def test_hysteresis_swings_hand_made() -> None:
    # bounds 21..24; T: low, mid, high, mid, low, high, high, low -> 2 upward swings in 8 h
    t = [21.2, 22.5, 23.8, 22.0, 21.1, 23.6, 23.9, 21.0]
    ts = pd.DataFrame({"t_air_c": t, "t_min_c": 21.0, "t_max_c": 24.0})
    assert fd.hysteresis_swings_per_week(ts) == pytest.approx(2 / (8 / 168))


def test_h2_price_response_hand_made() -> None:
    price = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8])
    h2 = np.array([0, 0, 100, 100, 100, 100, 900, 1100.0])
    hi, lo = fd.h2_price_response(pd.DataFrame({"price_buy_eur_per_kwh": price, "p_h2_w": h2}))
    assert hi == pytest.approx(1000.0)  # 75 % quantile 0.625 (linear): hours at 0.7 and 0.8
    assert lo == pytest.approx(0.0)  # 25 % quantile 0.275: hours at 0.1 and 0.2


def test_report_text_has_table_of_contents_alignment_and_no_latex_labels(comparison: Path) -> None:
    md = (comparison / "report.md").read_text()
    html = (comparison / "report.html").read_text()
    # table of contents: a link to every level-2 heading, in both files
    for heading in re.findall(r"^## (.+)$", md, re.M):
        anchor = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        assert f"(#{anchor})" in md and f'href="#{anchor}"' in html and f'id="{anchor}"' in html, heading
    # numbers right-aligned, text left-aligned (Markdown separator row and HTML classes)
    rows = md[md.index("## Findings of the paper"):].splitlines()
    sep = next(line for line in rows if line.startswith("|:") or line.startswith("|-"))
    assert sep == "|---:|:---|:---|:---|:---|"  # '#' is a number column, the rest text
    weekly = html[html.index('id="rbc-rbc'):]
    row = re.search(r"<tbody>\n<tr>(.*?)</tr>", weekly).group(1)  # week 1: label and date left, KPIs right
    cells = re.findall(r"<td( class=\"num\")?>", row)
    assert cells[:2] == ["", ""] and all(c == ' class="num"' for c in cells[2:])
    # every figure captioned with the label of the paper's figure it redraws
    for key, caption in CAPTIONS.items():
        assert caption.startswith(("fig:", "tab:")), key
        assert caption.split(".")[0] in md, key


def test_weekly_rows_median_over_full_weeks_and_partial_week_marked(comparison: Path) -> None:
    run = read_run(comparison / "runs" / "fuzzy")
    full = run.weekly.iloc[0].to_dict()
    partial = {**full, "week": 2, "full_week": False, "cost_eur": 1000.0}
    second = {**full, "week": 3, "cost_eur": float(full["cost_eur"]) + 2.0}
    weekly = pd.DataFrame([{**full, "full_week": True}, partial, {**second, "full_week": True}])
    rows = weekly_rows(replace(run, weekly=weekly))
    assert [r[0] for r in rows] == ["1", "2 (partial)", "3", "median"]
    col = 2 + [c for c, _, _, _ in WEEKLY_TABLE].index("cost_eur")
    # over all three rows (the 1000 EUR partial week among them) the median would be cost + 2
    assert float(rows[-1][col]) == pytest.approx(float(full["cost_eur"]) + 1.0, abs=0.01)
