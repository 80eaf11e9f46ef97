"""Exercise 2 controller analyzers on a simulated unicycle (dt = 0.016) driven by P-controllers."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import numpy as np
import pytest

from analyze_synth import T0, check, events_frame, law, simulate
from grader.analyze import get

TWO_GOALS = [(0.5, 2.0, 7.0), (25.5, 5.0, 1.0)]


@pytest.fixture(scope="module")
def runs() -> dict:
    return {kind: simulate(TWO_GOALS, law(kind), 50.0) for kind in ("correct", "wrong_sign", "no_wrap")}


def test_correct_controller_passes_everything(runs) -> None:
    fr = runs["correct"]
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "pass", f.feedback
    for g in f.evidence["goals"]:
        assert g["reached"] and g["held"] and g["stopped"] and 2 < g["time_to_reach"] < 20
        assert g["final_error"] < 0.1
    f = check(get("turn_direction")(fr, {}))
    assert f.status == "pass" and f.evidence["goals"][0]["initial_turn"] == "left (CCW)"
    f = check(get("control_law")(fr, {}))
    assert f.status == "pass", f.feedback
    assert f.evidence["K1"] == pytest.approx(0.5, rel=0.02)
    assert f.evidence["K2"] == pytest.approx(1.0, rel=0.02)
    assert f.evidence["R2_linear"] > 0.99 and f.evidence["R2_angular"] > 0.99
    f = check(get("publish_rate")(fr, {"topic": "/turtle1/cmd_vel", "expected_hz": 1 / 0.03}))
    assert f.status == "pass"


def test_other_gains_are_recovered() -> None:
    fr = simulate(TWO_GOALS, law("correct", k1=0.2, k2=0.7), 50.0)
    f = check(get("control_law")(fr, {}))
    assert f.status == "pass"
    assert f.evidence["K1"] == pytest.approx(0.2, rel=0.02) and f.evidence["K2"] == pytest.approx(0.7, rel=0.02)


def test_wrong_sign(runs) -> None:
    fr = runs["wrong_sign"]
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "fail" and f.fraction == 0.0 and "closest approach" in f.feedback
    f = check(get("turn_direction")(fr, {}))
    assert f.status == "fail" and "long way" in f.feedback
    assert f.evidence["goals"][0]["initial_turn"] == "right (CW)"
    f = check(get("control_law")(fr, {}))
    assert f.status == "partial" and f.fraction == 0.5
    assert f.evidence["K2"] < 0 and "wrong sign" in f.feedback
    assert f.feedback[0].isupper() and "K2 ≈" in f.feedback


def test_missing_wrap_is_detected_by_the_fit(runs) -> None:
    f = check(get("control_law")(runs["no_wrap"], {}))
    assert f.evidence["wrap"] == "missing" and f.status == "partial"
    assert f.evidence["R2_angular_unwrapped"] > 0.99 > f.evidence["R2_angular"]
    assert "without wrapping" in f.feedback
    # and the correct controller's wrap was actually tested, not skipped
    assert check(get("control_law")(runs["correct"], {})).evidence["wrap"] == "ok"


def test_missing_wrap_turns_the_long_way() -> None:
    # heading 2.8 rad, goal direction -2.82 rad: short way is +38 deg (left); naive difference is -322 deg
    start = (5.5, 5.5, 2.8)
    good = check(get("turn_direction")(simulate([(0.2, 1.0, 4.0)], law("correct"), 15.0, start=start), {}))
    assert good.status == "pass"
    row = good.evidence["goals"][0]
    assert row["wrap_matters"] and row["required_turn_deg"] == pytest.approx(37.9, abs=1.0)
    bad = check(get("turn_direction")(simulate([(0.2, 1.0, 4.0)], law("no_wrap"), 15.0, start=start), {}))
    assert bad.status == "fail" and "wrapped" in bad.feedback
    assert bad.evidence["goals"][0]["initial_turn"] == "right (CW)"


def test_turn_direction_does_not_depend_on_the_controllers_timer_phase() -> None:
    """Issue 22: a controller whose heading error is in degrees spins up to 3 rad per tick, so
    which way its heading seems to move from pose to pose depends on its timer's phase (0.75/3
    in one run, 3/3 in the next). Held at each hand-over (as a placed step is), the command it
    computes from the held pose has the right sign in every phase: judged on it, every phase
    gives one verdict, and wrong_sign's and no_wrap's too. (Judged from the poses, the degrees
    controller got all three answers here.)"""
    start = (5.5, 5.5, 2.8)            # goal (1, 4): 38 deg left, 322 deg right unwrapped; then (9, 9.5)
    for kind, want in (("degrees", {"pass"}), ("correct", {"pass"}), ("wrong_sign", {"fail", "partial"}),
                       ("no_wrap", {"fail", "partial"})):
        verdicts = set()
        for phase in np.arange(0.0005, 0.03, 0.0025):
            frames = simulate([(0.2, 1.0, 4.0), (6.0, 9.0, 9.5)], law(kind), 12.0, start=start,
                              ctrl_phase=phase, hold_s=0.15)
            f = check(get("turn_direction")(frames, {"min_turn_deg": 30.0}))
            verdicts.add((f.status, f.value))
        assert len(verdicts) == 1 and next(iter(verdicts))[0] in want, (kind, verdicts)


def test_a_hand_over_missing_from_the_bag_is_judged_by_the_first_tick_after_the_release() -> None:
    """Issue 22: the recorder matched a controller started just before the first goal late, and
    the bag had none of the commands sent while the turtle was held; the first one it had, 0.55 s
    after the goal, came after wrong_sign had turned past 180 degrees and pointed the short way
    (0.75/3 once, 0/3 in every other run). The first tick after the release is driven by the last
    command sent while held: judged from it, every phase and every gap gives the verdict of the
    whole recording. (Judged from the first recorded command, wrong_sign passed here.)"""
    for kind in ("wrong_sign", "correct", "degrees"):
        want = set()
        for phase in np.arange(0.0005, 0.03, 0.005):
            frames = simulate([(0.2, 2.0, 7.0)], law(kind), 6.0, start=(5.5, 5.5, 0.0), ctrl_phase=phase, hold_s=0.15)
            full = check(get("turn_direction")(frames, {}))
            want.add(full.status)
            for gap in (0.3, 0.55, 0.8):            # commands recorded only from T0 + 0.2 + gap
                cut = dict(frames)
                cmd = frames["/turtle1/cmd_vel"]
                cut["/turtle1/cmd_vel"] = cmd[cmd["pub_t"] > T0 + 0.2 + gap]
                f = check(get("turn_direction")(cut, {}))
                row = f.evidence["goals"][0]
                assert f.status == full.status and row["basis"] == "first tick", (kind, phase, gap, row)
        assert want == ({"fail"} if kind == "wrong_sign" else {"pass"}), (kind, want)


def test_a_turn_of_more_than_half_a_circle_per_tick_is_judged_by_its_command() -> None:
    """theta_e in degrees with K_2 = 2: 270 rad/s for a 135 degree left turn, 4.3 rad per 16 ms
    tick, which the poses show as a 2 rad turn to the right. The command says left: the short
    way. (Judged from the poses, it failed in every phase.)"""
    for phase in np.arange(0.0005, 0.03, 0.005):
        frames = simulate([(0.2, 3.0, 8.0)], law("degrees", k2=2.0), 4.0, start=(5.5, 5.5, 0.0),
                          ctrl_phase=phase, hold_s=0.15)
        f = check(get("turn_direction")(frames, {}))
        row = f.evidence["goals"][0]
        assert f.status == "pass" and row["basis"] == "command", row
        assert row["commanded_turn"] == "left (CCW)" and row["first_cmd_angular_z"] > 200


def test_large_right_turn_and_goal_behind() -> None:
    f = check(get("turn_direction")(simulate([(0.2, 3.0, 2.0)], law("correct"), 15.0), {}))
    assert f.status == "pass" and f.evidence["goals"][0]["initial_turn"] == "right (CW)"
    f = check(get("turn_direction")(simulate([(0.2, 3.0, 2.0)], law("wrong_sign"), 15.0), {}))
    assert f.status == "fail"
    # a goal right behind the turtle: both directions are the short way
    for kind in ("correct", "wrong_sign"):
        f = check(get("turn_direction")(simulate([(0.2, 1.0, 5.9)], law(kind), 10.0), {}))
        assert f.evidence["goals"][0]["ambiguous"]
        assert f.status == "pass"


def test_small_turn_goals_are_not_judged() -> None:
    f = check(get("turn_direction")(simulate([(0.2, 9.0, 6.0)], law("correct"), 10.0), {}))
    assert f.status == "error" and not f.evidence["goals"][0]["evaluated"]


def test_goals_from_topic_when_no_events() -> None:
    fr = simulate(TWO_GOALS, law("correct"), 50.0, events=False)
    assert "/grader/events" not in fr
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "pass" and f.evidence["goal_source"] == "topic"
    assert check(get("control_law")(fr, {})).status == "pass"


def test_reached_but_not_stopped_is_partial() -> None:
    def overshoot(x, y, th, gx, gy):
        v, w = law("correct")(x, y, th, gx, gy)
        return max(v, 0.6), w          # never slows below 0.6 m/s: passes the goal, circles around it
    fr = simulate([(0.2, 8.0, 5.544445)], overshoot, 15.0)
    f = check(get("goals_reached")(fr, {}))
    g = f.evidence["goals"][0]
    assert g["reached"] and not g["stopped"]
    assert f.status == "partial" and f.fraction == pytest.approx(0.75)
    assert "did not stay stopped" in f.feedback


def test_time_limit() -> None:
    fr = simulate([(0.2, 2.0, 7.0)], law("correct", k1=0.2), 20.0)
    assert check(get("goals_reached")(fr, {})).status == "pass"
    f = check(get("goals_reached")(fr, {"time_limit_s": 3.0}))
    assert f.status == "fail"


def test_missing_inputs() -> None:
    fr = simulate(TWO_GOALS, law("correct"), 5.0)
    no_pose = {k: v for k, v in fr.items() if k != "/turtle1/pose"}
    for name in ("goals_reached", "turn_direction", "control_law"):
        assert check(get(name)(no_pose, {})).status == "error"
    no_goals = {k: v for k, v in fr.items() if k != "/grader/events"}
    assert check(get("goals_reached")(no_goals, {})).status == "error"
    no_cmd = {k: v for k, v in fr.items() if k != "/turtle1/cmd_vel"}
    f = check(get("control_law")(no_cmd, {}))
    assert f.status == "fail" and "/turtle1/cmd_vel" in f.feedback


def test_goal_sent_on_another_topic_is_not_a_goal() -> None:
    fr = simulate(TWO_GOALS, law("correct"), 50.0)
    other = events_frame([(T0 + 30, "goal_sent", {"goal": [0.5, 0.5], "topic": "/random_numbers"})])
    fr["/grader/events"] = pd.concat([fr["/grader/events"], other]).sort_index()
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "pass" and len(f.evidence["goals"]) == 2


def test_a_turtle_placed_on_its_goal_by_the_scenario_has_not_reached_it(runs) -> None:
    """A rubric may teleport the turtle before the next goal (so every goal starts from the same
    pose in every run); the goal before it ends at that teleport, and the pose after it does not
    count as arriving there. Here wrong_sign's turtle is put on goal 1 for the last 2 s of goal
    1's window."""
    from grader.analyze.goals import goals

    fr = dict(runs["wrong_sign"])
    t_place = T0 + 23.5
    pose = fr["/turtle1/pose"].copy()
    after = pose.index >= t_place + 0.02
    pose.loc[after & (pose.index < T0 + 25.5), ["x", "y"]] = [2.0, 7.0]     # parked on goal 1
    fr["/turtle1/pose"] = pose
    placed = events_frame([(t_place, "service_call", {"service": "/turtle1/teleport_absolute"})])
    fr["/grader/events"] = pd.concat([fr["/grader/events"], placed]).sort_index()
    g1, g2 = goals(fr)
    assert g1.t_end == pytest.approx(t_place, abs=1e-6) and g2.t_end != g2.t_end      # NaN: the last goal
    f = check(get("goals_reached")(fr, {}))
    assert not f.evidence["goals"][0]["reached"], f.evidence["goals"][0]
    # the grader's own teleport is no integrity problem and costs no goal its credit
    assert "teleported" not in f.evidence["goals"][1]


