"""``feed``: publishes the scenario's exogenous signals, step by step, ahead of the plant.

For each step ``k`` the feed publishes (topics of ``msg_defs/topics.yaml``, element 0 =
``k``):

* ``feed/truth``: the inputs the plant applies in step ``k`` (``Exogenous`` of sim.py
  plus run length, start time and spot price); read by ``plant_sim`` only;
* what an EMS may read, split by ``tab:level_of_information``: ``feed/calendar``,
  ``feed/measured``, ``feed/comfort``, ``feed/prices`` (every EMS);
  ``feed/comfort_ahead``, ``feed/solar``, ``feed/h2_allowance`` (fuzzy and MPC);
  ``feed/t_amb`` and ``forecast/*`` (MPC only);
* for a house of a community (``community_file`` and ``community_house``, docs/community.md
  "Over ROS"): the house's scenario (its appliance load and hot-water draws of the community
  file on the run's scenario) and its parameters (the run's plant with its variation and its
  share of the hub's store), built by the core's community code; ``feed/h2_allowance`` is then
  the coordinator's (what it allots the house), not the feed's;
* once at start-up ``feed/info`` (transient local): scenario name, start, steps, forecast
  mode, seed, the run's id (parameter ``run_id``) and the EMS node served (``for_ems``, None:
  every EMS) as JSON, so that a bag recorded without the launcher knows its scenario and which
  inputs were published, and a bag holding another run's records is told apart.

The values are those of :class:`comems4build_ros.core.loop.ObservationBuilder` (MPC level,
which contains every other level), so an EMS node rebuilds exactly the observation of
the in-process loop. With ``for_ems`` (the contract name of the EMS node of the run, e.g.
``fuzzy_ems``; the launcher sets it) the feed publishes only the EMS topics that node
reads, built at its level (``fuzzy_ems``: no ``feed/t_amb``, no ``forecast/*``).

Pacing: the feed publishes when ``plant/step`` announces the step the plant waits for,
up to ``lookahead_steps`` steps ahead; a repeated announcement (the plant re-announces
while it waits, e.g. for a restarted EMS) makes it publish the steps
``k .. k + lookahead_steps`` again. The feed is never on the critical path of a step.
It exits with code 0 on ``plant/done`` (end of the run).

Parameters: ``scenario`` (``default`` or a CSV path), ``weeks`` (whole weeks, 0 = the
default length; its range ends at the whole weeks the scenario's data hold from
``start``, :func:`comems4build_ros.core.scenario.data_weeks`), ``steps`` (cut the run to its
first N steps, 0 = all), ``start`` (ISO time, empty = from the beginning), ``seed``
(default scenario only, -1 = the seed of ``config/scenario.yaml``), ``forecast_mode``
(empty = ``config/forecast.yaml``), ``lookahead_steps`` (may change during a run),
``allow_gap_fill`` (default false), ``for_ems`` (empty = every EMS topic), ``inputs``,
``live_config``, ``live_cache_dir``, ``wait_for_recorder``, ``recorder_node``,
``exit_when_done``, ``run_id`` (the run's id, named on ``feed/info``) and the plant parameters (see
:meth:`comems4build_ros.ros.package_node.NodeParameters.plant_params`). A scenario with a time gap,
a non-finite value, or missing values the core loader would interpolate makes the feed
refuse to start (exit code 2, the message names file, line and column); with
``allow_gap_fill:=true`` the loader's documented interpolation is accepted.
"""

from __future__ import annotations

import json
from array import array
from typing import Any

from rclpy.node import Node
from std_msgs.msg import String, UInt32

from comems4build_ros.core.community.spec import house_params, house_scenario, house_spec, load_community
from comems4build_ros.core.scenario.base import Scenario
from comems4build_ros.core.scenario.run import check_scenario, load_scenario
from comems4build_ros.core.types import EXOGENOUS_FIELDS, PlantState
from comems4build_ros.ros.node import (
    RECORDER_NODE,
    ArrayPublisher,
    ContractEndpoints,
    RecorderGate,
    RunEnd,
    layout_sizes,
)
from comems4build_ros.ros.package_node import (
    NodeParameters,
    debug_enabled,
    node_options,
    sim_time_logger,
    steady_timer,
)
from comems4build_ros.ros.parameters import ParameterError, spec_of
from comems4build_ros.ros.process import run_node

