"""Scenario part of the rubric schema: what to start, what to send, when a step is over.

A scenario is data for the scenario driver (``grader/scenario/``): the processes to run (by
package + executable, by Python entry point ``module:func``, or by launch file), and an ordered
list of ``steps``. Each step does at most one thing (send a goal, publish, call a service, send an
action goal, replay a bag, start/stop a process), then waits ``until`` a condition holds or its
``timeout`` expires. Everything is validated here so the driver can trust it: names exist,
conditions fit their step, and the declared wall-clock limit can hold all steps.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Union

from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from grader.rubric._nodes import Fields, Reader, describe, join_path, suggest

ROS_NAME = re.compile(r"^~?/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$")
PACKAGE = re.compile(r"^[a-z][a-z0-9_]*$")
EXECUTABLE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
MODULE = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*(:[A-Za-z_]\w*)?$")
LOCAL_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
RESERVED_PROCESSES = ("sim", "recorder", "driver")
DEFAULT_GOAL_TOPIC = "/turtle1/goal"
DEFAULT_POSE_TOPIC = "/turtle1/pose"


def interface_type(kind: str) -> re.Pattern[str]:
    """``pkg/msg/Name`` style type names for kind msg, srv or action."""
    return re.compile(rf"^[A-Za-z][A-Za-z0-9_]*/{kind}/[A-Z][A-Za-z0-9]*$")


# ----------------------------------------------------------------------------------------------
# dataclasses (what the scenario driver consumes)

@dataclass(frozen=True)
class StdinLine:
    """A line typed into a process after ``delay`` seconds (from the previous line / start)."""

    text: str
    delay: float = 0.5


@dataclass(frozen=True)
class Limits:
    """Resource limits; ``None`` leaves the driver's default. ``memory_mb`` = address space."""

    wall_s: float | None = None
    cpu_s: int | None = None
    memory_mb: int | None = None


@dataclass(frozen=True)
class Process:
    """One student (or supplied) program. Exactly one way to start it is set, except that
    ``executable`` and ``module`` may both be given: the executable is tried first and the
    entry point is the fallback (students often register console scripts under other names)."""

    name: str
    package: str | None = None
    executable: str | None = None
    module: str | None = None
    launch: str | None = None
    launch_arguments: Mapping[str, str] = field(default_factory=dict)
    args: tuple[str, ...] = ()
    parameters: Mapping[str, Any] = field(default_factory=dict)
    remappings: Mapping[str, str] = field(default_factory=dict)
    env: Mapping[str, str] = field(default_factory=dict)
    stdin: tuple[StdinLine, ...] | None = None   # None: stdin is /dev/null
    stdin_close: bool = False                    # EOF after the script (a terminal would not)
    start_delay: float = 0.0                     # after the previous process started
    autostart: bool = True                       # False: a step ``start:`` starts it
    limits: Limits = field(default_factory=Limits)
    line: int = 0


@dataclass(frozen=True)
class PublishGoal:
    """``goal: [x, y]``: publish ``Float32MultiArray(data=[x, y])`` on the scenario's goal topic."""

    x: float
    y: float
    topic: str = DEFAULT_GOAL_TOPIC


@dataclass(frozen=True)
class Publish:
    topic: str
    type: str
    msg: Mapping[str, Any] = field(default_factory=dict)
    count: int = 1
    rate_hz: float | None = None


@dataclass(frozen=True)
class ServiceCall:
    name: str
    type: str
    request: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ActionGoal:
    name: str
    type: str
    goal: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Replay:
    """Republish recorded messages into the graph (``rate_hz`` None keeps recorded timing)."""

    bag: Path
    topics: tuple[str, ...] | None = None
    rate_hz: float | None = None
    count: int | None = None


@dataclass(frozen=True)
class Start:
    processes: tuple[str, ...]


@dataclass(frozen=True)
class Stop:
    processes: tuple[str, ...]


StepAction = Union[PublishGoal, Publish, ServiceCall, ActionGoal, Replay, Start, Stop]


@dataclass(frozen=True)
class Condition:
    """``until`` of a step; ``params`` already hold every default (see CONDITIONS)."""

    name: str
    params: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Step:
    """Do ``action`` (if any), then wait until ``until`` holds, at most ``timeout`` seconds.
    Without ``until`` the step always lasts ``timeout`` (that is what ``wait: N`` means)."""

    id: str
    action: StepAction | None
    until: Condition | None
    timeout: float
    on_timeout: str = "continue"   # or "abort": skip the remaining steps
    line: int = 0


