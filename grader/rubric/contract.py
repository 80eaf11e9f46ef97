"""A lab's contract: the names students must use exactly, declared once per rubric.

A lab text fixes some names (Lab 3's package ``random_numbers`` and topic ``/random_numbers``,
the goal-setter's ``/set_goal`` service and its nodes' names in the launch file) and leaves the
others open (what the subscriber node is called, which launch file starts the application).
The rubric's ``contract:`` section lists the first kind, each under a role id; everything else
is found by behaviour (the node that subscribes to ``/robot_news``, whatever it is called).

* The rubric refers to a contract name as ``$role`` (a whole value, e.g. ``topic: $news``) or
  ``${role}`` inside text (a title, a hint), so each name is written once. The loader resolves
  the references before validating (:func:`resolve_references`); a process naming an
  ``executable: $greeter`` (or ``launch: $app``) takes the package from the contract.
* Which items depend on which names is derived (:func:`item_roles`, :func:`scenario_roles`):
  the names an item's parameters mention, and those its scenario runs or drives.
* After a run, the names are looked for in the recording (``grader.analyze.contract``); a name
  the student spelt differently is one :class:`Mismatch` ("your service is called /setgoal;
  this lab asks for /set_goal"), and the items that depend on it and did not pass are blocked by
  it (``grader.rubric.score``) instead of each failing with a message of its own.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Annotated, Any, Iterable, Iterator, Mapping

from pydantic import Field, field_validator, model_validator

from grader.scenario.fields import (ActionType, ExecutableName, LaunchFile, Model, MsgType, PackageName,
                                    RosName, SrvType)
from grader.contracts.text import pattern_text, suggest

Role = Annotated[str, pattern_text(r"^[a-z][a-z0-9_]*$", "a role id like news or greeter (lower case, digits, _)")]
Why = Annotated[str, Field(min_length=1, pattern=r"\S", description="where the lab text fixes it")]

#: a whole value ``$role``, and ``${role}`` inside text
REF = re.compile(r"^\$([a-z][a-z0-9_]*)$")
TEXT_REF = re.compile(r"\$\{([a-z][a-z0-9_]*)\}")

KINDS = ("packages", "executables", "nodes", "topics", "services", "actions", "launch_files")
#: one entry of each kind, in words ("a topic")
WHAT = {"packages": "package", "executables": "executable", "nodes": "node", "topics": "topic",
        "services": "service", "actions": "action", "launch_files": "launch file"}


def _short(value: Any) -> Any:
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
    def _plain(cls, value: Any) -> Any:
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
    def _one(cls, value: Any) -> Any:
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


# ------------------------------------------------------------------------ references, resolved
#: the contract kind a value under this key must name (``None``: the parent key decides)
_KEY_KIND = {"package": "packages", "executable": "executables", "launch": "launch_files",
             "topic": "topics", "topics": "topics", "goal_topic": "topics", "pose_topic": "topics",
             "cmd_topic": "topics", "action_name": "actions", "nodes": "nodes", "logger": "nodes"}
_NAME_UNDER = {"service": "services", "action": "actions"}


def _expected_kind(path: tuple) -> str | None:
    """The kind a name at ``path`` must be: ``service: {name: $x}`` a service, ``until:
    {condition: advertised, service: $x}`` too, ``package: $x`` a package; None: any."""
    keys = [p for p in path if isinstance(p, str)]
    if not keys:
        return None
    if keys[-1] == "name":
        return _NAME_UNDER.get(keys[-2]) if len(keys) >= 2 else None
    return _NAME_UNDER.get(keys[-1]) or _KEY_KIND.get(keys[-1])


def resolve_references(data: Any) -> tuple[Any, list[tuple[tuple, str]]]:
    """The rubric's raw data with every ``$role`` and ``${role}`` replaced by the contract's name,
    and the problems found, as ``(path, message)``. Unchanged when there is no reference."""
    if not isinstance(data, dict):
        return data, []
    problems: list[tuple[tuple, str]] = []
    raw = data.get("contract")
    contract = raw if isinstance(raw, dict) else {}
    table: dict[str, tuple[str, dict]] = {}     # role -> (kind, raw entry)
    for kind in KINDS:
        group = contract.get(kind)
        if not isinstance(group, dict):
            continue
        for role, entry in group.items():
            if role in table:
                problems.append((("contract", kind, role), f"role {role!r} is already {_a(WHAT[table[role][0]])} "
                                 f"(contract.{table[role][0]}.{role}); a role names one thing"))
                continue
            table[role] = (kind, _short(entry) if isinstance(entry, (str, dict)) else {})
    out = dict(data)
    if contract:
        out["contract"] = _resolve_contract(contract, table, problems)
    for key, value in data.items():
        if key != "contract":
            out[key] = _walk(value, (key,), table, problems)
    return out, problems


def _name_of(role: str, table: dict, path: tuple, problems: list, kinds: tuple[str, ...] | None) -> Any:
    found = table.get(role)
    if found is None:

        known = ", ".join(f"${r}" for r in table) or "none: the rubric has no contract"
        problems.append((path, f"${role} is not in the contract{suggest(role, list(table))} (roles: {known})"))
        return None
    kind, entry = found
    if kinds is not None and kind not in kinds:
        problems.append((path, f"${role} is {_a(WHAT[kind])} of the contract; this key needs "
                         f"{' or '.join(_a(WHAT[k]) for k in kinds)}"))
        return None
    return entry.get("name")


def _resolve_contract(contract: dict, table: dict, problems: list) -> dict:
    """Inside the contract: an executable's or launch file's ``package: $pkg``, and the names a
    node is found by (``serves: $set_goal``)."""
    out = dict(contract)
    for kind, keys in (("executables", {"package": ("packages",)}), ("launch_files", {"package": ("packages",)}),
                       ("nodes", {"publishes": ("topics",), "subscribes": ("topics",), "serves": ("services", "actions")})):
        group = contract.get(kind)
        if not isinstance(group, dict):
            continue
        new_group = {}
        for role, entry in group.items():
            if isinstance(entry, dict):
                entry = dict(entry)
                for key, kinds in keys.items():
                    value = entry.get(key)
                    at = ("contract", kind, role, key)
                    if isinstance(value, str) and (ref := REF.match(value)):
                        entry[key] = _name_of(ref[1], table, at, problems, kinds) or value
                    elif isinstance(value, list):
                        entry[key] = [(_name_of(ref[1], table, at + (i,), problems, kinds) or v)
                                      if isinstance(v, str) and (ref := REF.match(v)) else v
                                      for i, v in enumerate(value)]
                if table.get(role, ("",))[0] == kind:
                    table[role] = (kind, entry)      # a process using it takes the resolved package
            new_group[role] = entry
        out[kind] = new_group
    return out


def _walk(value: Any, path: tuple, table: dict, problems: list) -> Any:
    if isinstance(value, str):
        match = REF.match(value)
        if match:
            kind = _expected_kind(path)
            name = _name_of(match[1], table, path, problems, (kind,) if kind else None)
            return value if name is None else name
        if "${" in value:
            def sub(m: re.Match) -> str:
                name = _name_of(m[1], table, path, problems, None)
                return m[0] if name is None else str(name)
            return TEXT_REF.sub(sub, value)
        return value
    if isinstance(value, list):
        return [_walk(v, path + (i,), table, problems) for i, v in enumerate(value)]
    if isinstance(value, dict):
        out = {k: _walk(v, path + (k,), table, problems) for k, v in value.items()}
        # a process started by a contract executable or launch file takes its package from it
        for key, kind in (("executable", "executables"), ("launch", "launch_files")):
            ref = value.get(key)
            match = REF.match(ref) if isinstance(ref, str) else None
            if match and table.get(match[1], ("",))[0] == kind:
                package = table[match[1]][1].get("package")
                given = out.get("package")
                if given is None:
                    out["package"] = package
                elif given != package:
                    problems.append((path + ("package",), f"${match[1]} is {WHAT[kind]} {out[key]!r} of package "
                                     f"{package!r}; this process says package {given!r} (leave it out)"))
        # a step publishing on, calling or sending to a contract name takes its type from it
        ref_key = {"publish": "topic", "service": "name", "action": "name"}.get(path[-1] if path else "")
        ref = value.get(ref_key) if ref_key else None
        match = REF.match(ref) if isinstance(ref, str) else None
        if match and "type" not in value and table.get(match[1], ("", {}))[1].get("type"):
            out["type"] = table[match[1]][1]["type"]
        # ``until: {condition: advertised, action: $x, by_type: true}`` takes the action's type
        ref = value.get("action") if value.get("condition") == "advertised" and value.get("by_type") else None
        match = REF.match(ref) if isinstance(ref, str) else None
        if match and "action_type" not in value and table.get(match[1], ("", {}))[1].get("type"):
            out["action_type"] = table[match[1]][1]["type"]
        return out
    return value


# ------------------------------------------------------------------------ which items need which
def _strings(value: Any, path: tuple = ()) -> Iterator[tuple[tuple, str]]:
    if isinstance(value, str):
        yield path, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _strings(v, path + (k,))
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            yield from _strings(v, path + (i,))


def _named_roles(contract: Contract, values: Iterable[str]) -> set[str]:
    """Roles of the topics, services, actions and nodes some value names."""
    names = {node_name(v) for v in values if v and not v.startswith("$")}
    out = set()
    for kind in ("topics", "services", "actions", "nodes"):
        for role, entry in getattr(contract, kind).items():
            if node_name(entry.name) in names:
                out.add(role)
    return out


def item_roles(contract: Contract, item: Any) -> set[str]:
    """Contract roles an item's parameters name (a topic it measures, a node it looks for)."""
    if not contract:
        return set()
    return _named_roles(contract, (s for _, s in _strings(dict(item.params))))


