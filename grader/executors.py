"""The rclpy executor every long-running grader node uses (simulator, scenario driver), and the
bounded spin (:func:`spin_until`) the bag tools, the tests and the benchmarks wait with.

rclpy's EventsExecutor (C++, Jazzy "experimental") costs a fraction of the CPU of the Python
executors, which rebuild their wait set on every wake; on a 2-core machine that margin keeps the
simulator's 16 ms cadence and leaves the CPU to the student's nodes. ``kind="single"`` (or an
rclpy without EventsExecutor) falls back to the SingleThreadedExecutor.
"""

from __future__ import annotations

import time
from typing import Any, Callable


def make_executor(context: Any, kind: str = "events") -> Any:
    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor  # noqa: PLC0415 - rclpy.experimental: ROS, imported where it is used (this module loads in processes that never use it)
        except ImportError:
            pass
        else:
            return EventsExecutor(context=context)
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415 - rclpy.executors: ROS, imported where it is used (this module loads in processes that never use it)

    return SingleThreadedExecutor(context=context)


def spin_until(executor: Any, predicate: Callable[[], bool], timeout: float, step: float = 0.02) -> bool:
    """Spin until ``predicate()`` is true or ``timeout`` seconds pass; returns the predicate."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=step)
    return predicate()
