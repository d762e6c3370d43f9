"""A lean single-threaded executor for the lock-step loop.

Profile of one house's 12-week run with rclpy's ``SingleThreadedExecutor``
(py-spy, docs/ros_tools.md "Profile of a step"): 30 to 45 % of every node's CPU time went
to the executor itself, not to the callbacks. For every single callback it gathers the
entities of every node, enters each handle's context, builds a new ``WaitSet``, waits,
wraps the callback in a ``Task`` with a coroutine, and (in
``spin_until_future_complete``) adds one more done-callback to the awaited future.

:class:`LeanExecutor` keeps the semantics the nodes rely on (single thread, callbacks of
one node never run concurrently, SIGINT raises ``KeyboardInterrupt``, SIGTERM and
``rclpy.shutdown`` raise ``ExternalShutdownException``, ``spin_until_future_complete``)
and removes that overhead:

* the entities are gathered and their handles entered once, again only when a node,
  subscription, timer, service, client, guard condition or waitable is added or removed;
* one ``WaitSet`` is reused (cleared and refilled before each wait, as rcl requires);
* a ready subscription is drained (up to :data:`MAX_TAKE_PER_WAKE` messages per wake-up)
  and its callback called directly, without a ``Task``; a ready timer is called directly;
* services, clients, guard conditions of nodes and waitables (QoS event handlers) go
  through rclpy's own handlers (rare: parameter services, events).

Subclass of ``rclpy.executors.Executor`` (rclpy 7.1.6, pinned): ``add_node``,
``remove_node``, ``create_task``, ``wake`` and ``shutdown`` are inherited.
"""

from __future__ import annotations

import contextlib
import time
from typing import Any

from rclpy.executors import Executor, ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription

#: Messages taken from one subscription per wake-up before the others get their turn.
MAX_TAKE_PER_WAKE = 64
NS_PER_S = 1_000_000_000


