"""The late policy on a scored Result: at grading (``grader grade``) and at every regrade, from
the submission's arrival record (``OUT/<id>/intake.json``: its time and who says so, the
roster's late days left) and the rubric's ``late:`` policy (with the ``--due`` the batch was
graded with), plus a TA's override from ``grader scores merge`` (``late_penalty`` column).

A submission graded without intake (``grader check``, a Gradescope autograder run) or a rubric
without a late policy gets no ``late``: nothing changes for them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from grader.contracts.intake_record import IntakeRecord
from grader.intake.late import LatePenalty, SubmissionTime, assess
from grader.intake.model import read_record
from grader.scores.store import load_late_override

#: a TA's late penalty for a submission graded without a late policy
BY_HAND = "set by hand (grader scores merge)"


def policy_for(rubric, record: IntakeRecord | None):
    """The rubric's late policy, with the due date the batch was graded with (``--due``)."""
    policy = getattr(rubric, "late", None)
    due = record.due_override if record is not None else None
    if policy is not None and due is not None and due.get("due"):
        policy = policy.with_due(str(due["due"]), due.get("timezone"))
    return policy


def days_left(record: IntakeRecord) -> tuple[int | None, list[str]]:
    """The roster's ``late_days`` (days the student has left), or None (the whole budget)."""
    text = str(((record.student or {}).get("late_days")) or "").strip()
    if not text:
        return None, []
    try:
        value = float(text)
        if value < 0 or value != int(value):
            raise ValueError
        return int(value), []
    except ValueError:
        return None, [f"the roster's late_days {text!r} is not a whole number >= 0: the policy's whole "
                      "budget of late days was used"]


def apply_intake(sub_out: Path, rubric, result, record: IntakeRecord | None = None):
    """``result`` with the late policy's verdict (``Result.late``), and notes for the problems
    list. ``record``: the arrival record (default: read from ``sub_out``)."""
    record = record if record is not None else read_record(sub_out)
    policy = policy_for(rubric, record)
    override = load_late_override(sub_out)
    if record is None or policy is None:
        return with_late_override(replace(result, late=None), override), []
    time = SubmissionTime.from_dict(record.time) if record.time else None
    left, notes = days_left(record)
    return with_late_override(replace(result, late=assess(policy, time, left)), override), notes


def with_late_override(result, override):
    """``result`` with a TA's late penalty (a ManualScore's points) in force, or the policy's own
    (``override`` None). Without a late policy, an override still deducts its points."""
    if override is None:
        if result.late is not None and result.late.time_source == BY_HAND:
            return replace(result, late=None)               # a by-hand penalty, cleared
        return result if result.late is None else replace(result, late=result.late.with_override(None))
    late = result.late or LatePenalty(due="", zone="", submitted_at=None, time_source=BY_HAND, late_s=None,
                                      units=0, per="day", percent=0.0, of="max",
                                      note="Late penalty set by the instructor.")
    return replace(result, late=late.with_override(float(override.points), override.source))
