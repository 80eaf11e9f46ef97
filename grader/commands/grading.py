"""`grader grade` (instructor batch), `grader check` (student self-check), `grader regrade` (offline),
`grader merge` (the shards of a batch graded on several machines)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from grader.errors import GraderError
from grader import api
from grader.api.batch import INTAKE_KINDS, by_other_grader, parse_size
from grader.api.rubrics import rubric_for_lab
from grader.commands.options import positive as _positive, time_scale_option as _time_scale_option
from grader.commands.similarity import add_grade_options, grade_settings, say_comparison

if TYPE_CHECKING:
    from grader.api.batch import GradedSubmission


#: `grader check`'s exit status when an item could not be measured because the machine was
#: starved of CPU (0: every item passed; 1: some item did not)
STARVED_EXIT = 3


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
                   help="scenarios (and builds) run at once across the batch (default: twice the CPUs the grader is given, its cgroup's quota in a container)")
    g.add_argument("--only", nargs="+", metavar="ID", help="grade only these submission ids")
    g.add_argument("--shard", type=_shard, default=None, metavar="K/N",
                   help="grade only shard K of N (a stable 1/N of the submissions, by id; "
                        "combine the outputs with `grader merge`)")
    g.add_argument("--resume", action="store_true", help="skip submissions that already have a result.json in OUT (except those with items the "
                        "grading machine was too busy to measure: they are graded again)")
    g.add_argument("--cache-dir", type=Path, default=None, help="build cache folder")
    g.add_argument("--no-reuse", action="store_true",
                   help="run every scenario, even when an identical one was recorded before")
    _cache_cap_option(g)
    _time_scale_option(g)

    add_grade_options(g)
    g.set_defaults(func=run_grade)

    c = sub.add_parser("check", help="self-check your own workspace (public items only)",
                       description="Runs the lab's public auto-graded items on your workspace, prints a table "
                                   "with a hint per item and writes a report. Exit 0 only when all pass; 3 when the "
                                   "machine was too busy to measure an item's timing (run it again when quiet).")
    c.add_argument("workspace", type=Path, nargs="?", default=Path("."), help="your workspace (default: .)")
    c.add_argument("--lab", default=None, help="lab id, e.g. enee467-lab3 (see `grader labs`)")
    c.add_argument("--rubric", type=Path, default=None, help="rubric YAML instead of --lab")
    c.add_argument("-o", "--out", type=Path, default=None, help="report folder (default: WORKSPACE/.grader-check)")
    c.add_argument("--cache-dir", type=Path, default=None)
    c.add_argument("--jobs", type=_positive, default=None, help="scenarios run at once (default: one per CPU the grader is given on simulated time, twice that at --time-scale 1; its cgroup's quota in a container)")
    c.add_argument("--no-reuse", action="store_true",
                   help="run every scenario, even those whose packages did not change since the last check")
    _cache_cap_option(c)
    _time_scale_option(c)
    c.set_defaults(func=run_check)

    r = sub.add_parser("regrade", help="recompute grades from recorded bags (no ROS needed)",
                       description="Re-run analyzers and scoring on the bags of an earlier `grader grade` output "
                                   "(OUT or OUT/<id>), e.g. after fixing a rubric threshold.")
    r.add_argument("path", type=Path, help="OUT folder of a batch, or OUT/<id> of one submission")
    r.add_argument("--rubric", type=Path, required=True)
    r.set_defaults(func=run_regrade)

    m = sub.add_parser("merge", help="combine the outputs of `grader grade --shard` runs",
                       description="Copy the submissions of several grading outputs (shards) into one, "
                                   "then rebuild grades.csv and index.html.")
    m.add_argument("parts", type=Path, nargs="+", help="the shard outputs OUT_1 ... OUT_N")
    m.add_argument("-o", "--out", type=Path, required=True)
    m.add_argument("--rubric", type=Path, required=True, help="the rubric every shard was graded with")

    add_grade_options(m)
    m.set_defaults(func=run_merge)


def _cache_cap_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cache-max-size", type=_size, default=None, metavar="SIZE",
                        help="when done, remove the least recently used cache entries until the cache "
                             "fits SIZE (e.g. 5G, 500M; 0: no cap; default $GRADER_CACHE_MAX_SIZE or 5G)")


def _size(text: str) -> str:
    try:
        parse_size(text)
    except GraderError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _intake_options(g: argparse.ArgumentParser) -> None:
    g.add_argument("--roster", type=Path, help="roster CSV (Canvas gradebook export, Gradescope roster, any "
                                               "CSV): each submission is matched to a student")
    g.add_argument("--map", action="append", default=[], metavar="FIELD=COLUMN[,...]",
                   help="which roster column holds what (as for `grader scores export`)")
    g.add_argument("--classroom-prefix", metavar="PREFIX",
                   help="GitHub Classroom clones: the assignment prefix (lab3- for lab3-alice -> alice)")
    g.add_argument("--intake", choices=INTAKE_KINDS, default="auto",
                   help="what SUBMISSIONS is (default: recognised by its shape)")
    g.add_argument("--due", metavar="DATE",
                   help="replaces the due date of the rubric's late policy, e.g. '2025-02-14 23:59'")
    g.add_argument("--timezone", metavar="ZONE", help="time zone of --due (default: the rubric's), e.g. America/New_York")


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
        self.done = min(self.total, self.done + 1)      # a submission graded again counts once
        self.current = text
        self._draw()

    def close(self) -> None:
        if self.tty:
            sys.stderr.write("\n")


def run_grade(args: argparse.Namespace) -> int:
    similarity = grade_settings(args)      # a wrong --known/--boilerplate is said before any grading
    progress: Progress | None = None

    def found(intake: Any) -> None:
        print(intake.table(), flush=True)

    def start(selected: int, done_before: int) -> None:
        nonlocal progress
        progress = Progress(selected)
        progress.done = done_before

    def done(sid: str, graded: Any, error: str | None) -> None:
        assert progress is not None
        progress.advance(f"{sid}: ERROR {error}" if error and graded is None and "interrupted" not in error
                         else f"{sid}: {graded.result.auto_score:g}/{graded.result.auto_max:g}" if graded
                         else f"{sid}: {error}")

    def status(text: str) -> None:
        if progress is not None:
            progress.status(text)

    try:
        batch = api.grade(args.submissions, args.rubric, args.out, jobs=args.jobs, only=args.only, shard=args.shard,
                          resume=args.resume, reuse=not args.no_reuse, cache_dir=args.cache_dir,
                          time_scale=args.time_scale, intake=args.intake, roster=args.roster, roster_map=args.map,
                          classroom_prefix=args.classroom_prefix, due=args.due, timezone=args.timezone,
                          cache_max_size=args.cache_max_size, similarity=similarity, on_intake=found,
                          on_start=start, on_done=done, progress=status, on_notice=_notice)
    finally:
        if progress is not None:
            progress.close()
    say_comparison(args.out, batch.similarity)
    for sid, msg in batch.failures.items():
        print(f"grader: {sid}: {msg}", file=sys.stderr)
    for name, why in batch.refused.items():
        print(f"grader: {name}: not graded: {why}", file=sys.stderr)
    print(f"wrote {args.out / 'grades.csv'} and {args.out / 'index.html'}")
    if batch.interrupted:
        print("grader: interrupted; finished submissions are saved; rerun with --resume to continue",
              file=sys.stderr)
        return 130
    return 1 if batch.failures or batch.refused else 0


def run_check(args: argparse.Namespace) -> int:
    from grader.api.pipeline import check_table, contract_lines  # noqa: PLC0415 - api.pipeline loads grading.pipeline, pandas, numpy (424 ms CPU), only on this path

    if args.rubric is None and args.lab is None:
        raise GraderError("say which lab to check: --lab enee467-lab3 (or --rubric FILE).")
    rubric = api.load_rubric(args.rubric or rubric_for_lab(args.lab))
    names = contract_lines(rubric)
    if names:
        print("\n".join(names))
    progress = Progress(1)
    graded = api.check(args.workspace, rubric=rubric, out=args.out, jobs=args.jobs, cache_dir=args.cache_dir,
                       reuse=not args.no_reuse, time_scale=args.time_scale, cache_max_size=args.cache_max_size,
                       progress=progress.status, on_notice=_notice)
    progress.close()
    ok, table = check_table(graded, rubric)
    print("\n".join(table))
    print(f"report: {graded.out / 'report.html'}")
    if graded.result.starved:
        print(f"not measured: {len(graded.result.starved)} item(s) ({', '.join(graded.result.starved)}) need a "
              "quieter machine: it was too busy to measure their timing; run `grader check` again when it is quiet")
        return STARVED_EXIT
    return 0 if ok else 1


def _notice(text: str) -> None:
    print(f"grader: {text}", file=sys.stderr)


def run_merge(args: argparse.Namespace) -> int:
    rubric = api.load_rubric(args.rubric)
    similarity = grade_settings(args)
    merged = api.merge(args.parts, args.out, rubric, similarity=similarity)
    say_comparison(args.out, merged.similarity)
    print(f"merged {len(merged.merged)} submissions from {len(args.parts)} outputs into {args.out}")
    return 0


def run_regrade(args: argparse.Namespace) -> int:
    other_made: list[str] = []

    def done(g: GradedSubmission) -> None:
        other = by_other_grader(g.recordings)
        note = f"  (rests on recordings another grader made: {', '.join(other)})" if other else ""
        print(f"{g.id}: {g.result.auto_score:g}/{g.result.auto_max:g}{note}")
        other_made.extend([g.id] if other else [])

    regraded = api.regrade(args.path, args.rubric, on_done=done)
    if other_made:
        # the grades are recomputed by this grader, from recordings an earlier (or other) one made
        print(f"note: {len(other_made)} of {len(regraded)} grades rest on recordings made by another grader "
              "version or ROS installation (each report says which, result.json: recordings_by_other_grader); "
              "`grader grade --no-reuse` records them again with this one")
    return 0
