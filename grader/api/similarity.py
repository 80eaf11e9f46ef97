"""Similarity across a graded class, for ``grader similarity`` and what ``grader grade`` and
``grader merge`` run after a batch (the engine is ``grader.similarity``; the commands print).

This module loads ``grader.grading.similarity``, hence pandas and numpy (424 ms CPU in a fresh
interpreter): a front-end imports it inside the function that compares, as before.

:class:`Settings` says which pairs are listed; :func:`run_similarity` compares a batch and writes
``OUT/similarity/``; :func:`graded_ids` are the submissions it compares; :func:`compare_graded` is
the comparison after grading, which never fails the grading (:class:`ClassComparison` says what
it gave or why it was not computed).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from grader.rubric.schema import Rubric
from grader.grading.similarity import Settings, graded_ids, run_similarity

__all__ = ["ClassComparison", "Settings", "compare_graded", "graded_ids", "run_similarity"]


@dataclass(frozen=True)
class ClassComparison:
    """What comparing a graded class after grading gave: the summary ``run_similarity`` returns
    (``similarity.json``'s content), or the error that kept it from being computed."""

    summary: dict[str, Any] | None = None
    error: str | None = None


def compare_graded(out: Path, rubric: Rubric, settings: Settings | None) -> ClassComparison | None:
    """Similarity of the batch in ``out`` after ``grader grade``/``grader merge`` (seconds for a
    class); None when there is nothing to compare (``settings`` None: ``--no-similarity``, or
    fewer than two graded submissions). Never raises: the grades are written, similarity is extra."""
    if settings is None or len(graded_ids(out)) < 2:
        return None
    try:
        summary = run_similarity(out, rubric, settings)
    except Exception as exc:  # noqa: BLE001 - the grades are written; similarity is extra
        return ClassComparison(error=f"{type(exc).__name__}: {exc}")
    return ClassComparison(summary=summary)
