"""intake.json through its model (grader.contracts.intake_record). ``data/intake_v1.json`` was
written by grader main at a9b6cff (before the model) from a Canvas arrival matched to a roster
row, with a ``--due`` override: it reads, feeds the late policy and writes back byte for byte."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from grader.contracts.intake_record import IntakeRecord
from grader.errors import GraderError
from grader.intake.apply import days_left
from grader.intake.model import INTAKE_FILE, public_record, read_record, write_record

OLD = Path(__file__).parent / "data" / "intake_v1.json"


def test_the_previous_graders_intake_json_reads_and_writes_back_the_same(tmp_path: Path) -> None:
    shutil.copy(OLD, tmp_path / INTAKE_FILE)
    record = read_record(tmp_path)
    assert record is not None and record.source == "canvas" and record.due_override is not None
    assert days_left(record) == (2, [])
    public = public_record(tmp_path)
    assert public is not None and "schema" not in public and public["lms_id"] == "12345"
    again = tmp_path / "again"
    write_record(again, {"schema": 1, **{k: v for k, v in public.items() if k != "due_override"}},
                 record.due_override)
    assert (again / INTAKE_FILE).read_text() == OLD.read_text()


def test_a_bad_intake_record_names_its_field(tmp_path: Path) -> None:
    doc = json.loads(OLD.read_text())
    doc["notes"] = "one note"
    (tmp_path / INTAKE_FILE).write_text(json.dumps(doc))
    with pytest.raises(GraderError, match=r"intake.json: notes: Input should be a valid list"):
        read_record(tmp_path)
    with pytest.raises(ValueError, match="schema: Input should be 1"):
        IntakeRecord.parse({**doc, "schema": 2, "notes": []}, "intake.json")