@dataclass(frozen=True)
class Scenario:
    id: str
    steps: tuple[Step, ...]
    processes: tuple[Process, ...] = ()
    description: str = ""
    sim: bool = True
    record: tuple[str, ...] | None = None     # None: record every topic
    goal_topic: str = DEFAULT_GOAL_TOPIC
    limits: Limits = field(default_factory=Limits)
    line: int = 0

    def process(self, name: str) -> Process:
        return next(p for p in self.processes if p.name == name)

    @property
    def budget_s(self) -> float:
        """Longest the scenario can run: start delays of autostarted processes + step timeouts."""
        return (sum(p.start_delay for p in self.processes if p.autostart)
                + sum(s.timeout for s in self.steps))


# ----------------------------------------------------------------------------------------------
# conditions: name -> allowed params (validated in _read_condition)

CONDITIONS: dict[str, tuple[str, ...]] = {
    "goal_reached": ("goal", "tolerance", "settle", "pose_topic"),
    "action_done": (),          # the step's action goal was rejected or returned a result
    "service_done": (),         # the step's service call returned
    "replay_done": (),          # the step's replay published its last message
    "process_exit": ("process",),
    "output": ("process", "pattern"),   # a stdout/stderr line of the process matches the regex
    "messages": ("topic", "count"),     # count messages seen on topic since the step began
    "advertised": ("topic", "service", "action"),  # exactly one; appears in the ROS graph
    "subscribed": ("topic",),   # some node other than the grader subscribes to topic
}
_STEP_ACTIONS = ("goal", "publish", "service", "action", "replay", "start", "stop")
_NEEDS_ACTION = {"action_done": ActionGoal, "service_done": ServiceCall, "replay_done": Replay}


# ----------------------------------------------------------------------------------------------
# reading

@dataclass
class _Ctx:
    reader: Reader
    base_dir: Path
    check_files: bool


def read_scenario(reader: Reader, node: Node, path: str, scenario_id: str, base_dir: Path,
                  check_files: bool) -> Scenario | None:
    """Validate one ``scenarios.<id>`` entry; None if it had problems (already recorded)."""
    ctx = _Ctx(reader, base_dir, check_files)
    mark = len(reader.problems)
    f = reader.fields(node, path, ("description", "sim", "record", "goal_topic", "processes",
                                   "steps", "limits"), required=("steps",))
    if f is None:
        return None
    description = f.string("description", "") or ""
    sim = f.boolean("sim", True)
    goal_topic = f.string("goal_topic", DEFAULT_GOAL_TOPIC, pattern=ROS_NAME, what="a topic name")
    record = _read_record(ctx, f)
    limits = _read_limits(ctx, f, "limits")
    processes: list[Process] = []
    if "processes" in f:
        names: dict[str, int] = {}
        for index, pnode, ppath in reader.items(f.value_node("processes"), f.sub("processes")):
            proc = _read_process(ctx, pnode, ppath)
            if proc is None:
                continue
            if proc.name in names:
                reader.error(pnode, join_path(ppath, "name"),
                             f"duplicate process name {proc.name!r} (first on line {names[proc.name]})")
            names[proc.name] = proc.line
            processes.append(proc)
    steps: list[Step] = []
    step_ids: dict[str, int] = {}
    step_list = list(reader.items(f.value_node("steps"), f.sub("steps"))) if "steps" in f else []
    if "steps" in f and isinstance(f.value_node("steps"), SequenceNode) and not step_list:
        f.error("steps", "a scenario needs at least one step")
    for index, snode, spath in step_list:
        step = _read_step(ctx, snode, spath, processes, goal_topic or DEFAULT_GOAL_TOPIC)
        if step is None:
            continue
        if step.id in step_ids:
            reader.error(snode, join_path(spath, "id"),
                         f"duplicate step id {step.id!r} (first on line {step_ids[step.id]})")
        step_ids[step.id] = step.line
        steps.append(step)
    if len(reader.problems) > mark:
        return None
    scenario = Scenario(id=scenario_id, steps=tuple(steps), processes=tuple(processes),
                        description=description, sim=bool(sim), record=record,
                        goal_topic=goal_topic or DEFAULT_GOAL_TOPIC, limits=limits, line=f.line)
    _check_process_use(reader, f, scenario)
    if limits.wall_s is not None and scenario.budget_s > limits.wall_s:
        reader.error(f.value_node("limits"), join_path(f.sub("limits"), "wall_s"),
                     f"the steps may take up to {scenario.budget_s:g} s (start delays + step "
                     f"timeouts) but wall_s is {limits.wall_s:g}; raise it or shorten the steps")
    return scenario if len(reader.problems) == mark else None


