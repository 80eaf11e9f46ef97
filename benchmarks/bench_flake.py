"""No flaky points: the same code must get the same grade, whatever the batch's ``--jobs`` and
the machine's load.

Default: a *class generated from the fixtures* by realistic mutations (the operators of
``grader rubric audit``, :mod:`grader.audit.mutate`: flip a sign, scale a constant, swap
arguments, rename a topic, drop a call, remove an angle wrap, change a timer period) applied to
every fixture of each lab, sampled with a fixed seed: 40 Lab 3 submissions and 20 of each other
lab, plus the few hand-written variants in ``EXTRA`` (bugs no operator makes, e.g. a heading
error in degrees). The class is graded three times, at ``--jobs 2``, ``4`` and ``8``
(``--no-reuse``, one shared build cache, so the runs differ only in the scenarios), optionally with
``--load K`` CPU-burning processes alongside a run; ``--side-by-side`` grades the three runs at
the same time, each in a process of its own, so each run is the machine's load for the others. Every automatic item whose status or points
differ between the runs is printed with the evidence of each run side by side (the keys that
differ), and all of it goes to ``--report``. Target: none.

Buggy code is the point: a controller that oscillates or turns the long way is exactly the one
whose outcome a few milliseconds of scheduling could change, and whose points a student will
question. Fixtures alone cannot show it (they were made deterministic one by one).

    .venv/bin/python benchmarks/bench_flake.py                          # the class, 3 runs: ~3 h on 2 cores
    .venv/bin/python benchmarks/bench_flake.py --labs enee467_lab3 --per-lab 8 --jobs 2 4
    .venv/bin/python benchmarks/bench_flake.py --fixtures [--runs 3] [--jobs 3]   # the Lab 3 fixtures
    .venv/bin/python benchmarks/bench_flake.py --side-by-side              # the 3 runs at once: ~1.5 h
    options: --seed S, --load K [K ...] (one per run), --keep DIR, --report FILE.json,
             --scenarios ID [ID ...] (grade only the items of these scenarios: quicker samples)
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: lab folder under fixtures/submissions -> rubric file under rubrics/
LABS = {"enee467_lab3": "enee467_lab3.yaml", "goal_setter": "goal_setter.yaml",
        "wall_pen": "wall_pen.yaml", "first_nodes": "first_nodes.yaml", "chase": "chase.yaml"}
PER_LAB = {"enee467_lab3": 40, "goal_setter": 20, "wall_pen": 20, "first_nodes": 20, "chase": 20}
#: hand-written variants no operator makes: (name, source fixture, file, old text, new text)
EXTRA = {
    "enee467_lab3": [
        # the first case: theta_e converted to degrees before the gain (it spins wildly)
        ("degrees", "reference", "src/turtle_control/turtle_control/turtle_control.py",
         "omega_z = self.K_2 * theta_e", "omega_z = self.K_2 * np.degrees(theta_e)"),
        # a controller without the wrap and a steeper gain: spins at the seam much faster
        ("no_wrap_fast", "no_wrap", "src/turtle_control/turtle_control/turtle_control.py",
         '("K_2", 1.0)', '("K_2", 3.0)'),
    ],
}


def make_class(dest: Path, labs: list[str], per_lab: dict[str, int], seed: int) -> dict[str, list[dict]]:
    """Write the mutated class to ``dest/<lab>/<source>.<mutant id>/``; what each one is."""
    from grader.audit.mutate import mutants

    made: dict[str, list[dict]] = {}
    for lab in labs:
        root = REPO / "fixtures" / "submissions" / lab
        sources = [p for p in sorted(root.iterdir()) if (p / "expected.yaml").exists()]
        found = [m for src in sources for m in mutants(src)]
        made[lab] = []
        for m in stratified(found, per_lab[lab], seed):
            name = f"{m.root.name}.{m.id}"
            m.write(dest / lab / name)
            made[lab].append({"submission": name, "source": m.root.name, **m.summary()})
        for name, source, rel, old, new in EXTRA.get(lab, []):
            target = dest / lab / f"{source}.{name}"
            shutil.copytree(root / source, target, ignore=shutil.ignore_patterns("expected.yaml"))
            text = (target / rel).read_text()
            if old not in text:
                raise SystemExit(f"EXTRA variant {name}: {old!r} not in {source}/{rel}")
            (target / rel).write_text(text.replace(old, new, 1))
            made[lab].append({"submission": target.name, "source": source, "file": rel,
                              "description": f"hand-written: {old!r} -> {new!r}"})
    return made


def stratified(found: list, n: int, seed: int) -> list:
    """``n`` mutants, the operators taking turns (each operator's mutants in a seeded random
    order): a plain sample of Lab 3 is half dropped log lines, which say little about timing."""
    import random

    by_op: dict[str, list] = defaultdict(list)
    for m in found:
        by_op[m.operator].append(m)
    for i, op in enumerate(sorted(by_op)):
        random.Random(seed * 1000 + i).shuffle(by_op[op])
    picked: list = []
    while len(picked) < n and any(by_op.values()):
        for op in sorted(by_op):
            if by_op[op] and len(picked) < n:
                picked.append(by_op[op].pop())
    return picked


def burn(k: int) -> list[subprocess.Popen]:
    """``k`` processes that each keep a CPU busy (machine load), stopped by :func:`unburn`."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(k)]


