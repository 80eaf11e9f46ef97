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
While manual items are pending, the canvas and gradescope-csv formats are refused altogether
(:class:`PendingScores`) unless ``allow_pending`` (the complete grades only) or ``partial``.

A submission taken from an LMS download (``grader grade --roster``, grader.intake) carries its
student's ids in result.json's ``intake``: it finds its roster row by them (Canvas ID, SIS ids,
e-mail, SID) when the roster has no ``submission`` column or another id there. Late penalties
(grader.intake.late) are off every total written; the gradescope-csv format adds the submission
time, the lateness, the penalty and where the time came from, the long format a ``late_penalty``
row, and the report lists them (``late``) for the terminal (Canvas's import takes one column).
"""

from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping

from grader.contracts.result_document import ResultDocument
from grader.errors import GraderError
from grader.report.batch import intake_docs, load_results
from grader.report.index import read_docs
from grader.report.result import atomic_write
from grader.rubric.result import Result
from grader.scores.errors import ScoresError
from grader.scores.roster import Roster, Student

FORMATS = ("canvas", "gradescope-csv", "long")
CANVAS_STUDENT_COLUMNS = ["Student", "ID", "SIS User ID", "SIS Login ID", "Section"]
CANVAS_POINTS_ROW = "    Points Possible"           # as Canvas's own export writes it
GRADESCOPE_COLUMNS = ["Name", "SID", "Email", "Sections", "Total Score", "Max Points", "Status"]
LONG_COLUMNS = ["submission", "student", "student_id", "sis_user_id", "sis_login_id", "section",
                "email", "sid", "item", "title", "kind", "points", "max_points", "status", "feedback"]
_CANVAS_ID = re.compile(r"\s\(\d+\)$")
GRADESCOPE_LATE_COLUMNS = ["Submission ID", "Submission Time", "Lateness (H:M:S)", "Late Penalty", "Time Source"]
#: roster fields an intake record's student may be found by, strongest first
_IDENTITY = ("id", "sis_user_id", "sis_login_id", "email", "sid", "submission")


class PendingScores(GraderError):
    """Manual items still pending: an LMS gradebook is not written (``allow_pending`` to)."""


@dataclass
class ExportReport:
    path: Path
    format: str
    rows: int = 0                                            # students written
    no_roster_row: list[str] = field(default_factory=list)    # submission ids
    no_submission: list[Student] = field(default_factory=list)
    incomplete: list[str] = field(default_factory=list)       # left out: manual items pending
    notes: list[str] = field(default_factory=list)
    late: list[str] = field(default_factory=list)             # one line per late penalty written

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
                     partial: bool = False, allow_pending: bool = False) -> ExportReport:
    """Write the gradebook of batch ``out`` in ``fmt`` (see the module docstring) to ``path``
    (default ``OUT/gradebook-<fmt>.csv``). ``assignment``: Canvas column name, e.g.
    ``"Lab 3 (12345)"`` (default: the lab's title). Raises :class:`PendingScores` when a
    canvas or gradescope-csv gradebook would leave out submissions with pending manual items,
    unless ``allow_pending`` (leave them out, listed) or ``partial`` (their points so far)."""
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
    docs = read_docs(out, list(results))
    pairs = _match(results, roster, report, intake_docs(docs))
    if fmt != "long":
        keep = []
        for student, sid in pairs:
            if results[sid].complete or partial:
                keep.append((student, sid))
            else:
                report.incomplete.append(sid)
        if report.incomplete and not allow_pending:
            shown = ", ".join(f"{sid} ({', '.join(i.id for i in results[sid].items if i.status == 'pending')})"
                              for sid in report.incomplete[:5])
            more = f" and {len(report.incomplete) - 5} more" if len(report.incomplete) > 5 else ""
            raise PendingScores(
                f"{len(report.incomplete)} submission(s) still have manual items pending ({shown}{more}): "
                "merge their scores first (grader scores merge), or export the complete grades only "
                "with --allow-pending (--partial: the points so far); nothing was written")
        pairs = keep
    report.late = [_late_line(sid, results[sid]) for _, sid in pairs if results[sid].late is not None]
    writer: Callable[..., list[list[str]]] = {"canvas": _canvas, "gradescope-csv": _gradescope,
                                               "long": _long}[fmt]
    rows = writer(pairs, results, report=report, assignment=assignment, source=roster.name if roster else "",
                  docs=docs)
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    # a spreadsheet opens UTF-8 without a byte-order mark as Windows-1252: the long format has one
    atomic_write(report.path, ("\ufeff" if fmt == "long" else "") + buf.getvalue())
    return report


def _late_line(sid: str, r: Result) -> str:
    late = r.late
    assert late is not None
    how = "set by hand" if late.override_points is not None else late.note
    return f"{sid}: late penalty {r.late_penalty:g} point(s): {how}"


def _match(results: Mapping[str, Result], roster: Roster | None, report: ExportReport,
           intake: Mapping[str, Mapping] | None = None) -> list[tuple[Student | None, str]]:
    """(student, submission) in roster order; what matches nothing goes into the report. A
    submission's roster row: the one with its id in ``submission``, else the one holding the
    ids its intake record kept (Canvas ID, SIS ids, e-mail, SID)."""
    if roster is None:
        return [(None, sid) for sid in sorted(results)]
    from grader.intake.match import safe_id  # noqa: PLC0415 - at the head it would close a circle: scores.export -> intake -> intake.batch -> scores -> scores.export

    owner: dict[int, str] = {}
    by_sub = roster.by_submission()
    # an intake made the id safe for a folder ("Jane Doe" -> Jane_Doe): it is still that row's
    by_sub.update({safe_id(k): v for k, v in list(by_sub.items()) if safe_id(k) not in by_sub})
    for sid in sorted(results):
        if sid in by_sub:
            owner.setdefault(by_sub[sid].line, sid)
    for sid in sorted(results):
        if sid in by_sub:
            continue
        student = _by_identity(roster, _kept_ids((intake or {}).get(sid) or {}))
        if student is not None and student.line not in owner:
            owner[student.line] = sid
    matched = set(owner.values())
    report.no_roster_row = sorted(sid for sid in results if sid not in matched)
    pairs: list[tuple[Student | None, str]] = []
    for student in roster.students:
        if student.line in owner:
            pairs.append((student, owner[student.line]))
        else:
            report.no_submission.append(student)
    return pairs


def _kept_ids(intake: Mapping) -> dict[str, str]:
    """The roster fields an intake record knows: its roster row's, else the LMS's own (a batch
    graded without --roster: Canvas user id, Gradescope e-mail and SID, GitHub login)."""
    lms = intake.get("lms") or {}
    ids = {"id": lms.get("canvas_user_id"), "email": lms.get("email"), "sid": lms.get("sid"),
           "submission": lms.get("github_login")}
    ids.update({k: v for k, v in (intake.get("student") or {}).items() if v})
    return {k: str(v) for k, v in ids.items() if v}


def _by_identity(roster: Roster, kept: Mapping[str, str]) -> Student | None:
    """The one roster row with the strongest id the intake record kept."""
    for key in _IDENTITY:
        value = str(kept.get(key) or "").strip().casefold()
        if not value or key not in roster.columns:
            continue
        rows = [s for s in roster.students if s.get(key).strip().casefold() == value]
        if len(rows) == 1:
            return rows[0]
    return None


def _canvas(pairs, results, *, report: ExportReport, assignment: str | None, source: str,
            docs: Mapping[str, ResultDocument]) -> list[list[str]]:
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
                     _num(r.final_score)])      # the total, or the points so far with partial
    report.rows = len(pairs)
    return rows


def _scored_items(result: Result) -> list:
    return [i for i in result.items if i.kind in ("auto", "manual")]


def _gradescope(pairs, results, *, report: ExportReport, assignment: str | None,
                source: str, docs: Mapping[str, ResultDocument]) -> list[list[str]]:
    problems = [f"line {s.line}: no Email or SID value, Gradescope could not match the row ({sid})"
                for s, sid in pairs if not (s.get("email") or s.get("sid"))]
    if problems:
        raise ScoresError(source, problems)
    first = next(iter(results.values()))
    items = _scored_items(first)
    late = any(r.late is not None for r in results.values())
    rows = [GRADESCOPE_COLUMNS + (GRADESCOPE_LATE_COLUMNS if late else [])
            + [f"{i.id}: {i.title} ({i.max_points:.1f} pts)" for i in items]]
    for student, sid in pairs:
        r = results[sid]
        by_id = {i.id: i for i in r.items}
        rows.append([student.get("name"), student.get("sid"), student.get("email"), student.get("section"),
                     _num(r.final_score), _num(r.max_score), "Graded" if r.complete else "Ungraded"]
                    + (_late_cells(r, _intake(docs.get(sid))) if late else [])
                    + [_num(by_id[i.id].points) if i.id in by_id else "" for i in items])
    report.rows = len(pairs)
    return rows


def _intake(doc: ResultDocument | None) -> Mapping:
    """A submission's result.json ``intake`` ({} when none)."""
    return doc.intake if doc is not None and doc.intake is not None else {}


def _late_cells(r: Result, intake: Mapping) -> list[str]:
    """Submission ID, Submission Time, Lateness (H:M:S), Late Penalty, Time Source."""
    late = r.late
    gs_id = str(intake.get("lms_id") or "") if intake.get("source") == "gradescope" else ""
    if late is None:
        return [gs_id, "", "", "", ""]
    seconds = max(0, int(round(late.late_s or 0)))
    lateness = f"{seconds // 3600}:{seconds % 3600 // 60:02d}:{seconds % 60:02d}" if late.late_s is not None else ""
    return [gs_id, late.submitted_at or "", lateness, _num(r.late_penalty), _text(late.time_source)]


def _long(pairs, results, *, report: ExportReport, assignment: str | None, source: str,
          docs: Mapping[str, ResultDocument]) -> list[list[str]]:
    rows = [list(LONG_COLUMNS)]
    for student, sid in pairs:
        who = [_text(student.get(f)) if student else "" for f in
               ("name", "id", "sis_user_id", "sis_login_id", "section", "email", "sid")]
        r = results[sid]
        for i in r.items:
            rows.append([sid, *who, i.id, _text(i.title), i.kind, _num(i.points), _num(i.max_points),
                         i.status, _text(i.feedback or "")])
        if r.late is not None:
            status = "override" if r.late.override_points is not None else ("late" if r.late_penalty else "on time")
            rows.append([sid, *who, "late_penalty", "Late penalty", "late", _num(-r.late_penalty) if r.late_penalty else "0", "",
                         status, _text(r.late.note)])
        rows.append([sid, *who, "total", _text(r.title), "total", _num(r.total), _num(r.max_score),
                     "final" if r.complete else "pending", ""])
    report.rows = len(pairs)
    return rows