def _read_record(ctx: _Ctx, f: Fields) -> tuple[str, ...] | None:
    if "record" not in f:
        return None
    node = f.value_node("record")
    if isinstance(node, ScalarNode) and ctx.reader.scalar(node) == "all":
        return None
    topics = []
    if not isinstance(node, SequenceNode):
        f.error("record", f"expected 'all' or a list of topic names, got "
                          f"{describe(node, ctx.reader.scalar(node))}")
        return None
    for _, tnode, tpath in ctx.reader.items(node, f.sub("record")):
        topic = ctx.reader.string(tnode, tpath, pattern=ROS_NAME, what="a topic name")
        if topic:
            topics.append(topic)
    return tuple(topics)


def _read_limits(ctx: _Ctx, parent: Fields, key: str) -> Limits:
    if key not in parent:
        return Limits()
    f = ctx.reader.fields(parent.value_node(key), parent.sub(key), ("wall_s", "cpu_s", "memory_mb"))
    if f is None:
        return Limits()
    return Limits(wall_s=f.number("wall_s", minimum=0, exclusive_minimum=True),
                  cpu_s=f.number("cpu_s", minimum=0, exclusive_minimum=True, integer=True),
                  memory_mb=f.number("memory_mb", minimum=0, exclusive_minimum=True, integer=True))


_PROCESS_KEYS = ("name", "package", "executable", "module", "launch", "launch_arguments", "args",
                 "parameters", "remappings", "env", "stdin", "stdin_close", "start_delay",
                 "autostart", "limits")


