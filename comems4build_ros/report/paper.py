"""The paper's stated results (``paper_results.yaml``) beside the measured ones.

Every quantitative statement of the paper's abstract, ``sec:results`` and
``sec:discussion`` is an entry of ``paper_results.yaml``: the printed value per EMS (or for
the scenario's inputs), where the paper states it, and the *measure* it is compared with.
:func:`evaluate_statements` measures each one on a set of runs and returns one
:class:`Figure` per (statement, EMS) with the relative error, or for a bound or a set of
weeks whether it held. :func:`aggregate` combines the figures of several runs of the same
study (e.g. seeds of the modelled inputs) into the median over them with its range.

Week numbers are the paper's: week 1 starts with the run (2022-12-01 00:00 local for the
default scenario), 168 hours each; only full weeks count.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.kpi import DISCOMFORT_TOL_KH, HOURS_PER_WEEK
from comems4build_ros.files.inputs import load_yaml_file
from comems4build_ros.report.runs import RunData

#: Data file with the paper's statements (source label inside).
PAPER_RESULTS_FILE = Path(__file__).with_name("paper_results.yaml")
#: Percent per fraction.
PERCENT = 100.0
#: Hours per day.
HOURS_PER_DAY = 24.0
#: The pseudo-EMS of a statement about the scenario's inputs (the same in every run).
INPUT = "input"
#: Kinds of paper value.
VALUE, ZERO, BOUND, WEEKS = "value", "zero", "bound", "weeks"


@dataclass(frozen=True)
class Statement:
    """One quantitative statement of the paper.

    Attributes
    ----------
    key : short name
    label : the quantity, as the report prints it
    unit : its unit
    where : section / figure label of the paper
    quote : the paper's sentence
    measure : ``{"of": <measure name>, ...arguments}``
    paper : EMS (or ``input``) -> printed value: a number, ``{"below": x}`` or a list of weeks
    table : one of the paper's headline figures (weekly medians and H2 left)
    error_on : ``value`` or ``ratio`` (relative error of ``1 + x / 100`` for "x % more than")
    note : remark on how the quantities compare (optional)
    locates : name of the window the value locates (then it is shown, not compared)
    """

    key: str
    label: str
    unit: str
    where: str
    quote: str
    measure: dict[str, Any]
    paper: dict[str, Any]
    table: bool = False
    error_on: str = "value"
    note: str = ""
    locates: str = ""

    @property
    def eta(self) -> float | None:
        """FC system efficiency the statement is measured at (None: the runs' base efficiency)."""
        eta = self.measure.get("eta")
        return None if eta is None else float(eta)


@dataclass(frozen=True)
class Windows:
    """The paper's three-day windows, as its text locates them (``windows`` in the file).

    Attributes
    ----------
    start : local start of fig:performance_comparison (ISO 8601, no offset)
    days : length of both windows [d]
    after_days : the high-PV window starts at least this long after the run's start [d]
    trough : lowest buy price in the high-PV window [EUR/kWh]
    trough_tol : tolerance of ``trough`` [EUR/kWh]
    """

    start: str
    days: int
    after_days: float
    trough: float
    trough_tol: float


@dataclass(frozen=True)
class Statements:
    """The contents of ``paper_results.yaml``."""

    source: str
    ems: tuple[str, ...]
    zero_tol: float
    windows: Windows
    statements: tuple[Statement, ...]

    def get(self, key: str) -> Statement:
        """The statement called ``key``."""
        for s in self.statements:
            if s.key == key:
                return s
        raise KeyError(key)


def value_kind(value: Any) -> str:
    """Kind of a printed paper value: ``value``, ``zero``, ``bound`` or ``weeks``."""
    if isinstance(value, list):
        return WEEKS
    if isinstance(value, dict):
        return BOUND
    return ZERO if float(value) == 0.0 else VALUE


def _check_value(value: Any, where: str) -> None:
    if isinstance(value, bool):
        raise ValueError(f"{where}: a value must be a number, {{below: x}} or a list of weeks, got {value!r}")
    if isinstance(value, list):
        if not all(isinstance(w, int) and not isinstance(w, bool) and w >= 1 for w in value):
            raise ValueError(f"{where}: a list of weeks must hold week numbers >= 1, got {value!r}")
        return
    if isinstance(value, dict):
        if set(value) != {"below"} or isinstance(value["below"], bool) or not isinstance(value["below"], int | float):
            raise ValueError(f"{where}: a bound must be {{below: <number>}}, got {value!r}")
        return
    if not isinstance(value, int | float) or not math.isfinite(float(value)):
        raise ValueError(f"{where}: a value must be a finite number, got {value!r}")


def load_paper_results(path: str | Path = PAPER_RESULTS_FILE) -> Statements:
    """Read and check ``paper_results.yaml``.

    Raises
    ------
    ValueError
        Naming the file and the entry that is missing or invalid.
    """
    p = Path(path)
    data = load_yaml_file(p, "the paper's results")
    if not isinstance(data, dict) or not {"source", "ems", "statements", "windows"} <= set(data):
        raise ValueError(f"{p}: needs keys source, ems, windows, statements")
    try:
        pc, hp = data["windows"]["performance_comparison"], data["windows"]["high_pv"]
        windows = Windows(start=str(pc["start"]), days=int(pc["days"]), after_days=float(hp["after_days"]),
                          trough=float(hp["trough"]), trough_tol=float(hp["trough_tol"]))
        pd.Timestamp(windows.start)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{p}: windows: needs performance_comparison.start (ISO 8601), .days and high_pv."
                         f"after_days, .trough, .trough_tol ({exc})") from None
    ems = tuple(data["ems"])
    out: list[Statement] = []
    keys: set[str] = set()
    for i, row in enumerate(data["statements"]):
        where = f"{p}: statements[{i}]"
        missing = {"key", "label", "unit", "where", "quote", "measure", "paper"} - set(row)
        if missing:
            raise ValueError(f"{where} lacks {', '.join(sorted(missing))}")
        where = f"{p}: statement '{row['key']}'"
        if row["key"] in keys:
            raise ValueError(f"{where}: key given twice")
        keys.add(row["key"])
        measure = row["measure"]
        if not isinstance(measure, dict) or measure.get("of") not in MEASURES:
            raise ValueError(f"{where}: measure.of must be one of {', '.join(sorted(MEASURES))}, got {measure!r}")
        unknown = sorted(set(row["paper"]) - {*ems, INPUT})
        if unknown or not row["paper"]:
            raise ValueError(f"{where}: paper values for {', '.join(unknown) or 'nothing'} "
                             f"(known: {', '.join((*ems, INPUT))})")
        for e, value in row["paper"].items():
            _check_value(value, f"{where}, paper.{e}")
        error_on = row.get("error_on", "value")
        if error_on not in ("value", "ratio"):
            raise ValueError(f"{where}: error_on must be value or ratio, got {error_on!r}")
        out.append(Statement(
            key=str(row["key"]), label=str(row["label"]), unit=str(row["unit"]), where=str(row["where"]),
            quote=" ".join(str(row["quote"]).split()), measure=dict(measure), paper=dict(row["paper"]),
            table=bool(row.get("table", False)), error_on=error_on, note=" ".join(str(row.get("note", "")).split()),
            locates=str(row.get("locates", "")),
        ))
    return Statements(source=" ".join(str(data["source"]).split()), ems=ems,
                      zero_tol=float(data.get("zero_tol", 0.0)), windows=windows, statements=tuple(out))


