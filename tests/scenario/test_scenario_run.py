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
    import resource

    from grader.scenario import children_cpu_s

    counted, reaped = children_cpu_s(), resource.getrusage(resource.RUSAGE_CHILDREN)
    record = run_scenario(resolve("drive", scenario, None), tmp_path / "drive").to_json()
    assert record["errors"] == [], record
    # the scenario child's CPU and its processes' (simulator, recorder) is this thread's to read:
    # what the kernel says every child of this test process used
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    used = (after.ru_utime - reaped.ru_utime) + (after.ru_stime - reaped.ru_stime)
    assert used > 0.5 and children_cpu_s() - counted == pytest.approx(used, abs=0.05)
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
    assert names[0] == "scenario_start" and "service_call" in names and names[-2:] == ["scenario_end", "turtles_held"]
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


def test_a_placement_whose_spawn_finds_the_name_taken_teleports_the_turtle() -> None:
    """The driver had no pose of turtle2 yet, but the student's node had made it: turtlesim
    answers the grader's /spawn with no name, and the turtle is then placed by its teleport."""
    from types import SimpleNamespace

    from grader.scenario import model as m
    from grader.scenario.placement import _place

    class Driver:
        poses: dict = {}

        def pose_mark(self, topic: str) -> int:
            return 0

        def poses_since(self, topic: str, start: int) -> list:
            return [SimpleNamespace(x=2.0, y=3.0, theta=1.0)]

        def wait_until(self, predicate, *args, **kwargs) -> bool:
            return predicate()

    calls: list[str] = []

    def call(rt, step, spec: m.ServiceCall, state) -> dict:
        calls.append(spec.name)
        return {"response": {"name": ""} if spec.name == "/spawn" else {}}

    place = m.Placement(turtle="turtle2", x=2.0, y=3.0, theta=1.0, spawn=True)
    step = m.Step.model_validate({"id": "a", "place": place.model_dump(), "timeout": 1.0})
    out = _place(SimpleNamespace(driver=Driver()), step, place, SimpleNamespace(service_done=True), call)
    assert calls == ["/spawn", "/turtle2/teleport_absolute"]
    assert out["spawned"] is False and out["shown"] is True


