"""Repeated scenarios (``repeat: N``): the median that grades them, when runs can stop early,
what result.json and the report say. Pure: findings in, findings out (no ROS)."""

from __future__ import annotations

from pathlib import Path

import pytest

from grader.analyze import Finding
from grader.contracts.scenario_record import ScenarioRecord
from grader.grading.repeat import (repeated_finding, run_folder, run_folders, run_until_settled, scenario_of,
                                   settled)
from grader.report.readable import spread_text
from grader.rubric.schema import Item
from grader.rubric.score import _score_auto


def f(status: str, fraction: float, value: str = "") -> Finding:
    return Finding(value or status, fraction, status, f"{status} {fraction}")


def test_the_median_run_grades_and_the_spread_is_recorded() -> None:
    m = repeated_finding([f("pass", 1.0), f("partial", 0.5), f("pass", 1.0)], planned=3)
    assert (m.status, m.fraction) == ("pass", 1.0)
    assert m.decided["by"] == "median of repeated runs" and m.decided["repeat_by"] == "median"
    assert (m.decided["runs"], m.decided["agree"], m.decided["stable"]) == (3, 2, False)
    assert [o["status"] for o in m.decided["outcomes"]] == ["pass", "partial", "pass"]
    low = repeated_finding([f("fail", 0.0), f("partial", 0.25), f("pass", 1.0)], planned=3)
    assert (low.status, low.fraction) == ("partial", 0.25)                 # the middle one, not a mean
    same = repeated_finding([f("fail", 0.0), f("error", 0.0), f("fail", 0.0)], planned=3)
    assert same.status == "fail"
    one = repeated_finding([f("partial", 0.5)], planned=1)
    assert one.decided == {"by": "one run", "runs": 1} and one.status == "partial"


def test_runs_stop_once_more_than_half_agree_on_every_item() -> None:
    assert settled([[("pass", 1.0), ("pass", 1.0)]], planned=3)
    assert not settled([[("pass", 1.0), ("fail", 0.0)]], planned=3)
    assert not settled([[("pass", 1.0), ("pass", 1.0)], [("pass", 1.0), ("fail", 0.0)]], planned=3)
    assert not settled([[("pass", 1.0), ("pass", 1.0)]], planned=5)        # 2 of 5 is not a majority
    assert settled([[("pass", 1.0)] * 3], planned=5)


def test_run_until_settled_records_two_runs_when_they_agree_three_when_not(tmp_path: Path) -> None:
    made: list[int] = []

    def record(k: int, folder: Path) -> ScenarioRecord:
        folder.mkdir(parents=True)
        made.append(k)
        return ScenarioRecord(scenario="sc", errors=[f"e{k}"] if k == 3 else [], parent_wall_s=10.0, active_s=8.0)

    rec = run_until_settled(record, tmp_path / "a", "sc", 3, lambda folders: len(folders) >= 2)
    assert made == [1, 2] and rec.runs == 2 and rec.parent_wall_s == 20.0 and rec.active_s == 16.0
    made.clear()
    rec = run_until_settled(record, tmp_path / "b", "sc", 3, lambda folders: False)
    assert made == [1, 2, 3] and rec.runs == 3 and rec.errors == ["run 3: e3"]
    assert [p.name for p in run_folders(tmp_path / "b", "sc")] == ["sc", "sc.run2", "sc.run3"]
    assert run_folders(tmp_path / "b", "other") == [tmp_path / "b" / "other"]
    assert run_folder(tmp_path, "sc", 1) == tmp_path / "sc" and scenario_of("sc.run3") == "sc"
    made.clear()
    rec = run_until_settled(record, tmp_path / "c", "sc", 1, None)
    assert made == [1] and rec.runs is None and "runs" not in rec.to_json()


def test_result_and_report_say_how_an_item_was_decided() -> None:
    item = Item.model_validate({"id": "ex3.timeout", "title": "t", "section": {"exercise": 3}, "points": 4,
                                "scenario": "a", "analyzer": "logged", "partial": "none",
                                "params": {"logger": "x", "pattern": "y"}})
    res = _score_auto(item, repeated_finding([f("pass", 1.0), f("partial", 0.5), f("pass", 1.0)], planned=3))
    assert res.points == 4 and res.decided["runs"] == 3
    assert [o["points"] for o in res.decided["outcomes"]] == [4.0, 0.0, 4.0]     # partial: none
    assert spread_text(res.decided) == ("Graded by the median of 3 runs: 2 of 3 runs pass (4 points), "
                                        "1 of 3 runs fail (0 points).")
    two = _score_auto(item, repeated_finding([f("pass", 1.0), f("pass", 1.0)], planned=3))
    assert two.decided["stable"] and "a further 1 run(s) could not have changed the median" in spread_text(two.decided)
    single = _score_auto(item, f("pass", 1.0))
    assert single.decided == {"by": "one run", "runs": 1} and spread_text(single.decided) == ""