def fmt(value: float, digits: int = 2) -> str:
    """Fixed-point number as printed in the report (``digits`` decimals)."""
    return f"{value:.{digits}f}"


# --------------------------------------------------------------------------- what is measured


@dataclass
class Evidence:
    """The runs statements are measured on.

    Attributes
    ----------
    runs : EMS name -> run at the base FC system efficiency
    params : plant parameters of the base runs (time zone, H2 store, LOH_min)
    base_eta : FC system efficiency of the base runs [-]
    variants : (EMS name, eta_sys) -> run, other efficiencies (sec:heat_recovery)
    windows : the paper's windows (default: those of ``paper_results.yaml``)
    """

    runs: Mapping[str, RunData]
    params: PlantParams
    base_eta: float
    variants: Mapping[tuple[str, float], RunData] = field(default_factory=dict)
    windows: Windows | None = None
    _spans: dict[int, dict[str, tuple[int, int]]] = field(default_factory=dict, repr=False)

    def window(self, run: RunData, name: str) -> tuple[int, int]:
        """Step range of the paper's window ``name`` in ``run`` (:func:`paper_windows`)."""
        if id(run) not in self._spans:
            self._spans[id(run)] = paper_windows(run, self.tz, self.windows)
        return self._spans[id(run)][name]

    def run(self, ems: str, eta: float | None = None) -> RunData | None:
        """The run of ``ems`` at ``eta`` (None: base), or None when it was not made."""
        if eta is None or math.isclose(eta, self.base_eta):
            return self.runs.get(ems)
        for (e, v), run in self.variants.items():
            if e == ems and math.isclose(v, eta):
                return run
        return None

    @property
    def tz(self) -> str:
        """Local time zone of the site."""
        return self.params.site.timezone


