"""No flaky points: grade the Lab 3 fixtures N times (default 3) with ``--jobs 3`` on this machine
(2 cores: more scenarios than cores, the load under which a lost action response once cost a
correct server 4 points) and print every item whose result differed between the runs. Target:
none. Every run grades everything (``--no-reuse``); the build cache is shared, so the runs differ
only in the scenarios.

    .venv/bin/python benchmarks/bench_flake.py [N] [--jobs J]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from grader.cli import main as grader_main  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("runs", type=int, nargs="?", default=3)
    ap.add_argument("--jobs", type=int, default=3)
    args = ap.parse_args()
    subs = REPO / "fixtures" / "submissions" / "enee467_lab3"
    seen: dict[tuple[str, str], list[tuple]] = defaultdict(list)
    with tempfile.TemporaryDirectory(prefix="bench-flake-") as tmp:
        for run in range(args.runs):
            out = Path(tmp) / f"run{run}"
            t0 = time.monotonic()
            rc = grader_main(["grade", str(subs), "--rubric", str(REPO / "rubrics" / "enee467_lab3.yaml"),
                              "-o", str(out), "--jobs", str(args.jobs), "--no-reuse",
                              "--cache-dir", str(Path(tmp) / "cache")])
            print(f"run {run + 1}: exit {rc} in {time.monotonic() - t0:.0f} s", flush=True)
            for result in sorted(out.glob("*/result.json")):
                doc = json.loads(result.read_text())
                for item in doc["items"]:
                    if item["kind"] != "manual":
                        seen[(result.parent.name, item["id"])].append((item["status"], item["points"]))
    differing = {k: v for k, v in seen.items() if len(set(v)) > 1}
    for (sub, item), values in sorted(differing.items()):
        print(f"DIFFERS {sub} {item}: " + " | ".join(f"{s} {p}" for s, p in values))
    print(f"{len(seen)} item results compared over {args.runs} runs: {len(differing)} differed")
    return 1 if differing else 0


if __name__ == "__main__":
    sys.exit(main())
