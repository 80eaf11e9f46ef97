"""`grader scores export`: merge then export round trip for Canvas, Gradescope and long format;
unmatched rows listed; roster problems named."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import pytest
from scorehelpers import write_csv

from grader.cli import main as grader_main
from grader.scores import ScoresError, export_gradebook, merge_manual_scores, parse_mapping, read_roster

ROSTER = ("Student,ID,SIS User ID,SIS Login ID,Section,Email,github\n"
          '"Doe, Jane",101,UID1,jdoe,ENEE467-0101,jdoe@umd.edu,reference\n'
          '"Roe, Rick",102,UID2,rroe,ENEE467-0101,rroe@umd.edu,bm_log10\n'
          '"Poe, Ann",103,UID3,apoe,ENEE467-0102,apoe@umd.edu,apoe-gh\n'
          '"Moe, Max",104,UID4,mmoe,ENEE467-0102,mmoe@umd.edu,\n')
#: reference: complete (50 auto + 38.5 manual); bm_log10: report only (incomplete);
#: wrong_topic: complete (6 auto + 20 manual) but not on the roster
SHEET = ("submission,report,q1,q1 comment,q2,q3,q4,q5\n"
         "reference,9,8,=SUM(A1),7.5,0,6,8\n"
         "bm_log10,5,,,,,,\n"
         "wrong_topic,4,4,,4,4,4,0\n")


@pytest.fixture
def merged(batch: Path, tmp_path: Path) -> Path:
    merge_manual_scores(batch, write_csv(tmp_path / "manual.csv", SHEET))
    return batch


@pytest.fixture
def roster(tmp_path: Path):
    return read_roster(write_csv(tmp_path / "roster.csv", ROSTER), parse_mapping(["submission=github"]))


def canvas_import(text: str) -> dict:
    """What Canvas's gradebook importer takes from the file (its rules, from
    canvas-lms lib/gradebook_importer.rb): header row[0] names Student and row[1] ID, SIS User ID
    and SIS Login ID follow, Section ends the student columns; an assignment header "Title (id)"
    matches by id; a row whose first cell contains "Points Possible" sets the maximum."""
    rows = list(csv.reader(io.StringIO(text)))
    header = rows[0]
    assert "Student" in header[0] and "ID" in header[1]
    assert re.search(r"SIS\s+User\s+ID", header[2]) and re.search(r"SIS\s+Login\s+ID", header[3])
    assert "Section" in header[4]
    title, assignment_id = re.fullmatch(r"(.*)\s\((\d+)\)", header[5]).groups()
    points_possible, students = None, {}
    for row in rows[1:]:
        if "Points Possible" in row[0]:
            points_possible = float(row[5])
            continue
        students[row[1] or row[2] or row[3] or row[0]] = float(row[5])
    return {"title": title, "assignment_id": assignment_id, "points_possible": points_possible,
            "scores": students}


def test_canvas_round_trip(merged: Path, roster, tmp_path: Path) -> None:
    report = export_gradebook(merged, "canvas", roster=roster, assignment="Lab 3 (12345)",
                              path=tmp_path / "canvas.csv", allow_pending=True)
    text = (tmp_path / "canvas.csv").read_text(encoding="utf-8")
    assert text == ("Student,ID,SIS User ID,SIS Login ID,Section,Lab 3 (12345)\n"
                    "    Points Possible,,,,,100\n"
                    '"Doe, Jane",101,UID1,jdoe,ENEE467-0101,88.5\n')
    assert canvas_import(text) == {"title": "Lab 3", "assignment_id": "12345", "points_possible": 100,
                                   "scores": {"101": 88.5}}
    assert report.rows == 1
    assert report.no_roster_row == ["wrong_topic"]
    assert [s.describe() for s in report.no_submission] == ["line 4: Poe, Ann (apoe-gh)",
                                                            "line 5: Moe, Max (no submission id)"]
    assert report.incomplete == ["bm_log10"]
    assert report.notes == []


def test_canvas_partial_exports_points_so_far(merged: Path, roster, tmp_path: Path) -> None:
    report = export_gradebook(merged, "canvas", roster=roster, assignment="Lab 3 (12345)",
                              path=tmp_path / "canvas.csv", partial=True)
    assert canvas_import((tmp_path / "canvas.csv").read_text())["scores"] == {"101": 88.5, "102": 7}
    assert report.incomplete == []


def test_canvas_without_assignment_id_says_how_canvas_will_match(merged: Path, roster) -> None:
    report = export_gradebook(merged, "canvas", roster=roster, allow_pending=True)
    header = (merged / "gradebook-canvas.csv").read_text().splitlines()[0]
    assert header.endswith(",ENEE 467 Lab 3: Introduction to Programming with ROS 2")
    assert report.notes == [
        'the Canvas column "ENEE 467 Lab 3: Introduction to Programming with ROS 2" has no assignment '
        "id: Canvas will match it by exact name or create a new assignment; pass --assignment "
        "\"NAME (ID)\" with the id from the assignment's URL"]


def test_gradescope_csv(merged: Path, roster, tmp_path: Path) -> None:
    export_gradebook(merged, "gradescope-csv", roster=roster, path=tmp_path / "gs.csv", allow_pending=True)
    rows = list(csv.DictReader((tmp_path / "gs.csv").open(encoding="utf-8")))
    assert len(rows) == 1
    row = rows[0]
    assert {k: row[k] for k in ("Name", "SID", "Email", "Sections", "Total Score", "Max Points", "Status")} \
        == {"Name": "Doe, Jane", "SID": "", "Email": "jdoe@umd.edu", "Sections": "ENEE467-0101",
            "Total Score": "88.5", "Max Points": "100", "Status": "Graded"}
    assert row["q2: Question 2: build type for C++ and Python (8.0 pts)"] == "7.5"
    assert row["ex1.boxmuller: simple_subscriber computes the Box-Muller transform of each pair (6.0 pts)"] == "6"
    assert not any(k.startswith(("integrity.", "ex3.timeout")) for k in row)      # no points: no column


def test_long_format_has_every_item_and_guards_formulas(merged: Path, roster, tmp_path: Path) -> None:
    export_gradebook(merged, "long", roster=roster, path=tmp_path / "long.csv")
    raw = (tmp_path / "long.csv").read_bytes()
    assert raw.startswith(b"\xef\xbb\xbf")                          # Excel opens it as UTF-8
    rows = list(csv.DictReader(io.StringIO(raw.decode("utf-8-sig"))))
    assert {r["submission"] for r in rows} == {"reference", "bm_log10"}   # incomplete ones too
    ref = {r["item"]: r for r in rows if r["submission"] == "reference"}
    # 6 manual + 21 automatic items and the total
    assert len(ref) == 28 and ref["total"]["points"] == "88.5" and ref["total"]["status"] == "final"
    assert ref["q1"]["feedback"] == "'=SUM(A1)" and ref["q1"]["student"] == "Doe, Jane"
    assert ref["integrity.no_teleport"]["status"] == "pass"
    bm = {r["item"]: r for r in rows if r["submission"] == "bm_log10"}
    assert (bm["q1"]["points"], bm["q1"]["status"]) == ("", "pending")
    assert (bm["total"]["points"], bm["total"]["status"]) == ("", "pending")


def test_long_format_without_roster_lists_every_submission(merged: Path, tmp_path: Path) -> None:
    report = export_gradebook(merged, "long", path=tmp_path / "long.csv")
    rows = list(csv.DictReader(io.StringIO((tmp_path / "long.csv").read_text(encoding="utf-8-sig"))))
    assert sorted({r["submission"] for r in rows}) == ["bm_log10", "reference", "wrong_topic"]
    assert report.rows == 3 and report.no_roster_row == []


def test_cli_export_lists_what_it_left_out(merged: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    roster_path = write_csv(tmp_path / "roster.csv", ROSTER)
    out_file = tmp_path / "canvas.csv"
    assert grader_main(["scores", "export", str(merged), "--roster", str(roster_path), "--map",
                        "submission=github", "--format", "canvas", "--assignment", "Lab 3 (12345)",
                        "-o", str(out_file), "--allow-pending"]) == 0
    captured = capsys.readouterr()
    assert captured.err.splitlines() == [
        "grader: warning: submission wrong_topic has no roster row: not exported",
        "grader: warning: roster line 4: Poe, Ann (apoe-gh): no graded submission",
        "grader: warning: roster line 5: Moe, Max (no submission id): no graded submission",
        "grader: warning: submission bm_log10: manual items still pending, left out (--partial "
        "exports the points so far)"]
    assert captured.out == (f"wrote {out_file} (canvas): 1 student(s); 1 submission(s) without a roster "
                            "row, 2 roster row(s) without a submission, 1 incomplete left out\n")


def test_a_canvas_gradebook_export_works_as_roster_without_map(merged: Path, tmp_path: Path) -> None:
    """Canvas's own export (with its Points Possible row) plus a `submission` column."""
    path = write_csv(tmp_path / "canvas-export.csv", (
        "Student,ID,SIS User ID,SIS Login ID,Section,Lab 1 (11111),submission\n"
        "    Points Possible,,,,,10,\n"
        '"Doe, Jane",101,UID1,jdoe,ENEE467-0101,9,reference\n'
        '"Student, Test",999,,,ENEE467-0101,,\n'))
    roster = read_roster(path)
    assert roster.columns == {"submission": "submission", "name": "Student", "id": "ID",
                              "sis_user_id": "SIS User ID", "sis_login_id": "SIS Login ID",
                              "section": "Section"}
    report = export_gradebook(merged, "canvas", roster=roster, assignment="Lab 3 (12345)")
    assert canvas_import((merged / "gradebook-canvas.csv").read_text())["scores"] == {"101": 88.5}
    assert [s.describe() for s in report.no_submission] == ["line 4: Student, Test (no submission id)"]


