"""The grading process's own CPU after the scenarios, phase by phase, offline (no ROS).

What ``grader check`` spends once the scenarios have recorded their bags (issue 35: a graded
Lab 3 submission's CPU): the CLI's start-up and imports, the rubric, each bag read into
DataFrames, the analyzers, the contract check, the behaviour fingerprint, the replay data,
scoring, result.json, report.html (its figures apart), the self-check table. Each run is a fresh
interpreter (``--child``), as a real ``grader check`` is, so the imports and matplotlib's set-up
are counted where they are paid (with the modules' bytecode cached, as in an installed grader:
compiling grader's ~180 modules again in every run costs ~0.25 s more); its total is the
child's whole CPU (``RUSAGE_CHILDREN``), so what no phase names is the remainder (the
interpreter's start and exit among it). The submission's committed bags
(``fixtures/bags/lab3/<submission>``) stand in for its scenarios; the post-scenario calls are
those of ``grader.grading.pipeline.grade_submission`` in the student's view (public items).

``--against DIR`` runs another checkout's grader (e.g. the branch point, ``git worktree add``)
through the same path, its runs interleaved with this one's, and prints both side by side.

    PYTHONPATH=$PWD .venv/bin/python benchmarks/bench_post.py [--runs 5] [--submission reference]
        [--against OTHER_CHECKOUT] [--bags WORKSPACE/.grader-check/check/scenarios]
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

#: the checkout measured: this one, or (in a child run for ``--against``) the other one
REPO = Path(os.environ.get("BENCH_POST_CHECKOUT") or Path(__file__).resolve().parents[1])
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


def child(submission: str, dump: Path | None, bags: Path | None = None) -> None:
    """One post-scenario path in this (fresh) interpreter; prints the phases' CPU as JSON."""
    clock = Clock()
    with clock.phase("start-up (CLI, imports)"):
        from grader import cli  # noqa: PLC0415 - timed: what `grader check` imports
        cli.build_parser()
        freeze = getattr(cli, "freeze_heap", lambda: None)        # as the program does (absent before it)
        freeze()
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
        root = LAB3_BAGS
        if bags is not None:              # a graded folder's scenarios/ (e.g. WORKSPACE/.grader-check/check/scenarios)
            root = out / "bags"
            root.mkdir()
            (root / submission).symlink_to(bags.resolve())
        sid = layout(root, out / "graded", [submission])[0]
        out = out / "graded"
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
            if hasattr(outputs, "check_table"):          # the table's lines (newer grader)
                print("\n".join(outputs.check_table(graded, rubric)[1]))
            else:                                        # printed (older grader)
                outputs.print_check_table(graded, rubric)
        if dump is not None:
            dump.mkdir(parents=True, exist_ok=True)
            (dump / "table.txt").write_text(table.getvalue())
            (dump / "report.html").write_text((sub_out / "report.html").read_text())
            (dump / "result.json").write_text((sub_out / "result.json").read_text())
    print(json.dumps(clock.cpu), flush=True)
    freeze()                                                     # as the program ends


def run_once(checkout: Path, submission: str, bags: Path | None = None) -> dict[str, float]:
    """One fresh interpreter through the path with ``checkout``'s grader; its phases, the
    remainder and the total."""
    argv = [sys.executable, __file__, "--child", "--submission", submission] + (["--bags", str(bags)] if bags else [])
    env = {**os.environ, "BENCH_POST_CHECKOUT": str(checkout), "PYTHONPATH": str(checkout)}
    env.pop("PYTHONDONTWRITEBYTECODE", None)        # as installed: compiled once (the warm-up), not every run
    c0 = children_cpu()
    proc = subprocess.run(argv, capture_output=True, text=True, env=env, check=False, cwd=checkout)
    total = children_cpu() - c0
    if proc.returncode != 0:
        sys.exit(f"child failed ({checkout}):\n{proc.stderr}")
    phases = json.loads(proc.stdout.strip().splitlines()[-1])
    phases["rest (not named)"] = total - sum(phases.values())
    phases["total"] = total
    return phases


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--submission", default="reference", help="a folder of fixtures/bags/lab3")
    ap.add_argument("--against", type=Path, help="another checkout (e.g. `git worktree add /tmp/base main`): "
                    "its runs interleaved with this one's, printed beside them")
    ap.add_argument("--bags", type=Path, help="grade these recordings instead: a graded folder's scenarios/ "
                    "(e.g. WORKSPACE/.grader-check/check/scenarios of a real grader check)")
    ap.add_argument("--dump", type=Path, help="(with --child) write the report, result and table here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.submission, args.dump, args.bags)
        return 0
    checkouts = ([args.against.resolve()] if args.against else []) + [REPO]
    runs: dict[Path, list[dict[str, float]]] = {c: [] for c in checkouts}
    for c in checkouts:
        run_once(c, args.submission, args.bags)        # warm-up: bytecode, page cache, matplotlib's font cache
    for _ in range(args.runs):                          # interleaved: the machine's load hits both alike
        for c in checkouts:
            runs[c].append(run_once(c, args.submission, args.bags))
    what = args.bags or f"fixtures/bags/lab3/{args.submission}"
    print(f"grader check's post-scenario path on {what}: median CPU s of {args.runs} fresh processes "
          f"per checkout (load {os.getloadavg()[0]:.1f})\n")
    names = [("against" if c != REPO else "this checkout") for c in checkouts]
    print(f"{'phase':<26}" + "".join(f"{n:>15}" for n in names))
    for phase in (*PHASES, "total"):
        print(f"{phase:<26}" + "".join(f"{statistics.median(r[phase] for r in runs[c]):15.3f}" for c in checkouts))
    for c, n in zip(checkouts, names):
        totals = [r["total"] for r in runs[c]]
        print(f"  {n}: {c} (totals {min(totals):.2f}-{max(totals):.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
