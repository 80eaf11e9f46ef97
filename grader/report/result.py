"""Machine-readable outputs: ``OUT/<id>/result.json`` per submission and ``OUT/grades.csv``.

result.json is the archival record of one grade (with the versions that produced it, so a
regrade can be compared); grades.csv is what an instructor pastes into a gradebook: one row per
submission, one column per rubric item, manual items left empty for a person to fill in.
"""

from __future__ import annotations

import csv
import io
import json
import os
import threading
import re
from pathlib import Path
from typing import Any, Mapping

from grader.errors import GraderError
from grader.rubric.schema import Rubric, Section, SectionSpec
from grader.rubric.result import ItemResult, Notice, Result
from grader.contracts.jsonable import jsonable
from grader.contracts.contract import Mismatch
from grader.contracts.late import LatePenalty, late_by_text
from grader.contracts.document import DocumentError
from grader.contracts.output_folder import RESULT_JSON, OutputFolder
from grader.contracts.result_document import RESULT_SCHEMA, PreviousEntry, PreviousItem, ResultDocument
SUBMISSION_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._@+-]{0,127}$")


def check_submission_id(submission: str) -> str:
    """Submission ids become directory names and CSV cells: keep them plain and safe."""
    if not SUBMISSION_ID.match(submission or "") or ".." in submission:
        raise GraderError(f"submission id {submission!r} must start with a letter or digit and "
                          f"contain only letters, digits and . _ @ + - (no '..')")
    return submission


def item_to_dict(item: ItemResult) -> dict[str, Any]:
    return {
        "id": item.id,
        "title": item.title,
        "section": item.section.as_dict(),
        "kind": item.kind,
        "public": item.public,
        "points": item.points,
        "max_points": item.max_points,
        "status": item.status,
        "feedback": item.feedback,
        "hint": item.hint,
        "value": jsonable(item.value),
        "fraction": item.fraction,
        "evidence": jsonable(item.evidence),
        "params": jsonable(item.params),
        "hidden_params": list(item.hidden_params),
        "requires": list(item.requires),
        "analyzer": item.analyzer,
        "decided": jsonable(item.decided),
    }


def _notice_to_dict(notice: Notice) -> dict[str, Any]:
    return {"id": notice.item_id, "title": notice.title, "status": notice.status,
            "feedback": notice.feedback}


def result_document(result: Result, submission: str, *, versions: Mapping[str, str] | None = None,
                    extra: Mapping[str, Any] | None = None) -> ResultDocument:
    """The result.json document of ``result`` (``grader.contracts.result_document``). ``extra``:
    further top-level keys from the caller (build status, scenario errors, timings); they cannot
    replace ours. Built as the JSON object, then validated: what is written is what a reader parses."""
    doc = jsonable({
        "schema": RESULT_SCHEMA,
        "submission": submission,
        "lab": result.lab,
        "title": result.title,
        "view": "student" if result.student_view else "instructor",
        "score": result.score,
        "auto_score": result.auto_score,
        "auto_max": result.auto_max,
        "max_score": result.max_score,
        "manual_max": result.manual_max,
        "pending_max": result.pending_max,
        "total": result.total,
        "complete": result.complete,
        "hidden": {"items": result.hidden_items, "points": result.hidden_points},
        "sections": [
            {"section": s.section.as_dict(), "title": s.title, "name": s.name, "points": s.points,
             "max_points": s.max_points, "auto_points": s.auto_points, "auto_max": s.auto_max,
             "pending_max": s.pending_max, "items": list(s.item_ids)}
            for s in result.sections],
        "items": [item_to_dict(i) for i in result.items],
        **late_fields(result),
        "contract": [m.to_dict() for m in result.contract],
        "integrity_flags": [_notice_to_dict(n) for n in result.integrity_flags],
        "warnings": [_notice_to_dict(n) for n in result.warnings],
        "versions": dict(versions or {}),
    })
    for key, value in (extra or {}).items():
        if key in doc or key in ResultDocument.grade_keys() or key == "seal":
            raise ValueError(f"extra key {key!r} would replace a result.json field")
        doc[key] = jsonable(value)
    return ResultDocument.parse(doc, f"result.json of {submission}")


