"""publish_rate: mean rate like `ros2 topic hz`, pauses excluded."""

from __future__ import annotations

import numpy as np
import pytest

from analyze_synth import T0, check, frame, with_meta
from grader.analyze import get
from grader.analyze.rate import rate_stats


def _frames(t) -> dict:
    return with_meta({"/x": frame(t, v=np.zeros(len(t)))})


def test_rate_stats_matches_definition() -> None:
    rng = np.random.default_rng(0)
    t = T0 + np.cumsum(0.03 + rng.normal(0, 0.002, 300))
    st = rate_stats(t)
    d = np.diff(t)
    assert st["rate_hz"] == pytest.approx(1 / d.mean())
    assert st["min_s"] == pytest.approx(d.min()) and st["max_s"] == pytest.approx(d.max())
    assert st["std_s"] == pytest.approx(d.std())


@pytest.mark.parametrize("period,expected,status", [
    (1.0, 1.0, "pass"), (0.03, 33.33, "pass"), (0.016, 62.5, "pass"),
    (0.5, 1.0, "fail"),          # 2 Hz instead of 1 Hz
    (1.25, 1.0, "partial"),      # 0.8 Hz: off by 20 %
    (0.1, 33.33, "fail"),
])
def test_publish_rate(period: float, expected: float, status: str) -> None:
    rng = np.random.default_rng(1)
    n = max(20, int(30 / period))
    t = T0 + np.arange(n) * period + rng.normal(0, period * 0.02, n)
    f = check(get("publish_rate")(_frames(np.sort(t)), {"topic": "/x", "expected_hz": expected}))
    assert f.status == status, f.feedback
    assert f.evidence["rate_hz"] == pytest.approx(1 / period, rel=0.02)


def test_pauses_are_not_counted_as_periods() -> None:
    # two bursts at 33 Hz separated by 10 s of silence (controller idle between goals)
    t = np.concatenate([T0 + np.arange(300) * 0.03, T0 + 19 + np.arange(300) * 0.03])
    f = check(get("publish_rate")(_frames(t), {"topic": "/x", "expected_hz": 33.33}))
    assert f.status == "pass" and f.evidence["gaps_excluded"] == 1
    f = check(get("publish_rate")(_frames(t), {"topic": "/x", "expected_hz": 33.33, "gap_factor": None}))
    assert f.status != "pass"


def test_missing_topic_names_what_is_there() -> None:
    fr = with_meta({"/random_number": frame(T0 + np.arange(5), v=0.0)})
    f = check(get("publish_rate")(fr, {"topic": "/random_numbers", "expected_hz": 1.0}))
    assert f.status == "fail" and "/random_number" in f.feedback


def test_too_few_messages() -> None:
    f = check(get("publish_rate")(_frames(T0 + np.arange(3.0)), {"topic": "/x", "expected_hz": 1.0}))
    assert f.status == "fail" and "Only 3" in f.feedback
