"""`grader scores merge` (TAs: manual scores into a batch) and `grader scores export`
(instructors: the batch as a Canvas / Gradescope / spreadsheet gradebook). A front-end (it lived
in ``grader.scores``, whose functions it calls through ``grader.api.tools``)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from grader.errors import GraderError
from grader.api.tools import INTAKE_FILE, export_gradebook, merge_manual_scores, parse_mapping, read_roster


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("scores", help="merge manual scores; export a gradebook for Canvas/Gradescope",
                       description="Manual scores and gradebooks for a batch folder written by `grader grade`.")
    s.set_defaults(func=lambda _args: (s.print_help(), 2)[1])
    cmds = s.add_subparsers(dest="scores_command", metavar="COMMAND")

    m = cmds.add_parser(
        "merge", help="merge a TA's CSV of manual scores into OUT",
        description="Checks the whole CSV first (every problem is listed with its line; nothing is "
                    "written while any remains), then updates each submission's result.json, "
                    "report.html and manual_scores.json and rewrites grades.csv and index.html, all "
                    "files or none. Columns: submission, one per manual item (points; an empty cell "
                    "keeps the earlier score, 'pending' clears it), optionally '<item> comment'. "
                    "A filled-in copy of grades.csv works as it is.")
    m.add_argument("out", type=Path, help="the batch folder (OUT of `grader grade`)")
    m.add_argument("csv", type=Path, help="the TA's CSV")
    m.add_argument("--dry-run", action="store_true", help="check and show the changes, write nothing")
    m.set_defaults(func=run_merge)

    e = cmds.add_parser(
        "export", help="write a gradebook CSV (canvas, gradescope-csv, long)",
        description="Writes the batch's grades for an LMS. Submissions without a roster row, roster "
                    "rows without a submission and incomplete grades are listed on stderr, not "
                    "written.")
    e.add_argument("out", type=Path, help="the batch folder (OUT of `grader grade`)")
    e.add_argument("--format", dest="fmt", required=True, choices=["canvas", "gradescope-csv", "long"])
    e.add_argument("--roster", type=Path, help="roster CSV (required for canvas and gradescope-csv)")
    e.add_argument("--map", action="append", default=[], metavar="FIELD=COLUMN[,...]",
                   help="which roster column holds what: submission, name, id, sis_user_id, "
                        "sis_login_id, section, email, sid (e.g. --map submission=github_username,"
                        "name=Student); Canvas export column names are found without it")
    e.add_argument("--assignment", help='Canvas column name with the assignment id, e.g. "Lab 3 (12345)" '
                                        "(default: the lab's title)")
    e.add_argument("--partial", action="store_true",
                   help="also export submissions whose manual items are not all graded (points so far)")
    e.add_argument("--allow-pending", action="store_true",
                   help="export even while manual items are pending: the complete grades only, the others "
                        "listed (without it, canvas and gradescope-csv refuse)")
    e.add_argument("-o", "--output", type=Path, help="output file (default: OUT/gradebook-FORMAT.csv)")
    e.set_defaults(func=run_export)


def run_merge(args: argparse.Namespace) -> int:
    report = merge_manual_scores(args.out, args.csv, dry_run=args.dry_run)
    for change in report.changes:
        print(change.describe())
    verb = "would write" if report.dry_run else "wrote"
    if report.written:
        names = [str(p.relative_to(report.out)) for p in report.written]
        if len(names) > 10:
            subs = {Path(n).parts[0] for n in names if len(Path(n).parts) > 1}
            names = [f"{len(subs)} submission folder(s)"] + [n for n in names if "/" not in n]
        print(f"{verb} {len(report.written)} file(s): " + ", ".join(names))
    else:
        print(f"{report.sheet.name}: nothing to change ({report.rows} row(s) already merged)")
    if report.pending:
        shown = "; ".join(f"{sid} ({', '.join(items)})" for sid, items in list(report.pending.items())[:10])
        more = f"; and {len(report.pending) - 10} more" if len(report.pending) > 10 else ""
        print(f"{len(report.pending)} submission(s) still have pending manual items: {shown}{more}")
    return 0


def _has_intake(out: Path) -> bool:
    """The batch came from an LMS download (grader grade --roster): submissions find their roster
    rows by the ids they kept, so the roster needs no submission column."""
    return any(out.glob(f"*/{INTAKE_FILE}"))


def run_export(args: argparse.Namespace) -> int:
    if args.map and not args.roster:
        raise GraderError("--map describes the roster's columns: give the roster with --roster")
    roster = read_roster(args.roster, parse_mapping(args.map), require_submission=not _has_intake(args.out)) \
        if args.roster else None
    report = export_gradebook(args.out, args.fmt, roster=roster, path=args.output,
                              assignment=args.assignment, partial=args.partial, allow_pending=args.allow_pending)
    for line in report.warnings():
        print(f"grader: warning: {line}", file=sys.stderr)
    for line in report.late:
        print(line)
    print(report.summary())
    return 0
