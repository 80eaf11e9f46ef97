"""circle_radius / circle_period on a simulated unicycle driven by a constant Twist, and the way
round (``turn``, ``drive``) that the first-nodes rubric asks for (a blind spot found by
``grader rubric audit``: (-2, 1) and (2, -1) made the same radius and period as (2, 1))."""

from __future__ import annotations

from pathlib import Path

import pytest

from analyze_synth import check, simulate
from grader import analyze
from grader.rubric.load import load_rubric

REPO = Path(__file__).resolve().parents[2]


def circle(v: float, w: float, duration: float = 14.0) -> dict:
    return simulate([(0.0, 0.0, 0.0)], lambda *_: (v, w), duration, ctrl_period=0.1)


def rubric_params(item_id: str) -> dict:
    return dict(load_rubric(REPO / "rubrics" / "first_nodes.yaml").item(item_id).params)


def test_the_labs_circle_passes_both_items() -> None:
    frames = circle(2.0, 1.0)
    radius = check(analyze.run("circle_radius", frames, rubric_params("circle.radius")))
    assert radius.status == "pass", radius.feedback
    assert abs(radius.evidence["radius_m"] - 2.0) < 0.05
    assert (radius.evidence["turn"], radius.evidence["drive"]) == ("left", "forward")
    period = check(analyze.run("circle_period", frames, rubric_params("circle.period")))
    assert period.status == "pass", period.feedback


@pytest.mark.parametrize("v, w, wrong", [(-2.0, 1.0, "the turtle drove backward (linear.x < 0)"),
                                         (2.0, -1.0, "the turtle turned right (angular.z < 0)"),
                                         (-2.0, -1.0, "the turtle drove backward (linear.x < 0); it turned right")])
def test_the_right_circle_the_wrong_way_round_loses_half(v: float, w: float, wrong: str) -> None:
    frames = circle(v, w)
    # without turn/drive the radius item cannot tell these from the lab's circle
    blind = check(analyze.run("circle_radius", frames, {"expected_m": 2.0}))
    assert blind.status == "pass"
    radius = check(analyze.run("circle_radius", frames, rubric_params("circle.radius")))
    assert (radius.status, radius.fraction) == ("partial", 0.5), radius.feedback
    assert wrong in radius.feedback
    assert radius.feedback.endswith("the lab asks for driving forward while turning left "
                                    "(linear.x > 0, angular.z > 0).")
    assert check(analyze.run("circle_period", frames, rubric_params("circle.period"))).status == "pass"


def test_wrong_radius_and_wrong_way_says_both() -> None:
    finding = check(analyze.run("circle_radius", circle(1.0, -1.0), {"expected_m": 2.0, "turn": "left"}))
    assert finding.status == "fail" and "radius is 1.00 m" in finding.feedback
    assert "the turtle turned right" in finding.feedback


def test_a_bad_turn_value_is_a_configuration_error() -> None:
    finding = analyze.run("circle_radius", circle(2.0, 1.0), {"expected_m": 2.0, "turn": "Left"})
    assert finding.status == "error" and "turn must be left or right" in finding.feedback
