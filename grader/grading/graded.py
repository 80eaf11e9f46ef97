"""One graded submission as the pipeline hands it on: its result and what its grading left.

A record of its own (``grader.grading.pipeline`` makes it, ``grader.grading.outputs`` writes it,
the front-ends read it through ``grader.api.batch``): in the pipeline's module, outputs and
pipeline imported each other.

It stays on the grading floor rather than in ``grader.contracts``: its ``result`` is the engine's
``grader.rubric.result.Result`` (floor 6: items, scoring, the student view), which the ground
floor may not import, and what a front-end reads of a grade on disk is ``ResultDocument``
already. Its run records are the contracts' models (``grader.contracts.run_records``, the
intake and previous-grade models of result.json), so readers use attributes, not ``.get``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from grader.contracts.intake_record import IntakeRecord
from grader.contracts.result_document import PreviousEntry
from grader.contracts.run_records import ClockUse, EarlyEnd, Recording, ReusedRecording
from grader.rubric.result import Result


@dataclass
class GradedSubmission:
    id: str
    out: Path
    result: Result
    build_ok: bool
    build_failed: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    reused: dict[str, ReusedRecording] = field(default_factory=dict)   # scenario -> where its recording came from
    recordings: dict[str, Recording] = field(default_factory=dict)     # scenario -> key, made_by, reused_from
    cache: dict[str, int] = field(default_factory=dict)        # cache hits and misses (grader.cache.store)
    time_scales: dict[str, ClockUse] = field(default_factory=dict)     # scenario -> requested/used/fallback (--time-scale)
    #: scenario -> the steps that ended once their outcome was decided
    ended_early: dict[str, list[EarlyEnd]] = field(default_factory=dict)
    previous: PreviousEntry | None = None      # a regrade's summary of the result it replaced (class view diff)
    intake: IntakeRecord | None = None         # how it arrived: LMS ids, student, time (grader.intake)