def full_weeks(run: RunData) -> pd.DataFrame:
    """The weekly table without a last partial week."""
    w = run.weekly
    return w[w["hours"] >= HOURS_PER_WEEK - 1e-9] if "hours" in w else w


def week_value(run: RunData, column: str, week: int) -> float | None:
    """``column`` of week ``week`` (paper numbering, 1 = first week of the run), None if absent."""
    w = full_weeks(run)
    row = w[w["week"] == week]
    return None if row.empty else float(row[column].iloc[0])


def _local(run: RunData, tz: str) -> pd.Series:
    return pd.to_datetime(run.timeseries["time"], utc=True).dt.tz_convert(tz)


def _local_time(text: str, tz: str) -> pd.Timestamp:
    return pd.Timestamp(text).tz_localize(tz) if pd.Timestamp(text).tzinfo is None else pd.Timestamp(text)


def _week_mask(run: RunData, weeks: int | Sequence[int]) -> np.ndarray:
    ws = [weeks] if isinstance(weeks, int) else list(weeks)
    week_of_step = np.arange(len(run.timeseries)) // int(HOURS_PER_WEEK) + 1
    return np.isin(week_of_step, ws)


def paper_windows(run: RunData, tz: str, windows: Windows | None = None) -> dict[str, tuple[int, int]]:
    """Step ranges ``[start, stop)`` of the paper's two three-day windows (:class:`Windows`).

    ``performance_comparison``: from ``windows.start`` when the run covers it, else the
    run's days of highest mean buy price. ``high_pv``: of the windows starting at midnight at
    least ``after_days`` after the run's start whose lowest buy price is within
    ``trough_tol`` of ``trough``, the one with the most global radiation; without one, the
    sunniest window after ``after_days`` (or of the whole run). Runs shorter than the
    windows give the whole run for both.
    """
    w = windows or load_paper_results().windows
    ts = run.timeseries
    local = _local(run, tz)
    n = len(ts)
    length = int(HOURS_PER_DAY * w.days)
    starts = [i for i in range(n) if local.iloc[i].hour == 0 and i + length <= n]
    if not starts:
        return {"performance_comparison": (0, n), "high_pv": (0, n)}
    price = ts["price_buy_eur_per_kwh"].to_numpy(dtype=float)
    ghi = ts["ghi_w_m2"].to_numpy(dtype=float)
    first = _local_time(w.start, tz)
    fixed = [i for i in starts if local.iloc[i] == first]
    cold = fixed[0] if fixed else max(starts, key=lambda s: float(price[s : s + length].mean()))
    late = [s for s in starts if s >= w.after_days * HOURS_PER_DAY] or starts
    trough = [s for s in late if abs(float(price[s : s + length].min()) - w.trough) <= w.trough_tol] or late
    sunny = max(trough, key=lambda s: float(ghi[s : s + length].sum()))
    return {"performance_comparison": (cold, cold + length), "high_pv": (sunny, sunny + length)}


