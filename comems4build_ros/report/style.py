"""One figure style for every figure the package draws (report, sweep, fuzzy surfaces).

- **Sizes** of a journal page: figures are drawn at their printed size, so 8 pt text is
  8 pt in the paper. Widths follow Elsevier's artwork sizes (single column 90 mm, 1.5
  columns 140 mm, double column 190 mm; :func:`figsize`).
- **Colours**: the colour-blind-safe palette of Okabe and Ito ("Color Universal Design",
  2008; :data:`OKABE_ITO`); one colour per EMS in every figure (its row of ``config/ems.yaml``) and
  fixed colours for the signals (:data:`SIGNAL_COLOURS`), with line styles as a second cue.
- **Labels**: mathtext symbols of the paper with units in brackets (:data:`SYMBOLS`,
  :func:`axis_label`), never raw column names.
- **Layout**: matplotlib's constrained layout; legends outside the data (in a margin, a
  legend column or above the axes); twin axes without a second grid; no rotated dates.
  :func:`layout_problems` checks a drawn figure for what breaks these rules.
- **Files**: :func:`save_figure` writes every figure as PDF and SVG (vector, fonts
  embedded as TrueType / paths) and as a 300 dpi PNG.

Use :func:`paper_style` (a context manager) or the :func:`styled` decorator around code
that creates figures.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from comems4build_ros.core.ems import ems_table  # noqa: E402

#: Millimetres per inch.
MM_PER_INCH = 25.4
#: Figure widths of a two-column journal page [mm] (Elsevier artwork sizes).
WIDTH_MM: dict[str, float] = {"single": 90.0, "one-and-half": 140.0, "double": 190.0}
#: Tallest figure that fits a page with its caption [mm].
MAX_HEIGHT_MM = 230.0
#: Resolution of the PNG files [dpi].
PNG_DPI = 300
#: File formats written by :func:`save_figure`.
FORMATS = ("png", "pdf", "svg")

#: Okabe-Ito palette (colour-blind safe).
OKABE_ITO: dict[str, str] = {
    "black": "#000000",
    "orange": "#E69F00",
    "sky_blue": "#56B4E9",
    "bluish_green": "#009E73",
    "yellow": "#F0E442",
    "blue": "#0072B2",
    "vermillion": "#D55E00",
    "reddish_purple": "#CC79A7",
}
#: Neutral grey for bounds and secondary signals.
GREY = "#7A7A7A"
#: Colours for EMS without a colour of their own.
SPARE_COLOURS = (OKABE_ITO["orange"], OKABE_ITO["sky_blue"], OKABE_ITO["black"], OKABE_ITO["yellow"])
#: Fixed colours of the signals in time-series figures.
SIGNAL_COLOURS: dict[str, str] = {
    "main": OKABE_ITO["black"],
    "bound": GREY,
    "pv": OKABE_ITO["orange"],
    "radiation": OKABE_ITO["orange"],
    "dhw": OKABE_ITO["sky_blue"],
    "hp": OKABE_ITO["blue"],
    "sell": OKABE_ITO["orange"],
    "price": GREY,
    "battery": OKABE_ITO["sky_blue"],
    "fc": OKABE_ITO["reddish_purple"],
}

#: Mathtext symbols of the paper's quantities (``sec:system``, ``sec:evaluation_metrics``).
SYMBOLS: dict[str, str] = {
    "t_air": r"$T_\mathrm{air}$",
    "t_air_min": r"$T_\mathrm{air,min}$",
    "t_air_max": r"$T_\mathrm{air,max}$",
    "t_amb": r"$T_\mathrm{amb}$",
    "v_dhw": r"$V_\mathrm{DHW}$",
    "v_dhw_max": r"$V_\mathrm{DHW,max}$",
    "p_buy": r"$p_\mathrm{buy}$",
    "p_sell": r"$p_\mathrm{sell}$",
    "p_hat_buy": r"$\hat{p}_\mathrm{buy}$",
    "q_s": r"$\dot{q}_\mathrm{s}$",
    "P_pv": r"$P_\mathrm{PV}$",
    "P_load": r"$P_\mathrm{el,load}$",
    "P_hp": r"$P_\mathrm{el,HP}$",
    "P_buy": r"$P_\mathrm{buy}$",
    "P_sell": r"$P_\mathrm{sell}$",
    "P_b": r"$P_\mathrm{B}$",
    "P_fc": r"$P_\mathrm{el,FC}$",
    "soc": r"$\mathit{SOC}$",
    "loh": r"$\mathit{LOH}$",
    "dloh": r"$\Delta \mathit{LOH}$",
    "Q_fc_hr": r"$\dot{Q}_\mathrm{FC,hr}$",
    "eta_fc_sys": r"$\eta_\mathrm{sys,FC}$",
    "alpha_hp": r"$\alpha_\mathrm{HP}$",
    "alpha_fc": r"$\alpha_\mathrm{FC}$",
    "alpha_b": r"$\alpha_\mathrm{B}$",
    "dP": r"$\Delta P$",
    "dP_new": r"$\Delta P_\mathrm{new}$",
    "H2": r"$\mathrm{H_2}$",
}

#: Units as printed in brackets (mathtext where a plain string would be ambiguous).
UNITS: dict[str, str] = {
    "degC": "°C",
    "K": "K",
    "Kh": "K h",
    "W": "W",
    "kW": "kW",
    "kWh": "kWh",
    "W_m2": r"W/m$^2$",
    "EUR": "EUR",
    "EUR_kWh": "EUR/kWh",
    "h": "h",
    "-": "–",
    "%": "%",
    "l": "l",
}


def axis_label(quantity: str, unit: str | None = None) -> str:
    """``quantity [unit]``; ``quantity`` may be a key of :data:`SYMBOLS`, ``unit`` a key of :data:`UNITS`."""
    text = SYMBOLS.get(quantity, quantity)
    if unit is None:
        return text
    return f"{text} [{UNITS.get(unit, unit)}]"


def figsize(width: str | float, height_mm: float) -> tuple[float, float]:
    """Figure size [in] for a width of :data:`WIDTH_MM` (``single``, ``one-and-half``, ``double``) or in mm."""
    w = WIDTH_MM[width] if isinstance(width, str) else float(width)
    return w / MM_PER_INCH, min(height_mm, MAX_HEIGHT_MM) / MM_PER_INCH


def ems_colour(ems: str) -> str:
    """The EMS's colour (``config/ems.yaml``; a stable spare colour for a name outside the table)."""
    entry = ems_table().get(ems)
    return entry.colour if entry else SPARE_COLOURS[sum(map(ord, ems)) % len(SPARE_COLOURS)]


