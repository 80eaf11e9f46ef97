"""When a goal step is decided before its limit: the turtle at a fixed point (``give_up_still``).

Turtlesim is deterministic: the same pose and the same command give the same next pose. A
controller whose commands follow the pose (and the goal) therefore stays at a fixed point once
the turtle stands still with its commands unchanged, away from the goal: pinned against a wall,
or sent zero. Waiting out the step's limit there changes no measurement but the time it took
(Lab 3's ``ex2_controller`` held a buggy controller 4 x 60 s of simulated time). A rubric that
knows its controllers are of that kind says so on the condition
(``until: {condition: goal_reached, give_up_still: S}``); the step then ends ``decided`` and the
result lists the early end with its reason.
"""

from __future__ import annotations

from typing import Any, Callable

from grader.scenario.conditions import GoalReached

#: a pose this close to the one the stillness is measured from (m, rad) has not moved
STILL_M = 1e-4


def stillness_watch(driver: Any, cond: GoalReached, state: Any) -> Callable[[Any], None] | None:
    """A function of the current pose (called while the turtle is away from the goal) that sets
    ``state.decided`` once the turtle has stood still, with its commands on ``cond.cmd_topic``
    unchanged, for ``cond.give_up_still`` seconds of scenario time; None when the condition does
    not ask. A turtle that never received a command is not decided (a controller may start late)."""
    if cond.give_up_still is None:
        return None
    limit = cond.give_up_still
    commands = driver.commands.get(cond.cmd_topic)
    mark: list[Any] = [None, None, 0.0]          # pose, command, scenario time since both held

    def watch(pose: Any) -> None:
        now = driver.clock.now()
        here = (pose.x, pose.y, pose.theta)
        command = None if commands is None else commands[1]
        moved = mark[0] is None or any(abs(a - b) > STILL_M for a, b in zip(here, mark[0]))
        if moved or command != mark[1] or command is None:
            mark[:] = [here, command, now]
            return
        if now - mark[2] >= limit and state.decided is None:
            state.decided = (f"the turtle stood still at ({here[0]:.2f}, {here[1]:.2f}) with unchanged "
                             f"commands for {limit:g} s, away from the goal (give_up_still)")

    return watch
