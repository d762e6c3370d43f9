"""``comems4build fuzzy-surface`` draws the fig:FLC_3D maps."""

import numpy as np
import pytest

from comems4build_ros.app.cli import main
from comems4build_ros.app.commands.fuzzy_surface import surfaces
from comems4build_ros.core.config import load_plant_params
from comems4build_ros.core.ems.fuzzy import load_flcs

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_writes_four_figures_as_pdf_svg_png(tmp_path):
    assert main(["fuzzy-surface", "--out", str(tmp_path), "--dpi", "40"]) == 0
    for name in ("flc_flex", "flc_fc", "flc_b", "flc_3d"):
        data = (tmp_path / f"{name}.png").read_bytes()
        assert data[:8] == PNG_MAGIC and len(data) > 2000
        assert (tmp_path / f"{name}.pdf").read_bytes()[:5] == b"%PDF-"
        assert (tmp_path / f"{name}.svg").stat().st_size > 2000


def test_figures_pass_the_layout_check():
    import matplotlib.pyplot as plt

    from comems4build_ros.app.commands.fuzzy_surface import surface_figure, surfaces_figure
    from comems4build_ros.report.style import layout_problems, paper_style

    maps = surfaces(_systems(), chi=0.5, n=11)
    for fig in [*(surface_figure(s) for s in maps.values()), surfaces_figure(maps)]:
        with paper_style():
            assert layout_problems(fig) == []
        plt.close(fig)


def _systems():
    systems = {}
    for key, (system, section) in load_flcs(load_plant_params()).items():
        system.load_scale_w = float(section.get("load_scale_w", 10_000.0))
        systems[key] = system
    return systems


def test_bad_chi_is_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["fuzzy-surface", "--out", str(tmp_path), "--chi", "1.5"])
    assert exc.value.code == 2
    assert "argument --chi: 1.5 is outside the allowed range: a finite number in [0, 1]" in capsys.readouterr().err


def test_maps_show_the_papers_trends():
    systems = {}
    for key, (system, section) in load_flcs(load_plant_params()).items():
        system.load_scale_w = float(section.get("load_scale_w", 10_000.0))
        systems[key] = system
    maps = surfaces(systems, chi=0.5, n=11)
    fc = maps["flc_fc"]  # rows: dP (from big demand to 0), columns: EDF price 0 .. 1
    # fig:FLC_3D middle: alpha_FC grows with the price and with the load
    assert np.all(np.diff(fc["z"], axis=1) >= -1e-9)
    # a bigger load never gets less power (up to a centroid ripple of 0.01)
    assert np.all(np.diff(fc["z"], axis=0) <= 0.01)
    # it grows with the load at an average price; at the day's highest price a running FC
    # holds at "big positive" whatever the load (config/fuzzy/fc.yaml, rules_design)
    mid = fc["z"].shape[1] // 2
    assert fc["z"][0, mid] > fc["z"][-1, mid] + 0.1
    b = maps["flc_b"]  # rows: dP_new from demand to surplus
    # right: at low prices and small load it charges, at high prices and big load it discharges
    assert b["z"][len(b["z"]) // 2, 0] > 0.0
    assert b["z"][0, -1] < -0.5
