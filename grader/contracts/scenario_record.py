"""``<scenario folder>/scenario.json``, the record of one scenario run: :class:`ScenarioRecord`.

The scenario child writes it (``grader.scenario.run``: its steps, processes, clock, errors), the
parent adds what only it knows (``grader.scenario``: the sandbox's report, the wall time) and the
pipeline notes how the recording came about (``grader.grading``: reused from whom, the recording
key and maker, the time-scale or lockstep decision, a starved run made again). It is read by the
analysis (a bag on simulated time), a repeat (was the lockstep run exact), provenance (who made
the recording a grade rests on) and the sandbox summary of result.json.

The child fills in a plain dict while the run goes on and writes it through this model
(``ScenarioRecord.from_working``); from there on the record in memory is this model too: what
``run_scenario`` returns and the pipeline passes on (time scale, starvation retries, reuse,
repeats, the analysis) is read by attribute, and every note is an amendment through the model
(:meth:`ScenarioRecord.amended`, validated as a whole), so what the pipeline holds is what the
file would say. Fields are declared in the order the child writes them, so a
record written again is the same bytes in the usual case (``tests/grading/test_scenario_record.py``
reads every committed record of ``fixtures/bags``); unknown keys are kept, after the known ones.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Self

from pydantic import Field

from grader.contracts.document import Document, KeptOrder, Number
from grader.contracts.values import JsonValue

__all__ = ["ClockRecord", "ProcessRecord", "RecordingNote", "ReusedNote", "ScenarioRecord", "StepRecord"]


class _Entry(KeptOrder):
    """A part of the record: written back with the keys it was given, in their order."""


class StepRecord(_Entry):
    """One step's outcome (``grader.scenario.steps.run_step``)."""

    id: str
    action: str
    start: Number | None = None
    duration_s: Number = 0.0
    ended_by: str | None = None            # condition | timeout | decided | skipped | ...
    detail: dict[str, JsonValue] = Field(default_factory=dict)


class ProcessRecord(_Entry):
    """How a student process ended."""

    returncode: int | None = None
    crashed: bool = False
    exited_early: bool = False
    timed_out: bool = False
    killed: bool = False


class ClockRecord(_Entry):
    """``time_scale`` or ``lockstep``: how the clock ran (``used``: the factor, True for lockstep,
    False when it fell back to 1x), and why it fell back; the stepper's and the simulated clock's
    counters (``sim_s``, ``held_s``, ``quiet_timeouts``, ``wall_cuts``, ...) as they are."""

    used: bool | Number | None = None
    fallback: str | None = None
    quiet_timeouts: Number | None = None
    wall_cuts: Number | None = None


class ReusedNote(_Entry):
    """A recording copied from the cache: whose it was (``grader.grading.reuse``)."""

    from_: str | None = Field(None, alias="from")
    key: str | None = None
    recorded: str | None = None
    made_by: JsonValue = None


class RecordingNote(_Entry):
    """The recording's cache key and the grader that made it."""

    key: str | None = None
    made_by: JsonValue = None


class ScenarioRecord(Document):
    scenario: str
    steps: list[StepRecord] = Field(default_factory=list)
    processes: dict[str, ProcessRecord] = Field(default_factory=dict)
    errors: list[str] = Field(default_factory=list)
    bag: str | None = None
    canvas: str | None = None
    time_scale: ClockRecord | None = None
    lockstep: ClockRecord | None = None
    domain_id: int | None = None
    interrupted: bool = False
    traceback: str | None = None
    output_cut: list[JsonValue] = Field(default_factory=list)
    cpu_wait: dict[str, JsonValue] | None = None
    active_s: Number | None = None
    wall_s: Number | None = None
    # -- the parent (grader.scenario.run_scenario) --
    sandbox: dict[str, JsonValue] | None = None
    limits_hit: list[str] = Field(default_factory=list)
    parent_wall_s: Number | None = None
    # -- the pipeline (grader.grading) --
    reused: ReusedNote | None = None
    recording: RecordingNote | None = None
    starved: dict[str, JsonValue] | None = None
    cpu_quota: dict[str, JsonValue] | None = None
    # -- in memory only, never written: a repeated scenario's runs, the CPU of all of them --
    runs: int | None = None
    cpu_s: Number | None = None

    @classmethod
    def from_working(cls, record: dict[str, JsonValue], where: str) -> Self:
        """The record of a working dict: values JSON has no form for are written as text, as
        the child always wrote them (``default=str``)."""
        return cls.parse(json.loads(json.dumps(record, default=str)), where)

    def text(self) -> str:
        return json.dumps(self.to_json(), indent=1)

    def write(self, path: str | os.PathLike[str]) -> None:
        Path(path).write_text(self.text(), encoding="utf-8")

    def amended(self, changes: dict[str, JsonValue], where: str = "scenario.json") -> Self:
        """This record with ``changes`` (top-level keys, validated as a whole)."""
        return self.from_working({**self.to_json(), **changes}, where)

    @classmethod
    def amend(cls, path: str | os.PathLike[str], changes: dict[str, JsonValue]) -> None:
        """Write ``changes`` into the record at ``path`` (none there: nothing to amend)."""
        if Path(path).is_file():
            cls.read(path).amended(changes, str(path)).write(path)

    @property
    def exact_lockstep(self) -> bool:
        """A lockstep run with every tick quiet and no wait cut short by its wall-time limit:
        running it again repeats it exactly."""
        ls = self.lockstep
        return (ls is not None and bool(ls.used) and not ls.quiet_timeouts and not ls.wall_cuts
                and not self.errors)
