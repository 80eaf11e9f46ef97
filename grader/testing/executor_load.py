"""A student-like node idling next to the reference simulator, and its CPU share: how rclpy's
executors behave there (``benchmarks/bench_executor.py`` and the executor test).

``NODE`` has one ``/turtle1/pose`` subscription and optionally a 30 Hz ``create_rate`` like the
Lab 3 action server's, spun by a SingleThreadedExecutor or a four-thread MultiThreadedExecutor
(``argv``: ``single|multi`` and ``rate|-``).
"""

from __future__ import annotations

import os
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Sequence

from grader.runner import ProcessSpec, RosGraph
from grader.sim import sim_argv

NODE = textwrap.dedent("""
    import sys
    import rclpy
    from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
    from rclpy.node import Node
    from turtlesim.msg import Pose

    executor_kind, with_rate = sys.argv[1], sys.argv[2] == "rate"
    rclpy.init(args=sys.argv)
    node = Node("bench_executor")
    node.create_subscription(Pose, "/turtle1/pose", lambda msg: None, 10)
    if with_rate:
        rate = node.create_rate(30.0, node.get_clock())
    executor = MultiThreadedExecutor(num_threads=4) if executor_kind == "multi" else SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
""")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def share(argv: list[str], scale: float, seconds: float, prefixes: Sequence[Path] = ()) -> float:
    """CPU share of the process ``argv`` idling next to the simulator at ``scale``."""
    with tempfile.TemporaryDirectory(prefix="bench-executor-") as tmp, RosGraph(Path(tmp), prefixes=list(prefixes)) as graph:
        sim_scale = scale if scale > 1 else None
        graph.start(ProcessSpec("turtlesim", sim_argv(time_scale=sim_scale)))
        time.sleep(1.5)
        sim_args = ["--ros-args", "-p", "use_sim_time:=true"] if scale > 1 else []
        node = graph.start(ProcessSpec("node", [*argv, *sim_args], untrusted=True))   # a student's node
        time.sleep(3.0)         # start-up and discovery are not what is measured
        c0, t0 = cpu_seconds(node.pid), time.monotonic()
        time.sleep(seconds)
        return (cpu_seconds(node.pid) - c0) / (time.monotonic() - t0)


