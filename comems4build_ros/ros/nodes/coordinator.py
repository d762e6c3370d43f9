"""``coordinator``: the coordinator of a community's hydrogen hub as a ROS 2 node.

One node for a community (docs/community.md "Over ROS"), in the community's namespace; its
houses run under ``<namespace>/<house>`` (the names of the community file), each with its
own ``plant_sim`` (``hub:=true``), feed (``community_house``), EMS and recorder. The node runs
the coordinator of ``config/coordinators.yaml`` named by the parameter ``coordinator``
(any row: the class is loaded from the table, built with the community's fixed figures and
the row's options merged with ``coordinator_options``) and keeps the hub: its store, its
electrolysers and every house's H2 account (:class:`~comems4build_ros.core.community.hubrun.HubRun`,
the very code of the in-process loop). Per step ``k``:

1. allot: the coordinator reads the hub and the houses at the end of ``k - 1`` and allots;
   the hub applies the transfers; every house gets ``hub/allotment`` (its account, its
   allotted ``eq:deltaLOH``, the hub's electrolysers' state) and ``feed/h2_allowance`` (the
   allotted ``eq:deltaLOH``, which its EMS reads where an isolated house's reads its own; not for
   an EMS that does not read it, parameter ``for_ems``);
2. each house's EMS acts, its plant steps and reports (``hub/report``: its account as its
   fuel cell left it, its flows, its EMS's electrolyser request);
3. settle, once every house reported: the coordinator dispatches the hub, the hub steps and
   credits its production, every house gets ``hub/settlement`` (its account at the end of
   the step), the step's row of the hub's timeseries goes out on ``hub/record`` and the
   coordinator's ``step_info`` on ``coordinator/info``; then ``k + 1`` is allotted.

The figures are those of the in-process run, bit for bit: the same arithmetic on the same
values in the same order.

Clock (parameter ``clock``). ``sim``: lock-step, every step waits for every house; a house
that falls silent ends the run after ``stall_steps`` step time-outs (exit code 4, naming
it), and the launcher fails the run when a house's process leaves. ``wall`` or
``wall:<factor>`` (live operation): step ``k`` is allotted at ``t0 + k * period`` and settled
when every house reported or at ``t0 + (k + 1) * period``, whichever comes first; a house
without a report by then has left the community: from that step on it is left out
(``house_left`` on ``hub/events``, its account frozen, its later messages ignored), the hub's
balance stays closed, and ``houses_present`` of ``hub/record`` marks the gap.

Every ``hub/*`` message to or from house ``i`` carries the authentication code of its other
elements under the house's hub secret (parameter ``hub_token_files``, in the community file's
order; :func:`~comems4build_ros.wire.tokens.sign`); a report without it is ignored and counted
(``foreign`` on ``hub/events``). While it waits for reports the node sends the allotments
again every ``republish_period_s`` (a message sent before a reader matched is not
delivered); a report of a step already settled gets that step's settlement again.

With ``wait_for_recorder`` the node starts once its recorder (``recorder/ready`` in its
namespace) is ready and its writers matched the recorders' readers, allots no step more than
``record_window_steps`` beyond the recorder's ``recorder/progress`` (back-pressure), and ends
once the recorder has left. After the last step: ``hub/done`` (transient local), the
statistics on ``hub/events`` and exit code 0.
"""

from __future__ import annotations

import json
import time
from array import array
from typing import Any

from rclpy.duration import Duration
from rclpy.node import Node
from std_msgs.msg import Bool, String

from comems4build_ros.core.community.coordinator import Request
from comems4build_ros.core.community.hubrun import (
    NO_FLOWS,
    NO_REQUEST,
    HouseMeter,
    HubRun,
    initial_accounts,
)
from comems4build_ros.core.community.spec import community_of, load_community
from comems4build_ros.core.config import parse_assignments
from comems4build_ros.ros.lockstep import (
    ACK_POLL_S,
    ACK_TIMEOUT_S,
    LOOP_PARAMS,
    RECORD_WINDOW_STEPS,
    RECORDER_STALL_MIN_S,
)
from comems4build_ros.ros.node import RECORDER_NODE, ArrayPublisher, ContractEndpoints, RecorderGate, RunEnd
from comems4build_ros.ros.nodes.feed import SCENARIO_PARAMS, load_scenario, scenario_args
from comems4build_ros.ros.package_node import NodeParameters, node_options, sim_time_logger, steady_timer
from comems4build_ros.ros.process import report_cause, run_node
from comems4build_ros.wire.contract import resolve
from comems4build_ros.wire.exits import EXIT_STALLED
from comems4build_ros.wire.tokens import authentic, read_token_file, secret_key, sign

