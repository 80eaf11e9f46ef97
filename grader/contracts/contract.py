"""A lab's contract as a model: the names students must use exactly, each under a role id (the
rubric's ``contract:`` section, explained in ``grader.rubric.contract``), and a :class:`Mismatch`,
a contract name the student spelt differently. The ground floor: the rubric loads a contract, the
analyzers look its names up in a recording, scoring blocks items by its mismatches and the report
prints them, all with these classes."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Annotated, Iterator, Mapping, overload

from pydantic import Field, field_validator, model_validator

from grader.contracts.fields import (ActionType, ExecutableName, LaunchFile, Model, MsgType, PackageName,
                                     RosName, SrvType)
from grader.contracts.text import pattern_text
from grader.contracts.values import JsonValue

Role = Annotated[str, pattern_text(r"^[a-z][a-z0-9_]*$", "a role id like news or greeter (lower case, digits, _)")]
Why = Annotated[str, Field(min_length=1, pattern=r"\S", description="where the lab text fixes it")]

#: a whole value ``$role``, and ``${role}`` inside text
REF = re.compile(r"^\$([a-z][a-z0-9_]*)$")
TEXT_REF = re.compile(r"\$\{([a-z][a-z0-9_]*)\}")

KINDS = ("packages", "executables", "nodes", "topics", "services", "actions", "launch_files")
#: one entry of each kind, in words ("a topic")
WHAT = {"packages": "package", "executables": "executable", "nodes": "node", "topics": "topic",
        "services": "service", "actions": "action", "launch_files": "launch file"}


@overload
def _short(value: str | dict[str, JsonValue]) -> dict[str, JsonValue]: ...
@overload
def _short(value: object) -> object: ...
def _short(value: object) -> object:
    """``news: /robot_news`` is ``news: {name: /robot_news}``."""
    return {"name": value} if isinstance(value, str) else value


def _a(what: str) -> str:
    return ("an " if what[0] in "aeiou" else "a ") + what


def node_name(name: str) -> str:
    """``my_first_node`` and ``/my_first_node`` name the same node (ROS adds the ``/``)."""
    return "/" + str(name).strip().strip("/")


class _Entry(Model):
    why: Why | None = Field(None, description="where the lab text (or the course) fixes it")

    @model_validator(mode="before")
    @classmethod
    def _plain(cls, value: object) -> object:
        return _short(value)


class PackageEntry(_Entry):
    """A ROS package the students create under this name (``ros2 pkg create NAME``)."""

    name: PackageName


class ExecutableEntry(_Entry):
    """An executable of a package (``ros2 run PACKAGE NAME``)."""

    name: ExecutableName
    package: PackageName = Field(description="its package (a name or $role of a package)")


class NodeEntry(_Entry):
    """A node name (``ros2 node list``). ``publishes``/``subscribes``/``serves`` say how to find the
    student's node when it has another name (the node that serves /set_goal)."""

    name: RosName
    publishes: Annotated[tuple[RosName, ...], Field(strict=False)] = Field(
        (), description="topics the node publishes (names or $roles)")
    subscribes: Annotated[tuple[RosName, ...], Field(strict=False)] = Field(
        (), description="topics the node subscribes to")
    serves: Annotated[tuple[RosName, ...], Field(strict=False)] = Field(
        (), description="services or actions the node offers")

    @field_validator("name")
    @classmethod
    def _absolute(cls, name: str) -> str:
        return node_name(name)

    @field_validator("publishes", "subscribes", "serves", mode="before")
    @classmethod
    def _one(cls, value: object) -> object:
        return [value] if isinstance(value, str) else value


class TopicEntry(_Entry):
    """A topic a student node publishes or subscribes (and its type, when the lab fixes it)."""

    name: RosName
    type: MsgType | None = Field(None, description="its message type, when the lab fixes it")


class ServiceEntry(_Entry):
    """A service a student node offers."""

    name: RosName
    type: SrvType | None = Field(None, description="its service type, when the lab fixes it")


class ActionEntry(_Entry):
    """An action a student node serves."""

    name: RosName
    type: ActionType | None = Field(None, description="its action type, when the lab fixes it")


class LaunchEntry(_Entry):
    """A launch file of a package (``ros2 launch PACKAGE NAME``)."""

    name: LaunchFile
    package: PackageName = Field(description="its package (a name or $role of a package)")


Entry = PackageEntry | ExecutableEntry | NodeEntry | TopicEntry | ServiceEntry | ActionEntry | LaunchEntry


class Contract(Model):
    """What students must name exactly, each under a role id (unique across the kinds)."""

    packages: dict[Role, PackageEntry] = {}
    executables: dict[Role, ExecutableEntry] = {}
    nodes: dict[Role, NodeEntry] = {}
    topics: dict[Role, TopicEntry] = {}
    services: dict[Role, ServiceEntry] = {}
    actions: dict[Role, ActionEntry] = {}
    launch_files: dict[Role, LaunchEntry] = {}

    def entries(self) -> Iterator[tuple[str, str, Entry]]:
        """``(kind, role, entry)`` in declaration order, kind by kind."""
        for kind in KINDS:
            for role, entry in getattr(self, kind).items():
                yield kind, role, entry

    def __bool__(self) -> bool:
        return any(True for _ in self.entries())

    def lines(self) -> list[tuple[str, str, str, str]]:
        """``(what, name, how it is used, why)`` per entry, for ``grader check`` and the guide."""
        out = []
        for kind, _role, e in self.entries():
            use = ""
            if isinstance(e, ExecutableEntry):
                use = f"ros2 run {e.package} {e.name}"
            elif isinstance(e, LaunchEntry):
                use = f"ros2 launch {e.package} {e.name}"
            elif isinstance(e, NodeEntry):
                use = "; ".join([*(f"publishes {t}" for t in e.publishes), *(f"subscribes to {t}" for t in e.subscribes),
                                 *(f"serves {t}" for t in e.serves)])
            elif getattr(e, "type", None):
                use = str(e.type)   # type: ignore[union-attr]
            out.append((WHAT[kind], e.name, use, e.why or ""))
        return out


# ----------------------------------------------------------------------------------- mismatches
@dataclass(frozen=True)
class Mismatch:
    """A contract name the student spelt differently: one finding, naming both names.

    ``found``: the student's name(s) found by behaviour; ``scenarios``: the recordings it was
    seen in; ``blocks``: the items it blocked (filled in by scoring)."""

    role: str
    kind: str
    expected: str
    found: tuple[str, ...]
    feedback: str
    scenarios: tuple[str, ...] = ()
    blocks: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, JsonValue]:
        return {"role": self.role, "kind": self.kind, "expected": self.expected, "found": list(self.found),
                "feedback": self.feedback, "scenarios": list(self.scenarios), "blocks": list(self.blocks)}

    @classmethod
    def from_dict(cls, d: Mapping[str, JsonValue]) -> "Mismatch":
        return cls(role=str(d.get("role", "")), kind=str(d.get("kind", "")), expected=str(d.get("expected", "")),
                   found=tuple(d.get("found") or ()), feedback=str(d.get("feedback", "")),
                   scenarios=tuple(d.get("scenarios") or ()), blocks=tuple(d.get("blocks") or ()))
