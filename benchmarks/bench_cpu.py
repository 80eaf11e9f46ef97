"""Where the CPU of one graded submission goes, by phase and by process.

Grades one Lab 3 submission (default: the reference) with ``--no-reuse`` and one scenario at a
time, so that each phase's CPU can be read exactly:

* the grading process's own CPU (``time.process_time``) around the build, each scenario, the
  analysis and the report, plus its children's (``RUSAGE_CHILDREN``: colcon with cmake and the
  compilers, the scenario child with everything it started);
* inside a scenario, every Python process (scenario child = driver, recorder, simulator, the
  student's nodes) reports its own CPU at a few marks through ``benchmarks/cpu_probe``
  (sitecustomize): interpreter start-up, ``import rclpy``, ``rclpy.init`` + first node (DDS
  participant), running (spinning, discovery traffic, physics, recording), bag finalisation,
  exit. What no probe saw is the remainder: processes killed by a signal, interpreter and DDS
  teardown after ``atexit``, non-Python processes (cmake, the compiler), and the student's
  processes when the sandbox runs them (its minimal environment has no probe): "not probed".

It grades twice: with an empty build cache (the first submission of a class: it also pays the
build of the rubric's support packages) and with the cache holding another submission's build
(every later submission: the support packages are taken from their build), unless
``--cold-only``. Per-item results must be identical in both.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_cpu.py [--submission DIR] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))
PROBE = Path(__file__).resolve().parent / "cpu_probe"
LAB3 = REPO / "fixtures" / "submissions" / "enee467_lab3"


def children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


class Phases:
    """Wall, own CPU and children's CPU of each named phase (phases run one at a time); the
    children's CPU includes what jailed one-shot commands used (counted by their cgroup)."""

    def __init__(self) -> None:
        self.rows: dict[str, dict[str, float]] = {}
        self.windows: list[tuple[str, float, float]] = []    # (phase, start, end) in epoch seconds
        self.jailed = 0.0

    def add_jailed(self, cpu_s: float) -> None:
        self.jailed += cpu_s

    def wrap(self, name_of, fn):
        def wrapper(*args, **kwargs):
            name = name_of(*args, **kwargs)
            w0, s0, c0, j0 = time.monotonic(), time.process_time(), children_cpu(), self.jailed
            e0 = time.time()
            try:
                return fn(*args, **kwargs)
            finally:
                self.windows.append((name, e0, time.time()))
                row = self.rows.setdefault(name, {"wall_s": 0.0, "self_cpu_s": 0.0, "children_cpu_s": 0.0})
                row["wall_s"] += time.monotonic() - w0
                row["self_cpu_s"] += time.process_time() - s0
                row["children_cpu_s"] += children_cpu() - c0 + self.jailed - j0
        return wrapper


def role(argv: list[str]) -> str:
    """What a probed process is, from its command line."""
    text = " ".join(argv)
    for needle, name in (("grader.scenario.run", "scenario process (driver, recorder)"), ("grader.bag.recorder", "recorder"),
                         ("grader.sim", "simulator"), ("grader.workspace.launch", "student node"),
                         ("grader.launch.describe", "launch file resolution"), ("colcon", "colcon"),
                         ("setup.py", "colcon"), ("rosidl", "colcon"), ("ament", "colcon")):
        if needle in text:
            return name
    if any(re.search(r"/install/[^/]+/lib/[^/]+/[^/]+$", a) for a in argv[:2]):
        return "student node"          # an executable started as `ros2 run` starts it
    return "other: " + (argv[2] if len(argv) > 2 and argv[1] == "-m" else Path(argv[-1]).name)[:40]


def scenario_of(argv: list[str]) -> str | None:
    """The scenario a process belongs to, from the scenario folder its command line names (the
    scenario process's OUT_DIR, the simulator's canvas); pids do not tell (PID namespaces)."""
    text = " ".join(argv)
    if "grader.scenario.run" in text:
        return Path(argv[-1]).name
    if "--canvas-out" in argv:
        return Path(argv[argv.index("--canvas-out") + 1]).parent.name
    return None


STAGES = ("start-up", "import rclpy", "rclpy.init + node", "running", "bag finalisation", "exit")


def stages(rec: dict) -> dict[str, float]:
    """CPU seconds of a probed process by stage (see the module docstring)."""
    m = {k: v[1] for k, v in rec["marks"].items()}
    out = dict.fromkeys(STAGES, 0.0)
    out["start-up"] = m["site"]
    last = m["site"]
    if "rclpy" in m:
        out["import rclpy"] = m["rclpy"] - last
        last = m["rclpy"]
    node = max((m[k] for k in ("init", "node") if k in m), default=None)
    if node is not None:
        out["rclpy.init + node"] = node - last
        last = node
    if "finalize_start" in m and "finalize" in m:
        out["running"] = m["finalize_start"] - last
        out["bag finalisation"] = m["finalize"] - m["finalize_start"]
        last = m["finalize"]
        out["exit"] = m["exit"] - last
    else:
        out["running"] = m["exit"] - last
    return out


