"""What a scenario makes before its first step: a DDS entity made at the moment of use still has
to be discovered, and in lockstep the clock ticks while it is (issue 22)."""

from __future__ import annotations

from typing import Any

from grader.scenario import Scenario, resolve
from grader.scenario.steps import Runtime, prepare


class _Made:
    """Stands in for the driver's factories (no ROS here): notes what ``prepare`` asks for."""

    def __init__(self) -> None:
        self.clients: list[tuple[str, str]] = []
        self.other: list[str] = []

    def service_client(self, cls: Any, name: str) -> None:
        self.clients.append((name, f"{cls.__module__}.{cls.__qualname__}"))

    def __getattr__(self, name: str) -> Any:
        return lambda *args, **kwargs: self.other.append(name)


def test_placements_and_typed_service_steps_get_their_clients_before_the_scenario() -> None:
    scenario = Scenario.model_validate({
        "steps": [{"id": "placed", "place": {"x": 2.0, "y": 7.0, "theta": 2.1},
                   "publish": {"topic": "/marker", "type": "std_msgs/msg/Empty"}, "timeout": 0.2},
                  {"id": "pen", "service": {"name": "/turtle1/set_pen", "type": "turtlesim/srv/SetPen",
                                            "request": {"r": 255}}, "timeout": 2},
                  {"id": "untyped", "service": {"name": "/whatever"}, "timeout": 2}],
        "limits": {"wall_s": 60}})
    made = _Made()
    prepare(Runtime(made, resolve("prep", scenario, None), lambda name: [], {}))   # type: ignore[arg-type]
    assert ("/turtle1/teleport_absolute", "turtlesim.srv._teleport_absolute.TeleportAbsolute") in made.clients
    assert ("/turtle1/set_pen", "turtlesim.srv._set_pen.SetPen") in made.clients
    # a service step without a type is looked up in the graph when it runs: no client before
    assert [name for name, _ in made.clients] == ["/turtle1/teleport_absolute", "/turtle1/set_pen"]
    assert {"watch_pose", "watch_commands", "publisher"} <= set(made.other)