def h2_floor(ems: str, loh_min: float) -> float:
    """The H2 level at which the store of ``ems`` counts as empty [-].

    The plant's ``loh_min``, except for the RBC, which stops its FC at its own limit
    (``rbc.loh_reserve`` in ``config/rbc.yaml``; :func:`comems4build_ros.core.ems.rbc.loh_floor`).
    """
    if ems != "rbc":
        return loh_min
    from comems4build_ros.core.ems.settings import RBCSettings, load_settings

    return max(loh_min, load_settings(RBCSettings).loh_reserve)


#: The H2 store counts as empty within this fraction of the store above its floor [-]
#: (a FC at its minimum power needs about 0.4 kWh of H2 per hour; a remainder of 1 % of the
#: default 1800 kWh store is about a day of minimum operation).
H2_EMPTY_TOL = 0.01


def h2_empty_days_before_end(run: RunData, loh_min: float, tol: float = H2_EMPTY_TOL) -> float | None:
    """Days between the H2 store first falling to ``LOH_min + tol`` and the end of the run, or None [d]."""
    loh = run.timeseries["loh"].to_numpy(dtype=float)
    hit = (loh <= loh_min + tol).nonzero()[0]
    if hit.size == 0:
        return None
    end = pd.Timestamp(run.timeseries["time"].iloc[-1])
    reached = pd.Timestamp(run.timeseries["time"].iloc[int(hit[0])])
    return float((end - reached).total_seconds() / 3600.0 / HOURS_PER_DAY)


def covered_weeks(run: RunData) -> list[int]:
    """Full weeks whose DHW demand (with the tank's losses) the FC's heat covers."""
    w = full_weeks(run)
    return [int(x) for x in w.loc[w["heat_recovered_kwh"] >= w["dhw_demand_kwh"], "week"]]


Measure = Callable[[Evidence, str, RunData, Mapping[str, Any]], float | list[int] | None]


