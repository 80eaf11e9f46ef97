"""The scenario model: what to start, what to send, when a step is over. One model, three users.

A rubric's ``scenarios:`` section is validated into these classes (``grader.rubric.load``), the
grading pipeline hands them, as they are, to the scenario child process (inside a
:class:`grader.scenario.runspec.ScenarioRun`, serialised with ``model_dump_json`` and read back
with ``ScenarioRun.model_validate_json``), and the child
dispatches every step action and every ``until`` condition on its class. So a field has one name
everywhere, and what a rubric can say is exactly what the runner does; what it cannot say,
validation rejects (the loader turns each rejection into ``file:line: field: message``).

The classes mirror the YAML a rubric author writes (``Step.publish``, ``Step.until``...), which
is also why ``grader rubric schema`` can hand editors a JSON Schema generated from them.
pydantic is used because it gives typed, frozen models, strict validation with located errors,
JSON round-trips and JSON Schema from one declaration.

The field types and base model live in ``grader.contracts.fields``, the ``until:`` conditions in
``grader.scenario.conditions``; both are re-exported here, so ``model`` names the whole language.

A little over the project's ~400 lines: one class per step and process kind of the rubric
language, each short; the language reads best as one file (the guide is generated from it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal, Union, cast

from pydantic import (BeforeValidator, ConfigDict, Field, RootModel, ValidationInfo, field_validator,
                      model_validator)

# re-exported: the whole scenario language is importable from here
from grader.contracts.text import suggest
from grader.contracts.world import WORLD_SIZE_M
from grader.scenario.conditions import (  # noqa: F401
    ActionDone, Advertised, Condition, GoalReached, Messages, Output, ProcessExit, ReplayDone, ServiceDone,
    Subscribed)
from grader.contracts.fields import (  # noqa: F401
    GOAL_TYPES, RESERVED_PROCESSES, ActionType, EntryPoint, EnvName, ExecutableName, Goal,
    LaunchFile, LaxPath, LocalId, Model, MsgType, NonNegativeFloat, PackageName, ParamValue,
    PositiveFloat, PositiveInt, RosName, SrvType, with_rules)
from grader.contracts.process import Limits, StdinLine  # noqa: F401  (the scenario's processes are made of them)



class Placement(Model):
    """Where the grader puts a turtle before a step's action (turtlesim's ``teleport_absolute``),
    so the step starts from the same pose in every run, whatever the turtle did before."""

    x: Annotated[float, Field(ge=0.0, le=WORLD_SIZE_M, description="m")]
    y: Annotated[float, Field(ge=0.0, le=WORLD_SIZE_M, description="m")]
    theta: Annotated[float, Field(allow_inf_nan=False, description="rad, 0 = facing +x")]
    turtle: LocalId = Field("turtle1", description="the turtle's name")
    spawn: bool = Field(False, description="when the turtle does not exist (the simulator has published no "
                        "pose of it), spawn it there (turtlesim's /spawn) instead: the items of the steps "
                        "that need it are graded even when the student's code did not make it")


class Process(Model):
    """One student (or supplied) program: by ``executable`` (found as ``ros2 run`` finds it:
    console script, CMake-installed script or binary) and/or ``module`` (``pkg.module:func``,
    tried when the executable is missing: students name scripts freely),
    or by ``launch`` file (every node it declares starts as a process of its own)."""

    name: LocalId = Field(description="unique in the scenario; steps and conditions use it")
    package: PackageName | None = Field(None, description="the ROS package")
    executable: ExecutableName | None = Field(None, description="an executable of the package, found as `ros2 run` finds it")
    module: EntryPoint | None = Field(None, description="pkg.module:function, when the script's name varies")
    launch: LaunchFile | None = Field(None, description="a launch file of the package: starts its nodes (a "
                                      "pattern such as '*launch.py': the one launch file the package has)")
    launch_arguments: dict[str, str] = Field({}, description="name: value arguments of the launch file")
    args: Annotated[tuple[str, ...], Field(strict=False, description="extra command-line arguments")] = ()
    parameters: dict[str, ParamValue] = Field({}, description="ROS parameters, typed as written (30.0 is a double)")
    remappings: dict[RosName, RosName] = Field({}, description="from: to topic/service remappings")
    env: dict[EnvName, str] = Field({}, description="environment variables the process gets")
    stdin: Annotated[tuple[StdinLine, ...], Field(strict=False)] | None = Field(None, description="lines typed into the process; "
                                                "absent: stdin is /dev/null")
    stdin_close: bool = Field(False, description="EOF after the script (a terminal would not)")
    start_delay: NonNegativeFloat = Field(0.0, description="s after the previous process started")
    autostart: bool = Field(True, description="false: a `start:` step starts it")
    limits: Limits = Limits()

    @field_validator("name")
    @classmethod
    def _not_reserved(cls, name: str) -> str:
        if name in RESERVED_PROCESSES:
            raise ValueError(f"{name!r} is reserved for the grader's own processes "
                             f"({', '.join(RESERVED_PROCESSES)})")
        return name

    @field_validator("parameters")
    @classmethod
    def _homogeneous_lists(cls, params: dict[str, Any]) -> dict[str, Any]:
        for key, value in params.items():
            if isinstance(value, list) and (not value or len({type(v) for v in value}) != 1):
                raise ValueError(f"parameter {key!r}: a list parameter needs values of one type")
        return params

    @model_validator(mode="after")
    def _one_way_to_start(self) -> "Process":
        if not (self.executable or self.module or self.launch):
            raise ValueError("say how to start the process: executable (with package), module "
                             "('pkg.module:function') or launch (with package)")
        if self.launch and (self.executable or self.module):
            raise ValueError("launch cannot be combined with executable or module")
        if (self.executable or self.launch) and not self.package:
            raise ValueError(f"{'executable' if self.executable else 'launch'} needs a package")
        if self.launch_arguments and not self.launch:
            raise ValueError("launch_arguments only apply to a launch file")
        if self.stdin_close and self.stdin is None:
            raise ValueError("stdin_close needs a stdin script")
        return self

    def ros_args(self) -> list[str]:
        """``--ros-args -p k:=v -r a:=b`` for ``parameters``/``remappings``, then ``args``."""
        out: list[str] = []
        for key, value in self.parameters.items():
            out += ["-p", f"{key}:={param_text(value)}"]
        for old, new in self.remappings.items():
            out += ["-r", f"{old}:={new}"]
        return (["--ros-args", *out] if out else []) + list(self.args)


def param_text(value: Any) -> str:
    """A parameter value as rcl parses it on the command line (YAML): 30.0 stays a double."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(param_text(v) for v in value) + "]"
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    return repr(value)