def idle_rate(rec: dict, skip_s: float = 3.0) -> float | None:
    """CPU seconds per second of a process after its first ``skip_s`` s (median of the timeline)."""
    tl = rec.get("timeline") or []
    if len(tl) < 8:
        return None
    t0 = rec["marks"]["site"][0]
    pts = [(t, c) for t, c in tl if t - t0 >= skip_s]
    rates = [(c2 - c1) / (t2 - t1) for (t1, c1), (t2, c2) in zip(pts, pts[1:]) if t2 > t1]
    return statistics.median(rates) if rates else None


def profile(submission: Path, work: Path, cache: Path, label: str) -> dict:
    """Grade ``submission`` once, one scenario at a time, with every probe on."""
    import grader.grading.pipeline as pipeline
    import grader.scenario as scenario_mod
    import grader.workspace as workspace_mod
    from grader.grading.schedule import Slots
    from grader.rubric.load import load_rubric

    probe_dir = work / f"probe-{label}"
    probe_dir.mkdir(parents=True)
    os.environ["GRADER_CPU_PROBE"] = str(probe_dir)
    os.environ["PYTHONPATH"] = os.pathsep.join([str(PROBE), *filter(None, [os.environ.get("PYTHONPATH")])])
    phases = Phases()
    import grader.sandbox.oneshot as oneshot
    sys.path.insert(0, str(PROBE))
    from sitecustomize import jailed_cpu  # noqa: E402 - the probe's helper (inactive in this process)
    sys.path.remove(str(PROBE))
    saved_end = oneshot._end
    oneshot._end = jailed_cpu(saved_end, phases.add_jailed)
    saved = (workspace_mod.build_workspace, scenario_mod.run_scenario, pipeline.analyze_bags, pipeline.write_outputs)
    workspace_mod.build_workspace = phases.wrap(lambda *a, **k: "build", saved[0])
    scenario_mod.run_scenario = phases.wrap(lambda run, *a, **k: f"scenario {run.id}", saved[1])
    pipeline.analyze_bags = phases.wrap(lambda *a, **k: "analysis", saved[2])
    pipeline.write_outputs = phases.wrap(lambda *a, **k: "report (result.json, report.html)", saved[3])
    try:
        rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
        w0, s0, c0 = time.monotonic(), time.process_time(), children_cpu()
        graded = pipeline.grade_submission(submission, rubric, work / f"out-{label}", cache_dir=cache,
                                           slots=Slots(1), reuse=False)
        total = {"wall_s": time.monotonic() - w0,
                 "cpu_s": time.process_time() - s0 + children_cpu() - c0 + phases.jailed}
    finally:
        oneshot._end = saved_end
        (workspace_mod.build_workspace, scenario_mod.run_scenario, pipeline.analyze_bags,
         pipeline.write_outputs) = saved
        os.environ.pop("GRADER_CPU_PROBE", None)
    records = [json.loads(p.read_text()) for p in sorted(probe_dir.glob("*.json"))]
    sandbox = {}
    for rec in sorted((work / f"out-{label}").glob("*/scenarios/*/scenario.json")):
        counters = (json.loads(rec.read_text()).get("sandbox") or {}).get("counters") or {}
        sandbox[rec.parent.name] = counters
    return {"label": label, "phases": phases.rows, "windows": phases.windows, "total": total,
            "records": records, "sandbox": sandbox,
            "items": {it.id: (it.points, it.status) for it in graded.result.items},
            "timings": graded.timings}


def breakdown(run: dict) -> dict:
    """Per scenario: CPU by process role and stage; the rest of the phases as they are."""
    records = run["records"]
    scen_of: dict[int, str] = {}
    table: dict[str, dict[str, dict[str, float]]] = defaultdict(lambda: defaultdict(lambda: dict.fromkeys(STAGES, 0.0)))
    counts: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    idle: dict[str, list[float]] = defaultdict(list)
    for r in records:
        sc = scenario_of(r["argv"])
        started = r["marks"]["site"][0]
        # a student's node names no scenario folder: the (sequential) phase it started in does
        phase = f"scenario {sc}" if sc else next(
            (name for name, t0, t1 in run.get("windows", []) if t0 <= started <= t1), "build")
        name = role(r["argv"])
        for k, v in stages(r).items():
            table[phase][name][k] += v
        counts[phase][name] += 1
        rate = idle_rate(r)
        if rate is not None and phase != "build":
            idle[name].append(rate)
    return {"table": table, "counts": counts, "idle": idle}