NODE_NAME = "feed"
#: Feed topics besides feed/truth, published for every step.
EMS_TOPICS = (
    "feed/calendar",
    "feed/measured",
    "feed/comfort",
    "feed/prices",
    "feed/comfort_ahead",
    "feed/solar",
    "feed/h2_allowance",
    "feed/season",
    "feed/t_amb",
)
#: ``weeks_bound`` of :class:`Feed` not given: computed from the scenario's data.
_UNKNOWN = object()
#: Default number of steps published ahead of the step the plant waits for.
LOOKAHEAD_STEPS = 4
#: Feed parameters that choose the scenario, with their defaults.
SCENARIO_PARAMS: dict[str, Any] = {
    "scenario": "default", "start": "", "weeks": 0, "seed": -1, "steps": 0, "allow_gap_fill": False,
}


def scenario_args(values: dict[str, Any], params: Any) -> tuple[Any, ...]:
    """Positional arguments of :func:`load_scenario` from the feed's parameter values."""
    seed = int(values["seed"])
    return (str(values["scenario"]), params, str(values["start"]) or None, int(values["weeks"]) or None,
            None if seed < 0 else seed, int(values["steps"]) or None, bool(values["allow_gap_fill"]))


def prepare_scenario(node_params: dict[str, Any]) -> tuple[Scenario, list[str], int | None]:
    """The scenario a feed node with ROS parameters ``node_params`` (``config_files``,
    ``overrides``, :data:`SCENARIO_PARAMS` and, for a community's house, ``community_file``
    and ``community_house``) loads, the loader's notes and the bound of its ``weeks``
    (:func:`comems4build_ros.core.scenario.data_weeks`); no rclpy."""
    from comems4build_ros.core.config import load_plant_params, parse_assignments
    from comems4build_ros.core.scenario import data_weeks

    overrides = parse_assignments(node_params.get("overrides") or [], "parameter 'overrides':")
    files = [f for f in node_params.get("config_files") or [] if f]
    params = load_plant_params(files, overrides)
    values = {name: node_params.get(name, default) for name, default in SCENARIO_PARAMS.items()}
    notes: list[str] = []
    bound = data_weeks(str(values["scenario"]), params, str(values["start"]) or None)
    scenario = load_scenario(*scenario_args(values, params), notes=notes)
    house = community_house(str(node_params.get("community_file") or ""),
                            str(node_params.get("community_house") or ""), files, overrides, params)
    if house is not None:
        scenario = house_scenario(scenario, house[0], house[1])
    return scenario, notes, bound


def community_house(community_file: str, name: str, files: list[str], overrides: dict[str, Any],
                    params: Any) -> tuple[Any, Any] | None:
    """The community file's house ``name`` and its parameters as its EMS knows them
    (:func:`~comems4build_ros.core.community.spec.house_params`) on the run's parameters ``params``
    (of ``files`` and ``overrides``); None without a community.

    Raises
    ------
    ConfigError
        Naming the community file and the field, or the house it lacks.
    ValueError
        For a house without a community file, or the reverse.
    """
    if not community_file and not name:
        return None
    if not (community_file and name):
        raise ValueError(f"node '{NODE_NAME}': parameters 'community_file' and 'community_house' go together "
                         f"(got {community_file!r} and {name!r})")
    spec = load_community(community_file)
    house = house_spec(spec, name, community_file)
    return house, house_params(spec, house, files, overrides, params, community_file)[0]


