"""``validation.md`` and ``validation.html`` from the content of ``validation.json``, and docs/validation.md.

Both documents come from the same blocks (:class:`~comems4build_ros.report.document.Document`),
so they hold the same numbers; every number is read from the report mapping that
:func:`comems4build_ros.report.validation.evaluate` computed from its runs.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from comems4build_ros.files.quoted import fill_marks, quotes
from comems4build_ros.report.document import Document
from comems4build_ros.report.quoted import STORED, QuoteError, resolve

#: Title of both documents.
TITLE = "ComEMS4Build: validation on cases the defaults were not chosen on"
#: Markers of the generated part of ``docs/validation.md``.
DOC_BEGIN = "<!-- validation:begin -->"
DOC_END = "<!-- validation:end -->"
#: Figures of the docs (next to the page).
DOC_FIGURES = "figures/validation"
#: Subsets in table order.
SUBSETS = ("calibration", "development", "held-out")
#: Marks of a check in the per-case table.
MARK = {True: "yes", False: "NO", None: "-"}


def _pct(x: float | None, digits: int = 0) -> str:
    return "-" if x is None else f"{100 * x:.{digits}f} %"


def _share(c: Mapping[str, Any] | None) -> str:
    if not c or not c["cases"]:
        return "-"
    return f"{c['held']} of {c['cases']} ({_pct(c['share'])})"


def _dist(d: Mapping[str, float] | None, digits: int = 2, scale: float = 1.0, unit: str = "") -> str:
    if not d:
        return "-"
    f = f"{{:.{digits}f}}"
    return (f"{f.format(scale * d['median'])}{unit} [{f.format(scale * d['low'])}.."
            f"{f.format(scale * d['high'])}]")


def _signed(d: Mapping[str, float] | None) -> str:
    if not d:
        return "-"
    return f"{d['median']:+.1f} % [{d['low']:+.1f}..{d['high']:+.1f}]"


def _subsets(report: Mapping[str, Any]) -> list[str]:
    return [s for s in SUBSETS if s in report["subsets"]]


def _intro(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Summary")
    counts = {s: report["subsets"][s]["cases"] for s in _subsets(report)}
    resumed = (f", {report['runs_resumed']} more taken from an interrupted command's run store"
               if report.get("runs_resumed") else "")
    timing = (f"{report['runs_made']} runs made{resumed} in {report['wall_s']:.0f} s"
              + (f" with the load average {report['load_at_start']:.2f} at the start"
                 if report.get("load_at_start") is not None else ""))
    made = (f"the runs of {report['runs_from']} evaluated again ({timing} there)" if report.get("runs_from")
            else timing)
    doc.p(f"The three EMS ({', '.join(report['ems'])}) over {report['weeks']:g} weeks on "
          + ", ".join(f"{n} {s} case{'s' if n != 1 else ''}" for s, n in counts.items())
          + f" ({report['tasks']} runs; {made}). Calibration: the paper's winter on the reproduction's seeds "
          f"({', '.join(str(s) for s in report['seeds'])}), on which the defaults were chosen. Development and "
          "held-out: the validation set of config/validation.yaml (other winters at other stations with their own "
          "prices, other households on the paper's winter), split before any run; choices may look at the "
          "development cases, never at the held-out ones."
          + (f" The MPC ran with `--forecast {report['forecast']}` (docs/mpc.md)." if report.get("forecast") else ""))


def _checks(doc: Document, report: Mapping[str, Any]) -> None:
    share = report["criteria"]["share"]
    doc.h(2, "The checks on every case")
    doc.p(f"Share of the cases of each subset where the check holds; a check is met on a subset when it holds in "
          f"at least {_pct(share)} of its cases.")
    both = (report.get("combined") or {}).get("validation")
    rows = []
    for key, (_label, claim) in report["criteria_text"].items():
        row = [claim]
        for s in _subsets(report):
            c = report["subsets"][s]["criteria"][key]
            row.append(_share(c) + ("" if c["met"] is None else (" met" if c["met"] else " NOT MET")))
        if both:
            row.append(_share(both["criteria"][key]))
        rows.append(row)
    for key, (_label, claim) in report.get("supplementary_text", {}).items():
        rows.append([claim, *(_share(report["subsets"][s]["criteria"].get(key)) for s in _subsets(report)),
                     *([_share(both["criteria"].get(key))] if both else [])])
    doc.table(["check", *_subsets(report), *(["development and held-out"] if both else [])], rows)


def _distributions(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Distributions over the cases")
    doc.p("Median over the subset's cases [lowest..highest]. Paper: cost ratios RBC / ComEMS4Build 1.72 and MPC / "
          "ComEMS4Build 0.52, ComEMS4Build's H2 left 14.14 %, used \"mostly linearly\", its weeks with discomfort "
          "2, its FC +48.44 % hours and +6.09 % toggles against the MPC's. The largest distance of the LOH from the "
          "straight line between the full store and the run's end level is in per cent of the store.")
    rows = []
    for s in _subsets(report):
        d = report["subsets"][s]
        rows.append([s, str(d["cases"]), _dist(d["ratio_rbc"]), _dist(d["ratio_mpc"]),
                     _dist(d["loh_end"]["fuzzy"], 1, 100.0, " %"), _dist((d.get("h2_even") or {}).get("fuzzy"), 1,
                                                                           100.0, " %"),
                     _dist(d["discomfort_weeks"]["fuzzy"], 0),
                     _dist(d["discomfort_weeks"]["rbc"], 0), _signed(d["fc_hours_vs_mpc"]),
                     _signed(d.get("fc_toggles_vs_mpc")), _signed(d["fc_load_vs_mpc"])])
    doc.table(["subset", "cases", "RBC / ComEMS4Build", "MPC / ComEMS4Build", "ComEMS4Build H2 left",
               "its LOH's largest distance from linear use", "ComEMS4Build weeks with discomfort",
               "RBC weeks with discomfort", "ComEMS4Build FC hours vs MPC", "its FC toggles vs MPC",
               "its mean FC load vs MPC"], rows)


def _cases(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "Every case")
    doc.p("Mean buy price and median daily spread of the buy price (EUR/kWh); weekly cost medians (EUR/week); "
          "H2 left at the end of ComEMS4Build (MPC, RBC); weeks with discomfort of ComEMS4Build (RBC, MPC); the "
          "checks in the order of the first table (comfort, cost order, H2 left, FC longer at lower load, RBC sells "
          "most; in brackets the net cost order).")
    rows = []
    for m in report["cases"]:
        c = m["cost"]
        w = m["discomfort_weeks"]
        rows.append([m["id"], m["subset"], f"{m['price_mean']:.3f}", f"{m['spread']:.3f}",
                     *(f"{c[e]:.2f}" if e in c else "-" for e in ("mpc", "fuzzy", "rbc")),
                     f"{_pct(m['loh_end'].get('fuzzy'), 1)} ({_pct(m['loh_end'].get('mpc'), 1)}, "
                     f"{_pct(m['loh_end'].get('rbc'), 1)})",
                     f"{w.get('fuzzy', '-')} ({w.get('rbc', '-')}, {w.get('mpc', '-')})",
                     " ".join(MARK[m["criteria"][k]] for k in report["criteria_text"])
                     + f" (net: {MARK[m['criteria'].get('net_cost_order')]})"])
    doc.table(["case", "subset", "buy price", "spread", "MPC cost", "ComEMS4Build cost", "RBC cost",
               "H2 left", "weeks with discomfort", "checks"], rows)


def _findings(doc: Document, report: Mapping[str, Any]) -> None:
    doc.h(2, "The paper's findings on every case")
    doc.p("Each qualitative finding of the reproduction (comems4build_ros/report/findings.py), checked on every case: "
          "on how many of the subset's cases it holds.")
    rows = []
    for key, claim in report["findings_text"].items():
        row = [f"`{key}`: {claim}"]
        for s in _subsets(report):
            f = report["subsets"][s]["findings"].get(key)
            row.append("-" if not f or not f["cases"] else f"{f['held']} of {f['cases']}")
        rows.append(row)
    doc.table(["finding", *_subsets(report)], rows)


def _band(report: Mapping[str, Any]) -> str:
    band = report["criteria"].get("fc_hours_band_pct")
    return f"{band[0]:+.0f}..{band[1]:+.0f} %" if band else "-"


def _fit(fit: Mapping[str, Any] | None) -> str:
    if not fit:
        return "-"
    fc = fit.get("fc") or {}
    hours, toggles = fc.get("fuzzy_hours"), fc.get("fuzzy_toggles")
    fc_text = (f"; FC hours {hours['median']:+.0f} %, toggles {toggles['median']:+.0f} %"
               if hours and toggles else "")
    return (f"{_pct(fit['median_rel_error'], 1)} / {_pct(fit['table_rel_error'], 1)}; "
            f"{fit['findings_held']} of {fit['findings_total']} findings{fc_text}")


def _study(doc: Document, report: Mapping[str, Any]) -> None:
    if not report["study"]:
        return
    doc.h(2, "Every reading: calibration and validation")
    doc.p("Each reading of the reproduction's ambiguities (config/reproduce.yaml) run on every case with every other "
          "ambiguity at its default; (default) marks the shipped reading. Calibration fit: the reproduction's "
          "seed-median error over every stated figure / over the headline table, the findings holding on its "
          "seeds, and ComEMS4Build's FC working hours and toggles against the MPC's (seed medians; the reproduction's "
          "band for the hours " + _band(report) + "). Then per subset the share of cases holding each check "
          "(comfort, cost order, H2 left and spent evenly, FC longer at lower load, RBC sells most) and the "
          "medians of ComEMS4Build's H2 left and of the cost ratio RBC / ComEMS4Build.")
    by_amb: dict[str, list[Mapping[str, Any]]] = {}
    for r in report["study"]:
        by_amb.setdefault(r["ambiguity"], []).append(r)
    for amb, readings in by_amb.items():
        doc.h(3, f"{report['ambiguities'].get(amb, amb)} ({amb})")
        rows = []
        for r in readings:
            name = r["reading"] + (" (default)" if r["default"] else "")
            for s in _subsets(report):
                d = r["subsets"].get(s)
                if d is None:
                    continue
                checks = " / ".join(_pct(d["criteria"][k]["share"]) for k in report["criteria_text"])
                rows.append([name, s, _fit(r["calibration_fit"]) if s == "calibration" else "",
                             checks, _dist(d["loh_end"]["fuzzy"], 1, 100.0, " %"), _dist(d["ratio_rbc"])])
        doc.table(["reading", "subset", "calibration fit", "checks held (shares)", "ComEMS4Build H2 left",
                   "RBC / ComEMS4Build"], rows)


def _fit_short(fit: Mapping[str, Any] | None) -> str:
    return _fit(fit) if fit and fit.get("findings_held") is not None else "-"


def _identity(ident: Mapping[str, Any] | None) -> str:
    if not ident:
        return "not recorded (runs made before validate recorded it)"
    commit = ident.get("git_commit")
    git = (f"commit {commit[:12]}" + (" with uncommitted changes" if ident.get("git_dirty") else "")
           if commit else "no git checkout")
    return f"{git}; code {ident['code_sha256'][:12]}, parameters {ident['parameters_sha256'][:12]}"


def _choice(doc: Document, report: Mapping[str, Any]) -> None:
    choice = report.get("choice")
    if not choice:
        return
    doc.h(2, "The choice of the defaults")
    doc.p(f"The choosing step (validate --choose) reads only the calibration and development cases "
          f"({len(choice['cases'])} cases); the rule: {choice['rule']}. Checks met: of the five checks, those "
          f"holding in at least {_pct(choice['share'])} of the subset's cases. Calibration fit: the reproduction's "
          "seed-median error over every stated figure / the headline table, the findings holding on its seeds and "
          "ComEMS4Build's FC hours against the MPC's. Defaults of the runs: "
          + _identity((choice.get("defaults") or {}).get("runs")) + ".")
    rows = []
    for amb, a in choice["ambiguities"].items():
        for r in a["readings"]:
            mark = " (shipped)" if r["shipped"] else ""
            mark += " (chosen)" if r["reading"] == a["chosen"] else ""
            rows.append([amb, a["decided_by"], r["reading"] + mark, "-" if r["development_met"] is None else
                         str(r["development_met"]), "-" if r["calibration_met"] is None else str(r["calibration_met"]),
                         _fit_short(r["calibration_fit"]), str(len(r["runs"]))])
    doc.table(["ambiguity", "decided by", "reading", "checks met, development", "checks met, calibration",
               "calibration fit", "runs read"], rows)
    differ = [f"{k} (shipped {a['shipped']}, chosen {a['chosen']})" for k, a in choice["ambiguities"].items()
              if not a["agrees"]]
    doc.p("Every shipped default is the chosen reading." if not differ else
          "The shipped default differs from the chosen reading: " + "; ".join(differ) + ".")


def _judged(doc: Document, report: Mapping[str, Any]) -> None:
    rec = report.get("judged")
    if not rec:
        return
    doc.h(2, "What the held-out cases judged")
    text = (f"The judging step (validate --judge) ran the {len(rec['cases'])} held-out cases with the defaults of "
            + _identity(rec.get("defaults")) + "; evaluated at " + _identity(rec.get("evaluated")) + ".")
    c = rec.get("choice")
    if c is not None:
        text += (" The choice it judges was made " + ("on the same simulation code and default parameters"
                                                       if c["same_defaults"] else
                                                       "on other simulation code or default parameters ("
                                                       + _identity(c.get("defaults")) + ")") + "; "
                 + ("every shipped default is the chosen reading." if not c["differ"] else
                    "shipped and chosen readings differ for " + ", ".join(
                        f"{k} ({v[0]} against {v[1]})" for k, v in c["differ"].items()) + "."))
    doc.p(text)


def _radiation(doc: Document, report: Mapping[str, Any]) -> None:
    rows = report.get("radiation") or []
    if not rows:
        return
    doc.h(2, "Radiation of the cases")
    doc.p("Daily global horizontal irradiation per month (kWh/m2/d), the diffuse share of the run's steps and the "
          "daylight hours without a sunshine report (interpolated), median over the group's cases [range]: the "
          "winter cases' radiation from the sunshine duration (Angstrom-Prescott with FAO-56's coefficients on the "
          "extraterrestrial irradiance, Erbs; what the cases run on), beside the variant on pvlib's Ineichen clear "
          "sky (not run) and the paper's winter modelled with seeds as in the default scenario.")
    months = sorted({k for r in rows for k in r if k.startswith("ghi_kwh_m2_day_m")},
                    key=lambda m: (int(m[-2:]) < 7, m))
    names = {"m12": "December", "m01": "January", "m02": "February"}
    head = ["group", "cases", *(names.get(m[-3:], m[-3:]) for m in months), "diffuse share",
            "sunshine gaps [h]"]
    doc.table(head, [[r["group"], str(r["cases"]), *(_dist(r.get(m)) for m in months),
                      _dist(r.get("diffuse_share")), _dist(r.get("sunshine_gaps_h"), 0)] for r in rows])


#: Captions of the figures.
CAPTIONS = {
    "validation_cases": (
        "One point per case: filled black the calibration cases, filled blue the development cases, open orange "
        "the held-out cases; triangles winter cases, squares household cases. (a) Cost ratios (weekly medians) with "
        "the paper's (star); (b) ComEMS4Build's H2 left at the end and the largest distance of its LOH from the "
        "straight line to that end level, against the check's band and limit; (c) its FC working hours and mean FC "
        "load against the MPC's (the check: right of the reproduction's lower band end, below -5 %)."),
    "validation_prices": (
        "The same cases against their prices: (a) ComEMS4Build's advantage over the RBC against the median daily "
        "spread of the buy price; (b) the MPC's cost against ComEMS4Build's and (c) the MPC's H2 left at the end "
        "against the mean buy price; the line in (c) is the price below which an hour of the MPC's FC at full "
        "permissible power costs more in lifecycle cost than the electricity it replaces."),
}


def _figures(doc: Document, report: Mapping[str, Any], out: Path, rel_dir: str | None = None) -> None:
    names = [k for k in CAPTIONS if k in report.get("figures", {})]
    if not names:
        return
    doc.h(2, "Figures")
    for name in names:
        rel = report["figures"][name]
        png = out / rel if rel_dir is None else out / Path(rel).name
        doc.figure(png, rel_dir if rel_dir is not None else str(Path(rel).parent), CAPTIONS[name])


#: The parts of the documents in order.
PARTS = (_intro, _checks, _distributions, _cases, _findings, _choice, _judged, _study, _radiation)


def build_document(report: Mapping[str, Any], out: Path) -> Document:
    """The whole report as a :class:`Document`."""
    doc = Document(TITLE)
    for part in PARTS:
        part(doc, report)
    _figures(doc, report, out)
    return doc


def write_documents(report: Mapping[str, Any], out: Path) -> tuple[Path, Path]:
    """Write ``validation.md`` and ``validation.html`` into ``out``; return their paths."""
    doc = build_document(report, out)
    md, html_path = out / "validation.md", out / "validation.html"
    md.write_text(doc.markdown(), encoding="utf-8")
    html_path.write_text(doc.html(), encoding="utf-8")
    return md, html_path


def doc_section(report: Mapping[str, Any], figures: tuple[Path, str] | None = None) -> str:
    """The generated part of docs/validation.md (headings one level down).

    ``figures``: the directory holding the figures' PNGs and its path relative to the
    document; None leaves the figures out.
    """
    doc = Document(TITLE)
    for part in PARTS:
        part(doc, report)
    if figures is not None:
        _figures(doc, report, figures[0], figures[1])
    text = doc.markdown()
    body = text[text.index("\n## "):].strip()  # without the title and the table of contents
    return "\n".join(("#" + line) if line.startswith("#") else line for line in body.splitlines())


def update_doc(path: str | Path, report: Mapping[str, Any], figures_from: Path | None = None) -> Path:
    """Write the validation into ``path``: a Markdown document's generated part, and every file's quoted figures.

    A Markdown file (``.md``) gets :func:`doc_section` between the validation markers (its
    figures, from the command's output directory ``figures_from``, copied as PNG of the docs'
    width under ``figures/validation``) and the report stored next to it
    (``results/validation.json``, :data:`~comems4build_ros.report.quoted.STORED`); in every file the
    quoted figures (:mod:`comems4build_ros.files.quoted`) are filled from the report.

    Raises
    ------
    InputFileError
        For a Markdown file without the markers, or a quoted figure the report does not hold
        (naming the file, its line and the key).
    """
    from comems4build_ros.files.outputs import write_text_atomic
    from comems4build_ros.report.reproduce_doc import replace_doc_section

    path = Path(path)
    if path.suffix == ".md":
        replace_doc_section(path, report, figures_from, (DOC_BEGIN, DOC_END), DOC_FIGURES, doc_section)
        stored = path.parent / STORED["validation"]
        stored.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(stored, json.dumps(report, indent=1) + "\n")
    write_text_atomic(path, fill_quotes(path, {"validation": report}))
    return path


def fill_quotes(path: Path, stored: Mapping[str, Mapping[str, Any]]) -> str:
    """The text of ``path`` with its quoted figures filled from ``stored`` (study -> results).

    Raises
    ------
    InputFileError
        Naming the file, the line and the key of a figure that cannot be resolved, or why the
        file cannot be read as text.
    """
    from comems4build_ros.files.inputs import InputFileError, read_text

    text = read_text(path, "a document with quoted figures")
    lines = {q.key: q.line for q in quotes(text)}

    def value_of(key: str) -> str:
        try:
            return resolve(key, stored)
        except QuoteError as err:
            raise InputFileError(f"{path}:{lines.get(key, '?')}: quoted figure {err}") from None

    return fill_marks(text, value_of)
