"""The rubric's intake fields: the late policy (``late:``) and how a submission of bare source
files becomes a package (``loose_files:``).

They sit in their own classes (and module) because they describe how submissions arrive, not
what is graded: ``grader.intake`` reads them, the scoring model does not. Format reference:
rubrics/README.md ("Late policy", "Loose files").
"""

from __future__ import annotations

from zoneinfo import ZoneInfo, ZoneInfoNotFoundError
import math
from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from grader.contracts.fields import ExecutableName, Model, PackageName
from grader.contracts.text import pattern_text

#: ``my_node.py`` or ``my_node.py:main`` (the function the console script calls; default main)
PyFile = Annotated[str, pattern_text(r"^[A-Za-z_][A-Za-z0-9_]*\.py(:[A-Za-z_][A-Za-z0-9_]*)?$",
                "a Python file name like my_node.py (or my_node.py:function)")]
Percent = Annotated[float, Field(gt=0, le=100, allow_inf_nan=False)]
UNIT_SECONDS = {"day": 86400.0, "hour": 3600.0}


def parse_due(text: str, zone: str | None) -> datetime:
    """``2025-02-14 23:59`` (+ ``zone``) or ``2025-02-14T23:59-05:00`` -> an aware datetime.
    Raises ValueError with the fix in words."""
    text = str(text).strip()
    try:
        when = datetime.fromisoformat(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a date and time like 2025-02-14 23:59 "
                         "(or 2025-02-14T23:59-05:00)") from None
    if len(text) <= 10:
        raise ValueError(f"{text!r} has no time of day: write the minute it is due, e.g. {text} 23:59")
    if zone is not None:
        try:
            tz = ZoneInfo(zone)
        except (ZoneInfoNotFoundError, ValueError):
            raise ValueError(f"unknown time zone {zone!r}; use a name like America/New_York or UTC") from None
        if when.tzinfo is None:
            return when.replace(tzinfo=tz)
    if when.tzinfo is None:
        raise ValueError(f"{text!r} has no time zone: add timezone: (e.g. America/New_York) or an "
                         "offset (2025-02-14T23:59-05:00)")
    return when


class LatePolicy(Model):
    """When a submission is late and what it costs (``late:`` in a rubric; ``--due`` replaces
    the due date). A submission up to ``grace_minutes`` after ``due`` is on time; after that,
    every day (or hour, ``per``) begun after the due date costs ``percent`` of the lab's points
    (``of: max``) or of the points earned (``of: earned``), at most ``cap`` percent. With
    ``late_days``, each student has that many free late days for the course (the roster's
    ``late_days`` column says how many are left); the days they do not cover cost ``percent``
    each (all points when no ``percent`` is given)."""

    due: str = Field(description="date and time it is due, e.g. '2025-02-14 23:59'")
    timezone: str | None = Field(None, description="IANA time zone of `due`, e.g. America/New_York")
    grace_minutes: Annotated[float, Field(ge=0, allow_inf_nan=False)] = Field(
        0.0, description="minutes after `due` still counted on time")
    percent: Percent | None = Field(None, description="penalty per day (or hour) begun, in percent")
    per: Literal["day", "hour"] = Field("day", description="the unit of `percent`")
    cap: Percent = Field(100.0, description="the largest penalty, in percent")
    of: Literal["max", "earned"] = Field("max", description="percent of the lab's points or of those earned")
    late_days: Annotated[int, Field(ge=0)] | None = Field(
        None, description="free late days per student for the course (the roster's late_days column: "
                          "days left)")

    @field_validator("due", mode="before")
    @classmethod
    def _text(cls, value: Any) -> Any:
        # YAML reads 2025-02-14 23:59:00 as a timestamp; the loader hands it over as text
        return str(value) if isinstance(value, datetime) else value

    @model_validator(mode="after")
    def _consistent(self) -> "LatePolicy":
        parse_due(self.due, self.timezone)
        if self.percent is None and self.late_days is None:
            raise ValueError("say what lateness costs: percent (per day or hour) and/or late_days")
        if self.late_days is not None and self.per != "day":
            raise ValueError("late_days are counted in days: use per: day with late_days")
        return self

    @property
    def due_at(self) -> datetime:
        return parse_due(self.due, self.timezone)

    @property
    def zone_name(self) -> str:
        return self.timezone or str(self.due_at.tzinfo)

    def with_due(self, due: str, zone: str | None = None) -> "LatePolicy":
        """The same policy with another due date (``grader grade --due``)."""
        return LatePolicy.model_validate({**self.model_dump(), "due": due,
                                          "timezone": zone if zone is not None else self.timezone})

    def units(self, late_s: float) -> int:
        """Days (hours) begun after the due date, for a submission ``late_s`` seconds after it;
        0 within the grace period."""
        if late_s <= self.grace_minutes * 60.0:
            return 0
        return max(1, math.ceil(late_s / UNIT_SECONDS[self.per] - 1e-9))


class LooseFiles(Model):
    """How a submission of bare Python files (no package.xml anywhere) is graded: the files go
    into a generated ament_python package ``package`` whose console scripts are ``executables``
    (script name -> the student's file). Files the table does not name are copied along (helper
    modules). Without ``loose_files`` such a submission is refused with the reason."""

    package: PackageName
    executables: Annotated[dict[ExecutableName, PyFile], Field(min_length=1)] = Field(
        description="console script -> the student's file, e.g. my_first_node: my_first_node.py")
    depends: Annotated[tuple[PackageName, ...], Field(strict=False)] = Field(
        ("rclpy",), description="the generated package.xml's <depend> entries")

    @property
    def files(self) -> dict[str, str]:
        """script -> file name (without the ``:function``)."""
        return {script: spec.split(":", 1)[0] for script, spec in self.executables.items()}

    def entry_point(self, script: str) -> str:
        file, _, func = self.executables[script].partition(":")
        return f"{self.package}.{file[:-3]}:{func or 'main'}"


def intake_problems(rubric: Any) -> list[tuple[str, str]]:
    """Cross-references of the intake fields (``(field path, message)``): the loose-files
    package must be one a scenario runs."""
    loose = getattr(rubric, "loose_files", None)
    if loose is None:
        return []
    used = {p.package for sc in rubric.scenarios.values() for p in sc.processes if p.package}
    if loose.package not in used:
        return [("loose_files.package", f"no scenario runs package {loose.package!r} "
                 f"(the scenarios run {', '.join(sorted(used)) or 'no package'})")]
    return []
