"""Items judged on several scenarios, and scenarios in which the student's node never ran.

An item listing several scenarios is scored on the worst of its findings. For integrity flags a
scenario whose student node could not be built or started gives no evidence either way, so it
must not decide the flag: otherwise a broken build would be flagged or not depending on whether
the recorder had seen the simulator's pose before that empty scenario ended.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from analyze_synth import T0, events_frame, law, simulate, with_meta
from grader.grading.analysis import analyze_item, combine_findings
from grader.rubric import load_rubric

RUBRIC = load_rubric(Path(__file__).resolve().parents[2] / "rubrics" / "enee467_lab3.yaml")


def _node_never_ran() -> dict:
    """A scenario whose only student process did not build: events, no pose at all."""
    return with_meta({"/grader/events": events_frame([
        (T0, "scenario_start", {}),
        (T0 + 0.1, "node_unavailable", {"process": "controller",
                                        "error": "package 'turtle_control' did not build (failed)"})])})


def _clean_run(publishers: list[str] | None = None) -> dict:
    fr = {k: v for k, v in simulate([(0.2, 2.0, 7.0)], law("correct"), 8.0).items() if k != "__meta__"}
    return with_meta(fr, publishers={"/turtle1/pose": publishers or ["/turtlesim"]})


def _judge(item_id: str, scenarios: list[dict]):
    item = RUBRIC.item(item_id)
    return combine_findings(item, [analyze_item(item, fr) for fr in scenarios])


def test_integrity_is_judged_where_it_could_run() -> None:
    f = _judge("integrity.pose_publisher", [_node_never_ran(), _clean_run()])
    assert f.status == "pass", f.feedback
    f = _judge("integrity.pose_publisher", [_node_never_ran(), _clean_run(["/turtlesim", "/cheat"])])
    assert f.status == "fail" and "/cheat" in f.feedback


def test_integrity_with_nothing_to_check_is_an_error_not_a_flag() -> None:
    f = _judge("integrity.pose_publisher", [_node_never_ran(), _node_never_ran()])
    assert f.status == "error" and "did not build" in f.feedback


@pytest.mark.parametrize("order", [0, 1])
def test_a_scored_item_still_fails_when_the_node_never_ran(order: int) -> None:
    scenarios = [_node_never_ran(), _clean_run()]
    f = _judge("ex2.control_rate", scenarios[order:] + scenarios[:order])
    assert f.status == "fail" and "Could not run controller" in f.feedback
