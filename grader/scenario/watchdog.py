"""Is a faster-than-real-time run still faithful? The run-time signals that send it back to 1x.

ROS timers and ``create_rate`` follow ``/clock``; ``time.sleep``, ``time.time`` and the timeout
of ``spin_once`` do not. A node paced by the wall clock publishes K times too slowly in
simulated time (or, woken by every ``/clock``, far too fast), and its grade would change with
the speed. The static scan (:mod:`grader.grading.timescale`) finds the usual ways before the
run; at run time this watchdog checks every rate the rubric expects
(``ScenarioRun.expected_rates``, from its ``publish_rate`` items) in simulated time, with pauses
(intervals over ``GAP_FACTOR`` expected periods, e.g. between two goals) left out. The arrival
times are the driver's, so delivery in bursts on a busy machine averages out; the analyzer later
measures the recorded times.

* measured: off by more than the expectation's tolerance (the item's partial-credit band);
* too few messages: a student node advertises the topic, yet fewer than two messages arrived
  in ``QUIET_PERIODS`` expected periods of simulated time.

Either one sends the scenario back to 1x. A node that is simply wrong (10 Hz instead of 1 Hz)
is then graded at 1x too, which only costs time: the grade is never taken from a run that might
differ from 1x. Two more signals: anyone but the grader's clock publishing ``/clock``, and a
student process busy for ``BUSY_SHARE`` of a CPU core or more since its node came up (or, on a
loaded machine where it cannot get that, with a thread running or waiting for a CPU
``RUNNABLE_SHARE`` of the time): at K x it
handles K times the messages per wall second (every ``/clock`` included), and a process near a
full core falls behind simulated time. Measured on Lab 3's action server (rclpy's
MultiThreadedExecutor with ``Rate.sleep`` in its execute callback): 53-102 % of a core at 4x
(its 30 Hz control loop at 3-20 Hz of simulated time, gaps over 1 s); the Lab 3 controller and
subscriber nodes: 31-35 %. Any node on rclpy 7.1.6's MultiThreadedExecutor takes a whole core
once ``/clock`` arrives (ros2/rclpy issue 1452; ``benchmarks/bench_executor.py``: 1.01-1.03 CPU
s/s idle at 2x against 0.06-0.09 on the SingleThreadedExecutor): the static scan
(:data:`grader.grading.timescale.BUSY_ON_SIM_TIME`) keeps such a scenario at 1x before it starts,
since this signal, read between steps, can miss a short one.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from typing import Any

from grader.scenario.runspec import RateExpectation
from grader.sim.clock import CLOCK_TOPIC

#: intervals longer than this many expected periods are pauses, not the rate
GAP_FACTOR = 5.0
#: expected periods a published topic may stay silent before that alone is a signal
QUIET_PERIODS = 4.0
#: share of a CPU core a student process may use (averaged over at least BUSY_WINDOW_S of wall
#: time since its node came up) before it counts as unable to keep pace
BUSY_SHARE = 0.75
#: ... or the share of the time one of its threads was running or ready to run (waiting on a run
#: queue): a busy loop on a loaded machine gets half a core or less and waits for the rest (the
#: test's loop beside a test session, load ~4 on 2 cores: 0.4-0.6 of a core, runnable ~1.0 of the
#: time), where a node that waits for its timers sleeps between them. Per thread, not summed: the
#: Lab 3 subscriber at 4x (31-39 % of a core, 14 threads) had its busiest thread runnable 0.51-0.70
#: of the time at load 2.3-6.2, its threads summed 0.72-0.93, and 1.13 in a CI run, which sent it
#: back to 1x for nothing (the simulator waits ~0.1 of its time at load 20,
#: :mod:`grader.scenario.cpuwait`)
RUNNABLE_SHARE = 0.9
BUSY_WINDOW_S = 2.0


def tree_times(pids: dict[str, int]) -> dict[str, tuple[float, dict[int, float]]]:
    """Per named process and all its descendants (a sandbox's wrapper and the node inside count
    as one; the tree the lockstep quiet checks wait for, :func:`quiescence.descendants`), read
    from /proc: CPU seconds (user + system, reaped children included) and, per live thread
    (``tid``), runnable seconds (on a CPU or waiting for one: ``schedstat``); per thread, since
    summed they overstate a DDS node's wait (:data:`RUNNABLE_SHARE`)."""
    from grader.scenario.cpuwait import thread_schedstat  # noqa: PLC0415 - scenario.watchdog loads in every scenario child process; scenario.cpuwait only on this path
    from grader.scenario.quiescence import descendants  # noqa: PLC0415 - scenario.watchdog loads in every scenario child process; scenario.quiescence only on this path

    tick = os.sysconf("SC_CLK_TCK")
    out = {}
    for name, root in pids.items():
        total = 0.0
        runnable: dict[int, float] = {}
        for pid in descendants([root]):
            try:
                with open(f"/proc/{pid}/stat") as f:
                    stat = f.read()
            except OSError:                  # exited meanwhile
                continue
            total += sum(int(v) for v in stat[stat.rindex(")") + 2:].split()[11:15]) / tick
            for tid, (on_cpu, waiting) in thread_schedstat(pid).items():
                runnable[tid] = (on_cpu + waiting) / 1e9
        out[name] = (total, runnable)
    return out


