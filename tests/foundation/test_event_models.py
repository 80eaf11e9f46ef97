"""grader/contracts/events.py: one model per event kind, built by the driver and read back by
every reader; a field nobody declared is refused where it is emitted, a record that does not
fit its kind is kept but seen by no typed reader, and the analyzers' ``events`` returns models."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pandas as pd
import pytest

from grader.analyze._common import events
from grader.contracts import events as ev

GRADER = Path(__file__).resolve().parents[2] / "grader"


def _frames(*records: dict) -> dict[str, pd.DataFrame]:
    index = pd.Index([100.0 + k for k in range(len(records))], name="t")
    return {"/grader/events": pd.DataFrame({"data": [json.dumps(r) for r in records]}, index=index)}


def test_every_event_kind_has_its_model() -> None:
    assert set(ev.MODELS) == {str(k) for k in ev.Event}
    assert all(model.KIND is not None and str(model.KIND) == kind for kind, model in ev.MODELS.items())


def test_what_the_driver_emits_is_read_back_as_its_model() -> None:
    built = ev.build_event(ev.Event.SERVICE_CALL, 5.0, {"step": "place", "service": "/turtle1/teleport_absolute",
                                                        "type": "turtlesim/srv/TeleportAbsolute",
                                                        "request": {"x": 1.0, "y": 2.0, "theta": 0.0},
                                                        "client_gid": list(range(16))})
    frames = _frames({"event": "service_call", "wall": 5.0, **built.model_dump(exclude={"event", "wall", "t"})})
    (call,) = events(frames, ev.ServiceCall)
    assert isinstance(call, ev.ServiceCall) and call.t == 100.0
    assert call.request["y"] == 2.0 and call.client_gid == list(range(16)) and call.asked_for is None
    assert events(frames, ev.ServiceResponse) == []


def test_a_field_the_model_does_not_declare_is_refused_where_it_is_emitted() -> None:
    with pytest.raises(ev.EventFieldError, match="no field.*'colour'"):
        ev.build_event(ev.Event.STEP_START, 1.0, {"step": "a", "action": "wait", "colour": "red"})


def test_a_record_that_does_not_fit_its_kind_is_kept_but_no_typed_reader_sees_it() -> None:
    frames = _frames({"event": "goal_sent", "goal": "x"}, {"event": "goal_sent", "goal": [1, 2], "step": "g"},
                     {"event": "from_the_future", "what": 1}, "not an object")
    every = events(frames)
    assert [type(e) for e in every] == [ev.EventRecord, ev.GoalSent, ev.EventRecord]
    assert every[2].model_extra == {"what": 1}
    (goal,) = events(frames, ev.GoalSent)
    assert goal.goal == [1.0, 2.0] and goal.step == "g" and goal.topic is None


def test_an_older_recording_reads_with_the_defaults_that_say_what_it_meant() -> None:
    frames = _frames({"event": "graph", "nodes": ["/turtlesim"], "publishers": {"/turtle1/pose": ["turtlesim"]}},
                     {"event": "stdin_line", "process": "goals", "line": "1,2"})
    (graph,) = events(frames, ev.Graph)
    assert graph.running is None and graph.servers is None and graph.subscribers == {}
    (line,) = events(frames, ev.StdinLine)
    assert line.delivered


def test_asking_for_an_event_by_its_name_is_refused() -> None:
    with pytest.raises(TypeError, match="not an event's name"):
        events(_frames({"event": "step_start", "step": "a"}), "step_start")  # type: ignore[call-overload]


def test_events_of_several_kinds_keep_the_bags_order() -> None:
    frames = _frames({"event": "turtles_held", "step": "a", "ok": True}, {"event": "step_start", "step": "b"},
                     {"event": "turtles_released", "step": "a", "ok": True, "held_s": 0.5})
    got = events(frames, (ev.TurtlesHeld, ev.TurtlesReleased))
    assert [type(e) for e in got] == [ev.TurtlesHeld, ev.TurtlesReleased] and got[1].held_s == 0.5


def test_every_reader_asks_for_model_classes() -> None:
    """``events(frames, StepStart)``, never an event's name: what it returns is then typed, and
    mypy checks every attribute a reader uses."""
    offenders = []
    for path in sorted(GRADER.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "events" and len(node.args) >= 2:
                kind = node.args[1]
                names = kind.elts if isinstance(kind, ast.Tuple) else [kind]
                if any(isinstance(n, ast.Constant) or (isinstance(n, ast.Attribute) and
                                                      getattr(n.value, "id", "") == "Event") for n in names):
                    offenders.append(f"{path.relative_to(GRADER)}:{node.lineno}")
    assert offenders == [], "events(frames, <model class>), not an event name"