# ---------------------------------------------------------------------------------- step actions
class Publish(Model):
    """Publish ``msg`` (fields as a mapping) ``count`` times, at ``rate_hz`` when count > 1."""

    topic: RosName
    type: MsgType
    msg: dict[str, Any] = Field({}, description="field values, nested as in the message")
    count: PositiveInt = Field(1, description="messages to publish")
    rate_hz: PositiveFloat | None = Field(None, description="pace when count > 1")


class ServiceCall(Model):
    """Call a service once and wait for the response (at most ``response_timeout`` s).

    Without ``type`` the type is taken from the graph: whatever the server advertises, so a
    student's own ``pkg/srv/SetGoal`` works whatever their package is called.
    """

    name: RosName
    type: SrvType | None = Field(None, description="absent: the type the server advertises")
    request: dict[str, Any] = Field({}, description="request field values")
    server_timeout: PositiveFloat = Field(5.0, description="s to wait for the service to appear")
    response_timeout: PositiveFloat = Field(10.0, description="s to wait for the response")
    served_by: RosName | None = Field(
        None, description="the node expected to serve it (a call without `type`): with no server of "
                          "`name`, the one service of its own this node advertises is called instead (a student's other name for it; "
                          "the call's event says `asked_for: name`), so items about what the service does "
                          "are judged and only the item about its name is charged")


