"""``reproduce.md`` and ``reproduce.html`` from the content of ``reproduce.json``.

Both documents come from the same blocks (:class:`~comems4build_ros.report.document.Document`:
a table of contents, units in the headers, numbers right-aligned), so they hold the same
numbers; every number is read from the report mapping that
:func:`comems4build_ros.report.reproduce.reproduce` computed from its runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .document import Document

#: Title of both documents.
TITLE = "ComEMS4Build: reproducing the paper"
EMS = ("mpc", "fuzzy", "rbc")
EMS_LABEL = {"mpc": "MPC", "fuzzy": "ComEMS4Build", "rbc": "RBC"}
FIGURE_LABEL = {
    "cost": "cost, weekly median",
    "buy": "bought, weekly median",
    "sell": "sold, weekly median",
    "bess_charged": "BESS charged, weekly median",
    "loh_end": "LOH left at the end",
}
#: The paper's H2 figures (sec:results): weekly "H2 consumption" ranges and the value of the H2 left.
PAPER_H2 = {
    "mpc": ("23.44..123.08", "36.04"),
    "fuzzy": ("54.11..78.54", "97.75"),
    "rbc": ("-", "68.68"),
}


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f} %"


def _num(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}"


def _table(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "The paper's table beside ours")
    doc.p(f"Weekly medians over {report['weeks']:g} weeks of the default scenario "
          f"({report['scenario']}); relative error = |ours - paper| / paper, for the paper's nonzero "
          "figures. Paper: sec:results (the figures of the occupant-oriented metrics, the grid utilization, the "
          "HESS utilization and the H2 over the period).")
    by = {(r["figure"], r["ems"]): r for r in report["table"]}
    header = ["figure", "unit"]
    for e in EMS:
        header += [f"{EMS_LABEL[e]} paper", f"{EMS_LABEL[e]} ours", f"{EMS_LABEL[e]} error"]
    rows = []
    for fig in FIGURE_LABEL:
        row = [FIGURE_LABEL[fig], by[(fig, "mpc")]["unit"]]
        for e in EMS:
            r = by[(fig, e)]
            row += [_num(r["paper"]), _num(r["ours"]), _pct(r["rel_error"])]
        rows.append(row)
    doc.table(header, rows)
    target = report["median_error_target"]
    med = report["median_rel_error"]
    doc.p(f"Median relative error over the {sum(r['rel_error'] is not None for r in report['table'])} nonzero "
          f"figures: {_pct(med)} (target at most {_pct(target)}: {'met' if med <= target else 'not met'}).")
    above = [r for r in report["table"] if r["rel_error"] is not None and r["rel_error"] > report["explain_above"]]
    if above:
        doc.p(f"Figures off by more than {_pct(report['explain_above'])} (explained in docs/calibration.md): "
              + "; ".join(f"{EMS_LABEL[r['ems']]} {FIGURE_LABEL[r['figure']]}: {_num(r['ours'])} vs "
                          f"{_num(r['paper'])} ({_pct(r['rel_error'])})" for r in above) + ".")
    tol = report["ratio_tolerance"]
    rows = []
    for key, value in report["ratios"].items():
        p = report["paper_ratios"][key]
        lo, hi = p * (1 - tol), p * (1 + tol)
        a, b = key.split("/")
        rows.append([f"{EMS_LABEL[a]} / {EMS_LABEL[b]}", _num(p), f"{_num(lo)}..{_num(hi)}", _num(value),
                     "yes" if lo <= value <= hi else "no"])
    doc.h(3, "Cost ratios")
    doc.table(["weekly cost median", "paper", "target band", "ours", "in band"], rows)


def _h2(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Hydrogen")
    doc.p("Weekly H2 use as the FC's electrical output and as the LHV energy drawn from the store "
          "(min..max over the weeks); the paper's \"H2 consumption\" ranges fit the electrical output. "
          "Value of the H2 left = (LOH_end - LOH_min) x 1800 kWh x mean buy price of the run "
          "(the paper's method, sec:results); net cost = cost - reimbursement - that value.")
    rows = []
    for r in report["h2"]:
        paper_range, paper_value = PAPER_H2[r["ems"]]
        rows.append([
            EMS_LABEL[r["ems"]],
            f"{_num(r['fc_kwh_week_min'], 1)}..{_num(r['fc_kwh_week_max'], 1)}",
            f"{_num(r['h2_kwh_week_min'], 1)}..{_num(r['h2_kwh_week_max'], 1)}",
            paper_range,
            _num(r["loh_end_pct"]),
            _num(r["price_buy_mean_eur_per_kwh"], 3),
            _num(r["h2_left_value_eur"]),
            paper_value,
            _num(r["cost_net_eur_week"]),
        ])
    doc.table(["EMS", "FC electrical [kWh/week]", "H2 LHV [kWh/week]", "paper H2 [kWh/week]", "LOH left [%]",
               "mean buy price [EUR/kWh]", "value of H2 left [EUR]", "paper value [EUR]",
               "net cost [EUR/week]"], rows)


def _checks(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "The paper's findings")
    held = sum(c["held"] for c in report["checks"])
    doc.p(f"{held} of {len(report['checks'])} held.")
    doc.table(["finding", "paper", "held", "evidence"],
              [[c["claim"], c["source"], "held" if c["held"] else "NOT HELD", c["evidence"]]
               for c in report["checks"]])


def _study(doc: Document, report: Mapping[str, Any]) -> None:
    if not report["ambiguities"]:
        return
    doc.h(2, "Interpretation study")
    doc.p("Each reading is run on top of the defaults (every other ambiguity at its default reading). "
          "Columns: median and largest relative error over the paper's nonzero figures, the cost ratios "
          "(paper: RBC / ComEMS4Build 1.72, MPC / ComEMS4Build 0.52) and the findings held.")
    results = {(r["ambiguity"], r["reading"]): r for r in report["study"]}
    for a in report["ambiguities"]:
        doc.h(3, f"{a['title']} ({a['key']})")
        doc.p(f"Paper: {a['source']}")
        rows = []
        for rd in a["readings"]:
            r = results[(a["key"], rd["name"])]
            mark = " (default)" if rd["name"] == a["default"] else ""
            rows.append([
                rd["name"] + mark, rd["text"], _pct(r["median_rel_error"]), _pct(r["max_rel_error"]),
                _num(r["ratios"]["rbc/fuzzy"]), _num(r["ratios"]["mpc/fuzzy"]),
                f"{r['findings_held']} of {r['findings']}" + (f" (not: {', '.join(r['not_held'])})"
                                                               if r["not_held"] else ""),
            ])
        doc.table(["reading", "what", "median error", "largest error", "RBC/fuzzy", "MPC/fuzzy", "findings held"],
                  rows)
        doc.p(f"Chosen: {a['default']}. {a['reason']}")
        fig_rows = []
        for rd in a["readings"]:
            r = results[(a["key"], rd["name"])]
            for e in a["ems"]:
                d = r["discomfort"][e]
                fig_rows.append([rd["name"], EMS_LABEL[e]] + [_num(r["values"][f"{f}/{e}"]) for f in FIGURE_LABEL]
                                + [_num(d["median_kh"]), str(d["weeks"])])
        doc.table(["reading", "EMS", *FIGURE_LABEL.values(), "discomfort median [Kh/week]", "weeks with discomfort"],
                  fig_rows)


def build_document(report: Mapping[str, Any]) -> Document:
    """The blocks of the reproduction report."""
    doc = Document(TITLE)
    doc.p("Kovacevic et al., \"ComEMS4Build: Comfort-Oriented Energy Management System for Residential "
          "Buildings using Hydrogen for Seasonal Storage\", Applied Energy. Default scenario: the paper's "
          "winter from 2022-12-01 (ENTSO-E day-ahead prices DE-LU, DWD air temperature of station "
          "Rheinstetten, DHWcalc hot-water draws; radiation and appliance load modelled). "
          f"{report['runs_made']} runs in {report['wall_s']:.0f} s"
          + (" (evaluated again from the run directories without simulating)." if report.get("runs_from") else "."))
    _table(doc, report)
    _h2(doc, report)
    _checks(doc, report)
    _study(doc, report)
    return doc


#: Markers of the generated part of docs/calibration.md (``reproduce --update-doc``).
DOC_BEGIN = "<!-- reproduce:begin -->"
DOC_END = "<!-- reproduce:end -->"


def doc_section(report: Mapping[str, Any]) -> str:
    """The tables of the report as Markdown for docs/calibration.md (headings one level down)."""
    doc = Document(TITLE)
    _table(doc, report)
    _h2(doc, report)
    _checks(doc, report)
    _study(doc, report)
    text = doc.markdown()
    body = text[text.index("\n## "):].strip()  # without the title and the table of contents
    return "\n".join(("#" + line) if line.startswith("#") else line for line in body.splitlines())


def update_doc(path: str | Path, report: Mapping[str, Any]) -> Path:
    """Replace the text between :data:`DOC_BEGIN` and :data:`DOC_END` of ``path`` with :func:`doc_section`."""
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    head, sep, rest = text.partition(DOC_BEGIN)
    _, sep2, tail = rest.partition(DOC_END)
    if not sep or not sep2:
        raise ValueError(f"{path}: markers {DOC_BEGIN} / {DOC_END} not found")
    path.write_text(f"{head}{DOC_BEGIN}\n{doc_section(report)}\n{DOC_END}{tail}", encoding="utf-8")
    return path


def write_documents(report: Mapping[str, Any], out: Path) -> tuple[Path, Path]:
    """Write ``reproduce.md`` and ``reproduce.html`` into ``out``; return their paths."""
    doc = build_document(report)
    md = out / "reproduce.md"
    html_path = out / "reproduce.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    html_path.write_text(doc.html(), encoding="utf-8")
    return md, html_path
