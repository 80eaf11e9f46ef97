"""results.json in Gradescope's format, checked against the JSON Schema written from its
specification; the bundle's layout; a submission that cannot be graded still gets results."""

from __future__ import annotations

import dataclasses
import json
import os
import stat
import zipfile
from pathlib import Path

import jsonschema
import pytest

from grader.cli import main as grader_main
from grader.errors import GraderError
from grader.lms import gradescope
from grader.rubric import load_rubric, score

REPO = Path(__file__).resolve().parents[2]
LAB3 = REPO / "rubrics" / "enee467_lab3.yaml"


class FakeFinding:
    def __init__(self, status: str, value=None, fraction: float | None = None, feedback: str = "") -> None:
        self.status, self.value, self.feedback, self.evidence = status, value, feedback, {}
        self.fraction = fraction if fraction is not None else (1.0 if status == "pass" else 0.0)


def validate(doc: dict) -> None:
    jsonschema.validate(doc, json.loads(gradescope.SCHEMA.read_text()),
                        format_checker=jsonschema.FormatChecker())


@pytest.fixture(scope="module")
def rubric():
    return load_rubric(LAB3)


def test_schema_is_a_valid_json_schema_that_rejects_bad_documents() -> None:
    schema = json.loads(gradescope.SCHEMA.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    good = {"score": 1, "tests": [{"name": "a", "score": 1, "max_score": 1, "visibility": "visible"}]}
    validate(good)
    for bad in ({"tests": [{"name": "no score anywhere"}]},
                {"score": 1, "tests": [{"visibility": "students"}]},
                {"score": 1, "tests": [{"status": "partial"}]},
                {"score": 1, "output_format": "rst"},
                {"score": "ten"},
                {"score": 1, "tests": [{"score": 1, "hint": "unknown key"}]}):
        with pytest.raises(jsonschema.ValidationError):
            validate(bad)


def test_results_document_from_a_scored_lab3(rubric) -> None:
    findings = {i.id: FakeFinding("pass", value=62.4) for i in rubric.items if i.kind != "manual"}
    findings["ex1.boxmuller"] = FakeFinding("fail", value={"matched": 0, "of": 1000},
                                            feedback="Your values match z computed with log10.")
    findings["ex2.goals_reached"] = FakeFinding("partial", value=0.75, fraction=0.5)
    findings["integrity.no_teleport"] = FakeFinding("fail", feedback="teleport_absolute was called")
    result = score(rubric, findings)
    doc = gradescope.results_document(result, rubric, problems=["scenario ex2: node crashed"],
                                      build_ok=True, execution_time=93.6)
    validate(doc)
    tests = {t["extra_data"]["item"]: t for t in doc["tests"]}
    manual = {i.id for i in rubric.items if i.kind == "manual"}
    assert manual == {"report", "q1", "q2", "q3", "q4", "q5"} and not manual & set(tests)
    assert set(tests) == {i.id for i in rubric.items if i.kind != "manual"}
    assert doc["score"] == result.auto_score == sum(t["score"] for t in doc["tests"]) == 50 - 6 - 4
    assert doc["execution_time"] == 94
    bm = tests["ex1.boxmuller"]
    assert (bm["score"], bm["max_score"], bm["status"]) == (0, 6, "failed")
    assert "log10" in bm["output"] and "Hint: " in bm["output"] and '"matched": 0' in bm["output"]
    assert bm["tags"] == ["exercise 1"]
    assert tests["ex2.goals_reached"]["status"] == "failed" and tests["ex2.goals_reached"]["score"] == 4
    assert tests["ex1.pub_rate"]["status"] == "passed" and "Measured: 62.4" in tests["ex1.pub_rate"]["output"]
    for item in rubric.items:
        if item.kind == "manual":
            continue
        want = "hidden" if item.kind == "integrity" else ("visible" if item.public else "after_published")
        assert tests[item.id]["visibility"] == want
    assert tests["integrity.no_teleport"]["visibility"] == "hidden"
    hidden = dataclasses.replace(result.item("ex1.boxmuller"), public=False)
    assert gradescope.test_entry(hidden)["visibility"] == "after_published"
    assert "node crashed" in doc["output"] and "q1" in doc["output"]


def test_not_graded_document_validates(rubric) -> None:
    doc = gradescope.not_graded_document(rubric, "the submission is empty", execution_time=0.2)
    validate(doc)
    assert doc["score"] == 0 and all(t["score"] == 0 for t in doc["tests"])
    assert sum(t["max_score"] for t in doc["tests"]) == rubric.auto_max


def test_find_submission(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(GraderError, match="empty"):
        gradescope.find_submission(empty)
    ws = tmp_path / "ws" / "src" / "pkg"
    ws.mkdir(parents=True)
    (ws / "package.xml").write_text("<package><name>pkg</name></package>")
    assert gradescope.find_submission(tmp_path / "ws") == tmp_path / "ws"
    zipped = tmp_path / "zipped"
    zipped.mkdir()
    with zipfile.ZipFile(zipped / "lab3.zip", "w") as zf:
        zf.writestr("src/pkg/package.xml", "<package><name>pkg</name></package>")
    assert gradescope.find_submission(zipped) == zipped / "lab3.zip"
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notes.txt").write_text("hi")
    with pytest.raises(GraderError, match="package.xml"):
        gradescope.find_submission(tmp_path / "junk")


def test_run_autograder_on_an_empty_submission_writes_results(tmp_path: Path) -> None:
    root = tmp_path / "autograder"
    (root / "submission").mkdir(parents=True)
    assert grader_main(["gradescope-run", "--root", str(root), "--rubric", str(LAB3)]) == 0
    doc = json.loads((root / "results" / "results.json").read_text())
    validate(doc)
    assert doc["score"] == 0 and "empty" in doc["output"]


def test_bundle_layout(tmp_path: Path, capsys) -> None:
    wheel = tmp_path / "grader-0.1.0-py3-none-any.whl"
    wheel.write_bytes(b"stand-in: the slow test ships a real wheel")
    out = tmp_path / "autograder.zip"
    assert grader_main(["gradescope", "--rubric", str(LAB3), "-o", str(out), "--wheel", str(wheel)]) == 0
    printed = capsys.readouterr().out
    assert "report (10)" in printed and "Ubuntu 22.04" in printed
    with zipfile.ZipFile(out) as zf:
        names = set(zf.namelist())
        modes = {i.filename: i.external_attr >> 16 for i in zf.infolist()}
        zf.extractall(tmp_path / "source")
    assert {"setup.sh", "run_autograder", wheel.name, "rubric/rubrics/enee467_lab3.yaml"} <= names
    assert modes["run_autograder"] & stat.S_IXUSR and modes["setup.sh"] & stat.S_IXUSR
    staged = load_rubric(tmp_path / "source" / "rubric" / "rubrics" / "enee467_lab3.yaml")
    assert staged.support["turtle_control_interfaces"].is_relative_to(tmp_path / "source")
    run_script = (tmp_path / "source" / "run_autograder").read_text()
    assert '"$ROOT/source/rubric/rubrics/enee467_lab3.yaml"' in run_script
    assert wheel.name in (tmp_path / "source" / "setup.sh").read_text()


def test_bundle_errors(tmp_path: Path, capsys) -> None:
    assert grader_main(["gradescope", "--rubric", str(LAB3), "-o", str(tmp_path / "a.tar"),
                        "--wheel", str(LAB3)]) == 2
    assert "not a .whl" in capsys.readouterr().err
    assert grader_main(["gradescope", "--rubric", str(tmp_path / "none.yaml"), "-o", str(tmp_path / "a.zip")]) == 2
    assert "not found" in capsys.readouterr().err
    assert not os.listdir(tmp_path)
