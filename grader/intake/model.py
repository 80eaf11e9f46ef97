"""One submission as it arrived from an LMS download, a Classroom folder or a plain folder: what
is graded, who handed it in (as the LMS says and as the roster says), when, and why it is not
graded when it is not. The record (:meth:`Arrival.record`) goes into ``OUT/<id>/intake.json``
and result.json's ``intake``, so the LMS's ids travel with the grade unchanged.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from grader.contracts.intake_record import INTAKE_SCHEMA, IntakeRecord
from grader.contracts.output_folder import INTAKE_JSON
from grader.intake.late import SubmissionTime
from grader.errors import GraderError
from grader.report.result import atomic_write

if TYPE_CHECKING:
    from grader.scores.roster import Student

INTAKE_FILE = INTAKE_JSON
#: the kinds of input ``grader grade`` reads, in the words the table uses
SOURCES = {"canvas": "Canvas download", "gradescope": "Gradescope export",
           "classroom": "GitHub Classroom clones", "folder": "folder of submissions",
           "single": "one submission"}


@dataclass
class Arrival:
    """One submission. ``key``: the LMS's readable name for it (Canvas's ``doejane``, a GitHub
    login, an e-mail's user part), the id it gets unless the roster gives one. ``lms_id``: the
    LMS's own id (Canvas user id, Gradescope submission id, repository name, file name)."""

    source: str
    key: str
    lms_id: str
    original: list[str]                       # names as they arrived
    path: Path | None = None                  # what is graded: a folder or an archive
    lms: dict[str, Any] = field(default_factory=dict)     # what the LMS says: name, email, sid, ...
    time: SubmissionTime | None = None
    student: "Student | None" = None          # the roster row, once matched
    matched_by: str = ""                      # how, in words; or why not
    id: str = ""                              # the submission id (folder under OUT)
    refused: str | None = None                # why it is not graded: one sentence
    notes: list[str] = field(default_factory=list)        # e.g. loose files wrapped, a file missing

    @property
    def gradable(self) -> bool:
        return self.refused is None and self.path is not None

    def record(self) -> dict[str, Any]:
        """What result.json's ``intake`` and ``intake.json`` keep (no paths of this machine)."""
        student = None
        if self.student is not None:
            student = {"line": self.student.line, **{k: v for k, v in self.student.fields.items() if v}}
        return {"schema": INTAKE_SCHEMA, "source": self.source, "lms_id": self.lms_id, "key": self.key,
                "original": list(self.original), "lms": dict(self.lms),
                "time": self.time.to_dict() if self.time else None,
                "student": student, "matched_by": self.matched_by, "notes": list(self.notes)}


def write_record(sub_out: Path, record: Mapping[str, Any], due_override: Mapping[str, Any] | None = None) -> None:
    """``OUT/<id>/intake.json``: the arrival record (and a ``--due`` that replaced the rubric's)."""
    doc = dict(record)
    if due_override:
        doc["due_override"] = dict(due_override)
    path = Path(sub_out) / INTAKE_FILE
    # through JSON first: the record's values JSON has no form for are text, as they always were
    intake = IntakeRecord.parse_text(json.dumps(doc, default=str), str(path))
    atomic_write(path, json.dumps(intake.to_json(), indent=1) + "\n")


def read_record(sub_out: Path) -> IntakeRecord | None:
    """The arrival record of a graded submission, or None (graded without intake)."""
    path = Path(sub_out) / INTAKE_FILE
    if not path.exists():
        return None
    try:
        return IntakeRecord.read(path)
    except (OSError, ValueError) as exc:
        raise GraderError(f"{path} is not a readable intake record ({exc}); grade the submission "
                          "again to rewrite it") from None


def public_record(sub_out: Path) -> dict[str, Any] | None:
    """result.json's ``intake``: the arrival record as kept in intake.json."""
    record = read_record(sub_out)
    return None if record is None else record.public()