def ems_label(ems: str) -> str:
    """Display name of an EMS (``config/ems.yaml``; the name itself outside the table)."""
    entry = ems_table().get(ems)
    return entry.label if entry else ems


#: rcParams of the style.
RC: dict[str, Any] = {
    "font.family": ["STIXGeneral", "DejaVu Sans"],
    "mathtext.fontset": "stix",
    "font.size": 8.0,
    "axes.titlesize": 8.0,
    "axes.labelsize": 8.0,
    "xtick.labelsize": 7.0,
    "ytick.labelsize": 7.0,
    "legend.fontsize": 7.0,
    "figure.titlesize": 9.0,
    "axes.linewidth": 0.6,
    "axes.grid": True,
    "axes.axisbelow": True,
    "grid.linewidth": 0.4,
    "grid.alpha": 0.45,
    "grid.color": "#B0B0B0",
    "lines.linewidth": 1.0,
    "lines.markersize": 3.5,
    "patch.linewidth": 0.5,
    "xtick.major.width": 0.6,
    "ytick.major.width": 0.6,
    "xtick.major.size": 3.0,
    "ytick.major.size": 3.0,
    "xtick.minor.size": 1.8,
    "legend.frameon": False,
    "legend.handlelength": 1.8,
    "legend.columnspacing": 1.2,
    "legend.borderaxespad": 0.3,
    "figure.dpi": 100,
    "figure.constrained_layout.use": True,
    "figure.constrained_layout.h_pad": 0.03,
    "figure.constrained_layout.w_pad": 0.03,
    "savefig.dpi": PNG_DPI,
    "pdf.fonttype": 42,
    "ps.fonttype": 42,
    "svg.fonttype": "path",
}


@contextmanager
def paper_style() -> Iterator[None]:
    """Context in which figures get this style (:data:`RC`)."""
    with plt.rc_context(RC):
        yield


F = TypeVar("F", bound=Callable[..., Any])


