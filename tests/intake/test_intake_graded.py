"""Intake through to the gradebook, with the committed Lab 3 recordings standing in for building
and running (grader.testing.batch.recorded_intake): a Canvas download, a Gradescope export and
GitHub Classroom clones made by the tests, graded under a late policy; the roster table, the
penalties in result.json, grades.csv, the report and the class view; a TA's late_penalty
override; the Canvas and Gradescope gradebooks row by row. (A real build-and-run grading of a
Canvas download: test_intake_e2e.py.)"""

from __future__ import annotations

import csv
import io
import json
import shutil
from datetime import datetime
from pathlib import Path

import pytest
from intakehelpers import LAB3, LAB3_RUBRIC, canvas_zip, clone, gradescope_export, zip_tree

from grader.cli import main as grader_main
from grader.intake import read_intake
from grader.rubric.intake_fields import LatePolicy
from grader.rubric.load import load_rubric
from grader.scores import ScoresError, export_gradebook, merge_manual_scores, read_roster
from grader.testing.batch import LAB3_BAGS, recorded_intake

POLICY = LatePolicy(due="2025-02-14 23:59", timezone="America/New_York", grace_minutes=15, percent=10, cap=30)
CANVAS_ROSTER = ("Student,ID,SIS User ID,SIS Login ID,Section\n"
                 "    Points Possible,,,,\n"
                 '"Doe, Jane",101,UID1,jdoe,ENEE467-0101\n'
                 '"Roe, Rick",102,UID2,rroe,ENEE467-0101\n'
                 '"Moe, Max",104,UID4,mmoe,ENEE467-0102\n')
#: manual points for every submission (Lab 3: report 10, q1..q5 8 each = 50)
MANUAL = ("submission,report,q1,q2,q3,q4,q5\n"
          "jdoe,10,8,8,8,8,8\n"
          "rroe,5,4,4,4,4,4\n"
          "smithbob,10,8,8,8,8,8\n")


def lab3(policy: LatePolicy = POLICY):
    return load_rubric(LAB3_RUBRIC).model_copy(update={"late": policy})


