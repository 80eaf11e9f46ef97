"""What `grader grade` reads before grading: a Canvas download (zip of zips or its folder), a
Gradescope export, GitHub Classroom clones and plain folders, each submission matched to the
roster with one table, loose files wrapped or refused. No grading here (see test_intake_graded)."""

from __future__ import annotations

import shutil
import zipfile
from datetime import datetime
from pathlib import Path

import pytest
from intakehelpers import (FIRST, FIRST_RUBRIC, LAB3, LAB3_RUBRIC, MODULES, canvas_zip, clone,
                           gradescope_export, zip_tree)

from grader.errors import GraderError
from grader.intake import read_intake
from grader.intake.loose import scan
from grader.rubric.load import load_rubric
from grader.scores.roster import read_roster

CANVAS_ROSTER = ("Student,ID,SIS User ID,SIS Login ID,Section\n"
                 "    Points Possible,,,,\n"
                 '"Doe, Jane",101,UID1,jdoe,ENEE467-0101\n'
                 '"Roe, Rick",102,UID2,rroe,ENEE467-0101\n'
                 '"Poe, Ann",103,UID3,apoe,ENEE467-0102\n'
                 '"Moe, Max",104,UID4,mmoe,ENEE467-0102\n')


def canvas_download(tmp_path: Path) -> Path:
    """Jane late (her zip's newest file 10:30 the day after the due date), Rick on time, an
    unmatched Bob, Ann's loose .py files (one uploaded twice: -1), Max's text entry."""
    ws = tmp_path / "ws"
    ws.mkdir()
    jane = zip_tree(FIRST / "reference" / "src", ws / "jane.zip", datetime(2025, 2, 15, 10, 30))
    rick = zip_tree(FIRST / "slow_timer" / "src", ws / "rick.zip", datetime(2025, 2, 14, 20, 0))
    bob = zip_tree(FIRST / "no_spin" / "src", ws / "bob.zip", datetime(2025, 2, 14, 21, 0))
    files = {"doejane_LATE_101_9001_lab3_ws.zip": jane.read_bytes(),
             "roerick_102_9002_lab3_ws.zip": rick.read_bytes(),
             "smithbob_777_9003_lab3_ws-1.zip": bob.read_bytes(),
             "moemax_LATE_104_text.html": b"<p>I will send it later</p>"}
    for i, module in enumerate(sorted(MODULES.glob("*.py"))):
        upload = module.name.replace("node.py", "node-1.py")          # re-uploaded once
        files[f"poeann_103_{9100 + i}_{upload}"] = module.read_bytes()
    return canvas_zip(tmp_path / "submissions.zip", files)


@pytest.fixture
def roster(tmp_path: Path):
    (tmp_path / "roster.csv").write_text(CANVAS_ROSTER)
    return read_roster(tmp_path / "roster.csv", require_submission=False)


def test_canvas_download_zip_of_zips(tmp_path: Path, roster) -> None:
    batch = read_intake(canvas_download(tmp_path), load_rubric(FIRST_RUBRIC), work=tmp_path / "OUT" / ".intake",
                        roster=roster)
    assert batch.kind == "canvas"
    rows = {r[0] if r[0] != "—" else r[1]: r for r in batch.rows()}
    assert rows["jdoe"][1:5] == ["doejane_LATE_101_9001_lab3_ws.zip", "Doe, Jane (line 3)",
                                 "Canvas user id 101 = roster ID", "LATE (Canvas) 2025-02-15 10:30"]
    assert rows["rroe"][1:5] == ["roerick_102_9002_lab3_ws.zip", "Roe, Rick (line 4)",
                                 "Canvas user id 102 = roster ID", "on time (Canvas) 2025-02-14 20:00"]
    assert rows["smithbob"][2:4] == ["—", "not on the roster (no row with ID 777, name smithbob)"]
    assert rows["apoe"][1].startswith("poeann_103_9100___init__.py, poeann_103_9101_my_first_node-1.py")
    assert rows["apoe"][5] == ("loose files (__init__.py, my_first_node.py, number_publisher.py, number_subscriber.py, "
                               "turtle_controller.py) wrapped into package my_first_package (the rubric's loose_files)")
    assert rows["moemax_LATE_104_text.html"][0] == "—"
    assert rows["moemax_LATE_104_text.html"][5] == ("REFUSED: submitted a text entry (moemax_LATE_104_text.html), "
                                                   "which has no files to grade")
    assert [a.id for a in batch.gradable] == ["jdoe", "apoe", "rroe", "smithbob"]
    table = batch.table()
    assert table.splitlines()[0] == ("Canvas download submissions.zip: 5 submission(s), 4 to grade; "
                                     "roster roster.csv: 4 student(s)")
    assert "REFUSED: submitted a text entry" in table and "smithbob" in table
    # the loose files became a package the build can take: console scripts from the rubric
    ann = next(a for a in batch.arrivals if a.id == "apoe")
    assert scan(ann.path) == (True, [f"src/my_first_package/my_first_package/{m.name}"
                                     for m in sorted(MODULES.glob("*.py"))] + ["src/my_first_package/setup.py"])
    setup = (ann.path / "src" / "my_first_package" / "setup.py").read_text()
    assert "'my_first_node = my_first_package.my_first_node:main'" in setup
    assert (ann.path / "src" / "my_first_package" / "my_first_package" / "my_first_node.py").read_bytes() == \
        (MODULES / "my_first_node.py").read_bytes()
    # the record that travels into result.json: the LMS's ids unchanged
    jane = next(a for a in batch.arrivals if a.id == "jdoe").record()
    assert jane["lms"] == {"canvas_user_id": "101", "name": "doejane", "attachment_ids": ["9001"], "late_mark": True}
    assert jane["student"] == {"line": 3, "name": "Doe, Jane", "id": "101", "sis_user_id": "UID1",
                               "sis_login_id": "jdoe", "section": "ENEE467-0101"}
    assert jane["time"]["lms_late"] is True and jane["time"]["at"] == "2025-02-15T10:30:00"


