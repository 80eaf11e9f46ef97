"""Exercise 3 action server analyzers on synthetic driver events and poses."""

from __future__ import annotations

import numpy as np
import pytest

from analyze_synth import T0, check, events_frame, frame, rosout_frame, stdout_frame, with_meta
from grader.analyze import get
from grader.analyze.action_goals import action_goals


def _pose(track: list[tuple[float, float, float]]) -> object:
    """Piecewise-constant poses at 62.5 Hz: track = [(t_from, x, y), ...]."""
    t = np.arange(T0, T0 + 60, 0.016)
    x = np.full(len(t), 5.544445)
    y = np.full(len(t), 5.544445)
    for t0, px, py in track:
        x[t >= t0], y[t >= t0] = px, py
    return frame(t, x=x, y=y, theta=0.0, linear_velocity=0.0, angular_velocity=0.0)


def _goal(t, x, y, accepted, result=None, t_res=None, tol=0.1, time_out=None, gid=None, dt_resp=0.05):
    ev = [(t, "action_goal_sent", {"goal": {"goal": {"x": x, "y": y}, "goal_tol": tol,
                                           **({"time_out": time_out} if time_out is not None else {})},
                                  **({"step": gid} if gid else {})}),
          (t + dt_resp, "action_goal_response", {"accepted": accepted, **({"step": gid} if gid else {})})]
    if result is not None:
        ev.append((t_res, "action_result", {"status": 4, "result": {"success": result},
                                            **({"step": gid} if gid else {})}))
    return ev


def _frames(evs, track=(), meta_topics=None) -> dict:
    rows = sorted([e for ev in evs for e in ev], key=lambda r: r[0])
    fr = {"/grader/events": events_frame([(T0, "scenario_start", {})] + rows), "/turtle1/pose": _pose(list(track))}
    for tp in meta_topics or []:
        fr[tp] = frame([T0 + 1], data="x")
    return with_meta(fr)


def test_good_server() -> None:
    evs = [_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9), _goal(T0 + 10, 8.0, 3.0, True, True, T0 + 18),
           _goal(T0 + 20, 15.0, 5.0, False), _goal(T0 + 21, -1.0, 5.0, False),
           _goal(T0 + 22, 3.0, 3.0, True, False, T0 + 24.1, time_out=2.0)]
    fr = _frames(evs, [(T0 + 8.9, 1.0, 9.05), (T0 + 17.9, 7.97, 3.0), (T0 + 24, 4.0, 4.0)])
    f = check(get("action_goals_succeed")(fr, {}))
    assert f.status == "pass" and f.value == "2/2 succeeded", f.evidence
    f = check(get("action_rejects_out_of_bounds")(fr, {}))
    assert f.status == "pass" and f.value == "2/2 rejected"
    f = check(get("action_timeout")(fr, {}))
    assert f.status == "pass" and f.evidence["duration_s"] == pytest.approx(2.1)
    assert check(get("action_advertised")(fr, {})).status == "pass"     # it answered goals


def test_success_claimed_but_turtle_elsewhere() -> None:
    fr = _frames([_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 2)], [(T0 + 1.5, 3.0, 7.0)])
    f = check(get("action_goals_succeed")(fr, {}))
    assert f.status == "fail" and "m away" in f.feedback and "d_e <= goal_tol" in f.feedback


def test_failed_and_rejected_reachable_goals() -> None:
    evs = [_goal(T0 + 1, 1.0, 9.0, True, False, T0 + 9, time_out=8.0), _goal(T0 + 10, 8.0, 3.0, False),
           _goal(T0 + 12, 5.0, 5.0, True, True, T0 + 13)]
    fr = _frames(evs, [(T0 + 12.5, 5.0, 5.0)])
    f = check(get("action_goals_succeed")(fr, {}))
    assert f.status == "partial" and f.fraction == pytest.approx(1 / 3)
    probs = [g["problem"] for g in f.evidence["goals"]]
    assert "success=False" in probs[0] and "rejected" in probs[1] and probs[2] is None
    # the feedback says how long the server tried, how far the turtle was and the goal's timeout,
    # so a timeout on a slow machine is told apart from a controller that never converges
    assert "after 8.0 s" in probs[0] and "turtle 5.71 m away" in probs[0] and "goal timeout 8 s" in probs[0]


def test_out_of_bounds_accepted() -> None:
    fr = _frames([_goal(T0 + 1, 12.0, 5.0, True, False, T0 + 5), _goal(T0 + 6, 5.0, -0.5, False)])
    f = check(get("action_rejects_out_of_bounds")(fr, {}))
    assert f.status == "partial" and f.fraction == 0.5 and "was accepted" in f.feedback


