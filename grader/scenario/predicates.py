"""One predicate per ``until:`` condition class: when a step's condition holds.

``CONDITIONS[type(step.until)]`` makes the step's predicate before its action runs (a condition
that counts from the step's start is armed then); :func:`grader.scenario.steps.run_step` waits on it.
"""

from __future__ import annotations

import math
import re
from typing import Any, Callable, cast

from grader.scenario import model as m
from grader.scenario.runtime import Runtime, StepState
from grader.scenario.stillness import stillness_watch

Predicate = Callable[[], bool]


def _goal_reached(rt: Runtime, cond: m.GoalReached, state: StepState) -> Predicate:
    """Turtle within ``tolerance`` of the goal and, for ``settle`` s, never farther."""
    goal = state.step.target
    assert goal is not None            # the model requires one
    since: list[float | None] = [None]
    still = stillness_watch(rt.driver, cond, state)

    def check() -> bool:
        pose = rt.driver.poses.get(cond.pose_topic)
        if pose is None or math.hypot(pose.x - goal.x, pose.y - goal.y) > cond.tolerance:
            since[0] = None
            if pose is not None and still is not None:
                still(pose)
            return False
        now = rt.driver.clock.now()
        since[0] = since[0] or now
        return now - cast(float, since[0]) >= cond.settle

    return check


def _process_exit(rt: Runtime, cond: m.ProcessExit, state: StepState) -> Predicate:
    return lambda: all(p.returncode is not None for p in rt.processes_of(cond.process))


def _output(rt: Runtime, cond: m.Output, state: StepState) -> Predicate:
    pattern = re.compile(cond.pattern)
    lines = rt.driver.lines
    start = {n: len(lines.get(n, [])) for n in rt.members.get(cond.process, [])}

    def check() -> bool:
        for name in rt.members.get(cond.process, []):
            if any(pattern.search(line) for line in lines.get(name, [])[start.get(name, 0):]):
                return True
        return False

    return check


def _messages(rt: Runtime, cond: m.Messages, state: StepState) -> Predicate:
    """Counts the messages the recorder has written on the topic since the step began: the
    messages that end the step are in the bag. (Counting what the driver heard ended a step on a
    10 Hz talker's first 3 messages while the bag had none of them. Counting what it heard once
    the recorder's subscription showed the talker matched still ended one with 2 of them in the
    bag, in a fresh clone's make test: DDS matches each side of a pair on its own, and the
    talker's writer had not yet matched the recorder's reader.) A topic this recording does not
    take is counted as the driver hears it."""
    driver, topic = rt.driver, cond.topic
    driver.count_messages(topic, None, wait_s=0.0)
    in_bag = driver.recorded_count
    if in_bag is not None and (base := in_bag(topic)) is not None:
        return lambda: (in_bag(topic) or 0) - base >= cond.count
    heard = driver.counts.get(topic, 0)
    return lambda: driver.counts.get(topic, 0) - heard >= cond.count


def _advertised(rt: Runtime, cond: m.Advertised, state: StepState) -> Predicate:
    driver = rt.driver
    if cond.topic is not None:
        topic = cond.topic
        # advertised *and* recorded: the recorder's subscription in place and matched with
        # every publisher of the topic (the graph shows it before DDS has matched them)
        return lambda: driver.student_publishes(topic) and all(
            driver.recorder_matched(n) for n in driver.student_nodes()) and driver.topic_recorded(topic)
    if cond.service is not None:
        service = cond.service
        return lambda: driver.service_type(service) is not None
    action, action_type = cond.action or "", cond.action_type if cond.by_type else None
    if action_type is None:
        return lambda: driver.action_available(action)
    return lambda: driver.action_available(action) or driver.student_action_of_type(action_type) is not None


#: conditions on the ROS graph (discovery), not on what happens in simulated time
GRAPH_CONDITIONS = (m.Advertised, m.Subscribed)
#: lockstep: wall seconds after a graph condition holds before the next tick (DDS matches the
#: endpoints the graph shows a little later; every participant hears of them at the same time)
GRAPH_SETTLE_S = 0.3

CONDITIONS: dict[type, Callable[[Runtime, Any, StepState], Predicate]] = {
    m.GoalReached: _goal_reached,
    m.ActionDone: lambda rt, cond, state: (lambda: state.action_done),
    m.ServiceDone: lambda rt, cond, state: (lambda: state.service_done),
    m.ReplayDone: lambda rt, cond, state: (lambda: state.replay_done),
    m.ProcessExit: _process_exit,
    m.Output: _output,
    m.Messages: _messages,
    m.Advertised: _advertised,
    m.Subscribed: lambda rt, cond, state: (lambda: rt.driver.student_subscribes(cond.topic)),
}