def test_the_worst_run_grades_a_start_up_that_has_to_work_every_time() -> None:
    lucky = repeated_finding([f("pass", 1.0), f("fail", 0.0), f("pass", 1.0)], planned=3, by="worst")
    assert (lucky.status, lucky.fraction) == ("fail", 0.0)          # the median would have paid it
    assert lucky.decided["by"] == "worst of repeated runs" and lucky.decided["repeat_by"] == "worst"
    assert (lucky.decided["runs"], lucky.decided["agree"], lucky.decided["stable"]) == (3, 1, False)
    low = repeated_finding([f("pass", 1.0), f("partial", 0.5), f("partial", 0.25)], planned=3, by="worst")
    assert (low.status, low.fraction) == ("partial", 0.25)
    steady = repeated_finding([f("pass", 1.0)] * 3, planned=3, by="worst")
    assert steady.status == "pass" and steady.decided["stable"]
    assert spread_text(lucky.decided | {"outcomes": [{"status": "pass", "points": 3}, {"status": "fail", "points": 0},
                                                     {"status": "pass", "points": 3}]}) == (
        "Graded by the worst of 3 runs (it has to work in every run): 2 of 3 runs pass (3 points), "
        "1 of 3 runs fail (0 points).")
    first_fails = repeated_finding([f("fail", 0.0)], planned=3, by="worst")
    assert spread_text(first_fails.decided | {"outcomes": [{"status": "fail", "points": 0}]}) == (
        "Graded by the worst of 1 run (it has to work in every run): 1 of 1 run fail (0 points); a further 2 "
        "run(s) could not have raised it.")


def test_worst_runs_stop_at_the_first_run_that_fails_every_item_and_not_before() -> None:
    assert settled([[("fail", 0.0)], [("pass", 1.0), ("fail", 0.0)]], planned=3, by="worst")
    assert not settled([[("fail", 0.0)], [("pass", 1.0), ("pass", 1.0)]], planned=3, by="worst")
    assert not settled([[("pass", 1.0), ("pass", 1.0)]], planned=3, by="worst")       # working code: every run
    assert not settled([[("partial", 0.5)]], planned=3, by="worst")                   # a later run may be lower
    assert settled([[("pass", 1.0), ("pass", 1.0)]], planned=3)                       # the median would stop
    made: list[int] = []

    def record(k: int, folder: Path) -> ScenarioRecord:
        made.append(k)
        return ScenarioRecord(scenario="sc", errors=[])

    run_until_settled(record, Path("/nonexistent"), "sc", 3, lambda folders: len(folders) == 1)
    assert made == [1]                  # a first run that settles it (a worst of fail) is the only one


@pytest.mark.parametrize("spec, ok", [({"repeat": 1}, True), ({"repeat": 3}, True), ({"repeat": 2}, False),
                                      ({"repeat": 11}, False), ({"repeat": 2, "repeat_by": "worst"}, True),
                                      ({"repeat": 1, "repeat_by": "worst"}, False),
                                      ({"repeat": 3, "repeat_by": "mean"}, False)])
def test_the_rubric_loader_takes_odd_repeats_up_to_nine_and_any_for_the_worst(spec: dict, ok: bool) -> None:
    from pydantic import ValidationError

    from grader.scenario.model import Scenario

    spec = {**spec, "steps": [{"id": "w", "wait": 1}]}
    if ok:
        assert Scenario.model_validate(spec).repeat == spec["repeat"]
    else:
        with pytest.raises(ValidationError):
            Scenario.model_validate(spec)


