"""Integrity flags: pose publisher and teleport/reset calls."""

from __future__ import annotations

import numpy as np

from analyze_synth import T0, check, events_frame, frame, law, simulate, with_meta
from grader.analyze import get


def _sim() -> dict:
    return simulate([(0.2, 2.0, 7.0)], law("correct"), 12.0)


def test_clean_run() -> None:
    fr = _sim()
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "pass" and f.evidence["n_jumps"] == 0 and f.evidence["basis"] == "publisher list"
    f = check(get("integrity_no_teleport")(fr, {}))
    assert f.status == "pass"


def test_foreign_pose_publisher() -> None:
    fr = _sim()
    fr = with_meta({k: v for k, v in fr.items() if k != "__meta__"},
                   publishers={"/turtle1/pose": ["/turtlesim", "/turtle_control_node"]})
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "fail" and "/turtle_control_node" in f.feedback


def test_spoofed_pose_jump_without_publisher_info() -> None:
    fr = _sim()
    pose = fr["/turtle1/pose"].copy()
    i = len(pose) // 2
    pose.iloc[i, pose.columns.get_loc("x")] = 1.0          # one fake pose in the stream
    fr = with_meta({**{k: v for k, v in fr.items() if k != "__meta__"}, "/turtle1/pose": pose})
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "fail" and "jumped" in f.feedback
    assert f.evidence["basis"].startswith("pose stream")


def test_poses_bunched_and_dropped_by_a_loaded_machine_are_no_flag() -> None:
    """At --jobs 8 on 2 cores the poses reached the recorder in bursts, a few dropped from the
    keep-last-7 queue: receive times 0.1 ms apart ("11,000 Hz") and steps of several ticks.
    Correct code was flagged. With the simulator's own copy of every pose recorded, only a pose
    it never published counts. (Fails without: flagged for the rate and for jumps.)"""
    fr = _sim()
    pose = fr["/turtle1/pose"]
    t = pose.index.to_numpy().copy()
    t[100:400] = t[100] + np.arange(300) * 1e-4        # 300 poses delivered at once
    bunched = pose.set_axis(t).drop(pose.index[[500, 501, 502, 503, 504]])      # and five dropped
    fr = with_meta({**{k: v for k, v in fr.items() if k != "__meta__"}, "/turtle1/pose": bunched,
                    "/grader/sim/turtle1/pose": pose}, publishers={"/turtle1/pose": ["/turtlesim"]})
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "pass", f.feedback
    assert f.evidence["foreign_poses"] == 0 and "own copy" in f.evidence["basis"]
    spoofed = bunched.copy()
    spoofed.iloc[200, spoofed.columns.get_loc("x")] = 1.0           # one pose the simulator never sent
    fr["/turtle1/pose"] = spoofed
    f = check(get("integrity_pose_publisher")(fr, {}))
    assert f.status == "fail" and f.evidence["foreign_poses"] == 1


def _service(t, x, seq, gid=7) -> object:
    return frame(t, **{"info.event_type": 1, "info.sequence_number": seq,
                       **{f"info.client_gid[{i}]": gid for i in range(16)},
                       "request[0].x": x, "request[0].y": 5.0, "request[0].theta": 0.0})