NODE_NAME = "coordinator"
#: Default stall limit: step time-outs without a step before the run ends as stalled (0 = never).
STALL_STEPS = 0


class CoordinatorNode(Node):
    """The coordinator node (see the module docstring).

    Parameters
    ----------
    node_kwargs : passed to ``rclpy.node.Node`` (e.g. ``namespace``, ``parameter_overrides``)
    """

    def __init__(self, **node_kwargs: Any) -> None:
        from comems4build_ros.mqtt.clock import parse_clock

        super().__init__(NODE_NAME, **node_options(node_kwargs))
        self.log = sim_time_logger(self)
        self.parameters = NodeParameters(self)
        self.endpoints = ContractEndpoints(self, NODE_NAME)
        p = self.parameters
        params = p.plant_params()  # the run's plant, every house's base
        name = p.param("coordinator", "rule")
        options = parse_assignments(p.param("coordinator_options", []), f"node '{NODE_NAME}': coordinator_options:")
        community_file = p.param("community_file", "")
        if not community_file:
            raise ValueError(f"node '{NODE_NAME}': parameter 'community_file' (the community file) is required")
        values = {key: p.param(key, default) for key, default in SCENARIO_PARAMS.items()}
        token_files = p.string_list("hub_token_files")
        # the houses' EMS node: feed/h2_allowance goes out only if it reads it (tab:level_of_information)
        for_ems = p.param("for_ems", "")
        self.clock = parse_clock(p.param("clock", "sim"), params.simulation.time_step_h)
        for key, default in LOOP_PARAMS.items():
            setattr(self, key, p.param(key, default, on_change=self._setter(key)))
        self.stall_steps = p.param("stall_steps", STALL_STEPS, on_change=self._setter("stall_steps"))
        self.record_window_steps = p.param("record_window_steps", RECORD_WINDOW_STEPS)
        self.gate = RecorderGate(self, p.param("wait_for_recorder", False), p.param("recorder_node", RECORDER_NODE))
        self.run_end = RunEnd(p.param("exit_when_done", True))  # process.run_complete reads it
        self.finished = self.run_end.finished
        p.refuse_undeclared()  # before the community is built: a typo is named at once

        spec = load_community(community_file)
        if token_files and len(token_files) != len(spec.houses):
            raise ValueError(f"node '{NODE_NAME}': parameter 'hub_token_files': {len(token_files)} files for "
                             f"{len(spec.houses)} houses of {community_file}")
        files, given = p.plant_sources
        community = community_of(spec, files, given, params, load_scenario(*scenario_args(values, params)),
                                 community_file)
        self.hub = HubRun(community, name, options)
        self.n = len(community.houses)
        self.names = [h.name for h in community.houses]
        self.namespaces = [resolve(self.get_namespace(), h) for h in self.names]
        self.keys = [secret_key(read_token_file(f)) for f in token_files] if token_files else [None] * self.n
        self.accounts = initial_accounts(community)
        self.time_s = [t.timestamp() for t in community.scenario.time[:self.hub.n_steps]]

        contract = self.endpoints.contract
        self._report_length = contract.topic("hub/report").layout({}).length
        self._allot_pubs = [ArrayPublisher(self.endpoints, "hub/allotment", {}, ns) for ns in self.namespaces]
        allowance = not for_ems or "feed/h2_allowance" not in contract.inputs_not_read(for_ems)
        self._allowance_pubs = ([ArrayPublisher(self.endpoints, "feed/h2_allowance", {}, ns) for ns in self.namespaces]
                                if allowance else [])
        self._settle_pubs = [ArrayPublisher(self.endpoints, "hub/settlement", {}, ns) for ns in self.namespaces]
        self._record = ArrayPublisher(self.endpoints, "hub/record", {})
        self._info_pub = self.endpoints.publisher("coordinator/info")
        self._events_pub = self.endpoints.publisher("hub/events")
        self._done_pub = self.endpoints.publisher("hub/done")
        for i, ns in enumerate(self.namespaces):
            self.endpoints.subscription("hub/report", self._report_callback(i), namespace=ns)
        self._recorder_ready = False
        self._recorded = 0
        self.endpoints.subscription("recorder/ready", self._on_recorder_ready)
        self.endpoints.subscription("recorder/progress", self._on_recorder_progress)

        # the run
        self.k = 0  # the step allotted or to allot
        self.started = False
        self.allotted = -1  # the last step allotted
        self.present = [True] * self.n  # houses in the community (a wall-clock run goes on without one)
        self.reports: dict[int, tuple[float, HouseMeter, Request]] = {}  # house -> its report of step k
        self._allot_msgs: list[tuple[array, array] | None] = [None] * self.n
        self._settle_msgs: dict[int, tuple[int, array]] = {}  # house -> (step, its last settlement)
        self.counts = {"foreign_reports": 0, "late_reports": 0, "rejected_reports": 0, "resent_allotments": 0}
        self._t_created = time.monotonic()
        self._t_allot = 0.0  # when step k was allotted [s, monotonic]
        self._t_resend = 0.0
        self._t_moved = time.monotonic()
        self._t0_wall = 0.0  # wall clocks: the start of step 0 [s since the epoch]
        self._t_run0 = 0.0
        self._held_s = 0.0
        self._timer = steady_timer(self, self.watchdog_period_s, self._watchdog)
        self.get_logger().info(
            f"coordinator '{name}' of community '{community.name}' ({self.n} houses under "
            f"{self.get_namespace()}), {self.hub.n_steps} steps, clock {self.clock.spec()}")

    def _setter(self, name: str) -> Any:
        def apply(value: Any) -> None:
            setattr(self, name, value)
            if name == "watchdog_period_s":
                self._timer.timer_period_ns = int(float(value) * 1e9)

        return apply

    def get_logger(self) -> Any:
        """The node's logger, stamped with the simulated time (``package_node.sim_time_logger``)."""
        return getattr(self, "log", None) or super().get_logger()

    # ------------------------------------------------------------------ messages in
    def _on_recorder_ready(self, msg: Bool) -> None:
        self._recorder_ready = bool(msg.data)

    def _on_recorder_progress(self, msg: Any) -> None:
        if int(msg.data) > self._recorded:
            self._recorded = int(msg.data)
            self._t_moved = time.monotonic()
            self._next()

    def _report_callback(self, i: int) -> Any:
        def on_report(msg: Any) -> None:
            self._on_report(i, msg.data)

        return on_report

    def _on_report(self, i: int, data: Any) -> None:
        """House ``i``'s report: kept if it is for the step waited for; a report of a step already
        settled gets that settlement again (the house did not receive it)."""
        ns = self.namespaces[i]
        if len(data) != self._report_length:
            self.counts["rejected_reports"] += 1
            self.event("rejected", f"topic '{ns}/hub/report': {len(data)} elements, layout has {self._report_length}")
            return
        if not authentic(self.keys[i], data):
            self.counts["foreign_reports"] += 1
            self.event("foreign", f"topic '{ns}/hub/report': report for step {int(data[0])} ignored (not "
                                  "authenticated by the house's hub secret)")
            return
        step = int(data[0])
        if not self.present[i]:
            self.counts["late_reports"] += 1
            return
        if step != self.k or self.allotted != self.k or i in self.reports:
            last = self._settle_msgs.get(i)
            if last is not None and last[0] == step:
                self._settle_pubs[i].publish(last[1])
            return
        meter = HouseMeter(*(float(x) for x in data[2:-2]))
        self.reports[i] = (float(data[1]), meter, Request(float(data[-2]), meter.p_pv_w, meter.p_load_w))
        if all(j in self.reports for j in range(self.n) if self.present[j]):
            self._settle()

    # ------------------------------------------------------------------ stepping
    def _start(self) -> None:
        self.started = True
        self._t_run0 = time.monotonic()
        self.hub.start(self.accounts)
        if self.clock.wall:
            self._t0_wall = self.clock.first_boundary(time.time(), 0.0)
        self.get_logger().info("starting the community's run")
        self._next()

    def _next(self) -> None:
        """Allot step k if it may go out now: the run started, the step before settled, not held back
        by the recording (back-pressure), and a wall clock at the step's start."""
        if not self.started or self.run_end.saw_done or self.allotted == self.k or self.k >= self.hub.n_steps:
            return
        if self.gate.wait_for_recorder and self.k - self._recorded > self.record_window_steps:
            return
        if self.clock.wall and time.time() < self._t0_wall + self.k * self.clock.period_s:
            return
        self._allot()

    def _allot(self) -> None:
        k = self.k
        allotted = self.hub.allot(k, self.accounts, self.present)
        kf = float(k)
        for i in range(self.n):
            if not self.present[i]:
                continue
            dloh = float(allotted.dloh_per_day[i])
            allowance = array("d", (kf, dloh))
            message = sign(self.keys[i], array("d", (kf, self.accounts[i].loh, dloh,
                                                     1.0 if allotted.el_on_prev else 0.0, allotted.moved_wh[i])))
            self._allot_msgs[i] = (allowance, message)
            if self._allowance_pubs:  # first: the house's EMS reads it when the plant announces
                self._allowance_pubs[i].publish(allowance)
            self._allot_pubs[i].publish(message)
        self.allotted = k
        self.reports = {}
        self._t_allot = self._t_resend = time.monotonic()
        self._t_moved = self._t_allot

    def _settle(self) -> None:
        k = self.k
        flows: list[Any] = []
        requests: list[Request] = []
        for i in range(self.n):
            report = self.reports.get(i) if self.present[i] else None
            if report is None:
                flows.append(NO_FLOWS)
                requests.append(NO_REQUEST)
                continue
            self.accounts[i].loh = report[0]
            flows.append(report[1])
            requests.append(report[2])
        settled = self.hub.settle(k, self.accounts, flows, requests, self.present)
        kf = float(k)
        for i in range(self.n):
            if not self.present[i]:
                continue
            message = sign(self.keys[i], array("d", (kf, self.accounts[i].loh, settled.credited_wh[i],
                                                     float(settled.split[i]))))
            self._settle_msgs[i] = (k, message)
            self._settle_pubs[i].publish(message)
        row = self.hub.rows[-1]
        record = array("d", (kf, float(self.hub.n_steps), self.time_s[k]))
        record.extend(float(v) for v in row[2:])
        self._record.publish(record)
        info = {"step": k, "coordinator": self.hub.coord.name, "info": self.hub.coord_infos[-1]}
        self._info_pub.publish(String(data=json.dumps(info)))
        self.k = k + 1
        self._t_moved = time.monotonic()
        if self.k >= self.hub.n_steps:
            self._finish()
        else:
            self._next()

    # ------------------------------------------------------------------ watchdog
    def _watchdog(self) -> None:
        now = time.monotonic()
        if self.run_end.saw_done or self.finished.done():
            return
        if not self.started:
            matched = all(pub.publisher.get_subscription_count() > 0 for pub in self._allot_pubs)
            recorder = not self.gate.wait_for_recorder or (self._recorder_ready and self.gate.is_open())
            if recorder and (matched or now - self._t_created > self.startup_timeout_s):
                self._start()
            return
        if self.allotted != self.k:
            self._next()  # a wall clock's step start, or the recording caught up
            if self.allotted != self.k:
                self._check_stall(now, None)
            return
        missing = [i for i in range(self.n) if self.present[i] and i not in self.reports]
        if self.clock.wall and time.time() >= self._t0_wall + (self.k + 1) * self.clock.period_s:
            for i in missing:  # no report by the end of its step: the house has left
                self.present[i] = False
                self.event("house_left", f"house '{self.names[i]}' ({self.namespaces[i]}) sent no report for step "
                                         f"{self.k} within its wall-clock step of {self.clock.period_s:g} s: left out "
                                         "from now on, its account frozen")
            self._settle()
            return
        if now - self._t_resend > self.republish_period_s:
            self._t_resend = now
            for i in missing:
                sent = self._allot_msgs[i]
                if sent is not None:
                    if self._allowance_pubs:
                        self._allowance_pubs[i].publish(sent[0])
                    self._allot_pubs[i].publish(sent[1])
                    self.counts["resent_allotments"] += 1
        self._check_stall(now, missing)

    def _check_stall(self, now: float, missing: list[int] | None) -> None:
        """End the run (exit code 4) when, with ``stall_steps`` > 0, no step was made for
        ``stall_steps`` step time-outs: naming the houses whose reports are missing, or the
        recorder when the recording holds the run back."""
        if not self.stall_steps or self.clock.wall:
            return
        window = self.stall_steps * self.step_timeout_s
        if missing is None:  # held back by the recording
            window = max(window, RECORDER_STALL_MIN_S)
        if now - self._t_moved <= window:
            return
        if missing is None:
            what = (f"the recorder '{self.gate.recorder_node}' (step {self.k} held back until it has written step "
                    f"{self.k - self.record_window_steps}; written: {self._recorded})")
        else:
            what = "the reports on 'hub/report' of " + ", ".join(
                f"house '{self.names[i]}' ({self._publishers(self.namespaces[i])})" for i in missing)
        cause = (f"no step for {now - self._t_moved:.1f} s at step {self.k} (limit: {self.stall_steps} step "
                 f"time-outs of {self.step_timeout_s:g} s): waiting for {what}")
        self.event("stall", cause)
        report_cause(self.get_fully_qualified_name(), f"run stalled: {cause}", self.get_logger())
        self.finished.set_result(EXIT_STALLED)

    def _publishers(self, ns: str) -> str:
        infos = self.get_publishers_info_by_topic(resolve(ns, "hub/report"))
        names = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos})
        return f"publisher: {', '.join(names)}" if names else "no publisher left"

    # ------------------------------------------------------------------ output
    def event(self, kind: str, detail: str, step: int | None = None) -> None:
        """Log an event of the hub and publish it on hub/events (``<step> <kind> <detail>``)."""
        line = f"{self.k if step is None else step} {kind} {detail}"
        self.get_logger().warning(line)
        self._events_pub.publish(String(data=line))

    def stats(self) -> dict[str, float]:
        """Run statistics: steps, houses present at the end, wall time [s], the coordinator's own time [s],
        fault counters."""
        return {"steps": float(self.k), "houses": float(self.n), "houses_present": float(sum(self.present)),
                "wall_s": time.monotonic() - self._t_run0, "coordinator_s": self.hub.coordinator_s,
                **{k: float(v) for k, v in self.counts.items()}}

    def _finish(self) -> None:
        """End of the run: the statistics line, hub/done, then (``exit_when_done``) exit once the
        recorder has left (at most 5 s for the last messages' acknowledgement first)."""
        self.run_end.saw_done = True
        line = " ".join(f"{k}={v:.6g}" for k, v in self.stats().items())
        self.get_logger().info(f"run done: {line}")
        self._done_pub.publish(Bool(data=True))
        self._events_pub.publish(String(data=f"{self.k} stats {line}"))
        pubs = [self._record.publisher, self._done_pub, self._events_pub, *(p.publisher for p in self._settle_pubs)]
        t0 = time.monotonic()
        now_only = Duration(nanoseconds=0)
        timer: Any = None

        def poll() -> None:
            if not all(p.wait_for_all_acked(now_only) for p in pubs) and time.monotonic() - t0 < ACK_TIMEOUT_S:
                return
            timer.cancel()
            if self.run_end.exit_when_done:
                self.gate.finish_when_recorded(self.finished, "hub/record")

        timer = steady_timer(self, ACK_POLL_S, poll)


def main(args: list[str] | None = None) -> int:
    """Entry point of ``coordinator`` (``ros2 run comems4build_ros coordinator``)."""
    return run_node(CoordinatorNode, args, NODE_NAME)


if __name__ == "__main__":
    raise SystemExit(main())
