"""The driver's events, defined once: one pydantic model per kind. The driver builds them and
emits them on ``/grader/events`` (one JSON object each); the pipeline, the analyzers, the reports
and the similarity features read them back from the bag with :func:`parse_event`, as models.

Pure (pydantic only, no rclpy), so every floor may import it. Each event is
``{"event": <kind>, "wall": <epoch s>, ...fields}``; a reader gets ``t`` too, the bag's receive time
of the message (the simulated clock's when the run was on simulated time). Every field has a
default: a recording made before a field existed still parses, and the default says what such a
recording meant (``running: None``: the graph snapshot did not say which processes were alive).
A record that does not fit its kind's model (a hand-made or damaged bag) is kept as a plain
:class:`EventRecord`: no typed reader sees it, none crashes on it.
"""

from __future__ import annotations

from enum import StrEnum
from typing import ClassVar

from pydantic import BaseModel, ConfigDict, ValidationError
from grader.contracts.values import JsonValue

EVENTS_TOPIC = "/grader/events"
STDOUT_TOPIC = "/grader/stdout"


class Event(StrEnum):
    # scenario
    SCENARIO_START = "scenario_start"
    SCENARIO_END = "scenario_end"
    SCENARIO_ABORTED = "scenario_aborted"
    SCENARIO_INTERRUPTED = "scenario_interrupted"
    SCENARIO_ERROR = "scenario_error"
    # steps
    STEP_START = "step_start"
    STEP_END = "step_end"
    STEP_SKIPPED = "step_skipped"
    GOAL_SENT = "goal_sent"
    MESSAGE_SENT = "message_sent"
    SERVICE_CALL = "service_call"
    SERVICE_RESPONSE = "service_response"
    SERVICE_MISSING = "service_missing"
    ACTION_SERVER_FOUND = "action_server_found"
    ACTION_SERVER_MISSING = "action_server_missing"
    ACTION_GOAL_SENT = "action_goal_sent"
    ACTION_GOAL_RESPONSE = "action_goal_response"
    ACTION_GOAL_UNANSWERED = "action_goal_unanswered"
    ACTION_RESULT = "action_result"
    ACTION_CANCEL_SENT = "action_cancel_sent"
    TURTLES_HELD = "turtles_held"
    TURTLES_RELEASED = "turtles_released"
    REPLAY_START = "replay_start"
    REPLAY_END = "replay_end"
    # processes
    NODE_STARTED = "node_started"
    NODE_UNAVAILABLE = "node_unavailable"
    NODE_STOPPED = "node_stopped"
    PROCESS_EXIT = "process_exit"
    STDIN_READY = "stdin_ready"
    STDIN_LINE = "stdin_line"
    LAUNCH_RESOLVED = "launch_resolved"
    PACKAGES = "packages"
    LIMIT_HIT = "limit_hit"
    # the ROS graph
    GRAPH = "graph"


class EventRecord(BaseModel):
    """What every event has; a record of no known kind (or one that does not fit its kind) stays
    this. Fields a model does not declare are kept (``model_extra``): a reader never loses them,
    the emitter refuses them (:func:`build_event`)."""

    model_config = ConfigDict(extra="allow", frozen=True)
    KIND: ClassVar[Event | None] = None

    event: str
    wall: float | None = None
    #: the bag's receive time of the message (set by the reader; 0 while the driver builds it)
    t: float = 0.0


class StepEvent(EventRecord):
    """An event of a scenario step: ``step`` is its rubric id."""

    step: str = ""


class ScenarioStart(EventRecord):
    KIND = Event.SCENARIO_START
    scenario: str = ""
    domain_id: int | None = None
    #: the reference simulator's node name: never a student's node
    sim_node: str | None = None


class ScenarioEnd(EventRecord):
    KIND = Event.SCENARIO_END
    scenario: str = ""


class ScenarioAborted(StepEvent):
    """The step's condition never held and its ``on_timeout`` is ``abort``."""
    KIND = Event.SCENARIO_ABORTED


class ScenarioInterrupted(EventRecord):
    """Ctrl-C or SIGTERM of the batch."""
    KIND = Event.SCENARIO_INTERRUPTED