@pytest.mark.ros
@pytest.mark.slow
def test_a_placement_with_spawn_makes_a_missing_turtle_there(tmp_path: Path) -> None:
    """`place: {turtle: turtle2, spawn: true}` spawns turtle2 at the placement when the
    simulator has published no pose of it (the student's node did not make it), and teleports it
    once it exists; the calls are the driver's. Without `spawn`, a missing turtle is not placed
    (its teleport service does not exist), and nothing is spawned."""
    from grader.bag.frames import load_frames

    def place(step: str, x: float, spawn: bool) -> dict:
        return {"id": step, "place": {"turtle": "turtle2", "x": x, "y": 3.0, "theta": 1.0, "spawn": spawn},
                "publish": {"topic": "/marker", "type": "std_msgs/msg/Empty"}, "timeout": 0.2}

    scenario = Scenario.model_validate({"steps": [place("first", 2.0, True), place("again", 4.0, True)],
                                        "limits": {"wall_s": 30}, "lockstep": True})
    run = resolve("spawn", scenario, None).model_copy(update={"lockstep": True})
    record = run_scenario(run, tmp_path / "spawn").to_json()
    assert record["errors"] == [] and record["lockstep"]["used"] and "fallback" not in record["lockstep"], record
    first, again = (s["detail"]["placed"] for s in record["steps"])
    assert first["spawned"] is True and first["shown"] is True
    assert again["spawned"] is False and again["shown"] is True
    assert again["seen"] == pytest.approx([4.0, 3.0, 1.0], abs=1e-4)
    frames = load_frames(tmp_path / "spawn" / "bag")
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    calls = [e for e in events if e["event"] == "service_call"]
    assert [c["service"] for c in calls] == ["/spawn", "/turtle2/teleport_absolute"]
    assert calls[0]["request"]["name"] == "turtle2"
    truth = frames["/grader/sim/turtle2/pose"]
    assert ((truth["x"] - 2.0).abs() < 1e-4).any() and ((truth["x"] - 4.0).abs() < 1e-4).any()

    without = Scenario.model_validate({"steps": [place("first", 2.0, False)], "limits": {"wall_s": 30},
                                       "lockstep": True})
    record = run_scenario(resolve("nospawn", without, None).model_copy(update={"lockstep": True}),
                          tmp_path / "nospawn").to_json()
    placed = record["steps"][0]["detail"]["placed"]
    assert placed["spawned"] is False and placed["shown"] is False
    frames = load_frames(tmp_path / "nospawn" / "bag")
    services = [json.loads(d).get("service") for d in frames["/grader/events"]["data"]]
    assert "/spawn" not in services
    assert "/grader/sim/turtle2/pose" not in frames or len(frames["/grader/sim/turtle2/pose"]) == 0


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize("time_scale", [1.0, 4.0])
def test_place_puts_the_turtle_there_before_the_action(tmp_path: Path, time_scale: float) -> None:
    """`place:` holds the (moving) turtle still, teleports it, goes on with the action once the
    simulator shows it there, and releases it only after the hand-over: the simulator's poses
    from the teleport on are the placement itself, tick after tick, until the release. The
    teleport is recorded as the driver's own service call. (Before the hold, the turtle moved on
    with its last command between the teleport and the action, by a different amount each run.)"""
    from grader.scenario.placement import PLACE_HANDOFF_S

    scenario = Scenario.model_validate({"steps": [
        {"id": "go", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                 "msg": {"linear": {"x": 1.0}, "angular": {"z": 0.5}}}, "timeout": 0.5},
        {"id": "placed", "place": {"x": 2.0, "y": 7.0, "theta": 2.1},
         "publish": {"topic": "/marker", "type": "std_msgs/msg/Empty"}, "timeout": 0.2},
    ], "limits": {"wall_s": 30}})
    run = resolve("place", scenario, None).model_copy(update={"time_scale": time_scale})
    record = run_scenario(run, tmp_path / "place").to_json()
    assert record["errors"] == [], record
    placed = record["steps"][1]["detail"]["placed"]
    assert placed["pose"] == [2.0, 7.0, 2.1] and placed["shown"] is True
    assert placed["seen"] == pytest.approx([2.0, 7.0, 2.1], abs=1e-5)      # held: exactly there
    from grader.bag.frames import load_frames
    frames = load_frames(tmp_path / "place" / "bag")
    truth = frames["/grader/sim/turtle1/pose"]
    at = ((truth["x"] - 2.0).abs() < 1e-5) & ((truth["y"] - 7.0).abs() < 1e-5) & ((truth["theta"] - 2.1).abs() < 1e-5)
    assert at.any() and (truth["linear_velocity"][at] == 0).all() and (truth["angular_velocity"][at] == 0).all()
    first = int(at.to_numpy().argmax())
    run_len = int(at.to_numpy()[first:].argmin()) if not at.to_numpy()[first:].all() else int(at.sum())
    # one unbroken stretch of the placement, at least the hand-over long (16 ms ticks of
    # scenario time), and nothing between the pose before the teleport and the placement
    assert run_len >= int(PLACE_HANDOFF_S / 0.016) - 1 and run_len == int(at.sum()), (run_len, int(at.sum()))
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    order = [e["event"] for e in events if e["event"] in ("turtles_held", "service_call", "message_sent",
                                                         "turtles_released")]
    # ... and held again at the scenario's end (test_the_turtle_is_held_at_the_scenarios_end)
    assert order == ["message_sent", "turtles_held", "service_call", "message_sent", "turtles_released",
                     "turtles_held"]
    assert all(e["ok"] for e in events if e["event"] in ("turtles_held", "turtles_released"))
    calls = [e for e in events if e["event"] == "service_call"]
    assert [c["service"] for c in calls] == ["/turtle1/teleport_absolute"]
    # the driver recorded its client's id, and the simulator's event of the call names the same
    # DDS participant: the placement is the grader's by the call itself (grader.analyze.provenance)
    from grader.analyze import provenance
    assert len(calls[0]["client_gid"]) == 16, calls[0]
    assert [c.by for c in provenance.calls(frames, "/turtle1/teleport_absolute")] == [provenance.GRADER]


