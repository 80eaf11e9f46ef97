"""``OUT/<id>/intake.json``, how one submission arrived: :class:`IntakeRecord`.

``grader.intake.model.Arrival.record`` makes it when ``grader grade`` reads an LMS download, a
Classroom folder or a plain folder; the pipeline writes it (with a ``--due`` that replaced the
rubric's) and copies it, without ``schema``, into result.json's ``intake``; the late policy reads
it again at every grade and regrade (``grader.intake.apply``). Written in the order the arrival
record has always had: a file the previous grader wrote reads and writes back the same
(``tests/intake/test_intake_record.py``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from grader.contracts.document import Document
from grader.contracts.values import JsonValue

__all__ = ["INTAKE_SCHEMA", "IntakeRecord"]

INTAKE_SCHEMA = 1


class IntakeRecord(Document):
    schema_version: Literal[1] = Field(alias="schema")      # INTAKE_SCHEMA
    source: str                                # canvas | gradescope | classroom | folder | single
    lms_id: str = ""
    key: str = ""
    original: list[str] = Field(default_factory=list)
    lms: dict[str, JsonValue] = Field(default_factory=dict)        # what the LMS says: name, email, ...
    #: ``grader.contracts.late.SubmissionTime.to_dict()``
    time: dict[str, JsonValue] | None = None
    #: the roster row: ``line`` and its non-empty columns (``name``, ``late_days``, ...)
    student: dict[str, JsonValue] | None = None
    matched_by: str = ""
    notes: list[str] = Field(default_factory=list)
    #: ``--due``: ``{"due", "timezone"}`` that replaced the rubric's due date
    due_override: dict[str, JsonValue] | None = None

    def public(self) -> dict[str, JsonValue]:
        """result.json's ``intake``: this record without its ``schema``."""
        doc = self.to_json()
        doc.pop("schema", None)
        return doc
