"""What a repeated scenario costs (``repeat: N`` in a rubric), side by side in one run: the given
submissions graded with the rubric as it is and with every scenario's ``repeat`` set to 1,
alternating, each ``--no-reuse`` on a shared build cache. Prints each grading's wall time and the
runs each repeated scenario took (two when they agree), and whether every item came out the same.

    .venv/bin/python benchmarks/bench_repeat.py [--lab wall_pen] [--subs reference chapter] [--rounds 2] [--jobs 2] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

RUBRICS = {"enee467_lab3": "enee467_lab3.yaml", "goal_setter": "goal_setter.yaml", "wall_pen": "wall_pen.yaml",
           "first_nodes": "first_nodes.yaml"}


def main() -> int:
    from grader.grading.batch import grade_batch
    from grader.grading.schedule import Slots
    from grader.rubric import load_rubric

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lab", default="wall_pen", choices=sorted(RUBRICS))
    ap.add_argument("--subs", nargs="+", default=["reference", "chapter"])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--keep", type=Path, default=None, help="keep the outputs here")
    args = ap.parse_args()
    rubric = load_rubric(REPO / "rubrics" / RUBRICS[args.lab])
    once = rubric.model_copy(update={"scenarios": {k: v.model_copy(update={"repeat": 1})
                                                   for k, v in rubric.scenarios.items()}})
    subs = [REPO / "fixtures" / "submissions" / args.lab / s for s in args.subs]
    times: dict[str, list[float]] = {"as in the rubric": [], "repeat 1": []}
    outcomes: dict[str, set] = {}            # submission -> its items' outcomes, one per grading
    with tempfile.TemporaryDirectory(prefix="bench-repeat-") as scratch:
        tmp = str(args.keep or scratch)
        for k in range(args.rounds):
            for mode, rub in (("as in the rubric", rubric), ("repeat 1", once)):
                out = Path(tmp) / f"{mode.replace(' ', '_')}{k}"
                t0 = time.monotonic()
                grade_batch(subs, rub, out, slots=Slots(args.jobs), cache_dir=Path(tmp) / "cache", reuse=False)
                wall = time.monotonic() - t0
                times[mode].append(wall)
                runs = []
                for res in sorted(out.glob("*/result.json")):
                    doc = json.loads(res.read_text())
                    for i in doc["items"]:
                        dec = i.get("decided") or {}
                        if dec.get("stable") is False:
                            print(f"    {res.parent.name} {i['id']}: runs "
                                  + ", ".join(f"{o['status']} {o.get('points')}" for o in dec["outcomes"]))
                    outcomes.setdefault(res.parent.name, set()).add(
                        tuple((i["id"], i["status"], i["points"]) for i in doc["items"] if i["kind"] != "manual"))
                    runs += [f"{res.parent.name}: {max((i.get('decided') or {}).get('runs', 1) for i in doc['items'])} run(s)"]
                print(f"round {k + 1} {mode:17s} wall {wall:6.1f} s  load {os.getloadavg()[0]:4.1f}  "
                      + ", ".join(runs), flush=True)
    for mode, walls in times.items():
        print(f"{mode:17s} median wall {statistics.median(walls):.1f} s over {len(walls)} grading(s)")
    a, b = (statistics.median(times[m]) for m in times)
    print(f"cost of repetition: {a / b:.2f}x the wall time of one run per scenario")
    same = all(len(v) == 1 for v in outcomes.values())
    for sub, seen in sorted(outcomes.items()):
        if len(seen) > 1:
            differ = sorted({o for one in seen for o in one} - set.intersection(*(set(one) for one in seen)))
            print(f"  {sub} differs across gradings: {differ}")
    print(f"every item the same in every grading of both modes: {same}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
