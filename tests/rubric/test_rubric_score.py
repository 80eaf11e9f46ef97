"""Scoring: partial-credit rules, advisory warnings, manual items, integrity flags, student view."""

from __future__ import annotations

import math

import pytest

from grader.errors import GraderError
from grader.rubric import Partial, load_rubric, score, worst_finding
from grader.rubric.score import render_template


class FakeFinding:
    """Duck-typed Finding (kept local: test directories have no packages to import from)."""

    def __init__(self, value=None, fraction=1.0, status="pass", feedback="", evidence=None):
        self.value, self.fraction, self.status = value, fraction, status
        self.feedback, self.evidence = feedback, evidence or {}

RUBRIC = """
lab: demo-lab
title: Demo
sections:
  - {section: report, points: 10}
  - {section: {exercise: 1}, title: Numbers, points: 10}
  - {section: integrity, points: 0}
scenarios:
  s: {steps: [{id: run, wait: 1}]}
items:
  - {id: report, title: Report, section: report, points: 10, kind: manual}
  - {id: lin, title: Linear, section: {exercise: 1}, points: 3, scenario: s, analyzer: topic_type}
  - {id: none, title: All or nothing, section: {exercise: 1}, points: 2, scenario: s, analyzer: topic_type,
     partial: none}
  - id: steps
    title: Stepped
    section: {exercise: 1}
    points: 4
    scenario: s
    analyzer: topic_type
    partial: {steps: [[0.9, 1.0], [0.5, 0.5], [0, 0]]}
    feedback:
      pass: "Rate {value:.2f} Hz (at least {min_count}), {count} messages."
      fail: "Only {value:.2f} Hz; {unknown} stays; {feedback}"
    params: {min_count: 1}
    hint: Check the timer period.
  - {id: hidden, title: Hidden, section: {exercise: 1}, points: 1, scenario: s, analyzer: topic_type, public: false}
  - {id: adv, title: Advisory, section: {exercise: 1}, points: 0, kind: advisory, scenario: s, analyzer: topic_type}
  - {id: integ, title: Integrity, section: integrity, points: 0, kind: integrity, scenario: s,
     analyzer: topic_type, public: false}
"""


@pytest.fixture
def rubric(write_rubric):
    return load_rubric(write_rubric(RUBRIC))


def all_pass(**overrides):
    findings = {i: FakeFinding(value=1.0) for i in ("lin", "none", "steps", "hidden", "adv", "integ")}
    findings.update(overrides)
    return findings


@pytest.mark.parametrize("partial, fraction, credit", [
    (Partial("linear"), 0.5, 0.5), (Partial("linear"), 1.7, 1.0), (Partial("linear"), -1, 0.0),
    (Partial("linear"), math.nan, 0.0),
    (Partial("none"), 0.999, 0.0), (Partial("none"), 1.0, 1.0),
    (Partial("steps", ((0.9, 1.0), (0.5, 0.5), (0.0, 0.0))), 0.95, 1.0),
    (Partial("steps", ((0.9, 1.0), (0.5, 0.5), (0.0, 0.0))), 0.9, 1.0),
    (Partial("steps", ((0.9, 1.0), (0.5, 0.5), (0.0, 0.0))), 0.6, 0.5),
    (Partial("steps", ((0.9, 1.0), (0.5, 0.5))), 0.2, 0.0),
])
def test_partial_credit_rules(partial, fraction, credit):
    assert partial.credit(fraction) == credit


def test_all_pass_gives_auto_max_and_leaves_manual_pending(rubric):
    result = score(rubric, all_pass())
    assert result.auto_score == result.auto_max == 10
    assert result.max_score == 20 and result.manual_max == 10
    assert result.item("report").points is None and result.item("report").status == "pending"
    assert result.total is None and not result.complete
    assert result.score == 10
    assert result.integrity_flags == () and result.warnings == ()


def test_points_follow_each_rule(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(value=0.5, fraction=0.5, status="partial"),
                                    none=FakeFinding(fraction=0.8, status="partial"),
                                    steps=FakeFinding(value=0.61, fraction=0.6, status="partial")))
    assert (result.item("lin").points, result.item("lin").status) == (1.5, "partial")
    assert (result.item("none").points, result.item("none").status) == (0.0, "fail")
    assert (result.item("steps").points, result.item("steps").status) == (2.0, "partial")
    assert result.auto_score == 1.5 + 0 + 2 + 1


def test_rounding_of_thirds(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(fraction=1 / 3, status="partial")))
    assert result.item("lin").points == 1.0
    result = score(rubric, all_pass(steps=FakeFinding(fraction=2 / 3, status="partial")))
    assert result.item("steps").points == 2.0


def test_error_and_missing_findings_score_zero(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(fraction=1.0, status="error",
                                                    feedback="topic /random_numbers missing"),
                                    none=None))
    lin = result.item("lin")
    assert (lin.points, lin.status, lin.feedback) == (0.0, "error", "topic /random_numbers missing")
    assert result.item("none").status == "error" and result.item("none").points == 0.0
    assert "did not run" in result.item("none").feedback
    absent = all_pass()
    del absent["steps"]
    assert score(rubric, absent).item("steps").status == "error"


def test_unknown_status_is_an_error(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(fraction=1.0, status="great")))
    assert result.item("lin").status == "error" and result.item("lin").points == 0