class ActionGoal(Model):
    """Send one goal to an action server; the step's ``until: action_done`` waits for its end."""

    name: RosName
    type: ActionType
    goal: dict[str, Any] = Field({}, description="goal field values, nested as in the goal message")
    server_timeout: PositiveFloat = Field(5.0, description="s to wait for the action server")
    response_timeout: PositiveFloat = Field(10.0, description="s to wait for the server to accept or "
                                            "reject the goal")
    by_type: bool = Field(
        False, description="with no server of `name`, the one action server of `type` a student node "
                           "offers is sent the goal instead (a student's other name for the action; the goal's "
                           "events say `asked_for: name`), so items about what the server does are judged "
                           "and only the item about its name is charged")


class Replay(Model):
    """Publish recorded messages of ``bag`` back into the graph.

    ``topics``: which (default: every topic of the bag but the grader's own). ``rate_hz``: a
    fixed pace; absent = the recorded timing. ``count``: the first N messages. ``lead``: never
    more than this many messages ahead of the student's output lines (a subscriber that logs
    one line per message is paced instead of losing messages in its QoS history; a node that
    prints nothing per message gets the plain pace after a few messages). How long it waits for
    an answer: ``lead_wait_s`` and ``lead_budget_s`` (:mod:`grader.scenario.pacing`).
    """

    bag: LaxPath = Field(description="a bag folder, relative to the rubric")
    topics: Annotated[tuple[RosName, ...], Field(strict=False)] | None = Field(
        None, description="topics to publish (absent: all but the grader's own)")
    rate_hz: PositiveFloat | None = Field(None, description="fixed pace (absent: the recorded timing)")
    count: PositiveInt | None = Field(None, description="the first N messages (absent: all)")
    lead: PositiveInt | None = Field(None, description="at most this many messages ahead of the "
                                     "student's output lines")
    lead_wait_s: PositiveFloat = Field(2.0, description="with lead: wall s to wait for the student's "
                                       "answer before counting the messages as not answered (a "
                                       "starved node pauses, then answers everything queued)")
    lead_budget_s: NonNegativeFloat = Field(10.0, description="with lead: wall s of such waits beyond "
                                            "0.25 s each, over the whole replay (a node that answers only "
                                            "some messages)")

    @field_validator("bag", mode="before")
    @classmethod
    def _relative_to_rubric(cls, value: Any, info: ValidationInfo) -> Any:
        base = (info.context or {}).get("base_dir")
        if isinstance(value, str) and base is not None:
            return str((Path(base) / value).resolve())
        return value


def _names(value: Any) -> Any:
    if isinstance(value, str):
        return (value,)
    return tuple(value) if isinstance(value, list) else value


class Start(RootModel[tuple[LocalId, ...]]):
    """Start processes declared with ``autostart: false`` (a name or a list of names)."""

    model_config = ConfigDict(frozen=True, strict=True)
    root: Annotated[tuple[LocalId, ...], BeforeValidator(_names), Field(min_length=1, strict=False)]


class Stop(RootModel[tuple[LocalId, ...]]):
    """Stop processes (SIGINT, then SIGTERM, then SIGKILL), a name or a list of names."""

    model_config = ConfigDict(frozen=True, strict=True)
    root: Annotated[tuple[LocalId, ...], BeforeValidator(_names), Field(min_length=1, strict=False)]


Action = Union[Goal, Publish, ServiceCall, ActionGoal, Replay, Start, Stop]
#: step keys that hold an action, in the order they are documented
ACTION_KEYS = ("goal", "publish", "service", "action", "replay", "start", "stop")


