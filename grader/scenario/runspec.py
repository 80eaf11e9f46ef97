"""What crosses to the scenario child: the rubric's ``Scenario`` as it is (``grader.scenario.model``),
plus what the parent resolved against the build. ``ScenarioRun`` is serialised with
``model_dump_json`` by the grading pipeline and read back with ``ScenarioRun.model_validate_json``
by ``grader.scenario.run``; the other classes are its parts (the OS processes a rubric process
became, the packages the build made, the publish rates the watchdog checks).

Apart from ``model``, which is the rubric's scenario language (what an author writes); these are
what the grader fills in, never written in a rubric.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import Field

from grader.contracts.fields import Model, NonNegativeFloat, PositiveFloat, RosName
from grader.scenario.model import Scenario


class LaunchedProcess(Model):
    """One OS process the child starts for a rubric process (a launch file gives several)."""

    name: str                          # unique in the scenario: "server", "app.goal_setter"
    process: str                       # the rubric process it belongs to
    argv: Annotated[tuple[str, ...], Field(strict=False)] = ()
    env: dict[str, str] = {}
    start_delay: NonNegativeFloat = 0.0   # after its rubric process started (launch TimerAction)
    node_name: str | None = None       # the node name a launch file gave it
    package: str | None = None         # what a launch file declared (for "starts these nodes")
    executable: str | None = None
    stand_in: bool = False             # played by the grader's reference simulator: not started
    error: str = ""                    # why it cannot run (build failed, no such executable...)


class RateExpectation(Model):
    """A publish rate the rubric expects on a topic (a ``publish_rate`` item of the scenario):
    on simulated time the watchdog checks that the student's node keeps it in simulated time."""

    topic: RosName
    expected_hz: PositiveFloat
    rel_tol: PositiveFloat = 0.3


class PackageFacts(Model):
    """What the build made of one package of the submission: the names a contract may fix."""

    status: str                        # built | failed | skipped
    executables: Annotated[tuple[str, ...], Field(strict=False)] = ()
    launch_files: Annotated[tuple[str, ...], Field(strict=False)] = ()
    #: executables it installed under another package's lib/ folder (``lib/<other>/<name>``)
    stray_executables: Annotated[tuple[str, ...], Field(strict=False)] = ()


class ScenarioRun(Model):
    """What crosses to the scenario child: the rubric's scenario as it is, plus what the parent
    resolved against the build (argv of every process, install prefixes, the simulator's name)
    and how fast to run it (``time_scale`` > 1: on simulated time, see grader.scenario.simtime;
    ``lockstep``: on the simulator's lockstep clock, see grader.scenario.lockstep)."""

    id: str
    scenario: Scenario
    launched: dict[str, Annotated[tuple[LaunchedProcess, ...], Field(strict=False)]]  # rubric process -> OS processes
    prefixes: Annotated[tuple[str, ...], Field(strict=False)] = ()
    #: the grader's own builds of the build's interface packages: the only student types grader
    #: processes import (``grader.workspace.trusted_interfaces``)
    interfaces: Annotated[tuple[str, ...], Field(strict=False)] = ()
    sim_node: str = "turtlesim"
    notes: dict[str, Annotated[tuple[str, ...], Field(strict=False)]] = {}  # process -> remarks (launch)
    launch_installed: dict[str, bool] = {}   # process -> its launch file is in the package's share
    time_scale: Annotated[float, Field(ge=1.0, le=16.0, strict=False)] = 1.0   # 1: the wall clock
    lockstep: bool = False                   # run on the simulator's lockstep clock (grader.scenario.lockstep)
    expected_rates: Annotated[tuple[RateExpectation, ...], Field(strict=False)] = ()   # watchdog
    packages: dict[str, PackageFacts] = {}   # the build's packages (``packages`` event: contract names)
    launch_files: dict[str, str] = {}        # process -> the launch file found for its ``launch:``

    @property
    def wall_limit_s(self) -> float:
        """Wall seconds the scenario's processes may run: the scenario's limit, times
        ``LOCKSTEP_WALL_FACTOR`` in lockstep (a tick may take longer than 16 ms of wall time
        on a busy machine; a process that keeps it from ticking ends the lockstep run first)."""
        from grader.scenario.simtime import LOCKSTEP_WALL_FACTOR  # noqa: PLC0415 - at the head it would close a circle: scenario.runspec -> scenario -> scenario.runspec

        return self.scenario.time_limit_s * (LOCKSTEP_WALL_FACTOR if self.lockstep else 1.0)