class LiveFeed:
    """Live prices and weather for the feed (parameter ``inputs:=live``; docs/real_building.md).

    The run's steps are laid on the wall-clock hours from the current hour
    (:func:`comems4build_ros.core.scenario.live.live_scenario`). Prices and weather are fetched
    once, blocking, on start, then by a worker thread on their schedule; new values are
    taken into the steps not yet published. Without a live price for the first hour (a
    failed fetch and no cached price for it) the node refuses to start (exit code 2, the
    message names the source URL). A later failed fetch keeps the last valid values and
    is published as a ``warning`` on ``feed/events``.

    Parameters of the feed: ``live_config`` (default ``config/live_inputs.yaml``) and
    ``live_cache_dir`` (directory of the cache files, default ``~/.cache/comems4build_ros``).
    """

    POLL_S = 1.0

    def __init__(self, feed: Feed, base: Scenario, params: Any) -> None:
        import queue
        import threading
        from pathlib import Path

        import pandas as pd

        from comems4build_ros.core.scenario.live import PriceSource, WeatherSource, load_live_settings

        self.feed = feed
        self.base = base
        self.params = params
        settings = load_live_settings(feed.live_config or None)
        cache_dir = Path(feed.live_cache_dir or Path.home() / ".cache" / "comems4build_ros")
        tz = params.site.timezone
        self.warnings: queue.SimpleQueue[str] = queue.SimpleQueue()
        price_cache = Path(settings.prices.cache_file or cache_dir / "live_prices.json")
        self.prices = PriceSource(settings.prices, tz, price_cache, self.warnings.put)
        self.weather = WeatherSource(settings.weather, tz,
                                     Path(settings.weather.cache_file or cache_dir / "live_weather.json"),
                                     self.warnings.put)
        self.start_time = pd.Timestamp.now(tz=tz).floor("h")
        self.lock = threading.Lock()
        self.states: list[str] = []  # per step: the inputs stand-in values replace (:meth:`scenario`)
        self.stated = ""  # the state last stated on feed/events (:meth:`published`)
        self.changed = threading.Event()
        self.stop = threading.Event()
        self.prices.refresh(force=True)
        self.prices.require(self.start_time.timestamp())  # no run on stand-in prices (exit code 2)
        self.weather.refresh(force=True)
        self.thread = threading.Thread(target=self._work, name="live-inputs", daemon=True)

    def scenario(self) -> Scenario:
        """The run's scenario with the live values known now (and, in :attr:`states`, which
        inputs of each step stand-in values replace)."""
        import pandas as pd

        from comems4build_ros.core.scenario.live import live_scenario, stand_in_state

        with self.lock:
            scenario = live_scenario(self.base, self.params, self.start_time, self.prices, self.weather)
            self.states = stand_in_state(pd.DatetimeIndex(scenario.time), self.prices, self.weather)
        return scenario

    def published(self, k: int) -> None:
        """Step ``k`` is published for the first time: from the run's first step on, and
        whenever it changes, the inputs that stand-in values replace are stated on
        ``feed/events`` (:data:`~comems4build_ros.core.scenario.live.STAND_IN_EVENT`, read by
        evaluate into ``live_inputs`` of the summary)."""
        from comems4build_ros.core.scenario.live import STAND_IN_EVENT

        state = self.states[k]
        if k > 0 and state == self.stated:
            return
        self.stated = state
        why = {
            "none": "every input of this step is live",
            "prices": "no live price for this hour: the same hour of the latest day with prices stands in",
            "weather": "no weather forecast for this hour (or no weather source): the scenario's weather stands in",
            "prices+weather": "no live price and no weather forecast for this hour (or no weather source): the same "
                              "hour of the latest day with prices and the scenario's weather stand in",
        }[state]
        self.feed.event(STAND_IN_EVENT, f"{state}: {why} (from this step on, until the next {STAND_IN_EVENT} line)",
                        step=k)

    def start(self) -> None:
        """Start the worker thread and the feed's timer that takes new values in."""
        self.thread.start()
        steady_timer(self.feed, 0.25, self._tick)
        self._tick()

    def _work(self) -> None:
        while not self.stop.wait(self.POLL_S):
            with self.lock:
                new = self.prices.refresh() | self.weather.refresh()
            if new:
                self.changed.set()

    def _tick(self) -> None:
        while True:
            try:
                text = self.warnings.get_nowait()
            except Exception:  # queue.Empty
                break
            self.feed.event("warning", text)
        if self.changed.is_set():
            self.changed.clear()
            self.feed._use_scenario(self.scenario())
            self.feed.event("live", f"new live inputs taken in from step {self.feed._next}: {self.prices.describe()}")