def _read_process(ctx: _Ctx, node: Node, path: str) -> Process | None:
    reader = ctx.reader
    mark = len(reader.problems)
    f = reader.fields(node, path, _PROCESS_KEYS, required=("name",))
    if f is None:
        return None
    name = f.string("name", pattern=LOCAL_ID, what="a process name (letters, digits, _ or -)")
    if name in RESERVED_PROCESSES:
        f.error("name", f"{name!r} is reserved for the grader's own processes "
                        f"({', '.join(RESERVED_PROCESSES)})")
    package = f.string("package", pattern=PACKAGE, what="a ROS package name")
    executable = f.string("executable", pattern=EXECUTABLE, what="an executable name")
    module = f.string("module", pattern=MODULE, what="a Python entry point 'package.module:function'")
    launch = f.string("launch", pattern=EXECUTABLE, what="a launch file name")
    if not (executable or module or launch) and len(reader.problems) == mark:
        f.error(None, "say how to start the process: executable (with package), module "
                      "('pkg.module:function') or launch (with package)")
    if launch and (executable or module):
        f.error("launch", "launch cannot be combined with executable or module")
    if (executable or launch) and "package" not in f:
        f.error(None, f"{'executable' if executable else 'launch'} needs a package")
    if "launch_arguments" in f and not launch:
        f.error("launch_arguments", "launch_arguments only apply to a launch file")
    args = _string_list(ctx, f, "args")
    parameters = f.mapping("parameters")
    for key, value in parameters.items():
        if not _is_param_value(value):
            f.error("parameters", f"parameter {key!r}: expected a number, text, true/false or a "
                                  f"list of one of those, got {value!r}")
    remappings = _string_map(ctx, f, "remappings", key_pattern=ROS_NAME, value_pattern=ROS_NAME)
    env = _string_map(ctx, f, "env", key_pattern=re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$"))
    launch_arguments = _string_map(ctx, f, "launch_arguments")
    stdin = _read_stdin(ctx, f)
    stdin_close = f.boolean("stdin_close", False)
    if "stdin_close" in f and stdin is None:
        f.error("stdin_close", "stdin_close needs a stdin script")
    start_delay = f.number("start_delay", 0.0, minimum=0)
    autostart = f.boolean("autostart", True)
    limits = _read_limits(ctx, f, "limits")
    if len(reader.problems) > mark:
        return None
    return Process(name=name, package=package, executable=executable, module=module,
                   launch=launch, launch_arguments=launch_arguments, args=args,
                   parameters=parameters, remappings=remappings, env=env, stdin=stdin,
                   stdin_close=bool(stdin_close), start_delay=float(start_delay),
                   autostart=bool(autostart), limits=limits, line=f.line)


def _is_param_value(value: Any) -> bool:
    scalar = (bool, int, float, str)
    if isinstance(value, scalar):
        return True
    return (isinstance(value, list) and bool(value)
            and all(isinstance(v, scalar) for v in value)
            and len({type(v) for v in value}) == 1)


def _string_list(ctx: _Ctx, f: Fields, key: str) -> tuple[str, ...]:
    if key not in f:
        return ()
    out = []
    for _, node, path in ctx.reader.items(f.value_node(key), f.sub(key)):
        value = ctx.reader.string(node, path)
        if value is not None:
            out.append(value)
    return tuple(out)


def _string_map(ctx: _Ctx, f: Fields, key: str, key_pattern: re.Pattern[str] | None = None,
                value_pattern: re.Pattern[str] | None = None) -> dict[str, str]:
    if key not in f:
        return {}
    out = {}
    for name, key_node, value_node, path in ctx.reader.mapping_entries(f.value_node(key), f.sub(key)):
        if key_pattern is not None and not key_pattern.match(name):
            ctx.reader.error(key_node, path, f"{name!r} is not a valid name here")
            continue
        value = ctx.reader.string(value_node, path, pattern=value_pattern,
                                  what="a name" if value_pattern else "text")
        if value is not None:
            out[name] = value
    return out


def _read_stdin(ctx: _Ctx, f: Fields) -> tuple[StdinLine, ...] | None:
    if "stdin" not in f:
        return None
    lines = []
    for _, node, path in ctx.reader.items(f.value_node("stdin"), f.sub("stdin")):
        if isinstance(node, ScalarNode):
            text = ctx.reader.string(node, path, what="a line of text (quote it)")
            if text is not None:
                lines.append(StdinLine(text))
            continue
        lf = ctx.reader.fields(node, path, ("line", "delay"), required=("line",))
        if lf is None:
            continue
        text = lf.get("line", _any_text(ctx.reader))
        delay = lf.number("delay", 0.5, minimum=0)
        if text is not None and delay is not None:
            lines.append(StdinLine(text, float(delay)))
    return tuple(lines)


def _any_text(reader: Reader):
    """A string that may be empty or blank (stdin lines may be just Enter)."""
    def convert(node: Node, path: str) -> str | None:
        value = reader.scalar(node)
        if not isinstance(value, str):
            reader.error(node, path, f"expected a line of text (quote it), got {describe(node, value)}")
            return None
        return value
    return convert


_STEP_KEYS = ("id", "wait", *_STEP_ACTIONS, "until", "timeout", "on_timeout")


def _read_step(ctx: _Ctx, node: Node, path: str, processes: list[Process],
               goal_topic: str) -> Step | None:
    reader = ctx.reader
    mark = len(reader.problems)
    f = reader.fields(node, path, _STEP_KEYS, required=("id",))
    if f is None:
        return None
    step_id = f.string("id", pattern=LOCAL_ID, what="a step id (letters, digits, _ or -)")
    actions = [k for k in _STEP_ACTIONS if k in f]
    if len(actions) > 1:
        f.error(actions[1], f"a step does one thing; it has {' and '.join(actions)} — split it")
    if "wait" in f:
        wait = f.number("wait", minimum=0, exclusive_minimum=True)
        for other in ("until", "timeout", *actions):
            if other in f:
                f.error(other, f"'wait: N' is a pause on its own; use timeout with {other!r} instead")
        timeout = wait
    else:
        timeout = f.number("timeout", minimum=0, exclusive_minimum=True)
        if "timeout" not in f:
            f.error("timeout", "required key is missing (every step needs a time limit; "
                               "use 'wait: N' for a plain pause)")
    on_timeout = f.string("on_timeout", "continue", choices=("continue", "abort"))
    action = _read_action(ctx, f, actions[0], processes, goal_topic) if actions else None
    until = _read_condition(ctx, f, action, processes) if "until" in f else None
    if len(reader.problems) > mark:
        return None
    return Step(id=step_id, action=action, until=until, timeout=float(timeout),
                on_timeout=on_timeout, line=f.line)


def _read_action(ctx: _Ctx, f: Fields, kind: str, processes: list[Process],
                 goal_topic: str) -> StepAction | None:
    reader = ctx.reader
    node, path = f.value_node(kind), f.sub(kind)
    if kind == "goal":
        xy = _read_xy(reader, node, path)
        return PublishGoal(xy[0], xy[1], goal_topic) if xy else None
    if kind in ("start", "stop"):
        names = _read_names(reader, node, path)
        known = [p.name for p in processes]
        for name in names:
            if name not in known:
                reader.error(node, path, f"no process {name!r} in this scenario{suggest(name, known)}")
        return (Start if kind == "start" else Stop)(tuple(names))
    if kind == "publish":
        g = reader.fields(node, path, ("topic", "type", "msg", "count", "rate_hz"),
                          required=("topic", "type"))
        if g is None:
            return None
        return Publish(topic=g.string("topic", pattern=ROS_NAME, what="a topic name"),
                       type=g.string("type", pattern=interface_type("msg"),
                                     what="a message type like std_msgs/msg/String"),
                       msg=g.mapping("msg"), count=g.number("count", 1, minimum=1, integer=True),
                       rate_hz=g.number("rate_hz", minimum=0, exclusive_minimum=True))
    if kind == "service":
        g = reader.fields(node, path, ("name", "type", "request"), required=("name", "type"))
        if g is None:
            return None
        return ServiceCall(name=g.string("name", pattern=ROS_NAME, what="a service name"),
                           type=g.string("type", pattern=interface_type("srv"),
                                         what="a service type like turtlesim/srv/SetPen"),
                           request=g.mapping("request"))
    if kind == "action":
        g = reader.fields(node, path, ("name", "type", "goal"), required=("name", "type"))
        if g is None:
            return None
        return ActionGoal(name=g.string("name", pattern=ROS_NAME, what="an action name"),
                          type=g.string("type", pattern=interface_type("action"),
                                        what="an action type like turtlesim/action/RotateAbsolute"),
                          goal=g.mapping("goal"))
    # replay
    g = reader.fields(node, path, ("bag", "topics", "rate_hz", "count"), required=("bag",))
    if g is None:
        return None
    bag_text = g.string("bag", what="a path to a bag (relative to the rubric)")
    bag = (ctx.base_dir / bag_text).resolve() if bag_text else Path()
    if bag_text and ctx.check_files and not bag.exists():
        g.error("bag", f"bag {bag_text!r} not found (looked for {bag})")
    topics = None
    if "topics" in g:
        topics = tuple(t for _, tn, tp in reader.items(g.value_node("topics"), g.sub("topics"))
                       if (t := reader.string(tn, tp, pattern=ROS_NAME, what="a topic name")))
    return Replay(bag=bag, topics=topics,
                  rate_hz=g.number("rate_hz", minimum=0, exclusive_minimum=True),
                  count=g.number("count", minimum=1, integer=True))


def _read_xy(reader: Reader, node: Node, path: str) -> tuple[float, float] | None:
    """``[x, y]`` or ``{x: .., y: ..}``."""
    if isinstance(node, MappingNode):
        g = reader.fields(node, path, ("x", "y"), required=("x", "y"))
        if g is None:
            return None
        x, y = g.number("x"), g.number("y")
    elif isinstance(node, SequenceNode) and len(node.value) == 2:
        x = reader.number(node.value[0], join_path(path, 0))
        y = reader.number(node.value[1], join_path(path, 1))
    else:
        reader.error(node, path, f"expected a position [x, y] or {{x: .., y: ..}}, got "
                                 f"{describe(node, reader.scalar(node))}")
        return None
    return (float(x), float(y)) if x is not None and y is not None else None


def _read_names(reader: Reader, node: Node, path: str) -> list[str]:
    if isinstance(node, SequenceNode):
        return [n for _, child, p in reader.items(node, path)
                if (n := reader.string(child, p, pattern=LOCAL_ID, what="a process name"))]
    name = reader.string(node, path, pattern=LOCAL_ID, what="a process name or a list of them")
    return [name] if name else []


def _read_condition(ctx: _Ctx, f: Fields, action: StepAction | None,
                    processes: list[Process]) -> Condition | None:
    reader = ctx.reader
    node, path = f.value_node("until"), f.sub("until")
    if isinstance(node, ScalarNode):
        name = reader.string(node, path, choices=CONDITIONS, what="a condition name")
        params: dict[str, Any] = {}
        g = None
        if name is None:
            return None
    else:
        g = reader.fields(node, path, ("condition", *sorted({p for ps in CONDITIONS.values() for p in ps})),
                          required=("condition",))
        if g is None or "condition" not in g:
            return None
        name = g.string("condition", choices=CONDITIONS, what="a condition name")
        if name is None:
            return None
        for key in g.keys():
            if key != "condition" and key not in CONDITIONS[name]:
                allowed = ", ".join(CONDITIONS[name]) or "none"
                g.error(key, f"condition {name!r} takes no {key!r} (its parameters: {allowed})")
        params = {}

    def need(key: str) -> Node | None:
        if g is not None and key in g:
            return g.value_node(key)
        reader.error(node, join_path(path, key), f"condition {name!r} needs {key!r}")
        return None

    process_names = [p.name for p in processes]

    def process_param() -> None:
        pnode = need("process")
        if pnode is not None:
            pname = reader.string(pnode, join_path(path, "process"), what="a process name")
            if pname is not None and pname not in process_names:
                reader.error(pnode, join_path(path, "process"),
                             f"no process {pname!r} in this scenario{suggest(pname, process_names)}")
            params["process"] = pname

    if name in _NEEDS_ACTION and not isinstance(action, _NEEDS_ACTION[name]):
        wanted = {"action_done": "action", "service_done": "service", "replay_done": "replay"}[name]
        reader.error(node, path, f"{name!r} waits for this step's {wanted}, but the step has no {wanted!r}")
    elif name == "goal_reached":
        if g is not None and "goal" in g:
            params["goal"] = _read_xy(reader, g.value_node("goal"), join_path(path, "goal"))
        elif isinstance(action, PublishGoal):
            params["goal"] = (action.x, action.y)
        else:
            reader.error(node, join_path(path, "goal"),
                         "goal_reached needs a goal: give one here, or use it on a 'goal:' step")
        params["tolerance"] = g.number("tolerance", 0.1, minimum=0, exclusive_minimum=True) if g else 0.1
        params["settle"] = g.number("settle", 0.5, minimum=0) if g else 0.5
        params["pose_topic"] = (g.string("pose_topic", DEFAULT_POSE_TOPIC, pattern=ROS_NAME,
                                         what="a topic name") if g else DEFAULT_POSE_TOPIC)
    elif name == "process_exit":
        process_param()
    elif name == "output":
        process_param()
        pnode = need("pattern")
        if pnode is not None:
            pattern = reader.string(pnode, join_path(path, "pattern"), what="a regular expression")
            if pattern is not None:
                try:
                    re.compile(pattern)
                except re.error as exc:
                    reader.error(pnode, join_path(path, "pattern"), f"invalid regular expression: {exc}")
            params["pattern"] = pattern
    elif name == "messages":
        tnode = need("topic")
        if tnode is not None:
            params["topic"] = reader.string(tnode, join_path(path, "topic"), pattern=ROS_NAME,
                                            what="a topic name")
        params["count"] = g.number("count", 1, minimum=1, integer=True) if g else 1
    elif name == "subscribed":
        tnode = need("topic")
        if tnode is not None:
            params["topic"] = reader.string(tnode, join_path(path, "topic"), pattern=ROS_NAME,
                                            what="a topic name")
    elif name == "advertised":
        given = [k for k in ("topic", "service", "action") if g is not None and k in g]
        if len(given) != 1:
            reader.error(node, path, "advertised needs exactly one of topic, service or action")
        else:
            params[given[0]] = g.string(given[0], pattern=ROS_NAME, what=f"a {given[0]} name")
    return Condition(name, params)


def _check_process_use(reader: Reader, f: Fields, scenario: Scenario) -> None:
    """Processes with ``autostart: false`` must be started by a step, and only those."""
    started = {n for s in scenario.steps if isinstance(s.action, Start) for n in s.action.processes}
    for step in scenario.steps:
        if isinstance(step.action, Start):
            for name in step.action.processes:
                if scenario.process(name).autostart:
                    reader.error(step.line, f"{f.path}.steps[{scenario.steps.index(step)}].start",
                                 f"process {name!r} already starts with the scenario; "
                                 f"set 'autostart: false' on it")
    for proc in scenario.processes:
        if not proc.autostart and proc.name not in started:
            reader.error(proc.line, f"{f.path}.processes[{scenario.processes.index(proc)}]",
                         f"process {proc.name!r} has autostart: false but no step starts it")