class ScenarioError(EventRecord):
    KIND = Event.SCENARIO_ERROR
    error: str = ""


class StepStart(StepEvent):
    KIND = Event.STEP_START
    action: str = ""


class StepEnd(StepEvent):
    KIND = Event.STEP_END
    action: str = ""
    ended_by: str = ""
    duration_s: float | None = None


class StepSkipped(StepEvent):
    KIND = Event.STEP_SKIPPED
    reason: str = ""
    #: each student process's exit code (None: still running)
    exited: dict[str, int | None] = {}


class GoalSent(StepEvent):
    KIND = Event.GOAL_SENT
    #: [x, y]
    goal: list[float] = []
    #: the topic it was published on; None: set by a service
    topic: str | None = None


class MessageSent(StepEvent):
    KIND = Event.MESSAGE_SENT
    topic: str = ""
    type: str = ""
    msg: JsonValue = None
    count: int = 1


class Asked(StepEvent):
    """``asked_for``: the rubric's name when the call or goal went to another name (the name the
    ``served_by`` node uses, or another action server of the same type: ``ActionGoal.by_type``)."""

    asked_for: str | None = None


class ServiceCall(Asked):
    """``client_gid``: the rmw GID of the calling client (16 ints); a service event whose
    ``info.client_gid`` has its first 12 bytes, the DDS participant, is the driver's call. None
    (with ``client_gid_error``) when the rmw could not say or the recording is older."""
    KIND = Event.SERVICE_CALL
    service: str = ""
    type: str = ""
    request: dict[str, JsonValue] = {}
    client_gid: list[int] | None = None
    client_gid_error: str | None = None


class ServiceResponse(Asked):
    KIND = Event.SERVICE_RESPONSE
    service: str = ""
    #: None: no response in time
    response: dict[str, JsonValue] | None = None
    timed_out: bool = False


class ServiceMissing(StepEvent):
    KIND = Event.SERVICE_MISSING
    service: str = ""


class ActionEvent(Asked):
    """``action``: the name the goal went to."""

    action: str = ""


class ActionServerFound(ActionEvent):
    KIND = Event.ACTION_SERVER_FOUND


class ActionServerMissing(ActionEvent):
    KIND = Event.ACTION_SERVER_MISSING


class ActionGoalSent(ActionEvent):
    KIND = Event.ACTION_GOAL_SENT
    goal: dict[str, JsonValue] = {}


class ActionGoalResponse(ActionEvent):
    KIND = Event.ACTION_GOAL_RESPONSE
    accepted: bool = False
    #: the goal status read from the status topic when no goal response came
    recovered_from_status: int | None = None


class ActionGoalUnanswered(ActionEvent):
    """No goal response and no status within ``waited_s``."""
    KIND = Event.ACTION_GOAL_UNANSWERED
    waited_s: float | None = None


class ActionResult(ActionEvent):
    KIND = Event.ACTION_RESULT
    status: int | None = None
    result: dict[str, JsonValue] = {}


class ActionCancelSent(StepEvent):
    KIND = Event.ACTION_CANCEL_SENT


class TurtlesHeld(StepEvent):
    """The simulator holds every turtle still (``ok``: it said so)."""
    KIND = Event.TURTLES_HELD
    ok: bool = False


class TurtlesReleased(StepEvent):
    """The turtles move again after ``held_s``."""
    KIND = Event.TURTLES_RELEASED
    ok: bool = False
    held_s: float | None = None


class ReplayStart(StepEvent):
    KIND = Event.REPLAY_START
    topics: list[str] = []
    count: int = 0
    rate_hz: float | None = None
    bag: str = ""


class ReplayEnd(StepEvent):
    KIND = Event.REPLAY_END
    count: int = 0
    #: student messages published while it replayed
    outputs: int = 0
    paced: bool = False
    resyncs: int = 0
    waited_s: float = 0.0
    duration_s: float | None = None


class ProcessEvent(EventRecord):
    """``process``: the name of a student process the grader started (``<rubric process>`` or,
    for a launch file's node, ``<rubric process>/<node>``)."""

    process: str = ""