# ----------------------------------------------------------------------------------------- steps
class Step(Model):
    """Do at most one action, then wait until ``until`` holds, at most ``timeout`` seconds.

    ``wait: N`` is a plain pause of N seconds (no action, no condition).
    """

    id: LocalId
    place: Placement | None = Field(None, description="first teleport the turtle there and wait until "
                                    "the simulator shows it there; then the action")
    goal: Goal | None = Field(None, description="publish [x, y] on the scenario's goal_topic")
    publish: Publish | None = None
    service: ServiceCall | None = None
    action: ActionGoal | None = None
    replay: Replay | None = None
    start: Start | None = None
    stop: Stop | None = None
    wait: PositiveFloat | None = None
    until: Condition | None = None
    timeout: PositiveFloat | None = Field(None, description="s; required unless `wait`")
    on_timeout: Literal["continue", "abort"] = Field(
        "continue", description="abort: skip the remaining steps when the condition never held")

    @model_validator(mode="wrap")
    @classmethod
    def _shape(cls, value: Any, handler: Any) -> Any:
        """Which keys go together; reported with the field errors, at the offending key."""
        if not isinstance(value, dict):
            return handler(value)
        own: list[tuple[tuple, str]] = []
        actions = [k for k in ACTION_KEYS if value.get(k) is not None]
        if len(actions) > 1:
            own.append(((actions[1],), f"a step does one thing; it has {' and '.join(actions)}: split it"))
        if value.get("wait") is not None:
            extra = [k for k in ("until", "timeout", "place", *actions) if value.get(k) is not None]
            if extra:
                own.append(((extra[0],), f"'wait: N' is a pause on its own; use timeout with "
                                         f"{extra[0]!r} instead"))
        elif value.get("timeout") is None:
            own.append((("timeout",), "required key is missing (every step needs a time limit; "
                                      "use 'wait: N' for a plain pause)"))
        until = value.get("until")
        name = until if isinstance(until, str) else until.get("condition") if isinstance(until, dict) else None
        needs = {"action_done": "action", "service_done": "service", "replay_done": "replay"}.get(cast(str, name))
        if needs and needs not in actions:
            own.append((("until",), f"{name!r} waits for this step's {needs}, but the step has no {needs!r}"))
        if name == "goal_reached" and "goal" not in cast(Any, until) and value.get("goal") is None:
            own.append((("until", "goal"), "goal_reached needs a goal: give one here, or use it "
                                           "on a 'goal:' step"))
        return with_rules(cls, handler, value, own)

    @property
    def do(self) -> Action | None:
        """The step's one action (None for a pause or a pure wait for a condition)."""
        for key in ACTION_KEYS:
            value = getattr(self, key)
            if value is not None:
                return value
        return None

    @property
    def limit_s(self) -> float:
        """How long the step may last."""
        return float(self.wait if self.wait is not None else self.timeout)  # type: ignore[arg-type]

    @property
    def target(self) -> Goal | None:
        """The position this step drives to: the condition's goal, else the step's ``goal:``."""
        if isinstance(self.until, GoalReached) and self.until.goal is not None:
            return self.until.goal
        return self.goal


