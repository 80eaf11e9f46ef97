"""Executing scenario steps: one handler per action class, and the step itself.

Dispatch is by type (``HANDLERS[type(step.do)]``, and ``CONDITIONS[type(step.until)]`` of
:mod:`grader.scenario.predicates`), so every class of ``grader.scenario.model`` has exactly one
implementation and a test can check that none is missing. What handlers and predicates share
is in :mod:`grader.scenario.runtime`; placed steps are in :mod:`grader.scenario.placement`,
replay pacing in :mod:`grader.scenario.pacing`.
"""

from __future__ import annotations

import contextlib
import time
import uuid
from typing import Any, Callable

from grader.scenario import model as m
from grader.contracts.events import Event
from grader.scenario.lockstep import LockstepFailed
from grader.scenario.messages import fill, import_type, to_plain
from grader.scenario.pacing import Pacer
from grader.scenario.placement import (SPAWN_SERVICE, SPAWN_TYPE, TELEPORT_TYPE, handoff_topic, place_and_hold,
                                      placement_topic, teleport_service)
from grader.scenario.predicates import CONDITIONS, GRAPH_CONDITIONS, GRAPH_SETTLE_S
from grader.scenario.runtime import Runtime, StepState
from grader.scenario.client_gid import client_gid


# ----------------------------------------------------------------------------------- actions
def _publish_goal(rt: Runtime, step: m.Step, goal: m.Goal, state: StepState) -> dict[str, Any]:
    sc = rt.scenario
    assert sc.goal_topic and sc.goal_type   # the model requires them for goal steps
    pub = rt.driver.publisher(sc.goal_topic, sc.goal_type)
    msg = import_type(sc.goal_type)()
    if sc.goal_type.endswith("Float32MultiArray"):
        msg.data = [float(goal.x), float(goal.y)]
    else:
        msg.x, msg.y = float(goal.x), float(goal.y)
    pub.publish(msg)
    rt.driver.event(Event.GOAL_SENT, step=step.id, goal=[goal.x, goal.y], topic=sc.goal_topic)
    return {"topic": sc.goal_topic, "goal": [goal.x, goal.y]}


def _publish(rt: Runtime, step: m.Step, spec: m.Publish, state: StepState) -> dict[str, Any]:
    pub = rt.driver.publisher(spec.topic, spec.type)
    msg = fill(import_type(spec.type)(), spec.msg)
    period = 1.0 / spec.rate_hz if spec.rate_hz else 0.0
    for i in range(spec.count):
        pub.publish(msg)
        if i + 1 < spec.count and period:
            rt.driver.clock.sleep(period)
    fields = {"topic": spec.topic, "type": spec.type, "msg": to_plain(msg), "count": spec.count}
    rt.driver.event(Event.MESSAGE_SENT, step=step.id, **fields)
    return fields


def _service(rt: Runtime, step: m.Step, spec: m.ServiceCall, state: StepState) -> dict[str, Any]:
    driver = rt.driver
    out: dict[str, Any] = {"service": spec.name}
    try:
        found = _server(rt, spec)
        if found is None:
            driver.event(Event.SERVICE_MISSING, step=step.id, service=spec.name)
            return out | {"available": False}
        name, type_name, client = found
        # under another name (``served_by``): the call's events carry the name used
        asked = {"asked_for": spec.name} if name != spec.name else {}
        request = fill(client.srv_type.Request(), spec.request)
        driver.event(Event.SERVICE_CALL, step=step.id, service=name, type=type_name,
                     request=to_plain(request), **asked, **_client_id(client))
        future = client.call_async(request)
        driver.wait_until(future.done, spec.response_timeout)
        response = to_plain(future.result()) if future.done() else None
        driver.event(Event.SERVICE_RESPONSE, step=step.id, service=name, response=response,
                     timed_out=not future.done(), **asked)
        return out | {"available": True, "type": type_name, "response": response, **asked}
    finally:
        state.service_done = True


def _server(rt: Runtime, spec: m.ServiceCall) -> tuple[str, str, Any] | None:
    """The service to call for ``spec`` (its name, type and the driver's client), or None when
    there is no server: ``spec.name``, else the one service of its own ``spec.served_by``
    advertises (remembered for the scenario's later calls)."""
    driver = rt.driver
    name = rt.service_names.get(spec.name, spec.name)
    type_name = spec.type
    if type_name is None:
        driver.wait_until(lambda: driver.service_type(name) is not None, spec.server_timeout,
                          wall=True)      # discovery takes wall time at any speed
        type_name = driver.service_type(name)
    if type_name is None and spec.served_by and name == spec.name:     # (a call without ``type``)
        other = driver.own_service(spec.served_by)
        other_type = driver.service_type(other) if other is not None else None
        if other is not None and other_type is not None:
            name, type_name = other, other_type
            rt.service_names[spec.name] = other
    if type_name is None:
        return None
    client = driver.service_client(import_type(type_name), name)
    if not client.wait_for_service(timeout_sec=spec.server_timeout):
        return None
    return name, type_name, client