def _until_settled(controller, goal: tuple[float, float], until, timeout: float, start) -> dict:
    """The run of one Lab 3 goal step as the scenario ends it: from the goal until the turtle has
    stayed within ``until.tolerance`` for ``until.settle`` s (or the step's timeout)."""
    full = simulate([(0.0, *goal)], controller, timeout, start=start)
    pose = full["/turtle1/pose"]
    t = pose.index.to_numpy(float)
    inside = np.hypot(pose["x"].to_numpy() - goal[0], pose["y"].to_numpy() - goal[1]) <= until.tolerance
    since = None
    for ti, ok in zip(t, inside):
        since = (since if since is not None else ti) if ok else None
        if since is not None and ti - since >= until.settle:
            return simulate([(0.0, *goal)], controller, ti - T0, start=start)
    return full


def test_lab3_a_higher_positive_gain_still_stops_at_the_goal() -> None:
    """``grader rubric audit`` of Lab 3 killed scale_constant-1e55946b, the reference with
    K_1 = 1.0 (K_2 = 1.0): correct by the lab text (K_1, K_2 positive gains; Question 4 asks to
    change them), yet it lost half of ex2.goals_reached (4 of 8 points) on every goal, "did not
    stay stopped" (recorded: moved 0.066 m at up to 0.098 m/s in the last second). A goal step
    ended 1 s after the turtle came within 0.1 m, so the analyzer's last second was the arrival
    itself, where v = K_1 d_e falls from 0.1 K_1: every K_1 above ~0.7 moved more than 0.05 m
    in it. With the rubric's steps, any positive gain is stopped in its last second, and a
    controller that keeps circling the goal at 0.1 m/s still is not."""
    from grader.rubric.load import load_rubric

    rubric = load_rubric(Path(__file__).resolve().parents[2] / "rubrics" / "enee467_lab3.yaml", check_files=False)
    params = dict(rubric.item("ex2.goals_reached").params)
    steps = [s for s in rubric.scenarios["ex2_controller"].steps if s.goal is not None]
    goal_lab = steps[0]
    start = (goal_lab.place.x, goal_lab.place.y, goal_lab.place.theta)

    def run(controller):
        frames = _until_settled(controller, goal_lab.goal.xy, goal_lab.until, goal_lab.timeout, start)
        return check(get("goals_reached")(frames, params))

    for k1, k2 in ((1.0, 1.0), (2.0, 4.0), (0.5, 1.0), (0.5, 0.5)):
        f = run(law("correct", k1=k1, k2=k2))
        assert f.status == "pass", (k1, k2, f.evidence["goals"][0])

    def circles(x, y, th, gx, gy):
        v, w = law("correct")(x, y, th, gx, gy)
        return max(v, 0.1), w          # never slower than 0.1 m/s: circles the goal inside 0.1 m
    f = run(circles)
    assert f.status == "partial" and not f.evidence["goals"][0]["stopped"], f.evidence["goals"][0]


