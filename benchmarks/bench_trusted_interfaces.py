"""The cost of the grader's own build of a student's interface packages
(``grader/workspace/trusted_interfaces.py``), side by side with the student's build it follows.

Builds, with an empty build cache, the goal-setter reference (``turtle_goal_interfaces``: one
service; ``turtle_goal``: Python) and then a second submission that differs from it in a Python
file only (a classmate with the same interface package: the trusted build is a cache hit). For
each jailed colcon run: wall time and the CPU its cgroup counted (``cpu_probe``'s hook). The Lab 3
reference shows the case where the student's interface package is the rubric's support package:
its build is taken from the support build, so no trusted rebuild happens at all.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_trusted_interfaces.py
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
PROBE = Path(__file__).resolve().parent / "cpu_probe"


def main() -> int:
    import grader.sandbox.oneshot as oneshot
    from grader.rubric.load import load_rubric
    from grader.workspace.build import build_support, build_workspace

    sys.path.insert(0, str(PROBE))
    from sitecustomize import jailed_cpu  # noqa: E402 - the probe's helper (inactive in this process)
    sys.path.remove(str(PROBE))
    runs: list[float] = []
    saved = oneshot._end
    oneshot._end = jailed_cpu(saved, runs.append)
    print(f"load average {os.getloadavg()[0]:.1f}")
    try:
        with tempfile.TemporaryDirectory(prefix="bench-trusted-") as tmp:
            tmp = Path(tmp)
            first = REPO / "fixtures" / "submissions" / "goal_setter" / "reference"
            second = tmp / "classmate"
            shutil.copytree(first, second)
            node = next(second.rglob("turtle_controller.py"))
            node.write_text(node.read_text() + "\n# a classmate's comment\n")
            cases = [("goal-setter reference (cold cache)", first, None),
                     ("classmate, same interface package", second, None),
                     ("Lab 3 reference (interfaces = support package)",
                      REPO / "fixtures" / "submissions" / "enee467_lab3" / "reference",
                      dict(load_rubric(REPO / "rubrics" / "enee467_lab3.yaml").support))]
            print(f"{'submission':50} {'student build':>22} {'trusted interface build':>26}")
            for label, sub, support in cases:
                if support:
                    build_support(support, tmp / "cache")       # as `grader gradescope-setup` does, not counted
                runs.clear()
                t0 = time.monotonic()
                result = build_workspace(sub, cache_dir=tmp / "cache", support=support)
                wall = time.monotonic() - t0
                trusted = result.interfaces
                student_cpu = runs[0] if runs else 0.0
                trusted_cpu = sum(runs[1:])
                print(f"{label:50} {result.duration_s:8.1f} s wall {student_cpu:5.1f} s CPU "
                      f"{trusted.duration_s:9.1f} s wall {trusted_cpu:5.1f} s CPU   "
                      f"({wall:.1f} s in all; trusted: {', '.join(sorted(trusted.prefixes)) or 'none'}"
                      f"{'; problems: ' + str(trusted.problems) if trusted.problems else ''})", flush=True)
    finally:
        oneshot._end = saved
    return 0


if __name__ == "__main__":
    sys.exit(main())