class NodeEvent(ProcessEvent):
    """A student process of a rubric process (``of``) and what starts it: the rubric's package,
    executable, module or launch file, and the node name a launch file gives it."""

    of: str | None = None
    package: str | None = None
    executable: str | None = None
    module: str | None = None
    launch: str | None = None
    node_name: str | None = None


class NodeStarted(NodeEvent):
    KIND = Event.NODE_STARTED
    argv: list[str] = []


class NodeUnavailable(NodeEvent):
    KIND = Event.NODE_UNAVAILABLE
    #: why it could not be started
    error: str | None = None


class NodeStopped(ProcessEvent):
    KIND = Event.NODE_STOPPED
    returncode: int | None = None


class ProcessExit(ProcessEvent):
    KIND = Event.PROCESS_EXIT
    returncode: int | None = None
    stopped_by_grader: bool = False
    timed_out: bool = False


class StdinReady(ProcessEvent):
    """The process's nodes are up: its scripted standard input may be typed."""
    KIND = Event.STDIN_READY
    nodes: list[str] = []


class StdinLine(ProcessEvent):
    KIND = Event.STDIN_LINE
    line: str = ""
    #: False: the process had closed its input (a recording without it: delivered)
    delivered: bool = True


class LaunchResolved(ProcessEvent):
    KIND = Event.LAUNCH_RESOLVED
    #: the launch file found
    launch: str | None = None
    installed: bool = False
    notes: list[str] = []
    #: the nodes it declares (name, node_name, package, executable, stand_in, error, start_delay)
    nodes: list[dict[str, JsonValue]] = []


class Packages(EventRecord):
    """The build's packages: ``{name: {status, executables, launch_files, ...}}``."""
    KIND = Event.PACKAGES
    packages: dict[str, dict[str, JsonValue]] = {}


class LimitHit(EventRecord):
    KIND = Event.LIMIT_HIT
    #: memory | processes | cpu | output
    limit: str = ""
    detail: str = ""
    process: str | None = None
    stream: str | None = None
    count: int | None = None
    seconds: float | None = None


class Graph(EventRecord):
    """A snapshot of the ROS graph: names, and who publishes, subscribes and serves what."""
    KIND = Event.GRAPH
    nodes: list[str] = []
    publishers: dict[str, list[str]] = {}
    subscribers: dict[str, list[str]] = {}
    services: list[str] = []
    topic_types: dict[str, list[str]] = {}
    #: None: recorded before servers were
    servers: dict[str, list[str]] | None = None
    service_types: dict[str, list[str]] = {}
    #: the student processes still alive once the graph was read; None: recorded before it was
    running: list[str] | None = None


def _kinds() -> dict[str, type[EventRecord]]:
    found: dict[str, type[EventRecord]] = {}
    todo: list[type[EventRecord]] = [EventRecord]
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        if cls.KIND is not None:
            found[str(cls.KIND)] = cls
    return found


#: the model of each kind
MODELS: dict[str, type[EventRecord]] = _kinds()
assert set(MODELS) == {str(k) for k in Event}, "every Event has its model"


def parse_event(data: dict[str, JsonValue], t: float = 0.0) -> EventRecord:
    """The model of one event as recorded (``t``: its receive time); a record that does not fit
    its kind's model is a plain :class:`EventRecord` (see the module's docstring)."""
    record = {**data, "t": t}
    model = MODELS.get(str(data.get("event")))
    if model is not None:
        try:
            return model.model_validate(record)
        except ValidationError:
            pass
    try:
        return EventRecord.model_validate(record)
    except ValidationError:
        return EventRecord.model_validate({"event": str(data.get("event")), "t": t})


class EventFieldError(TypeError):
    """The driver built an event with a field its model does not declare (a programming error)."""


def build_event(kind: Event, wall: float, fields: dict[str, JsonValue]) -> EventRecord:
    """The model of an event the driver is about to emit; ``fields`` must be JSON already (the
    driver round-trips them). A field the model does not know is refused, so every field an
    event carries is declared here."""
    record = MODELS[str(kind)].model_validate({"event": str(kind), "wall": wall, **fields})
    if record.model_extra:
        raise EventFieldError(f"{kind} has no field(s) {sorted(record.model_extra)}: declare them in "
                              "grader/contracts/events.py")
    return record