def styled(fn: F) -> F:
    """Decorator: run ``fn`` inside :func:`paper_style`."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with paper_style():
            return fn(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def figure_files(path_stem: str | Path) -> dict[str, Path]:
    """The files :func:`save_figure` writes for ``path_stem`` (format -> path)."""
    stem = Path(path_stem)
    if stem.suffix.lower().lstrip(".") in FORMATS:
        stem = stem.with_suffix("")
    return {fmt: stem.with_name(f"{stem.name}.{fmt}") for fmt in FORMATS}


def save_figure(fig: Figure, path_stem: str | Path, close: bool = True, dpi: int = PNG_DPI) -> Path:
    """Write ``fig`` as ``<stem>.pdf``, ``<stem>.svg`` and a ``<stem>.png`` (300 dpi); return the PNG path.

    The figure keeps its size (drawn at its printed size with constrained layout; no
    ``bbox_inches="tight"``), so widths stay those of :data:`WIDTH_MM`. A suffix on
    ``path_stem`` (``.png``) is dropped. The directory is created if needed.

    Parameters
    ----------
    fig : the figure (closed afterwards unless ``close`` is False)
    path_stem : output path without suffix
    close : close the figure after writing
    dpi : resolution of the PNG [dpi]
    """
    files = figure_files(path_stem)
    files["png"].parent.mkdir(parents=True, exist_ok=True)
    with paper_style():
        for fmt, path in files.items():
            fig.savefig(path, format=fmt, dpi=dpi, metadata=_metadata(fmt))
            if fig.get_layout_engine() is not None:  # laid out once; the other formats keep the positions
                with plt.rc_context({"figure.autolayout": False, "figure.constrained_layout.use": False}):
                    fig.set_layout_engine(None)
    if close:
        plt.close(fig)
    return files["png"]


def _metadata(fmt: str) -> dict[str, Any]:
    """File metadata without creation dates (identical inputs give identical files)."""
    if fmt == "pdf":
        return {"CreationDate": None, "Creator": "comems4build_ros"}
    if fmt == "svg":
        return {"Date": None, "Creator": "comems4build_ros"}
    return {"Software": "comems4build_ros"}


def no_twin_grid(ax: plt.Axes) -> None:
    """Twin axes draw no grid of their own (only the primary axes' grid is shown)."""
    ax.grid(False)


def outside_legend(ax: plt.Axes, handles: Sequence[Any] | None = None, labels: Sequence[str] | None = None,
                   ncol: int | None = None, **kwargs: Any) -> Any:
    """Legend above ``ax``, outside the data, in one row by default."""
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    return ax.legend(handles, labels, loc="lower left", bbox_to_anchor=(0.0, 1.01),
                     ncol=ncol or max(1, len(handles)), borderaxespad=0.0, **kwargs)


# ------------------------------------------------------------------ layout checks

#: A label of the paper's LaTeX source (``fig:...``, ``tab:...``, ``eq:...``, ``sec:...``).
LATEX_LABEL = re.compile(r"\b(fig|tab|eq|sec):[A-Za-z]")
#: Tolerance of the geometric checks [px at the figure's dpi].
TOL_PX = 1.0


def _strip_math(text: str) -> str:
    return re.sub(r"\$[^$]*\$", "", text)


def _inside(inner: Any, outer: Any, tol: float = TOL_PX) -> bool:
    return (inner.x0 >= outer.x0 - tol and inner.y0 >= outer.y0 - tol and inner.x1 <= outer.x1 + tol
            and inner.y1 <= outer.y1 + tol)


def _overlap(a: Any, b: Any, tol: float = TOL_PX) -> bool:
    return a.x0 < b.x1 - tol and b.x0 < a.x1 - tol and a.y0 < b.y1 - tol and b.y0 < a.y1 - tol


def _data_axes(fig: Figure) -> list[plt.Axes]:
    return [ax for ax in fig.axes if ax.get_visible() and ax.axison and ax.name != "3d"]


def layout_problems(fig: Figure) -> list[str]:
    """What in the drawn ``fig`` breaks the style's rules (empty when nothing does).

    Checked: every text inside the figure canvas (nothing clipped at the edges) and
    overlapping no other text (tick labels of neighbouring axes included); no raw
    names (an underscore outside mathtext) and no LaTeX labels (``fig:``) in any text;
    value labels (texts of an axes) inside their axes; legends not over the data of any
    axes; x tick labels horizontal and not overlapping (dates do not wrap or collide);
    twin axes with at most one visible y grid or grids at the same heights; table cell
    texts inside their cells.
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    problems: list[str] = []
    canvas = fig.bbox
    hidden = _undrawn_tick_labels(fig)
    drawn: list[tuple[str, Any, Text]] = []
    for t in fig.findobj(Text):
        text = t.get_text()
        if not t.get_visible() or not text.strip() or id(t) in hidden:
            continue
        box = t.get_window_extent(renderer)
        drawn.append((text, box, t))
        if not _inside(box, canvas):
            problems.append(f"text {text!r} outside the figure ({box.x0:.0f}..{box.x1:.0f}, "
                            f"{box.y0:.0f}..{box.y1:.0f} px; canvas {canvas.x1:.0f} x {canvas.y1:.0f})")
        if "_" in _strip_math(text):
            problems.append(f"raw name in text {text!r} (use mathtext)")
        if LATEX_LABEL.search(text):
            problems.append(f"LaTeX label of the paper in text {text!r}")
    upright = [(text, box) for text, box, t in drawn if t.get_rotation() % 90.0 < 1e-6]
    for i, (text, box) in enumerate(upright):  # slanted texts (3D axis labels) have loose boxes
        for other, obox in upright[i + 1:]:
            if _overlap(box, obox):
                problems.append(f"texts {text!r} and {other!r} overlap")
    data_axes = _data_axes(fig)
    for ax in fig.axes:
        for t in ax.texts:
            if t.get_visible() and t.get_text().strip() and ax in data_axes:
                if not _inside(t.get_window_extent(renderer), ax.bbox):
                    problems.append(f"value label {t.get_text()!r} outside its axes")
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    for leg in legends:
        if not leg.get_visible():
            continue
        box = leg.get_window_extent(renderer)
        for ax in data_axes:
            if _overlap(box, ax.bbox):
                problems.append(f"legend ({', '.join(t.get_text() for t in leg.get_texts())}) over the data of "
                                f"an axes ({ax.get_ylabel() or ax.get_title()!r})")
                break
    for ax in data_axes:
        own = ax.get_position().bounds
        for t in [*ax.get_xticklabels(which="both"), *ax.get_yticklabels(which="both")]:
            if not t.get_visible() or not t.get_text().strip() or id(t) in hidden:
                continue
            box = t.get_window_extent(renderer)
            for other in data_axes:
                if other.get_position().bounds != own and _overlap(box, other.bbox):
                    problems.append(f"tick label {t.get_text()!r} over another axes ({other.get_ylabel()!r})")
                    break
        labels = [t for t in ax.get_xticklabels(which="both") if t.get_visible() and t.get_text().strip()
                  and id(t) not in hidden]
        if any(abs(t.get_rotation()) > 1e-6 for t in labels):
            problems.append(f"rotated x tick labels in axes {ax.get_ylabel()!r}")
        boxes = sorted((t.get_window_extent(renderer) for t in labels), key=lambda b: b.x0)
        if any(a.x1 > b.x0 + TOL_PX for a, b in zip(boxes, boxes[1:])):
            problems.append(f"overlapping x tick labels in axes {ax.get_ylabel()!r}")
        if len({round(b.height) for b in boxes}) > 1 and any("\n" in t.get_text() for t in labels):
            problems.append(f"x tick labels wrap in axes {ax.get_ylabel()!r}")
    problems.extend(_twin_grid_problems(data_axes))
    for ax in fig.axes:
        for table in ax.tables:
            for (r, c), cell in table.get_celld().items():
                if not cell.get_text().get_text().strip():
                    continue
                if not _inside(cell.get_text().get_window_extent(renderer), cell.get_window_extent(renderer)):
                    problems.append(f"table cell ({r}, {c}) text {cell.get_text().get_text()!r} clipped")
    return problems


def _undrawn_tick_labels(fig: Figure) -> set[int]:
    """Ids of the tick labels of ticks outside their axis' view interval (matplotlib does not draw them)."""
    out: set[int] = set()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis, *([ax.zaxis] if hasattr(ax, "zaxis") else [])):
            lo, hi = sorted(axis.get_view_interval())
            tol = 1e-9 * max(abs(hi - lo), 1.0)
            for tick in [*axis.get_major_ticks(), *axis.get_minor_ticks()]:
                loc = tick.get_loc()
                if loc is None or not lo - tol <= loc <= hi + tol:
                    out.update((id(tick.label1), id(tick.label2)))
    return out


def _y_grid_visible(ax: plt.Axes) -> bool:
    return any(line.get_visible() for line in ax.yaxis.get_gridlines())


def _twin_grid_problems(axes: Sequence[plt.Axes]) -> list[str]:
    out = []
    for i, a in enumerate(axes):
        for b in axes[i + 1:]:
            if a.get_position().bounds != b.get_position().bounds:
                continue
            if not (_y_grid_visible(a) and _y_grid_visible(b)):
                continue
            ya = sorted(round(a.transData.transform((0, y))[1]) for y in a.get_yticks()
                        if a.get_ylim()[0] <= y <= a.get_ylim()[1])
            yb = sorted(round(b.transData.transform((0, y))[1]) for y in b.get_yticks()
                        if b.get_ylim()[0] <= y <= b.get_ylim()[1])
            if ya != yb:
                out.append(f"twin axes {a.get_ylabel()!r} / {b.get_ylabel()!r} with two y grids that do not line up")
    return out
