"""Scenario definitions: what to start, what to send, when each step is over.

A scenario is plain data (it comes from a rubric's ``scenarios:`` section) and crosses a process
boundary as JSON: the parent resolves executables against a build and writes ``spec.json``; the
scenario child (``python -m grader.scenario.run``) executes it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from grader.errors import GraderError


@dataclass
class NodeSpec:
    """A student (or support) executable: by console-script name and/or by ``module:func``."""

    name: str                                   # process name in logs and events
    package: str
    executable: str | None = None
    module: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)
    args: list[str] = field(default_factory=list)
    stdin: bool = False                         # give it a stdin pipe (steps type into it)
    stdin_script: list[list] = field(default_factory=list)   # [[text, delay_s], ...] typed from start
    stdin_close: bool = False                   # EOF after the script (a terminal would not)
    env: dict[str, str] = field(default_factory=dict)
    autostart: bool = True                      # False: a ``start`` step starts it
    wall_s: float | None = None
    cpu_s: int | None = None
    memory_mb: int | None = None
    ready: dict[str, str] = field(default_factory=dict)   # e.g. {"subscriber": "/turtle1/goal"}
    ready_timeout_s: float = 10.0
    start_delay_s: float = 0.0
    argv: list[str] = field(default_factory=list)         # filled in by the parent (resolved)
    error: str = ""                             # why it could not be resolved (build failed, ...)

    def ros_args(self) -> list[str]:
        out: list[str] = []
        for k, v in self.params.items():
            val = str(v).lower() if isinstance(v, bool) else str(v)
            out += ["-p", f"{k}:={val}"]
        for a, b in self.remap.items():
            out += ["-r", f"{a}:={b}"]
        return (["--ros-args", *out] if out else []) + list(self.args)


@dataclass
class Step:
    """One driver action and the condition that ends it.

    Exactly one action key is set: ``wait`` (seconds), ``publish`` ({topic, type, msg}),
    ``stdin`` ({process, line}), ``replay`` ({bag, topic, rate_hz, count, type}),
    ``action_goal`` ({action, type, goal, id}), ``service`` ({service, type, request}),
    ``stop`` / ``start`` ({processes: [...]}).
    ``until`` ends the step early: ``{goal_reached: {x, y, tol}, settle_s}``,
    ``{messages: {topic, count}}``, ``{idle_s}`` (no student output for that long),
    ``{action_done: true}``, ``{process_exit: name}``, ``{output: {process, pattern}}``,
    ``{advertised: {topic|service|action: name}}``, ``{subscribed: topic}``.
    ``timeout_s`` bounds the step; ``wait`` with an ``until`` waits for the condition.
    """

    id: str = ""
    wait: float | None = None
    publish: dict[str, Any] | None = None
    stdin: dict[str, Any] | None = None
    replay: dict[str, Any] | None = None
    action_goal: dict[str, Any] | None = None
    service: dict[str, Any] | None = None
    stop: dict[str, Any] | None = None
    start: dict[str, Any] | None = None
    until: dict[str, Any] = field(default_factory=dict)
    timeout_s: float = 10.0
    abort_on_timeout: bool = False

    ACTIONS = ("wait", "publish", "stdin", "replay", "action_goal", "service", "stop", "start")

    def action(self) -> str:
        set_keys = [k for k in self.ACTIONS if getattr(self, k) is not None]
        if len(set_keys) != 1:
            raise GraderError(f"step {self.id or '?'} must have exactly one of {', '.join(self.ACTIONS)}; "
                              f"has {', '.join(set_keys) or 'none'}")
        return set_keys[0]


@dataclass
class Scenario:
    id: str
    sim: bool = True                            # start the reference turtlesim
    sim_args: list[str] = field(default_factory=list)
    nodes: list[NodeSpec] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    record: list[str] = field(default_factory=list)       # topics; empty = everything
    settle_s: float = 0.5                       # recording kept after the last step
    time_limit_s: float = 180.0
    prefixes: list[str] = field(default_factory=list)     # filled in by the parent

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "Scenario":
        data = dict(data)
        nodes = [n if isinstance(n, NodeSpec) else NodeSpec(**n) for n in data.pop("nodes", [])]
        steps = [s if isinstance(s, Step) else Step(**s) for s in data.pop("steps", [])]
        for i, s in enumerate(steps):
            s.id = s.id or f"step{i + 1}"
            s.action()
        return cls(nodes=nodes, steps=steps, **data)