def test_band_between_11_and_world_edge_is_not_judged() -> None:
    fr = _frames([_goal(T0 + 1, 11.05, 5.0, True, True, T0 + 9)], [(T0 + 8, 11.05, 5.0)])
    assert check(get("action_goals_succeed")(fr, {})).status == "error"
    assert check(get("action_rejects_out_of_bounds")(fr, {})).status == "error"


def test_timeout_not_enforced() -> None:
    fr = _frames([_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 12, time_out=2.0)], [(T0 + 11.9, 1.0, 9.0)])
    f = check(get("action_timeout")(fr, {}))
    assert f.status == "fail" and "now() - T1" in f.feedback
    fr = _frames([_goal(T0 + 1, 1.0, 9.0, True, False, T0 + 12, time_out=2.0)])
    f = check(get("action_timeout")(fr, {}))
    assert f.status == "partial" and f.fraction == 0.5
    fr = _frames([_goal(T0 + 1, 1.0, 9.0, True, None, None, time_out=2.0)])
    assert check(get("action_timeout")(fr, {})).status == "fail"
    # the timeout probe is not counted among the goals that must succeed
    assert check(get("action_goals_succeed")(fr, {})).status == "error"


def test_pairing_by_id_out_of_order() -> None:
    evs = [_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9, gid="a"), _goal(T0 + 2, 8.0, 3.0, True, False, T0 + 5, gid="b")]
    gs = action_goals(_frames(evs))
    assert [(g["x"], g["success"]) for g in gs] == [(1.0, True), (8.0, False)]


def test_pairing_in_order_without_ids() -> None:
    # second goal sent before the first result: results answer accepted goals in order
    evs = [_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9), _goal(T0 + 2, 15.0, 3.0, False),
           _goal(T0 + 3, 8.0, 3.0, True, False, T0 + 10)]
    gs = action_goals(_frames(evs))
    assert [(g["x"], g["accepted"], g["success"]) for g in gs] == [(1.0, True, True), (15.0, False, None),
                                                                   (8.0, True, False)]


def test_advertised() -> None:
    fr = _frames([[(T0 + 1, "action_server_found", {"action": "/turtle_goal"})]])
    assert check(get("action_advertised")(fr, {})).status == "pass"
    fr = _frames([], meta_topics=["/turtle_goal/_action/status"])
    assert check(get("action_advertised")(fr, {})).status == "pass"
    fr = _frames([], meta_topics=["/turtle_goals/_action/status"])
    f = check(get("action_advertised")(fr, {}))
    assert f.status == "fail" and "/turtle_goals" in f.feedback
    fr = _frames([[(T0 + 1, "action_server_missing", {"action": "/turtle_goal"})]])
    assert check(get("action_advertised")(fr, {})).status == "fail"


def test_no_events_is_error() -> None:
    fr = with_meta({"/turtle1/pose": _pose([])})
    for name in ("action_goals_succeed", "action_rejects_out_of_bounds", "action_timeout", "action_client_rejected"):
        assert check(get(name)(fr, {})).status == "error", name


def _client(lines, logs, exit_t=None) -> dict:
    ev = [(t, "stdin_line", {"process": "action_client", "line": ln}) for t, ln in lines]
    if exit_t:
        ev.append((exit_t, "process_exit", {"process": "action_client", "returncode": 1}))
    fr = {"/grader/events": events_frame(sorted(ev, key=lambda r: r[0])),
          "/rosout": rosout_frame([(t, "turtle_controller_client_node", m) for t, m in logs]),
          "/grader/stdout": stdout_frame([(T0, "action_client", "stdout", "")])}
    return with_meta(fr)


CLIENT_LINES = [(T0 + 1, "1.0,9.0"), (T0 + 10, "20.0,5.0"), (T0 + 12, "5.0,5.0")]


def test_client_rejected_and_responsive() -> None:
    logs = [(T0 + 1.1, "Goal Accepted, Navigating"), (T0 + 9, "Navigation Successful: True"),
            (T0 + 10.1, "Goal Rejected"), (T0 + 12.1, "Goal Accepted, Navigating")]
    f = check(get("action_client_rejected")(_client(CLIENT_LINES, logs), {}))
    assert f.status == "pass" and f.evidence["responsive_after"] is True


def test_client_never_told_rejected() -> None:
    logs = [(T0 + 1.1, "Goal Accepted, Navigating"), (T0 + 9, "Navigation Successful: True")]
    f = check(get("action_client_rejected")(_client(CLIENT_LINES, logs), {}))
    assert f.status == "fail" and "GoalResponse.REJECT" in f.feedback


def test_client_hangs_after_rejection() -> None:
    logs = [(T0 + 1.1, "Goal Accepted, Navigating"), (T0 + 10.1, "Goal Rejected")]
    f = check(get("action_client_rejected")(_client(CLIENT_LINES, logs), {}))
    assert f.status == "partial" and f.evidence["responsive_after"] is False