def rate(times: list[float], max_gap: float) -> float:
    """Messages per second: 1 / mean interval, intervals over ``max_gap`` left out (0 when every
    interval is one); nan with fewer than two messages."""
    gaps = [b - a for a, b in zip(times, times[1:])]
    if not gaps:
        return float("nan")
    kept = [g for g in gaps if g <= max_gap]
    if not kept:
        return 0.0
    mean = sum(kept) / len(kept)
    return 1.0 / mean if mean > 0 else float("inf")


def off_rate(expect: RateExpectation, sim_times: list[float], wall_times: list[float]) -> str | None:
    """Why the measured rate would not grade like 1x, or None."""
    max_gap = GAP_FACTOR / expect.expected_hz
    r_sim = rate(sim_times, max_gap)
    if r_sim != r_sim or abs(r_sim / expect.expected_hz - 1.0) <= expect.rel_tol:
        return None
    r_wall = rate(wall_times, max_gap)
    return (f"{expect.topic} was published at {_hz(r_sim)} of simulated time ({_hz(r_wall)} of wall "
            f"time) where {expect.expected_hz:g} Hz is expected: not paced by the ROS clock alone")


def _hz(value: float) -> str:
    return f"{value:.3g} Hz" if value != float("inf") else "several messages per clock tick"


@dataclass
class RateWatchdog:
    """Arrival times (simulated and wall) of the watched topics, fed by the driver."""

    expected: tuple[RateExpectation, ...]
    clock_owner: str
    arrivals: dict[str, tuple[list[float], list[float]]] = field(default_factory=dict)
    advertised_at: dict[str, float] = field(default_factory=dict)   # sim time a student publisher was seen
    #: process -> (cpu s, runnable s per thread, wall s) when first seen
    cpu_base: dict[str, tuple[float, dict[int, float], float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.arrivals = {e.topic: ([], []) for e in self.expected}

    def arrived(self, topic: str, sim_s: float) -> None:
        lists = self.arrivals.get(topic)
        if lists is not None and sim_s > 0:
            lists[0].append(sim_s)
            lists[1].append(time.monotonic())

    def busy(self, pids: dict[str, int]) -> str | None:
        """A student process (``name -> pid`` of those running) that used ``BUSY_SHARE`` of a
        core, or had a thread runnable ``RUNNABLE_SHARE`` of the time, since the first call that
        saw it (its node was up by then; a thread started since counts from its start)."""
        now = time.monotonic()
        for name, (cpu, runnable) in tree_times(pids).items():
            base = self.cpu_base.setdefault(name, (cpu, runnable, now))
            wall = now - base[2]
            if wall < BUSY_WINDOW_S:
                continue
            used = (cpu - base[0]) / wall
            wanted = max((r - base[1].get(tid, 0.0) for tid, r in runnable.items()), default=0.0) / wall
            if used >= BUSY_SHARE:
                return (f"{name} used {100 * used:.0f} % of a CPU core for {wall:.1f} s: "
                        "a process that busy cannot keep pace with simulated time")
            if wanted >= RUNNABLE_SHARE:
                return (f"a thread of {name} was running or waiting for a CPU {100 * wanted:.0f} % of "
                        f"{wall:.1f} s ({100 * used:.0f} % of a core on this busy machine): a process "
                        "that busy cannot keep pace with simulated time at this speed")
        return None

    def verdict(self, node: Any, sim_now: float, student_publishes: Any = None) -> str | None:
        """The first reason to rerun at 1x, or None. ``node``: an rclpy node of the graph;
        ``student_publishes(topic)``: does a student node advertise it."""
        try:
            others = sorted({i.node_name for i in node.get_publishers_info_by_topic(CLOCK_TOPIC)}
                            - {self.clock_owner})
        except Exception:  # noqa: BLE001 - graph queries can race with shutdown
            others = []
        if others:
            return f"{', '.join(others)} published {CLOCK_TOPIC}, which only the grader's clock may"
        for expect in self.expected:
            sim_times, wall_times = self.arrivals[expect.topic]
            reason = off_rate(expect, sim_times, wall_times)
            if reason:
                return reason
            if len(sim_times) >= 2 or student_publishes is None:
                continue
            if expect.topic not in self.advertised_at:
                if student_publishes(expect.topic):
                    self.advertised_at[expect.topic] = sim_now
                continue
            quiet = sim_now - max([self.advertised_at[expect.topic], *sim_times])
            if quiet >= QUIET_PERIODS / expect.expected_hz:
                return (f"{expect.topic} is advertised but only {len(sim_times)} message(s) arrived in "
                        f"{quiet:.3g} s of simulated time where {expect.expected_hz:g} Hz is expected")
        return None