def result_to_dict(result: Result, submission: str, *, versions: Mapping[str, str] | None = None,
                   extra: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The JSON object of :func:`result_document` (what result.json holds, before its seal)."""
    return result_document(result, submission, versions=versions, extra=extra).to_json()


def late_fields(result: Result) -> dict[str, Any]:
    """result.json's ``late_penalty`` (points) and ``late`` (the policy's verdict), when the
    rubric has a late policy; ``score`` stays the points earned, ``total`` has the penalty off."""
    if result.late is None:
        return {}
    return {"late_penalty": result.late_penalty, "late": result.late.to_dict()}


def _section(key: Mapping[str, int | str | None]) -> Section:
    (kind, number), = key.items()
    return Section(kind=kind, number=number)


def result_from_document(doc: ResultDocument) -> Result:
    """Rebuild a Result from result.json, so batch outputs (grades.csv, index.html) can be
    regenerated from disk after submissions were graded in separate runs."""
    items = tuple(ItemResult(
        id=i.id, title=i.title, section=_section(i.section), kind=i.kind,
        public=i.public, points=i.points, max_points=i.max_points, status=i.status,
        feedback=i.feedback, hint=i.hint, value=i.value,
        fraction=i.fraction, evidence=i.evidence or {}, params=i.params or {},
        hidden_params=tuple(i.hidden_params), requires=tuple(i.requires),
        analyzer=i.analyzer, decided=i.decided or {}) for i in doc.items)
    specs = tuple(SectionSpec(section=_section(s.section), title=s.name) for s in doc.sections)
    late = LatePenalty.from_dict(doc.late) if doc.late is not None else None
    return Result(lab=doc.lab, title=doc.title, items=items, section_specs=specs,
                  contract=tuple(Mismatch.from_dict(m) for m in doc.contract),
                  student_view=doc.view == "student",
                  hidden_items=doc.hidden.items, hidden_points=float(doc.hidden.points),
                  late=late)


def result_from_dict(doc: Any) -> Result:
    """:func:`result_from_document` of a parsed JSON object (a GraderError when it is not one)."""
    try:
        return result_from_document(ResultDocument.parse(doc, RESULT_JSON))
    except DocumentError as exc:
        raise GraderError(str(exc)) from None


def previous_summary(doc: ResultDocument | None) -> PreviousEntry | None:
    """What a regrade keeps of the result.json it replaces (stored as its ``previous`` key), so
    the class view can show who changed and by how much: totals and each item's points and
    status. None when there is no result."""
    if doc is None:
        return None
    return PreviousEntry(
        auto_score=doc.auto_score, score=doc.score, total=doc.total, versions=doc.versions,
        items={i.id: PreviousItem(points=i.points, status=i.status) for i in doc.items},
    )


def read_document(path: str | os.PathLike[str]) -> ResultDocument:
    """The result.json at ``path``, unverified; a GraderError naming the file when it cannot be
    read or is not a result.json (``path: field: what is wrong``)."""
    try:
        return ResultDocument.read(path)
    except OSError as exc:
        raise GraderError(f"cannot read {path}: {exc}") from None
    except DocumentError as exc:
        raise GraderError(str(exc)) from None


def read_result(path: str | os.PathLike[str], *, verify: bool = True) -> tuple[str, Result]:
    """``(submission id, Result)`` from a result.json file; with ``verify``, only when its seal
    shows the grader wrote it as it is (a GraderError naming the file otherwise)."""
    from grader.report.seal import check_doc  # noqa: PLC0415 - at the head it would close a circle: report.result -> report -> report.result

    doc = read_document(path)
    if verify:
        check_doc(doc, Path(path))
    return doc.submission, result_from_document(doc)


def atomic_write(path: Path, text: str) -> None:
    """Write via a temporary file + rename so a crash never leaves half a report."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def write_result(out_dir: str | os.PathLike[str], submission: str, result: Result, *,
                 versions: Mapping[str, str] | None = None, extra: Mapping[str, Any] | None = None,
                 filename: str = RESULT_JSON, inputs: Mapping[str, str] | None = None) -> Path:
    """Write ``out_dir/<submission>/result.json``, sealed (``grader.report.seal``); ``versions``
    come from the caller (grader version, ROS distro, rmw, python...) because only it knows what
    actually ran. ``inputs``: digests of the files the grade was computed from (default: the
    bags and canvases in the submission's folder now). ``filename`` lets a student view sit next
    to it (e.g. ``student.json``)."""
    from grader.report.seal import input_digests, sealed  # noqa: PLC0415 - at the head it would close a circle: report.result -> report -> report.result

    check_submission_id(submission)
    path = Path(out_dir) / submission / plain_file_name(filename)
    doc = result_document(result, submission, versions=versions, extra=extra)
    if inputs is None:
        inputs = input_digests(path.parent)
    atomic_write(path, dumps(sealed(doc, inputs).to_json()))
    return path


