"""`grader grade` (instructor batch), `grader check` (student self-check), `grader regrade` (offline)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from grader.errors import GraderError


def register(sub: argparse._SubParsersAction) -> None:
    g = sub.add_parser("grade", help="grade a folder of submissions against a rubric",
                       description="Build each submission, run the rubric's scenarios against the reference "
                                   "turtlesim while recording bags, analyze, score; writes OUT/<id>/result.json, "
                                   "report.html, bags and logs, plus OUT/grades.csv and OUT/index.html.")
    g.add_argument("submissions", type=Path,
                   help="a Canvas download (zip or folder), a Gradescope export, a folder of GitHub Classroom "
                        "clones (with --classroom-prefix), a folder with one folder or archive per student, "
                        "or one submission")
    g.add_argument("--rubric", type=Path, required=True, help="rubric YAML (e.g. rubrics/enee467_lab3.yaml)")
    g.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    _intake_options(g)
    g.add_argument("--jobs", type=_positive, default=None,
                   help="scenarios (and builds) run at once across the batch (default: twice the cores)")
    g.add_argument("--only", nargs="+", metavar="ID", help="grade only these submission ids")
    g.add_argument("--shard", type=_shard, default=None, metavar="K/N",
                   help="grade only shard K of N (a stable 1/N of the submissions, by id; "
                        "combine the outputs with `grader merge`)")
    g.add_argument("--resume", action="store_true", help="skip submissions that already have a result.json in OUT")
    g.add_argument("--cache-dir", type=Path, default=None, help="build cache folder")
    g.add_argument("--no-reuse", action="store_true",
                   help="run every scenario, even when an identical one was recorded before")
    _time_scale_option(g)
    from grader.similarity.cli import add_grade_options

    add_grade_options(g)
    g.set_defaults(func=run_grade)

    c = sub.add_parser("check", help="self-check your own workspace (public items only)",
                       description="Runs the lab's public auto-graded items on your workspace, prints a table "
                                   "with a hint per item and writes a report. Exit 0 only when all pass.")
    c.add_argument("workspace", type=Path, nargs="?", default=Path("."), help="your workspace (default: .)")
    c.add_argument("--lab", default=None, help="lab id, e.g. enee467-lab3 (see `grader labs`)")
    c.add_argument("--rubric", type=Path, default=None, help="rubric YAML instead of --lab")
    c.add_argument("-o", "--out", type=Path, default=None, help="report folder (default: WORKSPACE/.grader-check)")
    c.add_argument("--cache-dir", type=Path, default=None)
    c.add_argument("--jobs", type=_positive, default=None, help="scenarios run at once (default: twice the cores)")
    c.add_argument("--no-reuse", action="store_true",
                   help="run every scenario, even those whose packages did not change since the last check")
    _time_scale_option(c)
    c.set_defaults(func=run_check)

    r = sub.add_parser("regrade", help="recompute grades from recorded bags (no ROS needed)",
                       description="Re-run analyzers and scoring on the bags of an earlier `grader grade` output "
                                   "(OUT or OUT/<id>), e.g. after fixing a rubric threshold.")
    r.add_argument("path", type=Path, help="OUT folder of a batch, or OUT/<id> of one submission")
    r.add_argument("--rubric", type=Path, required=True)
    r.set_defaults(func=run_regrade)


def _intake_options(g: argparse.ArgumentParser) -> None:
    from grader.intake.batch import KINDS

    g.add_argument("--roster", type=Path, help="roster CSV (Canvas gradebook export, Gradescope roster, any "
                                               "CSV): each submission is matched to a student")
    g.add_argument("--map", action="append", default=[], metavar="FIELD=COLUMN[,...]",
                   help="which roster column holds what (as for `grader scores export`)")
    g.add_argument("--classroom-prefix", metavar="PREFIX",
                   help="GitHub Classroom clones: the assignment prefix (lab3- for lab3-alice -> alice)")
    g.add_argument("--intake", choices=KINDS, default="auto",
                   help="what SUBMISSIONS is (default: recognised by its shape)")
    g.add_argument("--due", metavar="DATE",
                   help="replaces the due date of the rubric's late policy, e.g. '2025-02-14 23:59'")
    g.add_argument("--timezone", metavar="ZONE", help="time zone of --due (default: the rubric's), e.g. America/New_York")


def _due_override(args: argparse.Namespace, rubric) -> dict | None:
    """``--due``/``--timezone`` checked against the rubric's late policy."""
    from pydantic import ValidationError

    if args.due is None:
        if args.timezone:
            raise GraderError("--timezone goes with --due (the rubric's late policy has its own time zone)")
        return None
    if rubric.late is None:
        raise GraderError(f"--due replaces the due date of the rubric's late policy, and {args.rubric} has "
                          "none: add a late: section to the rubric (rubrics/README.md, \"Late policy\")")
    try:
        rubric.late.with_due(args.due, args.timezone)
    except ValidationError as exc:
        raise GraderError("--due: " + "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())) from None
    return {"due": args.due, "timezone": args.timezone}


def _time_scale_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--time-scale", type=_time_scale, default=1.0, metavar="K",
                        help="run scenarios K times faster than real time on simulated time (e.g. 4), "
                             "each one that may: a node paced by the wall clock runs at 1x, and the "
                             "result says so (default 1: real time)")


