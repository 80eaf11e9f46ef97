"""Grading cost and determinism: grade the reference Lab 3 solution N times (default 5).

Prints, per run, the wall time of `grade_submission`, the sum of the scenarios' active durations
(the time the scenarios must take: turtle motion, replay pacing, waits), their ratio (overhead:
build cache, process start-up, discovery, bag finalization, analysis), and the score. The scores
must be identical in every run.

    .venv/bin/python benchmarks/bench_grade.py [N]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from grader.grading.pipeline import grade_submission  # noqa: E402
from grader.rubric.load import load_rubric  # noqa: E402


def main() -> int:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    sub = REPO / "fixtures" / "submissions" / "enee467_lab3" / "reference"
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-grade-") as tmp:
        for i in range(runs):
            t0 = time.monotonic()
            graded = grade_submission(sub, rubric, Path(tmp) / f"run{i}", cache_dir=Path(tmp) / "cache")
            wall = time.monotonic() - t0
            active = sum(v for k, v in graded.timings.items() if k.endswith(":active_s"))
            items = tuple((it.id, it.points, it.status) for it in graded.result.items)
            rows.append((wall, active, graded.result.auto_score, items, graded.timings.get("build_s", 0)))
            print(f"run {i + 1}: wall {wall:6.1f} s  active {active:6.1f} s  ratio {wall / active:4.2f}  "
                  f"build {rows[-1][4]:5.1f} s  score {graded.result.auto_score:g}/{graded.result.auto_max:g}",
                  flush=True)
    walls = [r[0] for r in rows]
    ratios = [r[0] / r[1] for r in rows]
    print(f"\nwall: median {statistics.median(walls):.1f} s (min {min(walls):.1f}, max {max(walls):.1f}); "
          f"overhead ratio wall/active: median {statistics.median(ratios):.2f} (target < 1.5); "
          f"first run includes the colcon build")
    same = len({r[3] for r in rows}) == 1
    print(f"scores: {sorted({r[2] for r in rows})}; item results identical in all runs: {same}")
    if not same:
        for idx in range(len(rows[0][3])):
            seen = {r[3][idx] for r in rows}
            if len(seen) > 1:
                print(f"  differs: {sorted(map(str, seen))}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
