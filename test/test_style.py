"""Figure style: sizes, files written, and the layout check on deliberately broken figures."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from PIL import Image

from comems4build_ros.report import style


@style.styled
def _clean() -> plt.Figure:
    fig, ax = plt.subplots(figsize=style.figsize("single", 60))
    ax.plot([0, 1, 2], [1, 3, 2], label=style.axis_label("t_air"))
    ax.set_ylabel(style.axis_label("t_air", "degC"))
    ax.set_xlabel("time [h]")
    style.outside_legend(ax)
    return fig


@style.styled
def _axes(height_mm: float = 50) -> tuple[plt.Figure, plt.Axes]:
    return plt.subplots(figsize=style.figsize("single", height_mm))


def _problems(fig: plt.Figure) -> list[str]:
    with style.paper_style():
        out = style.layout_problems(fig)
    plt.close(fig)
    return out


def test_figsize_is_the_printed_width() -> None:
    assert style.figsize("single", 60) == pytest.approx((90 / 25.4, 60 / 25.4))
    assert style.figsize("double", 500)[1] == pytest.approx(style.MAX_HEIGHT_MM / 25.4)


def test_save_figure_writes_pdf_svg_and_a_300_dpi_png(tmp_path: Path) -> None:
    png = style.save_figure(_clean(), tmp_path / "sub" / "fig.png")
    assert png == tmp_path / "sub" / "fig.png"
    assert (tmp_path / "sub" / "fig.pdf").read_bytes()[:5] == b"%PDF-"
    assert b"<svg" in (tmp_path / "sub" / "fig.svg").read_bytes()[:2000]
    with Image.open(png) as im:
        assert im.info["dpi"] == pytest.approx((300, 300), abs=0.5)
        assert im.size[0] == pytest.approx(90 / 25.4 * 300, abs=2)  # the printed width at 300 dpi
    assert b"/CreationDate" not in (tmp_path / "sub" / "fig.pdf").read_bytes()  # reproducible files


def test_ems_colours_are_okabe_ito_and_stable() -> None:
    for ems in ("mpc", "fuzzy", "rbc", "mpc-qp"):
        assert style.ems_colour(ems) in style.OKABE_ITO.values()
    assert style.ems_colour("my-ems") == style.ems_colour("my-ems")


def test_clean_figure_has_no_problems() -> None:
    assert _problems(_clean()) == []


def test_raw_names_and_latex_labels_are_found() -> None:
    fig = _clean()
    fig.axes[0].set_ylabel("p_buy [EUR/kWh]")
    fig.axes[0].set_title("after fig:grid_usage")
    found = _problems(fig)
    assert any("raw name" in p and "p_buy" in p for p in found)
    assert any("LaTeX label" in p for p in found)


def test_legend_over_the_data_is_found() -> None:
    fig = _clean()
    fig.axes[0].legend(loc="center")
    assert any(p.startswith("legend") for p in _problems(fig))


def test_text_outside_the_canvas_and_clipped_value_labels_are_found() -> None:
    fig = _clean()
    ax = fig.axes[0]
    fig.text(0.99, 0.5, "a long label that runs off the page")
    bars = ax.bar([0, 1], [1.0, 3.0])
    ax.bar_label(bars, fmt="%.0f")  # the tallest label sits above the axes' top
    ax.set_ylim(0, 3.0)
    found = _problems(fig)
    assert any("outside the figure" in p for p in found)
    assert any("value label" in p for p in found)


def test_rotated_and_colliding_dates_are_found() -> None:
    fig, axes = plt.subplots(1, 2, figsize=style.figsize("single", 50), layout="constrained")
    t = np.arange("2022-12-07", "2022-12-10", dtype="datetime64[h]")
    for ax in axes:
        ax.plot(t, np.arange(len(t)))
        ax.set_xticks(t[::24], [f"{d} 00:00" for d in ("07.12.", "08.12.", "09.12.")])
    found = _problems(fig)
    assert any("overlap" in p for p in found)
    fig, ax = _axes()
    ax.plot(t, np.arange(len(t)))
    fig.autofmt_xdate()
    assert any("rotated" in p for p in _problems(fig))


def test_twin_axes_with_two_grids_are_found() -> None:
    fig, ax = _axes()
    ax.plot([0, 1], [0, 1])
    ax.grid(True)
    twin = ax.twinx()
    twin.plot([0, 1], [0, 7])
    twin.set_ylim(-0.3, 7.7)
    twin.grid(True)
    assert any("twin axes" in p for p in _problems(fig))
    fig, ax = _axes()
    ax.plot([0, 1], [0, 1])
    twin = ax.twinx()
    twin.plot([0, 1], [0, 7])
    style.no_twin_grid(twin)
    assert _problems(fig) == []


def test_clipped_table_header_is_found() -> None:
    fig, ax = _axes(30)
    ax.axis("off")
    table = ax.table(cellText=[["x", "y"]], colLabels=["a very long header text", "b"], colWidths=[0.2, 0.8],
                     loc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    assert any("table cell (0, 0)" in p for p in _problems(fig))
