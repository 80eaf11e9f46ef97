"""Faster than real time: the reference self-check at 1x and at --time-scale 4, side by side.

For each run: wall time of the self-check (``grader check``'s ``grade_submission``: public items,
scenarios side by side within the default budget, no recording reused), the sum of its
scenarios' active time (step durations, in scenario time: the time the scenarios must take), their
ratio (target <= 0.25 at 4x; today's 1x is ~1.2 without parallel scenarios), the speed-up of
4x over 1x (target >= 3) and which scenarios ran at 4x. Runs alternate between the modes so a
changing machine load hits both alike. Every run's per-item results must be identical.

``--fixtures``: also every Lab 3 fixture in one ``grader grade`` batch at 1x and twice at 4x
(``--jobs 2``, no reuse): each submission's per-item (points, status) tuples must be identical in
all three batches, except items its expected.yaml lists with several outcomes (chaotic at 1x
too, e.g. no_wrap's turn direction: those must stay within the list), and match its
expected.yaml. Slow (~30 min on a busy 2-core machine).

    .venv/bin/python benchmarks/bench_timescale.py [N] [--fixtures]
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from grader.grading.pipeline import grade_submission  # noqa: E402
from grader.grading.schedule import Slots, default_jobs  # noqa: E402
from grader.rubric.load import load_rubric  # noqa: E402

LAB3 = REPO / "fixtures" / "submissions" / "enee467_lab3"
RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"


def items_of(result: dict | object) -> tuple:
    items = result["items"] if isinstance(result, dict) else [i.__dict__ for i in result.items]
    return tuple((i["id"], i["points"], i["status"]) for i in items)


def self_check(tmp: Path, scale: float, i: int) -> dict:
    rubric = load_rubric(RUBRIC)
    t0 = time.monotonic()
    graded = grade_submission(LAB3 / "reference", rubric, tmp / f"{scale:g}x-{i}", cache_dir=tmp / "cache",
                              public_only=True, sid="check", slots=Slots(default_jobs()), reuse=False,
                              time_scale=scale)
    wall = time.monotonic() - t0
    active = sum(v for k, v in graded.timings.items() if k.endswith(":active_s"))
    fast = sorted(sc for sc, ts in graded.time_scales.items() if float(ts.get("used", 1)) > 1)
    return {"wall": wall, "active": active, "items": items_of(graded.result), "fast": fast,
            "fallbacks": {sc: ts["fallback"] for sc, ts in graded.time_scales.items() if "fallback" in ts},
            "score": graded.result.auto_score}


def bench_self_check(runs: int) -> bool:
    rows: dict[float, list[dict]] = {1.0: [], 4.0: []}
    with tempfile.TemporaryDirectory(prefix="bench-timescale-") as tmp:
        self_check(Path(tmp), 1.0, -1)          # warm the build cache (not counted)
        for i in range(runs):
            for scale in (1.0, 4.0):
                row = self_check(Path(tmp), scale, i)
                rows[scale].append(row)
                print(f"run {i + 1} at {scale:g}x: wall {row['wall']:5.1f} s  active {row['active']:5.1f} s  "
                      f"ratio {row['wall'] / row['active']:4.2f}  at 4x: {len(row['fast'])} scenario(s)  "
                      f"score {row['score']:g}" + (f"  fallbacks {row['fallbacks']}" if row["fallbacks"] else ""),
                      flush=True)
    med = {s: statistics.median(r["wall"] for r in rows[s]) for s in rows}
    ratio = {s: statistics.median(r["wall"] / r["active"] for r in rows[s]) for s in rows}
    print(f"\nself-check wall: 1x median {med[1.0]:.1f} s, 4x median {med[4.0]:.1f} s: "
          f"{med[1.0] / med[4.0]:.2f}x faster (target >= 3)")
    print(f"wall / sum of scenario active time: 1x {ratio[1.0]:.2f}, 4x {ratio[4.0]:.2f} (target <= 0.25 at 4x)")
    same = len({r["items"] for s in rows for r in rows[s]}) == 1
    print(f"per-item results identical in every run of both modes: {same}")
    return same


def bench_fixtures() -> bool:
    from grader.cli import main as grader_main
    import yaml

    subs = sorted(p.name for p in LAB3.iterdir() if (p / "expected.yaml").exists())
    batches = {}
    with tempfile.TemporaryDirectory(prefix="bench-timescale-fx-") as tmp:
        for label, scale in (("1x", "1"), ("4x-a", "4"), ("4x-b", "4")):
            out = Path(tmp) / label
            t0 = time.monotonic()
            rc = grader_main(["grade", str(LAB3), "--rubric", str(RUBRIC), "-o", str(out), "--jobs", "2",
                              "--no-reuse", "--time-scale", scale, "--cache-dir", str(Path(tmp) / "cache")])
            wall = time.monotonic() - t0
            results = {s: json.loads((out / s / "result.json").read_text()) for s in subs}
            batches[label] = results
            fallbacks = {f"{s}/{sc}": ts.get("fallback", "")[:90] for s, r in results.items()
                         for sc, ts in (r.get("time_scale") or {}).items() if "fallback" in ts}
            print(f"batch {label}: exit {rc}, {wall:.0f} s for {len(subs)} submissions; scenarios back at 1x: "
                  f"{len(fallbacks)}", flush=True)
            for where, why in sorted(fallbacks.items()):
                print(f"    {where}: {why}")
    ok = True
    for s in subs:
        want = yaml.safe_load((LAB3 / s / "expected.yaml").read_text())["expected"]
        chaotic = {i for i, w in want.items() if isinstance(w, list)}
        tuples = {label: tuple(t for t in items_of(batches[label][s]) if t[0] not in chaotic) for label in batches}
        identical = len(set(tuples.values())) == 1
        wrong = []
        for label in batches:
            for item_id, _points, status in items_of(batches[label][s]):
                allowed = want.get(item_id)
                if allowed is None:
                    continue
                allowed = allowed if isinstance(allowed, list) else [allowed]
                allowed = {("fail" if a == "warn" else a) for a in allowed} | ({"partial"} if "warn" in allowed else set())
                if status not in allowed:
                    wrong.append(f"{label} {item_id}: {status} (expected {want[item_id]})")
        ok &= identical and not wrong
        print(f"  {s:18} identical 1x/4x/4x: {identical}" + (f" (chaotic at 1x too, within expected: "
                                                              f"{', '.join(sorted(chaotic))})" if chaotic else "")
              + (f"; not as expected: {wrong}" if wrong else ""))
        if not identical:
            for idx, row in enumerate(tuples["1x"]):
                seen = {label: tuples[label][idx] for label in tuples}
                if len(set(seen.values())) > 1:
                    print(f"      {seen}")
    print(f"every Lab 3 fixture identical at 1x and (twice) at 4x (items chaotic at 1x: within their "
          f"expected outcomes), and as expected: {ok}")
    return ok


def main() -> int:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    ok = bench_self_check(int(args[0]) if args else 2)
    if "--fixtures" in sys.argv:
        ok = bench_fixtures() and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
