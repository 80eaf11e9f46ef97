"""``grader scores merge OUT manual.csv``: a TA's manual scores into a graded batch.

The sheet is checked completely first (grader.scores.sheet); then every file that changes
(``<id>/manual_scores.json``, ``<id>/result.json``, ``<id>/report.html``, ``grades.csv``,
``index.html``) is written to a staging folder and moved into place all together
(grader.scores.transaction). Files whose content would not change are not touched, so merging
the same sheet twice changes nothing the second time.

An empty cell keeps what an earlier merge set, ``pending`` clears it: a corrected sheet can
be merged over the first one, and a sheet holding only some columns or rows touches only those.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from grader.errors import GraderError
from grader.report.html import write_html
from grader.report.index import read_docs, write_index
from grader.contracts.result_document import ResultDocument
from grader.contracts.output_folder import GRADES_CSV, INDEX_HTML, REPORT_HTML, RESULT_JSON, SubmissionFolder
from grader.report.result import read_document, result_from_document, write_grades_csv, write_result
from grader.report.seal import check_doc
from grader.rubric.result import Result
from grader.scores import transaction
from grader.scores.sheet import LATE, SheetRow, read_sheet
from grader.scores.store import (MANUAL_SCORES, ManualScore, apply_manual_scores, load_late_override,
                                 load_manual_scores, manual_scores_text)
from grader.analyze.plugins import load_recorded_files

#: order of the moves: the record of the TA's scores first, the batch overview last
_ORDER = {MANUAL_SCORES: 0, RESULT_JSON: 1, REPORT_HTML: 2, GRADES_CSV: 3, INDEX_HTML: 4}


@dataclass(frozen=True)
class Change:
    submission: str
    item: str
    before: ManualScore | None
    after: ManualScore | None

    def describe(self) -> str:
        unset = "policy" if self.item == LATE else "pending"

        def text(s: ManualScore | None) -> str:
            return unset if s is None else f"{s.points:g}" + (f' "{s.comment}"' if s.comment else "")
        return f"{self.submission}: {self.item} {text(self.before)} -> {text(self.after)}"


@dataclass
class MergeReport:
    """What a merge did (or, with ``dry_run``, would do)."""

    out: Path
    sheet: Path
    rows: int
    changes: list[Change] = field(default_factory=list)
    written: list[Path] = field(default_factory=list)
    pending: dict[str, list[str]] = field(default_factory=dict)    # submission -> pending items
    dry_run: bool = False


@dataclass
class _Graded:
    """One submission as it is on disk."""

    sid: str
    doc: ResultDocument
    result: Result


def load_graded(out: Path) -> dict[str, _Graded]:
    """Every instructor-view result under ``out`` (all of one lab)."""
    graded: dict[str, _Graded] = {}
    for path in sorted(out.glob("*/result.json")):
        doc = read_document(path)
        check_doc(doc, path)
        if doc.view == "student":
            continue
        graded[doc.submission] = _Graded(doc.submission, doc, result_from_document(doc))
    if not graded:
        raise GraderError(f"{out} holds no graded submissions (no <id>/result.json); run "
                          "`grader grade` first")
    labs = sorted({g.result.lab for g in graded.values()})
    if len(labs) > 1:
        raise GraderError(f"{out} holds results of several labs ({', '.join(labs)}); merge and "
                          "export work on one lab's folder")
    return graded


def _baseline(sub_out: Path, result: Result) -> dict[str, ManualScore]:
    """The manual scores in force: the stored ones, plus any graded manual item of result.json
    that the store does not know (a result scored with ``score(..., manual=...)``)."""
    scores = load_manual_scores(sub_out)
    for item in result.items:
        if item.kind == "manual" and item.points is not None and item.id not in scores:
            scores[item.id] = ManualScore(item.points, item.feedback or "", RESULT_JSON)
    return scores


def _apply_row(row: SheetRow, before: dict[str, ManualScore], source: str,
               stamp: str) -> tuple[dict[str, ManualScore], list[Change]]:
    after = dict(before)
    for item_id, update in row.updates.items():
        old = before.get(item_id)
        if update.action == "clear":
            after.pop(item_id, None)
        else:
            points = update.points if update.action == "set" else old.points  # type: ignore[union-attr]
            comment = update.comment if update.comment is not None else (old.comment if old else "")
            if old is not None and old.points == points and old.comment == comment:
                continue                              # unchanged: keep where it came from
            after[item_id] = ManualScore(float(points), comment, f"{source} line {row.line}", stamp)  # type: ignore[arg-type]
    changes = [Change(row.submission, i, before.get(i), after.get(i))
               for i in row.updates if before.get(i) != after.get(i)]
    return after, changes


def _apply_late(row: SheetRow, before: ManualScore | None, source: str,
                stamp: str) -> tuple[ManualScore | None, list[Change]]:
    """The TA's late_penalty override after this row (None: the late policy's own penalty)."""
    if row.late is None:
        return before, []
    after = None if row.late.action == "clear" else ManualScore(float(row.late.points or 0.0), "",
                                                                 f"{source} line {row.line}", stamp)
    if before is not None and after is not None and before.points == after.points:
        return before, []
    return after, ([Change(row.submission, LATE, before, after)] if before != after else [])


def merge_manual_scores(out: str | os.PathLike[str], sheet: str | os.PathLike[str], *,
                        dry_run: bool = False) -> MergeReport:
    """Merge the TA's CSV ``sheet`` into the batch ``out`` (see the module docstring).
    Raises ScoresError (every problem of the sheet, nothing written) or GraderError."""
    from grader.intake.apply import with_late_override  # noqa: PLC0415 - at the head it would close a circle: scores.merge -> intake -> intake.batch -> scores -> scores.merge

    out, sheet = Path(out), Path(sheet)
    if not out.is_dir():
        raise GraderError(f"{out} is not a folder written by `grader grade`")
    with transaction.locked(out):
        graded = load_graded(out)
        rows = read_sheet(sheet, {sid: g.result for sid, g in graded.items()})
        report = MergeReport(out=out, sheet=sheet, rows=len(rows), dry_run=dry_run)
        stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        results = {sid: g.result for sid, g in graded.items()}
        new_scores: dict[str, dict[str, ManualScore]] = {}
        new_late: dict[str, ManualScore | None] = {}
        for row in rows:
            g = graded[row.submission]
            scores, changes = _apply_row(row, _baseline(out / g.sid, g.result), sheet.name, stamp)
            late, late_changes = _apply_late(row, load_late_override(out / g.sid), sheet.name, stamp)
            report.changes += changes + late_changes
            new_scores[g.sid], new_late[g.sid] = scores, late
            results[g.sid] = with_late_override(apply_manual_scores(g.result, scores), late)
        report.pending = {sid: [i.id for i in r.items if i.kind == "manual" and i.points is None]
                          for sid, r in sorted(results.items()) if not r.complete}
        with transaction.staging(out) as stage:
            for sid, scores in new_scores.items():
                _stage_submission(stage, out, graded[sid], results[sid], scores, new_late[sid])
            write_grades_csv(stage, results, intake={sid: g.doc.intake for sid, g in graded.items()
                                                     if g.doc.intake is not None})
            write_index(stage, results, docs=read_docs(out, list(results)))
            files = sorted(transaction.changed_files(stage, out),
                           key=lambda rel: (_ORDER.get(rel.name, 9), str(rel)))
            report.written = ([out / rel for rel in files] if dry_run
                              else transaction.commit(stage, out, files))
    return report


def _stage_submission(stage: Path, out: Path, g: _Graded, result: Result,
                      scores: dict[str, ManualScore], late: ManualScore | None = None) -> None:
    """manual_scores.json and result.json; report.html only when the result changed."""
    sub_out = out / g.sid
    if scores or late is not None or (sub_out / MANUAL_SCORES).exists():
        (stage / g.sid).mkdir(parents=True, exist_ok=True)
        (stage / g.sid / MANUAL_SCORES).write_text(manual_scores_text(result.lab, g.sid, scores, late),
                                                    encoding="utf-8")
    extra = g.doc.run_records()
    versions = g.doc.versions
    # the grade still rests on the bags that were graded: keep their recorded digests
    inputs = g.doc.seal.inputs if g.doc.seal is not None else {}
    path = write_result(stage, g.sid, result, versions=versions, extra=extra, inputs=inputs)
    if SubmissionFolder(sub_out).result_json.read_bytes() == path.read_bytes() and SubmissionFolder(sub_out).report_html.exists():
        return
    canvases = {p.parent.name: str(p) for p in sorted(sub_out.glob("scenarios/*/canvas.png"))}

    load_recorded_files(g.doc.analyzer_files)      # the lab's own figures and labels
    write_html(stage, g.sid, result, versions=versions, canvas_png=canvases or None,
               problems=list(g.doc.errors), intake=g.doc.intake)