def unburn(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        p.kill()
        p.wait()


def grade(lab: str, subs: Path, out: Path, jobs: int, cache: Path, scenarios: list[str] | None) -> tuple[float, int]:
    """One lab's class graded like ``grader grade --no-reuse --jobs J``; wall seconds and the
    most scenarios that ran at once (``--jobs`` is an upper bound: grader.grading.schedule)."""
    from grader.grading.batch import grade_batch
    from grader.grading.pipeline import discover_submissions
    from grader.grading.schedule import Slots
    from grader.rubric import load_rubric

    rubric = load_rubric(REPO / "rubrics" / LABS[lab])
    if scenarios:
        keep = [i for i in rubric.items if not i.automatic or set(i.scenario) & set(scenarios)]
        rubric = rubric.model_copy(update={"items": keep})
    t0 = time.monotonic()
    slots = Slots(jobs)
    grade_batch(discover_submissions(subs), rubric, out, slots=slots, cache_dir=cache, reuse=False)
    return time.monotonic() - t0, slots.peak


def item_outcomes(out: Path) -> dict[tuple[str, str], dict[str, Any]]:
    """(submission, item) -> status, points, evidence and how it was decided, of one run's lab."""
    seen = {}
    for result in sorted(out.glob("*/result.json")):
        doc = json.loads(result.read_text())
        for item in doc["items"]:
            if item["kind"] != "manual":
                seen[(result.parent.name, item["id"])] = {
                    "status": item["status"], "points": item["points"], "evidence": item.get("evidence") or {},
                    "decided": item.get("decided") or {}}
    return seen


def evidence_diff(evidences: list[dict], limit: int = 6) -> dict[str, list]:
    """The evidence keys (one level deep, then inside goal tables) whose values differ."""
    out: dict[str, list] = {}
    keys = sorted({k for ev in evidences for k in ev} - {"scenario_start", "trajectory", "heading_error"})
    for k in keys:
        vals = [ev.get(k) for ev in evidences]
        if len({json.dumps(v, sort_keys=True, default=str) for v in vals}) > 1:
            out[k] = [_short(v) for v in vals]
        if len(out) >= limit:
            break
    return out


def _short(v: Any, n: int = 160) -> Any:
    text = json.dumps(v, default=str)
    return v if len(text) <= n else text[:n] + "..."


def grade_run(n: int, j: int, k: int, labs: list[str], classes: dict[str, Path], work: Path,
              scenarios: list[str] | None) -> dict[str, Any]:
    """Run ``n`` (1-based) of the class at ``--jobs j`` with ``k`` CPU burners, into
    ``work/run<n>/<lab>/``; its wall time, peak concurrency and load go to ``work/run<n>/run.json``."""
    burners = burn(k)
    t0, load0 = time.monotonic(), os.getloadavg()[0]
    peak = 0
    try:
        for lab in labs:
            out = work / f"run{n}" / lab
            shutil.rmtree(out, ignore_errors=True)
            peak = max(peak, grade(lab, classes[lab], out, j, work / "cache", scenarios)[1])
    finally:
        unburn(burners)
    done = {"run": n, "jobs": j, "burners": k, "wall_s": time.monotonic() - t0, "peak": peak,
            "load": [load0, os.getloadavg()[0]]}
    (work / f"run{n}" / "run.json").write_text(json.dumps(done))
    print(f"run {n}: --jobs {j}, {k} CPU burner(s): {done['wall_s']:.0f} s, at most {peak} at once "
          f"(load {load0:.1f} -> {done['load'][1]:.1f})", flush=True)
    return done


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fixtures", action="store_true", help="grade the Lab 3 fixtures instead of the class")
    ap.add_argument("--runs", type=int, default=3, help="with --fixtures: how many runs")
    ap.add_argument("--labs", nargs="+", choices=sorted(LABS), default=list(LABS))
    ap.add_argument("--per-lab", type=int, default=None, help="mutants per lab (default: 40 Lab 3, 20 others)")
    ap.add_argument("--seed", type=int, default=22)
    ap.add_argument("--jobs", type=int, nargs="+", default=None,
                    help="--jobs of each run (default 2 4 8; with --fixtures 3 for every run)")
    ap.add_argument("--load", type=int, nargs="+", default=[0], help="CPU burners alongside each run")
    ap.add_argument("--scenarios", nargs="+", default=None, help="grade only the items of these scenarios")
    ap.add_argument("--side-by-side", action="store_true",
                    help="grade the runs at the same time, each a process of its own (each run is load for the others)")
    ap.add_argument("--only-run", type=int, default=None, help=argparse.SUPPRESS)   # a side-by-side child
    ap.add_argument("--compare-only", action="store_true",
                    help="grade nothing: compare the runs already in --keep (e.g. labs graded by two invocations)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the class and the outputs here")
    ap.add_argument("--report", type=Path, default=None, help="write every differing item here (JSON)")
    args = ap.parse_args()

    labs = ["enee467_lab3"] if args.fixtures else args.labs
    jobs = args.jobs or ([3] * args.runs if args.fixtures else [2, 4, 8])
    loads = (args.load * len(jobs))[:len(jobs)] if len(args.load) == 1 else args.load
    if len(loads) != len(jobs):
        ap.error("--load takes one value, or one per run")
    work = args.keep or Path(tempfile.mkdtemp(prefix="bench-flake-"))
    work.mkdir(parents=True, exist_ok=True)
    if args.fixtures:
        classes = {"enee467_lab3": REPO / "fixtures" / "submissions" / "enee467_lab3"}
    else:
        classes = {lab: work / "class" / lab for lab in labs}
    if args.only_run is not None:
        n = args.only_run
        grade_run(n, jobs[n - 1], loads[n - 1], labs, classes, work, args.scenarios)
        return 0
    try:
        made: dict[str, list[dict]] = {}
        if not args.fixtures and not args.compare_only:
            per_lab = {lab: args.per_lab or PER_LAB[lab] for lab in labs}
            shutil.rmtree(work / "class", ignore_errors=True)
            made = make_class(work / "class", labs, per_lab, args.seed)
            for lab in labs:
                print(f"class {lab}: {len(made[lab])} submissions", flush=True)
        if args.compare_only:
            runs = [json.loads(f.read_text()) if (f := work / f"run{n}" / "run.json").exists() else {"wall_s": float("nan")}
                    for n in range(1, len(jobs) + 1)]
        elif args.side_by_side:
            argv = [sys.executable, str(Path(__file__).resolve()), "--keep", str(work),
                    "--labs", *labs, "--jobs", *map(str, jobs), "--load", *map(str, loads)]
            argv += ["--fixtures"] if args.fixtures else []
            argv += ["--scenarios", *args.scenarios] if args.scenarios else []
            children = [subprocess.Popen(argv + ["--only-run", str(n)]) for n in range(1, len(jobs) + 1)]
            if any(c.wait() != 0 for c in children):
                raise SystemExit("a run failed (its output is above)")
            runs = [json.loads((work / f"run{n}" / "run.json").read_text()) for n in range(1, len(jobs) + 1)]
        else:
            runs = [grade_run(n, j, k, labs, classes, work, args.scenarios)
                    for n, (j, k) in enumerate(zip(jobs, loads), 1)]
        walls = [r["wall_s"] for r in runs]
        seen: dict[tuple[str, str, str], list[dict]] = defaultdict(list)
        for n in range(1, len(jobs) + 1):
            for lab in labs:
                for (sub, item), got in item_outcomes(work / f"run{n}" / lab).items():
                    seen[(lab, sub, item)].append(got)
        differing = {key: v for key, v in seen.items()
                     if len({(o["status"], o["points"]) for o in v}) > 1 or len(v) != len(jobs)}
        rows = []
        for (lab, sub, item), values in sorted(differing.items()):
            outcomes = " | ".join(f"--jobs {j}: {o['status']} {o['points']:g}" for j, o in zip(jobs, values))
            diff = evidence_diff([o["evidence"] for o in values])
            print(f"DIFFERS {lab}/{sub} {item}: {outcomes}", flush=True)
            for key, vals in diff.items():
                print(f"    {key}: " + "  ||  ".join(json.dumps(v, default=str) for v in vals))
            rows.append({"lab": lab, "submission": sub, "item": item, "jobs": jobs,
                         "outcomes": [{"status": o["status"], "points": o["points"], "decided": o["decided"],
                                       "evidence": o["evidence"]} for o in values]})
        decided: dict[str, int] = defaultdict(int)
        unstable = []
        for (lab, sub, item), values in seen.items():
            for o in values:
                mode = (o["decided"] or {}).get("by", "one run")
                decided[mode] += 1
                if (o["decided"] or {}).get("stable") is False:
                    unstable.append((lab, sub, item))
        per_lab_n = {lab: len({s for (lb, s, _i) in seen if lb == lab}) for lab in labs}
        how = "side by side" if args.side_by_side else "one after another"
        print(f"submissions: {per_lab_n}; run wall times ({how}): " + ", ".join(f"{w:.0f} s" for w in walls))
        print("item results decided by: " + ", ".join(f"{m} {n}" for m, n in sorted(decided.items())))
        if unstable:
            print(f"items whose repeated runs disagreed (graded by the median): {len(set(unstable))}")
        print(f"{len(seen)} item results compared over {len(jobs)} runs (--jobs {', '.join(map(str, jobs))}): "
              f"{len(differing)} differed")
        if args.report:
            args.report.write_text(json.dumps({"jobs": jobs, "loads": loads, "walls_s": walls, "runs": runs,
                                               "side_by_side": args.side_by_side, "class": made,
                                               "compared": len(seen), "differing": rows}, indent=1, default=str))
        return 1 if differing else 0
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