def test_pairing_with_repeated_ids() -> None:
    # the driver's default id is the action name, so every goal may carry the same id
    evs = [_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9, gid="turtle_goal"),
           _goal(T0 + 2, 15.0, 3.0, False, gid="turtle_goal"),
           _goal(T0 + 3, 8.0, 3.0, True, False, T0 + 10, gid="turtle_goal")]
    gs = action_goals(_frames(evs))
    assert [(g["x"], g["accepted"], g["success"]) for g in gs] == [(1.0, True, True), (15.0, False, None),
                                                                   (8.0, True, False)]


def test_server_never_found_is_the_students_fault() -> None:
    fr = _frames([[(T0 + 5, "action_server_missing", {"action": "/turtle_goal", "id": "g1"})]])
    f = check(get("action_advertised")(fr, {}))
    assert f.status == "fail" and "never appeared" in f.feedback
    for name in ("action_goals_succeed", "action_rejects_out_of_bounds", "action_timeout"):
        f = check(get(name)(fr, {}))
        assert f.status == "fail" and "never found" in f.feedback, name


@pytest.mark.parametrize("hz,status", [(30.0, "pass"), (15.0, "pass"), (60.0, "pass"), (3000.0, "fail"), (0.0, "fail")])
def test_the_control_loop_is_paced(hz: float, status: str) -> None:
    # the template's 30 Hz, a student's default of 15 or 60 Hz; a loop without self.rate.sleep()
    # (thousands a second, the audit's surviving mutant); a loop that publishes nothing
    evs = [_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9), _goal(T0 + 10, 8.0, 3.0, True, True, T0 + 18),
           _goal(T0 + 20, 15.0, 5.0, False)]
    fr = _frames(evs)
    if hz:
        t = np.concatenate([np.arange(a + 0.06, b, 1.0 / hz) for a, b in ((T0 + 1, T0 + 9), (T0 + 10, T0 + 18))])
        fr["/turtle1/cmd_vel"] = frame(t, **{"linear.x": 0.5, "angular.z": 0.1})
        fr = with_meta({k: v for k, v in fr.items() if k != "__meta__"})
    f = check(get("action_loop_paced")(fr, {}))
    assert f.status == status, f.feedback
    if hz:
        assert f.evidence["rate_hz"] == pytest.approx(hz, rel=0.03)
    if hz > 200:
        assert "self.rate.sleep()" in f.feedback


def test_the_loop_needs_a_goal_that_ran() -> None:
    f = check(get("action_loop_paced")(_frames([_goal(T0 + 1, 15.0, 5.0, False)]), {}))
    assert f.status == "fail" and "long enough" in f.feedback


def test_a_success_the_goal_status_contradicts_is_not_a_success() -> None:
    # execute_callback returning without goal_handle.succeed(): rclpy aborts the goal, and
    # `ros2 action send_goal` reports ABORTED although the result says success=True
    ev = _goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9)
    ev[-1][2]["status"] = 6
    f = check(get("action_goals_succeed")(_frames([ev], [(T0 + 8.9, 1.0, 9.05)]), {}))
    assert f.status == "fail" and "ABORTED" in f.feedback and "goal_handle.succeed()" in f.feedback


def test_a_server_under_another_name_is_charged_once() -> None:
    """The goals went to the student's other name for the action (``ActionGoal.by_type``): the
    name item fails and says where the server is; the items about what the server does are
    judged on those goals and say under which name they saw it (issue 37)."""
    other = {"action": "/go_to_goal", "asked_for": "/turtle_goal"}
    evs = [[(T0 + 0.5, "action_server_found", {"step": "g1", **other})],
           _goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9, gid="g1"), _goal(T0 + 20, 15.0, 5.0, False, gid="g2")]
    for ev in evs:
        for _t, kind, payload in ev:
            if kind.startswith("action_goal"):
                payload.update(other)
    fr = _frames(evs, [(T0 + 8.9, 1.0, 9.05)])
    f = check(get("action_advertised")(fr, {}))
    assert f.status == "fail" and f.evidence["served_as"] == "/go_to_goal", f.feedback
    assert f.feedback.startswith("There is no action /turtle_goal: your server offers it as /go_to_goal")
    for analyzer in ("action_goals_succeed", "action_rejects_out_of_bounds"):
        f = check(get(analyzer)(fr, {}))
        assert f.status == "pass" and "Sent to /go_to_goal" in f.feedback and "/turtle_goal" in f.feedback, f.feedback
    # the same goals answered under the lab's name: the name item passes, nothing is noted
    for ev in evs:
        for _t, _kind, payload in ev:
            payload.pop("asked_for", None)
            payload["action"] = "/turtle_goal"
    fr = _frames(evs, [(T0 + 8.9, 1.0, 9.05)])
    assert check(get("action_advertised")(fr, {})).status == "pass"
    assert "Sent to" not in check(get("action_goals_succeed")(fr, {})).feedback