def _client_id(client: Any) -> dict[str, Any]:
    """The ``client_gid`` of a ``service_call`` event: whose call a service event is, read off
    the event itself (see :mod:`grader.scenario.client_gid`); ``client_gid_error`` when the rmw
    could not say."""
    try:
        return {"client_gid": client_gid(client)}
    except (OSError, AttributeError) as exc:
        return {"client_gid": None, "client_gid_error": f"{type(exc).__name__}: {exc}"}


def _action_client(rt: Runtime, name: str, type_name: str) -> Any:
    """The driver's client of action ``name`` (made once per scenario, its status watched)."""
    from rclpy.action import ActionClient  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

    key = (name, type_name)
    if key not in rt.action_clients:
        rt.action_clients[key] = ActionClient(rt.driver.node, import_type(type_name), name)
        rt.driver.watch_action_status(name)
    return rt.action_clients[key]


def _action_server(rt: Runtime, spec: m.ActionGoal) -> tuple[str, Any, bool]:
    """The action to send ``spec``'s goal to: its name, the driver's client and whether the
    server was found; with ``by_type`` and no server of ``spec.name``, the one action of its
    type a student node serves (remembered for the scenario's later goals)."""
    name = rt.action_names.get(spec.name, spec.name)
    if spec.by_type and name == spec.name and not rt.driver.action_available(name):
        other = rt.driver.student_action_of_type(spec.type)
        if other is not None and other != name:
            name = rt.action_names[spec.name] = other
    client = _action_client(rt, name, spec.type)
    return name, client, bool(client.wait_for_server(timeout_sec=spec.server_timeout))


def _action(rt: Runtime, step: m.Step, spec: m.ActionGoal, state: StepState) -> dict[str, Any]:
    from unique_identifier_msgs.msg import UUID  # noqa: PLC0415 - unique_identifier_msgs: ROS, imported where it is used, so this module loads without a ROS install

    driver = rt.driver
    name, client, found = _action_server(rt, spec)
    # under another name (``by_type``): the goal's events carry the name used
    asked = {"asked_for": spec.name} if name != spec.name else {}
    driver.event(Event.ACTION_SERVER_FOUND if found else Event.ACTION_SERVER_MISSING,
                 step=step.id, action=name, **asked)
    if not found:
        state.action_done = True
        return {"server": False}
    goal = fill(import_type(spec.type).Goal(), spec.goal)
    goal_uuid = UUID(uuid=list(uuid.uuid4().bytes))
    driver.event(Event.ACTION_GOAL_SENT, step=step.id, action=name, goal=to_plain(goal), **asked)
    result: dict[str, Any] = {"server": True, **asked}

    def on_result(future: Any) -> None:
        res = future.result()
        result.update(status=int(res.status), result=to_plain(res.result))
        driver.event(Event.ACTION_RESULT, step=step.id, action=name, status=int(res.status),
                     result=to_plain(res.result), **asked)
        state.action_done = True

    def accepted(handle: Any, **extra: Any) -> None:
        result["accepted"] = bool(handle.accepted)
        driver.event(Event.ACTION_GOAL_RESPONSE, step=step.id, action=name,
                     accepted=bool(handle.accepted), **asked, **extra)
        if handle.accepted:
            state.goal_handle = handle
            handle.get_result_async().add_done_callback(on_result)
        else:
            state.action_done = True

    with driver.executor_paused():           # see Driver.executor_paused (a lost goal response)
        client.send_goal_async(goal, goal_uuid=goal_uuid).add_done_callback(lambda f: accepted(f.result()))
    if not driver.wait_until(lambda: "accepted" in result, spec.response_timeout):
        # no goal response: the server's status topic says whether it accepted the goal anyway
        status = driver.action_status(name, bytes(goal_uuid.uuid))
        if status is None:
            driver.event(Event.ACTION_GOAL_UNANSWERED, step=step.id, action=name,
                         waited_s=spec.response_timeout, **asked)
            state.action_done = True
        else:
            from rclpy.action.client import ClientGoalHandle  # noqa: PLC0415 - rclpy: ROS, imported where it is used, so this module loads without a ROS install

            response = client._action_type.Impl.SendGoalService.Response(accepted=True)
            with driver.executor_paused():
                accepted(ClientGoalHandle(client, goal_uuid, response), recovered_from_status=status)
    return result