def test_canvas_folder_reads_like_its_zip_and_no_roster_keeps_canvas_names(tmp_path: Path) -> None:
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(canvas_download(tmp_path)) as zf:
        zf.extractall(folder)
    batch = read_intake(folder, load_rubric(FIRST_RUBRIC), work=tmp_path / "w")
    assert batch.kind == "canvas"
    assert sorted(a.id for a in batch.gradable) == ["doejane", "poeann", "roerick", "smithbob"]
    assert {a.matched_by for a in batch.arrivals} == {"no roster given"}


def test_loose_files_without_loose_files_in_the_rubric_are_refused_with_the_reason(tmp_path: Path, roster) -> None:
    batch = read_intake(canvas_download(tmp_path), load_rubric(LAB3_RUBRIC), work=tmp_path / "w", roster=roster)
    ann = next(a for a in batch.arrivals if a.lms.get("canvas_user_id") == "103")
    assert ann.refused == ("only loose files (__init__.py, my_first_node-1.py, number_publisher.py, "
                           "number_subscriber.py, turtle_controller.py) and no ROS package (package.xml): this "
                           "rubric does not say which package they belong in (loose_files:); ask for the "
                           "workspace's src/ folder or the package folders")
    assert not ann.gradable and "REFUSED: only loose files" in batch.table()


GRADESCOPE_META = """\
submission_1001:
  :submitters:
  - :name: Jane Doe
    :sid: '5001'
    :email: JDoe@umd.edu
  :created_at: 2025-02-15 04:10:00.861687000 Z
  :score: 0.0
  :history: []
  :results: !ruby/hash:ActiveSupport::HashWithIndifferentAccess
    score: 0.0
submission_1002:
  :submitters:
  - :name: Rick Roe
    :sid: '5002'
    :email: rroe@umd.edu
  - :name: Ann Poe
    :sid: '5003'
    :email: apoe@umd.edu
  :created_at: 2025-02-16 06:00:00.000000000 Z
  :score: 0.0
submission_1003:
  :submitters:
  - :name: Bob Smith
    :sid: '5009'
    :email: bsmith@umd.edu
  :created_at: 2025-02-14 22:00:00.000000000 -05:00
submission_1004:
  :submitters:
  - :name: Max Moe
    :sid: '5004'
    :email: mmoe@umd.edu
  :created_at: 2025-02-14 10:00:00.000000000 Z
"""
GRADESCOPE_ROSTER = ("Name,SID,Email,Sections\n"
                     "Jane Doe,5001,jdoe@umd.edu,0101\n"
                     "Rick Roe,5002,rroe@umd.edu,0101\n"
                     "Ann Poe,,apoe@umd.edu,0102\n"
                     "Max Moe,5004,mmoe@umd.edu,0102\n")


