"""``comems4build sweep``: a tiny grid (2 battery sizes, 1 week, thermostat) and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.report.style import layout_problems, paper_style
from comems4build_ros.report.sweep import SWEEP_KPIS, kpi_figure, markdown_table, param_label
from comems4build_ros.study.sweep import grid, parse_param


def test_tiny_sweep(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    rc = main(["sweep", "--param", "battery.e_max_kwh=5,10", "--ems", "thermostat", "--weeks", "1",
               "--jobs", "2", "--out", str(out)])
    assert rc == 0
    df = pd.read_csv(out / "sweep.csv")
    assert list(df["battery.e_max_kwh"]) == [5, 10]
    assert list(df["ems"]) == ["thermostat", "thermostat"]
    for row in df.itertuples(index=False):
        name = f"thermostat__battery.e_max_kwh={row[1]}"
        summary = json.loads((out / "runs" / name / "summary.json").read_text())
        for key, _ in SWEEP_KPIS:
            assert getattr(row, key) == pytest.approx(summary[key]), key
    md = (out / "sweep.md").read_text()
    assert "| ems | battery.e_max_kwh | cost_eur_week_median" in md
    for key, _ in SWEEP_KPIS:
        png = out / "figures" / f"{key}.png"
        assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 3000
        assert (out / "figures" / f"{key}.pdf").read_bytes()[:5] == b"%PDF-"
        assert (out / "figures" / f"{key}.svg").stat().st_size > 3000
        for ext in ("png", "pdf", "svg"):
            assert f"figures/{key}.{ext}" in md
    assert not (out / "runs" / "thermostat__battery.e_max_kwh=5" / "timeseries.csv").exists()


def test_parse_param() -> None:
    assert parse_param("battery.e_max_kwh=5,6.5, 10") == ("battery.e_max_kwh", [5, 6.5, 10])
    assert parse_param("grid.buy_offset_eur_per_kwh=0.2") == ("grid.buy_offset_eur_per_kwh", [0.2])
    for bad in ("battery.e_max_kwh", "e_max_kwh=5", "battery.e_max_kwh=", "battery.e_max_kwh=5,5"):
        with pytest.raises(ValueError, match="--param"):
            parse_param(bad)


def test_grid_is_the_product() -> None:
    cases = grid({"a.x": [1, 2], "b.y": [0.1, 0.2, 0.3]}, ["rbc", "fuzzy"])
    assert len(cases) == 12
    assert len({c.name for c in cases}) == 12
    assert cases[0].values == {"a.x": 1, "b.y": 0.1} and cases[0].ems == "rbc"
    assert cases[-1].values == {"a.x": 2, "b.y": 0.3} and cases[-1].ems == "fuzzy"


def test_markdown_table() -> None:
    md = markdown_table(pd.DataFrame({"ems": ["rbc"], "a.x": [1.0], "k": [2.34567]}), digits=2)
    assert md.splitlines() == ["| ems | a.x | k |", "|---|---|---|", "| rbc | 1.00 | 2.35 |"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--param", "battery.e_max_kwh=-5", "--ems", "thermostat"], "battery.e_max_kwh"),
        (["--param", "battery.bogus=1", "--ems", "thermostat"], "battery.bogus"),
        (["--param", "nosection=1", "--ems", "thermostat"], "--param 'nosection=1'"),
        (["--param", "battery.e_max_kwh=5", "--ems", "nosuch"], "unknown EMS 'nosuch'"),
    ],
)
def test_bad_input_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], message: str) -> None:
    assert main(["sweep", *argv, "--weeks", "1", "--out", str(tmp_path / "x")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x" / "runs").exists()


def test_sweep_figures_pass_the_layout_check() -> None:
    """Parameter names become labels with units; legends above the data; nothing clipped."""
    import matplotlib.pyplot as plt

    rows = [{"ems": e, "battery.e_max_kwh": b, "grid.surcharge_eur_per_kwh": g, "cost_eur_week_median": c}
            for e in ("rbc", "fuzzy") for b in (5, 10) for g in (0.2, 0.3) for c in (30.0 + b + 10 * g,)]
    df = pd.DataFrame(rows)
    fig = kpi_figure(df, ["battery.e_max_kwh", "grid.surcharge_eur_per_kwh"], "cost_eur_week_median",
                     dict(SWEEP_KPIS)["cost_eur_week_median"])
    with paper_style():
        assert layout_problems(fig) == []
    texts = [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text"))]
    assert param_label("battery.e_max_kwh") in texts
    plt.close(fig)


def test_param_label_fallback_names_the_unit() -> None:
    assert param_label("building.r_air_amb_k_per_w") == "building: r air amb [K/W]"
    assert param_label("hydrogen.loh_min") == "hydrogen: loh min [–]"
