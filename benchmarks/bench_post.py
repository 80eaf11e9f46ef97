"""The grading process's own CPU after the scenarios, phase by phase, offline (no ROS).

What ``grader check`` spends once the scenarios have recorded their bags (issue 35: a graded
Lab 3 submission's CPU): the CLI's start-up and imports, the rubric, each bag read into
DataFrames, the analyzers, the contract check, the behaviour fingerprint, the replay data,
scoring, result.json, report.html (its figures apart), the self-check table. Each run is a fresh
interpreter (``--child``), as a real ``grader check`` is, so the imports and matplotlib's set-up
are counted where they are paid (with the modules' bytecode cached, as in an installed grader:
compiling grader's ~180 modules again in every run costs ~0.25 s more); its total is the child's whole CPU (``RUSAGE_CHILDREN``), so
what no phase names is the remainder. The submission's committed bags
(``fixtures/bags/lab3/<submission>``) stand in for its scenarios; the post-scenario calls are
those of ``grader.grading.pipeline.grade_submission`` in the student's view (public items).

``--baseline FILE`` prints a run saved with ``--json`` (another checkout, e.g. before a change)
side by side with this one.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_post.py [--runs 5] [--submission reference]
        [--json OUT] [--baseline OLD.json]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

#: the phases in the order they are printed (a run's wrapped calls are counted under these)
PHASES = ("start-up (CLI, imports)", "rubric", "bags -> DataFrames", "analyzers", "contract check",
          "fingerprint", "replay data", "scoring", "result.json", "figures", "report HTML (no figures)",
          "self-check table", "rest (not named)")


def children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


class Clock:
    """Own CPU of named phases; a phase inside another (figures in the report) is taken out of
    the outer one, so the phases add up."""

    def __init__(self) -> None:
        self.cpu: dict[str, float] = {}
        self._stack: list[list[Any]] = []

    def wrap(self, module: Any, attr: str, phase: str) -> None:
        fn = getattr(module, attr)

        def wrapper(*args: Any, **kwargs: Any) -> Any:
            frame = [phase, time.process_time(), 0.0]      # phase, start, CPU of phases inside it
            self._stack.append(frame)
            try:
                return fn(*args, **kwargs)
            finally:
                self._stack.pop()
                spent = time.process_time() - frame[1]
                self.cpu[phase] = self.cpu.get(phase, 0.0) + spent - frame[2]
                if self._stack:
                    self._stack[-1][2] += spent
        setattr(module, attr, wrapper)

    @contextlib.contextmanager
    def phase(self, name: str):  # noqa: ANN201 - a context manager
        t0 = time.process_time()
        yield
        self.cpu[name] = self.cpu.get(name, 0.0) + time.process_time() - t0


def child(submission: str, dump: Path | None) -> None:
    """One post-scenario path in this (fresh) interpreter; prints the phases' CPU as JSON."""
    clock = Clock()
    with clock.phase("start-up (CLI, imports)"):
        from grader.cli import build_parser  # noqa: PLC0415 - timed: what `grader check` imports
        build_parser()
        from grader.grading import analysis, outputs, pipeline  # noqa: PLC0415 - timed, as run_check imports them
        from grader.report import html  # noqa: PLC0415 - timed
        from grader.testing.batch import LAB3_BAGS, layout  # noqa: PLC0415 - timed
        from grader import api  # noqa: PLC0415 - timed
    for module, attr, phase in (
            (analysis, "scenario_frames", "bags -> DataFrames"), (analysis, "analyze_item", "analyzers"),
            (analysis, "check_contract", "contract check"), (analysis, "write_fingerprint", "fingerprint"),
            (pipeline, "write_replay", "replay data"), (pipeline, "score", "scoring"),
            (pipeline, "apply_saved_manual_scores", "scoring"), (pipeline, "apply_intake", "scoring"),
            (outputs, "write_result", "result.json"), (html, "figures_for", "figures"),
            (outputs, "write_html", "report HTML (no figures)")):
        clock.wrap(module, attr, phase)
    with clock.phase("rubric"):
        rubric = api.load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    with tempfile.TemporaryDirectory(prefix="bench-post-") as tmp:
        out = Path(tmp)
        sid = layout(LAB3_BAGS, out, [submission])[0]
        sub_out = out / sid
        # grade_submission after its scenarios, in the student's view (grader check)
        items = pipeline.selected_items(rubric, True)
        findings, problems = analysis.analyze_bags(rubric, items, sub_out, on_frames=pipeline.write_replay)
        result, kept = pipeline.apply_saved_manual_scores(sub_out, pipeline.score(rubric, findings))
        result, late = pipeline.apply_intake(sub_out, rubric, result)
        result = result.for_student()
        graded = pipeline.GradedSubmission(sid, sub_out, result, build_ok=True, build_failed=[],
                                           errors=problems + kept + late, timings={},
                                           recordings=pipeline.scenario_recordings(sub_out),
                                           intake=pipeline.public_record(sub_out))
        pipeline.write_outputs(graded, rubric, public_only=True)
        table = io.StringIO()
        with clock.phase("self-check table"), contextlib.redirect_stdout(table):
            outputs.print_check_table(graded, rubric)
        if dump is not None:
            dump.mkdir(parents=True, exist_ok=True)
            (dump / "table.txt").write_text(table.getvalue())
            (dump / "report.html").write_text((sub_out / "report.html").read_text())
            (dump / "result.json").write_text((sub_out / "result.json").read_text())
    print(json.dumps(clock.cpu), flush=True)
    from grader import cli  # noqa: PLC0415 - as `grader` ends (absent before the change: nothing done)
    getattr(cli, "leave_heap_to_exit", lambda: None)()


