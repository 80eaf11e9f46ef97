"""What a late policy decided about one submission, and when it came in: the records the intake
writes (``grader.intake.late`` assesses them) and the result, the reports and the exports read
(``Result.late``, result.json ``late``). On the ground floor because every one of those floors
reads them; the policy and its arithmetic over dates stay with the intake.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from datetime import datetime
from typing import Mapping

from grader.contracts.values import JsonValue


@dataclass(frozen=True)
class SubmissionTime:
    """When a submission came in, and who says so. ``at`` may be naive (a zip file's times
    carry no zone): it is then read in the due date's zone. ``lms_late``: the LMS's own
    verdict, when it gives one (Canvas's LATE mark)."""

    at: datetime | None
    source: str
    lms_late: bool | None = None

    def to_dict(self) -> dict[str, JsonValue]:
        return {"at": self.at.isoformat() if self.at else None, "source": self.source,
                "lms_late": self.lms_late}

    @classmethod
    def from_dict(cls, doc: Mapping[str, JsonValue]) -> "SubmissionTime":
        at = doc.get("at")
        return cls(datetime.fromisoformat(at) if at else None, str(doc.get("source") or ""),
                   doc.get("lms_late"))


@dataclass(frozen=True)
class LatePenalty:
    """What the late policy made of one submission (result.json ``late``). ``percent`` of the
    lab's points (``of: max``) or of the points earned (``of: earned``) is deducted, unless a
    TA's ``override_points`` (``grader scores merge``, column ``late_penalty``) replaces it."""

    due: str                          # ISO, with offset
    zone: str                         # the zone times are shown in
    submitted_at: str | None          # ISO, or None: unknown
    time_source: str                  # who says when it came in
    late_s: float | None              # seconds after the due date counted (None: unknown)
    units: int                        # days (hours) begun after the due date, beyond the grace period
    per: str                          # day | hour
    percent: float                    # penalty in percent of `of`
    of: str                           # max | earned
    grace_minutes: float = 0.0
    lms_late: bool | None = None      # the LMS's own verdict (Canvas's LATE mark), if it gave one
    late_days_used: int = 0
    late_days_left: int | None = None
    override_points: float | None = None
    override_source: str = ""
    note: str = ""                    # one sentence for the student's report

    def points(self, score: float, max_score: float) -> float:
        """Points deducted from ``score`` (never more than it)."""
        if self.override_points is not None:
            return round(min(score, self.override_points), 2)
        base = max_score if self.of == "max" else score
        return round(min(score, base * self.percent / 100.0), 2)

    def to_dict(self) -> dict[str, JsonValue]:
        return asdict(self)

    @classmethod
    def from_dict(cls, doc: Mapping[str, JsonValue]) -> "LatePenalty":
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in doc.items() if k in names})

    def with_override(self, points: float | None, source: str = "") -> "LatePenalty":
        return replace(self, override_points=points, override_source=source if points is not None else "")


def duration_words(seconds: float) -> str:
    """``1 day 2 h``, ``3 h 5 min``, ``12 min``, ``40 s``."""
    seconds = max(0.0, seconds)
    days, rest = divmod(int(round(seconds)), 86400)
    hours, rest = divmod(rest, 3600)
    minutes, secs = divmod(rest, 60)
    if days:
        return f"{days} day{'s' if days != 1 else ''}" + (f" {hours} h" if hours else "")
    if hours:
        return f"{hours} h" + (f" {minutes} min" if minutes else "")
    return f"{minutes} min" if minutes else f"{secs} s"


def late_by_text(p: LatePenalty) -> str:
    """``2 days`` / ``on time`` / ``unknown``: for tables."""
    if p.late_s is None:
        return "late (LMS mark), by an unknown time" if p.lms_late else "unknown"
    if p.late_s <= 0:
        return "on time"
    return duration_words(p.late_s)


__all__ = ["LatePenalty", "SubmissionTime", "duration_words", "late_by_text"]
