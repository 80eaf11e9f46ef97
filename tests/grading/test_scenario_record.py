"""scenario.json through its model (grader.contracts.scenario_record): the records committed in
fixtures/bags (written by the scenario child before the model) read and write back byte for
byte; the pipeline's notes amend a record through the model; unknown keys survive; a bad record
names its field."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from grader.contracts.document import DocumentError
from grader.contracts.scenario_record import ScenarioRecord
from grader.grading.provenance import scenario_recordings
from grader.grading.repeat import exact_lockstep
from grader.sandbox.scenario import recorded_summary

REPO = Path(__file__).resolve().parents[2]
COMMITTED = subprocess.run(["git", "ls-files", "fixtures/bags/*scenario.json"], cwd=REPO, check=True,
                           capture_output=True, text=True).stdout.split()


def test_there_are_committed_records() -> None:
    assert len(COMMITTED) >= 10


@pytest.mark.parametrize("rel", COMMITTED)
def test_a_committed_record_reads_and_writes_back_byte_for_byte(rel: str) -> None:
    path = REPO / rel
    record = ScenarioRecord.read(path)
    assert record.text() == path.read_text(encoding="utf-8")
    assert record.scenario == path.parent.name and record.steps and record.sandbox is not None
    assert all(s.duration_s >= 0 for s in record.steps)


def test_the_pipeline_reads_records_by_their_model(tmp_path: Path) -> None:
    src = REPO / "fixtures/bags/lab3/reference/ex2_controller/scenario.json"
    folder = tmp_path / "sub" / "scenarios" / "ex2_controller"
    folder.mkdir(parents=True)
    (folder / "scenario.json").write_text(src.read_text())
    got = scenario_recordings(tmp_path / "sub")["ex2_controller"]
    assert got.key == "6fa91f5599655c16d62b294a" and got.reused_from is not None
    assert got.reused_from.from_ == "reference"
    assert recorded_summary([folder])["mode"] == "auto"
    assert not exact_lockstep(folder)
    ScenarioRecord.amend(folder / "scenario.json", {"lockstep": {"used": True, "quiet_timeouts": 0, "ticks": 5}})
    assert exact_lockstep(folder)
    saved = json.loads((folder / "scenario.json").read_text())
    assert saved["lockstep"] == {"used": True, "quiet_timeouts": 0, "ticks": 5}     # unknown sub-keys kept
    assert list(saved)[:3] == ["scenario", "steps", "processes"]


def test_a_newer_writers_keys_are_kept_and_a_bad_record_is_named(tmp_path: Path) -> None:
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps({"scenario": "s", "steps": [{"id": "a", "action": "wait", "duration_s": 1}],
                                "gpu_s": 3}))
    record = ScenarioRecord.read(path)
    assert record.to_json()["gpu_s"] == 3 and record.steps[0].duration_s == 1
    path.write_text(json.dumps({"scenario": "s", "steps": [{"id": "a", "duration_s": "long"}]}))
    with pytest.raises(DocumentError, match=rf"{path}: steps\[0\]\.action: Field required; "
                                            r"steps\[0\]\.duration_s: should be a finite number"):
        ScenarioRecord.read(path)
    with pytest.raises(DocumentError, match=r"processes\.node\.returncode"):
        ScenarioRecord.parse({"scenario": "s", "processes": {"node": {"returncode": "x"}}}, "r")
    ScenarioRecord.amend(tmp_path / "none.json", {"errors": ["x"]})           # no record: nothing written
    assert not (tmp_path / "none.json").exists()


def test_a_note_keeps_the_order_it_was_made_in_through_the_record():
    """The pipeline's 1x note is made as requested, used, fallback; result.json (sealed bytes) has
    always written it so. Declared order (used, fallback, ...) would change those bytes."""
    record = ScenarioRecord.model_validate({"scenario": "ex2_controller"})
    note = {"requested": 4.0, "used": 1.0, "fallback": "the machine was too busy", "attempt_wall_s": 3.2}
    amended = record.amended({"time_scale": note})
    assert list(amended.to_json()["time_scale"]) == list(note)
    assert list(amended.time_scale.to_json()) == list(note)
    again = ScenarioRecord.model_validate_json(json.dumps(amended.to_json()))
    assert list(again.to_json()["time_scale"]) == list(note)
