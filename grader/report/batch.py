"""Batch outputs rebuilt from disk: ``grades.csv`` and ``index.html`` from ``OUT/*/result.json``.

Reading the archived results (instead of keeping Results in memory) keeps the batch files right
however the submissions were graded: in parallel, resumed in a later run, or regraded one by one.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

from grader.contracts.result_document import ResultDocument
from grader.errors import GraderError
from grader.report.index import read_docs, write_index
from grader.report.result import read_result, write_grades_csv
from grader.rubric.schema import Rubric
from grader.rubric.result import Result
from grader.similarity.summary import read_summary


def load_results(out_dir: str | os.PathLike[str], rubric: Rubric | None = None) -> dict[str, Result]:
    """Instructor-view results under ``out_dir`` (self-check/student views are not grades),
    restricted to ``rubric``'s lab when given."""
    results: dict[str, Result] = {}
    for path in sorted(Path(out_dir).glob("*/result.json")):
        try:
            sid, result = read_result(path)
        except GraderError:
            if not path.exists():       # its submission is being graded again right now
                continue
            raise
        if result.student_view or (rubric is not None and result.lab != rubric.lab):
            continue
        results[sid] = result
    return results


def write_batch(out_dir: str | os.PathLike[str], rubric: Rubric | None = None) -> tuple[Path, Path]:
    """(Re)write ``out_dir/grades.csv`` and ``out_dir/index.html`` (the class view); returns both."""
    results = load_results(out_dir, rubric)
    docs = read_docs(out_dir, list(results))
    return (write_grades_csv(out_dir, results, rubric=rubric, intake=intake_docs(docs)),
            write_index(out_dir, results, docs=docs, similarity=read_summary(Path(out_dir))))


def intake_docs(docs: Mapping[str, ResultDocument]) -> dict[str, dict[str, Any]]:
    """Each submission's result.json ``intake`` (who it is, from which LMS download), if any."""
    return {sid: doc.intake for sid, doc in docs.items() if doc.intake is not None}
