"""Behaviour similarity's weighing (grader.similarity.compare) on made-up features: rarity in the
class, the discount for what passing submissions do, and who counts as the class. No ROS."""

from __future__ import annotations

import numpy as np

from grader.contracts.result_document import ItemEntry
from grader.similarity.behaviour import Feature, result_features, template
from grader.similarity.compare import cap, compare_behaviour


def _path(rng, bend: float, noise: float = 0.0) -> list[list[float]]:
    s = np.linspace(0.0, 1.0, 40)
    xy = np.column_stack([5.5 - 3.5 * s, 5.5 + 1.5 * s + bend * np.sin(np.pi * s)])
    return np.round(xy + rng.normal(0.0, noise, xy.shape), 4).tolist()


def _class(n_honest: int = 12, n_other: int = 6) -> tuple[dict, dict, list]:
    """honest: one forced path (the lab's gains); other: each its own path; two copies of one
    unusual path and one log line nobody else has."""
    rng = np.random.default_rng(1)
    feats: dict[str, list[Feature]] = {}
    key = "sc|path|/turtle1/pose|goal_lab"
    for i in range(n_honest):
        feats[f"honest{i}"] = [Feature(key, "path", "path", "path", _path(rng, 0.0, 0.004), "sc"),
                               Feature("sc|log|New goal: (#, #)", "token", "log", "log", "New goal: (#, #)", "sc")]
    for i in range(n_other):
        feats[f"other{i}"] = [Feature(key, "path", "path", "path", _path(rng, 0.3 + 0.25 * i, 0.004), "sc")]
    for name in ("copy1", "copy2"):
        feats[name] = [Feature(key, "path", "path", "path", _path(rng, -1.7, 0.004), "sc"),
                       Feature("sc|log|goal is now #,#!!", "token", "log", "log", "goal is now #,#!!", "sc")]
    passing = {"sc": {s for s in feats if s.startswith("honest")}}
    return feats, passing, sorted(feats)


def test_an_unusual_shared_path_outranks_the_one_the_lab_forces() -> None:
    feats, passing, ids = _class()
    matches = compare_behaviour(feats, passing, ids)
    copies = matches[("copy1", "copy2")]
    assert copies.score > 0.9, copies
    honest = [m.score for (a, b), m in matches.items() if a.startswith("honest") and b.startswith("honest")]
    assert max(honest, default=0.0) < 0.15         # twelve drive it because the lab asks for it (a common
    #                                                log line, 0.74 bits of 2 groups x 3.32, is all they share)
    assert copies.score > max(m.score for k, m in matches.items() if k != ("copy1", "copy2"))
    path = next(s for s in copies.shared if s.group == "path")
    assert path.holders == 2 and path.forced == 0.0 and abs(path.bits - cap(len(ids))) < 1e-3


def test_without_the_forced_discount_the_honest_pairs_would_share_the_path() -> None:
    """The same class with nobody passing: the twelve honest paths become shared evidence, so
    the discount above is what keeps them low (this test fails if it is removed)."""
    feats, _, ids = _class()
    matches = compare_behaviour(feats, {}, ids)
    pair = matches[("honest0", "honest1")]
    path = next(s for s in pair.shared if s.group == "path")
    assert path.forced == 0.0 and path.evidence > 0.5 and path.holders >= 12


def test_rarity_counts_the_submissions_that_ran_the_scenario() -> None:
    """Ten submissions whose builds failed (no recording) do not make a path two of four drive rare."""
    rng = np.random.default_rng(2)
    key = "sc|path|p|s"
    feats = {f"s{i}": [Feature(key, "path", "path", "path", _path(rng, 0.5 if i < 2 else 0.9 * i), "sc")]
             for i in range(4)}
    ids = sorted(feats)
    alone = compare_behaviour(feats, {}, ids)[("s0", "s1")]
    feats.update({f"z{i}": [] for i in range(10)})
    with_failed = compare_behaviour(feats, {}, sorted(feats))[("s0", "s1")]
    assert with_failed.score == alone.score and with_failed.bits == alone.bits


def test_result_features_skip_items_that_measured_nothing() -> None:
    common = {"title": "", "section": {"exercise": 2}, "public": True, "points": 0, "max_points": 1, "feedback": ""}
    items = [ItemEntry(**common, **i) for i in (
        {"id": "ex2.goals_reached", "kind": "auto", "status": "fail", "value": 0.25, "evidence": {"n_goals": 4}},
        {"id": "ex2.control_rate", "kind": "auto", "status": "fail", "value": None, "evidence": {}},
        {"id": "ex2.turn_direction", "kind": "auto", "status": "pass", "value": 1.0, "evidence": {"share": 1.0}})]
    feats = result_features(items, {"ex2.goals_reached": ["sc"], "ex2.control_rate": ["sc"],
                                  "ex2.turn_direction": ["sc"]})
    failures = [f.key for f in feats if f.group == "failure"]
    assert failures == ["item|ex2.goals_reached|outcome"]
    assert {f.key for f in feats if f.group == "measured"} == {"item|ex2.goals_reached|n_goals",
                                                              "item|ex2.turn_direction|share"}


def test_log_templates_ignore_numbers_and_spacing() -> None:
    assert template("New goal:  (2.00, 7.00)") == template("New goal: (0.8, -5.5e-1)") == "New goal: (#, #)"


def test_the_account_of_a_pair_adds_up_to_its_score() -> None:
    """The matrices score every pair; ``shared`` explains one: with one feature per group the
    explained evidence is the pair's bits, and every scored pair has an account."""
    feats, passing, ids = _class()
    matches = compare_behaviour(feats, passing, ids)
    assert matches and all(m.shared for m in matches.values())
    for m in matches.values():
        assert abs(sum(min(cap(len(ids)), s.evidence) for s in m.shared) - m.bits) < 0.01, m