_SCALAR = r"(?:-?[0-9][0-9.eE+-]*|null|true|false)"
_NUMBER_LIST = re.compile(rf"\[\n\s+({_SCALAR}(?:,\n\s+{_SCALAR})*)\n\s*\]")


def dumps(doc: Any) -> str:
    """Indented JSON with lists of numbers on one line each (plot series in the evidence would
    otherwise take a line per number). Only structural newlines are touched: JSON strings cannot
    hold a raw newline."""
    return compact_number_lists(json.dumps(doc, indent=2, allow_nan=False, ensure_ascii=False)) + "\n"


def compact_number_lists(text: str) -> str:
    """Indented JSON ``text`` with each list of scalars (numbers, null, booleans) on one line."""
    return _NUMBER_LIST.sub(lambda m: "[" + re.sub(r",\n\s+", ", ", m.group(1)) + "]", text)


def plain_file_name(filename: str) -> str:
    if not SUBMISSION_ID.match(filename) or ".." in filename:
        raise ValueError(f"not a plain file name: {filename!r}")
    return filename


def _cell(item: ItemResult) -> str:
    if item.kind in ("advisory", "integrity"):
        return item.status             # 0-point checks: the verdict is the information
    return "" if item.points is None else f"{item.points:g}"


#: grades.csv columns after the items (late_penalty only with a late policy)
LATE_COLUMNS = ("submitted_at", "late_by", "time_source")
INTAKE_COLUMNS = ("intake", "lms_id", "student")


def grades_csv_text(results: Mapping[str, Result], rubric: Rubric | None = None,
                    intake: Mapping[str, Mapping[str, Any]] | None = None) -> str:
    """CSV text: ``submission, <item ids...>, auto_total, manual_total, [late_penalty,] total,
    max, integrity_flags`` (+ ``submitted_at, late_by, time_source`` with a late policy, +
    ``intake, lms_id, student`` for submissions taken from an LMS download, ``intake``: each
    submission's result.json ``intake``); empty cells for ungraded manual items and for totals
    not final yet."""
    first = next(iter(results.values()), None)
    if rubric is not None:
        item_ids = rubric.item_ids
        lab = rubric.lab
    else:
        item_ids = [i.id for i in first.items] if first else []
        lab = first.lab if first else ""
    late = (rubric is not None and getattr(rubric, "late", None) is not None) or \
        any(r.late is not None for r in results.values())
    # who handed it in: for submissions from an LMS download or matched to a roster
    intake = {k: v for k, v in (intake or {}).items() if isinstance(v, Mapping)
              and (v.get("source") in ("canvas", "gradescope", "classroom") or v.get("student"))}
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["submission", *item_ids, "auto_total", "manual_total", *(["late_penalty"] if late else []),
                     "total", "max", "integrity_flags", *(LATE_COLUMNS if late else ()),
                     *(INTAKE_COLUMNS if intake else ())])
    for submission in sorted(results):
        check_submission_id(submission)
        result = results[submission]
        if result.lab != lab:
            raise ValueError(f"{submission}: result is for {result.lab!r}, not {lab!r}")
        if result.student_view:
            raise ValueError(f"{submission}: grades.csv needs the instructor view, not for_student()")
        by_id = {i.id: i for i in result.items}
        cells = [_cell(by_id[i]) if i in by_id else "" for i in item_ids]
        manual = result.manual_score
        row = [submission, *cells, f"{result.auto_score:g}", "" if manual is None else f"{manual:g}"]
        if late:
            row.append("" if result.late is None else f"{result.late_penalty:g}")
        row += ["" if result.total is None else f"{result.total:g}", f"{result.max_score:g}",
                ";".join(n.item_id for n in result.integrity_flags)]
        if late:
            p = result.late
            row += ["", "", ""] if p is None else [p.submitted_at or "", late_by_text(p), p.time_source]
        if intake:
            doc = intake.get(submission) or {}
            row += [str(doc.get("source") or ""), str(doc.get("lms_id") or ""),
                    str((doc.get("student") or {}).get("name") or "")]
        writer.writerow(row)
    return buf.getvalue()


def write_grades_csv(out_dir: str | os.PathLike[str], results: Mapping[str, Result], *,
                     rubric: Rubric | None = None, intake: Mapping[str, Mapping[str, Any]] | None = None) -> Path:
    """Write ``out_dir/grades.csv`` for a batch (columns in rubric order when given)."""
    path = OutputFolder(Path(out_dir)).grades_csv
    atomic_write(path, grades_csv_text(results, rubric, intake))
    return path