@pytest.fixture(scope="module")
def canvas_batch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Jane (reference) LATE, her zip's newest file 1 day 3 h after the due date; Rick (bm_log10)
    on time; Bob (wrong_topic) on time and not on the roster."""
    tmp = tmp_path_factory.mktemp("canvas")
    zips = tmp / "zips"
    zips.mkdir()
    files = {
        "doejane_LATE_101_9001_ws.zip": zip_tree(LAB3 / "reference" / "src", zips / "a.zip",
                                                 datetime(2025, 2, 16, 2, 59)).read_bytes(),
        "roerick_102_9002_ws.zip": zip_tree(LAB3 / "bm_log10" / "src", zips / "b.zip",
                                            datetime(2025, 2, 14, 20, 0)).read_bytes(),
        "smithbob_777_9003_ws.zip": zip_tree(LAB3 / "wrong_topic" / "src", zips / "c.zip",
                                             datetime(2025, 2, 14, 21, 0)).read_bytes()}
    download = canvas_zip(tmp / "submissions.zip", files)
    (tmp / "roster.csv").write_text(CANVAS_ROSTER)
    rubric = lab3()
    out = tmp / "OUT"
    batch = read_intake(download, rubric, work=out / ".intake",
                        roster=read_roster(tmp / "roster.csv", require_submission=False))
    assert [(a.id, a.matched_by) for a in batch.arrivals] == [
        ("jdoe", "Canvas user id 101 = roster ID"), ("rroe", "Canvas user id 102 = roster ID"),
        ("smithbob", "not on the roster (no row with ID 777, name smithbob)")]
    assert [s.get("name") for s in batch.no_submission] == ["Moe, Max"]
    recorded_intake(batch.arrivals, {"jdoe": LAB3_BAGS / "reference", "rroe": LAB3_BAGS / "bm_log10",
                                     "smithbob": LAB3_BAGS / "wrong_topic"}, out, rubric)
    return out


@pytest.fixture
def canvas_out(canvas_batch: Path, tmp_path: Path) -> Path:
    out = tmp_path / "OUT"
    shutil.copytree(canvas_batch, out, symlinks=True)
    (tmp_path / "roster.csv").write_text(CANVAS_ROSTER)
    return out


def grades(out: Path) -> dict[str, dict[str, str]]:
    return {r["submission"]: r for r in csv.DictReader((out / "grades.csv").open(encoding="utf-8"))}


def test_canvas_penalties_in_result_grades_report_and_class_view(canvas_out: Path) -> None:
    rows = grades(canvas_out)
    late = {sid: {k: r[k] for k in ("auto_total", "manual_total", "late_penalty", "total", "late_by", "intake",
                                     "lms_id", "student")} for sid, r in rows.items()}
    assert late == {
        "jdoe": {"auto_total": "50", "manual_total": "", "late_penalty": "20", "total": "", "late_by": "1 day 3 h",
                 "intake": "canvas", "lms_id": "101", "student": "Doe, Jane"},
        "rroe": {"auto_total": "2", "manual_total": "", "late_penalty": "0", "total": "", "late_by": "on time",
                 "intake": "canvas", "lms_id": "102", "student": "Roe, Rick"},
        "smithbob": {"auto_total": "6", "manual_total": "", "late_penalty": "0", "total": "", "late_by": "on time",
                     "intake": "canvas", "lms_id": "777", "student": ""}}
    assert rows["jdoe"]["time_source"] == ("Canvas's LATE mark in the file name (the download has no submission "
                                           "times); lateness from the newest file time inside ws.zip (set by the "
                                           "student's machine)")
    assert rows["jdoe"]["submitted_at"] == "2025-02-16T02:59:00-05:00"
    doc = json.loads((canvas_out / "jdoe" / "result.json").read_text())
    assert (doc["score"], doc["late_penalty"], doc["late"]["units"], doc["late"]["percent"]) == (50, 20, 2, 20)
    assert doc["intake"]["student"]["sis_login_id"] == "jdoe" and doc["intake"]["lms"]["late_mark"] is True
    report = (canvas_out / "jdoe" / "report.html").read_text()
    assert ('<p class="sub" id="late">Submitted 2025-02-16 02:59 EST, 1 day 3 h after the due date 2025-02-14 '
            "23:59 EST: 2 days begun; 20% of the lab&#x27;s points deducted. Time from Canvas&#x27;s LATE mark")\
        in report
    assert 'data-score="late">Late<b>−20</b><span>late policy</span>' in report
    assert '<p class="sub" id="who">Doe, Jane · Canvas user id 101 · doejane_LATE_101_9001_ws.zip</p>' in report
    index = (canvas_out / "index.html").read_text()
    assert '<button type="button" class="sort">Late penalty</button>' in index and "−20 (1 day 3 h)" in index


def test_merge_takes_a_late_penalty_override_and_regrade_keeps_it(canvas_out: Path, tmp_path: Path) -> None:
    sheet = tmp_path / "manual.csv"
    sheet.write_text(MANUAL.replace("submission,report", "submission,late_penalty,report")
                     .replace("jdoe,10", "jdoe,5,10").replace("rroe,5", "rroe,0,5").replace("smithbob,10", "smithbob,,10"))
    report = merge_manual_scores(canvas_out, sheet)
    assert [c.describe() for c in report.changes if c.item == "late_penalty"] == ["jdoe: late_penalty policy -> 5"]
    rows = grades(canvas_out)          # rroe's 0 is the penalty in force: no override
    assert {sid: (r["late_penalty"], r["total"]) for sid, r in rows.items()} == {
        "jdoe": ("5", "95"), "rroe": ("0", "27"), "smithbob": ("0", "56")}
    assert "The instructor set the late penalty to 5 point(s) (manual.csv line 2)." in \
        (canvas_out / "jdoe" / "report.html").read_text()
    assert grader_main(["regrade", str(canvas_out), "--rubric", str(LAB3_RUBRIC)]) == 0
    # the rubric file has no late policy: the TA's 5 points stay; the others have none now
    assert {sid: (r.get("late_penalty"), r["total"]) for sid, r in grades(canvas_out).items()} == {
        "jdoe": ("5", "95"), "rroe": ("", "27"), "smithbob": ("", "56")}
    sheet.write_text("submission,late_penalty\njdoe,policy\n")
    merge_manual_scores(canvas_out, sheet)
    assert "late_penalty" not in grades(canvas_out)["jdoe"]


def test_merge_rejects_bad_late_penalties(canvas_out: Path, tmp_path: Path) -> None:
    sheet = tmp_path / "bad.csv"
    sheet.write_text("submission,late_penalty\njdoe,-3\nrroe,lots\nsmithbob,101\n")
    with pytest.raises(ScoresError) as exc:
        merge_manual_scores(canvas_out, sheet)
    assert exc.value.problems == [
        "line 2, late_penalty: -3 is negative (the points deducted for lateness: 0 or more)",
        'line 3, late_penalty: "lots" is not a number (the points to deduct, 0 to waive the penalty, or "policy" '
        "for the late policy's own)",
        "line 4, late_penalty: 101 is over the lab's 100 points"]


def test_canvas_gradebook_row_by_row(canvas_out: Path, tmp_path: Path, capsys) -> None:
    """The Canvas gradebook export (no submission column) is the roster: each submission finds its
    row by the Canvas user id it kept; the totals have the late penalty off."""
    roster = tmp_path / "roster.csv"
    args = ["scores", "export", str(canvas_out), "--roster", str(roster), "--format", "canvas",
            "--assignment", "Lab 3 (555)", "-o", str(tmp_path / "canvas.csv")]
    assert grader_main(args) == 2                              # manual items pending: refused
    assert "2 submission(s) still have manual items pending (jdoe (report" in capsys.readouterr().err
    sheet = tmp_path / "manual.csv"
    sheet.write_text(MANUAL)
    merge_manual_scores(canvas_out, sheet)
    assert grader_main(args) == 0
    captured = capsys.readouterr()
    assert (tmp_path / "canvas.csv").read_text().splitlines() == [
        "Student,ID,SIS User ID,SIS Login ID,Section,Lab 3 (555)",
        "    Points Possible,,,,,100",
        '"Doe, Jane",101,UID1,jdoe,ENEE467-0101,80',            # 100 - 20 (2 days late)
        '"Roe, Rick",102,UID2,rroe,ENEE467-0101,27']
    assert captured.err.splitlines() == [
        "grader: warning: submission smithbob has no roster row: not exported",
        "grader: warning: roster line 5: Moe, Max (no submission id): no graded submission"]
    assert captured.out.splitlines()[0].startswith(
        "jdoe: late penalty 20 point(s): Submitted 2025-02-16 02:59 EST, 1 day 3 h after the due date")
    assert captured.out.splitlines()[-1].endswith("2 student(s); 1 submission(s) without a roster row, "
                                                  "1 roster row(s) without a submission, 0 incomplete left out")


GRADESCOPE_META = """\
submission_1001:
  :submitters:
  - {':name': Jane Doe, ':sid': '5001', ':email': jdoe@umd.edu}
  :created_at: 2025-02-15 04:20:00.000000000 Z