@pytest.mark.ros
def test_the_turtle_is_held_at_the_scenarios_end(tmp_path: Path) -> None:
    """Once the scenario is over the simulator holds the turtle still before the student's
    processes are stopped: a turtle still driving would otherwise coast on its last command for
    turtlesim's 1 s command timeout, by however far the shutdown took, and draw that on the
    canvas a grade reads (a canvas item got 2.5, 5 and 2.5 points for the same code)."""
    import numpy as np

    from grader.analyze._common import events
    from grader.bag.frames import load_frames
    from grader.contracts.events import ScenarioEnd, TurtlesHeld

    scenario = Scenario.model_validate({"steps": [
        {"id": "drive", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                    "msg": {"linear": {"x": 1.0}}, "count": 15, "rate_hz": 10}, "timeout": 1.5},
    ], "limits": {"wall_s": 30}})
    record = run_scenario(resolve("end", scenario, None), tmp_path / "end").to_json()
    assert record["errors"] == [], record
    frames = load_frames(tmp_path / "end" / "bag")
    t_end = events(frames, ScenarioEnd)[0].t
    truth = frames["/grader/sim_record/turtle1/pose"]
    t = truth.index.to_numpy(float)
    x = truth["x"].to_numpy(float)
    assert x[t < t_end].max() > 6.5                   # it was driving at 1 m/s when the scenario ended
    after = t > t_end + 0.15                          # the hold's call and the next tick
    assert after.sum() >= 3, "the simulator recorded poses after the scenario's end"
    assert np.ptp(x[after]) == 0.0 and (truth["linear_velocity"].to_numpy(float)[after] == 0).all(), \
        f"the turtle went on {np.ptp(x[after]):.3f} m after the scenario's end"
    held = events(frames, TurtlesHeld)
    assert [(e.step, e.ok) for e in held] == [("scenario_end", True)]


@pytest.mark.ros
def test_a_scenario_starts_only_once_the_simulators_poses_are_recorded(tmp_path: Path, monkeypatch) -> None:
    """The recorder is a DDS participant of its own: on a loaded machine it can discover the
    simulator up to ~1 s after the driver does. A scenario whose student code cannot start ends
    ~0.5 s later (``make demo``: goal_setter's handout had no pose in its bag, and its pose
    integrity check could not run). Here the recorder is made to see the simulator's topics 2 s
    late; the scenario still records its poses from the start. (Fails without the wait.)"""
    import time

    from grader.bag.frames import load_frames
    from grader.bag.recorder import Recorder
    from grader.scenario import run as scenario_run

    for key in scenario_run.DISCOVERY_ENV:          # run_scenario_here sets them for its own nodes
        monkeypatch.delenv(key, raising=False)
    t0 = time.monotonic()
    wanted = Recorder.wanted

    def late(self, topic: str) -> bool:
        if "turtle1/" in topic and time.monotonic() - t0 < 2.0:
            return False
        return wanted(self, topic)

    monkeypatch.setattr(Recorder, "wanted", late)
    scenario = Scenario.model_validate({"steps": [{"id": "short", "wait": 0.1}], "limits": {"wall_s": 30}})
    record = scenario_run.run_scenario_here(resolve("late", scenario, None), tmp_path / "late")
    assert record["errors"] == [], record
    frames = load_frames(tmp_path / "late" / "bag")
    events = [json.loads(d) for d in frames["/grader/events"]["data"]]
    start = next(e["wall"] for e in events if e["event"] == "scenario_start")
    for name in ("/turtle1/pose", "/grader/sim/turtle1/pose"):
        assert name in frames and len(frames[name]) > 0, name
        assert frames[name].index[0] <= start, name      # recorded before the scenario began


def _late_recorder(monkeypatch: pytest.MonkeyPatch, late_topic: str, delay_s: float) -> None:
    """The scenario's recorder (in this process) subscribes to ``late_topic`` only ``delay_s``
    after its first sight of it (not after the test's start: on a loaded machine the start-up
    alone took longer than that): a loaded machine's discovery, exaggerated."""
    import time

    from grader.bag.recorder import Recorder
    from grader.scenario import run as scenario_run

    for key in scenario_run.DISCOVERY_ENV:
        monkeypatch.delenv(key, raising=False)
    wanted = Recorder.wanted
    first: list[float] = []

    def late(self, topic: str) -> bool:
        if topic == late_topic:
            first[:] = first or [time.monotonic()]
            if time.monotonic() - first[0] < delay_s:
                return False
        return wanted(self, topic)

    monkeypatch.setattr(Recorder, "wanted", late)