def _time_scale(text: str) -> float:
    from grader.sim.cli import MAX_TIME_SCALE

    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not 1.0 <= value <= MAX_TIME_SCALE:
        raise argparse.ArgumentTypeError(f"expected a speed-up between 1 and {MAX_TIME_SCALE:g} (e.g. 4), "
                                         f"got {text!r}")
    return value


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def _shard(text: str) -> tuple[int, int]:
    try:
        k, n = (int(part) for part in text.split("/"))
    except ValueError:
        k = n = 0
    if not (n >= 1 and 1 <= k <= n):
        raise argparse.ArgumentTypeError(f"expected K/N with 1 <= K <= N (e.g. 2/4), got {text!r}")
    return k, n


class Progress:
    """A one-line progress bar on stderr (plain lines when stderr is not a terminal)."""

    def __init__(self, total: int) -> None:
        self.total, self.done, self.t0 = total, 0, time.monotonic()
        self.tty = sys.stderr.isatty()
        self.current = ""

    def _draw(self) -> None:
        width = 24
        filled = int(width * self.done / max(1, self.total))
        elapsed = time.monotonic() - self.t0
        line = (f"[{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} "
                f"{elapsed:5.0f}s  {self.current}")
        if self.tty:
            sys.stderr.write("\r\033[K" + line[:150])
        else:
            sys.stderr.write(line + "\n")
        sys.stderr.flush()

    def status(self, text: str) -> None:
        self.current = text
        self._draw()

    def advance(self, text: str) -> None:
        self.done += 1
        self.current = text
        self._draw()

    def close(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def run_grade(args: argparse.Namespace) -> int:
    from grader.grading.batch import grade_batch
    from grader.grading.outputs import write_batch_outputs
    from grader.grading.schedule import Slots, default_jobs
    from grader.grading.shards import in_shard, write_shard_note
    from grader.intake.batch import WORK_DIR, read_intake
    from grader.report.result import atomic_write
    from grader.rubric.load import load_rubric
    from grader.scores.roster import parse_mapping, read_roster

    from grader.similarity.cli import after_grading, grade_settings

    rubric = load_rubric(args.rubric)
    similarity = grade_settings(args)
    due = _due_override(args, rubric)
    if args.map and not args.roster:
        raise GraderError("--map describes the roster's columns: give the roster with --roster")
    roster = read_roster(args.roster, parse_mapping(args.map), require_submission=False) if args.roster else None
    args.out.mkdir(parents=True, exist_ok=True)
    intake = read_intake(args.submissions, rubric, work=args.out / WORK_DIR, roster=roster,
                         classroom_prefix=args.classroom_prefix, kind=args.intake)
    print(intake.table(), flush=True)
    atomic_write(args.out / "intake.csv", intake.csv_text())
    subs = intake.gradable
    refused = {a.original[0]: a.refused or "" for a in intake.refused}
    if args.only:
        subs = [s for s in subs if s.id in set(args.only)]
        if not subs:
            raise GraderError(f"none of {', '.join(args.only)} is among the submissions in {args.submissions}.")
        refused = {}
    if args.shard:
        subs = [s for s in subs if in_shard(s.id, *args.shard)]
        write_shard_note(args.out, rubric, *args.shard)
    todo = [s for s in subs if not (args.resume and (args.out / s.id / "result.json").exists())]
    progress = Progress(len(subs))
    progress.done = len(subs) - len(todo)

    def done(sid: str, graded, error: str | None) -> None:
        progress.advance(f"{sid}: ERROR {error}" if error and graded is None and "interrupted" not in error
                         else f"{sid}: {graded.result.auto_score:g}/{graded.result.auto_max:g}" if graded
                         else f"{sid}: {error}")

    failures: dict[str, str] = {}
    interrupted = False
    try:
        failures = grade_batch(todo, rubric, args.out, slots=Slots(args.jobs or default_jobs()),
                               cache_dir=args.cache_dir, reuse=not args.no_reuse, on_done=done,
                               progress=progress.status, time_scale=args.time_scale, due_override=due)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        progress.close()
        write_batch_outputs(args.out, rubric)
    for sid, msg in failures.items():
        print(f"grader: {sid}: {msg}", file=sys.stderr)
    for name, why in refused.items():
        print(f"grader: {name}: not graded: {why}", file=sys.stderr)
    if not interrupted and not args.shard:     # a shard is compared once merged (grader merge)
        after_grading(args.out, rubric, similarity)
    print(f"wrote {args.out / 'grades.csv'} and {args.out / 'index.html'}")
    if interrupted or any("interrupted" in m for m in failures.values()):
        print("grader: interrupted; finished submissions are saved; rerun with --resume to continue",
              file=sys.stderr)
        return 130
    return 1 if failures or refused else 0


def run_check(args: argparse.Namespace) -> int:
    from grader.grading.outputs import print_check_table
    from grader.grading.pipeline import grade_submission
    from grader.labs import rubric_for_lab
    from grader.rubric.load import load_rubric

    if args.rubric is None and args.lab is None:
        raise GraderError("say which lab to check: --lab enee467-lab3 (or --rubric FILE).")
    rubric = load_rubric(args.rubric or rubric_for_lab(args.lab))
    from grader.grading.outputs import print_contract

    print_contract(rubric)
    ws = args.workspace.resolve()
    out = (args.out or ws / ".grader-check").resolve()
    from grader.grading.schedule import Slots, default_jobs

    progress = Progress(1)
    graded = grade_submission(ws, rubric, out, cache_dir=args.cache_dir, public_only=True,
                              sid="check", progress=progress.status, slots=Slots(args.jobs or default_jobs()),
                              reuse=not args.no_reuse, time_scale=args.time_scale)
    progress.close()
    ok = print_check_table(graded, rubric)
    print(f"report: {graded.out / 'report.html'}")
    return 0 if ok else 1


def run_regrade(args: argparse.Namespace) -> int:
    from grader.grading.outputs import write_batch_outputs
    from grader.grading.pipeline import SCENARIOS_DIR, regrade_submission
    from grader.rubric.load import load_rubric

    rubric = load_rubric(args.rubric)
    path = args.path
    if (path / SCENARIOS_DIR).is_dir():
        graded = regrade_submission(path, rubric)
        print(f"{graded.id}: {graded.result.auto_score:g}/{graded.result.auto_max:g}")
        return 0
    subs = sorted(p for p in path.iterdir() if (p / SCENARIOS_DIR).is_dir()) if path.is_dir() else []
    if not subs:
        raise GraderError(f"{path} holds no graded submissions (no */{SCENARIOS_DIR}/ folders).")
    for sub in subs:
        graded = regrade_submission(sub, rubric)
        print(f"{graded.id}: {graded.result.auto_score:g}/{graded.result.auto_max:g}")
    write_batch_outputs(path, rubric)
    return 0