def _summary(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float:
    return float(run.summary[m["key"]]) * float(m.get("scale", 1.0))


def _minus_mpc(ev: Evidence, ems: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    mpc = ev.run("mpc")
    return None if mpc is None else float(run.summary[m["key"]]) - float(mpc.summary[m["key"]])


def _minus(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    other = ev.run(m["other"])
    return None if other is None else float(run.summary[m["key"]]) - float(other.summary[m["key"]])


def _pct_vs_mpc(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    mpc = ev.run("mpc")
    if mpc is None or float(mpc.summary[m["key"]]) == 0.0:
        return None
    ref = float(mpc.summary[m["key"]])
    return PERCENT * (float(run.summary[m["key"]]) - ref) / ref


def _week(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    return week_value(run, m["column"], int(m["week"]))


def _mpc_ranked_week(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    mpc = ev.run("mpc", ev.base_eta)
    if mpc is None:
        return None
    w = full_weeks(mpc).sort_values(m["column"], ascending=False, kind="stable")
    rank = int(m["rank"])
    if len(w) < rank:
        return None
    return week_value(run, m["column"], int(w["week"].iloc[rank - 1]))


def _ranked_week(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    values = sorted(full_weeks(run)[m["column"]].astype(float), reverse=True)
    rank = int(m["rank"])
    return None if len(values) < rank else values[rank - 1]


def _weeks_without(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float:
    return float((full_weeks(run)[m["column"]] <= DISCOMFORT_TOL_KH).sum())


def _week_extreme(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float:
    col = full_weeks(run)[m["column"]].astype(float)
    return float(col.min() if m["which"] == "min" else col.max())


def _between(ev: Evidence, run: RunData, start: str, end: str) -> np.ndarray:
    t = _local(run, ev.tz)
    return ((t >= _local_time(start, ev.tz)) & (t < _local_time(end, ev.tz))).to_numpy()


def _max_between(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    mask = _between(ev, run, m["start"], m["end"])
    if not mask.any():
        return None
    return float(run.timeseries[m["column"]].to_numpy(dtype=float)[mask].max()) * float(m.get("scale", 1.0))


def _min_in_window(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float:
    a, b = ev.window(run, m["window"])
    return float(run.timeseries[m["column"]].iloc[a:b].min())


def _window_start(ev: Evidence, _: str, run: RunData, m: Mapping[str, Any]) -> float:
    # the state at the window's start is that at the end of the step before it
    a, _b = ev.window(run, m["window"])
    value = float(run.timeseries[m["column"]].iloc[a - 1]) if a > 0 else float(run.timeseries[m["column"]].iloc[0])
    return value * float(m.get("scale", 1.0))


def _in_week(run: RunData, m: Mapping[str, Any]) -> np.ndarray:
    return run.timeseries[m["column"]].to_numpy(dtype=float)[_week_mask(run, m["week"])]


def _min_in_week(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    v = _in_week(run, m)
    return float(v.min()) if v.size else None


def _max_in_week(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float | None:
    v = _in_week(run, m)
    return float(v.max()) if v.size else None


def _mean(_: Evidence, __: str, run: RunData, m: Mapping[str, Any]) -> float:
    return float(run.timeseries[m["column"]].mean())


def _h2_empty_days(ev: Evidence, ems: str, run: RunData, _: Mapping[str, Any]) -> float:
    floor = run.summary.get("rbc_loh_floor", h2_floor(ems, ev.params.hydrogen.loh_min))
    days = h2_empty_days_before_end(run, float(floor))
    return 0.0 if days is None else days


def _h2_empty_share(ev: Evidence, ems: str, run: RunData, m: Mapping[str, Any]) -> float:
    total_days = len(run.timeseries) / HOURS_PER_DAY
    return PERCENT * _h2_empty_days(ev, ems, run, m) / total_days


def _covered_weeks(_: Evidence, __: str, run: RunData, ___: Mapping[str, Any]) -> list[int]:
    return covered_weeks(run)


#: Measure name (``measure.of`` in ``paper_results.yaml``) -> function(evidence, EMS, run, spec).
MEASURES: dict[str, Measure] = {
    "summary": _summary,
    "minus_mpc": _minus_mpc,
    "minus": _minus,
    "pct_vs_mpc": _pct_vs_mpc,
    "week": _week,
    "mpc_ranked_week": _mpc_ranked_week,
    "ranked_week": _ranked_week,
    "weeks_without": _weeks_without,
    "week_extreme": _week_extreme,
    "max_between": _max_between,
    "min_in_window": _min_in_window,
    "window_start": _window_start,
    "min_in_week": _min_in_week,
    "max_in_week": _max_in_week,
    "mean": _mean,
    "h2_empty_days": _h2_empty_days,
    "h2_empty_share": _h2_empty_share,
    "covered_weeks": _covered_weeks,
}


# --------------------------------------------------------------------------- compared


@dataclass
class Figure:
    """One stated figure of the paper for one EMS, beside ours.

    Attributes
    ----------
    key : statement key
    ems : EMS name, or ``input``
    kind : ``value``, ``zero``, ``bound`` or ``weeks`` (kind of the paper's value)
    paper : the paper's value (number, ``{"below": x}`` or weeks)
    ours : our value (number or weeks), None when not measurable with these runs
    rel_error : relative error (``value`` figures), else None
    held : whether a zero, bound or set of weeks holds (else None)
    """

    key: str
    ems: str
    kind: str
    paper: Any
    ours: float | list[int] | None
    rel_error: float | None = None
    held: bool | None = None


def relative_error(ours: float, paper: float, on: str = "value") -> float:
    """``|ours - paper| / |paper|``; on ``ratio``, of ``1 + x / 100`` (x in percent) [-]."""
    if on == "ratio":
        ours, paper = 1.0 + ours / PERCENT, 1.0 + paper / PERCENT
    return abs(ours - paper) / abs(paper)


def compare(statement: Statement, ems: str, ours: float | list[int] | None, zero_tol: float) -> Figure:
    """One figure: the paper's value of ``ems`` against ``ours``."""
    paper = statement.paper[ems]
    kind = value_kind(paper)
    fig = Figure(statement.key, ems, kind, paper, ours)
    if ours is None or statement.locates:
        return fig
    if kind == WEEKS:
        fig.held = sorted(ours) == sorted(paper)  # type: ignore[arg-type]
    elif kind == BOUND:
        fig.held = float(ours) < float(paper["below"])  # type: ignore[arg-type]
    elif kind == ZERO:
        fig.held = abs(float(ours)) <= zero_tol  # type: ignore[arg-type]
    else:
        fig.rel_error = relative_error(float(ours), float(paper), statement.error_on)  # type: ignore[arg-type]
    return fig


def evaluate_statements(ev: Evidence, statements: Statements | None = None) -> list[Figure]:
    """Every statement measured on ``ev`` (one figure per EMS the paper gives a value for)."""
    statements = statements or load_paper_results()
    if ev.windows is None:
        ev.windows = statements.windows
    out = []
    for s in statements.statements:
        fn = MEASURES[s.measure["of"]]
        for ems in s.paper:
            source = next(iter(ev.runs)) if ems == INPUT else ems
            run = ev.run(source, s.eta)
            ours = None if run is None else fn(ev, source, run, s.measure)
            out.append(compare(s, ems, ours, statements.zero_tol))
    return out


@dataclass
class Aggregate:
    """One figure over several runs of a study (e.g. seeds): median and range.

    Attributes
    ----------
    key, ems, kind, paper : as :class:`Figure`
    ours : median of our values (numbers), or the most frequent set of weeks
    low, high : range of our values (numbers)
    rel_error : median over the runs of the relative error (``value`` figures)
    held : in how many runs a zero, bound or set of weeks held
    runs : how many runs measured it
    """

    key: str
    ems: str
    kind: str
    paper: Any
    ours: float | list[int] | None
    low: float | None
    high: float | None
    rel_error: float | None
    held: int | None
    runs: int


def aggregate(per_run: Sequence[Sequence[Figure]]) -> list[Aggregate]:
    """Figures of several runs (same statements, same order) as medians with ranges."""
    out = []
    for figs in zip(*per_run, strict=True):
        first = figs[0]
        measured = [f for f in figs if f.ours is not None]
        low = high = med = err = None
        held = None
        ours: float | list[int] | None = None
        if measured and first.kind == WEEKS:
            sets = [tuple(sorted(f.ours)) for f in measured]  # type: ignore[arg-type]
            ours = list(max(set(sets), key=lambda s: (sets.count(s), s)))
        elif measured:
            values = [float(f.ours) for f in measured]  # type: ignore[arg-type]
            med, low, high = statistics.median(values), min(values), max(values)
            ours = med
        if first.kind == VALUE:
            errs = [f.rel_error for f in measured if f.rel_error is not None]
            err = statistics.median(errs) if errs else None
        else:
            held = sum(bool(f.held) for f in measured)
        out.append(Aggregate(first.key, first.ems, first.kind, first.paper, ours, low, high, err, held,
                             len(measured)))
    return out


def printed(value: Any, unit: str = "") -> str:
    """A paper or measured value as the report prints it."""
    if value is None:
        return "not run"
    if isinstance(value, list | tuple):
        return "none" if not value else ", ".join(str(int(w)) for w in value)
    if isinstance(value, dict):
        return f"below {value['below']:g}"
    digits = 0 if unit in ("weeks", "d") else 2
    return fmt(float(value), digits)
