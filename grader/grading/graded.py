"""One graded submission as the pipeline hands it on: its result and what its grading left.

A record of its own (``grader.grading.pipeline`` makes it, ``grader.grading.outputs`` writes it,
the front-ends read it): in the pipeline's module, outputs and pipeline imported each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

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
    reused: dict[str, dict] = field(default_factory=dict)     # scenario -> where its recording came from
    recordings: dict[str, dict] = field(default_factory=dict)  # scenario -> key, made_by, reused_from
    cache: dict[str, int] = field(default_factory=dict)        # cache hits and misses (grader.cache.store)
    time_scales: dict[str, dict] = field(default_factory=dict)  # scenario -> requested/used/fallback (--time-scale)
    #: scenario -> the steps that ended once their outcome was decided ({step, at_s, limit_s, reason})
    ended_early: dict[str, list[dict]] = field(default_factory=dict)
    previous: dict | None = None      # a regrade's summary of the result it replaced (class view diff)
    intake: dict | None = None        # how it arrived: LMS ids, student, time (grader.intake)
