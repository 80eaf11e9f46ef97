"""The speed scenarios run at when nobody says: 4x where the grader has two CPUs, 1x in a small
container (Gradescope's default 0.5 CPU starved every 4x recording of the Lab 3 reference)."""

from __future__ import annotations

from grader.grading import timescale
from grader.sandbox.allotment import Allotment
from grader.contracts.speed import DEFAULT_TIME_SCALE, default_time_scale


def test_the_default_follows_the_cpus_the_grader_is_given(monkeypatch) -> None:
    assert default_time_scale(2.0) == DEFAULT_TIME_SCALE == 4.0
    assert default_time_scale(16.0) == 4.0
    assert default_time_scale(1.5) == default_time_scale(0.5) == 1.0
    monkeypatch.setattr(timescale.allotment, "current", lambda: Allotment(cores=2, cpus=0.5, quota_cpus=0.5))
    assert timescale.machine_time_scale() == 1.0
    monkeypatch.setattr(timescale.allotment, "current", lambda: Allotment(cores=2, cpus=2.0))
    assert timescale.machine_time_scale() == 4.0
