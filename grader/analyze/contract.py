"""The contract's names, looked for in a recording: which did the student spell differently?

Pure, like every analyzer: it reads the driver's ``graph`` snapshots (nodes, who publishes,
subscribes and serves what, with the types) and the ``packages`` event (the build's packages,
their executables and launch files) from the bag, so a regrade finds the same.

A name is a *mismatch* only when the student's own name for the same thing is found by
behaviour: the package that holds the nodes, the executable of that package nobody asked for,
the node that serves ``/set_goal``, the topic of the same type their node publishes instead. A
name that is simply absent (the node crashed, the package did not build) is not a contract
problem: the items say what happened.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from grader.analyze._common import Frames, events, meta, norm_type, sim_node
from grader.contracts.contract import (Contract, ExecutableEntry, LaunchEntry, Mismatch, NodeEntry, PackageEntry,
                                       TopicEntry, node_name)
from grader.contracts.events import Graph, Packages

#: topics every node has, and the grader's own
_STANDARD_TOPICS = ("/rosout", "/parameter_events", "/clock")
#: services rclpy gives every node
_NODE_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters", "list_parameters",
                  "set_parameters", "set_parameters_atomically", "get_type_description")


@dataclass
class _Graph:
    """Every snapshot of a scenario's graph together (a node seen once counts)."""

    sim: str = "turtlesim"
    nodes: set[str] = field(default_factory=set)             # full names: /ns/name
    pubs: dict[str, set[str]] = field(default_factory=dict)  # topic -> node names (no namespace)
    subs: dict[str, set[str]] = field(default_factory=dict)
    topic_types: dict[str, set[str]] = field(default_factory=dict)
    services: set[str] = field(default_factory=set)
    servers: dict[str, set[str]] | None = None              # None: an older bag without it
    service_types: dict[str, set[str]] = field(default_factory=dict)

    @classmethod
    def of(cls, frames: Frames) -> "_Graph":
        g = cls(sim=sim_node(frames))
        for e in events(frames, Graph):
            g.nodes |= {node_name(n) for n in e.nodes}
            g.services |= set(e.services)
            for table, target in ((e.publishers, g.pubs), (e.subscribers, g.subs), (e.topic_types, g.topic_types),
                                  (e.service_types, g.service_types)):
                for name, values in table.items():
                    target.setdefault(name, set()).update(str(v) for v in values or [])
            if e.servers is not None:
                g.servers = g.servers or {}
                for name, values in e.servers.items():
                    g.servers.setdefault(name, set()).update(str(v) for v in values or [])
        m = meta(frames)
        if m is not None and "type" in m.columns:        # recorded topics' types (older bags)
            for name, kind in zip(m["topic"], m["type"]):
                g.topic_types.setdefault(str(name), set()).add(str(kind))
        return g

    def grader(self, node: str) -> bool:
        short = node.rsplit("/", 1)[-1]
        return short.startswith(("grader_", "_", "launch_ros_"))

    def student(self, node: str, sim_too: bool = False) -> bool:
        return not self.grader(node) and (sim_too or node.rsplit("/", 1)[-1] != self.sim)

    def users(self, table: dict[str, set[str]], topic: str, sim_too: bool = False) -> set[str]:
        return {n for n in table.get(topic, ()) if self.student(n, sim_too)}

    def of_type(self, topic: str, wanted: str | None, table: dict[str, set[str]]) -> bool:
        types = {norm_type(t) for t in table.get(topic, ())}
        return not wanted or not types or norm_type(wanted) in types


def _facts(frames: Frames) -> dict[str, dict[str, Any]] | None:
    found = events(frames, Packages)
    return found[-1].packages if found else None


def _said(kind: str, expected: str, found: list[str], lead: str, tail: str = "") -> str:
    if len(found) == 1:
        return f"{lead} is called {found[0]}; this lab asks for {expected}{tail}."
    return f"This lab asks for {kind} called {expected}{tail}; yours are called {', '.join(found)}."


