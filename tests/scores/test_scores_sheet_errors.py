"""Every bad score sheet gets its exact error, with the line; all problems at once; nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest
from scorehelpers import snapshot, write_csv

from grader.scores import ScoresError, merge_manual_scores

MANUAL = "the manual items are report, q1, q2, q3, q4, q5"
SAVE_AS = 'save it from the spreadsheet as "CSV UTF-8 (Comma delimited)"'
AUTO_FIX = ("leave the cell empty or as exported (to change an automatic grade, fix the rubric and "
            "run grader regrade)")

CASES = {
    "unknown submission": (
        "submission,q1\nreferense,5\n",
        ['line 2: unknown submission "referense" (no graded result for it) (did you mean "reference"?)']),
    "unknown item": (
        "submission,q6,Q1\nreference,5,4\n",
        [f'line 1, column B: unknown item "q6"; {MANUAL}',
         f'line 1, column C: unknown item "Q1" (did you mean "q1"?); {MANUAL}']),
    "auto item given a score": (
        "submission,ex1.boxmuller,ex2.goal_publisher_robust\nbm_log10,6,pass\n",
        ['line 2, ex1.boxmuller: ex1.boxmuller is graded automatically (auto; recorded: 0), "6" cannot '
         f"be set by hand: {AUTO_FIX}",
         'line 2, ex2.goal_publisher_robust: ex2.goal_publisher_robust is graded automatically '
         f'(advisory; recorded: error), "pass" cannot be set by hand: {AUTO_FIX}']),
    "over max points": (
        "submission,q1,report\nreference,8.5,10\n",
        ["line 2, q1: 8.5 is over the maximum of 8 points"]),
    "negative": (
        "submission,q1\nreference,-1\n",
        ["line 2, q1: -1 is negative (points go from 0 to 8)"]),
    "not a number": (
        "submission,q1,q2,q3,q4\nreference,seven,80%,nan,\"7,5\"\n",
        [f'line 2, {q}: "{v}" is not a number (give points like 7 or 7.5, or "pending" to clear the score)'
         for q, v in (("q1", "seven"), ("q2", "80%"), ("q3", "nan"), ("q4", "7,5"))]),
    "duplicate rows": (
        "submission,q1\nreference,5\nbm_log10,4\nreference,6\n",
        ['line 4: submission "reference" is also on line 2: give each submission one row']),
    "duplicate column": (
        "submission,q1,q2,q1\nreference,5,4,6\n",
        ['line 1, column D: column "q1" appears twice (first in column B)']),
    "shifted row": (
        "submission,q1,q1 comment,q2\nreference,5,good, but short,4\n",
        ["line 2: 5 cells but the header has 4 columns (a comma in a comment that is not inside quotes?)"]),
    "missing submission id": (
        "submission,q1\n,5\n",
        ["line 2: no submission id in column A"]),
    "comment without a score": (
        "submission,q1,q1 comment,q2 comment\nreference,pending,why,no q2 column\n",
        ["line 2, q1 comment: a comment for q1, which has no score (give its points in column B)",
         'line 2, q2 comment: a comment for q2, which has no score (give its points in column "q2")']),
    "comment on an automatic item": (
        "submission,ex1.boxmuller comment,q9 comment\nreference,nice,x\n",
        ['line 1, column B: "ex1.boxmuller comment": comments go with manual items only '
         "(report, q1, q2, q3, q4, q5)",
         f'line 1, column C: "q9 comment" is a comment for unknown item "q9"; {MANUAL}']),
    "no submission column": (
        "student,q1\nreference,5\n",
        ['line 1: no "submission" column (the header has "student", "q1")']),
    "value without a header": (
        "submission,q1,,\nreference,5,oops,\nbm_log10,4,,\n",      # empty columns are fine
        ["line 2, column C: a value in a column without a header"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_sheet_exact_error_and_nothing_written(case: str, batch: Path, tmp_path: Path) -> None:
    text, problems = CASES[case]
    before = snapshot(batch)
    with pytest.raises(ScoresError) as exc:
        merge_manual_scores(batch, write_csv(tmp_path / "manual.csv", text))
    assert exc.value.problems == problems
    count = f"{len(problems)} problem" + ("s" if len(problems) > 1 else "")
    assert str(exc.value).startswith(f"manual.csv: {count}; nothing was changed:\n  {problems[0]}")
    assert snapshot(batch) == before


ENCODINGS = {
    "UTF-16 (Excel Unicode Text)": (
        "submission\tq1\r\nreference\t5\r\n".encode("utf-16"),
        [f"the file is UTF-16 text (Excel's \"Unicode Text\"): {SAVE_AS}"]),
    "Windows-1252 (Excel plain CSV)": (
        "submission,q1,q1 comment\nreference,5,ok\nbm_log10,4,très bien\n".encode("cp1252"),
        ["line 3: not UTF-8 text (byte 0xe8 on line 3); Excel's plain \"CSV (Comma delimited)\" "
         f"writes Windows-1252: {SAVE_AS}"]),
    "an xlsx workbook named .csv": (
        b"PK\x03\x04\x14\x00\x06\x00" + b"\x00" * 40,
        [f"this is a spreadsheet workbook (.xlsx), not a CSV file: {SAVE_AS}"]),
    "a byte-order mark inside (two files pasted together)": (
        "\ufeffsubmission,q1\nreference,5\n\ufeffsubmission,q1\n".encode("utf-8"),
        ["line 3: a byte-order mark (U+FEFF) inside the file, where it hides in a cell: were two CSV "
         "files pasted together? Delete it (or copy the cells into a new sheet)"]),
    "empty": (b"\xef\xbb\xbf\r\n\r\n", ["the file is empty"]),
}


@pytest.mark.parametrize("case", list(ENCODINGS))
def test_bad_encoding_exact_error(case: str, batch: Path, tmp_path: Path) -> None:
    data, problems = ENCODINGS[case]
    path = tmp_path / "manual.csv"
    path.write_bytes(data)
    before = snapshot(batch)
    with pytest.raises(ScoresError) as exc:
        merge_manual_scores(batch, path)
    assert exc.value.problems == problems
    assert snapshot(batch) == before


def test_every_problem_is_listed_at_once_in_line_order(batch: Path, tmp_path: Path) -> None:
    text = ("submission,q1,q2,q7\n"
            "reference,9,x,\n"
            "nobody,1,1,\n"
            "bm_log10,8,-2,\n"
            "reference,1,1,\n")
    with pytest.raises(ScoresError) as exc:
        merge_manual_scores(batch, write_csv(tmp_path / "manual.csv", text))
    assert exc.value.problems == [
        f'line 1, column D: unknown item "q7"; {MANUAL}',
        "line 2, q1: 9 is over the maximum of 8 points",
        'line 2, q2: "x" is not a number (give points like 7 or 7.5, or "pending" to clear the score)',
        'line 3: unknown submission "nobody" (no graded result for it)',
        "line 4, q2: -2 is negative (points go from 0 to 8)",
        'line 5: submission "reference" is also on line 2: give each submission one row',
    ]