def replay_topics(spec: m.Replay) -> list[str]:
    """The topics a replay step publishes: its ``topics``, else every topic of the bag except
    the grader's own, logging, parameter events, service events and action internals."""
    from grader.bag.reader import open_bag  # noqa: PLC0415 - bag.reader loads numpy (147 ms CPU), only on this path

    if spec.topics:
        return list(spec.topics)
    names = open_bag(spec.bag).topics
    return sorted(t for t in names if not (t.startswith("/grader/") or t in ("/rosout", "/parameter_events")
                                           or t.endswith("/_service_event") or "/_action/" in t))


def _replay(rt: Runtime, step: m.Step, spec: m.Replay, state: StepState) -> dict[str, Any]:
    """Publish the recorded messages (their CDR bytes, untouched) at the recorded timing or at
    ``rate_hz``; with ``lead``, never more than that many messages ahead of the student's output."""
    from grader.bag.replay import plan  # noqa: PLC0415 - bag.replay loads numpy (147 ms CPU), only on this path

    driver = rt.driver
    topics = replay_topics(spec)
    p = plan(spec.bag, topics)
    pubs = [driver.publisher(name, type_name) for _, name, type_name, _ in p.topics]
    n = len(p.payloads) if spec.count is None else min(spec.count, len(p.payloads))
    driver.event(Event.REPLAY_START, step=step.id, topics=topics, count=n, rate_hz=spec.rate_hz,
                 bag=str(spec.bag))
    pacer = None if spec.lead is None else Pacer(spec.lead, spec.lead_wait_s, spec.lead_budget_s,
                                                 driver.output_count())

    def offset(k: int) -> float:
        """Seconds from the first message to message ``k`` on the replay's schedule."""
        return k / spec.rate_hz if spec.rate_hz else (p.times[k] - p.times[0]) / 1e9

    def wait(predicate: Callable[[], bool], timeout: float) -> tuple[bool, float]:
        # the student's processing takes wall time: it gets the 1x allowance at any speed
        t = time.monotonic()
        met = driver.wait_until(predicate, timeout, poll=0.002, wall=True, react=True)
        return met, time.monotonic() - t

    clock = driver.clock
    t_start = t0 = clock.now()
    base = driver.output_count()
    for i in range(n):
        pubs[p.pubs[i]].publish(p.payloads[i])
        if i + 1 < n:
            clock.sleep_until(t0 + offset(i + 1))
        if pacer is not None:
            pacer.after(i, driver.output_count, wait, rt.students_gone)
        if i + 1 < n:
            t0 = max(t0, clock.now() - offset(i + 1))   # no burst after waiting for the student
    driver.last_output = time.monotonic()
    state.replay_done = True
    driver.event(Event.REPLAY_END, step=step.id, count=n, outputs=driver.output_count() - base,
                 **(pacer.summary() if pacer is not None else {"paced": False}),
                 duration_s=round(clock.now() - t_start, 3))
    return {"topics": topics, "count": n}


def _start(rt: Runtime, step: m.Step, spec: m.Start, state: StepState) -> dict[str, Any]:
    return {"started": [name for proc in spec.root for name in rt.start(proc)]}


def _stop(rt: Runtime, step: m.Step, spec: m.Stop, state: StepState) -> dict[str, Any]:
    codes: dict[str, Any] = {}
    for proc_name in spec.root:
        for name in rt.members.get(proc_name, []):
            proc = rt.driver.processes.get(name)
            codes[name] = proc.stop() if proc else None
            rt.driver.event(Event.NODE_STOPPED, process=name, returncode=codes[name])
    return {"returncodes": codes}


HANDLERS: dict[type, Callable[[Runtime, m.Step, Any, StepState], dict[str, Any]]] = {
    m.Goal: _publish_goal, m.Publish: _publish, m.ServiceCall: _service, m.ActionGoal: _action,
    m.Replay: _replay, m.Start: _start, m.Stop: _stop,
}


