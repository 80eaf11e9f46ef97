"""Field types and the strict base model of the scenario language (``grader.scenario.model``).

Names (topics, packages, types...) are constrained strings whose errors say what was expected
("a ROS name like /turtle1/pose") instead of a regular expression; :class:`Model` is frozen,
strict and closed to unknown keys; :func:`with_rules` reports a model's own rules together with
its field errors. ``Goal`` sits here because steps and conditions both use it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Union

from pydantic import BaseModel, ConfigDict, Field, model_validator

from grader.contracts.text import pattern_text
from pydantic import ValidationError, ValidatorFunctionWrapHandler
from pydantic_core import InitErrorDetails, PydanticCustomError

RosName = Annotated[str, pattern_text(r"^~?/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$", "a ROS name like /turtle1/pose")]
PackageName = Annotated[str, pattern_text(r"^[a-z][a-z0-9_]*$", "a ROS package name (lower case, digits, _)")]
ExecutableName = Annotated[str, pattern_text(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$", "an executable name")]
EntryPoint = Annotated[str, pattern_text(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*(:[A-Za-z_]\w*)?$",
                    "a Python entry point 'package.module:function'")]
LaunchFile = Annotated[str, pattern_text(r"^[A-Za-z0-9_*?][A-Za-z0-9_.*?-]*$",
                    "a launch file name like app.launch.py, or a pattern like *launch.py")]
LocalId = Annotated[str, pattern_text(r"^[A-Za-z][A-Za-z0-9_-]*$", "an id (letters, digits, _ or -)")]
EnvName = Annotated[str, pattern_text(r"^[A-Za-z_][A-Za-z0-9_]*$", "an environment variable name")]
MsgType = Annotated[str, pattern_text(r"^[A-Za-z][A-Za-z0-9_]*/msg/[A-Z][A-Za-z0-9]*$", "a message type like std_msgs/msg/String")]
SrvType = Annotated[str, pattern_text(r"^[A-Za-z][A-Za-z0-9_]*/srv/[A-Z][A-Za-z0-9]*$", "a service type like turtlesim/srv/SetPen")]
ActionType = Annotated[str, pattern_text(r"^[A-Za-z][A-Za-z0-9_]*/action/[A-Z][A-Za-z0-9]*$",
                    "an action type like turtlesim/action/RotateAbsolute")]
#: sequences and paths accept what YAML/JSON give (lists, text); their items stay strict
LaxPath = Annotated[Path, Field(strict=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
PositiveInt = Annotated[int, Field(gt=0)]
ParamScalar = Union[bool, int, float, str]
ParamValue = Union[bool, int, float, str, list[bool], list[int], list[float], list[str]]

#: the grader's own processes; rubric processes may not take these names
RESERVED_PROCESSES = ("sim", "recorder", "driver")
#: where ``goal:`` steps may publish, and how [x, y] fills each type
GOAL_TYPES = ("std_msgs/msg/Float32MultiArray", "geometry_msgs/msg/Point", "geometry_msgs/msg/Pose2D")


class Model(BaseModel):
    """Frozen, no unknown keys, strict types (a quoted number is text, ``yes`` is not 1)."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


def with_rules(cls: type, handler: ValidatorFunctionWrapHandler, value: object,
               own: list[tuple[tuple, str]]) -> object:
    """Run a wrap validator's ``handler`` and report ``own`` problems (``(loc, message)``, loc
    relative to the model) together with the field errors, so a user sees every problem at once."""
    errors: list[InitErrorDetails] = []
    result = None
    try:
        result = handler(value)
    except ValidationError as exc:
        for err in exc.errors():
            detail: dict[str, object] = {"type": err["type"], "loc": err["loc"], "input": err.get("input")}
            if err["type"] in ("value_error", "assertion_error", "rule"):
                detail["type"] = PydanticCustomError("rule", _braces(err["msg"].removeprefix("Value error, ")))
            elif "ctx" in err:
                detail["ctx"] = err["ctx"]
            errors.append(detail)  # type: ignore[arg-type]
    known = {tuple(e["loc"]) for e in errors}
    for loc, message in own:
        if loc not in known:
            errors.append({"type": PydanticCustomError("rule", _braces(message)), "loc": loc,
                           "input": value.get(loc[0]) if loc and isinstance(value, dict) else value})
    if errors:
        raise ValidationError.from_exception_data(cls.__name__, errors)
    return result


def _braces(message: str) -> str:
    """A message as a pydantic template: literal braces doubled."""
    return message.replace("{", "{{").replace("}", "}}")


# ---------------------------------------------------------------------------------------- leaves
class Goal(Model):
    """A position ``[x, y]`` or ``{x: .., y: ..}`` (m, turtlesim world frame)."""

    x: Annotated[float, Field(allow_inf_nan=False, description="m")]
    y: Annotated[float, Field(allow_inf_nan=False, description="m")]

    @model_validator(mode="before")
    @classmethod
    def _pair(cls, value: object) -> object:
        if isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise ValueError(f"expected a position [x, y] or {{x: .., y: ..}}, got a list of {len(value)}")
            return {"x": value[0], "y": value[1]}
        return value

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x, self.y)
