"""Mamdani fuzzy inference in vectorised numpy, built from rule-base data files.

The paper's controllers (``sec:appendix``) are Mamdani systems: rule strength = min over
the antecedents (AND), aggregation = max over the rules of a consequent term, output
fuzzy set = max over the terms clipped at their strengths, crisp output = centroid
(centre of gravity). This module evaluates such a system for a batch of inputs with a
handful of numpy array operations (no Python loop over rules), so one step of all three
ComEMS4Build controllers costs some tens of microseconds instead of the ~11 ms per call of
``skfuzzy.control``. :meth:`FuzzySystem.to_skfuzzy` builds the equivalent
``skfuzzy.control`` system from the same data; the tests and ``comems4build bench ems``
compare the two.

Data file format (one file per controller, ROS 2 parameter-file form, section named by
the controller, e.g. ``flc_fc``)::

    inputs:
      order: [dp, dloh, soc, price, s_onoff]      # input order of evaluate()
      dp:
        universe: [-1.0, 0.0]                     # [lo, hi] of the variable
        terms:                                    # 3 points: triangle, 4: trapezoid
          sn: ["-dp_fc", "0.0", "0.0"]            # numbers or device quantities
    output:
      name: alpha_fc
      universe: [0.0, 1.0]
      points: 201                                 # centroid grid
      terms: {off: [0.0, 0.0, 0.5], ...}
    rules_paper: ["dp=sn, dloh=empty, soc=full, price=high, s_onoff=off -> off", ...]
    rules_design: [...]

Term points may name a device quantity (see :func:`device_quantities`) with an optional
sign and factor (``"-0.5*p_d"``), so membership peaks follow the configured devices. A
rule is ``var=term[, var=term|term ...] -> out_term``; a variable left out matches any
value (its antecedent is omitted, as in ``skfuzzy.control``); ``a|b`` is OR (max).
A shoulder (``a == b`` or ``c == d``) is allowed only at the universe's edge.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from comems4build_ros.core.config import ConfigError, PlantParams, check_known_keys
from comems4build_ros.core.numerics import rowdot

#: Rule base sections in a file: the paper's snapshot rules and ours.
RULE_SECTIONS = ("rules_paper", "rules_design")
#: Keys of an input variable; the output variable has ``name`` and ``points`` besides.
VARIABLE_KEYS = ("universe", "terms")

_RULE_RE = re.compile(r"^\s*(?P<ante>.*?)\s*->\s*(?P<cons>[A-Za-z_][A-Za-z0-9_]*)\s*$")
_POINT_RE = re.compile(
    r"^\s*(?P<sign>[+-]?)\s*(?:(?P<factor>\d+(?:\.\d*)?|\.\d+)\s*\*\s*)?(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*$"
)


#: Plant parameters each device quantity of :func:`device_quantities` is computed from.
QUANTITY_PARAMS: dict[str, tuple[str, ...]] = {
    "soc_min": ("battery.soc_min",),
    "soc_mid": ("battery.soc_min", "battery.soc_max"),
    "soc_max": ("battery.soc_max",),
    "loh_min": ("hydrogen.loh_min",),
    "loh_mid": ("hydrogen.loh_min", "hydrogen.loh_max"),
    "loh_max": ("hydrogen.loh_max",),
    "dp_fc": ("fuel_cell.zeta", "fuel_cell.p_max_w"),
    "dp_fc_bess": ("fuel_cell.zeta", "fuel_cell.p_max_w", "battery.p_d_max_w"),
    "p_ch": ("battery.p_ch_max_w",),
    "p_d": ("battery.p_d_max_w",),
    "dp_el_min": ("electrolyser.n_modules", "electrolyser.p_el_points_w"),
    "dp_el_max": ("electrolyser.n_modules", "electrolyser.p_el_points_w"),
    "alpha_el_min": ("electrolyser.n_modules", "electrolyser.p_el_points_w"),
}


class QuantityError(ConfigError):
    """A membership function that is invalid because of the plant parameters its points come from.

    Parameters
    ----------
    message : str
        What is wrong with the membership function.
    plant_params : tuple[str, ...]
        The dotted plant parameters behind the device quantities of its points.
    """

    def __init__(self, message: str, plant_params: tuple[str, ...]) -> None:
        super().__init__(message)
        self.plant_params = plant_params


def device_quantities(params: PlantParams, load_scale_w: float | None) -> dict[str, float]:
    """Compute the named device quantities that membership points may refer to.

    Parameters
    ----------
    params : PlantParams
        Plant parameters (battery, fuel cell, H2 store, electrolyser).
    load_scale_w : float or None
        Power the loads are normalised on [W] (the paper's 10 kW scale, ``sec:appendix``);
        None: a controller without a power input (FLC_flex), whose points name no load.

    Returns
    -------
    dict[str, float]
        Name -> value [-]:

        - ``soc_min``, ``soc_mid``, ``soc_max``: battery SOC bounds and their mean;
        - ``loh_min``, ``loh_mid``, ``loh_max``: H2 store bounds and their mean;
        - ``dp_fc``: load the FC alone covers, zeta * P_FC,max / scale (peak of dP
          "medium negative");
        - ``dp_fc_bess``: load FC and BESS cover together, (zeta * P_FC,max + P_d,max) /
          scale (peak of dP "big negative");
        - ``p_ch``, ``p_d``: full battery charging / discharging power / scale (peaks of
          dP_new "big positive" / "big negative"; half of them: "medium");
        - ``alpha_fc_min``: the FC's minimum power as a share of zeta * P_FC,max: below it
          ``P_el,FC = alpha_FC * zeta * P_FC,max`` is under P_FC,min and the FC is off (end
          of the alpha_FC "off" term);
        - ``dp_el_min``, ``dp_el_max``: the electrolyser's minimal and maximal intake /
          scale (compression included; 0 without an electrolyser);
        - ``alpha_el_min``: P_EL,min / P_EL,max (0 without an electrolyser).

        The loads (``dp_*``, ``p_ch``, ``p_d``) only with a ``load_scale_w``.

    Raises
    ------
    ConfigError
        For a ``load_scale_w`` that is not positive.
    """
    if load_scale_w is not None and load_scale_w <= 0:
        raise ConfigError(f"load_scale_w must be positive, got {load_scale_w}")
    from comems4build_ros.core.models.electrolyser import ElectrolyserTable

    b, fc, h2 = params.battery, params.fuel_cell, params.hydrogen
    p_fc = fc.zeta * fc.p_max_w
    el = ElectrolyserTable(params.electrolyser)
    out = {
        "soc_min": b.soc_min,
        "soc_mid": 0.5 * (b.soc_min + b.soc_max),
        "soc_max": b.soc_max,
        "loh_min": h2.loh_min,
        "loh_mid": 0.5 * (h2.loh_min + h2.loh_max),
        "loh_max": h2.loh_max,
        "alpha_fc_min": fc.p_min_w / p_fc,
        "alpha_el_min": el.p_min_w / el.p_max_w if el.n else 0.0,
    }
    if load_scale_w is not None:
        out.update({
            "dp_fc": p_fc / load_scale_w,
            "dp_fc_bess": (p_fc + b.p_d_max_w) / load_scale_w,
            "p_ch": b.p_ch_max_w / load_scale_w,
            "p_d": b.p_d_max_w / load_scale_w,
            "dp_el_min": el.p_min_w / load_scale_w,
            "dp_el_max": el.p_max_w / load_scale_w,
        })
    return out


@dataclass(frozen=True)
class Variable:
    """A linguistic variable: universe and trapezoidal terms ``(a, b, c, d)``.

    Attributes
    ----------
    name : str
        Variable name (``chi``, ``dp``, ``soc``, ...).
    lo, hi : float
        Universe [unit of the variable; loads in units of ``load_scale_w``].
    term_names : tuple[str, ...]
        Term names (``low``, ``average``, ...).
    points : numpy.ndarray
        Corner points of each term, shape (n_terms, 4); a triangle has b == c.
    """

    name: str
    lo: float
    hi: float
    term_names: tuple[str, ...]
    points: np.ndarray  # (n_terms, 4)

    def membership(self, x: np.ndarray) -> np.ndarray:
        """Compute the membership of every term at ``x``.

        Parameters
        ----------
        x : numpy.ndarray
            Values [unit of the variable], clipped to the universe.

        Returns
        -------
        numpy.ndarray
            Memberships [-] in [0, 1], shape ``x.shape + (n_terms,)``.
        """
        xx = np.clip(np.asarray(x, dtype=float), self.lo, self.hi)[..., None]
        return _trap(xx, self.points)


@dataclass(frozen=True)
class Rule:
    """One rule: per input a tuple of term indices (OR) or ``None`` (any), one output term.

    Attributes
    ----------
    antecedent : tuple
        Per input the indices of its terms (OR), or None (any value).
    consequent : int
        Index of the output term.
    source : str
        ``paper`` (``tab:FLC*_rules``) or ``design`` (ours).
    text : str
        The rule as written in the file.
    """

    antecedent: tuple[tuple[int, ...] | None, ...]
    consequent: int
    source: str  # "paper" or "design"
    text: str


def _trap(x: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Trapezoid memberships; shoulders (a == b, c == d) are flat to the universe edge."""
    a, b, c, d = pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        left = np.where(b > a, (x - a) / np.where(b > a, b - a, 1.0), 1.0)
        right = np.where(d > c, (d - x) / np.where(d > c, d - c, 1.0), 1.0)
    return np.clip(np.minimum(left, right), 0.0, 1.0)


def _slopes(pts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Linear pieces ``left = x * sl + ol``, ``right = x * sr + or`` of trapezoids."""
    a, b, c, d = pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3]
    flat_l = b <= a
    flat_r = d <= c
    sl = np.where(flat_l, 0.0, 1.0 / np.where(flat_l, 1.0, b - a))
    ol = np.where(flat_l, 1.0, -a * sl)
    sr = np.where(flat_r, 0.0, -1.0 / np.where(flat_r, 1.0, d - c))
    orr = np.where(flat_r, 1.0, d / np.where(flat_r, 1.0, d - c))
    return sl, ol, sr, orr


class FuzzySystem:
    """A Mamdani controller (min AND, max aggregation, centroid) evaluated with numpy.

    Parameters
    ----------
    name : str
        Controller name (e.g. ``flc_fc``).
    inputs : Sequence[Variable]
        Input variables in evaluation order.
    output : Variable
        Output variable.
    rules : Sequence[Rule]
        The rule base.
    n_points : int
        Points of the output grid used for the centroid (at least 3).
    source : str
        File the system came from (for messages).

    Raises
    ------
    ConfigError
        For fewer than 3 output points or an empty rule base.
    """

    def __init__(
        self,
        name: str,
        inputs: Sequence[Variable],
        output: Variable,
        rules: Sequence[Rule],
        n_points: int,
        source: str = "",
    ) -> None:
        if n_points < 3:
            raise ConfigError(f"{source}: {name}: output.points must be at least 3")
        if not rules:
            raise ConfigError(f"{source}: {name}: empty rule base")
        self.name = name
        #: Power the load inputs are divided by [W] (set by :func:`flc_system`; 0: not set).
        self.load_scale_w = 0.0
        self.n_points = n_points
        self.inputs = tuple(inputs)
        self.output = output
        self.rules = tuple(rules)
        self.source = source
        self.input_names = tuple(v.name for v in self.inputs)
        self._lo = np.array([v.lo for v in self.inputs])
        self._hi = np.array([v.hi for v in self.inputs])
        # All input terms side by side: term j belongs to input _term_input[j].
        self._term_input = np.concatenate([np.full(len(v.term_names), i) for i, v in enumerate(self.inputs)])
        pts = np.concatenate([v.points for v in self.inputs])
        self._sl, self._ol, self._sr, self._or = _slopes(pts)
        offsets = np.cumsum([0] + [len(v.term_names) for v in self.inputs])
        n_terms = int(offsets[-1])
        # Distinct antecedent sets (OR over terms, or "any"): membership = max over the set.
        sets: dict[tuple[int, ...], int] = {}
        rule_idx = np.empty((len(self.rules), len(self.inputs)), dtype=np.intp)
        for r, rule in enumerate(self.rules):
            for i, ante in enumerate(rule.antecedent):
                key = (n_terms,) if ante is None else tuple(int(offsets[i]) + t for t in ante)
                rule_idx[r, i] = sets.setdefault(key, len(sets))
        self._sets = np.zeros((len(sets), n_terms + 1))
        for key, s in sets.items():
            self._sets[s, list(key)] = 1.0
        self._single = all(len(key) == 1 for key in sets)
        self._set_first = np.array([key[0] for key in sorted(sets, key=sets.get)], dtype=np.intp)
        self._rule_idx = rule_idx
        n_out = len(output.term_names)
        self._cons = np.zeros((n_out, len(self.rules)))
        self._cons[[r.consequent for r in self.rules], np.arange(len(self.rules))] = 1.0
        # Output grid (n_points plus every term vertex, as in to_skfuzzy) and exact
        # integrals of the piecewise-linear output set on it: area = w . y, moment = m . y.
        self.grid = np.union1d(np.linspace(output.lo, output.hi, n_points), output.points.ravel())
        self._out_mf = _trap(self.grid[None, :].T, output.points).T  # (n_out, n_grid)
        h = np.diff(self.grid)
        x0 = self.grid[:-1]
        w = np.zeros(len(self.grid))
        w[:-1] += 0.5 * h
        w[1:] += 0.5 * h
        m = np.zeros(len(self.grid))
        m[:-1] += h * x0 / 2.0 + h * h / 6.0
        m[1:] += h * x0 / 2.0 + h * h / 3.0
        self._w_area = w
        self._w_moment = m

    # ------------------------------------------------------------------ inference
    def input_memberships(self, x: np.ndarray) -> np.ndarray:
        """Compute the memberships of all input terms.

        Parameters
        ----------
        x : numpy.ndarray
            Inputs, shape (batch, n_inputs), clipped to the universes.

        Returns
        -------
        numpy.ndarray
            Memberships [-], shape (batch, n_terms + 1); the last column is 1 ("any").
        """
        x = np.clip(x, self._lo, self._hi)
        xt = x[:, self._term_input]
        mu = np.minimum(xt * self._sl + self._ol, xt * self._sr + self._or)
        np.clip(mu, 0.0, 1.0, out=mu)
        return np.concatenate([mu, np.ones((x.shape[0], 1))], axis=1)

    def firing(self, x: np.ndarray) -> np.ndarray:
        """Compute the rule strengths (min over the antecedents, max over a rule's OR terms).

        Parameters
        ----------
        x : numpy.ndarray
            Inputs, shape (batch, n_inputs) or (n_inputs,).

        Returns
        -------
        numpy.ndarray
            Strengths [-], shape (batch, n_rules).

        Raises
        ------
        ValueError
            If ``x`` has another number of inputs.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if x.shape[1] != len(self.inputs):
            raise ValueError(f"{self.name}: expected {len(self.inputs)} inputs {self.input_names}, got {x.shape[1]}")
        mu = self.input_memberships(x)
        if self._single:
            mu_sets = mu[:, self._set_first]
        else:
            mu_sets = (mu[:, None, :] * self._sets[None, :, :]).max(axis=2)
        return mu_sets[:, self._rule_idx].min(axis=2)

    def activation(self, x: np.ndarray) -> np.ndarray:
        """Compute the strength of every output term: the max of :meth:`firing` over its rules.

        Returns
        -------
        numpy.ndarray
            Strengths [-] of the inputs ``x`` (as for :meth:`firing`), shape (batch, n_out_terms).
        """
        fire = self.firing(x)
        return (fire[:, None, :] * self._cons[None, :, :]).max(axis=2)

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """Compute the crisp outputs (centroid) for a batch of inputs.

        Parameters
        ----------
        x : numpy.ndarray
            Inputs, shape (batch, n_inputs) or (n_inputs,), in the order of ``input_names``;
            values outside a universe are clipped to it.

        Returns
        -------
        numpy.ndarray
            Crisp outputs [unit of the output variable], shape (batch,).

        Raises
        ------
        ValueError
            If no rule fires for some input (an incomplete rule base).
        """
        act = self.activation(x)
        agg = np.minimum(act[:, :, None], self._out_mf[None, :, :]).max(axis=1)
        area = rowdot(agg, self._w_area)
        if np.any(area <= 0.0):
            bad = np.atleast_2d(np.asarray(x, dtype=float))[np.argmax(area <= 0.0)]
            raise ValueError(f"{self.name}: no rule fires for inputs {dict(zip(self.input_names, bad.tolist()))}")
        return rowdot(agg, self._w_moment) / area

    def __call__(self, *values: float) -> float:
        """Compute the crisp output for one input vector given as positional values."""
        return float(self.evaluate(np.array([values], dtype=float))[0])

    # ------------------------------------------------------------------ helpers
    def variable(self, name: str) -> Variable:
        """Find an input or output variable by name.

        Parameters
        ----------
        name : str
            Variable name.

        Returns
        -------
        Variable
            The variable.

        Raises
        ------
        KeyError
            If the system has no such variable.
        """
        for v in (*self.inputs, self.output):
            if v.name == name:
                return v
        raise KeyError(f"{self.name} has no variable '{name}'")

    def peak(self, var: str, term: str) -> float:
        """Return the middle of the core of a term (its peak for a triangle).

        Parameters
        ----------
        var, term : str
            Variable and term names.

        Returns
        -------
        float
            The point [unit of the variable]; a shoulder's universe edge.
        """
        v = self.variable(var)
        a, b, c, d = v.points[v.term_names.index(term)]
        if b == v.lo and a == b:
            return float(v.lo)
        if c == v.hi and c == d:
            return float(v.hi)
        return float(0.5 * (b + c))

    def term_centroid(self, term: str) -> float:
        """Return the centroid of one output term alone (the crisp output when only it fires fully).

        Parameters
        ----------
        term : str
            Output term name.

        Returns
        -------
        float
            The centroid [unit of the output variable].
        """
        mf = self._out_mf[self.output.term_names.index(term)]
        return float(rowdot(mf, self._w_moment) / rowdot(mf, self._w_area))

    def to_skfuzzy(self, n_grid: int = 201) -> Any:
        """Build the same controller as a ``skfuzzy.control.ControlSystem`` (for tests and benchmarks).

        Universes are ``n_grid`` points plus every term vertex, so that skfuzzy's
        linear interpolation of the membership functions is exact.

        Parameters
        ----------
        n_grid : int
            Grid points of each input universe.

        Returns
        -------
        skfuzzy.control.ControlSystem
            The controller.
        """
        from skfuzzy import control as ctrl
        from skfuzzy import membership as mf

        def universe(v: Variable, n: int) -> np.ndarray:
            pts = np.clip(v.points.ravel(), v.lo, v.hi)
            return np.union1d(np.linspace(v.lo, v.hi, n), pts)

        def add_terms(var: Any, v: Variable) -> None:
            for name, (a, b, c, d) in zip(v.term_names, v.points):
                var[name] = mf.trapmf(var.universe, [a, b, c, d])

        ants = []
        for v in self.inputs:
            ant = ctrl.Antecedent(universe(v, n_grid), v.name)
            add_terms(ant, v)
            ants.append(ant)
        out = ctrl.Consequent(universe(self.output, self.n_points), self.output.name, defuzzify_method="centroid")
        add_terms(out, self.output)
        sk_rules = []
        for rule in self.rules:
            expr = None
            for ant, v, sel in zip(ants, self.inputs, rule.antecedent):
                if sel is None:
                    continue
                term = ant[v.term_names[sel[0]]]
                for t in sel[1:]:
                    term = term | ant[v.term_names[t]]
                expr = term if expr is None else expr & term
            sk_rules.append(ctrl.Rule(expr, out[self.output.term_names[rule.consequent]]))
        return ctrl.ControlSystem(sk_rules)


# ---------------------------------------------------------------------- loading
def _point(value: Any, quantities: Mapping[str, float], where: str) -> float:
    if isinstance(value, bool):
        raise ConfigError(f"{where}: expected a number or a device quantity, got {value!r}")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
        m = _POINT_RE.match(value)
        if m and m["name"] in quantities:
            factor = float(m["factor"]) if m["factor"] else 1.0
            sign = -1.0 if m["sign"] == "-" else 1.0
            return sign * factor * quantities[m["name"]]
        raise ConfigError(
            f"{where}: cannot read point {value!r} (a number or [-][factor*]quantity with quantity one of "
            f"{', '.join(sorted(quantities))})"
        )
    raise ConfigError(f"{where}: expected a number or a device quantity, got {value!r}")


def _variable(name: str, spec: Any, quantities: Mapping[str, float], where: str,
              keys: tuple[str, ...] = VARIABLE_KEYS) -> Variable:
    if not isinstance(spec, Mapping):
        raise ConfigError(f"{where}: variable '{name}' must be a mapping with universe and terms")
    check_known_keys(spec, keys, f"{where}: variable '{name}'")
    try:
        lo, hi = (float(v) for v in spec["universe"])
    except (KeyError, TypeError, ValueError):
        raise ConfigError(f"{where}: variable '{name}': 'universe' must be [lo, hi]") from None
    if not lo < hi:
        raise ConfigError(f"{where}: variable '{name}': universe needs lo < hi, got [{lo}, {hi}]")
    terms = spec.get("terms")
    if not isinstance(terms, Mapping) or not terms:
        raise ConfigError(f"{where}: variable '{name}': 'terms' must be a non-empty mapping")
    names, rows = [], []
    for term, raw in terms.items():
        tw = f"{where}: term '{name}.{term}'"
        if not isinstance(raw, Sequence) or isinstance(raw, str) or len(raw) not in (3, 4):
            raise ConfigError(f"{tw}: expected 3 (triangle) or 4 (trapezoid) points")
        pts = [_point(p, quantities, tw) for p in raw]
        if len(pts) == 3:
            pts = [pts[0], pts[1], pts[1], pts[2]]
        problem = ""
        if any(q < p for p, q in zip(pts, pts[1:])):
            problem = f"points must not decrease, got {[round(p, 6) for p in pts]}"
        elif pts[0] < lo - 1e-12 or pts[3] > hi + 1e-12:
            problem = f"points {[round(p, 6) for p in pts]} leave the universe [{lo}, {hi}]"
        elif pts[0] == pts[1] and pts[0] != lo:
            problem = "a left shoulder (a == b) is allowed only at the universe's lower end"
        elif pts[2] == pts[3] and pts[3] != hi:
            problem = "a right shoulder (c == d) is allowed only at the universe's upper end"
        if problem:
            used = [q for p in raw if isinstance(p, str) for q in QUANTITY_PARAMS if re.search(rf"\b{q}\b", p)]
            if used:
                plant = tuple(dict.fromkeys(x for q in used for x in QUANTITY_PARAMS[q]))
                raise QuantityError(f"{tw}: {problem} (points from {', '.join(used)})", plant)
            raise ConfigError(f"{tw}: {problem}")
        names.append(str(term))
        rows.append(pts)
    return Variable(name, lo, hi, tuple(names), np.array(rows, dtype=float))


def _rule(text: Any, inputs: Sequence[Variable], output: Variable, source: str, where: str) -> Rule:
    if not isinstance(text, str):
        raise ConfigError(f"{where}: a rule must be a string 'var=term, ... -> term', got {text!r}")
    m = _RULE_RE.match(text)
    if not m:
        raise ConfigError(f"{where}: cannot read rule {text!r} (expected 'var=term, ... -> term')")
    by_name = {v.name: i for i, v in enumerate(inputs)}
    ante: list[tuple[int, ...] | None] = [None] * len(inputs)
    for part in filter(None, (p.strip() for p in m["ante"].split(","))):
        if "=" not in part:
            raise ConfigError(f"{where}: rule {text!r}: '{part}' is not 'var=term'")
        var, terms = (s.strip() for s in part.split("=", 1))
        if var not in by_name:
            raise ConfigError(f"{where}: rule {text!r}: unknown input '{var}' (inputs: {', '.join(by_name)})")
        i = by_name[var]
        if ante[i] is not None:
            raise ConfigError(f"{where}: rule {text!r}: input '{var}' given twice")
        idx = []
        for t in (s.strip() for s in terms.split("|")):
            if t not in inputs[i].term_names:
                raise ConfigError(
                    f"{where}: rule {text!r}: '{var}' has no term '{t}' (terms: {', '.join(inputs[i].term_names)})"
                )
            idx.append(inputs[i].term_names.index(t))
        ante[i] = tuple(sorted(set(idx)))
    if all(a is None for a in ante):
        raise ConfigError(f"{where}: rule {text!r} has no antecedent")
    cons = m["cons"]
    if cons not in output.term_names:
        raise ConfigError(
            f"{where}: rule {text!r}: output '{output.name}' has no term '{cons}' "
            f"(terms: {', '.join(output.term_names)})"
        )
    return Rule(tuple(ante), output.term_names.index(cons), source, text.strip())


def build_system(name: str, spec: Mapping[str, Any], quantities: Mapping[str, float], source: str) -> FuzzySystem:
    """Build a :class:`FuzzySystem` from one controller section of a data file.

    Parameters
    ----------
    name : str
        Section name (``flc_fc``).
    spec : Mapping[str, Any]
        The section: ``inputs`` (``order`` and one variable per input), ``output`` and
        the rule lists ``rules_paper`` / ``rules_design``.
    quantities : Mapping[str, float]
        Device quantities the term points may name (:func:`device_quantities`).
    source : str
        The file (for messages).

    Returns
    -------
    FuzzySystem
        The controller, its rule base complete and consistent (:func:`check_consistency`).

    Raises
    ------
    ConfigError
        Naming the file, the variable, term or rule at fault; also if two rules with the
        same antecedent terms name different outputs (checked term by term over every
        combination of input terms).
    """
    where = f"{source}: {name}"
    inputs_spec = spec.get("inputs")
    if not isinstance(inputs_spec, Mapping) or "order" not in inputs_spec:
        raise ConfigError(f"{where}: 'inputs' must be a mapping with 'order' and one entry per input")
    order = list(inputs_spec["order"])
    inputs = []
    for var in order:
        if var not in inputs_spec:
            raise ConfigError(f"{where}: input '{var}' listed in inputs.order has no definition")
        inputs.append(_variable(var, inputs_spec[var], quantities, f"{where}.inputs"))
    extra = set(inputs_spec) - set(order) - {"order"}
    if extra:
        raise ConfigError(f"{where}: inputs {', '.join(sorted(extra))} are defined but not in inputs.order")
    out_spec = spec.get("output")
    if not isinstance(out_spec, Mapping) or "name" not in out_spec:
        raise ConfigError(f"{where}: 'output' must be a mapping with name, universe, points and terms")
    output = _variable(str(out_spec["name"]), out_spec, quantities, f"{where}.output",
                       ("name", "points", *VARIABLE_KEYS))
    rules: list[Rule] = []
    for section in RULE_SECTIONS:
        texts = spec.get(section, [])
        if not isinstance(texts, Sequence) or isinstance(texts, str):
            raise ConfigError(f"{where}: '{section}' must be a list of rule strings")
        for j, text in enumerate(texts):
            rules.append(_rule(text, inputs, output, section.removeprefix("rules_"), f"{where}.{section}[{j}]"))
    system = FuzzySystem(name, inputs, output, rules, int(out_spec.get("points", 201)), source)
    check_consistency(system)
    return system


def check_consistency(system: FuzzySystem) -> None:
    """Check that every combination of input terms is covered by a rule, and by agreeing ones.

    All rules covering the same combination must name the same output term.

    Parameters
    ----------
    system : FuzzySystem
        The controller to check.

    Raises
    ------
    ConfigError
        Naming the uncovered combination or the conflicting rules.
    """
    sizes = [len(v.term_names) for v in system.inputs]
    grids = np.stack(np.meshgrid(*[np.arange(n) for n in sizes], indexing="ij"), axis=-1).reshape(-1, len(sizes))
    cover = np.ones((len(grids), len(system.rules)), dtype=bool)
    for r, rule in enumerate(system.rules):
        for i, ante in enumerate(rule.antecedent):
            if ante is not None:
                cover[:, r] &= np.isin(grids[:, i], ante)
    where = f"{system.source}: {system.name}"
    for g, combo in enumerate(grids):
        hit = np.flatnonzero(cover[g])
        names = ", ".join(f"{v.name}={v.term_names[t]}" for v, t in zip(system.inputs, combo))
        if hit.size == 0:
            raise ConfigError(f"{where}: incomplete rule base: no rule covers {names}")
        outs = {system.rules[r].consequent for r in hit}
        if len(outs) > 1:
            texts = "; ".join(f"'{system.rules[r].text}'" for r in hit)
            raise ConfigError(f"{where}: conflicting rules for {names}: {texts}")


def flc_system(name: str, spec: Mapping[str, Any], params: PlantParams, source: str) -> FuzzySystem:
    """Build the fuzzy controller of one rule-file section for the plant ``params``.

    Parameters
    ----------
    name : str
        Section name (``flc_flex``, ``flc_fc``, ``flc_b``, ``flc_el``).
    spec : Mapping[str, Any]
        The section as checked by :class:`~comems4build_ros.core.ems.settings.FLCSection`:
        ``inputs``, ``output``, the rule lists and, for a controller with a power input,
        ``load_scale_w`` [W].
    params : PlantParams
        Plant parameters: the device quantities the membership functions name
        (:func:`device_quantities`).
    source : str
        The rule file (for messages).

    Returns
    -------
    FuzzySystem
        The controller; its ``load_scale_w`` [W] is the section's (0 without a power input).

    Raises
    ------
    ConfigError
        Naming the file and the variable, term or rule at fault, or the plant parameters
        that make a membership function degenerate.
    """
    scale = spec.get("load_scale_w")  # FLC_flex has no power input
    try:
        system = build_system(name, spec, device_quantities(params, scale), source)
    except QuantityError as exc:
        values = {p: _param_value(params, p) for p in exc.plant_params}
        zero = [p for p, v in values.items() if v == 0.0]
        blamed = zero or list(values)
        text = ", ".join(f"{p} = {_shown(values[p])}" for p in blamed)
        others = ", ".join(f"{p} = {_shown(v)}" for p, v in values.items() if p not in blamed)
        raise ConfigError(
            f"plant parameter{'s' if len(blamed) > 1 else ''} {text}: the fuzzy EMS cannot work with "
            f"{'this value' if len(blamed) == 1 else 'these values'}: it makes a membership function degenerate "
            f"({exc}{'; also from ' + others if others else ''})"
        ) from None
    system.load_scale_w = float(scale or 0.0)
    return system


def _param_value(params: PlantParams, dotted: str) -> float | list[float]:
    """Return the plant parameter ``section.key``: a number, or a table (the electrolyser's power points)."""
    section, key = dotted.split(".")
    value = getattr(getattr(params, section), key)
    return [float(v) for v in value] if isinstance(value, list | tuple) else float(value)


def _shown(value: float | list[float]) -> str:
    """Format a parameter's value for a message: ``2.5`` or ``[1, 2]``."""
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"