def gradescope(tmp_path: Path) -> Path:
    return gradescope_export(tmp_path / "assignment_77_export", GRADESCOPE_META, {
        "submission_1001": LAB3 / "reference",
        "submission_1002": LAB3 / "bm_log10",
        "submission_1003": LAB3 / "wrong_topic",
        "submission_1009": LAB3 / "pub_10hz"})           # not in the metadata


def test_gradescope_export(tmp_path: Path) -> None:
    (tmp_path / "roster.csv").write_text(GRADESCOPE_ROSTER)
    roster = read_roster(tmp_path / "roster.csv", require_submission=False)
    batch = read_intake(gradescope(tmp_path), load_rubric(LAB3_RUBRIC), work=tmp_path / "w", roster=roster)
    assert batch.kind == "gradescope"
    rows = [r[:5] for r in batch.rows()]
    assert rows == [
        ["jdoe", "submission_1001", "Jane Doe (line 2)", "e-mail JDoe@umd.edu = roster Email", "2025-02-15 04:10 +0000"],
        ["rroe", "submission_1002", "Rick Roe (line 3)", "e-mail rroe@umd.edu = roster Email", "2025-02-16 06:00 +0000"],
        ["apoe", "submission_1002", "Ann Poe (line 4)", "e-mail apoe@umd.edu = roster Email", "2025-02-16 06:00 +0000"],
        ["bsmith", "submission_1003", "—", "not on the roster (no row with e-mail bsmith@umd.edu, SID 5009, "
                                           "submission bsmith)", "2025-02-14 22:00 -0500"],
        ["—", "submission_1004", "Max Moe (line 5)", "e-mail mmoe@umd.edu = roster Email", "2025-02-14 10:00 +0000"]]
    assert batch.arrivals[1].notes == ["group submission 1002 of Rick Roe, Ann Poe: each gets its grade"]
    assert batch.arrivals[1].path == batch.arrivals[2].path
    assert batch.arrivals[4].refused == "listed in submission_metadata.yml but the export has no folder submission_1004"
    assert batch.skipped == ["submission_1009: a folder submission_metadata.yml does not list; not graded"]
    assert batch.no_submission == []
    assert batch.arrivals[0].record()["lms"] == {"submission_id": "1001", "name": "Jane Doe",
                                                 "email": "JDoe@umd.edu", "sid": "5001"}


def test_a_gradescope_export_zip_is_recognised(tmp_path: Path) -> None:
    root = gradescope(tmp_path)
    archive = shutil.make_archive(str(tmp_path / "export"), "zip", root.parent, root.name)
    batch = read_intake(Path(archive), load_rubric(LAB3_RUBRIC), work=tmp_path / "w")
    assert batch.kind == "gradescope" and [a.id for a in batch.gradable] == ["jdoe", "rroe", "apoe", "bsmith"]


def classroom(tmp_path: Path) -> Path:
    root = tmp_path / "lab3-submissions"
    root.mkdir()
    clone(LAB3 / "reference", root / "lab3-alice", ["2025-02-13T12:00:00-05:00", "2025-02-14T22:00:00-05:00"])
    clone(LAB3 / "bm_log10", root / "lab3-Bob-R", ["2025-02-16T01:30:00-05:00"])
    shutil.copytree(LAB3 / "wrong_topic", root / "lab3-carol")                    # not a clone: no time
    shutil.copytree(LAB3 / "pub_10hz", root / "starter-code")
    return root


def test_classroom_clones(tmp_path: Path) -> None:
    (tmp_path / "roster.csv").write_text("identifier,github_username,github_id,name\n"
                                         "alice@umd.edu,alice,1,Alice A\nbob@umd.edu,bob-r,2,Bob R\n"
                                         "dan@umd.edu,,,Dan D\n")
    roster = read_roster(tmp_path / "roster.csv")
    batch = read_intake(classroom(tmp_path), load_rubric(LAB3_RUBRIC), work=tmp_path / "w", roster=roster,
                        classroom_prefix="lab3-")
    assert batch.kind == "classroom"
    assert [r[:5] for r in batch.rows()] == [
        ["alice", "lab3-alice", "Alice A (line 2)", "GitHub login alice = roster submission", "2025-02-14 22:00 -0500"],
        ["bob-r", "lab3-Bob-R", "Bob R (line 3)", "GitHub login Bob-R = roster submission", "2025-02-16 01:30 -0500"],
        ["carol", "lab3-carol", "—", "not on the roster (no row with submission carol)", "—"]]
    assert batch.arrivals[0].time.source == ("the last commit's date (git committer date, set by the student's "
                                             "machine)")
    assert batch.skipped == ["starter-code: does not start with the prefix 'lab3-' (--classroom-prefix); not graded"]
    assert [s.get("name") for s in batch.no_submission] == ["Dan D"]
    assert "roster line 4: Dan D: no submission" in batch.table()


