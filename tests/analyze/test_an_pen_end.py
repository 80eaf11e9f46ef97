"""pen_on_crossings at the end of a run: a crossing too close to the end to be answered is left
out, and so is the call that answers it (grader rubric audit found a correct mutant losing 0.47
points to that call, counted as "not at a crossing")."""

from __future__ import annotations

import numpy as np

from analyze_synth import T0, check, events_frame, frame, with_meta
from grader import analyze

BLUE, GREEN = [0, 0, 255], [0, 255, 0]


def run(calls: list[tuple[float, list[int]]], end: float) -> dict:
    """Poses at 62.5 Hz: left of x = 5.5 until 2 s, right of it until 9.97 s (0.03 s before the
    scenario ends at ``end`` = 10 s), left again; set_pen events at ``calls``."""
    t = np.arange(0.0, end + 0.2, 0.016)
    x = np.where((t >= 2.0) & (t < 9.97), 5.52, 5.48)
    pose = frame(T0 + t, x=x, y=np.full_like(t, 5.5), theta=0.0, linear_velocity=1.0, angular_velocity=0.0)
    pen = frame([T0 + c for c, _ in calls], **{
        "info.event_type": 0, "info.sequence_number": list(range(1, len(calls) + 1)), "info.client_gid[0]": 7,
        "request[0].r": [c[0] for _, c in calls], "request[0].g": [c[1] for _, c in calls],
        "request[0].b": [c[2] for _, c in calls], "request[0].width": 3, "request[0].off": 0})
    frames = {"/turtle1/pose": pose, "/turtle1/set_pen/_service_event": pen,
              "/grader/events": events_frame([(T0, "scenario_start", {}), (T0 + end, "scenario_end", {})])}
    return with_meta(frames, types={"/turtle1/set_pen/_service_event": "turtlesim/srv/SetPen_Event"},
                     publishers={"/turtle1/pose": ["/turtlesim"]})


def test_the_answer_to_a_crossing_at_the_end_is_not_a_stray_call() -> None:
    # a crossing at 2 s answered at 2.01 s, and one 0.03 s before the end answered 5 ms later
    frames = run([(2.01, BLUE), (9.975, GREEN)], end=10.0)
    finding = check(analyze.run("pen_on_crossings", frames, {}))
    assert finding.status == "pass", finding.feedback
    assert finding.evidence["extra_calls"] == []


def test_a_stray_call_before_the_end_still_counts() -> None:
    frames = run([(2.01, BLUE), (5.0, GREEN), (9.975, GREEN)], end=10.0)
    finding = check(analyze.run("pen_on_crossings", frames, {}))
    assert finding.status == "partial" and "1 set_pen call(s) not at a crossing (first at t = 5.0 s" in finding.feedback
