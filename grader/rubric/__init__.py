"""Rubrics: the YAML model (with located errors), loading, and scoring of findings.

``load_rubric(path) -> Rubric`` and ``score(rubric, findings) -> Result`` are the entry points;
the report layer (``grader.report``) turns a Result into result.json, grades.csv and HTML.
"""

from grader.rubric.load import RubricError, load_rubric
from grader.rubric.schema import Item, Partial, Rubric, Section, SectionSpec
from grader.rubric.score import score, worst_finding
from grader.rubric.result import ItemResult, Notice, Result, SectionResult

__all__ = ["Item", "ItemResult", "Notice", "Partial", "Result", "Rubric", "RubricError",
           "Section", "SectionResult", "SectionSpec", "load_rubric", "score", "worst_finding"]
