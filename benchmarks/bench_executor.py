"""rclpy's executors next to the simulator, per time scale: the MultiThreadedExecutor busy loop and its fix.

A minimal student-like node (one ``/turtle1/pose`` subscription, optionally a 30 Hz
``create_rate`` like the lab's action server) spins next to the reference simulator for a few
seconds; its CPU share (CPU seconds per wall second, from /proc) is measured with rclpy's
SingleThreadedExecutor and MultiThreadedExecutor, at 1x and on simulated time (``--time-scale``
2 and 4: the simulator publishes ``/clock`` every tick and the node runs with ``use_sim_time``),
side by side in one run. With ``--lab3`` also the Lab 3 reference action server itself.

Measured on the 2-core development machine, quiet (load 0.5), rclpy 7.1.6 from the Jazzy wheels
as the wheel ships it (ranges over three runs):

```
executor   node               1x          2x     4x   (CPU s per s, idle next to the simulator)
single     pose              0.03-0.04   0.06-0.09  -
multi      pose              0.05-0.08   1.02-1.03  -
multi      pose + rate       0.08-1.02   1.01-1.02  -
lab 3 action server          0.07-0.08   1.01-1.02  1.02-1.03
```

The MultiThreadedExecutor took a whole core as soon as ``/clock`` arrived, whatever the scale
(and, with a rate timer, now and then at 1x too: a state it tips into and stays in): its spin
thread yielded the same subscription tasks again before a worker thread had started them, and
while a task waited its reader still had data, so the wait set woke at once with nothing to hand
out. This is ros2/rclpy issue 1452, fixed upstream after this wheel (pull request 1547).
``make bootstrap`` and ``grader setup`` now fix it in the grader's venv (``grader/rclpy_fix.py``);
the same machine, with the fix (2026-12-01):

```
executor   node               1x     2x     4x
single     pose              0.04   0.09     -
multi      pose              0.05   0.13     -
multi      pose + rate       0.06   0.13     -
lab 3 action server          0.07   0.14   0.24
```

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_executor.py [--seconds S] [--lab3]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from grader.testing.executor_load import NODE, share  # noqa: E402

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