ROSTER_ERRORS = {
    "unknown field": (["github=submission"], None,
                      ["unknown field \"github\"; the fields are submission, name, id, sis_user_id, "
                       "sis_login_id, section, email, sid, late_days"]),
    "not FIELD=COLUMN": (["submission"], None,
                         ['"submission" is not FIELD=COLUMN (e.g. submission=github_username)']),
    "missing column": (["submission=GitHub user"], ROSTER,
                       ['--map submission=GitHub user: the roster has no column "GitHub user" (its '
                        'columns: "Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Email", '
                        '"github")']),
    "no submission column": ([], ROSTER,
                             ['no column with the submission ids: name it with --map submission=COLUMN '
                              '(the roster\'s columns: "Student", "ID", "SIS User ID", "SIS Login ID", '
                              '"Section", "Email", "github")']),
    "submission id on two rows": (["submission=github"],
                                  "Student,github\nA,reference\nB,bm_log10\nC,reference\n",
                                  ['line 4: submission id "reference" is also on line 2']),
}


@pytest.mark.parametrize("case", list(ROSTER_ERRORS))
def test_roster_errors(case: str, tmp_path: Path) -> None:
    specs, text, problems = ROSTER_ERRORS[case]
    with pytest.raises(ScoresError) as exc:
        read_roster(write_csv(tmp_path / "roster.csv", text or ROSTER), parse_mapping(specs))
    assert exc.value.problems == problems