class LeanExecutor(Executor):
    """Single-threaded executor with a reused wait set and direct callbacks (see the module docstring)."""

    def __init__(self, *, context: Any = None) -> None:
        super().__init__(context=context)
        self._signature: tuple[Any, ...] | None = None
        self._stack: contextlib.ExitStack | None = None
        self._wait_set: Any = None
        self._subs: dict[int, tuple[Any, Any, Any, bool, Any]] = {}
        self._timers: dict[int, tuple[Any, Any]] = {}
        self._rare: list[tuple[str, Any, Any]] = []  # (kind, entity, node): services, clients, guards
        self._waitables: list[tuple[Any, Any]] = []
        self._sub_handles: list[Any] = []
        self._timer_handles: list[Any] = []
        self._guard_handles: list[Any] = []
        self._service_handles: list[Any] = []
        self._client_handles: list[Any] = []

    # ------------------------------------------------------------------ entities
    @staticmethod
    def _entity_signature(nodes: list[Any]) -> tuple[Any, ...]:
        """Cheap fingerprint of every node's entity lists (rclpy 7.1's ``Node`` keeps them in
        the lists below; their public properties are generators): length and last entity of
        each, so that destroying one entity and creating another (same length) counts too."""

        def mark(entities: list[Any]) -> tuple[int, int]:
            return len(entities), id(entities[-1]) if entities else 0

        return tuple(
            (id(n), mark(n._subscriptions), mark(n._timers), mark(n._guards), mark(n._clients), mark(n._services),
             mark(n._Node__waitables))
            for n in nodes
        )

    def _release(self) -> None:
        if self._stack is not None:
            self._stack.close()
            self._stack = None
        self._wait_set = None
        self._signature = None

    def _refresh(self) -> None:
        """Gather the entities again if any node's set of entities changed."""
        nodes = self.get_nodes()
        sig = self._entity_signature(nodes)
        if sig == self._signature:
            return
        self._release()
        stack = contextlib.ExitStack()
        subs: dict[int, tuple[Any, Any, Any, bool, Any]] = {}
        timers: dict[int, tuple[Any, Any]] = {}
        rare: list[tuple[str, Any, Any]] = []
        waitables: list[tuple[Any, Any]] = []
        sub_h, tmr_h, gc_h, srv_h, cli_h = [], [], [], [], []
        n_events = 0
        for node in nodes:
            for sub in node.subscriptions:
                h = sub.handle
                stack.enter_context(h)
                with_info = sub._callback_type is Subscription.CallbackType.WithMessageInfo
                subs[h.pointer] = (h, sub.msg_type, sub.raw, with_info, sub.callback)
                sub_h.append(h)
            for tmr in node.timers:
                h = tmr.handle
                stack.enter_context(h)
                timers[h.pointer] = (h, tmr.callback)
                tmr_h.append(h)
            for kind, entities, handles in (("guard", node.guards, gc_h), ("service", node.services, srv_h),
                                             ("client", node.clients, cli_h)):
                for e in entities:
                    stack.enter_context(e.handle)
                    handles.append(e.handle)
                    rare.append((kind, e, node))
            for wt in node.waitables:
                stack.enter_context(wt)
                n_events += wt.get_num_entities().num_events
                waitables.append((wt, node))
        for gc in (self._guard, self._sigint_gc):
            stack.enter_context(gc.handle)
            gc_h.append(gc.handle)
        stack.enter_context(self._context.handle)
        n_wait_subs = len(sub_h) + sum(wt.get_num_entities().num_subscriptions for wt, _ in waitables)
        n_wait_gcs = len(gc_h) + sum(wt.get_num_entities().num_guard_conditions for wt, _ in waitables)
        n_wait_tmrs = len(tmr_h) + sum(wt.get_num_entities().num_timers for wt, _ in waitables)
        n_wait_clis = len(cli_h) + sum(wt.get_num_entities().num_clients for wt, _ in waitables)
        n_wait_srvs = len(srv_h) + sum(wt.get_num_entities().num_services for wt, _ in waitables)
        self._wait_set = _rclpy.WaitSet(n_wait_subs, n_wait_gcs, n_wait_tmrs, n_wait_clis, n_wait_srvs, n_events,
                                        self._context.handle)
        self._stack = stack
        self._subs, self._timers, self._rare, self._waitables = subs, timers, rare, waitables
        self._sub_handles, self._timer_handles, self._guard_handles = sub_h, tmr_h, gc_h
        self._service_handles, self._client_handles = srv_h, cli_h
        self._signature = sig

    # ------------------------------------------------------------------ spinning
    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait for work (at most ``timeout_sec``; None = forever) and run every ready callback once."""
        if self._is_shutdown:
            return
        self._run_tasks()
        self._refresh()
        ws = self._wait_set
        ws.clear_entities()
        for h in self._sub_handles:
            ws.add_subscription(h)
        for h in self._timer_handles:
            ws.add_timer(h)
        for h in self._guard_handles:
            ws.add_guard_condition(h)
        for h in self._service_handles:
            ws.add_service(h)
        for h in self._client_handles:
            ws.add_client(h)
        for wt, _ in self._waitables:
            wt.add_to_wait_set(ws)
        timeout_ns = -1 if timeout_sec is None or timeout_sec < 0 else int(timeout_sec * NS_PER_S)
        ws.wait(timeout_ns)
        if self._is_shutdown:
            return
        if not self._context.ok():
            raise ExternalShutdownException()
        ready_waitables = [(wt, node) for wt, node in self._waitables if wt.is_ready(ws)]
        for ptr in ws.get_ready_entities("timer"):
            entry = self._timers.get(ptr)
            if entry is not None and entry[0].is_timer_ready():
                entry[0].call_timer()
                entry[1]()
        for ptr in ws.get_ready_entities("subscription"):
            entry = self._subs.get(ptr)
            if entry is None:
                continue
            handle, msg_type, raw, with_info, callback = entry
            for _ in range(MAX_TAKE_PER_WAKE):
                taken = handle.take_message(msg_type, raw)
                if taken is None:
                    break
                if with_info:
                    callback(taken[0], taken[1])
                else:
                    callback(taken[0])
        if self._rare:
            self._run_rare(ws)
        for wt, node in ready_waitables:
            self._run_handler(self._make_handler(wt, node, self._take_waitable))
        self._run_tasks()

    def _run_rare(self, ws: Any) -> None:
        """Services, clients and node guard conditions through rclpy's own handlers."""
        srv_ready = set(ws.get_ready_entities("service"))
        cli_ready = set(ws.get_ready_entities("client"))
        gc_ready = set(ws.get_ready_entities("guard_condition"))
        for kind, entity, node in self._rare:
            ptr = entity.handle.pointer
            if kind == "service" and ptr in srv_ready:
                self._run_handler(self._make_handler(entity, node, self._take_service))
            elif kind == "client" and ptr in cli_ready:
                self._run_handler(self._make_handler(entity, node, self._take_client))
            elif kind == "guard" and ptr in gc_ready:
                entity._executor_triggered = True
                self._run_handler(self._make_handler(entity, node, self._take_guard_condition))

    def _run_handler(self, handler: Any) -> None:
        handler()
        if handler.exception() is not None:
            raise handler.exception()

    def _run_tasks(self) -> None:
        """Run the tasks of ``create_task`` (e.g. done-callbacks of futures bound to this executor)."""
        if not self._tasks:
            return
        with self._tasks_lock:
            tasks, self._tasks = self._tasks, []
        keep = []
        for entry in tasks:
            task = entry[0]
            if not task.executing() and not task.done():
                task()
            if not task.done() and not task.cancelled():
                keep.append(entry)
            elif task.exception() is not None:
                raise task.exception()
        if keep:
            with self._tasks_lock:
                self._tasks = keep + self._tasks

    def spin_once_until_future_complete(self, future: Any, timeout_sec: Any = None) -> None:  # noqa: D102
        self.spin_once(getattr(timeout_sec, "timeout", timeout_sec))

    def spin_until_future_complete(self, future: Any, timeout_sec: float | None = None) -> None:
        """Spin until ``future`` is done, rclpy shuts down, or ``timeout_sec`` passes (None = no limit)."""
        future.add_done_callback(lambda _f: self.wake())
        end = None if timeout_sec is None or timeout_sec < 0 else time.monotonic() + timeout_sec
        while self._context.ok() and not future.done() and not future.cancelled() and not self._is_shutdown:
            left = None
            if end is not None:
                left = end - time.monotonic()
                if left <= 0:
                    return
            self.spin_once(left)

    def spin(self) -> None:
        """Spin until rclpy shuts down or :meth:`shutdown` is called."""
        while self._context.ok() and not self._is_shutdown:
            self.spin_once()

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Release the entered handles, then rclpy's shutdown of the executor."""
        self._release()
        return super().shutdown(timeout_sec)