def _package(contract: Contract, e: PackageEntry, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    if not facts or e.name in facts:
        return None
    claimed = {p.name for p in contract.packages.values()}
    found = sorted(n for n, f in facts.items() if n not in claimed
                   and (f.get("executables") or f.get("launch_files") or f.get("stray_executables")))
    return (found, _said("a package", e.name, found, "Your package")) if found else None


def _executable(contract: Contract, e: ExecutableEntry, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    f = (facts or {}).get(e.package)
    if not f or f.get("status") != "built" or e.name in (f.get("executables") or []):
        return None
    claimed = {x.name for x in contract.executables.values() if x.package == e.package}
    found = sorted(x for x in f.get("executables") or [] if x not in claimed)
    return (found, _said("an executable", e.name, found, f"Your executable in {e.package}",
                         f" (ros2 run {e.package} {e.name})")) if found else None


def _launch(contract: Contract, e: LaunchEntry, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    f = (facts or {}).get(e.package)
    if not f or e.name in (f.get("launch_files") or []):
        return None
    claimed = {x.name for x in contract.launch_files.values() if x.package == e.package}
    found = sorted(x for x in f.get("launch_files") or [] if x not in claimed)
    return (found, _said("a launch file", e.name, found, f"Your launch file in {e.package}",
                         f" (ros2 launch {e.package} {e.name})")) if found else None


def _node(contract: Contract, e: NodeEntry, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    present = {n for n in g.nodes if not g.grader(n)}
    if e.name in present:
        return None
    claimed = {x.name for x in contract.nodes.values()}
    related = bool(e.publishes or e.subscribes or e.serves)
    if e.serves and g.servers is None:
        return None                       # an older bag: who serves what was not recorded

    def does(node: str) -> bool:
        short = node.rsplit("/", 1)[-1]
        return (all(short in g.pubs.get(t, ()) for t in e.publishes)
                and all(short in g.subs.get(t, ()) for t in e.subscribes)
                and all(short in (g.servers or {}).get(s, set()) | (g.servers or {}).get(s + "/_action/send_goal", set())
                        for s in e.serves))

    found = sorted(n for n in present if n not in claimed and g.student(n, sim_too=related) and does(n))
    if not found:
        return None
    rel = "; ".join([*(f"publishes {t}" for t in e.publishes), *(f"subscribes to {t}" for t in e.subscribes),
                     *(f"serves {s}" for s in e.serves)])
    return found, _said("a node", e.name, found, f"Your node that {rel}" if rel else "Your node")


def _topic(contract: Contract, e: TopicEntry, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    claimed = {x.name for x in contract.topics.values()}

    def free(topic: str) -> bool:
        return (topic not in claimed and not topic.startswith(("/grader/",)) and topic not in _STANDARD_TOPICS
                and "/_action/" not in topic and not topic.endswith("/_service_event")
                and not ({g.sim} & (g.pubs.get(topic, set()) | g.subs.get(topic, set())))
                and g.of_type(topic, e.type, g.topic_types))

    grader_publishes = any(g.grader(n) for n in g.pubs.get(e.name, ()))
    if not grader_publishes and not g.users(g.pubs, e.name, sim_too=True):
        found = sorted(t for t in g.pubs if free(t) and g.users(g.pubs, t))
        if found:
            return found, _said("a topic", e.name, found, "The topic your node publishes")
    if g.pubs.get(e.name) and not g.users(g.subs, e.name, sim_too=True):
        found = sorted(t for t in g.subs if free(t) and g.users(g.subs, t) and not g.pubs.get(t))
        if found:
            return found, _said("a topic", e.name, found, "The topic your node subscribes to")
    return None


def _served(g: _Graph) -> dict[str, set[str]]:
    return {s: {n for n in nodes if g.student(n)} for s, nodes in (g.servers or {}).items()
            if any(g.student(n) for n in nodes)}


def _service(contract: Contract, e: Any, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    if g.servers is None or e.name in _served(g):
        return None
    claimed = {x.name for x in contract.services.values()}
    found = sorted(s for s in _served(g) if s not in claimed and "/_action/" not in s
                   and s.rsplit("/", 1)[-1] not in _NODE_SERVICES and g.of_type(s, e.type, g.service_types))
    return (found, _said("a service", e.name, found, "Your service")) if found else None


def _action(contract: Contract, e: Any, g: _Graph, facts: dict | None) -> tuple[list[str], str] | None:
    suffix = "/_action/send_goal"
    if g.servers is None or e.name + suffix in _served(g):
        return None
    claimed = {x.name for x in contract.actions.values()}
    goal_type = f"{e.type}_SendGoal" if e.type else None      # the hidden service's type
    found = sorted(s[: -len(suffix)] for s in _served(g) if s.endswith(suffix) and s[: -len(suffix)] not in claimed
                   and (not goal_type or g.of_type(s, goal_type, g.service_types)))
    return (found, _said("an action", e.name, found, "Your action")) if found else None


_CHECKS = {"packages": _package, "executables": _executable, "launch_files": _launch, "nodes": _node,
           "topics": _topic, "services": _service, "actions": _action}


def check_contract(contract: Contract, roles: set[str], frames: Frames) -> list[Mismatch]:
    """The contract names among ``roles`` that this recording shows under another name."""
    if not contract or not roles:
        return []
    graph, facts = _Graph.of(frames), _facts(frames)
    out = []
    for kind, role, entry in contract.entries():
        if role not in roles:
            continue
        hit = _CHECKS[kind](contract, entry, graph, facts)      # type: ignore[operator]
        if hit:
            found, text = hit
            out.append(Mismatch(role=role, kind=kind, expected=entry.name, found=tuple(found), feedback=text))
    return out
