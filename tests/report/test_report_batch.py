"""result.json round trip, caller-supplied extras, and batch outputs rebuilt from disk."""

from __future__ import annotations

import csv
import hashlib
import json

import pytest

from grader.contracts.result_document import ResultDocument
from grader.errors import GraderError
from grader.report import read_result, result_from_dict, result_to_dict, write_batch, write_result
from grader.rubric import score


def test_round_trip_through_json(lab3_result):
    doc = result_to_dict(lab3_result, "alice")
    again = result_from_dict(json.loads(json.dumps(doc)))
    assert result_to_dict(again, "alice") == doc
    student = lab3_result.for_student()
    assert result_to_dict(result_from_dict(result_to_dict(student, "a")), "a") == result_to_dict(student, "a")


def test_extra_keys_cannot_replace_fields(lab3_result):
    assert result_to_dict(lab3_result, "a", extra={"build": {"ok": True}})["build"] == {"ok": True}
    with pytest.raises(ValueError, match="score"):
        result_to_dict(lab3_result, "a", extra={"score": 100})


def test_write_result_extra_and_problems_in_html(tmp_path, lab3_result):
    from grader.report import write_html
    path = write_result(tmp_path, "alice", lab3_result, extra={"build": {"ok": False, "failed": ["x"]}})
    assert json.loads(path.read_text())["build"] == {"ok": False, "failed": ["x"]}
    html = write_html(tmp_path, "alice", lab3_result,
                      problems=["package x did not build:\nSyntaxError: <bad>", "y" * 5000]).read_text()
    assert "Problems while grading" in html and "SyntaxError: &lt;bad&gt;" in html
    assert "y" * 3000 + "…" in html and "y" * 3001 not in html


def test_batch_from_disk(tmp_path, lab3, lab3_result):
    write_result(tmp_path, "bob", score(lab3, {}))
    write_result(tmp_path, "alice", lab3_result)
    write_result(tmp_path, "check", lab3_result.for_student())     # a self-check: not a grade
    (tmp_path / "stray").mkdir()                                     # folder without a result
    csv_path, index = write_batch(tmp_path, lab3)
    rows = list(csv.DictReader(csv_path.open()))
    assert [r["submission"] for r in rows] == ["alice", "bob"]
    assert rows[0]["auto_total"] == "47" and rows[1]["auto_total"] == "0"
    assert 'href="alice/report.html"' in index.read_text() and "check/" not in index.read_text()


def test_a_result_removed_while_the_batch_is_listed_is_left_out(tmp_path, lab3, lab3_result, monkeypatch):
    """Grading into a folder that holds an earlier run: a submission graded again removes its old
    result.json, possibly between the batch listing the folder and reading that file."""
    import grader.report.batch as batch

    write_result(tmp_path, "alice", lab3_result)
    write_result(tmp_path, "bob", lab3_result)
    real = batch.read_result

    def regraded_meanwhile(path, **kw):
        if path.parent.name == "bob":
            path.unlink()
        return real(path, **kw)

    monkeypatch.setattr(batch, "read_result", regraded_meanwhile)
    assert list(batch.load_results(tmp_path, lab3)) == ["alice"]
    (tmp_path / "alice" / "result.json").write_text("{not json")     # still there, unreadable: said
    with pytest.raises(GraderError, match="cannot read"):
        batch.load_results(tmp_path, lab3)


def test_unreadable_result_is_a_clear_error(tmp_path, lab3):
    bad = tmp_path / "x" / "result.json"
    bad.parent.mkdir()
    bad.write_text("{not json")
    with pytest.raises(GraderError, match="cannot read"):
        read_result(bad)
    bad.write_text(json.dumps({"schema": 99}))
    with pytest.raises(GraderError, match="schema 99 is not 1"):      # a newer grader's: said before the seal
        read_result(bad)
    with pytest.raises(GraderError, match="schema 99 is not 1"):
        read_result(bad, verify=False)
    doc = json.loads(write_result(tmp_path, "y", score(lab3, {})).read_text())
    (tmp_path / "y" / "result.json").write_text(json.dumps({k: v for k, v in doc.items() if k != "seal"}))
    with pytest.raises(GraderError, match="no seal"):
        read_result(tmp_path / "y" / "result.json")
    doc["items"][0]["points"] = "many"
    bad.write_text(json.dumps(doc))
    with pytest.raises(GraderError, match=r"x/result.json: items\[0\]\.points: .*'many'"):
        read_result(bad, verify=False)


def test_a_result_changed_after_grading_is_refused(tmp_path, monkeypatch, lab3_result):
    """A result.json edited by anything but the grader (a student process, a hand) is an error
    naming the file, and the batch's grades.csv is not rebuilt from it."""
    from grader.report.batch import load_results
    from grader.report.result import write_result
    from grader.report.seal import changed_inputs

    monkeypatch.setenv("GRADER_SEAL_KEY", str(tmp_path / "key"))
    result = lab3_result
    bag = tmp_path / "out" / "s1" / "scenarios" / "a" / "bag"
    bag.mkdir(parents=True)
    (bag / "x.mcap").write_bytes(b"recorded")
    path = write_result(tmp_path / "out", "s1", result)
    assert load_results(tmp_path / "out")                      # sealed: fine
    doc = json.loads(path.read_text())
    assert doc["seal"]["inputs"] == {"scenarios/a/bag/x.mcap": hashlib.sha256(b"recorded").hexdigest()}
    doc["auto_score"] = 1000
    path.write_text(json.dumps(doc))
    with pytest.raises(GraderError, match=r"s1/result.json was changed after the grader wrote it"):
        load_results(tmp_path / "out")
    (bag / "x.mcap").write_bytes(b"edited")                   # and a changed bag is noticed
    assert changed_inputs(ResultDocument.read(path), path.parent) == ["scenarios/a/bag/x.mcap"]
