"""Rubrics and labs for the front-ends: ``grader rubric`` (schema, guide, audit, collateral), the
Gradescope bundle, ``grader check --lab``.

A rubric is loaded with :func:`grader.api.load_rubric`; what is here answers questions about one
without reaching into ``grader.rubric``'s modules: where it is shown as (:func:`display_path`),
which contract roles an item names (:func:`item_roles`), which aspects of the code an item's
analyzer judges (:func:`judges`), the rubric's JSON Schema and the guide's generated tables
(:func:`json_schema`, :func:`refresh_guide`), a rubric copied with the files it references
(:func:`stage_rubrics`), and the labs known (:func:`known_labs`, :func:`rubric_for_lab`,
:func:`rubrics_dir`, :data:`CHECKOUT`, :func:`in_checkout`). :class:`Rubric` and :class:`Scenario` are the models themselves.
"""

from __future__ import annotations

from grader import analyze
from grader.labs import CHECKOUT, Lab, in_checkout, known_labs, rubric_for_lab, rubrics_dir
from grader.rubric.contract import item_roles
from grader.rubric.guide import json_schema, refresh as refresh_guide
from grader.rubric.load import display_path
from grader.rubric.schema import Rubric
from grader.rubric.stage import stage_rubrics
from grader.scenario.model import Scenario
from grader.scenario.runspec import ScenarioRun

__all__ = ["CHECKOUT", "Lab", "Rubric", "Scenario", "ScenarioRun", "display_path", "in_checkout", "item_roles", "json_schema",
           "judges", "known_labs", "refresh_guide", "rubric_for_lab", "rubrics_dir", "stage_rubrics"]


def judges(analyzer: str | None) -> tuple[str, ...]:
    """The aspects of the code analyzer ``analyzer`` judges (``register(judges=...)``, and
    ``timing`` when it declares its timing): what the collateral audit mutates for an item."""
    return analyze.judges(analyzer)