def scenario_roles(contract: Contract, scenario: Any) -> set[str]:
    """Contract roles a scenario runs (packages, executables, launch files of its processes) or
    drives (topics, services, actions its steps use)."""
    if not contract:
        return set()
    out: set[str] = set()
    for proc in scenario.processes:
        for role, pkg in contract.packages.items():
            if proc.package == pkg.name:
                out.add(role)
        for role, exe in contract.executables.items():
            if (proc.package, proc.executable) == (exe.package, exe.name):
                out.add(role)
        for role, launch in contract.launch_files.items():
            if (proc.package, proc.launch) == (launch.package, launch.name):
                out.add(role)
    data = scenario.model_dump(mode="json", include={"goal_topic", "steps"})
    return out | _named_roles(contract, (s for _, s in _strings(data)))


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

    def to_dict(self) -> dict[str, Any]:
        return {"role": self.role, "kind": self.kind, "expected": self.expected, "found": list(self.found),
                "feedback": self.feedback, "scenarios": list(self.scenarios), "blocks": list(self.blocks)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Mismatch":
        return cls(role=str(d.get("role", "")), kind=str(d.get("kind", "")), expected=str(d.get("expected", "")),
                   found=tuple(d.get("found") or ()), feedback=str(d.get("feedback", "")),
                   scenarios=tuple(d.get("scenarios") or ()), blocks=tuple(d.get("blocks") or ()))


def merge_mismatches(per_scenario: dict[str, list[Mismatch]]) -> tuple[Mismatch, ...]:
    """One mismatch per role and found name, with every scenario it was seen in."""
    merged: dict[tuple, Mismatch] = {}
    for scenario, found in per_scenario.items():
        for m in found:
            key = (m.role, m.found)
            old = merged.get(key)
            merged[key] = replace(m, scenarios=(*(old.scenarios if old else ()), scenario))
    return tuple(merged.values())

