"""`grader scores merge` on a real graded batch: every output updated, re-runs safe, regrade and
re-grade keep the scores, all files or none."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import pytest
from scorehelpers import RUBRIC, snapshot, write_csv

from grader.cli import main as grader_main
from grader.report import read_result
from grader.rubric import load_rubric, score
from grader.scores import MANUAL_SCORES, load_manual_scores, merge_manual_scores
from grader.scores import transaction
from grader.scores.store import manual_scores_kept

FULL = {"report": 9, "q1": 8, "q2": 7.5, "q3": 0, "q4": 6, "q5": 8}


def sheet(tmp_path: Path, text: str, name: str = "manual.csv") -> Path:
    return write_csv(tmp_path / name, text)


def result(out: Path, sid: str):
    return read_result(out / sid / "result.json")[1]


def grades(out: Path) -> dict[str, dict[str, str]]:
    return {r["submission"]: r for r in csv.DictReader((out / "grades.csv").open(encoding="utf-8"))}


def test_merge_updates_result_report_store_and_grades_csv(batch: Path, tmp_path: Path) -> None:
    before = result(batch, "reference")
    assert before.manual_score is None and before.total is None and before.auto_score == 50
    path = sheet(tmp_path, "submission,report,q1,q1 comment,q2,q3,q4,q5\n"
                           'reference,9,8,"Right rate, <b>and</b> units.",7.5,0,6,8\n'
                           "bm_log10,5,,,,,,\n")
    report = merge_manual_scores(batch, path)

    ref = result(batch, "reference")
    assert {i.id: i.points for i in ref.items if i.kind == "manual"} == FULL
    assert ref.item("q1").feedback == "Right rate, <b>and</b> units."
    assert ref.manual_score == 38.5 and ref.complete and ref.total == 88.5
    # the same statuses and fractions as scoring with these manual points from the start
    expected = score(load_rubric(RUBRIC, check_files=False), {}, manual=FULL)
    for item_id in FULL:
        got, want = ref.item(item_id), expected.item(item_id)
        assert (got.points, got.status, got.fraction) == (want.points, want.status, want.fraction)
    # automatic items untouched
    assert [i for i in ref.items if i.kind != "manual"] == [i for i in before.items if i.kind != "manual"]

    html = (batch / "reference" / "report.html").read_text(encoding="utf-8")
    q1_row = html[html.index('data-item="q1"'):]
    q1_row = q1_row[: q1_row.index("</li>")]
    assert "8 / 8" in q1_row and "Right rate, &lt;b&gt;and&lt;/b&gt; units." in q1_row
    assert "88.5 / 100" in html

    rows = grades(batch)
    assert (rows["reference"]["q2"], rows["reference"]["manual_total"], rows["reference"]["total"]) == \
        ("7.5", "38.5", "88.5")
    assert (rows["bm_log10"]["report"], rows["bm_log10"]["q1"], rows["bm_log10"]["total"]) == ("5", "", "")
    assert rows["wrong_topic"]["report"] == "" and rows["wrong_topic"]["auto_total"] == "6"
    assert "88.5 / 100" in (batch / "index.html").read_text(encoding="utf-8")

    stored = load_manual_scores(batch / "reference")
    assert {k: v.points for k, v in stored.items()} == FULL
    assert stored["q1"].source == "manual.csv line 2" and stored["q1"].comment.startswith("Right rate")
    assert not (batch / "wrong_topic" / MANUAL_SCORES).exists()

    assert len(report.changes) == 7
    assert report.pending == {"bm_log10": ["q1", "q2", "q3", "q4", "q5"],
                              "wrong_topic": ["report", "q1", "q2", "q3", "q4", "q5"]}
    assert [p.name for p in report.written][-2:] == ["grades.csv", "index.html"]
    assert not list(batch.glob(".grader-stage*"))


def test_merging_the_same_sheet_twice_changes_nothing(batch: Path, tmp_path: Path) -> None:
    path = sheet(tmp_path, "submission,report,q1,q1 comment\nreference,9,8,fine\nbm_log10,5,,\n")
    merge_manual_scores(batch, path)
    first = snapshot(batch)
    again = merge_manual_scores(batch, path)
    assert again.changes == [] and again.written == []
    assert snapshot(batch) == first


def test_a_corrected_sheet_blank_keeps_pending_clears(batch: Path, tmp_path: Path) -> None:
    merge_manual_scores(batch, sheet(tmp_path, "submission,report,q1,q1 comment,q2,q3\n"
                                               "reference,9,8,first comment,7,6\n"))
    second = sheet(tmp_path, "submission,report,report comment,q1,q2,q3\n"
                             "reference,,Well structured.,,5,pending\n", "fix.csv")
    report = merge_manual_scores(batch, second)
    ref = result(batch, "reference")
    assert (ref.item("report").points, ref.item("report").feedback) == (9, "Well structured.")
    assert (ref.item("q1").points, ref.item("q1").feedback) == (8, "first comment")    # kept
    assert ref.item("q2").points == 5
    pending = score(load_rubric(RUBRIC, check_files=False), {}).item("q3")
    assert ref.item("q3") == pending                                 # exactly as never graded
    stored = load_manual_scores(batch / "reference")
    assert set(stored) == {"report", "q1", "q2"}
    assert stored["q1"].source == "manual.csv line 2" and stored["q2"].source == "fix.csv line 2"
    assert sorted(c.item for c in report.changes) == ["q2", "q3", "report"]


def test_a_filled_in_copy_of_grades_csv_is_a_valid_sheet(batch: Path, tmp_path: Path) -> None:
    rows = list(csv.reader((batch / "grades.csv").open(encoding="utf-8")))
    header = rows[0] + ["q4 comment"]
    for row in rows[1:]:
        row.append("")
        if row[0] == "reference":
            for item_id, points in FULL.items():
                row[header.index(item_id)] = f"{points:g}"
            row[header.index("q4 comment")] = "K_2 effect missing"
            row[header.index("total")] = "999"          # derived columns are ignored
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\r\n").writerows([header, *rows[1:]])
    merge_manual_scores(batch, sheet(tmp_path, buf.getvalue(), "grades-filled.csv"))
    assert grades(batch)["reference"]["total"] == "88.5"
    assert result(batch, "reference").item("q4").feedback == "K_2 effect missing"


def test_excel_csv_utf8_with_bom_semicolons_and_decimal_commas(batch: Path, tmp_path: Path) -> None:
    text = "\ufeffsubmission;q1;q1 comment\r\nreference;7,5;Très bien, merci\r\n"
    merge_manual_scores(batch, write_csv(tmp_path / "excel.csv", text))
    q1 = result(batch, "reference").item("q1")
    assert (q1.points, q1.feedback) == (7.5, "Très bien, merci")


def test_regrade_keeps_merged_manual_scores(batch: Path, tmp_path: Path) -> None:
    merge_manual_scores(batch, sheet(tmp_path, "submission,report,q1,q1 comment,q2,q3,q4,q5\n"
                                               "reference,9,8,ok,7.5,0,6,8\n"))
    assert grader_main(["regrade", str(batch), "--rubric", str(RUBRIC)]) == 0
    ref = result(batch, "reference")
    assert {i.id: i.points for i in ref.items if i.kind == "manual"} == FULL
    assert ref.item("q1").feedback == "ok" and ref.total == 88.5
    assert grades(batch)["reference"]["total"] == "88.5"
    assert "ok" in (batch / "reference" / "report.html").read_text(encoding="utf-8")


def test_regrade_reports_a_stored_score_the_rubric_no_longer_accepts(batch: Path, tmp_path: Path) -> None:
    merge_manual_scores(batch, sheet(tmp_path, "submission,q1,q2\nreference,8,7\n"))
    store = batch / "reference" / MANUAL_SCORES
    doc = json.loads(store.read_text())
    doc["items"]["q1"]["points"] = 9                  # e.g. the rubric lowered q1 to 8 points
    store.write_text(json.dumps(doc))
    assert grader_main(["regrade", str(batch / "reference"), "--rubric", str(RUBRIC)]) == 0
    ref_doc = json.loads((batch / "reference" / "result.json").read_text())
    assert "manual score 9 for q1 (in manual_scores.json) not applied: 9 is outside 0..8 points" \
        in ref_doc["errors"]
    ref = result(batch, "reference")
    assert ref.item("q1").points is None and ref.item("q2").points == 7
    assert json.loads(store.read_text())["items"]["q1"]["points"] == 9      # nothing lost


def test_a_fresh_grade_keeps_the_manual_scores_file(batch: Path, tmp_path: Path) -> None:
    """`grader grade` empties OUT/<id> before grading: the merged scores survive it."""
    merge_manual_scores(batch, sheet(tmp_path, "submission,q1\nreference,8\n"))
    sub = batch / "reference"
    kept = (sub / MANUAL_SCORES).read_text()
    with manual_scores_kept(sub):
        shutil.rmtree(sub)
        sub.mkdir()
    assert (sub / MANUAL_SCORES).read_text() == kept


def test_a_failed_move_puts_every_file_back(batch: Path, tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    before = snapshot(batch)
    moves = []
    real_move = transaction._move

    def failing_move(src: Path, dst: Path) -> None:
        moves.append(dst)
        if len(moves) == 4:
            raise OSError(28, "No space left on device")
        real_move(src, dst)

    monkeypatch.setattr(transaction, "_move", failing_move)
    path = sheet(tmp_path, "submission,report,q1\nreference,9,8\nbm_log10,5,4\n")
    with pytest.raises(OSError, match="No space left"):
        merge_manual_scores(batch, path)
    assert len(moves) == 4
    assert snapshot(batch) == before
    assert sorted(p.name for p in batch.iterdir()) == ["bm_log10", "grades.csv", "index.html",
                                                       "reference", "wrong_topic"]


def test_dry_run_writes_nothing(batch: Path, tmp_path: Path) -> None:
    before = snapshot(batch)
    report = merge_manual_scores(batch, sheet(tmp_path, "submission,q1\nreference,8\n"), dry_run=True)
    assert [c.describe() for c in report.changes] == ["reference: q1 pending -> 8"]
    # index.html shows totals only: with q3..q5 still pending it does not change
    assert [p.name for p in report.written] == [MANUAL_SCORES, "result.json", "report.html", "grades.csv"]
    assert snapshot(batch) == before


def test_cli_merge(batch: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = sheet(tmp_path, "submission,q1,q1 comment\nreference,8,nice\n")
    assert grader_main(["scores", "merge", str(batch), str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == 'reference: q1 pending -> 8 "nice"'
    assert out[1] == ("wrote 4 file(s): reference/manual_scores.json, reference/result.json, "
                      "reference/report.html, grades.csv")
    assert out[2].startswith("3 submission(s) still have pending manual items: bm_log10 (report, q1")
    assert grader_main(["scores", "merge", str(batch), str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[0] == "manual.csv: nothing to change (1 row(s) already merged)"
    bad = sheet(tmp_path, "submission,q1\nreference,9\n", "bad.csv")
    assert grader_main(["scores", "merge", str(batch), str(bad)]) == 2
    assert capsys.readouterr().err == ("grader: error: bad.csv: 1 problem; nothing was changed:\n"
                                       "  line 2, q1: 9 is over the maximum of 8 points\n")