@pytest.mark.ros
def test_a_placement_waits_until_the_commands_are_recorded(tmp_path: Path, monkeypatch) -> None:
    """A placed step right after a controller's start-up: the recorder (another DDS participant)
    may match the controller's command publisher up to ~1 s after the driver does, and the
    commands computed during the hand-over were then missing from the bag (wrong_sign's goal 1
    judged from a command sent after the release: the short way, once). Here the recorder is made
    to see /turtle1/cmd_vel 1 s late; the placed step waits for it, and the command sent during
    the placement is in the bag. (Fails without the wait: the bag has no command.)"""
    from grader.bag.frames import load_frames
    from grader.scenario import run as scenario_run

    _late_recorder(monkeypatch, "/turtle1/cmd_vel", 1.0)
    scenario = Scenario.model_validate({"steps": [
        {"id": "placed", "place": {"x": 2.0, "y": 7.0, "theta": 2.1},
         "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                     "msg": {"angular": {"z": 0.5}}}, "timeout": 0.2},
    ], "limits": {"wall_s": 30}})
    record = scenario_run.run_scenario_here(resolve("heard", scenario, None), tmp_path / "heard")
    assert record["errors"] == [], record
    placed = record["steps"][0]["detail"]["placed"]
    assert placed["commands_heard"] is True and placed["heard_after_s"] > 0.3, placed
    frames = load_frames(tmp_path / "heard" / "bag")
    assert "/turtle1/cmd_vel" in frames and len(frames["/turtle1/cmd_vel"]) == 1
    assert frames["/turtle1/cmd_vel"]["angular.z"].iloc[0] == 0.5


@pytest.mark.ros
def test_a_line_logged_in_a_constructor_is_recorded_when_the_recorder_is_late(pacing_build, tmp_path: Path,
                                                                               monkeypatch) -> None:
    """A node that logs once, in its constructor (first_nodes' greeter): /rosout keeps the line
    for a late subscriber, but not once the node has stopped. Here the recorder subscribes to
    /rosout 8 s after it first sees the topic (a loaded machine's discovery, exaggerated); the
    process start waits until the recorder has matched every /rosout publisher, so the line is
    in the bag. (Fails without that wait: the scenario ends, and the node stops, before.)"""
    from grader.bag.frames import load_frames
    from grader.scenario import run as scenario_run

    _late_recorder(monkeypatch, "/rosout", 8.0)
    scenario = Scenario.model_validate({
        "sim": False, "processes": [{"name": "ticker", "package": "pacers", "executable": "timer_node"}],
        "steps": [{"id": "idle", "wait": 0.5}], "limits": {"wall_s": 60}})
    record = scenario_run.run_scenario_here(resolve("logged", scenario, pacing_build), tmp_path / "logged")
    assert record["errors"] == [], record
    rosout = load_frames(tmp_path / "logged" / "bag").get("/rosout")
    assert rosout is not None and (rosout["msg"] == "ticker up").sum() == 1, rosout


@pytest.mark.ros
def test_a_turtle_at_a_fixed_point_ends_its_goal_step_early(tmp_path: Path) -> None:
    """``give_up_still``: the turtle, sent one command, moves for turtlesim's 1 s command timeout
    and then stands still with that command unchanged, away from the goal: the step ends
    ``decided`` about 2 s later (not after its 30 s), the record says why; without the option
    the same step waits for its whole limit."""
    def steps(give_up: float | None, timeout: float) -> dict:
        until = {"condition": "goal_reached", "goal": [9.0, 9.0], "tolerance": 0.1}
        if give_up is not None:
            until["give_up_still"] = give_up
        return Scenario.model_validate({"steps": [
            {"id": "go", "publish": {"topic": "/turtle1/cmd_vel", "type": "geometry_msgs/msg/Twist",
                                     "msg": {"linear": {"x": 1.0}}}, "timeout": 0.2},
            {"id": "reach", "until": until, "timeout": timeout},
        ], "limits": {"wall_s": 60}})

    record = run_scenario(resolve("still", steps(2.0, 30.0), None), tmp_path / "still").to_json()
    assert record["errors"] == [], record
    reach = record["steps"][1]
    assert reach["ended_by"] == "decided", reach
    assert 2.0 <= reach["duration_s"] <= 6.0, reach
    assert "stood still" in reach["detail"]["ended_early"] and "give_up_still" in reach["detail"]["ended_early"]
    waited = run_scenario(resolve("waited", steps(None, 4.0), None), tmp_path / "waited").steps[1].to_json()
    assert waited["ended_by"] == "timeout" and waited["duration_s"] >= 4.0, waited
