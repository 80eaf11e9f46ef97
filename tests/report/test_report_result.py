"""result.json and grades.csv: file locations, shapes, and what is left empty for humans."""

from __future__ import annotations

import csv
import io
import json
import math

import pytest

from grader.errors import GraderError
from grader.report import write_grades_csv, write_result
from grader.report.result import grades_csv_text, jsonable
from grader.rubric import score

VERSIONS = {"grader": "0.1.0", "ros_distro": "jazzy", "rmw": "rmw_fastrtps_cpp", "python": "3.11.7"}


def test_result_json_shape(tmp_path, lab3, lab3_result):
    path = write_result(tmp_path, "team-07", lab3_result, versions=VERSIONS)
    assert path == tmp_path / "team-07" / "result.json"
    doc = json.loads(path.read_text())
    assert doc["submission"] == "team-07" and doc["lab"] == "enee467-lab3"
    assert (doc["score"], doc["auto_score"], doc["auto_max"], doc["max_score"]) == (47, 47, 50, 100)
    assert doc["total"] is None and doc["complete"] is False and doc["pending_max"] == 50
    assert doc["versions"] == VERSIONS
    assert [i["id"] for i in doc["items"]] == lab3.item_ids
    item = {i["id"]: i for i in doc["items"]}
    assert set(item["ex1.pub_rate"]) == {"id", "title", "section", "kind", "public", "points",
                                         "max_points", "status", "feedback", "hint", "value",
                                         "fraction", "evidence", "params", "hidden_params", "requires",
                                         "analyzer", "decided"}
    assert item["ex1.pub_rate"]["decided"] == {"by": "one run", "runs": 1}       # no repeated scenario
    assert item["ex1.pub_rate"]["section"] == {"exercise": 1}
    assert (item["ex1.pub_rate"]["points"], item["ex1.pub_rate"]["max_points"]) == (1.5, 3)
    assert item["ex1.pub_rate"]["status"] == "partial"
    assert item["report"]["section"] == {"report": None}
    assert item["report"]["points"] is None and item["report"]["status"] == "pending"
    assert item["q3"]["section"] == {"question": 3}
    assert item["integrity.no_teleport"]["public"] is False
    assert doc["integrity_flags"] == [{"id": "integrity.no_teleport", "status": "fail",
                                       "title": item["integrity.no_teleport"]["title"],
                                       "feedback": "1 teleport_absolute call during ex2_controller."}]
    assert [w["id"] for w in doc["warnings"]] == ["ex2.goal_publisher_robust", "ex3.timeout"]
    sections = {json.dumps(s["section"]): s for s in doc["sections"]}
    assert sections['{"exercise": 1}']["points"] == 18.5 and sections['{"exercise": 1}']["max_points"] == 20


def test_student_result_json_drops_hidden_items(tmp_path, lab3_result):
    doc = json.loads(write_result(tmp_path, "s1", lab3_result.for_student()).read_text())
    assert doc["view"] == "student"
    assert not any(i["id"].startswith("integrity.") for i in doc["items"])
    assert doc["hidden"] == {"items": 2, "points": 0} and doc["integrity_flags"] == []


def test_evidence_becomes_strict_json(tmp_path, lab3, make_finding):
    np = pytest.importorskip("numpy")
    evidence = {"nan": math.nan, "inf": [1.0, math.inf], "arr": np.arange(3), "i": np.int64(4),
                "f": np.float32(0.5), "b": np.bool_(True), "t": (1, 2), "nested": {"x": np.nan}}
    result = score(lab3, {"ex1.pub_rate": make_finding(value=np.float64(0.99), evidence=evidence)})
    text = write_result(tmp_path, "x", result).read_text()
    assert "NaN" not in text and "Infinity" not in text
    got = {i["id"]: i for i in json.loads(text)["items"]}["ex1.pub_rate"]
    assert got["evidence"] == {"nan": None, "inf": [1.0, None], "arr": [0, 1, 2], "i": 4, "f": 0.5,
                               "b": True, "t": [1, 2], "nested": {"x": None}}
    assert got["value"] == 0.99
    assert jsonable({1: object}) == {"1": str(object)}


@pytest.mark.parametrize("bad", ["", "../x", "a/b", ".hidden", "a..b", "x" * 200, "-rf"])
def test_unsafe_submission_ids_are_refused(tmp_path, lab3_result, bad):
    with pytest.raises(GraderError, match="submission id"):
        write_result(tmp_path, bad, lab3_result)


def test_grades_csv(tmp_path, lab3, lab3_result, make_finding):
    other = score(lab3, {"ex1.pub_topic": make_finding()}, manual={m: 5 for m in
                                                                   ("report", "q1", "q2", "q3", "q4", "q5")})
    path = write_grades_csv(tmp_path, {"zed": other, "amy": lab3_result}, rubric=lab3)
    assert path == tmp_path / "grades.csv"
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    header = path.read_text().splitlines()[0].split(",")
    assert header == ["submission", *lab3.item_ids, "auto_total", "manual_total", "total", "max",
                      "integrity_flags"]
    assert [r["submission"] for r in rows] == ["amy", "zed"]          # sorted
    amy, zed = rows
    assert amy["report"] == "" and amy["q1"] == ""                     # manual: empty for a person
    assert amy["ex1.pub_rate"] == "1.5" and amy["ex1.pub_topic"] == "4"
    assert amy["ex2.goal_publisher_robust"] == "fail" and amy["ex3.timeout"] == "error"
    assert (amy["auto_total"], amy["manual_total"], amy["total"], amy["max"]) == ("47", "", "", "100")
    assert amy["integrity_flags"] == "integrity.no_teleport"
    assert zed["ex1.pub_topic"] == "4" and zed["ex1.pub_rate"] == "0"    # missing finding -> 0
    assert (zed["manual_total"], zed["total"]) == ("30", "34")


def test_grades_csv_refuses_mixed_labs_and_student_views(lab3, lab3_result):
    with pytest.raises(ValueError, match="instructor view"):
        grades_csv_text({"a": lab3_result.for_student()}, lab3)
    from dataclasses import replace
    with pytest.raises(ValueError, match="not 'enee467-lab3'"):
        grades_csv_text({"a": replace(lab3_result, lab="other")}, lab3)


def test_result_json_keeps_number_lists_on_one_line(tmp_path, lab3, make_finding):
    from grader.report.result import dumps

    evidence = {"series": {"t": [0.5, 1.0, None], "ok": [True, False]}, "text": "a [\n 1,\n 2\n] b",
                "rows": [{"x": 1}, {"x": 2}]}
    text = dumps({"evidence": evidence})
    assert '"t": [0.5, 1.0, null]' in text and '"ok": [true, false]' in text
    assert json.loads(text) == {"evidence": evidence}          # strings untouched, rows still indented
    result = score(lab3, {"ex1.pub_rate": make_finding(evidence=evidence)})
    assert json.loads(write_result(tmp_path, "x", result).read_text())["items"][8]["evidence"] == evidence


def test_previous_summary_is_what_a_regrade_keeps(lab3_result):
    from grader.report.result import previous_summary, result_document

    prev = previous_summary(result_document(lab3_result, "alice", versions={"grader": "0.1.0"}))
    assert prev is not None and prev.auto_score == 47 and prev.versions == {"grader": "0.1.0"}
    assert prev.model_dump(mode="json")["items"]["ex1.pub_rate"] == {"points": 1.5, "status": "partial"}
    assert previous_summary(None) is None
