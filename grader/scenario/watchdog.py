"""Is a faster-than-real-time run still faithful? The run-time signals that send it back to 1x.

ROS timers and ``create_rate`` follow ``/clock``; ``time.sleep`` and ``time.time`` do not. A node
that paces itself with the wall clock publishes K times too slowly in simulated time, and its
grade would change with the speed. The static scan (:mod:`grader.grading.timescale`) finds the
usual ways to do that before the run; at run time this watchdog compares each rate the rubric
expects (``ScenarioRun.expected_rates``) with the student's messages, timed both ways:

* the rate in simulated time is off by more than the expectation's tolerance, **and**
* the rate in wall time is closer to the expectation (in ratio) than the simulated one.

A node that is simply wrong (10 Hz instead of 1 Hz on its ROS timer) is as wrong at 1x, fails
the first test's partner and keeps its fast run; one paced by the wall clock matches in wall
time and is sent back. A second signal: anyone but the grader's clock publishing ``/clock``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

from grader.scenario.model import RateExpectation
from grader.sim.clock import CLOCK_TOPIC

#: intervals needed before a rate is judged
MIN_INTERVALS = 4


def rate(times: list[float]) -> float:
    """Messages per second over the span of ``times`` (nan with fewer than two)."""
    if len(times) < 2 or times[-1] <= times[0]:
        return float("nan")
    return (len(times) - 1) / (times[-1] - times[0])


def wall_paced(expect: RateExpectation, sim_times: list[float], wall_times: list[float]) -> str | None:
    """Why the topic looks paced by the wall clock, or None (see the module docstring)."""
    if len(sim_times) < MIN_INTERVALS + 1:
        return None
    r_sim, r_wall = rate(sim_times), rate(wall_times)
    if not (math.isfinite(r_sim) and math.isfinite(r_wall)):
        return None
    off_sim = abs(math.log(r_sim / expect.expected_hz))
    off_wall = abs(math.log(r_wall / expect.expected_hz))
    if abs(r_sim / expect.expected_hz - 1.0) > expect.rel_tol and off_wall < off_sim:
        return (f"{expect.topic} was published at {r_sim:.3g} Hz in simulated time but {r_wall:.3g} Hz "
                f"in wall time (expected {expect.expected_hz:g} Hz): the node paces itself with the "
                "wall clock")
    return None


@dataclass
class RateWatchdog:
    """Arrival times (simulated and wall) of the watched topics, fed by the driver."""

    expected: tuple[RateExpectation, ...]
    clock_owner: str
    arrivals: dict[str, tuple[list[float], list[float]]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.arrivals = {e.topic: ([], []) for e in self.expected}

    def arrived(self, topic: str, sim_s: float) -> None:
        lists = self.arrivals.get(topic)
        if lists is not None and sim_s > 0:
            lists[0].append(sim_s)
            lists[1].append(time.monotonic())

    def verdict(self, node: Any = None) -> str | None:
        """The first reason to rerun at 1x, or None. ``node``: an rclpy node to ask who
        publishes ``/clock``."""
        if node is not None:
            try:
                others = sorted({i.node_name for i in node.get_publishers_info_by_topic(CLOCK_TOPIC)}
                                - {self.clock_owner})
            except Exception:  # noqa: BLE001 - graph queries can race with shutdown
                others = []
            if others:
                return f"{', '.join(others)} published {CLOCK_TOPIC}, which only the grader's clock may"
        for expect in self.expected:
            sim_times, wall_times = self.arrivals[expect.topic]
            reason = wall_paced(expect, sim_times, wall_times)
            if reason:
                return reason
        return None
