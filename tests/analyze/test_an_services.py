"""A service judged from the driver's calls: under the lab's name, and under the name a student's
node serves it as (``ServiceCall.served_by``): only the item about the service's name is charged."""

from __future__ import annotations

from analyze_synth import T0, check, events_frame, frame, with_meta
from grader.analyze import get

SETTER = {"service": "/set_goal", "field": "success", "expected": True}
ECHO = {"service": "/set_goal", "topic": "/goal", "fields": {"x": "x", "y": "y"}}


def _frames(service: str, asked_for: str | None) -> dict:
    """Two calls to ``service`` answered success, each request published on /goal."""
    extra = {"asked_for": asked_for} if asked_for else {}
    rows, goals = [], []
    for k, (x, y) in enumerate(((8.5, 7.0), (2.0, 2.5))):
        t = T0 + 2.0 + 5.0 * k
        request = {"x": x, "y": y}
        rows += [(t, "service_call", {"step": f"goal_{k}", "service": service, "type": "turtle_goal/srv/SetGoal",
                                      "request": request, **extra}),
                 (t + 0.01, "service_response", {"step": f"goal_{k}", "service": service,
                                                 "response": {"success": True}, **extra})]
        goals.append((t + 0.005, x, y))
    fr = {"/grader/events": events_frame([(T0, "scenario_start", {}), *rows]),
          "/goal": frame([g[0] for g in goals], x=[g[1] for g in goals], y=[g[2] for g in goals], z=0.0)}
    return with_meta(fr, types={"/goal": "geometry_msgs/msg/Point"})


def test_under_the_labs_name_both_items_pass() -> None:
    fr = _frames("/set_goal", None)
    assert check(get("service_answers")(fr, SETTER)).status == "pass"
    echoed = check(get("request_echoed")(fr, ECHO))
    assert echoed.status == "pass" and "called as" not in echoed.feedback


def test_under_another_name_only_the_name_is_charged_and_both_say_what_they_saw() -> None:
    fr = _frames("/set_goal_renamed", "/set_goal")
    answers = check(get("service_answers")(fr, SETTER))
    assert answers.status == "fail" and answers.fraction == 0.0
    assert "serves it as /set_goal_renamed" in answers.feedback and "2 of 2 calls answered success = True" \
        in answers.feedback
    echoed = check(get("request_echoed")(fr, ECHO))
    assert echoed.status == "pass" and echoed.fraction == 1.0
    assert "called as /set_goal_renamed" in echoed.feedback and echoed.evidence["called_as"] == "/set_goal_renamed"


def test_a_call_to_another_service_is_no_call_of_this_one() -> None:
    fr = _frames("/set_goal_renamed", None)       # nobody asked for /set_goal
    assert check(get("service_answers")(fr, SETTER)).status == "error"
