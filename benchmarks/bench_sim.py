"""Benchmark of the reference turtlesim: pose rate / interval jitter and CPU per turtle.

Measures like ``ros2 topic hz``: receive times of ``/<turtle>/pose`` in a subscriber, over a
window of >= 10 s, reporting the mean rate and min/max/std of the intervals.  CPU use of the
simulator process comes from ``/proc/<pid>/stat`` (utime + stime) over the same window.
Runs the simulator with 1 and with 20 turtles; total runtime is about 40 s.

    .venv/bin/python benchmarks/bench_sim.py [--window 10] [--turtles 1 20]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from grader.runner import ProcessSpec, RosGraph  # noqa: E402
from grader.sim import sim_argv  # noqa: E402
from grader.testing.ros import rclpy_node, spin_until  # noqa: E402

TARGET_HZ = 62.5


@dataclass
class Result:
    turtles: int
    topic: str
    count: int
    rate: float
    imin: float
    imax: float
    istd: float
    cpu_pct: float


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process (all its threads) in seconds, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    ticks = int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)
    return ticks / os.sysconf("SC_CLK_TCK")


def measure(n_turtles: int, window: float, workdir: Path) -> list[Result]:
    """Start a sim, spawn up to ``n_turtles``, measure pose intervals and sim CPU."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from turtlesim.msg import Pose
    from turtlesim.srv import Spawn

    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                     reliability=ReliabilityPolicy.RELIABLE)
    with RosGraph(workdir / f"bench{n_turtles}") as graph:
        sim = graph.start(ProcessSpec(name="sim", argv=sim_argv()))
        with rclpy_node(graph.domain_id, "bench_sim") as (node, executor):
            client = node.create_client(Spawn, "/spawn")
            assert spin_until(executor, client.service_is_ready, 20.0), "sim did not start"
            names = ["turtle1"]
            for i in range(1, n_turtles):
                fut = client.call_async(Spawn.Request(x=1.0 + (i % 5) * 2.0,
                                                      y=1.0 + (i // 5) * 2.0, name=""))
                assert spin_until(executor, fut.done, 10.0)
                names.append(fut.result().name)
            # like `ros2 topic hz`: the first and the last turtle in update order
            topics = sorted({names[0], sorted(names)[-1]})
            stamps: dict[str, list[float]] = {t: [] for t in topics}
            for t in topics:
                node.create_subscription(Pose, f"/{t}/pose",
                                         lambda _m, s=stamps[t]: s.append(time.monotonic()), qos)
            assert spin_until(executor, lambda: all(len(s) > 10 for s in stamps.values()), 10.0)
            spin_until(executor, lambda: False, 1.0)  # warm-up
            for s in stamps.values():
                s.clear()
            cpu0, wall0 = cpu_seconds(sim.pid), time.monotonic()
            spin_until(executor, lambda: False, window, step=0.005)
            cpu1, wall1 = cpu_seconds(sim.pid), time.monotonic()
        sim.stop()
    cpu_pct = 100.0 * (cpu1 - cpu0) / (wall1 - wall0)
    results = []
    for t in topics:
        iv = np.diff(np.asarray(stamps[t]))
        results.append(Result(n_turtles, f"/{t}/pose", len(stamps[t]), 1.0 / iv.mean(),
                              iv.min(), iv.max(), iv.std(), cpu_pct))
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--window", type=float, default=10.0, help="seconds per measurement")
    parser.add_argument("--turtles", type=int, nargs="+", default=[1, 20])
    args = parser.parse_args(argv)
    rows: list[Result] = []
    with tempfile.TemporaryDirectory(prefix="bench_sim_") as tmp:
        for n in args.turtles:
            rows.extend(measure(n, args.window, Path(tmp)))
    print(f"\nturtlesim pose rate over {args.window:.0f} s windows (target {TARGET_HZ} Hz)")
    header = (f"{'turtles':>7} {'topic':<16} {'msgs':>5} {'rate Hz':>8} {'min s':>7} "
              f"{'max s':>7} {'std s':>8} {'sim CPU %':>9} {'CPU %/turtle':>12}")
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{r.turtles:>7} {r.topic:<16} {r.count:>5} {r.rate:>8.3f} {r.imin:>7.4f} "
              f"{r.imax:>7.4f} {r.istd:>8.5f} {r.cpu_pct:>9.1f} {r.cpu_pct / r.turtles:>12.2f}")
    by_n = {r.turtles: r.cpu_pct for r in rows}
    if len(by_n) >= 2:
        lo, hi = min(by_n), max(by_n)
        print(f"marginal CPU per added turtle: {(by_n[hi] - by_n[lo]) / (hi - lo):.2f} %")
    ok = all(abs(r.rate - TARGET_HZ) <= 0.5 for r in rows)
    print("rate within 62.5 +- 0.5 Hz:", "yes" if ok else "NO")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