def test_the_report_and_the_class_view_show_unstable_items() -> None:
    from grader.report.html import render_html
    from grader.report.index import render_index
    from grader.rubric.result import Result

    item = Item.model_validate({"id": "ex3.timeout", "title": "gives up in time", "section": {"exercise": 3},
                                "points": 4, "scenario": "a", "analyzer": "logged",
                                "params": {"logger": "x", "pattern": "y"}})
    shaky = _score_auto(item, repeated_finding([f("pass", 1.0), f("fail", 0.0), f("pass", 1.0)], planned=3))
    steady = _score_auto(item, repeated_finding([f("pass", 1.0), f("pass", 1.0)], planned=3))
    page = render_html(Result(lab="x", title="X", items=(shaky,)), "alice")
    assert "Graded by the median of 3 runs: 2 of 3 runs pass (4 points), 1 of 3 runs fail (0 points)." in page
    index = render_index({"alice": Result(lab="x", title="X", items=(shaky,)),
                          "bob": Result(lab="x", title="X", items=(steady,))})
    assert 'id="unstable-h"' in index and "2 item result(s) were graded from repeated runs" in index
    assert 'data-submission="alice" data-item="ex3.timeout"' in index and 'data-submission="bob" data-item' not in index
    quiet = render_index({"bob": Result(lab="x", title="X", items=(steady,))})
    assert 'id="unstable-none"' in quiet
    assert 'id="unstable-h"' not in render_index({"carol": Result(lab="x", title="X", items=(_score_auto(item, f("pass", 1.0)),))})


def test_an_item_on_a_repeated_and_a_single_scenario_says_how_each_came_out() -> None:
    from grader.grading.analysis import combine_findings

    item = Item.model_validate({"id": "spawn.turtle2", "title": "t", "section": {"part": 1}, "points": 3,
                                "scenario": ["chase", "spawn"], "analyzer": "logged",
                                "params": {"logger": "x", "pattern": "y"}})
    chase = repeated_finding([f("pass", 1.0)], planned=1, lockstep=True)
    lucky_once = repeated_finding([f("pass", 1.0), f("fail", 0.0)], planned=3, by="worst")
    got = combine_findings(item, [chase, lucky_once], item.scenario)
    assert got is not None and got.status == "fail"
    assert got.decided["scenarios"] == [
        {"scenario": "chase", "by": "one lockstep run", "runs": 1, "stable": True, "status": "pass"},
        {"scenario": "spawn", "by": "worst of repeated runs", "runs": 2, "stable": False, "status": "fail",
         "repeat_by": "worst"}]
    res = _score_auto(item, got)
    assert spread_text(res.decided).endswith(
        "The item takes the worst of its scenarios: chase (one lockstep run: pass); spawn (the worst of 2 runs: fail).")
    both = combine_findings(item, [chase, repeated_finding([f("pass", 1.0)] * 3, planned=3, by="worst")], item.scenario)
    assert both is not None and spread_text(both.decided) == (
        "The item takes the worst of its scenarios: chase (one lockstep run: pass); spawn (the worst of 3 runs: pass).")
    plain = combine_findings(item, [chase, repeated_finding([f("pass", 1.0)], planned=1)], item.scenario)
    assert plain is not None and spread_text(plain.decided) == ""          # nothing repeated: nothing to say


def test_the_class_view_lists_an_item_whose_repeated_scenario_disagreed_with_its_other_one() -> None:
    from grader.grading.analysis import combine_findings
    from grader.report.index import render_index
    from grader.rubric.result import Result

    item = Item.model_validate({"id": "spawn.turtle2", "title": "spawns turtle2", "section": {"part": 1},
                                "points": 3, "scenario": ["chase", "spawn"], "analyzer": "logged",
                                "params": {"logger": "x", "pattern": "y"}})
    chase_lost = repeated_finding([f("fail", 0.0)], planned=1, lockstep=True)
    chase_won = repeated_finding([f("pass", 1.0)], planned=1, lockstep=True)
    lost_once = repeated_finding([f("fail", 0.0)], planned=3, by="worst")        # stopped at its first run
    works = repeated_finding([f("pass", 1.0)] * 3, planned=3, by="worst")
    never = combine_findings(item, [chase_lost, lost_once], item.scenario)       # the same every time
    raced = combine_findings(item, [chase_won, lost_once], item.scenario)        # won once, lost once
    steady = combine_findings(item, [chase_won, works], item.scenario)
    index = render_index({name: Result(lab="x", title="X", items=(_score_auto(item, fd),))
                          for name, fd in (("ann", never), ("ben", raced), ("cy", steady))})
    assert "3 item result(s) were graded from repeated runs; 1 of them came out differently" in index
    assert 'data-submission="ben" data-item="spawn.turtle2"' in index
    assert 'data-submission="ann" data-item' not in index and 'data-submission="cy" data-item' not in index
