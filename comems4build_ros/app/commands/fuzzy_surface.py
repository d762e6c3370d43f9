"""``comems4build fuzzy-surface``: input-output maps of the three ComEMS4Build FLCs (paper ``fig:FLC_3D``).

Draws, as in the paper's figure and with the conditions of its caption:

- FLC_flex: alpha_HP over EDF price and solar radiation q_s for SOC[k-1] = 10 % and
  LOH[k-1] = 10 % (the thermal state min(chi_SH, chi_DHW) is not given in the caption;
  ``--chi``, default 0.5);
- FLC_FC: alpha_FC over EDF price and load dP for SOC[k-1] = 20 %, dLOH[k-1] = 80 % and
  s_on/off[k-1] = on;
- FLC_B: alpha_B over EDF price and residual load dP_new for SOC[k-1] = 50 %.

Writes ``flc_flex``, ``flc_fc``, ``flc_b`` (one column wide each) and ``flc_3d`` (all three
side by side, two columns wide) into ``--out``, each as PDF, SVG and PNG
(:func:`comems4build_ros.report.style.save_figure`). The controllers are built from
``config/fuzzy/*.yaml`` and the plant parameters (``--config``), so the maps follow the
configured device sizes.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from comems4build_ros.app.commands.options import FRACTION, integer

#: What ``fuzzy-surface`` writes into its output directory (PDF, SVG and PNG of each map).
SURFACE_FILES = ("flc_flex.*", "flc_fc.*", "flc_b.*", "flc_3d.*")
#: Grid points per axis of each map.
N_GRID = 41
#: Watts per kilowatt for the load axes.
W_PER_KW = 1000.0
#: Axis label of the EDF price feature (``eq:EDF_prices``).
_P_HAT = r"EDF price $\hat{p}_\mathrm{buy}$ [–]"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``fuzzy-surface``."""
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory for the figures (PDF, SVG, PNG)")
    parser.add_argument("--chi", metavar="X", type=FRACTION, default=0.5,
                        help="min(chi_SH, chi_DHW) of the FLC_flex map, in [0, 1] (default 0.5)")
    parser.add_argument("--config", action="append", default=[], metavar="FILE", help="extra plant parameter file")
    parser.add_argument("--dpi", metavar="DPI", type=integer(10, 2400), default=300,
                        help="resolution of the PNG files, 10 .. 2400 (default 300)")


def surfaces(systems: dict[str, Any], chi: float, n: int = N_GRID) -> dict[str, dict[str, Any]]:
    """The three maps as arrays: per FLC x, y (meshgrids), z and axis labels."""
    import numpy as np

    flex, fc, bat = systems["flex"], systems["fc"], systems["battery"]
    price = np.linspace(0.0, 1.0, n)
    out: dict[str, dict[str, Any]] = {}

    qs = np.linspace(flex.variable("qs").lo, flex.variable("qs").hi, n)
    x, y = np.meshgrid(price, qs)
    inputs = np.column_stack([np.full(x.size, chi), np.full(x.size, 0.1), np.full(x.size, 0.1), x.ravel(), y.ravel()])
    out["flc_flex"] = {
        "x": x, "y": y, "z": flex.evaluate(inputs).reshape(x.shape),
        "xlabel": _P_HAT, "ylabel": r"$\dot{q}_\mathrm{s}$ [W/m$^2$]", "zlabel": r"$\alpha_\mathrm{HP}$ [–]",
        "title": r"FLC$_\mathrm{flex}$: $\mathit{SOC}$ = 10 %, $\mathit{LOH}$ = 10 %, "
                 rf"$\min(\chi_\mathrm{{SH}}, \chi_\mathrm{{DHW}})$ = {chi:g}",
    }

    scale_fc = fc.load_scale_w
    # dP from twice the FC + BESS load (start of "big negative") to 0
    v = fc.variable("dp")
    dp = np.linspace(max(v.lo, 2.0 * v.points[v.term_names.index("bn")][2]), v.hi, n)
    x, y = np.meshgrid(price, dp)
    inputs = np.column_stack([y.ravel(), np.full(x.size, 0.8), np.full(x.size, 0.2), x.ravel(), np.ones(x.size)])
    out["flc_fc"] = {
        "x": x, "y": y * scale_fc / W_PER_KW, "z": fc.evaluate(inputs).reshape(x.shape),
        "xlabel": _P_HAT, "ylabel": r"$\Delta P$ [kW]", "zlabel": r"$\alpha_\mathrm{FC}$ [–]",
        "title": r"FLC$_\mathrm{FC}$: $\mathit{SOC}$ = 20 %, $\Delta\mathit{LOH}$ = 80 %, FC on",
    }

    scale_b = bat.load_scale_w
    span = 2.0 * max(abs(bat.peak("dp_new", "mn")) * 2.0, bat.peak("dp_new", "mp") * 2.0)
    dpn = np.linspace(-span, span, n)
    x, y = np.meshgrid(price, dpn)
    inputs = np.column_stack([y.ravel(), np.full(x.size, 0.5), x.ravel()])
    out["flc_b"] = {
        "x": x, "y": y * scale_b / W_PER_KW, "z": bat.evaluate(inputs).reshape(x.shape),
        "xlabel": _P_HAT, "ylabel": r"$\Delta P_\mathrm{new}$ [kW]", "zlabel": r"$\alpha_\mathrm{B}$ [–]",
        "title": r"FLC$_\mathrm{B}$: $\mathit{SOC}$ = 50 %",
    }
    return out


