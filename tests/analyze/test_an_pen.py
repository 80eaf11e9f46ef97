"""pen_on_crossings on synthetic frames: one set_pen call per crossing of x = 5.5, and the one
call before the first crossing that sets the colour of the side the turtle is on (the wall-pen
lab text's own node makes it, and so does a node that sets its initial state on purpose)."""

from __future__ import annotations

import math

import numpy as np

from analyze_synth import DT, T0, check, events_frame, frame, with_meta
from grader.analyze import get

BLUE, GREEN, PURPLE = [0, 0, 255], [0, 255, 0], [255, 0, 255]
SPLIT = 5.5


def _poses(duration: float = 28.0) -> tuple[np.ndarray, np.ndarray]:
    """x swings from the start (5.544, right of the line) out to 8.5 and back across x = 5.5
    every 5 s: 5 crossings in 28 s, the first leftward at t = 5 s."""
    t = T0 + DT * np.arange(1, int(duration / DT) + 1)
    x = 5.544445 + 3.0 * np.sin(2 * math.pi * (t - T0) / 10.0)
    return t, x


def _crossings(t: np.ndarray, x: np.ndarray) -> list[tuple[float, str]]:
    i = np.nonzero((x[:-1] <= SPLIT) != (x[1:] <= SPLIT))[0]
    return [(float(t[k + 1]), "right" if x[k + 1] > SPLIT else "left") for k in i]


def _frames(calls: list[tuple[float, list[int]]], duration: float = 28.0) -> dict:
    t, x = _poses(duration)
    fr = {"/turtle1/pose": frame(t, x=x, y=5.5, theta=0.0, linear_velocity=1.0, angular_velocity=0.0),
          "/grader/events": events_frame([(T0, "scenario_start", {}), (T0 + duration, "scenario_end", {})])}
    if calls:
        ts = [c[0] for c in calls]
        fr["/turtle1/set_pen/_service_event"] = frame(ts, **{
            "info.event_type": 1, "info.sequence_number": list(range(1, len(calls) + 1)),
            "info.client_gid[0]": 7, "request[0].r": [c[1][0] for c in calls],
            "request[0].g": [c[1][1] for c in calls], "request[0].b": [c[1][2] for c in calls],
            "request[0].width": 3, "request[0].off": 0})
    return with_meta(fr, types={"/turtle1/set_pen/_service_event": "turtlesim/srv/SetPen_Event"},
                     publishers={"/turtle1/pose": ["/turtlesim"]})


def _at_crossings() -> list[tuple[float, list[int]]]:
    t, x = _poses()
    return [(tc + 0.02, BLUE if d == "right" else GREEN) for tc, d in _crossings(t, x)]


def _grade(calls, **params):
    return check(get("pen_on_crossings")(_frames(calls), {**get("pen_on_crossings").defaults, **params}))


def test_one_call_per_crossing_passes() -> None:
    f = _grade(_at_crossings())
    assert f.status == "pass" and f.value == "5/5 crossings" and "start_call" not in f.evidence


def test_the_start_colour_for_the_side_the_turtle_is_on_is_no_extra_call() -> None:
    # the lab text's node: previous_x_ = 0, so the first pose (x = 5.54, right of the line) sets blue
    f = _grade([(T0 + 0.03, BLUE)] + _at_crossings())
    assert f.status == "pass" and f.fraction == 1.0, f.feedback
    assert f.evidence["start_call"] == [{"t": f.evidence["start_call"][0]["t"], "color": BLUE, "side": "right"}]
    assert "before the first crossing" in f.feedback
    # set on purpose a little later (after waiting for the service), still before any crossing
    assert _grade([(T0 + 1.5, BLUE)] + _at_crossings()).status == "pass"


def test_a_wrong_start_colour_is_still_an_extra_call() -> None:
    # green while the turtle is right of the line: the trail starts in the wrong colour
    f = _grade([(T0 + 0.03, GREEN)] + _at_crossings())
    assert f.status == "partial" and f.evidence["extra_calls"][0]["color"] == GREEN
    assert f.fraction == 5 / 6
    # another colour altogether, or the pen switched off, is no start state of this lab either
    assert _grade([(T0 + 0.03, PURPLE)] + _at_crossings()).status == "partial"


def test_only_start_calls_many_are_accepted() -> None:
    twice = [(T0 + 0.03, BLUE), (T0 + 0.5, BLUE)] + _at_crossings()
    f = _grade(twice)
    assert f.status == "partial" and len(f.evidence["extra_calls"]) == 1 and len(f.evidence["start_call"]) == 1
    assert _grade(twice, start_calls=2).status == "pass"
    # the rubric can forbid it: then the start call is a call not at a crossing, as before
    assert _grade([(T0 + 0.03, BLUE)] + _at_crossings(), start_calls=0).status == "partial"


def test_calls_on_every_pose_still_fail() -> None:
    t, x = _poses()
    every = [(float(tt) + 0.002, BLUE if xx > SPLIT else GREEN) for tt, xx in zip(t, x)]
    f = _grade(every)
    assert f.status == "fail" and f.fraction == 0.0 and len(f.evidence["start_call"]) == 1
    # every crossing answered right among 200 stray calls: 5/205 of the credit was 0.02 or 0.01
    # of 7 points by the count of stray calls in runs of the same code; below min_credit, none
    strays = [(float(tt) + 0.002, BLUE if xx > SPLIT else GREEN) for tt, xx in zip(t[5::8], x[5::8])]
    mixed = sorted(_at_crossings() + strays[:200])
    f = _grade(mixed)
    assert f.status == "fail" and f.fraction == 0.0
    assert 0.0 < _grade(mixed, min_credit=0.0).fraction < 0.05


def test_a_start_call_needs_a_crossing_to_be_graded() -> None:
    fr = _frames([(T0 + 0.03, BLUE)])
    fr["/turtle1/pose"] = frame(fr["/turtle1/pose"].index, x=7.0, y=5.5, theta=0.0,
                                linear_velocity=0.0, angular_velocity=0.0)
    f = check(get("pen_on_crossings")(fr, dict(get("pen_on_crossings").defaults)))
    assert f.status == "fail" and "never crossed" in f.feedback


def test_one_direction_always_wrong_gets_half_whatever_the_number_of_crossings() -> None:
    # blue both ways: every leftward crossing wrong. Per crossing it was 6/13, 7/14 or 5/11 in
    # three runs of the same code (issue 22); per direction it is 0.5 in each
    got = set()
    for duration in (28.0, 33.0, 38.0):          # 5, 6 and 7 crossings
        t, x = _poses(duration)
        calls = [(tc + 0.02, BLUE) for tc, _d in _crossings(t, x)]
        fr = _frames(calls, duration)
        f = check(get("pen_on_crossings")(fr, get("pen_on_crossings").defaults))
        assert f.status == "partial" and f.evidence["share_by_direction"] == {"right": 1.0, "left": 0.0}
        got.add((f.fraction, len(f.evidence["crossings"])))
    assert {g[0] for g in got} == {0.5} and len({g[1] for g in got}) == 3, got