def run_once(submission: str, dump: Path | None = None) -> dict[str, float]:
    """One fresh interpreter through the path; its phases, the remainder and the total."""
    argv = [sys.executable, __file__, "--child", "--submission", submission] + (["--dump", str(dump)] if dump else [])
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    env.pop("PYTHONDONTWRITEBYTECODE", None)        # as installed: compiled once (the warm-up), not every run
    c0 = children_cpu()
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, check=False, cwd=REPO)
    total = children_cpu() - c0
    if proc.returncode != 0:
        sys.exit(f"child failed:\n{proc.stderr}")
    phases = json.loads(proc.stdout.strip().splitlines()[-1])
    phases["rest (not named)"] = total - sum(phases.values())
    phases["total"] = total
    return phases


def summary(runs: list[dict[str, float]]) -> dict[str, float]:
    return {k: statistics.median(r.get(k, 0.0) for r in runs) for k in (*PHASES, "total")}


def print_table(now: dict[str, float], before: dict[str, float] | None, label: str) -> None:
    head = f"{'phase':<28} {'before':>9} {'after':>9}" if before else f"{'phase':<28} {label:>9}"
    print(head)
    for phase in (*PHASES, "total"):
        cell = f"{now.get(phase, 0.0):8.3f}s"
        print(f"{phase:<28} {before.get(phase, 0.0):8.3f}s {cell}" if before else f"{phase:<28} {cell}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--submission", default="reference", help="a folder of fixtures/bags/lab3")
    ap.add_argument("--json", type=Path, help="save the runs here")
    ap.add_argument("--baseline", type=Path, help="a --json file of another checkout, printed beside")
    ap.add_argument("--dump", type=Path, help="(with --child) write the report, result and table here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.submission, args.dump)
        return 0
    run_once(args.submission)              # warm-up: the OS page cache, matplotlib's font cache
    runs = [run_once(args.submission) for _ in range(args.runs)]
    load = os.getloadavg()[0]
    now = summary(runs)
    print(f"grader check's post-scenario path, {args.submission}, median CPU of {args.runs} fresh "
          f"processes (load {load:.1f}; totals {min(r['total'] for r in runs):.2f}-{max(r['total'] for r in runs):.2f} s)\n")
    before = summary(json.loads(args.baseline.read_text())["runs"]) if args.baseline else None
    print_table(now, before, "CPU")
    if args.json:
        args.json.write_text(json.dumps({"submission": args.submission, "load": load, "runs": runs}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