def test_teleport_is_flagged_unless_the_driver_made_it() -> None:
    fr = {k: v for k, v in _sim().items() if k != "__meta__"}
    # two events (request received + response sent) per call; two calls
    fr["/turtle1/teleport_absolute/_service_event"] = _service([T0 + 3, T0 + 3.001, T0 + 6, T0 + 6.001],
                                                               [9.0, np.nan, 2.0, np.nan], [1, 1, 2, 2])
    fr["/turtle1/set_pen/_service_event"] = frame([T0 + 1], **{"info.sequence_number": 1, "request[0].off": 1})
    f = check(get("integrity_no_teleport")(with_meta(fr), {}))
    assert f.status == "fail" and f.value == "2 call(s)" and "teleport_absolute" in f.feedback
    assert f.evidence["flagged_calls"][0]["request"]["x"] == 9.0
    assert len(f.evidence["set_pen_calls"]) == 1
    # the driver placed the turtle itself at t=3 with a client of another participant (gid 8...):
    # both calls are still the student's, whatever their timing
    fr["/grader/events"] = events_frame([(T0 + 2.9, "service_call", {"service": "/turtle1/teleport_absolute",
                                                                      "client_gid": [8] * 16})])
    f = check(get("integrity_no_teleport")(with_meta(fr), {}))
    assert f.status == "fail" and f.value == "2 call(s)" and not f.evidence["driver_calls"]
    # with its own participant's id (gid 7...): they are the grader's
    fr["/grader/events"] = events_frame([(T0 + 2.9, "service_call", {"service": "/turtle1/teleport_absolute",
                                                                      "client_gid": [7] * 16})])
    f = check(get("integrity_no_teleport")(with_meta(fr), {}))
    assert f.status == "pass" and len(f.evidence["driver_calls"]) == 2


def test_no_pose_is_error() -> None:
    assert check(get("integrity_pose_publisher")(with_meta({}), {})).status == "error"


def test_foreign_publisher_from_the_drivers_graph_snapshot() -> None:
    fr = {k: v for k, v in _sim().items() if k != "__meta__"}
    fr["/grader/events"] = events_frame([(T0 + 5, "graph", {"publishers": {"/turtle1/pose": ["turtlesim", "cheat"]},
                                                            "subscribers": {}})])
    f = check(get("integrity_pose_publisher")(with_meta(fr), {}))
    assert f.status == "fail" and "cheat" in f.feedback


def test_jump_caused_by_a_teleport_call_is_left_to_the_teleport_flag() -> None:
    fr = {k: v for k, v in _sim().items() if k != "__meta__"}
    pose = fr["/turtle1/pose"].copy()
    i = len(pose) // 2
    pose.iloc[i:, pose.columns.get_loc("x")] = 1.0       # teleported and stays there
    fr["/turtle1/pose"] = pose
    t_jump = float(pose.index[i])
    fr["/turtle1/teleport_absolute/_service_event"] = _service([t_jump - 0.01], [1.0], [1])
    assert check(get("integrity_pose_publisher")(with_meta(fr), {})).status == "pass"
    assert check(get("integrity_no_teleport")(with_meta(fr), {})).status == "fail"
    del fr["/turtle1/teleport_absolute/_service_event"]
    assert check(get("integrity_pose_publisher")(with_meta(fr), {})).status == "fail"


def test_poses_the_simulator_never_published_are_flagged_and_goals_use_its_own() -> None:
    """The simulator's copy (/grader/sim/turtle1/pose) tells its poses from anyone else's: a fake
    pose on /turtle1/pose is flagged, poses recorded on the public topic before the copy was
    subscribed are not, and arrival is judged on the copy."""
    import pandas as pd

    from grader.analyze._common import sim_pose

    fr = {k: v for k, v in _sim().items() if k != "__meta__"}
    truth = fr["/turtle1/pose"].copy()
    public = truth.copy()
    fr["/grader/sim/turtle1/pose"] = truth.iloc[20:]           # the copy subscribed a bit later
    assert check(get("integrity_pose_publisher")(with_meta(dict(fr)), {})).status == "pass"
    fake = public.iloc[[len(public) // 2]].copy()
    fake.index = fake.index + 0.001
    fake["x"], fake["y"] = 2.0, 7.0                            # "I am at the goal"
    fr["/turtle1/pose"] = pd.concat([public, fake]).sort_index()
    f = check(get("integrity_pose_publisher")(with_meta(dict(fr)), {}))
    assert f.status == "fail" and f.evidence["foreign_poses"] == 1
    assert sim_pose(fr, "/turtle1/pose") is fr["/grader/sim/turtle1/pose"]