def _draw(ax: Any, s: dict[str, Any]) -> None:
    from matplotlib.ticker import MaxNLocator

    ax.plot_surface(s["x"], s["y"], s["z"], cmap="viridis", linewidth=0, antialiased=True, rcount=N_GRID,
                    ccount=N_GRID)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax.set_xlabel(s["xlabel"])
    ax.set_ylabel(s["ylabel"])
    ax.zaxis.set_rotate_label(False)
    ax.set_zlabel(s["zlabel"], rotation=90)
    ax.tick_params(pad=0)
    ax.set_title(s["title"], fontsize=7)
    ax.view_init(elev=28, azim=-130)
    ax.set_box_aspect(None, zoom=0.85)


def surface_figure(s: dict[str, Any]) -> Any:
    """One map of :func:`surfaces` as a one-column figure (style of :mod:`comems4build_ros.report.style`)."""
    import matplotlib.pyplot as plt

    from comems4build_ros.report.style import figsize, paper_style

    with paper_style():
        fig = plt.figure(figsize=figsize("single", 80), layout="none")
        fig.subplots_adjust(left=0.04, right=0.96, bottom=0.02, top=0.94)
        _draw(fig.add_subplot(projection="3d"), s)
    return fig


def surfaces_figure(maps: dict[str, dict[str, Any]]) -> Any:
    """The three maps side by side as a two-column figure (as the paper's figure)."""
    import matplotlib.pyplot as plt

    from comems4build_ros.report.style import figsize, paper_style

    with paper_style():
        fig = plt.figure(figsize=figsize("double", 72), layout="none")
        fig.subplots_adjust(left=0.05, right=0.99, bottom=0.02, top=0.94, wspace=0.14)
        for i, s in enumerate(maps.values()):
            _draw(fig.add_subplot(1, 3, i + 1, projection="3d"), s)
    return fig


def run(args: argparse.Namespace) -> int:
    """Write the figures; print the paths of their PNG versions."""
    from comems4build_ros.app.commands.options import load_params, output_dir
    from comems4build_ros.core.ems.fuzzy import load_flcs
    from comems4build_ros.report.style import save_figure

    output = output_dir(args, "fuzzy-surface", writes=SURFACE_FILES, replaces=SURFACE_FILES)
    output.check()
    params = load_params(args.config)
    systems = {key: system for key, (system, _) in load_flcs(params).items()}
    maps = surfaces(systems, args.chi)
    with output:  # the figures replace an earlier drawing's only when all are drawn
        stage = output.stage
        written = [save_figure(surface_figure(s), stage / name, dpi=args.dpi) for name, s in maps.items()]
        written.append(save_figure(surfaces_figure(maps), stage / "flc_3d", dpi=args.dpi))
    for p in written:
        print(output.path / Path(p).name)
    return 0
