"""LeanExecutor: timers, subscriptions (drained), late entities, services, futures, shutdown, in one process."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import pytest
from waits import BUDGET_S, Deadline

rclpy = pytest.importorskip("rclpy")

from rclpy.node import Node  # noqa: E402
from rclpy.task import Future  # noqa: E402
from std_msgs.msg import UInt32  # noqa: E402

from comems4build_ros.ros.executor import LeanExecutor  # noqa: E402
from comems4build_ros.ros.process import EXECUTOR_ENV, make_executor  # noqa: E402

pytestmark = pytest.mark.ros


@pytest.fixture()
def context() -> Iterator[object]:
    from comems4build_ros.run.supervisor import acquire_domain_id

    with acquire_domain_id() as did:
        os.environ["ROS_DOMAIN_ID"] = str(did)
        ctx = rclpy.Context()
        rclpy.init(context=ctx)
        try:
            yield ctx
        finally:
            rclpy.try_shutdown(context=ctx)


def test_timer_subscription_and_future(context: object) -> None:
    ex = LeanExecutor(context=context)
    node = Node("lean_a", context=context)
    ex.add_node(node)
    got: list[int] = []
    pub = node.create_publisher(UInt32, "x", 100)
    node.create_subscription(UInt32, "x", lambda m: got.append(m.data), 100)
    sent = [0]

    def tick() -> None:
        for _ in range(5):  # bursts: the executor drains them in one wake-up
            sent[0] += 1
            pub.publish(UInt32(data=sent[0]))

    node.create_timer(0.01, tick)  # created after add_node: picked up by the entity refresh
    done = Future()
    node.create_timer(0.05, lambda: done.set_result(1) if len(got) >= 50 and not done.done() else None)
    ex.spin_until_future_complete(done, timeout_sec=BUDGET_S)
    assert done.done() and done.result() == 1
    assert got[:50] == list(range(1, 51))  # in order, none lost
    t0 = time.monotonic()
    ex.spin_until_future_complete(Future(), timeout_sec=0.2)  # a future never done: returns after the timeout
    assert 0.15 < time.monotonic() - t0 < BUDGET_S
    ex.shutdown()
    node.destroy_node()


def test_parameter_service_answers(context: object) -> None:
    from rcl_interfaces.srv import ListParameters

    ex = LeanExecutor(context=context)
    server = Node("lean_server", context=context, parameter_overrides=[rclpy.parameter.Parameter("p", value=3)],
                  automatically_declare_parameters_from_overrides=True)
    client_node = Node("lean_client", context=context)
    ex.add_node(server)
    ex.add_node(client_node)
    cli = client_node.create_client(ListParameters, "/lean_server/list_parameters")
    deadline = Deadline("the parameter service discovered")
    while not cli.service_is_ready() and not deadline.passed():
        ex.spin_once(0.05)
    future = cli.call_async(ListParameters.Request())
    ex.spin_until_future_complete(future, timeout_sec=BUDGET_S)
    assert "p" in future.result().result.names
    ex.shutdown()
    server.destroy_node()
    client_node.destroy_node()


def test_shutdown_of_rclpy_ends_spin(context: object) -> None:
    """rclpy shut down (what SIGTERM does) while spinning: spin ends, as with rclpy's executors."""
    ex = LeanExecutor(context=context)
    node = Node("lean_b", context=context)
    ex.add_node(node)
    node.create_timer(0.05, lambda: rclpy.try_shutdown(context=context))
    t0 = time.monotonic()
    ex.spin()  # the timer's shutdown ends the loop
    assert time.monotonic() - t0 < BUDGET_S
    ex.shutdown()
    node.destroy_node()


def test_make_executor_by_environment(monkeypatch: pytest.MonkeyPatch, context: object) -> None:
    monkeypatch.setenv(EXECUTOR_ENV, "bogus")
    with pytest.raises(ValueError, match="COMEMS4BUILD_EXECUTOR='bogus'.*lean, single"):
        make_executor()