def test_a_folder_of_workspaces_and_archives_lists_stray_files(tmp_path: Path) -> None:
    root = tmp_path / "subs"
    shutil.copytree(FIRST / "reference", root / "alice")
    zip_tree(FIRST / "no_spin" / "src", root / "bob.zip", datetime(2025, 2, 14, 9, 0))
    (root / "carol.py").write_text("print('hi')\n")
    batch = read_intake(root, load_rubric(FIRST_RUBRIC), work=tmp_path / "w")
    assert batch.kind == "folder" and [a.id for a in batch.gradable] == ["alice", "bob"]
    assert batch.arrivals[0].time is None                        # a plain folder has no time
    assert batch.arrivals[1].time.source == "the newest file time inside bob.zip (set by the student's machine)"
    assert batch.skipped == ["carol.py: a file, not a submission folder or archive; not graded (put each "
                             "student's files in a folder named for the student)"]
    one = read_intake(FIRST / "reference", load_rubric(FIRST_RUBRIC), work=tmp_path / "w1")
    assert one.kind == "single" and [a.id for a in one.gradable] == ["reference"]


def test_a_folder_of_loose_files_is_wrapped(tmp_path: Path) -> None:
    root = tmp_path / "subs"
    (root / "dana" / "code").mkdir(parents=True)
    for module in ("my_first_node.py", "turtle_controller.py"):
        shutil.copy(MODULES / module, root / "dana" / "code" / module)
    batch = read_intake(root, load_rubric(FIRST_RUBRIC), work=tmp_path / "w")
    dana = batch.arrivals[0]
    assert dana.notes == ["loose files (my_first_node.py, turtle_controller.py) wrapped into package "
                          "my_first_package (the rubric's loose_files)",
                          "not among the files: number_publisher needs number_publisher.py; number_subscriber "
                          "needs number_subscriber.py (those programs cannot run)"]


def test_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(GraderError, match="does not exist"):
        read_intake(tmp_path / "nope", load_rubric(FIRST_RUBRIC), work=tmp_path / "w")
    (tmp_path / "empty").mkdir()
    with pytest.raises(GraderError, match="holds no submissions"):
        read_intake(tmp_path / "empty", load_rubric(FIRST_RUBRIC), work=tmp_path / "w")
    with pytest.raises(GraderError, match="need --classroom-prefix"):
        read_intake(tmp_path / "empty", load_rubric(FIRST_RUBRIC), work=tmp_path / "w", kind="classroom")


@pytest.mark.parametrize("name, parts", [
    ("doejane_LATE_12345_67890_lab3_ws.zip", ("doejane", "12345", "67890", "lab3_ws.zip", True, "")),
    ("o_brienpat_12_34_ws-1.zip", ("o_brienpat", "12", "34", "ws-1.zip", False, "")),     # name with _
    ("doejane_12_34_lab_1_2_x.py", ("doejane", "12", "34", "lab_1_2_x.py", False, "")),
    ("LATE_anon_Ab1Cd_34_ws.zip", ("anon_Ab1Cd", "Ab1Cd", "34", "ws.zip", True, "")),   # anonymous grading
    ("doejane_LATE_12345_link.html", ("doejane", "12345", "", "link.html", True, "link")),
    ("notes.txt", None), ("alice.zip", None),
])
def test_canvas_file_names(name: str, parts) -> None:
    from grader.intake.canvas import parse_name

    got = parse_name(name)
    assert (None if got is None else (got.name, got.user, got.attachment, got.file, got.late, got.entry)) == parts


def test_a_git_link_to_another_repository_gives_no_time(tmp_path: Path) -> None:
    """A submission whose .git is a link to another repository (the grader's own, say) gets no
    commit time from it (git would read that repository's history)."""
    from grader.intake.times import last_commit_time

    repo = clone(LAB3 / "wrong_topic", tmp_path / "lab3-eve", ["2025-02-14T21:00:00-05:00"])
    assert last_commit_time(repo).at.isoformat() == "2025-02-14T21:00:00-05:00"
    other = tmp_path / "other"
    shutil.copytree(LAB3 / "wrong_topic", other)
    (other / ".git").symlink_to(repo / ".git")
    assert last_commit_time(other) is None
