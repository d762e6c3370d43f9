"""``reproduce.md`` and ``reproduce.html`` from the content of ``reproduce.json``.

Both documents come from the same blocks (:class:`~comems4build_ros.report.document.Document`:
a table of contents, units in the headers, numbers right-aligned), so they hold the same
numbers; every number is read from the report mapping that
:func:`comems4build_ros.report.reproduce.reproduce` computed from its runs.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from comems4build_ros.files.errors import InputError
from comems4build_ros.report.document import Document
from comems4build_ros.report.figures import CAPTIONS
from comems4build_ros.report.paper import printed
from comems4build_ros.report.style import ems_label as _label

#: Title of both documents.
TITLE = "ComEMS4Build: reproducing the paper"
EMS = ("mpc", "fuzzy", "rbc")
#: The headline figures listed per reading in the study tables: (statement key, short label).
STUDY_FIGURES = (("cost", "cost"), ("buy", "bought"), ("sell", "sold"), ("bess_charged", "BESS charged"),
                 ("loh_end", "LOH left"))


def _pct(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{100 * x:.{digits}f} %"


def _num(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _met(ok: bool) -> str:
    return "met" if ok else "NOT MET"


def _seeds(report: Mapping[str, Any]) -> str:
    seeds = report["seeds"]
    return f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''} ({', '.join(str(s) for s in seeds)})"


def _figure_rows(report: Mapping[str, Any], case: Mapping[str, Any]) -> list[list[str]]:
    info = report["statements"]
    n = len(report["seeds"])
    rows = []
    for f in case["figures"]:
        s = info[f["key"]]
        if f["ours"] is None:
            ours, err = "not run", "-"
        else:
            ours = printed(f["ours"], s["unit"])
            if f["low"] is not None and n > 1 and f["kind"] != "weeks":
                ours += f" [{printed(f['low'], s['unit'])}..{printed(f['high'], s['unit'])}]"
            if s["locates"]:
                err = "locates the window"
            elif f["rel_error"] is not None:
                err = _pct(f["rel_error"])
            else:
                err = f"held on {f['held']} of {f['runs']}"
        rows.append([s["label"] + (" *" if s["table"] else ""), s["unit"], s["where"], _label(f["ems"]),
                     printed(f["paper"], s["unit"]), ours, err])
    return rows


def _summary(doc: Document, report: Mapping[str, Any]) -> None:
    base, t = report["base"], report["targets"]
    doc.h(2, "Summary")
    ratios = base["ratios"]
    tol = t["ratio_tolerance"]
    rows = [
        ["median relative error, every stated figure", f"at most {_pct(t['median_error'], 0)}",
         _pct(base["median_rel_error"]), _met(base["median_rel_error"] <= t["median_error"])],
        ["median relative error, the headline table (*)", f"at most {_pct(t['table_error'], 0)}",
         _pct(base["table_rel_error"]), _met(base["table_rel_error"] <= t["table_error"])],
    ]
    for key, p in report["paper_ratios"].items():
        lo, hi = p * (1 - tol), p * (1 + tol)
        a, b = key.split("/")
        v = ratios[key]["median"]
        rows.append([f"cost ratio {_label(a)} / {_label(b)} (paper {p:.2f})", f"{lo:.2f}..{hi:.2f}",
                     f"{v:.2f} [{ratios[key]['low']:.2f}..{ratios[key]['high']:.2f}]", _met(lo <= v <= hi)])
    fc = base["fc"]
    for key, band, paper in (("fuzzy_hours", t["fuzzy_fc_hours_pct"], "+48.44 %"),
                             ("fuzzy_toggles", t["fuzzy_fc_toggles_pct"], "+6.09 %")):
        v = fc[key]["median"]
        what = "working hours" if key.endswith("hours") else "toggles"
        rows.append([f"ComEMS4Build's FC {what} vs MPC (paper {paper})", f"{band[0]:+.0f}..{band[1]:+.0f} %",
                     f"{v:+.1f} % [{fc[key]['low']:+.1f}..{fc[key]['high']:+.1f}]", _met(band[0] <= v <= band[1])])
    v = fc["rbc_hours"]["median"]
    rows.append(["RBC's FC working hours vs MPC (paper -7.59 %)", "below 0 %",
                 f"{v:+.1f} % [{fc['rbc_hours']['low']:+.1f}..{fc['rbc_hours']['high']:+.1f}]", _met(v < 0)])
    rows.append([f"findings holding on at least {t['findings_seeds']} of {len(report['seeds'])} seeds", "all",
                 f"{base['findings_held']} of {base['findings_total']}",
                 _met(base["findings_held"] == base["findings_total"])])
    doc.p(f"The three EMS on the default scenario over {report['weeks']:g} weeks, for {_seeds(report)} of the "
          "modelled radiation and appliance load (the first is the default scenario's). Each figure is the median "
          "over the seeds; its error is the median over the seeds of |ours - paper| / |paper|.")
    doc.table(["target", "band", "ours: median [range over the seeds]", "status"], rows)


def _statements(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Every stated figure of the paper beside ours")
    doc.p(f"Paper: {report['source']}. One row per statement and EMS (`input`: a statement about the scenario's "
          "inputs); ours is the median over the seeds with its range; error: the seed-median relative error, or "
          "on how many seeds a bound or a set of weeks held. Weeks are the paper's: week 1 starts on 2022-12-01. "
          "(*) marks the figures of the paper's headline table. \"x % more than the MPC\" is compared as the "
          "ratio 1 + x / 100. The quoted sentences and the measure of each statement are in "
          "comems4build_ros/report/paper_results.yaml.")
    doc.table(["figure", "unit", "paper's source", "EMS", "paper", "ours", "error"],
              _figure_rows(report, report["base"]))
    above = [f for f in report["base"]["figures"] if f["rel_error"] is not None
             and f["rel_error"] > report["targets"]["explain_above"]]
    if above:
        info = report["statements"]
        doc.p(f"Figures off by more than {_pct(report['targets']['explain_above'], 0)} (explained in "
              "docs/calibration.md): " + "; ".join(
                  f"`{f['ems']}/{f['key']}` ({info[f['key']]['label']}: {printed(f['ours'], info[f['key']]['unit'])} "
                  f"vs {printed(f['paper'], info[f['key']]['unit'])}, {_pct(f['rel_error'])})" for f in above) + ".")


def _fc(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Fuel cell and hydrogen (default seed)")
    doc.p("Weekly H2 use as the FC's electrical output and as the LHV energy drawn from the store (min..max over "
          "the weeks); the paper's \"H2 consumption\" ranges (MPC 23.44..123.08, ComEMS4Build 54.11..78.54 kWh/week) "
          "fit the electrical output. Value of the H2 left = (LOH_end - LOH_min) x 1800 kWh x mean buy price of the "
          "run (the paper's method, sec:results); net cost = cost - reimbursement - that value.")
    rows = []
    for r in report["h2"]:
        rows.append([
            _label(r["ems"]), _num(r["fc_working_hours"], 0), _num(r["fc_toggles"], 0),
            _num(r["fc_mean_load_w"], 0), _num(r["fc_mean_eta_el"], 3),
            f"{_num(r['fc_kwh_week_min'], 1)}..{_num(r['fc_kwh_week_max'], 1)}",
            f"{_num(r['h2_kwh_week_min'], 1)}..{_num(r['h2_kwh_week_max'], 1)}",
            _num(r["loh_end_pct"]), _num(r["h2_left_value_eur"]), _num(r["cost_net_eur_week"]),
        ])
    doc.table(["EMS", "FC hours [h]", "FC toggles [-]", "FC mean load [W]", "FC mean eta_el [-]",
               "FC electrical [kWh/week]", "H2 LHV [kWh/week]", "LOH left [%]", "value of H2 left [EUR]",
               "net cost [EUR/week]"], rows)


def _findings(doc: Document, report: Mapping[str, Any]) -> None:
    base = report["base"]
    n, need = len(report["seeds"]), report["targets"]["findings_seeds"]
    doc.h(2, "The paper's findings")
    doc.p(f"Each finding is checked on every seed (comems4build_ros/report/findings.py); it holds when it holds on at "
          f"least {need} of {n} seeds. {base['findings_held']} of {base['findings_total']} hold. Evidence: the "
          f"default seed ({report['seeds'][0]}).")
    first = str(report["seeds"][0])
    doc.table(["finding", "paper", f"held on (of {n})", "evidence (default seed)"],
              [[f["claim"], f["source"], f"{f['held']}" + ("" if f["held"] >= need else " NOT HELD"),
                f["evidence"].get(first, "")] for f in base["findings"]])


def _figures(doc: Document, report: Mapping[str, Any], where: tuple[Path, str]) -> None:
    """The figure blocks; ``where``: the directory holding the PNGs and its path relative to the document."""
    if not report.get("figures"):
        return
    png_dir, rel = where
    doc.h(2, "The paper's figures from our runs")
    w = report["windows"]
    spans = {k: f"{a[:16]} to {b[:16]}" for k, (a, b) in w.items()}
    doc.p(f"Drawn from the runs of the default seed ({report['seeds'][0]}); the heat recovery at "
          f"{report['heat_eta'] * 100:.0f} % FC system efficiency is "
          + ("each EMS's own dispatch evaluated at that efficiency." if report["heat_mode"] == "posthoc"
             else "a run of each EMS at that efficiency.")
          + (" PDF and SVG beside each PNG." if any(
              (png_dir / Path(p).name).with_suffix(".pdf").is_file() for p in report["figures"].values()) else ""))
    for key, path in report["figures"].items():
        doc.figure(png_dir / Path(path).name, rel, CAPTIONS[key].format(**spans))


def _study(doc: Document, report: Mapping[str, Any]) -> None:
    if not report["ambiguities"]:
        return
    doc.h(2, "Interpretation study")
    doc.p(f"Each reading is run on top of the defaults (every other ambiguity at its default reading) on "
          f"{_seeds(report)}. Columns: the seed-median relative error, median over every stated figure and over the "
          "headline table, the largest; the cost ratios (paper: RBC / ComEMS4Build 1.72, MPC / ComEMS4Build 0.52) "
          "and ComEMS4Build's FC hours and toggles relative to the MPC's (paper +48.44 % and +6.09 %), medians over "
          "the seeds; the findings holding.")
    results = {(r["ambiguity"], r["reading"]): r for r in report["study"]}
    for a in report["ambiguities"]:
        doc.h(3, f"{a['title']} ({a['key']})")
        doc.p(f"Paper: {a['source']}")
        rows = []
        for rd in a["readings"]:
            r = results[(a["key"], rd["name"])]
            mark = " (default)" if rd["name"] == a["default"] else ""
            rows.append([
                rd["name"] + mark, rd["text"], _pct(r["median_rel_error"]), _pct(r["table_rel_error"]),
                _pct(r["max_rel_error"], 0), _num(r["ratios"]["rbc/fuzzy"]["median"]),
                _num(r["ratios"]["mpc/fuzzy"]["median"]), f"{r['fc']['fuzzy_hours']['median']:+.0f} %",
                f"{r['fc']['fuzzy_toggles']['median']:+.0f} %",
                f"{r['findings_held']} of {r['findings_total']}"
                + (f" (not: {', '.join(r['not_held'])})" if r["not_held"] else ""),
            ])
        doc.table(["reading", "what", "median error", "table error", "largest error", "RBC/fuzzy", "MPC/fuzzy",
                   "fuzzy FC hours", "fuzzy FC toggles", "findings held"], rows)
        doc.p(f"Chosen: {a['default']}. {a['reason']}")
        fig_rows = []
        for rd in a["readings"]:
            r = results[(a["key"], rd["name"])]
            for e in a["ems"]:
                d = r["discomfort"][e]
                fig_rows.append([rd["name"], _label(e)]
                                + [_num(r["values"].get(f"{key}/{e}")) for key, _ in STUDY_FIGURES]
                                + [_num(d["median_kh"]), _num(d["weeks"], 0)])
        doc.table(["reading", "EMS", *(lab for _, lab in STUDY_FIGURES), "discomfort median [Kh/week]",
                   "weeks with discomfort"], fig_rows)


def _sections(doc: Document, report: Mapping[str, Any], figures: tuple[Path, str] | None) -> None:
    _summary(doc, report)
    _statements(doc, report)
    _fc(doc, report)
    _findings(doc, report)
    if figures is not None:
        _figures(doc, report, figures)
    _study(doc, report)


class ReportFileError(InputError):
    """A ``reproduce.json`` that is not one this version writes; the message names the file and the key."""


#: Top-level keys of ``reproduce.json`` and the JSON types each must have (the documents read them all).
REPORT_KEYS: dict[str, tuple[type, ...]] = {
    "weeks": (int, float, type(None)), "seeds": (list,), "eta_sys": (int, float), "heat_eta": (int, float),
    "heat_mode": (str,), "targets": (dict,), "statements": (dict, list), "source": (str,),
    "paper_ratios": (dict,), "base": (dict,), "h2": (list,), "windows": (dict,), "figures": (dict,),
    "study": (list,), "ambiguities": (list,), "runs_made": (int,), "wall_s": (int, float),
    "runs_from": (str, type(None)),
}


def check_report(report: Any, source: str) -> dict[str, Any]:
    """``report`` (the content of a ``reproduce.json``) if its keys have the types the documents read.

    Each figure must be a PNG path inside ``figures/`` (no ``..``, not absolute), so that a
    crafted file cannot make ``--from-json`` or ``--update-doc`` read or copy other files.

    Raises
    ------
    ReportFileError
        Naming ``source`` and the first key that is missing or of the wrong type.
    """
    import math

    if not isinstance(report, dict):
        raise ReportFileError(f"{source}: expected a JSON object (the content of reproduce.json), got "
                              f"{type(report).__name__}")
    for key, types in REPORT_KEYS.items():
        if key not in report:
            raise ReportFileError(f"{source}: key '{key}' missing (not a reproduce.json of this version)")
        value = report[key]
        if isinstance(value, bool) or not isinstance(value, types):
            names = " or ".join("null" if t is type(None) else t.__name__ for t in types)
            raise ReportFileError(f"{source}: '{key}' must be {names}, got {type(value).__name__}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ReportFileError(f"{source}: '{key}' must be finite, got {value}")
    if report["runs_made"] < 0 or report["wall_s"] < 0:
        raise ReportFileError(f"{source}: 'runs_made' and 'wall_s' must not be negative")
    if not all(isinstance(x, int) and not isinstance(x, bool) and 0 <= x < 2**32 for x in report["seeds"]) \
            or not report["seeds"]:
        raise ReportFileError(f"{source}: 'seeds' must be a non-empty list of integers in 0..2^32-1")
    for name, rel in report["figures"].items():
        parts = Path(str(rel)).parts
        if not isinstance(rel, str) or Path(rel).is_absolute() or ".." in parts or parts[:1] != ("figures",) \
                or not rel.endswith(".png"):
            raise ReportFileError(f"{source}: figures.{name}: {rel!r} is not a PNG file inside figures/")
    for key in ("study", "ambiguities", "h2"):
        for i, item in enumerate(report[key]):
            if not isinstance(item, dict):
                raise ReportFileError(f"{source}: {key}[{i}] must be an object, got {type(item).__name__}")
    return report


def build_document(report: Mapping[str, Any], out: Path) -> Document:
    """The blocks of the reproduction report written into ``out`` (figures in ``out/figures``)."""
    doc = Document(TITLE)
    doc.p("Kovacevic et al., \"ComEMS4Build: Comfort-Oriented Energy Management System for Residential "
          "Buildings using Hydrogen for Seasonal Storage\", Applied Energy. Default scenario: the paper's "
          "winter from 2022-12-01 (ENTSO-E day-ahead prices DE-LU, DWD air temperature of station "
          "Rheinstetten, DHWcalc hot-water draws; radiation and appliance load modelled). "
          f"{report['runs_made']} runs in {report['wall_s']:.0f} s"
          + (" (evaluated again from the run directories without simulating)." if report.get("runs_from") else "."))
    _sections(doc, report, (out / "figures", "figures"))
    return doc


#: Markers of the generated part of docs/calibration.md (``reproduce --update-doc``).
DOC_BEGIN = "<!-- reproduce:begin -->"
DOC_END = "<!-- reproduce:end -->"


#: Where docs/calibration.md keeps the figures of the reproduction (relative to it), and the
#: width they are stored at [px] (the report's PNGs are 300 dpi).
DOC_FIGURES = "figures/reproduce"
DOC_FIGURE_WIDTH_PX = 1400


def doc_section(report: Mapping[str, Any], figures: tuple[Path, str] | None = None) -> str:
    """The tables of the report as Markdown for docs/calibration.md (headings one level down).

    ``figures``: the directory holding the figures' PNGs and its path relative to the
    document; None leaves the figures out.
    """
    doc = Document(TITLE)
    _sections(doc, report, figures)
    text = doc.markdown()
    body = text[text.index("\n## "):].strip()  # without the title and the table of contents
    return "\n".join(("#" + line) if line.startswith("#") else line for line in body.splitlines())


def update_doc(path: str | Path, report: Mapping[str, Any], figures_from: Path | None = None) -> Path:
    """Replace the text between :data:`DOC_BEGIN` and :data:`DOC_END` of ``path`` with :func:`doc_section`.

    ``figures_from``: the reproduction's output directory; its figures are copied (as PNG of
    :data:`DOC_FIGURE_WIDTH_PX`) next to ``path`` under :data:`DOC_FIGURES` and shown.
    """
    return replace_doc_section(path, report, figures_from, (DOC_BEGIN, DOC_END), DOC_FIGURES, doc_section)


def replace_doc_section(path: str | Path, report: Mapping[str, Any], figures_from: Path | None,
                        markers: tuple[str, str], figures_dir: str,
                        section: Callable[[Mapping[str, Any], Any], str]) -> Path:
    """Replace the text between the two ``markers`` of the document ``path`` (written atomically)
    with ``section(report, figures)``; the report's figures, when ``figures_from`` (the command's
    output directory) is given, are copied as PNG of the docs' width under ``figures_dir`` next
    to ``path`` (``figures``: that folder and its relative name, else None)."""
    from comems4build_ros.files.inputs import between_markers, read_text
    from comems4build_ros.files.outputs import write_text_atomic

    path = Path(path)
    begin, end = markers
    head, tail = between_markers(read_text(path, "a document with a generated section"), begin, end, str(path))
    figures = None
    if figures_from is not None and report.get("figures"):
        target = path.parent / figures_dir
        target.mkdir(parents=True, exist_ok=True)
        for rel in report["figures"].values():
            downscale_png(Path(figures_from) / rel, target / Path(rel).name)
        figures = (target, figures_dir)
    return write_text_atomic(path, f"{head}{begin}\n{section(report, figures)}\n{end}{tail}")


def downscale_png(src: Path, dst: Path) -> None:
    """Copy the PNG ``src`` to ``dst`` at :data:`DOC_FIGURE_WIDTH_PX` wide (never wider than it is)."""
    from PIL import Image

    with Image.open(src) as im:
        width = min(DOC_FIGURE_WIDTH_PX, im.width)
        height = round(im.height * width / im.width)
        im.convert("RGB").resize((width, height), Image.Resampling.LANCZOS).save(dst, optimize=True)


def write_documents(report: Mapping[str, Any], out: Path) -> tuple[Path, Path]:
    """Write ``reproduce.md`` and ``reproduce.html`` into ``out``; return their paths."""
    doc = build_document(report, out)
    md = out / "reproduce.md"
    html_path = out / "reproduce.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    html_path.write_text(doc.html(), encoding="utf-8")
    return md, html_path


def explained(doc_text: str) -> set[str]:
    """``<ems>/<statement>`` names the explanation section of docs/calibration.md covers."""
    import re

    section = doc_text.split("## Figures off by more than 40 %", 1)
    if len(section) < 2:
        return set()
    return set(re.findall(r"`(\w+/\w+)`", section[1].split("\n## ", 1)[0]))


def unexplained(report: Mapping[str, Any], doc_text: str, keys: Sequence[str] | None = None) -> list[str]:
    """Figures off by more than the study's limit that docs/calibration.md does not explain."""
    names = explained(doc_text)
    limit = report["targets"]["explain_above"]
    return [f"{f['ems']}/{f['key']}" for f in report["base"]["figures"]
            if f["rel_error"] is not None and f["rel_error"] > limit and f"{f['ems']}/{f['key']}" not in names
            and (keys is None or f["key"] in keys)]
