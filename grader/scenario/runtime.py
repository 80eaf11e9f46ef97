"""What a step's handler and its condition's predicate share: the step's state and the runtime.

On a floor of its own, below :mod:`grader.scenario.steps` (the handlers),
:mod:`grader.scenario.predicates` (the conditions) and :mod:`grader.scenario.placement`, which
all take them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

from grader.scenario import model as m
from grader.scenario.driver import Driver
from grader.scenario.runspec import ScenarioRun


@dataclass
class StepState:
    """What a step's action leaves for its condition (and the step record)."""

    step: m.Step
    t0: float = field(default_factory=time.monotonic)   # scenario time the step began
    action_done: bool = False
    service_done: bool = False
    replay_done: bool = False
    goal_handle: Any = None
    detail: dict[str, Any] = field(default_factory=dict)
    #: why the step's outcome was decided before its condition or limit (an early end)
    decided: str | None = None


class Runtime:
    """What handlers need besides the driver: the scenario, its processes, how to start them."""

    def __init__(self, driver: Driver, run: ScenarioRun,
                 start: Callable[[str], list[str]], members: dict[str, list[str]]) -> None:
        self.driver = driver
        self.run = run
        self.scenario = run.scenario
        self.start = start                # rubric process name -> names of OS processes started
        self.members = members            # rubric process name -> its OS process names so far
        self.action_clients: dict[tuple[str, str], Any] = {}
        #: a service's name -> the name its server uses instead (``ServiceCall.served_by``)
        self.service_names: dict[str, str] = {}
        #: an action's name -> the name its server uses instead (``ActionGoal.by_type``)
        self.action_names: dict[str, str] = {}

    def processes_of(self, name: str) -> list[Any]:
        return [self.driver.processes[n] for n in self.members.get(name, []) if n in self.driver.processes]

    def students_gone(self) -> bool:
        procs = list(self.driver.processes.values())
        return bool(procs) and not any(p.alive() for p in procs)
