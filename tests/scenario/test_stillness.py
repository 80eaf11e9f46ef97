"""``give_up_still`` of ``until: goal_reached``: when a turtle's stillness decides its step."""

from __future__ import annotations

from types import SimpleNamespace

from grader.scenario import model as m
from grader.scenario.conditions import GoalReached
from grader.scenario.steps import StepState
from grader.scenario.stillness import stillness_watch


def watcher(limit: float = 2.0):
    clock = SimpleNamespace(t=0.0)
    commands = [0, None]
    driver = SimpleNamespace(commands={"/turtle1/cmd_vel": commands}, clock=SimpleNamespace(now=lambda: clock.t))
    cond = GoalReached(condition="goal_reached", goal=[9.0, 9.0], give_up_still=limit)
    step = m.Step.model_validate({"id": "reach", "until": cond.model_dump(), "timeout": 30})
    state = StepState(step, t0=0.0)
    watch = stillness_watch(driver, cond, state)
    assert watch is not None
    return watch, state, clock, commands


def pose(x: float, y: float = 5.0, theta: float = 0.0):
    return SimpleNamespace(x=x, y=y, theta=theta)


def test_still_with_the_same_command_is_decided_after_the_limit() -> None:
    watch, state, clock, commands = watcher()
    commands[1] = (1.0, 0.0, 0.0)
    for k in range(200):                    # 16 ms ticks, 3.2 s at the same pose
        clock.t = k * 0.016
        watch(pose(11.09))
    assert state.decided and "stood still at (11.09, 5.00)" in state.decided


def test_moving_turning_or_changing_commands_is_not_still() -> None:
    watch, state, clock, commands = watcher()
    commands[1] = (1.0, 0.0, 0.5)
    for k in range(400):                    # turning on the spot: theta changes
        clock.t = k * 0.016
        watch(pose(5.0, theta=0.008 * k))
    assert state.decided is None
    for k in range(400):                    # still, but the controller's command keeps changing
        clock.t = 10 + k * 0.016
        commands[1] = (0.0, 0.0, 0.001 * k)
        watch(pose(5.0))
    assert state.decided is None
    commands[1] = None                      # still, but no command was ever heard
    watch2, state2, clock2, _ = watcher()
    for k in range(400):
        clock2.t = k * 0.016
        watch2(pose(5.0))
    assert state2.decided is None


def test_a_slow_creep_is_motion() -> None:
    watch, state, clock, commands = watcher()
    commands[1] = (0.003, 0.0, 0.0)
    for k in range(400):                    # 0.05 mm a tick: 0.3 mm a limit's worth of ticks
        clock.t = k * 0.016
        watch(pose(5.0 + 5e-5 * k))
    assert state.decided is None
