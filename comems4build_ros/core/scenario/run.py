"""The scenario of a run as a distributed run uses it: loaded, cut to its window, checked.

The feed node builds its run's scenario here, and so do the commands that must check a
scenario before they start any node (``comems4build launch``), the simulated house
behind MQTT (``mqtt_plant``) and the ROS benchmark, so that all of them get exactly the
scenario the feed publishes. On top of :func:`comems4build_ros.core.scenario.resolve_scenario`
(the core loaders with their file checks): a cut to the first ``steps`` steps, and a
refusal of values the loader filled by interpolation (unless ``allow_gap_fill``), of
non-finite values and of irregular time steps.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from comems4build_ros.core.config import SECONDS_PER_HOUR
from comems4build_ros.core.scenario.base import SERIES, Scenario
from comems4build_ros.files.errors import InputError

#: Text of the core loader's warning about interpolated missing values.
GAP_FILL_MARK = "filled by linear interpolation"
#: Tolerance on the hourly spacing check of the scenario time index [s].
TIME_STEP_TOL_S = 1e-6


class ScenarioInputError(InputError):
    """The scenario has a gap, an irregular step or a non-finite value."""


def check_scenario(scenario: Scenario, time_step_h: float) -> None:
    """Refuse a scenario with non-finite values or irregular time steps.

    Parameters
    ----------
    scenario : Scenario
        The scenario to check.
    time_step_h : float
        The plant's step; the index must advance by exactly it [h].

    Raises
    ------
    ScenarioInputError
        Naming the scenario, the series and the first offending time.
    """
    for name in SERIES:
        values = np.asarray(getattr(scenario, name), dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            i = int(bad[0])
            raise ScenarioInputError(
                f"scenario '{scenario.name}': series '{name}' has {bad.size} non-finite value(s), "
                f"first at {scenario.time[i].isoformat()} (row {i}): {values[i]}"
            )
    if len(scenario.time) > 1:
        dt = np.asarray((scenario.time[1:] - scenario.time[:-1]).total_seconds(), dtype=float)
        want = time_step_h * SECONDS_PER_HOUR
        bad = np.flatnonzero(np.abs(dt - want) > TIME_STEP_TOL_S)
        if bad.size:
            i = int(bad[0])
            raise ScenarioInputError(
                f"scenario '{scenario.name}': time step {dt[i]:.0f} s instead of {want:.0f} s between "
                f"{scenario.time[i].isoformat()} and {scenario.time[i + 1].isoformat()} (gap or irregular index)"
            )


def load_scenario(
    spec: str,
    params: Any,
    start: str | None,
    weeks: int | None,
    seed: int | None,
    steps: int | None = None,
    allow_gap_fill: bool = False,
    notes: list[str] | None = None,
) -> Scenario:
    """Load the run's scenario through the core's loaders (their file checks included).

    Parameters
    ----------
    spec : str
        ``default``, another embedded scenario's name, or a scenario CSV path.
    params : PlantParams
        Plant parameters.
    start : str or None
        First day of the run (see :func:`comems4build_ros.core.scenario.resolve_scenario`).
    weeks : int or None
        Length of the run [weeks].
    seed : int or None
        Generator seed of the default scenario (None = the configured seed).
    steps : int, optional
        Cut the run to its first ``steps`` steps (the rest stays as look-ahead); None = the
        whole window.
    allow_gap_fill : bool, optional
        Accept missing values the loader filled by interpolation (its ``ScenarioWarning``);
        by default they make the feed refuse the scenario.
    notes : list of str, optional
        Receives the text of every other loader warning.

    Returns
    -------
    Scenario
        The run's scenario.

    Raises
    ------
    ScenarioInputError
        For filled missing values unless ``allow_gap_fill``.
    ScenarioError, ValueError
        From the loaders (file, line and column named) or for an invalid window.
    """
    from comems4build_ros.core.scenario import ScenarioWarning, resolve_scenario

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ScenarioWarning)
        out = resolve_scenario(spec, params, start=start, weeks=weeks, **({} if seed is None else {"seed": seed}))
    for w in caught:
        text = str(w.message)
        if issubclass(w.category, ScenarioWarning) and GAP_FILL_MARK in text and not allow_gap_fill:
            raise ScenarioInputError(
                f"{text}: the feed refuses a scenario with missing values "
                "(parameter allow_gap_fill:=true accepts the core loader's documented interpolation)"
            )
        if notes is not None:
            notes.append(text)
    if steps is not None:
        if not 0 < steps <= out.n_steps:
            raise ScenarioInputError(f"parameter 'steps': {steps} outside 1..{out.n_steps} of scenario '{out.name}'")
        out = dataclasses.replace(out, n_steps=steps)
    return out


