"""One real intake, end to end: `grader grade` on a Canvas "Download Submissions" zip made by the
test (a LATE student, an on-time one, a student not on the roster, a student who uploaded the
four .py files instead of the package, a text entry), with the roster and a late policy; then
`grader scores export --format canvas`. Everything is built and run for real (first-nodes lab);
identical workspaces take the first one's build and recordings."""

from __future__ import annotations

import csv
import json
from datetime import datetime
from pathlib import Path

import pytest
from intakehelpers import FIRST, FIRST_RUBRIC, MODULES, canvas_zip, zip_tree

from grader.cli import main as grader_main

ROSTER = ("Student,ID,SIS User ID,SIS Login ID,Section\n"
          "    Points Possible,,,,\n"
          '"Doe, Jane",101,UID1,jdoe,0101\n'
          '"Roe, Rick",102,UID2,rroe,0101\n'
          '"Poe, Ann",103,UID3,apoe,0102\n'
          '"Moe, Max",104,UID4,mmoe,0102\n')
LATE = """
late:
  due: 2025-02-14 23:59
  timezone: America/New_York
  grace_minutes: 15
  percent: 10
  per: day
  cap: 30
"""


@pytest.mark.slow
@pytest.mark.ros
def test_grade_a_canvas_download_then_export_it(tmp_path: Path, capsys) -> None:
    ws = tmp_path / "ws"
    ws.mkdir()
    late = zip_tree(FIRST / "reference" / "src", ws / "late.zip", datetime(2025, 2, 16, 2, 59)).read_bytes()
    files = {"doejane_LATE_101_9001_lab1_ws.zip": late,        # 1 day 3 h late: 2 days begun, 20%
             "roerick_102_9002_lab1_ws.zip": late,             # the same files, on time by Canvas
             "smithbob_777_9003_lab1_ws.zip": late,            # not on the roster
             "moemax_LATE_104_text.html": b"<p>see attached</p>"}
    files.update({f"poeann_103_{9100 + i}_{m.name}": m.read_bytes() for i, m in enumerate(sorted(MODULES.glob("*.py")))})
    download = canvas_zip(tmp_path / "submissions.zip", files)
    rubric = tmp_path / "first_nodes.yaml"
    rubric.write_text(FIRST_RUBRIC.read_text().replace("\nitems:\n", LATE + "\nitems:\n", 1))
    (tmp_path / "roster.csv").write_text(ROSTER)
    out = tmp_path / "OUT"

    rc = grader_main(["grade", str(download), "--rubric", str(rubric), "-o", str(out), "--roster",
                      str(tmp_path / "roster.csv"), "--jobs", "2", "--cache-dir", str(tmp_path / "cache")])
    captured = capsys.readouterr()
    assert rc == 1, captured.err                       # the text entry is not graded: said, not skipped
    assert ("grader: moemax_LATE_104_text.html: not graded: submitted a text entry (moemax_LATE_104_text.html), "
            "which has no files to grade") in captured.err
    table = captured.out.splitlines()
    assert table[0] == ("Canvas download submissions.zip: 5 submission(s), 4 to grade; roster roster.csv: "
                        "4 student(s)")
    assert [line.split()[0] for line in table[2:7]] == ["jdoe", "—", "apoe", "rroe", "smithbob"]
    assert "Canvas user id 101 = roster ID" in table[2] and "LATE (Canvas) 2025-02-16 02:59" in table[2]
    assert "wrapped into package my_first_package" in table[4]

    rows = {r["submission"]: r for r in csv.DictReader((out / "grades.csv").open())}
    not_passed = {sid: [f"{i['id']}: {i['feedback'][:300]}" for i in json.loads((out / sid / "result.json")
                                                                               .read_text())["items"]
                        if i["status"] != "pass"] for sid in rows}
    # the loose files earn every point, as the package does: wrapping changes nothing
    assert {sid: (r["auto_total"], r["late_penalty"], r["total"], r["lms_id"], r["student"])
            for sid, r in rows.items()} == {
        "apoe": ("20", "0", "20", "103", "Poe, Ann"),
        "jdoe": ("20", "4", "16", "101", "Doe, Jane"),
        "rroe": ("20", "0", "20", "102", "Roe, Rick"),
        "smithbob": ("20", "0", "20", "777", "")}, not_passed
    assert "Submitted 2025-02-16 02:59 EST, 1 day 3 h after the due date" in (out / "jdoe" / "report.html").read_text()

    assert grader_main(["scores", "export", str(out), "--roster", str(tmp_path / "roster.csv"), "--format",
                        "canvas", "--assignment", "Lab 1 (555)", "-o", str(tmp_path / "canvas.csv")]) == 0
    assert (tmp_path / "canvas.csv").read_text().splitlines() == [
        "Student,ID,SIS User ID,SIS Login ID,Section,Lab 1 (555)",
        "    Points Possible,,,,,20",
        '"Doe, Jane",101,UID1,jdoe,0101,16',
        '"Roe, Rick",102,UID2,rroe,0101,20',
        '"Poe, Ann",103,UID3,apoe,0102,20']
    err = capsys.readouterr().err.splitlines()
    assert err == ["grader: warning: submission smithbob has no roster row: not exported",
                   "grader: warning: roster line 6: Moe, Max (no submission id): no graded submission"]