def report(run: dict) -> list[str]:
    """Lines of the breakdown table for one profiled grade."""
    bd = breakdown(run)
    lines = [f"== {run['label']}: {run['total']['cpu_s']:.1f} s CPU, {run['total']['wall_s']:.1f} s wall =="]
    totals_by_role: dict[str, float] = defaultdict(float)
    totals_by_stage: dict[str, float] = defaultdict(float)
    lines.append(f"{'phase':42s} {'wall s':>7s} {'CPU s':>7s}   (grader process / children)")
    for phase, row in run["phases"].items():
        cpu = row["self_cpu_s"] + row["children_cpu_s"]
        lines.append(f"{phase:42s} {row['wall_s']:7.1f} {cpu:7.2f}   ({row['self_cpu_s']:.2f} / {row['children_cpu_s']:.2f})")
        procs = bd["table"].get(phase, {})
        seen = 0.0
        for name, st in sorted(procs.items()):
            s = sum(st.values())
            seen += s
            totals_by_role[name] += s
            for k, v in st.items():
                totals_by_stage[k] += v
            detail = ", ".join(f"{k} {v:.2f}" for k, v in st.items() if v >= 0.005)
            lines.append(f"    {name:38s}{'':8s}{s:7.2f}   x{bd['counts'][phase][name]}: {detail}")
        students = (run.get("sandbox", {}).get(phase.removeprefix("scenario "), {}) or {}).get("cpu_s")
        if students is not None and "student node" not in procs:
            seen += students
            totals_by_role["student nodes (sandbox cgroup)"] += students
            lines.append(f"    {'student nodes (sandbox cgroup)':38s}{'':8s}{students:7.2f}")
        if procs or students is not None:
            rest = row["children_cpu_s"] - seen
            label = "not probed (teardown, non-Python, killed)"
            totals_by_role[label] += rest
            lines.append(f"    {label:38s}{'':8s}{rest:7.2f}")
    phase_sum = sum(r["self_cpu_s"] + r["children_cpu_s"] for r in run["phases"].values())
    lines.append(f"{'other (scheduling, threads, imports)':42s} {'':7s} {run['total']['cpu_s'] - phase_sum:7.2f}")
    students = totals_by_role.get("student node", 0.0) + totals_by_role.get("student nodes (sandbox cgroup)", 0.0)
    lines.append(f"the grader's own CPU: {run['total']['cpu_s'] - students:.1f} s; the student's code: {students:.1f} s")
    lines.append("by role (scenarios): " + ", ".join(f"{k} {v:.1f}" for k, v in
                                                  sorted(totals_by_role.items(), key=lambda kv: -kv[1])))
    lines.append("by stage (probed processes of scenarios): " + ", ".join(f"{k} {v:.1f}" for k, v in totals_by_stage.items()))
    lines.append("steady CPU per second after 3 s (median): " + ", ".join(
        f"{k} {statistics.median(v):.3f}" for k, v in sorted(bd["idle"].items())))
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--submission", type=Path, default=LAB3 / "reference")
    ap.add_argument("--warm-from", type=Path, default=LAB3 / "template",
                    help="submission built first into the cache of the warm run (default: the template)")
    ap.add_argument("--cold-only", action="store_true", help="only the first submission (empty cache)")
    ap.add_argument("--later-only", action="store_true", help="only a later submission (support build cached)")
    ap.add_argument("--json", type=Path, help="write the raw measurements here")
    args = ap.parse_args()
    runs = []
    print(f"machine: {os.cpu_count()} cores, load average " + "/".join(f"{x:.1f}" for x in os.getloadavg()),
          flush=True)
    with tempfile.TemporaryDirectory(prefix="bench-cpu-") as tmp:
        work = Path(tmp)
        if not args.later_only:
            runs.append(profile(args.submission, work, work / "cache-cold", "first submission (empty build cache)"))
            print("\n".join(report(runs[-1])), flush=True)
        if not args.cold_only:
            from grader.grading.pipeline import discover_submissions  # noqa: F401 - warm the import
            from grader.rubric.load import load_rubric
            from grader.workspace import build_workspace

            rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
            build_workspace(args.warm_from, cache_dir=work / "cache-warm", support=dict(rubric.support))
            runs.append(profile(args.submission, work, work / "cache-warm",
                                f"later submission (cache holds the build of {args.warm_from.name})"))
            print("\n".join(report(runs[-1])), flush=True)
        same = len({json.dumps(r["items"], sort_keys=True) for r in runs}) == 1
        print(f"per-item results identical across runs: {same}; load average after: "
              + "/".join(f"{x:.1f}" for x in os.getloadavg()))
        if args.json:
            args.json.write_text(json.dumps(runs, indent=1, default=str))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
