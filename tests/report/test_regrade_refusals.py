"""`grader regrade` grades only the recordings that were graded: a bag changed since, or one that
was not finalised cleanly, makes its items errors (never a silent new grade); timings and build
problems of the run are kept."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from grader.contracts.result_document import ResultDocument
from grader.grading.pipeline import regrade_submission
from grader.rubric import load_rubric
from grader.testing.batch import recorded_batch

REPO = Path(__file__).resolve().parents[2]
RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"


@pytest.fixture
def graded(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setenv("GRADER_SEAL_KEY", str(tmp_path / "key"))
    out = tmp_path / "out"
    recorded_batch(REPO / "fixtures" / "bags" / "lab3", out, load_rubric(RUBRIC), only=["reference"])
    # the layout links the committed bags; these tests damage recordings, so work on copies
    for link in (out / "reference" / "scenarios").glob("*/bag"):
        target = link.resolve()
        link.unlink()
        shutil.copytree(target, link)
    return out / "reference"


def items(sub: Path) -> dict[str, dict]:
    return {i["id"]: i for i in json.loads((sub / "result.json").read_text())["items"]}


def test_regrade_of_unchanged_bags_keeps_the_grade_and_the_run_record(graded: Path) -> None:
    doc = json.loads((graded / "result.json").read_text())
    doc_timings = doc.get("timings")
    before = items(graded)
    regrade_submission(graded, load_rubric(RUBRIC))
    after = json.loads((graded / "result.json").read_text())
    assert {k: (v["points"], v["status"]) for k, v in items(graded).items()} == \
        {k: (v["points"], v["status"]) for k, v in before.items()}
    assert after.get("timings") == doc_timings
    assert after["seal"]["inputs"] == doc["seal"]["inputs"]


def test_a_bag_changed_since_grading_is_not_regraded(graded: Path) -> None:
    mcap = next((graded / "scenarios" / "ex2_controller" / "bag").glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    data[len(data) // 2] ^= 0xFF
    mcap.write_bytes(bytes(data))
    regrade_submission(graded, load_rubric(RUBRIC))
    got = items(graded)
    assert got["ex2.goals_reached"]["status"] == "error"
    assert "changed since it was graded" in got["ex2.goals_reached"]["feedback"]
    assert got["ex1.pub_rate"]["status"] == "pass"                 # other scenarios are untouched
    doc = json.loads((graded / "result.json").read_text())
    assert any("ex2_controller" in e and "changed" in e for e in doc["errors"])


def test_a_cut_bag_is_not_regraded(graded: Path) -> None:
    mcap = next((graded / "scenarios" / "ex3_action" / "bag").glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    # the cut also changes its digest; make the seal agree so the finalisation check is what refuses
    doc = ResultDocument.read(graded / "result.json")
    from grader.report.result import dumps
    from grader.report.seal import input_digests, sealed
    (graded / "result.json").write_text(dumps(sealed(doc, input_digests(graded)).to_json()))
    regrade_submission(graded, load_rubric(RUBRIC))
    got = items(graded)
    assert got["ex3.goals_succeed"]["status"] == "error"
    assert "not finalised cleanly" in got["ex3.goals_succeed"]["feedback"]


def test_a_damaged_result_json_is_regraded_from_the_bags(graded: Path) -> None:
    """A result.json that is not one (cut short, another program's) does not stop a regrade: the
    bags are what a grade comes from; the problems say why nothing of the old file was kept."""
    before = items(graded)
    (graded / "result.json").write_text(json.dumps({"schema": 1, "items": "none"}))
    regrade_submission(graded, load_rubric(RUBRIC))
    doc = ResultDocument.read(graded / "result.json")
    assert {i.id: i.status for i in doc.items} == {k: v["status"] for k, v in before.items()}
    assert any("result.json: " in e and "regraded from the bags as they are" in e for e in doc.errors)
