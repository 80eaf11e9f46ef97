"""The pieces of a grading batch a front-end composes itself, beyond :func:`grader.api.grade`:
the mutation audit grades its mutants with :func:`grade_batch` on :class:`Slots` at
:func:`machine_time_scale`; Gradescope builds the rubric's support packages into its image
(:func:`build_support`) and grades one upload (:func:`grader.api.pipeline.grade_submission`,
loaded only on that path); ``grader grade``/``grader check`` parse ``--intake`` (:data:`INTAKE_KINDS`),
``--cache-max-size`` (:func:`parse_size`) and say whose recordings a grade rests on
(:func:`by_other_grader`).

Every name is the engine's own (typed and documented where it is defined), re-exported here so
that the front-ends reach the engine through ``grader.api`` only (pyproject's import-linter
contract "front-ends reach the engine through grader.api").
"""

from __future__ import annotations

from grader.cache.store import parse_size
from grader.grading.batch import grade_batch
from grader.grading.graded import GradedSubmission
from grader.grading.provenance import by_other_grader
from grader.grading.schedule import Slots
from grader.grading.starvation import REGRADE_TIME_SCALE
from grader.grading.timescale import machine_time_scale
from grader.intake.batch import KINDS as INTAKE_KINDS
from grader.workspace.build import build_support
from grader.workspace.source import find_packages, is_archive

__all__ = ["GradedSubmission", "INTAKE_KINDS", "REGRADE_TIME_SCALE", "Slots", "build_support", "by_other_grader",
           "find_packages", "grade_batch", "is_archive", "machine_time_scale", "parse_size"]
