"""A scenario end to end with no student code: sim + recorder + driver steps → bag + record."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grader.scenario import resolve, run_scenario
from grader.scenario.model import Scenario


@pytest.mark.ros
@pytest.mark.slow
def test_drive_turtle_and_record(tmp_path: Path) -> None:
    scenario = Scenario.model_validate({"steps": [
        {"id": "go", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                 "msg": {"linear": {"x": 2.0}, "angular": {"z": 1.8}}},
         "until": {"condition": "messages", "topic": "/turtle1/cmd_vel", "count": 1}, "timeout": 5},
        {"id": "coast", "wait": 1.5},
        # someone else's "poses" on the grader's names: the bag's record must not take them
        {"id": "fake", "publish": {"topic": "/grader/sim_record/turtle1/pose", "type": "turtlesim/msg/Pose",
                                   "msg": {"x": 1.0, "y": 1.0}, "count": 20, "rate_hz": 20}, "timeout": 1.5},
        {"id": "fake_copy", "publish": {"topic": "/grader/sim/turtle1/pose", "type": "turtlesim/msg/Pose",
                                        "msg": {"x": 1.0, "y": 1.0}, "count": 20, "rate_hz": 20}, "timeout": 1.5},
        # ... and a forged event of the grader's: only the driver's own events are recorded
        {"id": "forged", "publish": {"topic": "/grader/events", "type": "std_msgs/msg/String",
                                     "msg": {"data": '{"event": "service_call", "forged": true}'},
                                     "count": 20, "rate_hz": 20}, "timeout": 1.5},
        {"id": "pen", "service": {"name": "/turtle1/set_pen", "request": {"r": 255, "g": 0, "b": 0, "width": 5,
                                                                          "off": 0}},
         "until": "service_done", "timeout": 10},
    ], "limits": {"wall_s": 60}})
    record = run_scenario(resolve("drive", scenario, None), tmp_path / "drive")
    assert record["errors"] == [], record
    assert [s["ended_by"] for s in record["steps"]] == ["condition", "done", "done", "done", "done", "condition"]
    assert record["steps"][5]["detail"]["type"] == "turtlesim/srv/SetPen"   # found from the graph
    from grader.bag.frames import load_frames
    frames = load_frames(tmp_path / "drive" / "bag")
    pose = frames["/turtle1/pose"]
    assert len(pose) > 100
    # the one cmd_vel from the start pose ends near the spec's test vector
    assert pose["x"].iloc[-1] == pytest.approx(6.6028166, abs=0.05)
    assert pose["y"].iloc[-1] == pytest.approx(6.9389896, abs=0.05)
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    names = [e["event"] for e in events]
    assert names[0] == "scenario_start" and "service_call" in names and names[-1] == "scenario_end"
    assert not any(e.get("forged") for e in events)
    assert "/turtle1/set_pen/_service_event" in frames
    assert Path(record["canvas"]).exists()
    # the simulator's own record of its poses is in the bag, the published ones exactly, and
    # nothing published under its name got in; poses are judged on it alone
    from grader.analyze._common import sim_pose
    from grader.bag.conformance import check_bag
    rec = frames["/grader/sim_record/turtle1/pose"]
    assert len(rec) > 100 and not ((rec["x"] == 1.0) & (rec["y"] == 1.0)).any()
    public = set(zip(pose["x"], pose["y"], pose["theta"]))
    assert public <= set(zip(rec["x"], rec["y"], rec["theta"]))
    assert sim_pose(frames, "/turtle1/pose") is rec
    assert not (tmp_path / "drive" / "sim_poses.record").exists()
    assert check_bag(tmp_path / "drive" / "bag") == []


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize("time_scale", [1.0, 4.0])
def test_place_puts_the_turtle_there_before_the_action(tmp_path: Path, time_scale: float) -> None:
    """`place:` teleports the (moving) turtle and goes on once the simulator shows it there; the
    teleport is recorded as the driver's own service call. On simulated time the clock is held
    at once while the action is handed over, so the turtle has not moved on when it arrives."""
    scenario = Scenario.model_validate({"steps": [
        {"id": "go", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                 "msg": {"linear": {"x": 1.0}, "angular": {"z": 0.5}}}, "timeout": 0.5},
        {"id": "placed", "place": {"x": 2.0, "y": 7.0, "theta": 2.1},
         "publish": {"topic": "/marker", "type": "std_msgs/msg/Empty"}, "timeout": 0.2},
    ], "limits": {"wall_s": 30}})
    run = resolve("place", scenario, None).model_copy(update={"time_scale": time_scale})
    record = run_scenario(run, tmp_path / "place")
    assert record["errors"] == [], record
    if time_scale > 1:
        from grader.scenario.steps import PLACE_HANDOFF_S
        assert record["time_scale"]["used"] == 4.0 and record["time_scale"]["held_s"] >= PLACE_HANDOFF_S
    placed = record["steps"][1]["detail"]["placed"]
    assert placed["pose"] == [2.0, 7.0, 2.1] and placed["shown"] is True
    # the pose seen when the action went on: there, moved by a tick of the command it still had
    assert placed["seen"] == pytest.approx([2.0, 7.0, 2.1], abs=0.04)
    from grader.bag.frames import load_frames
    frames = load_frames(tmp_path / "place" / "bag")
    marker_t = frames["/marker"].index[0]
    truth = frames["/grader/sim/turtle1/pose"]
    before = truth[truth.index < marker_t].iloc[-1]
    # the last pose before the action is the placement, moved by at most a tick of the command
    assert abs(before["x"] - 2.0) < 0.05 and abs(before["y"] - 7.0) < 0.05 and abs(before["theta"] - 2.1) < 0.05
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    calls = [e for e in events if e["event"] == "service_call"]
    assert [c["service"] for c in calls] == ["/turtle1/teleport_absolute"]
    # the driver recorded its client's id, and the simulator's event of the call names the same
    # DDS participant: the placement is the grader's by the call itself (grader.analyze.provenance)
    from grader.analyze import provenance
    assert len(calls[0]["client_gid"]) == 16, calls[0]
    assert [c.by for c in provenance.calls(frames, "/turtle1/teleport_absolute")] == [provenance.GRADER]
    if time_scale > 1:
        # the clock stood still while the action was handed over: every /clock recorded in the
        # first 0.1 s of wall time after the marker carries one time (running, 25 ticks at 4x)
        from rosbags.highlevel import AnyReader
        with AnyReader([tmp_path / "place" / "bag"]) as reader:
            conns = [c for c in reader.connections if c.topic in ("/marker", "/clock")]
            msgs = [(c.topic, t, reader.deserialize(raw, c.msgtype) if c.topic == "/clock" else None)
                    for c, t, raw in reader.messages(connections=conns)]
        marker_wall = next(t for topic, t, _ in msgs if topic == "/marker")
        held = {(m.clock.sec, m.clock.nanosec) for topic, t, m in msgs
                if topic == "/clock" and marker_wall <= t <= marker_wall + 100_000_000}
        assert len(held) == 1, sorted(held)