class Scenario(Model):
    """Processes to run against the reference simulator, and the steps that drive them."""

    description: str = ""
    sim: bool = Field(True, description="start the reference turtlesim")
    record: Literal["all"] | Annotated[tuple[RosName, ...], Field(strict=False)] = Field(
        "all", description="topics to record (the grader's /grader/* always are)")
    goal_topic: RosName | None = Field(None, description="where `goal:` steps publish")
    goal_type: Literal[GOAL_TYPES] | None = Field(  # type: ignore[valid-type]
        None, description="the message `goal:` steps publish: Float32MultiArray data [x, y], "
                          "Point or Pose2D x, y")
    processes: Annotated[tuple[Process, ...], Field(strict=False)] = ()
    steps: Annotated[tuple[Step, ...], Field(min_length=1, strict=False)]
    limits: Limits = Limits()
    real_time: bool = Field(False, description="run at 1x even with --time-scale (the scenario judges "
                            "wall-clock behaviour; say why in a comment)")
    lockstep: bool = Field(False, description="run on lockstep simulated time: the clock advances a 16 ms tick "
                           "only once every process has handled the last one, so the same code gets the "
                           "same poses in every run (a chaotic path; say why in a comment). Nodes paced by "
                           "the wall clock run on it instead, and the result says why")
    repeat_by: Literal["median", "worst"] = Field(
        "median", description="how `repeat` grades an item from its runs: the median run, or the worst one (a "
        "start-up that must work every time the node starts, where one lucky run would pay a race)")
    repeat: int = Field(1, ge=1, le=9, description="run it this many times (odd, for the median) and grade each "
                        "of its items by the median run, or by the worst (`repeat_by`); an item that stays "
                        "timing-sensitive: say why in a comment")

    @field_validator("repeat")
    @classmethod
    def _repeat(cls, value: int, info: ValidationInfo) -> int:
        by = info.data.get("repeat_by", "median")
        if by == "median" and value % 2 == 0:
            raise ValueError(f"must be odd (1, 3, 5...): the median of {value} runs would not be one run's result")
        if by == "worst" and value < 2:
            raise ValueError("repeat_by: worst needs 2 runs or more (the worst of one run is that run)")
        return value

    @model_validator(mode="after")
    def _lockstep(self) -> "Scenario":
        if self.lockstep and not self.sim:
            raise ValueError("lockstep needs the simulator (sim: true): it is the simulator's clock that steps")
        if self.lockstep and self.real_time:
            raise ValueError("lockstep and real_time exclude each other: lockstep runs on simulated time")
        return self

    @model_validator(mode="after")
    def _goal_publishing(self) -> "Scenario":
        if any(s.goal is not None for s in self.steps) and not (self.goal_topic and self.goal_type):
            raise ValueError("steps with 'goal:' need the scenario's goal_topic and goal_type "
                             f"(one of {', '.join(GOAL_TYPES)})")
        return self

    def process(self, name: str) -> Process:
        return next(p for p in self.processes if p.name == name)

    @property
    def budget_s(self) -> float:
        """Longest the scenario can run: start delays of autostarted processes + step limits."""
        return (sum(p.start_delay for p in self.processes if p.autostart)
                + sum(s.limit_s for s in self.steps))

    @property
    def time_limit_s(self) -> float:
        """The scenario's wall-clock limit: ``limits.wall_s``, else its budget plus 30 s."""
        return float(self.limits.wall_s or max(60.0, self.budget_s + 30.0))

    def problems(self) -> list[tuple[str, str]]:
        """Cross-references within the scenario, as ``(field path, message)``; [] when fine."""
        out: list[tuple[str, str]] = []
        names = [p.name for p in self.processes]
        seen: set[str] = set()
        for i, proc in enumerate(self.processes):
            if proc.name in seen:
                out.append((f"processes[{i}].name", f"duplicate process name {proc.name!r}"))
            seen.add(proc.name)
        started: set[str] = set()
        step_ids: set[str] = set()
        for i, step in enumerate(self.steps):
            if step.id in step_ids:
                out.append((f"steps[{i}].id", f"duplicate step id {step.id!r}"))
            step_ids.add(step.id)
            for key in ("start", "stop"):
                value = getattr(step, key)
                for name in (value.root if value is not None else ()):
                    if name not in names:
                        out.append((f"steps[{i}].{key}", f"no process {name!r} in this scenario"
                                    + suggest(name, names)))
                    elif key == "start":
                        started.add(name)
                        if self.process(name).autostart:
                            out.append((f"steps[{i}].start", f"process {name!r} already starts with "
                                        "the scenario; set 'autostart: false' on it"))
            proc_ref = getattr(step.until, "process", None)
            if proc_ref is not None and proc_ref not in names:
                out.append((f"steps[{i}].until.process", f"no process {proc_ref!r} in this scenario"
                            + suggest(proc_ref, names)))
        for i, proc in enumerate(self.processes):
            if not proc.autostart and proc.name not in started:
                out.append((f"processes[{i}]", f"process {proc.name!r} has autostart: false but no "
                            "step starts it"))
        if self.limits.wall_s is not None and self.budget_s > self.limits.wall_s:
            out.append(("limits.wall_s", f"the steps may take up to {self.budget_s:g} s (start delays + "
                        f"step limits) but wall_s is {self.limits.wall_s:g}; raise it or shorten the steps"))
        return out
