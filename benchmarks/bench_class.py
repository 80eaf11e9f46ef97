"""A class graded as users grade it, side by side in one run (issue 35, "measure it where users feel it").

The class: every Lab 3 fixture (correct solutions, the instructor's handout and template, realistic
bugs) plus ``--mutants N`` one-line mutants of the reference (``grader.audit.mutate``, a fixed
seed: the same class every run), at least 30 submissions by default. Modes, each from an empty
build cache and with ``--no-reuse`` (a class graded from scratch):

1. the default settings (``grader grade --no-reuse``: simulated time, the jobs the machine's
   cgroup allows);
2. ``--jobs 4 --time-scale 1`` (the wall clock, as graded before simulated time was the default);
3. optionally (``--jobs2-1x``) ``--jobs 2 --time-scale 1``, the acceptance's reference mode.

Then the reference's self-check at the default and at 1x, and (as root, ``--quotas``) at the
default inside cgroups of 0.5 CPU / 768 MB (Gradescope's default container) and 1 CPU / 1.5 GB.

Reported per mode: wall time, submissions per minute, CPU seconds per submission (the grader and
everything it started, ``RUSAGE_CHILDREN``, plus the sandbox's jailed builds), and every per-item
status and points compared with the first mode: a difference is printed (exit 1). Then the
reference's self-check (``grader check --no-reuse``, build cached) at the default and at 1x.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_class.py [--mutants 14] [--only batch|check]
        [--jobs2-1x] [--skip-1x] [--quotas]

Long: the 1x mode takes about a minute per submission on 2 cores with nothing else running.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_scale import LAB3, REPO, RUBRIC, grader, items_of, load  # noqa: E402

from grader.audit.mutate import mutants, sample  # noqa: E402


def make_class(dest: Path, n_mutants: int, seed: int = 7) -> list[str]:
    """Copy the fixtures and write ``n_mutants`` mutants of the reference into ``dest``."""
    dest.mkdir(parents=True)
    names = []
    for sub in sorted(LAB3.iterdir()):
        if (sub / "src").is_dir():
            shutil.copytree(sub, dest / sub.name, ignore=shutil.ignore_patterns("expected.yaml"))
            names.append(sub.name)
    chosen = sample([m for m in mutants(LAB3 / "reference") if m.file.startswith("src/")], n_mutants, seed)
    for m in chosen:
        m.write(dest / f"mutant_{m.id}")
        (dest / f"mutant_{m.id}" / "expected.yaml").unlink(missing_ok=True)
        names.append(f"mutant_{m.id}")
    return names


def grade_class(subs: Path, out: Path, cache: Path, extra: list[str]) -> tuple[float, float, dict]:
    wall, cpu, rc = grader("grade", str(subs), "--rubric", str(RUBRIC), "-o", str(out), "--cache-dir",
                           str(cache), "--no-reuse", *extra)
    results = {p.parent.name: items_of(p) for p in sorted(out.glob("*/result.json"))}
    if rc not in (0, 1):
        print(f"  grade exited {rc}", flush=True)
    return wall, cpu, results


def cpu_by_phase(result_jsons: list[Path], total_cpu_s: float) -> str:
    """CPU seconds per submission by phase, from each result.json's ``timings``: every scenario
    (its child and the processes it ran, retries included), analysis (analyze + score), and the
    rest of the total (build, reports, the grader's start-up)."""
    n = max(1, len(result_jsons))
    phases: dict[str, float] = {}
    for path in result_jsons:
        for key, value in json.loads(path.read_text()).get("timings", {}).items():
            if key.endswith(":cpu_s") or key == "analysis_cpu_s":
                name = key.split(":")[1] if key.startswith("scenario:") else "analysis"
                phases[name] = phases.get(name, 0.0) + float(value)
    phases["build, reports, start-up"] = total_cpu_s - sum(phases.values())
    return "  ".join(f"{name} {value / n:.1f}" for name, value in phases.items())


def compare(base: dict, other: dict, label: str) -> int:
    diffs = 0
    for sid, items in base.items():
        for item, got in items.items():
            if other.get(sid, {}).get(item) != got:
                diffs += 1
                print(f"  differs: {sid} {item}: first mode {got} vs {label} {other.get(sid, {}).get(item)}")
    missing = sorted(set(base) - set(other))
    if missing:
        print(f"  {label}: no result for {missing}")
    return diffs + len(missing)


def bench_batch(tmp: Path, n_mutants: int, jobs2: bool, skip_1x: bool) -> int:
    subs = tmp / "class"
    names = make_class(subs, n_mutants)
    print(f"== a class of {len(names)} Lab 3 submissions ({len(names) - n_mutants} fixtures, {n_mutants} mutants "
          "of the reference), each mode from an empty build cache, --no-reuse", flush=True)
    modes = [("default settings", [])]
    if not skip_1x:
        modes.append(("--jobs 4 --time-scale 1", ["--jobs", "4", "--time-scale", "1"]))
    if jobs2:
        modes.append(("--jobs 2 --time-scale 1", ["--jobs", "2", "--time-scale", "1"]))
    first: dict | None = None
    bad = 0
    for k, (label, extra) in enumerate(modes):
        before = load()
        wall, cpu, results = grade_class(subs, tmp / f"out-{k}", tmp / f"cache-{k}", extra)
        n = len(names)
        print(f"  {label:26s} {wall:7.1f} s  {n / wall * 60:5.2f} submissions/min  CPU {cpu / n:5.1f} s/submission  "
              f"graded {len(results)}/{n}  load {before} -> {load()}", flush=True)
        print(f"    CPU s/submission by phase: {cpu_by_phase(sorted((tmp / f'out-{k}').glob('*/result.json')), cpu)}",
              flush=True)
        if first is None:
            first = results
        else:
            bad += compare(first, results, label)
    print(f"  per-item status and points identical in every mode: {bad == 0}")
    return bad


def check_in_group(tmp: Path, cache: Path, cpus: float, memory_mb: int) -> None:
    """The reference's self-check inside a cgroup of ``cpus`` and ``memory_mb``: wall, CPU (its
    process tree's), the group's memory peak (cgroup v1), the score and the items left ``error``."""
    import resource
    import subprocess
    import time

    from grader.testing.cgroup import limited_group

    out = tmp / f"check-{cpus:g}cpu"
    with limited_group(cpus, memory_mb, name=f"bench-class-{os.getpid()}") as group:
        if group is None:
            print(f"  {cpus:g} CPU / {memory_mb} MB: no writable cgroup (run as root)")
            return
        t0, ru0 = time.monotonic(), resource.getrusage(resource.RUSAGE_CHILDREN)
        proc = subprocess.run([str(REPO / ".venv" / "bin" / "grader"), "check", str(LAB3 / "reference"), "--rubric",
                               str(RUBRIC), "-o", str(out), "--cache-dir", str(cache), "--no-reuse"],
                              capture_output=True, text=True, preexec_fn=group.join)
        wall, ru1 = time.monotonic() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
        mem = group.dirs["memory"]
        peak = (mem / "memory.max_usage_in_bytes").read_text().strip() if (mem / "memory.max_usage_in_bytes").exists() else "?"
    result = json.loads((out / "check" / "result.json").read_text())
    peak_mb = f"{int(peak) / 2**20:.0f} MB" if peak.isdigit() else peak
    cpu_s = f"{(ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime):.1f} s"
    print(f"  {cpus:g} CPU / {memory_mb} MB: wall {wall:6.1f} s  CPU {cpu_s}  memory peak {peak_mb}  "
          f"{result['auto_score']:g}/{result['auto_max']:g}  exit {proc.returncode}  "
          f"starved items {sorted(i['id'] for i in result['items'] if i['status'] == 'error')}", flush=True)


def bench_check(tmp: Path, quotas: bool = False) -> int:
    print("\n== self-check of the reference (grader check --no-reuse, build cached)", flush=True)
    cache = tmp / "check-cache"
    support = f"turtle_control_interfaces={REPO / 'fixtures/support/enee467_lab3/turtle_control_interfaces'}"
    grader("build", str(LAB3 / "reference"), "--cache-dir", str(cache), "--support", support)
    results = {}
    for label, extra in (("default settings", []), ("--time-scale 1", ["--time-scale", "1"])):
        out = tmp / f"check-{len(results)}"
        before = load()
        wall, cpu, rc = grader("check", str(LAB3 / "reference"), "--rubric", str(RUBRIC), "-o", str(out),
                               "--cache-dir", str(cache), "--no-reuse", *extra)
        result = json.loads((out / "check" / "result.json").read_text())
        phases = {k: v for k, v in result["timings"].items() if k in ("build_s", "scenarios_wall_s", "analysis_s")}
        results[label] = items_of(out / "check" / "result.json")
        print(f"  {label:18s} wall {wall:6.1f} s  CPU {cpu:5.1f} s  {result['auto_score']:g}/{result['auto_max']:g}  "
              f"exit {rc}  {phases}  load {before} -> {load()}", flush=True)
        print(f"    CPU s by phase: {cpu_by_phase([out / 'check' / 'result.json'], cpu)}", flush=True)
    if quotas:
        for cpus, memory_mb in ((0.5, 768), (1.0, 1536)):
            check_in_group(tmp, cache, cpus, memory_mb)
    first, *rest = results.values()
    return sum(compare({"reference": first}, {"reference": other}, label)
               for label, other in zip(list(results)[1:], rest))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=["batch", "check"])
    ap.add_argument("--mutants", type=int, default=14, help="mutants of the reference added to the fixtures")
    ap.add_argument("--jobs2-1x", action="store_true", help="also grade the class at --jobs 2 --time-scale 1")
    ap.add_argument("--skip-1x", action="store_true", help="grade the class at the default settings only")
    ap.add_argument("--quotas", action="store_true", help="also self-check in 0.5 CPU / 768 MB and 1 CPU / 1.5 GB "
                                                         "cgroups (root)")
    args = ap.parse_args()
    print(f"machine: os.cpu_count() {os.cpu_count()}, load average {load()}", flush=True)
    bad = 0
    with tempfile.TemporaryDirectory(prefix="bench-class-") as tmp:
        if args.only in (None, "batch"):
            bad += bench_batch(Path(tmp), args.mutants, args.jobs2_1x, args.skip_1x)
        if args.only in (None, "check"):
            bad += bench_check(Path(tmp), args.quotas)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
