"""Lateness: when a submission came in (and who says so), and what the rubric's late policy
makes of it. Pure: a policy, a time and the late days a student has left in, a
:class:`LatePenalty` out; the Result carries it (``Result.late``) and every total, report and
export subtracts it.

Where the time comes from matters and is always stated (``time_source``): the LMS's own record
(Gradescope's ``created_at``; Canvas's download carries only its ``LATE`` mark), the last commit
of a clone, or the newest file time inside an archive. The last two are set by the student's own
machine. When the LMS says whether a submission is late (Canvas), its verdict decides, and a time
only measures by how much; when nothing says how late, the least lateness the evidence shows
counts (a student is never charged for lateness nobody can show).
"""

from __future__ import annotations

from zoneinfo import ZoneInfo
from dataclasses import replace
from datetime import datetime

from grader.contracts.late import LatePenalty, SubmissionTime, duration_words, late_by_text
from grader.rubric.intake_fields import LatePolicy


def _show(when: datetime, zone: str) -> str:
    try:
        when = when.astimezone(ZoneInfo(zone))
    except (KeyError, ValueError):
        pass
    return when.strftime("%Y-%m-%d %H:%M %Z").strip()


def assess(policy: LatePolicy, when: SubmissionTime | None, days_left: int | None = None) -> LatePenalty:
    """The penalty ``policy`` gives a submission that came in ``when``; ``days_left``: the
    student's free late days before this lab (default: the policy's whole budget)."""
    due = policy.due_at
    zone = policy.zone_name
    at = when.at if when else None
    if at is not None:
        at = at.replace(tzinfo=due.tzinfo) if at.tzinfo is None else at.astimezone(due.tzinfo)
    source = when.source if when else "no submission time"
    late_s = (at - due).total_seconds() if at is not None else None
    lms_late = when.lms_late if when else None
    counted: float | None
    unmeasured = lms_late is True and (late_s is None or late_s <= 0)   # late, by how much nobody says
    if lms_late is False:
        counted = 0.0                        # the LMS says on time (extensions live there)
    elif lms_late is True:
        counted = max(late_s or 0.0, 1.0)    # late by at least what the evidence shows
    else:
        counted = late_s
    units = policy.units(counted) if counted is not None and counted > 0 else 0
    used, left = 0, None
    if policy.late_days is not None:
        before = policy.late_days if days_left is None else max(0, days_left)
        used = min(units, before)
        left = before - used
    charged = units - used
    percent = 0.0
    if charged:
        step = policy.percent if policy.percent is not None else 100.0
        percent = round(min(policy.cap, charged * step), 4)
    penalty = LatePenalty(
        due=due.isoformat(), zone=zone, submitted_at=at.isoformat() if at else None, time_source=source,
        late_s=None if counted is None or unmeasured else round(counted, 1), units=units, per=policy.per,
        percent=percent, of=policy.of, grace_minutes=policy.grace_minutes, lms_late=lms_late,
        late_days_used=used, late_days_left=left)
    return replace(penalty, note=_note(policy, penalty, at, late_s, lms_late, due, zone))


def _note(policy: LatePolicy, p: LatePenalty, at: datetime | None, late_s: float | None,
          lms_late: bool | None, due: datetime, zone: str) -> str:
    """One true sentence (or two) for the report."""
    due_text = _show(due, zone)
    src = f"Time from {p.time_source}."
    if lms_late is False:
        return f"Not late: the LMS did not mark it late (due {due_text}). {src}"
    if at is None and lms_late is None:
        return f"Not counted late: no submission time is known (due {due_text}). {src}"
    if lms_late is True and (late_s is None or late_s <= 0):
        lead = (f"The LMS marks it late (due {due_text}) but the download carries no submission "
                f"time, so it counts as late by the least the evidence shows")
    elif late_s is not None and late_s <= 0:
        return f"On time: submitted {_show(at, zone)}, due {due_text}. {src}"  # type: ignore[arg-type]
    else:
        lead = f"Submitted {_show(at, zone)}, {duration_words(late_s or 0)} after the due date {due_text}"  # type: ignore[arg-type]
    if p.units == 0:
        return f"{lead}, within the {policy.grace_minutes:g}-minute grace period: no penalty. {src}"
    unit = f"{p.units} {p.per}{'s' if p.units != 1 else ''} begun"
    parts = [f"{lead}: {unit}"]
    if policy.late_days is not None:
        parts.append(f"{p.late_days_used} late day{'s' if p.late_days_used != 1 else ''} used, "
                     f"{p.late_days_left} left")
    if p.percent:
        what = "the lab's points" if p.of == "max" else "the points earned"
        capped = " (the cap)" if abs(p.percent - policy.cap) < 1e-9 and policy.cap < 100 else ""
        parts.append(f"{p.percent:g}% of {what} deducted{capped}")
    else:
        parts.append("no penalty")
    return "; ".join(parts) + f". {src}"


__all__ = ["LatePenalty", "SubmissionTime", "assess", "duration_words", "late_by_text"]