def prepare(rt: Runtime) -> None:
    """Create the driver's publishers, counters and service clients before student nodes start,
    so the recorder and the servers have matched them by the time anything is sent. A server
    answers a client whose response reader it has not matched yet only once it has (the rmw
    waits for it, asleep): in lockstep the clock ticked on meanwhile, and a placement's first
    teleport, by a client made at the call, was answered 0 or 4 ticks after it from run to run
    (a Lab 3 class graded three times: the same poses, shifted)."""
    sc = rt.scenario
    for step in sc.steps:
        if step.goal is not None and sc.goal_topic and sc.goal_type:
            rt.driver.publisher(sc.goal_topic, sc.goal_type)
        if step.publish is not None:
            rt.driver.publisher(step.publish.topic, step.publish.type)
        if step.replay is not None:
            from grader.bag.reader import open_bag  # noqa: PLC0415 - bag.reader loads numpy (147 ms CPU), only on this path
            bag = open_bag(step.replay.bag)
            for topic in replay_topics(step.replay):
                rt.driver.publisher(topic, bag.topics[topic].type)
        if isinstance(step.until, m.Messages):
            rt.driver.count_messages(step.until.topic, None, wait_s=0.0)
        if isinstance(step.until, m.GoalReached):
            rt.driver.watch_pose(step.until.pose_topic)
            if step.until.give_up_still is not None:
                rt.driver.watch_commands(step.until.cmd_topic)
        if step.place is not None:
            rt.driver.watch_pose(placement_topic(step.place))
            rt.driver.watch_commands(handoff_topic(step.place))
            rt.driver.service_client(import_type(TELEPORT_TYPE), teleport_service(step.place))
            if step.place.spawn:
                rt.driver.service_client(import_type(SPAWN_TYPE), SPAWN_SERVICE)
        if step.service is not None and step.service.type is not None:
            rt.driver.service_client(import_type(step.service.type), step.service.name)


# -------------------------------------------------------------------------------------- a step
def action_name(step: m.Step) -> str:
    """The step's action as its YAML key (``publish``, ``service``...), ``wait`` or ``until``."""
    for key in m.ACTION_KEYS:
        if getattr(step, key) is not None:
            return key
    return "wait" if step.wait is not None else "until"


def run_step(rt: Runtime, step: m.Step) -> dict[str, Any]:
    """Do the step's action, then wait for its condition (or its whole limit); the record."""
    driver = rt.driver
    state = StepState(step, t0=driver.clock.now())
    kind = action_name(step)
    # conditions that count from the step's start are armed before the action runs
    predicate = CONDITIONS[type(step.until)](rt, step.until, state) if step.until is not None else None
    start_wall = time.time()
    driver.event(Event.STEP_START, step=step.id, action=kind)
    ended_by = "done"
    action = step.do
    handoff = contextlib.ExitStack()
    if step.place is not None:
        place_and_hold(rt, step, step.place, state, handoff, _service)
    if step.target is not None and not isinstance(action, m.Goal):
        # a goal set some other way (e.g. a service call): it is active from before the action,
        # so whatever the student's nodes do in answer (even a teleport) falls inside its window
        driver.event(Event.GOAL_SENT, step=step.id, goal=[step.target.x, step.target.y], topic=None)
    if action is not None:
        try:
            state.detail = {**state.detail, **HANDLERS[type(action)](rt, step, action, state)}
        except LockstepFailed:
            raise                          # the whole run goes to the wall clock, not this step
        except Exception as exc:  # noqa: BLE001 - a bad step must not kill the whole run
            state.detail = {"error": f"{type(exc).__name__}: {exc}"}
            ended_by = "error"
    handoff.close()
    if ended_by != "error":
        remaining = max(0.0, step.limit_s - (driver.clock.now() - state.t0))
        if predicate is None:
            ended_by = "students_exited" if driver.wait_until(rt.students_gone, remaining) else "done"
        else:
            # in lockstep a wait on discovery does not tick (wall seconds): how long DDS takes
            # must not decide at which tick the scenario goes on; then a moment for the
            # endpoints the graph shows to be matched, still without a tick
            graph = driver.clock.lockstep and isinstance(step.until, GRAPH_CONDITIONS)
            driver.wait_until(lambda: predicate() or rt.students_gone() or state.decided is not None,
                              remaining, wall=graph)
            if graph:
                time.sleep(GRAPH_SETTLE_S)
            ended_by = ("condition" if predicate() else "students_exited" if rt.students_gone() else
                        "decided" if state.decided is not None else "timeout")
            if ended_by == "decided":
                state.detail = {**state.detail, "ended_early": state.decided}
    if isinstance(action, m.ActionGoal) and ended_by == "timeout" and state.goal_handle is not None:
        state.goal_handle.cancel_goal_async()
        driver.event(Event.ACTION_CANCEL_SENT, step=step.id)
    duration = driver.clock.now() - state.t0
    driver.graph_snapshot()
    driver.event(Event.STEP_END, step=step.id, action=kind, ended_by=ended_by, duration_s=round(duration, 3))
    return {"id": step.id, "action": kind, "start": start_wall, "duration_s": round(duration, 3),
            "ended_by": ended_by, "detail": state.detail}
