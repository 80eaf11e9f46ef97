"""The late policy: what a rubric's ``late:`` says a submission costs, from when it came in and
who says so; and the loader's checks of ``late:`` and ``loose_files:``."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from grader.intake.late import SubmissionTime, assess, late_by_text
from grader.rubric.intake_fields import LatePolicy
from grader.rubric.load import RubricError, load_rubric

REPO = Path(__file__).resolve().parents[2]
DUE = "2025-02-14 23:59"
ZONE = "America/New_York"
DUE_UTC = datetime(2025, 2, 15, 4, 59, tzinfo=timezone.utc)     # 23:59 EST


def policy(**kw) -> LatePolicy:
    return LatePolicy(**{"due": DUE, "timezone": ZONE, **kw})


def at(delta: timedelta, source: str = "Gradescope's submission time", **kw) -> SubmissionTime:
    return SubmissionTime(DUE_UTC + delta, source, **kw)


@pytest.mark.parametrize("late, kw, units, percent", [
    (timedelta(minutes=-5), {}, 0, 0),                                   # on time
    (timedelta(minutes=10), {"grace_minutes": 15}, 0, 0),                # within grace
    (timedelta(minutes=16), {"grace_minutes": 15}, 1, 10),               # a day begun
    (timedelta(days=1, minutes=1), {}, 2, 20),                           # the second day begun
    (timedelta(days=9), {}, 9, 50),                                      # capped at 50
    (timedelta(hours=2, minutes=30), {"per": "hour", "percent": 5}, 3, 15),
])
def test_percent_per_day_or_hour_with_grace_and_cap(late, kw, units, percent) -> None:
    p = assess(policy(**{"percent": 10, "cap": 50, **kw}), at(late))
    assert (p.units, p.percent) == (units, percent)
    assert p.points(18, 20) == round(20 * percent / 100, 2)             # of the lab's points


def test_percent_of_the_points_earned_never_below_zero() -> None:
    p = assess(policy(percent=25, of="earned"), at(timedelta(days=1, hours=1)))
    assert p.percent == 50 and p.points(12, 20) == 6
    assert assess(policy(percent=100), at(timedelta(days=3))).points(4, 20) == 4     # not 20


def test_late_day_budget_covers_days_then_charges_the_rest() -> None:
    three_days = at(timedelta(days=2, hours=3))
    full = assess(policy(late_days=5), three_days)                       # the whole budget left
    assert (full.units, full.late_days_used, full.late_days_left, full.percent) == (3, 3, 2, 0)
    assert "3 late days used, 2 left" in full.note and "no penalty" in full.note
    short = assess(policy(late_days=5, percent=20), three_days, days_left=1)
    assert (short.late_days_used, short.late_days_left, short.percent) == (1, 0, 40)
    none_left = assess(policy(late_days=5), three_days, days_left=0)     # beyond: all points
    assert none_left.percent == 100


def test_notes_say_when_how_late_what_it_cost_and_who_says_so() -> None:
    p = assess(policy(percent=10, cap=50, grace_minutes=15), at(timedelta(days=1, hours=2)))
    assert p.note == ("Submitted 2025-02-16 01:59 EST, 1 day 2 h after the due date 2025-02-14 23:59 EST: "
                      "2 days begun; 20% of the lab's points deducted. Time from Gradescope's submission time.")
    assert p.submitted_at == "2025-02-16T01:59:00-05:00" and p.due == "2025-02-14T23:59:00-05:00"
    assert p.time_source == "Gradescope's submission time"


def test_the_lms_verdict_decides_and_a_time_only_measures() -> None:
    pol = policy(percent=10)
    # Canvas marks it late, the download has no time: the least lateness the evidence shows
    marked = assess(pol, SubmissionTime(None, "Canvas's LATE mark", lms_late=True))
    assert (marked.units, marked.percent, marked.late_s) == (1, 10, None)
    assert late_by_text(marked) == "late (LMS mark), by an unknown time"
    assert marked.note.startswith("The LMS marks it late (due 2025-02-14 23:59 EST) but the download carries no "
                                  "submission time, so it counts as late by the least the evidence shows")
    # ... and within a grace period that could cover it, no penalty
    assert assess(policy(percent=10, grace_minutes=30),
                  SubmissionTime(None, "Canvas", lms_late=True)).percent == 0
    # a late mark with an archive time: that lateness
    assert assess(pol, at(timedelta(days=2, hours=1), "Canvas", lms_late=True)).units == 3
    # Canvas says on time (an extension lives in Canvas): a later file time does not count
    assert assess(pol, at(timedelta(days=4), "Canvas", lms_late=False)).percent == 0


def test_no_known_time_is_not_late() -> None:
    p = assess(policy(percent=10), None)
    assert (p.late_s, p.percent) == (None, 0)
    assert p.note.startswith("Not counted late: no submission time is known")


def test_a_zip_time_without_zone_is_read_in_the_due_dates_zone() -> None:
    naive = SubmissionTime(datetime(2025, 2, 15, 0, 30), "the newest file time inside ws.zip")
    assert assess(policy(percent=10), naive).late_s == 31 * 60


def test_an_override_replaces_the_policys_points() -> None:
    p = assess(policy(percent=10), at(timedelta(days=2))).with_override(0.0, "manual.csv line 2")
    assert p.points(20, 20) == 0 and p.override_source == "manual.csv line 2"
    assert p.with_override(None).points(20, 20) == 4


# ------------------------------------------------------------------------------- the loader
BASE = (REPO / "rubrics" / "first_nodes.yaml").read_text()


def _rubric(tmp_path: Path, extra: str) -> Path:
    text = BASE.replace("\nitems:\n", "\n" + extra + "\nitems:\n", 1)
    path = tmp_path / "r.yaml"
    path.write_text(text)
    return path


def _problems(tmp_path: Path, extra: str) -> list[str]:
    with pytest.raises(RubricError) as exc:
        load_rubric(_rubric(tmp_path, extra))
    return [f"{p.path}: {p.message}" for p in exc.value.problems]


@pytest.mark.parametrize("late, message", [
    ("late: {due: 2025-02-14 23:59, percent: 10}",
     "has no time zone: add timezone: (e.g. America/New_York) or an offset"),
    ("late: {due: 2025-02-14, timezone: UTC, percent: 10}", "has no time of day"),
    ("late: {due: 'Friday', timezone: UTC, percent: 10}", "is not a date and time like 2025-02-14 23:59"),
    ("late: {due: 2025-02-14 23:59, timezone: Mars/Olympus, percent: 10}", "unknown time zone 'Mars/Olympus'"),
    ("late: {due: 2025-02-14 23:59, timezone: UTC}", "say what lateness costs"),
    ("late: {due: 2025-02-14 23:59, timezone: UTC, late_days: 3, per: hour}", "late_days are counted in days"),
    ("late: {due: 2025-02-14 23:59, timezone: UTC, percent: 120}", "expected a number > 0 and <= 100, got 120"),
])
def test_a_late_policy_the_runner_cannot_apply_is_rejected(tmp_path: Path, late: str, message: str) -> None:
    problems = _problems(tmp_path, late)
    assert len(problems) == 1 and problems[0].startswith("late") and message in problems[0], problems


def test_late_and_loose_files_load(tmp_path: Path) -> None:
    rubric = load_rubric(_rubric(tmp_path, "late: {due: 2025-02-14T23:59:00-05:00, percent: 10, cap: 30}"))
    assert rubric.late.due_at == datetime(2025, 2, 14, 23, 59, tzinfo=timezone(timedelta(hours=-5)))
    assert rubric.loose_files.entry_point("turtle_controller") == "my_first_package.turtle_controller:main"


def test_loose_files_must_name_a_package_a_scenario_runs_and_python_files(tmp_path: Path) -> None:
    text = BASE.replace("package: my_first_package\n  executables:", "package: my_second_package\n  executables:")
    text = text.replace("my_first_node: my_first_node.py", "my_first_node: my_first_node.txt")
    path = tmp_path / "r.yaml"
    path.write_text(text)
    with pytest.raises(RubricError) as exc:
        load_rubric(path)
    shown = str(exc.value)
    assert "loose_files.executables.my_first_node: expected a Python file name like my_node.py" in shown
    text = BASE.replace("package: my_first_package\n  executables:", "package: my_second_package\n  executables:")
    path.write_text(text)
    with pytest.raises(RubricError) as exc:
        load_rubric(path)
    assert "loose_files.package: no scenario runs package 'my_second_package' (the scenarios run " \
           "my_first_package)" in str(exc.value)