class Feed(Node):
    """Scenario publisher node (see the module docstring).

    Parameters
    ----------
    scenario, weeks_bound : the scenario of the node's parameters and the bound of its ``weeks``,
        prepared beforehand (:func:`prepare_scenario`, used by a container process of feeds to
        build many in parallel)
    node_kwargs : passed to ``rclpy.node.Node`` (e.g. ``namespace``, ``parameter_overrides``)
    """

    def __init__(self, scenario: Scenario | None = None, weeks_bound: Any = _UNKNOWN, **node_kwargs: Any) -> None:
        super().__init__(NODE_NAME, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.debug = debug_enabled(self.log)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, NODE_NAME)
        from comems4build_ros.core.loop import load_forecast_settings

        params = self.parameters.plant_params()
        values, mode = self._read_parameters(params, weeks_bound)
        self.parameters.refuse_undeclared()  # before the scenario is built: a typo is named at once
        # a community's house: its parameters (its share as its store) and, below, its scenario
        house = community_house(self.community_file, self.community_house, *self.parameters.plant_sources, params)
        base_params = params
        if house is not None:
            params = house[1]
        seed = int(values["seed"])
        # Publishers first: DDS discovery (its own threads) matches them with the recorder
        # and the EMS while this thread builds the scenario, the longest part of start-up.
        self._create_publishers(params)
        # (an announcement that comes in meanwhile waits in the queue until the node spins)
        self.endpoints.subscription("plant/step", self._on_plant_step)
        self.endpoints.subscription("plant/done", self._on_done)
        self._done = False
        notes: list[str] = []
        if scenario is None:
            scenario = load_scenario(*scenario_args(values, base_params), notes=notes)
            if house is not None:
                scenario = house_scenario(scenario, house[0], params)
        for note in notes:
            self.get_logger().warning(note)
        check_scenario(scenario, params.simulation.time_step_h)
        self.n_steps = scenario.n_steps
        self._params = params
        self._forecast = load_forecast_settings(**({"mode": mode} if mode else {}))
        self._live: LiveFeed | None = None
        if self.inputs == "live":
            self._live = LiveFeed(self, scenario, params)
            scenario = self._live.scenario()
        self._use_scenario(scenario)
        # The builder's state-dependent fields are not published by the feed (plant_sim
        # publishes the state); a neutral state fills them.
        self._blank = PlantState(soc=0.0, loh=0.0, t_air_c=0.0, t_wall_in_c=0.0, t_wall_out_c=0.0, v_dhw_l=0.0)
        self._check_payload_lengths()
        self.info = {"scenario": scenario.name, "start": scenario.time[0].isoformat(), "n_steps": self.n_steps,
                     "forecast": self._forecast.mode, "seed": None if seed < 0 else seed,
                     "run_id": self.run_id or None, "for_ems": self.for_ems or None,
                     **({"house": self.community_house} if house is not None else {})}
        self._info_pub.publish(String(data=json.dumps(self.info)))
        self._next = 0  # first step not yet published
        self._last_request = -1
        if self._live is not None:
            self._live.start()
        self.get_logger().info(
            f"scenario '{scenario.name}': {self.n_steps} steps from {scenario.time[0].isoformat()}, "
            f"forecast {self._forecast.mode}, {self.lookahead} steps ahead, inputs: {self.inputs}"
        )

    def _read_parameters(self, params: Any, weeks_bound: Any) -> tuple[dict[str, Any], str]:
        """Declare and read every parameter besides the plant's: the scenario's (returned with the
        forecast mode), the others as attributes (``lookahead_steps`` may change during a run)."""
        values = self._scenario_values(params, weeks_bound)
        mode = self.parameters.param("forecast_mode", "")
        self.lookahead = self.parameters.param("lookahead_steps", LOOKAHEAD_STEPS,
                                    on_change=lambda v: setattr(self, "lookahead", v))
        self.inputs = self.parameters.param("inputs", "scenario")
        if self.inputs not in ("scenario", "live"):
            raise ValueError(f"node '{NODE_NAME}': parameter 'inputs': '{self.inputs}' is not 'scenario' or 'live'")
        self.live_config = self.parameters.param("live_config", "")
        self.live_cache_dir = self.parameters.param("live_cache_dir", "")
        # With a house behind MQTT its own meters give the PV output and load: the
        # mqtt_bridge publishes feed/measured and the feed leaves it out.
        self.publish_measured = self.parameters.param("publish_measured", True)
        # Serving one EMS, the feed publishes only what that EMS reads (its information
        # level, tab:level_of_information); without, every EMS input (any EMS, or a bag
        # that can later drive any EMS with replay --inputs-only).
        self.for_ems = self.parameters.param("for_ems", "")
        # the run's id, named on feed/info: evaluate tells this run's records from another's by it
        self.run_id = self.parameters.param("run_id", "")
        # a house of a community: its scenario and parameters; the coordinator publishes its h2 allowance
        self.community_file = self.parameters.param("community_file", "")
        self.community_house = self.parameters.param("community_house", "")
        self.run_end = RunEnd(self.parameters.param("exit_when_done", True))  # process.run_complete reads it
        self.finished = self.run_end.finished
        self.gate = RecorderGate(self, self.parameters.param("wait_for_recorder", False),
                                 self.parameters.param("recorder_node", RECORDER_NODE))
        return values, mode

    def _create_publishers(self, params: Any) -> None:
        """feed/truth, the EMS topics the run's EMS reads (``for_ems``), feed/events and feed/info."""
        sizes_ = layout_sizes(params)
        self._truth = ArrayPublisher(self.endpoints, "feed/truth", sizes_)
        contract = self.endpoints.contract
        forecast_topics = tuple(t.name for t in contract.published_by(NODE_NAME) if t.name.startswith("forecast/"))
        self.level = "mpc"
        unread: set[str] = set()
        if self.for_ems:
            unread = set(self.endpoints.contract.inputs_not_read(self.for_ems))
            self.level = self.endpoints.contract.node(self.for_ems).info_level or "mpc"
        if self.community_house:  # what the coordinator allots the house, on its own (contract: publisher coordinator)
            unread.add("feed/h2_allowance")
        ems_topics = [t for t in EMS_TOPICS if (self.publish_measured or t != "feed/measured") and t not in unread]
        self.topics = (*ems_topics, *(t for t in forecast_topics if t not in unread))
        self._pubs = [ArrayPublisher(self.endpoints, t, sizes_) for t in self.topics]
        self._events = self.endpoints.publisher("feed/events")
        self._info_pub = self.endpoints.publisher("feed/info")
        self._pub_fields = [p.layout.fields for p in self._pubs]

    def _scenario_values(self, params: Any, weeks_bound: Any) -> dict[str, Any]:
        """The parameters of :data:`SCENARIO_PARAMS`, ``weeks`` declared with the bound of the
        scenario's data (``weeks_bound``, computed here unless given)."""
        import dataclasses

        from comems4build_ros.core.scenario import data_weeks

        values = {name: self.parameters.param(name, default) for name, default in SCENARIO_PARAMS.items()
                  if name != "weeks"}
        if weeks_bound is _UNKNOWN:
            weeks_bound = data_weeks(values["scenario"], params, values["start"] or None)
        spec = spec_of("weeks")
        held = ""
        if weeks_bound is not None:
            held = (f"the data of scenario '{values['scenario']}' hold {weeks_bound} whole week(s) from "
                    f"{values['start'] or 'its start'} (its look-ahead kept)")
            spec = dataclasses.replace(spec, high=float(weeks_bound), description=f"{spec.description}; {held}")
        try:
            values["weeks"] = self.parameters.param("weeks", SCENARIO_PARAMS["weeks"], spec=spec)
        except ParameterError as exc:
            raise ParameterError(f"{exc}{': ' + held if held else ''}") from None
        return values

    def _use_scenario(self, scenario: Scenario) -> None:
        """Build the observation values of every step from ``scenario`` (again when live inputs change)."""
        from comems4build_ros.core.loop import ObservationBuilder, exogenous_series

        exo = exogenous_series(scenario, self._params)
        self._builder = ObservationBuilder(scenario, self._params, self.level, exo, self._forecast)
        self._exo = exo
        self._time_s = [t.timestamp() for t in scenario.time]
        self._spot = scenario.spot_eur_per_mwh.tolist()
        self.scenario = scenario

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    def event(self, kind: str, detail: str, step: int | None = None) -> None:
        """Log an input event and publish it on feed/events (``<step> <kind> <detail>``;
        ``step`` default: the first step not yet published)."""
        line = f"{self._next if step is None else step} {kind} {detail}"
        self.get_logger().warning(line)
        self._events.publish(String(data=line))

    # ------------------------------------------------------------------ publishing
    def payloads(self, k: int) -> list[array]:
        """Payloads of step ``k``: feed/truth first, then the EMS and forecast topics."""
        e = self._exo[k]
        truth = array("d", (float(k), float(self.n_steps), self._time_s[k]))
        truth.extend(float(getattr(e, f)) for f in EXOGENOUS_FIELDS)
        truth.append(float(self._spot[k]))
        out = [truth]
        data = self._builder.data(k, self._blank)
        forecast = data.get("forecast", {})
        for fields in self._pub_fields:
            payload = array("d")
            for f in fields:
                head, dot, key = f.name.partition(".")
                value = forecast[key] if dot else data[head]
                if f.size is None:
                    payload.append(float(value))
                else:
                    payload.extend(value)
            out.append(payload)
        return out

    def _check_payload_lengths(self) -> None:
        for pub, payload in zip((self._truth, *self._pubs), self.payloads(0)):
            if len(payload) != pub.layout.length:
                raise ValueError(
                    f"topic '{pub.topic}': the feed builds {len(payload)} elements, "
                    f"the contract layout has {pub.layout.length}"
                )

    def _publish_step(self, k: int) -> None:
        for pub, payload in zip((self._truth, *self._pubs), self.payloads(k)):
            pub.publish(payload)

    def _on_done(self, msg: Any) -> None:
        """End of the run (``plant/done``): the node exits with code 0."""
        if msg.data:
            self.run_end.saw_done = True
        if msg.data and self.run_end.exit_when_done and not self._done:
            self._done = True
            self.get_logger().info("run done: exiting once the recorder has left")
            self.gate.finish_when_recorded(self.finished, "feed/truth")

    def _on_plant_step(self, msg: UInt32) -> None:
        k = int(msg.data)
        if k >= self.n_steps:
            return
        if not self.gate.is_open():  # not yet: answered once the gate opens
            self.gate.when_open(lambda: self._on_plant_step(msg))
            return
        last = min(k + self.lookahead, self.n_steps - 1)
        first = k if k <= self._last_request else max(self._next, k)
        for j in range(first, last + 1):
            if self._live is not None and j >= self._next:
                self._live.published(j)
            self._publish_step(j)
        if first <= last and self.debug:
            self.get_logger().debug(f"plant/step {k}: inputs of steps {first}..{last} published")
        self._next = max(self._next, last + 1)
        self._last_request = k


def main(args: list[str] | None = None) -> int:
    """Entry point of ``feed`` (``ros2 run comems4build_ros feed``)."""
    return run_node(Feed, args, NODE_NAME)


if __name__ == "__main__":
    raise SystemExit(main())

