"""result.json through its model (grader.contracts.result_document): a file the previous grader
wrote still reads, seal included, and writes back byte for byte; bad files are named clearly.

``data/result_v1.json`` was written by grader main at a9b6cff (before the model), from the
conftest's Lab 3 result with a late penalty, a contract mismatch and every pipeline record
(build, timings, sandbox, previous, intake, ...), sealed with ``data/seal_test.key`` (a test key:
32 bytes of ``k``).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.contracts.document import DocumentError
from grader.contracts.result_document import ResultDocument
from grader.errors import GraderError
from grader.report.result import dumps, read_result, result_document, write_result
from grader.report.seal import mac_ok

DATA = Path(__file__).parent / "data"
OLD = DATA / "result_v1.json"


@pytest.fixture
def test_key(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GRADER_SEAL_KEY", str(DATA / "seal_test.key"))


def test_the_previous_graders_result_json_reads_and_writes_back_byte_for_byte(test_key: None) -> None:
    doc = ResultDocument.read(OLD)
    assert mac_ok(doc)                                  # the seal is over the same JSON
    assert dumps(doc.to_json()) == OLD.read_text(encoding="utf-8")
    sid, result = read_result(OLD)                      # verified
    assert sid == "alice" and result.late is not None and result.late.percent == 10
    assert [m.found for m in result.contract] == [("/goal",)]
    assert doc.build_ok and doc.previous is not None and doc.previous.items["ex1_rate"].points == 2
    assert doc.intake == {"source": "canvas", "lms_id": "123", "student": {"name": "Ada"}}
    # the Result read back is written as the same grade (the run's records kept as they were)
    again = result_document(result, sid, versions=doc.versions, extra=doc.run_records())
    assert again.to_json() == doc.without_seal()


def test_another_key_or_an_edit_breaks_the_seal(test_key: None, monkeypatch: pytest.MonkeyPatch,
                                                tmp_path: Path) -> None:
    raw = json.loads(OLD.read_text(encoding="utf-8"))
    raw["items"][0]["points"] = 99
    edited = tmp_path / "alice" / "result.json"
    edited.parent.mkdir()
    edited.write_text(json.dumps(raw))
    assert not mac_ok(ResultDocument.read(edited))
    monkeypatch.setenv("GRADER_SEAL_KEY", str(tmp_path / "other.key"))
    assert not mac_ok(ResultDocument.read(OLD))


def test_written_now_reads_back_the_same(tmp_path: Path, lab3_result) -> None:
    path = write_result(tmp_path, "bob", lab3_result, extra={"build": {"ok": False, "failed": ["pkg"]}})
    doc = ResultDocument.read(path)
    assert dumps(doc.to_json()) == path.read_text(encoding="utf-8")
    assert not doc.build_ok and doc.build is not None and doc.build.failed == ["pkg"]
    assert "late" not in doc.to_json() and "sandbox" not in doc.to_json()    # absent stays absent


def test_a_newer_graders_unknown_keys_are_kept(tmp_path: Path) -> None:
    raw = json.loads(OLD.read_text(encoding="utf-8"))
    raw["items"][0]["confidence"] = 0.9
    raw["energy_j"] = {"total": 12}
    doc = ResultDocument.parse(raw, "r.json")
    assert doc.to_json()["energy_j"] == {"total": 12} and doc.to_json()["items"][0]["confidence"] == 0.9
    assert doc.run_records()["energy_j"] == {"total": 12}
    assert ResultDocument.grade_keys()[-1] == "versions" and "late" in ResultDocument.grade_keys()


def test_a_bad_file_names_the_field(tmp_path: Path) -> None:
    raw = json.loads(OLD.read_text(encoding="utf-8"))
    raw["items"][2]["kind"] = "bonus"
    del raw["lab"]
    with pytest.raises(DocumentError) as err:
        ResultDocument.parse(raw, "out/alice/result.json")
    assert str(err.value).startswith("out/alice/result.json: ")
    assert "lab: Field required" in str(err.value) and "items[2].kind: Input should be" in str(err.value)
    bad = tmp_path / "result.json"
    bad.write_text(json.dumps({**raw, "lab": "x", "schema": 2}))
    with pytest.raises(GraderError, match=r"result.json: \(top\): schema 2 is not 1"):
        read_result(bad, verify=False)
