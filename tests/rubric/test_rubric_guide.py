"""The rubric guide and the editors' JSON Schema are generated from the model and stay current;
every rubric validates against the schema; the runner implements everything the model can say."""

from __future__ import annotations

import json
import typing
from pathlib import Path

import jsonschema
import pytest
import yaml

from grader.rubric.guide import json_schema, refresh

REPO = Path(__file__).resolve().parents[2]
RUBRICS = sorted((REPO / "rubrics").glob("*.yaml"))


def test_guide_tables_are_current() -> None:
    assert refresh(REPO / "rubrics" / "README.md", check=True) == [], \
        "rubrics/README.md is stale: run `grader rubric guide`"


def test_committed_schema_is_the_generated_one() -> None:
    committed = json.loads((REPO / "rubrics" / "rubric.schema.json").read_text())
    assert committed == json.loads(json.dumps(json_schema())), \
        "rubrics/rubric.schema.json is stale: run `grader rubric schema -o rubrics/rubric.schema.json`"


@pytest.mark.parametrize("path", RUBRICS, ids=[p.name for p in RUBRICS])
def test_every_rubric_validates_against_the_schema(path: Path) -> None:
    validator = jsonschema.Draft202012Validator(json_schema())
    errors = [f"{list(e.path)}: {e.message}" for e in validator.iter_errors(yaml.safe_load(path.read_text()))]
    assert not errors


@pytest.mark.parametrize("change", [
    lambda r: r["items"][0].update(pionts=3),                                   # unknown key
    lambda r: next(iter(r["scenarios"].values()))["steps"][0].update(until="arrived"),  # no such condition
    lambda r: r["items"][0].update(partial="half"),
    lambda r: next(iter(r["scenarios"].values()))["steps"][0].update(timeout="soon"),
])
def test_schema_rejects_what_the_loader_rejects(change) -> None:
    rubric = yaml.safe_load((REPO / "rubrics" / "wall_pen.yaml").read_text())
    change(rubric)
    assert list(jsonschema.Draft202012Validator(json_schema()).iter_errors(rubric))


def test_runner_implements_every_action_and_condition() -> None:
    """What a rubric can say, the runner does: one handler per action class, one predicate per
    condition class of the scenario model."""
    from grader.scenario import model as m
    from grader.scenario.predicates import CONDITIONS
    from grader.scenario.steps import HANDLERS

    assert set(HANDLERS) == set(typing.get_args(m.Action))
    conditions = typing.get_args(typing.get_args(m.Condition)[0])
    assert set(CONDITIONS) == set(conditions)