def _as_action_goals(fr: dict) -> dict:
    """The same run with its goals sent to an action server (ex3_action's `action:` steps)."""
    import json

    from analyze_synth import string_frame, with_meta
    ev = fr["/grader/events"]
    rows = []
    for t, d in zip(ev.index, ev["data"]):
        e = json.loads(d)
        if e["event"] == "goal_sent":
            e = {"event": "action_goal_sent", "step": e["step"],
                 "goal": {"goal": {"x": e["goal"][0], "y": e["goal"][1]}, "goal_tol": 0.1}}
        rows.append((t, e))
    out = {k: v for k, v in fr.items() if k != "__meta__"}
    out["/grader/events"] = string_frame(rows)
    return with_meta(out, publishers={"/turtle1/pose": ["/turtlesim"]})


def test_the_control_law_of_an_action_servers_loop() -> None:
    # the Lab 3 audit's surviving server mutant: theta_e = atan2(y_e c - x_e s, x_e c - y_e s)
    # chatters between +-pi at the goal's heading and still reaches goals; its law does not fit
    def chatter(x, y, th, gx, gy):
        dx, dy = gx - x, gy - y
        te = math.atan2(dy * math.cos(th) - dx * math.sin(th), dx * math.cos(th) - dy * math.sin(th))
        return 0.5 * math.hypot(dx, dy), 2.0 * te

    goals3 = [(0.5, 2.0, 7.0), (15.5, 8.0, 7.0), (30.5, 8.0, 9.5)]
    good = _as_action_goals(simulate(goals3, law("correct", 0.5, 2.0), 45.0))
    assert get("goals_reached")(good, {"goal_source": "action"}).evidence["goals"][0]["reached"]
    f = check(get("control_law")(good, {"goal_source": "action", "r2_min": 0.75}))
    assert f.status == "pass", f.feedback
    assert 1.8 < float(str(f.value).split("K2=")[1].split()[0]) < 2.2, f.value
    bad = _as_action_goals(simulate(goals3, chatter, 45.0))
    f = check(get("control_law")(bad, {"goal_source": "action", "r2_min": 0.75}))
    assert f.status != "pass", f.evidence
    # without source="action" the goals are not seen at all
    assert get("control_law")(good, {}).status != "pass"
