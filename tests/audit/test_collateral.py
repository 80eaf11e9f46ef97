"""The collateral-loss audit's pure half (issue 37): one-aspect mutants of a reference, and which
lost items are about the aspect a mutant changed (the rest cost the student twice)."""

from __future__ import annotations

import ast
from pathlib import Path

from grader.audit.aspects import ASPECT_OPERATORS
from grader.audit.collateral import classify, items_about
from grader.audit.mutate import mutants
from grader.audit.outcome import Outcome
from grader.rubric import load_rubric
from grader.rubric.schema import AcceptedCollateral

REPO = Path(__file__).resolve().parents[2]
FIRST = REPO / "fixtures" / "submissions" / "first_nodes" / "reference"
RUBRIC = load_rubric(REPO / "rubrics" / "first_nodes.yaml")


def by_operator(found: list, op: str) -> list:
    return [m for m in found if m.operator == op]


def test_one_aspect_mutants_of_a_first_package() -> None:
    found = mutants(FIRST, ASPECT_OPERATORS)
    renamed = by_operator(found, "rename_node")
    assert sorted(m.original for m in renamed) == ["'my_first_node'", "'number_publisher'", "'number_subscriber'",
                                                   "'turtle_controller'"]
    printed = by_operator(found, "log_to_print")
    assert [m.replacement for m in printed if "Hello" in m.original] == ["print('Hello ROS2 developer')"]
    for m in found:
        ast.parse(m.mutated_source())
    assert [m.id for m in found] == [m.id for m in mutants(FIRST, ASPECT_OPERATORS)]     # stable
    # the mutation audit's default operators are unchanged
    assert not by_operator(mutants(FIRST), "rename_node") and not by_operator(mutants(FIRST), "log_to_print")


def test_a_node_of_another_name_is_about_the_name_item_only() -> None:
    assert items_about(RUBRIC, "node names", "'my_first_node'") == ["node.name"]
    assert items_about(RUBRIC, "node names", "'turtle_controller'") == []      # a name the lab leaves open
    assert items_about(RUBRIC, "logging", "x") == ["node.greeting", "news.heard"]
    assert set(items_about(RUBRIC, "timing", "0.1")) == {"circle.period", "circle.keeps_moving"}


def outcome(mutant_id: str, original: str, lost: dict[str, float], operator: str = "rename_node") -> Outcome:
    return Outcome(mutant={"id": mutant_id, "operator": operator, "description": "x", "original": original,
                           "file": "f.py", "line": 1}, diff="", status="killed", lost=lost)


def test_a_second_item_lost_for_one_mistake_is_collateral_unless_the_rubric_accepts_it() -> None:
    twice = outcome("rename_node-0000000a", "'my_first_node'", {"node.name": 1.0, "node.greeting": 3.0})
    loss = classify(RUBRIC, twice)
    assert loss.about == ["node.name"] and loss.collateral == {"node.greeting": 3.0} and not loss.accepted
    accepting = RUBRIC.model_copy(update={"accepted_collateral": (
        AcceptedCollateral(mutant="rename_node-0000000a", items=("node.greeting",), reason="a test's reason"),)})
    loss = classify(accepting, twice)
    assert loss.collateral == {} and loss.accepted == {"node.greeting": "a test's reason"}
    once = classify(RUBRIC, outcome("rename_node-0000000b", "'my_first_node'", {"node.name": 1.0}))
    assert once.collateral == {}