def test_feedback_templates(rubric):
    ok = score(rubric, all_pass(steps=FakeFinding(value=0.998, fraction=1.0,
                                                  evidence={"count": 6})))
    assert ok.item("steps").feedback == "Rate 1.00 Hz (at least 1), 6 messages."
    bad = score(rubric, all_pass(steps=FakeFinding(value=None, fraction=0.0, status="fail",
                                                   feedback="Too slow.")))
    assert bad.item("steps").feedback == "Only n/a Hz; {unknown} stays; Too slow."
    # no rubric text for this status: the analyzer's own feedback
    assert score(rubric, all_pass(lin=FakeFinding(feedback="Fine."))).item("lin").feedback == "Fine."
    assert bad.item("steps").hint == "Check the timer period."


def test_render_template_never_raises():
    assert render_template("{value:.2f}", {"value": "abc"}) == "abc"
    assert render_template("{x[3]} {y.z}", {"x": [1], "y": 1}) == "{x[3]} {y.z}"
    assert render_template("{a!r}", {"a": "q"}) == "'q'"
    assert render_template("{missing:>5}", {}) == "{missing:>5}"


def test_advisory_is_a_warning_worth_nothing(rubric):
    result = score(rubric, all_pass(adv=FakeFinding(fraction=0.0, status="fail", feedback="Crashed on 'oops'.")))
    assert result.auto_score == 10
    assert result.item("adv").points == 0 and result.item("adv").status == "fail"
    assert [(w.item_id, w.feedback) for w in result.warnings] == [("adv", "Crashed on 'oops'.")]


def test_integrity_flags(rubric):
    result = score(rubric, all_pass(integ=FakeFinding(fraction=0.0, status="fail", feedback="teleport")))
    assert [(f.item_id, f.status) for f in result.integrity_flags] == [("integ", "fail")]
    assert result.auto_score == 10      # flagged for review, not auto-penalised
    assert score(rubric, all_pass(integ=None)).integrity_flags == ()


def test_manual_grades_complete_the_total(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(fraction=0.5, status="partial")), manual={"report": 7.5})
    assert result.item("report").points == 7.5 and result.item("report").status == "partial"
    assert result.complete and result.total == 7.5 + 8.5 and result.manual_score == 7.5
    with pytest.raises(GraderError, match="report: expected points between 0 and 10"):
        score(rubric, all_pass(), manual={"report": 11})
    with pytest.raises(GraderError, match="lin: is graded automatically"):
        score(rubric, all_pass(), manual={"lin": 1})
    with pytest.raises(GraderError, match="nope: not an item"):
        score(rubric, all_pass(), manual={"nope": 1})


def test_findings_for_unknown_items_are_a_bug(rubric):
    with pytest.raises(ValueError, match="zzz"):
        score(rubric, all_pass(zzz=FakeFinding()))


def test_sections_group_items_in_table_order(rubric):
    result = score(rubric, all_pass(lin=FakeFinding(fraction=0.0, status="fail")))
    sections = result.sections
    assert [s.section.key for s in sections] == ["report", "exercise 1", "integrity"]
    ex1 = sections[1]
    assert ex1.title == "Exercise 1: Numbers"
    assert (ex1.points, ex1.max_points, ex1.pending_max) == (7, 10, 0)
    assert ex1.item_ids == ("lin", "none", "steps", "hidden", "adv")
    assert sections[0].pending_max == 10 and sections[0].points == 0


def test_student_view_hides_non_public_items(rubric):
    full = score(rubric, all_pass(integ=FakeFinding(fraction=0, status="fail")))
    student = full.for_student()
    ids = [i.id for i in student.items]
    assert "hidden" not in ids and "integ" not in ids and "lin" in ids
    assert student.auto_max == 9 and student.auto_score == 9
    assert (student.hidden_items, student.hidden_points) == (2, 1)
    assert student.integrity_flags == ()
    assert student.student_view and not full.student_view
    assert [s.section.key for s in student.sections] == ["report", "exercise 1"]


def test_worst_finding():
    a, b, c = FakeFinding(fraction=1.0), FakeFinding(fraction=0.4, status="partial"), \
        FakeFinding(fraction=0.0, status="error")
    assert worst_finding([a, b, c]) is b
    assert worst_finding([a, None, c]) is c
    assert worst_finding([None, None]) is None


GATED = """
lab: gate-lab
title: Gate
sections:
  - {section: {exercise: 3}, points: 6}
scenarios:
  s: {steps: [{id: run, wait: 1}]}
items:
  - {id: goals, title: Goals, section: {exercise: 3}, points: 4, scenario: s, analyzer: topic_type}
  - {id: advertised, title: Advertised, section: {exercise: 3}, points: 2, scenario: s, analyzer: topic_type,
     partial: none, requires: [goals]}
"""


@pytest.mark.parametrize("fraction, status, earns", [
    (1.0, "pass", True),
    # two of three goals reached: the loop is the student's own, the given parts count (a
    # chaotic goal must not cost the gated items too: issue 22)
    (2 / 3, "partial", True),
    (0.0, "fail", False),          # the handout: every goal aborts
    (0.0, "error", False),
])
def test_requires_gates_until_the_required_item_earns_points(write_rubric, fraction, status, earns):
    rubric = load_rubric(write_rubric(GATED))
    result = score(rubric, {"goals": FakeFinding(fraction=fraction, status=status),
                            "advertised": FakeFinding(status="pass")})
    adv = {i.id: i for i in result.items}["advertised"]
    if earns:
        assert (adv.status, adv.points) == ("pass", 2.0) and "gated_by" not in adv.evidence
    else:
        assert (adv.status, adv.points) == ("fail", 0.0)
        assert adv.evidence["gated_by"] == ["goals"] and adv.evidence["own_status"] == "pass"
        assert adv.feedback.startswith("No points yet: this item counts once goals earns points")