submission_1002:
  :submitters:
  - {':name': Rick Roe, ':sid': '5002', ':email': rroe@umd.edu}
  - {':name': Ann Poe, ':sid': '5003', ':email': apoe@umd.edu}
  :created_at: 2025-02-17 06:00:00.000000000 Z
"""
GRADESCOPE_ROSTER = ("Name,SID,Email,Sections,late_days\n"
                     "Jane Doe,5001,jdoe@umd.edu,0101,2\n"
                     "Rick Roe,5002,rroe@umd.edu,0101,1\n"
                     "Ann Poe,5003,apoe@umd.edu,0102,\n")


def test_gradescope_export_with_late_days_row_by_row(tmp_path: Path) -> None:
    """Late days: Jane 5 minutes late but within the 15-minute grace; Rick and Ann's group
    submission 2 days 1 h late (3 days begun): Rick has 1 late day left (2 charged at 10%), Ann
    the whole budget of 3 (nothing charged)."""
    root = gradescope_export(tmp_path / "export", GRADESCOPE_META, {
        "submission_1001": LAB3 / "wrong_topic", "submission_1002": LAB3 / "bm_log10"})
    (tmp_path / "roster.csv").write_text(GRADESCOPE_ROSTER)
    rubric = lab3(LatePolicy(due="2025-02-14 23:59", timezone="America/New_York", grace_minutes=15,
                             late_days=3, percent=10, of="earned"))
    out = tmp_path / "OUT"
    batch = read_intake(root, rubric, work=out / ".intake",
                        roster=read_roster(tmp_path / "roster.csv", require_submission=False))
    recorded_intake(batch.arrivals, {"jdoe": LAB3_BAGS / "wrong_topic", "rroe": LAB3_BAGS / "bm_log10",
                                     "apoe": LAB3_BAGS / "bm_log10"}, out, rubric)
    merge_manual_scores(out, _sheet(tmp_path, "submission,report,q1,q2,q3,q4,q5\njdoe,10,8,8,8,8,8\n"
                                              "rroe,10,8,8,8,8,8\napoe,10,8,8,8,8,8\n"))
    export_gradebook(out, "gradescope-csv", roster=read_roster(tmp_path / "roster.csv", require_submission=False),
                     path=tmp_path / "gs.csv")
    rows = list(csv.reader(io.StringIO((tmp_path / "gs.csv").read_text())))
    assert rows[0][:12] == ["Name", "SID", "Email", "Sections", "Total Score", "Max Points", "Status",
                            "Submission ID", "Submission Time", "Lateness (H:M:S)", "Late Penalty", "Time Source"]
    source = "Gradescope's submission time (created_at in submission_metadata.yml)"
    assert [r[:12] for r in rows[1:]] == [
        ["Jane Doe", "5001", "jdoe@umd.edu", "0101", "56", "100", "Graded", "1001",
         "2025-02-14T23:20:00-05:00", "0:00:00", "0", source],
        ["Rick Roe", "5002", "rroe@umd.edu", "0101", "41.6", "100", "Graded", "1002",
         "2025-02-17T01:00:00-05:00", "49:01:00", "10.4", source],            # 20% of 52 earned
        ["Ann Poe", "5003", "apoe@umd.edu", "0102", "52", "100", "Graded", "1002",
         "2025-02-17T01:00:00-05:00", "49:01:00", "0", source]]
    docs = {sid: json.loads((out / sid / "result.json").read_text())["late"] for sid in ("rroe", "apoe")}
    assert [(d["units"], d["late_days_used"], d["late_days_left"], d["percent"]) for d in docs.values()] == \
        [(3, 1, 0, 20), (3, 3, 0, 0)]
    long_rows = _long(out, tmp_path)
    assert long_rows["rroe"]["late_penalty"]["points"] == "-10.4" and long_rows["rroe"]["total"]["points"] == "41.6"


def _sheet(tmp_path: Path, text: str) -> Path:
    (tmp_path / "manual.csv").write_text(text)
    return tmp_path / "manual.csv"


def _long(out: Path, tmp_path: Path) -> dict[str, dict[str, dict[str, str]]]:
    export_gradebook(out, "long", path=tmp_path / "long.csv")
    rows: dict[str, dict[str, dict[str, str]]] = {}
    for r in csv.DictReader(io.StringIO((tmp_path / "long.csv").read_text(encoding="utf-8-sig"))):
        rows.setdefault(r["submission"], {})[r["item"]] = r
    return rows


def test_classroom_clones_late_by_their_last_commit(tmp_path: Path) -> None:
    root = tmp_path / "clones"
    root.mkdir()
    clone(LAB3 / "wrong_topic", root / "lab3-alice", ["2025-02-14T23:50:00-05:00"])
    clone(LAB3 / "bm_log10", root / "lab3-bob", ["2025-02-14T12:00:00-05:00", "2025-02-15T03:00:00-05:00"])
    out = tmp_path / "OUT"
    rubric = lab3()
    batch = read_intake(root, rubric, work=out / ".intake", classroom_prefix="lab3-")
    recorded_intake(batch.arrivals, {"alice": LAB3_BAGS / "wrong_topic", "bob": LAB3_BAGS / "bm_log10"}, out,
                    rubric, due_override={"due": "2025-02-15 00:30", "timezone": None})   # --due
    rows = grades(out)
    assert {sid: (r["late_penalty"], r["late_by"], r["intake"], r["lms_id"]) for sid, r in rows.items()} == {
        "alice": ("0", "on time", "classroom", "lab3-alice"),
        "bob": ("2", "2 h 30 min", "classroom", "lab3-bob")}          # 10% of 100, capped at the 2 earned
    assert rows["bob"]["time_source"] == "the last commit's date (git committer date, set by the student's machine)"
    doc = json.loads((out / "bob" / "result.json").read_text())
    assert doc["late"]["due"] == "2025-02-15T00:30:00-05:00" and doc["intake"]["due_override"]["due"] == \
        "2025-02-15 00:30"


def test_graded_without_roster_the_export_finds_students_by_canvas_id(tmp_path: Path, capsys) -> None:
    """Graded without --roster (ids are Canvas's names), exported with the gradebook: the Canvas
    user id each submission kept finds its row."""
    zips = tmp_path / "zips"
    zips.mkdir()
    ws = zip_tree(LAB3 / "wrong_topic" / "src", zips / "a.zip", datetime(2025, 2, 14, 20, 0)).read_bytes()
    download = canvas_zip(tmp_path / "submissions.zip", {"roerick_102_9002_ws.zip": ws, "smithbob_777_9003_ws.zip": ws})
    out = tmp_path / "OUT"
    rubric = load_rubric(LAB3_RUBRIC)
    batch = read_intake(download, rubric, work=out / ".intake")
    assert [a.id for a in batch.arrivals] == ["roerick", "smithbob"]
    recorded_intake(batch.arrivals, {a.id: LAB3_BAGS / "wrong_topic" for a in batch.arrivals}, out, rubric)
    (tmp_path / "roster.csv").write_text(CANVAS_ROSTER)
    assert grader_main(["scores", "export", str(out), "--roster", str(tmp_path / "roster.csv"), "--format",
                        "canvas", "--partial", "-o", str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.csv").read_text().splitlines()[2:] == ['"Roe, Rick",102,UID2,rroe,ENEE467-0101,6']
    assert "submission smithbob has no roster row: not exported" in capsys.readouterr().err
