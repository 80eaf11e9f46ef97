"""Whose call a service event is, from the client id in the event (not its timing), and what a
move by student code costs every analyzer that judges poses; poses only from the simulator's record.

The client ids are shaped as measured with rmw_fastrtps (grader.scenario.client_gid): the driver
records its client's GID (the request writer), the simulator's event carries the client's response
reader: same 12-byte participant prefix, another entity id.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analyze_synth import T0, check, events_frame, frame, law, simulate, with_meta
from grader.analyze import get, provenance
from grader.analyze._common import sim_pose

DRIVER = [1, 15, 120, 253, 220, 103, 65, 235, 0, 0, 0, 0]     # the driver's participant (GUID prefix)
STUDENT = [1, 15, 120, 253, 7, 7, 7, 7, 1, 0, 0, 0]
AS_RECORDED = DRIVER + [0, 0, 21, 3]      # rmw_get_gid_for_client: the request writer
AS_SERVED = DRIVER + [0, 0, 20, 4]        # in the simulator's event: the response reader
TELEPORT = "/turtle1/teleport_absolute"
GOALS = [(0.2, 2.0, 7.0), (20.0, 8.0, 3.0)]


def service_events(calls: list[tuple[float, list[int], int, dict]]) -> pd.DataFrame:
    """``<service>/_service_event`` rows: request received + response sent per call
    (t, client gid, sequence number, request)."""
    rows = []
    for t, gid, seq, request in calls:
        for dt, kind in ((0.0, 1), (0.001, 2)):
            rows.append((t + dt, kind, gid, seq, request if kind == 1 else {}))
    cols: dict = {"info.event_type": [r[1] for r in rows], "info.sequence_number": [r[3] for r in rows],
                  "info.client_gid.len": 16}
    for i in range(16):
        cols[f"info.client_gid[{i}]"] = [r[2][i] for r in rows]
    for key in sorted({k for r in rows for k in r[4]}):
        cols[f"request[0].{key}"] = [r[4].get(key, np.nan) for r in rows]
    return frame([r[0] for r in rows], **cols)


def placed_run(student_t: float | None, student_service: str = TELEPORT, request: dict | None = None,
               driver_gid: list[int] | str | None = AS_RECORDED) -> dict:
    """Two goals; the grader places the turtle at goal 1 before goal 2 (at T0 + 19.9, its
    teleport reaching the simulator 10 ms later), and student code calls ``student_service`` at
    ``student_t`` (0.3 s after the placement: within the 2 s the old timing rule took for the
    grader's) and parks the turtle on goal 2."""
    fr = {k: v for k, v in simulate(GOALS, law("correct"), 40.0).items() if k != "__meta__"}
    t_place = T0 + 19.9
    call = {"service": TELEPORT, "type": "turtlesim/srv/TeleportAbsolute", "request": {"x": 2.0, "y": 7.0}}
    if driver_gid != "absent":                       # "absent": recorded before client ids were
        call["client_gid"] = driver_gid
    placed = events_frame([(t_place, "service_call", call)])
    fr["/grader/events"] = pd.concat([fr["/grader/events"], placed]).sort_index()
    served = [(t_place + 0.01, AS_SERVED, 1, {"x": 2.0, "y": 7.0, "theta": 0.0})]
    if student_t is not None:
        pose = fr["/turtle1/pose"].copy()
        pose.loc[pose.index >= student_t + 0.01, ["x", "y"]] = [8.0, 3.0]
        fr["/turtle1/pose"] = pose
        student = (student_t, STUDENT + [0, 0, 18, 4], 1, request or {"x": 8.0, "y": 3.0, "theta": 0.0})
        if student_service == TELEPORT:
            served.append(student)
        else:
            fr[student_service + "/_service_event"] = service_events([student])
    fr[TELEPORT + "/_service_event"] = service_events(sorted(served, key=lambda c: c[0]))
    return with_meta(fr, publishers={"/turtle1/pose": ["/turtlesim"]})


def test_the_graders_placement_is_the_graders_and_costs_nothing() -> None:
    fr = placed_run(None)
    assert [c.by for c in provenance.calls(fr, TELEPORT)] == [provenance.GRADER]
    f = check(get("integrity_no_teleport")(fr, {}))
    assert f.status == "pass" and len(f.evidence["driver_calls"]) == 1
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "pass" and f.value == "2/2 reached", f.feedback


def test_a_student_teleport_right_after_the_placement_is_the_students() -> None:
    """Fails with the timing rule (a call within 2 s of the driver's was taken for the driver's):
    the teleport fault of Lab 3 earned every goal."""
    fr = placed_run(T0 + 20.2)
    assert [c.by for c in provenance.calls(fr, TELEPORT)] == [provenance.GRADER, provenance.STUDENT]
    f = check(get("integrity_no_teleport")(fr, {}))
    assert f.status == "fail" and f.value == "1 call(s)" and "student code" in f.feedback
    assert len(f.evidence["driver_calls"]) == 1 and f.evidence["flagged_calls"][0]["request"]["x"] == 8.0
    f = check(get("goals_reached")(fr, {}))
    goal2 = f.evidence["goals"][1]
    assert f.status == "partial" and f.value == "1/2 reached" and goal2["teleported"] == 1
    assert "teleport_absolute called by student code 1 time(s)" in f.feedback and "earns nothing" in f.feedback


@pytest.mark.parametrize("service,request_", [("/reset", {}), ("/spawn", {"x": 8.0, "y": 3.0, "name": "turtle1"}),
                                              ("/turtle1/teleport_relative", {"linear": 3.0})])
def test_a_reset_or_spawn_by_student_code_costs_the_goal(service, request_) -> None:
    fr = placed_run(T0 + 20.2, service, request_ or {"structure_needs_at_least_one_member": 0})
    f = check(get("goals_reached")(fr, {}))
    assert f.evidence["goals"][1].get("teleported") == 1 and not f.evidence["goals"][1]["reached"]
    assert service in f.feedback


def test_spawning_another_turtle_moves_nothing() -> None:
    fr = placed_run(T0 + 20.2, "/spawn", {"x": 8.0, "y": 3.0, "name": "turtle2"})
    assert provenance.moves(fr, "/turtle1/pose") == []


def test_a_recording_without_the_graders_client_ids_cannot_tell() -> None:
    """Bags made before the driver recorded client ids: nothing is held against the student, and
    the integrity check says it could not decide."""
    fr = placed_run(T0 + 20.2, driver_gid="absent")
    assert {c.by for c in provenance.calls(fr, TELEPORT)} == {provenance.UNKNOWN}
    f = check(get("integrity_no_teleport")(fr, {}))
    assert f.status == "error" and "cannot be told" in f.feedback
    assert provenance.moves(fr, "/turtle1/pose") == []


def test_turn_and_law_earn_nothing_for_a_moved_goal() -> None:
    fr = placed_run(T0 + 20.2)
    f = check(get("turn_direction")(fr, {"min_turn_deg": 0.0}))
    moved = [r for r in f.evidence["goals"] if r.get("teleported")]
    assert moved and not moved[0]["short_way"] and f.status != "pass"
    law_ = check(get("control_law")(fr, {}))
    clean = check(get("control_law")(placed_run(None), {}))
    assert law_.evidence["rows"] < clean.evidence["rows"]


def test_action_goal_reached_by_a_teleport_earns_nothing() -> None:
    from test_an_action_server import _frames, _goal

    fr = dict(_frames([_goal(T0 + 1, 1.0, 9.0, True, True, T0 + 9)], [(T0 + 3.01, 1.0, 9.0)]))
    fr[TELEPORT + "/_service_event"] = service_events([(T0 + 3, STUDENT + [0, 0, 18, 4], 1, {"x": 1.0, "y": 9.0})])
    f = check(get("action_goals_succeed")(with_meta({k: v for k, v in fr.items() if k != "__meta__"}), {}))
    assert f.status == "fail" and "student code" in f.feedback and "earns nothing" in f.feedback


@pytest.mark.parametrize("analyzer,params", [
    ("circle_radius", {"expected_m": 2.0}), ("circle_period", {"expected_s": 6.2832}), ("keeps_moving", {}),
    ("no_wall_contact", {}), ("pen_on_crossings", {})])
def test_whole_run_analyzers_earn_nothing_after_a_student_move(analyzer, params) -> None:
    fr = placed_run(T0 + 20.2)
    f = check(get(analyzer)(fr, params))
    assert f.status == "fail" and f.fraction == 0.0 and "moved without driving" in f.feedback
    assert f.evidence["student_moves"][0]["service"] == TELEPORT


def record_run() -> dict:
    """A run whose bag holds the simulator's record (/grader/sim_record/turtle1/pose) beside a
    public topic and a grader copy on which a student node published "I am at the goal"."""
    fr = {k: v for k, v in simulate([(0.2, 2.0, 7.0)], law("wrong_sign"), 12.0).items() if k != "__meta__"}
    truth = fr["/turtle1/pose"]
    fake = truth.iloc[::10].copy()
    fake.index = fake.index + 0.003
    fake["x"], fake["y"] = 2.0, 7.0
    fr["/grader/sim_record/turtle1/pose"] = truth
    fr["/turtle1/pose"] = pd.concat([truth, fake]).sort_index()
    fr["/grader/sim/turtle1/pose"] = pd.concat([truth, fake]).sort_index()
    return with_meta(fr, publishers={"/turtle1/pose": ["/turtlesim"], "/grader/sim/turtle1/pose": ["/turtlesim"]})


def test_goals_are_judged_on_the_simulators_record_only() -> None:
    """Fails when poses come from /grader/sim/turtle1/pose, which any node can publish on."""
    fr = record_run()
    assert sim_pose(fr, "/turtle1/pose") is fr["/grader/sim_record/turtle1/pose"]
    f = check(get("goals_reached")(fr, {}))
    assert f.status == "fail" and "the simulator never published were ignored" in f.feedback
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "fail" and "on the grader's copy /grader/sim/turtle1/pose" in f.feedback and f.evidence["foreign_poses"] > 0


def test_an_empty_record_is_not_replaced_by_topics_anyone_can_publish() -> None:
    fr = record_run()
    fr["/grader/sim_record/turtle1/pose"] = fr["/grader/sim_record/turtle1/pose"].iloc[:0]
    assert sim_pose(fr, "/turtle1/pose") is None
    assert check(get("goals_reached")(fr, {})).status == "error"


def test_a_starved_simulators_bursts_are_not_a_second_publisher() -> None:
    """A simulator starved on a loaded machine publishes its late ticks in bursts (the fault
    corpus measured 9 kHz "rates" at load 60): with its own record, only foreign poses count."""
    fr = {k: v for k, v in simulate([(0.2, 2.0, 7.0)], law("correct"), 12.0).items() if k != "__meta__"}
    pose = fr["/turtle1/pose"].copy()
    t = pose.index.to_numpy()
    pose.index = pd.Index(t[::8].repeat(8)[:len(t)] + np.tile(np.arange(8) * 1e-5, len(t) // 8 + 1)[:len(t)], name="t")
    fr["/turtle1/pose"] = pose
    fr["/grader/sim_record/turtle1/pose"] = pose.copy()
    fr = with_meta(fr, publishers={"/turtle1/pose": ["/turtlesim"]})
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "pass" and "own record" in f.feedback, f.feedback
    # a recording without the record but with the simulator's copy: still exact
    copy_only = {k: v for k, v in fr.items() if k != "/grader/sim_record/turtle1/pose"}
    assert check(get("integrity_pose_publisher")(copy_only, {})).status == "pass"
    # with neither, only the stream can speak: its rate is taken as count over span, so the
    # bursts average out (a rate from the gaps between receive times read them as ~100 kHz)
    legacy = {k: v for k, v in copy_only.items() if k != "/grader/sim/turtle1/pose"}
    f = check(get("integrity_pose_publisher")(legacy, {}))
    assert f.status == "pass" and f.evidence["rate_hz"] < 70, (f.feedback, f.evidence.get("rate_hz"))