def test_rows_an_lms_could_not_match_are_errors(merged: Path, tmp_path: Path) -> None:
    roster = read_roster(write_csv(tmp_path / "r.csv", "Section,github\nS1,reference\n"),
                         parse_mapping(["submission=github"]))
    with pytest.raises(ScoresError) as exc:
        export_gradebook(merged, "canvas", roster=roster, path=tmp_path / "x.csv")
    assert exc.value.problems == ["line 2: no Student, ID, SIS User ID or SIS Login ID value, Canvas "
                                  "could not match the row (reference)"]
    with pytest.raises(ScoresError) as exc:
        export_gradebook(merged, "gradescope-csv", roster=roster, path=tmp_path / "x.csv")
    assert exc.value.problems == ["line 2: no Email or SID value, Gradescope could not match the row "
                                  "(reference)"]
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("fmt", ["canvas", "gradescope-csv"])
def test_export_refuses_while_manual_scores_are_pending(fmt: str, merged: Path, tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """bm_log10's questions are still pending: no gradebook file, a non-zero exit and one
    sentence (it used to write a file without them and exit 0). --allow-pending writes the
    complete grades and lists the rest; --partial the points so far."""
    roster_path = write_csv(tmp_path / "roster.csv", ROSTER)
    out_file = tmp_path / "book.csv"
    args = ["scores", "export", str(merged), "--roster", str(roster_path), "--map", "submission=github",
            "--format", fmt, "--assignment", "Lab 3 (12345)", "-o", str(out_file)]
    assert grader_main(args) != 0
    err = capsys.readouterr().err
    assert err == ("grader: error: 1 submission(s) still have manual items pending (bm_log10 (q1, q2, q3, q4, "
                   "q5)): merge their scores first (grader scores merge), or export the complete grades only "
                   "with --allow-pending (--partial: the points so far); nothing was written\n")
    assert not out_file.exists()
    assert grader_main(args + ["--allow-pending"]) == 0
    assert out_file.exists() and "bm_log10: manual items still pending" in capsys.readouterr().err
    assert grader_main(args + ["--partial"]) == 0
