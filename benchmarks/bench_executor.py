"""Why Lab 3's action scenario stays at 1x: rclpy's executors next to the simulator, per time scale.

A minimal student-like node (one ``/turtle1/pose`` subscription, optionally a 30 Hz
``create_rate`` like the lab's action server) spins next to the reference simulator for a few
seconds; its CPU share (CPU seconds per wall second, from /proc) is measured with rclpy's
SingleThreadedExecutor and MultiThreadedExecutor, at 1x and on simulated time (``--time-scale``
2 and 4: the simulator publishes ``/clock`` every tick and the node runs with ``use_sim_time``),
side by side in one run. With ``--lab3`` also the Lab 3 reference action server itself.

Measured on the 2-core development machine, quiet (load 0.5), rclpy 7.1.6 from the Jazzy wheels
(ranges over three runs):

```
executor   node               1x          2x     4x   (CPU s per s, idle next to the simulator)
single     pose              0.03-0.04   0.06-0.09  -
multi      pose              0.05-0.08   1.02-1.03  -
multi      pose + rate       0.08-1.02   1.01-1.02  -
lab 3 action server          0.07-0.08   1.01-1.02  1.02-1.03
```

The MultiThreadedExecutor takes a whole core as soon as ``/clock`` arrives, whatever the scale
(and, with a rate timer, now and then at 1x too: a state it tips into and stays in):
its spin thread yields the same subscription tasks again before a worker thread has started them
(counted: 100-4,000 queued copies of the same two tasks) and rescans its list of futures on every
spin (profile: 16.7 million ``Task.done`` calls in 8 s). This is ros2/rclpy issue 1452, fixed
upstream after this wheel (pull request 1547). A node busy for a core cannot keep pace with
simulated time (the watchdog's ``BUSY_SHARE``), so Lab 3's ``ex3_action`` is ``real_time: true``.
On a machine whose rclpy has the fix, this script shows it: the ``multi`` rows stay near the
``single`` ones, and the pin can be lifted.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_executor.py [--seconds S] [--lab3]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import textwrap
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from grader.runner import ProcessSpec, RosGraph  # noqa: E402
from grader.sim import sim_argv  # noqa: E402

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


def share(argv: list[str], scale: float, seconds: float, prefixes: list[Path] = ()) -> float:
    """CPU share of the process ``argv`` idling next to the simulator at ``scale``."""
    with tempfile.TemporaryDirectory(prefix="bench-executor-") as tmp, RosGraph(Path(tmp), prefixes=prefixes) as graph:
        sim_scale = scale if scale > 1 else None
        graph.start(ProcessSpec("turtlesim", sim_argv(time_scale=sim_scale)))
        time.sleep(1.5)
        sim_args = ["--ros-args", "-p", "use_sim_time:=true"] if scale > 1 else []
        node = graph.start(ProcessSpec("node", [*argv, *sim_args], untrusted=True))   # a student's node
        time.sleep(3.0)         # start-up and discovery are not what is measured
        c0, t0 = cpu_seconds(node.pid), time.monotonic()
        time.sleep(seconds)
        return (cpu_seconds(node.pid) - c0) / (time.monotonic() - t0)


def lab3_server() -> tuple[list[str], list[Path]]:
    from grader.workspace.build import build_workspace

    build = build_workspace(REPO / "fixtures" / "submissions" / "enee467_lab3" / "reference",
                            cache_dir=Path(tempfile.gettempdir()) / "bench-executor-cache")
    return build.argv("turtle_controller_server", "turtle_controller_server_node"), build.prefixes()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=6.0, help="measured window per row")
    ap.add_argument("--lab3", action="store_true", help="also the Lab 3 reference action server (builds it)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {'/'.join(f'{x:.1f}' for x in os.getloadavg())}")
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(NODE)
    rows = [("single", "pose", [sys.executable, f.name, "single", "-"], [], (1.0, 2.0)),
            ("multi", "pose", [sys.executable, f.name, "multi", "-"], [], (1.0, 2.0)),
            ("multi", "pose + rate", [sys.executable, f.name, "multi", "rate"], [], (1.0, 2.0))]
    if args.lab3:
        argv, prefixes = lab3_server()
        rows.append(("lab 3", "action server", argv, prefixes, (1.0, 2.0, 4.0)))
    print(f"{'executor':10s} {'node':18s} {'1x':>6s} {'2x':>6s} {'4x':>6s}   (CPU s per s, idle next to the simulator)")
    try:
        for kind, what, argv, prefixes, scales in rows:
            got = {s: share(argv, s, args.seconds, prefixes) for s in scales}
            cells = " ".join(f"{got[s]:6.2f}" if s in got else f"{'-':>6s}" for s in (1.0, 2.0, 4.0))
            print(f"{kind:10s} {what:18s} {cells}", flush=True)
    finally:
        os.unlink(f.name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
