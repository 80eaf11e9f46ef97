"""``grader scores export``: the batch's grades as a gradebook file an LMS imports.

Formats:

* ``canvas``: Canvas's gradebook import CSV. The header is ``Student, ID, SIS User ID,
  SIS Login ID, Section`` and one column for the lab, named like Canvas's own export
  (``Lab 3 (12345)``: Canvas matches the number in parentheses to the assignment id, else the
  exact name, else it creates a new assignment); the second row is ``Points Possible`` with
  the lab's maximum; then one row per student with the lab total. Canvas identifies a student
  by ID, then SIS User ID, then SIS Login ID, then name, so each row needs one of them.
* ``gradescope-csv``: the columns of Gradescope's per-assignment score export (``Name, SID,
  Email, Sections, Total Score, Max Points, Status``, then one ``<item>: <title> (<max> pts)``
  column per scored item); Gradescope matches students by Email or SID.
* ``long``: one row per student and item (plus a ``total`` row), every status included, for a
  spreadsheet or pandas. The roster is optional here.

Submissions without a roster row, roster rows without a submission and (unless ``partial``)
submissions whose manual items are not all graded are not written but listed in the report,
never dropped silently: a blank cell in a Canvas import could erase a grade already there.
"""

from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

from grader.errors import GraderError
from grader.report.batch import load_results
from grader.report.result import atomic_write
from grader.rubric.score import Result
from grader.scores.errors import ScoresError
from grader.scores.roster import Roster, Student

FORMATS = ("canvas", "gradescope-csv", "long")
CANVAS_STUDENT_COLUMNS = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
CANVAS_POINTS_ROW = "    Points Possible"           # as Canvas's own export writes it
GRADESCOPE_COLUMNS = ["Name", "SID", "Email", "Sections", "Total Score", "Max Points", "Status"]
LONG_COLUMNS = ["submission", "student", "student_id", "sis_user_id", "sis_login_id", "section",
                "email", "sid", "item", "title", "kind", "points", "max_points", "status", "feedback"]
_CANVAS_ID = re.compile(r"\s\(\d+\)$")


@dataclass
class ExportReport:
    path: Path
    format: str
    rows: int = 0                                            # students written
    no_roster_row: list[str] = field(default_factory=list)    # submission ids
    no_submission: list[Student] = field(default_factory=list)
    incomplete: list[str] = field(default_factory=list)       # left out: manual items pending
    notes: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """One line per thing left out, for stderr."""
        out = [f"submission {s} has no roster row: not exported" for s in self.no_roster_row]
        out += [f"roster {s.describe()}: no graded submission" for s in self.no_submission]
        out += [f"submission {s}: manual items still pending, left out (--partial exports the "
                f"points so far)" for s in self.incomplete]
        return out + self.notes

    def summary(self) -> str:
        return (f"wrote {self.path} ({self.format}): {self.rows} student(s); "
                f"{len(self.no_roster_row)} submission(s) without a roster row, "
                f"{len(self.no_submission)} roster row(s) without a submission, "
                f"{len(self.incomplete)} incomplete left out")


def _num(value: float | None) -> str:
    return "" if value is None else f"{round(value, 2):g}"


def _text(value: str) -> str:
    """Free text for a spreadsheet: a leading = + - @ would make Excel run it as a formula."""
    return "'" + value if value[:1] in ("=", "+", "-", "@", "\t", "\r") else value


def export_gradebook(out: str | os.PathLike[str], fmt: str, *, roster: Roster | None = None,
                     path: str | os.PathLike[str] | None = None, assignment: str | None = None,
                     partial: bool = False) -> ExportReport:
    """Write the gradebook of batch ``out`` in ``fmt`` (see the module docstring) to ``path``
    (default ``OUT/gradebook-<fmt>.csv``). ``assignment``: Canvas column name, e.g.
    ``"Lab 3 (12345)"`` (default: the lab's title)."""
    out = Path(out)
    if fmt not in FORMATS:
        raise GraderError(f"unknown format {fmt!r}; the formats are {', '.join(FORMATS)}")
    if roster is None and fmt != "long":
        raise GraderError(f"--format {fmt} needs --roster (which student handed in which submission)")
    results = load_results(out)
    if not results:
        raise GraderError(f"{out} holds no graded submissions (no <id>/result.json)")
    labs = sorted({r.lab for r in results.values()})
    if len(labs) > 1:
        raise GraderError(f"{out} holds results of several labs ({', '.join(labs)})")
    report = ExportReport(Path(path) if path else out / f"gradebook-{fmt}.csv", fmt)
    pairs = _match(results, roster, report)
    if fmt != "long":
        keep = []
        for student, sid in pairs:
            if results[sid].complete or partial:
                keep.append((student, sid))
            else:
                report.incomplete.append(sid)
        pairs = keep
    writer: Callable[..., list[list[str]]] = {"canvas": _canvas, "gradescope-csv": _gradescope,
                                               "long": _long}[fmt]
    rows = writer(pairs, results, report=report, assignment=assignment, source=roster.name if roster else "")
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    # a spreadsheet opens UTF-8 without a byte-order mark as Windows-1252: the long format has one
    atomic_write(report.path, ("\ufeff" if fmt == "long" else "") + buf.getvalue())
    return report


