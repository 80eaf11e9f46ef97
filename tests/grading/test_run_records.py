"""GradedSubmission's run records (grader.contracts.run_records) and an output folder's paths
(grader.contracts.output_folder)."""

from __future__ import annotations

import json
from pathlib import Path

from grader.contracts.output_folder import OutputFolder, ScenarioFolder
from grader.contracts.run_records import ClockUse, EarlyEnd, Recording, ReusedRecording

REPO = Path(__file__).resolve().parents[2]


def test_a_record_is_written_in_the_order_it_was_made() -> None:
    # declared order is used, fallback, ...; result.json has always had clock first (and requested)
    lockstep = {"clock": "lockstep", "used": True, "sim_s": 12.5, "quiet_timeouts": 0}
    scaled = {"requested": 4, "used": 1, "fallback": "busy"}
    for made in (lockstep, scaled):
        assert list(ClockUse.model_validate(made).to_json().items()) == list(made.items())
    clock = ClockUse.model_validate(lockstep)
    assert clock.clock == "lockstep" and clock.used is True and clock.quiet_timeouts == 0
    reused = ReusedRecording.model_validate({"key": "k", "from": "bob", "made_by": None, "recorded": "t"})
    assert reused.from_ == "bob" and list(reused.to_json()) == ["key", "from", "made_by", "recorded"]
    end = EarlyEnd.model_validate({"step": "g1", "at_s": 3, "limit_s": 20.0, "reason": "reached"})
    assert end.to_json() == {"step": "g1", "at_s": 3, "limit_s": 20.0, "reason": "reached"}
    assert isinstance(end.to_json()["at_s"], int)          # an int stays an int (the bytes)


def test_a_recording_reads_its_origin_by_attribute() -> None:
    made = {"key": "abc", "made_by": {"grader": "1"}, "reused_from": {"from": "alice", "recorded": "t"}}
    rec = Recording.model_validate(made)
    assert rec.reused_from is not None and rec.reused_from.from_ == "alice"
    assert json.dumps(rec.to_json()) == json.dumps(made)


def test_output_folder_paths_are_the_files_the_fixtures_have(tmp_path: Path) -> None:
    out = OutputFolder(tmp_path)
    sub = out.submission("alice")
    assert sub.result_json == tmp_path / "alice" / "result.json" and sub.id == "alice"
    assert sub.report_html.name == "report.html" and sub.intake_json.name == "intake.json"
    assert (out.grades_csv.name, out.index_html.name, out.similarity.name) == ("grades.csv", "index.html", "similarity")
    assert sub.scenario("ex2_controller.run2").scenario_json == (
        tmp_path / "alice" / "scenarios" / "ex2_controller.run2" / "scenario.json")
    # a committed recording (fixtures/bags keeps scenario folders without scenarios/) has these files
    run = ScenarioFolder(REPO / "fixtures" / "bags" / "lab3" / "reference" / "ex2_controller")
    assert run.scenario_json.is_file() and run.bag.is_dir()
