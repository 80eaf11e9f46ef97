"""In-process rclpy helpers for tests and the scenario driver: own context, bounded spinning."""

from __future__ import annotations

import contextlib
from typing import Iterator

from grader.executors import spin_until  # noqa: F401 - the tests' and benchmarks' name for it


@contextlib.contextmanager
def rclpy_node(domain_id: int, name: str = "test_client") -> Iterator[tuple]:
    """Yield ``(node, executor)`` on ``domain_id`` with a private rclpy Context.

    A private context (not ``rclpy.init()``) lets one test process talk to several isolated
    graphs and never leaks global state between tests.
    """
    import rclpy  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    node = rclpy.create_node(name, context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