def _match(results: Mapping[str, Result], roster: Roster | None,
           report: ExportReport) -> list[tuple[Student | None, str]]:
    """(student, submission) in roster order; what matches nothing goes into the report."""
    if roster is None:
        return [(None, sid) for sid in sorted(results)]
    by_sub = roster.by_submission()
    report.no_roster_row = sorted(sid for sid in results if sid not in by_sub)
    pairs = []
    for student in roster.students:
        if student.submission in results:
            pairs.append((student, student.submission))
        else:
            report.no_submission.append(student)
    return pairs


def _canvas(pairs, results, *, report: ExportReport, assignment: str | None, source: str) -> list[list[str]]:
    first = next(iter(results.values()))
    title = (assignment or first.title).strip()
    if not _CANVAS_ID.search(title):
        report.notes.append(f'the Canvas column "{title}" has no assignment id: Canvas will match it by '
                            'exact name or create a new assignment; pass --assignment "NAME (ID)" with '
                            "the id from the assignment's URL")
    problems = [f"line {s.line}: no Student, ID, SIS User ID or SIS Login ID value, Canvas could not "
                f"match the row ({sid})" for s, sid in pairs
                if not any(s.get(f) for f in ("name", "id", "sis_user_id", "sis_login_id"))]
    if problems:
        raise ScoresError(source, problems)
    rows = [CANVAS_STUDENT_COLUMNS + [title],
            [CANVAS_POINTS_ROW, "", "", "", "", _num(first.max_score)]]
    for student, sid in pairs:
        r = results[sid]
        rows.append([student.get("name"), student.get("id"), student.get("sis_user_id"),
                     student.get("sis_login_id"), student.get("section"),
                     _num(r.score)])            # the total, or the points so far with partial
    report.rows = len(pairs)
    return rows


def _scored_items(result: Result) -> list:
    return [i for i in result.items if i.kind in ("auto", "manual")]


def _gradescope(pairs, results, *, report: ExportReport, assignment: str | None,
                source: str) -> list[list[str]]:
    problems = [f"line {s.line}: no Email or SID value, Gradescope could not match the row ({sid})"
                for s, sid in pairs if not (s.get("email") or s.get("sid"))]
    if problems:
        raise ScoresError(source, problems)
    first = next(iter(results.values()))
    items = _scored_items(first)
    rows = [GRADESCOPE_COLUMNS + [f"{i.id}: {i.title} ({i.max_points:.1f} pts)" for i in items]]
    for student, sid in pairs:
        r = results[sid]
        by_id = {i.id: i for i in r.items}
        rows.append([student.get("name"), student.get("sid"), student.get("email"), student.get("section"),
                     _num(r.score), _num(r.max_score), "Graded" if r.complete else "Ungraded"]
                    + [_num(by_id[i.id].points) if i.id in by_id else "" for i in items])
    report.rows = len(pairs)
    return rows


def _long(pairs, results, *, report: ExportReport, assignment: str | None, source: str) -> list[list[str]]:
    rows = [list(LONG_COLUMNS)]
    for student, sid in pairs:
        who = [_text(student.get(f)) if student else "" for f in
               ("name", "id", "sis_user_id", "sis_login_id", "section", "email", "sid")]
        r = results[sid]
        for i in r.items:
            rows.append([sid, *who, i.id, _text(i.title), i.kind, _num(i.points), _num(i.max_points),
                         i.status, _text(i.feedback or "")])
        rows.append([sid, *who, "total", _text(r.title), "total", _num(r.total), _num(r.max_score),
                     "final" if r.complete else "pending", ""])
    report.rows = len(pairs)
    return rows
