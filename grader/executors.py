"""The rclpy executor every long-running grader node uses (simulator, scenario driver).

rclpy's EventsExecutor (C++, Jazzy "experimental") costs a fraction of the CPU of the Python
executors, which rebuild their wait set on every wake; on a 2-core machine that margin keeps the
simulator's 16 ms cadence and leaves the CPU to the student's nodes. ``kind="single"`` (or an
rclpy without EventsExecutor) falls back to the SingleThreadedExecutor.
"""

from __future__ import annotations

from typing import Any


def make_executor(context: Any, kind: str = "events") -> Any:
    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            pass
        else:
            return EventsExecutor(context=context)
    from rclpy.executors import SingleThreadedExecutor

    return SingleThreadedExecutor(context=context)
