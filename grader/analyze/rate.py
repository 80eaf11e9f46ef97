"""Publish rate of a topic, measured the way ``ros2 topic hz`` reports it.

``ros2 topic hz`` prints ``average rate = 1 / mean(interval)`` plus min, max and std dev of the
intervals between receive times. We do the same on the recorded receive times, with one
addition: intervals longer than ``gap_factor`` x the median interval are treated as pauses
(e.g. a controller that only publishes while a goal is active, or a node started late) and
excluded, so the rate describes the node's timer rather than the scenario's idle periods.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, register
from grader.analyze._common import (Frames, missing_topic_feedback, since_start, thin, times,
                                    topic_or_student_topic)
from grader.analyze.evidence import SHARE

EVIDENCE = {
    "partial_credit": ('credit within the partial tolerance', SHARE),
    "use_pub_time": ('use publisher send times', ''),
    "fallback_type": ("type of the student's own topic to measure instead", ''),
    "value": ("publish rate", "Hz"),
    "expected_hz": ("expected rate", "Hz"),
    "rate_hz": ("measured rate (1 / mean interval)", "Hz"),
    "n": ("messages recorded", ""),
    "mean_s": ("mean interval between messages", "s"),
    "min_s": ("shortest interval", "s"),
    "max_s": ("longest interval (pauses left out)", "s"),
    "std_s": ("standard deviation of the intervals", "s"),
    "gaps_excluded": ("pauses left out of the rate", ""),
    "span_s": ("time from first to last message", "s"),
    "rel_error": ("difference from the expected rate", SHARE),
    "rel_tol": ("tolerance for full credit", SHARE),
    "partial_rel_tol": ("tolerance for partial credit", SHARE),
    "min_messages": ("messages needed to measure", ""),
    "gap_factor": ("an interval longer than this many median intervals is a pause", ""),
    "intervals": None,            # {t, dt}: the figure's series (t in s since the scenario start)
}


def rate_stats(t: np.ndarray, gap_factor: float | None = 5.0) -> dict:
    """Rate statistics of sorted receive times ``t`` (seconds).

    Returns mean rate (1/mean interval, Hz), min/max/std of intervals (s), number of samples,
    and how many pauses were excluded.
    """
    t = np.sort(np.asarray(t, float))
    t = t[np.isfinite(t)]
    if len(t) < 2:
        return {"n": int(len(t)), "rate_hz": float("nan"), "min_s": float("nan"),
                "max_s": float("nan"), "std_s": float("nan"), "mean_s": float("nan"),
                "gaps_excluded": 0, "span_s": 0.0}
    d = np.diff(t)
    n_gaps = 0
    if gap_factor:
        med = float(np.median(d))
        if med > 0:
            keep = d <= gap_factor * med
            n_gaps = int((~keep).sum())
            if keep.any():
                d = d[keep]
    d = d[d >= 0]
    mean = float(d.mean()) if len(d) else float("nan")
    return {
        "n": int(len(t)),
        "rate_hz": 1.0 / mean if mean and mean > 0 else float("nan"),
        "mean_s": mean,
        "min_s": float(d.min()) if len(d) else float("nan"),
        "max_s": float(d.max()) if len(d) else float("nan"),
        "std_s": float(d.std()) if len(d) else float("nan"),
        "gaps_excluded": n_gaps,
        "span_s": float(t[-1] - t[0]),
    }


class PublishRateParams(AnalyzerParams):
    topic: str = Field(description='topic to measure, e.g. "/random_numbers"')
    expected_hz: float = Field(gt=0, description="Hz: nominal rate, e.g. 1.0, 33.33 (0.03 s timer), 62.5")
    rel_tol: float = Field(0.10, ge=0, description="|rate/expected - 1| <= rel_tol -> full credit")
    partial_rel_tol: float = Field(0.30, ge=0, description="|rate/expected - 1| <= this -> partial_credit")
    partial_credit: float = Field(0.5, ge=0, le=1, description="credit within partial_rel_tol")
    min_messages: int = Field(5, ge=0, description="fewer messages -> fail (not enough to measure)")
    gap_factor: float | None = Field(
        5.0, gt=0, description="intervals > gap_factor x median are pauses, not timer periods (None: none are)")
    use_pub_time: bool = Field(False, description="measure on publisher send time (pub_t) instead of receive time")
    fallback_type: str | None = Field(
        None, description="measure the student's own topic of this type when `topic` is misnamed")


@register("publish_rate", timing="the publish rate", evidence=EVIDENCE, expect="{expected_hz:g} Hz ± {rel_tol:.0%}",
          params=PublishRateParams)
def publish_rate(frames: Frames, p: PublishRateParams) -> Finding:
    """Mean publish rate vs. the expected rate.

    Why receive time by default: that is what ``ros2 topic hz`` (the lab's tool for Question 1)
    measures, and a node whose timer is right but which blocks its executor shows the problem there.
    """
    name, expected = p.topic, p.expected_hz
    if not name or not expected:
        return Finding.error("publish_rate needs params 'topic' and 'expected_hz'.")
    df, name, note = topic_or_student_topic(frames, name, p.fallback_type)
    if df is None:
        return Finding.fail(missing_topic_feedback(frames, name), {"topic": name})
    if note:
        finding = publish_rate(frames, {**p.model_dump(), "topic": name, "fallback_type": None})
        finding.feedback = note + finding.feedback
        finding.evidence = {**finding.evidence, "measured_topic": name}
        return finding
    t = times(df)
    if p.use_pub_time and "pub_t" in df.columns:
        pt = df["pub_t"].to_numpy(float)
        if np.isfinite(pt).sum() >= 2:
            t = pt
    st = rate_stats(t, p.gap_factor)
    ev = {"topic": name, "expected_hz": float(expected), **st}
    ts = np.sort(t[np.isfinite(t)])
    if len(ts) >= 2:
        keep = thin(len(ts) - 1, 400)
        ev["intervals"] = {"t": since_start(frames, ts[1:][keep]).tolist(),
                           "dt": np.round(np.diff(ts)[keep], 5).tolist()}
    if st["n"] < p.min_messages or not np.isfinite(st["rate_hz"]):
        return Finding(st["rate_hz"], 0.0, "fail",
                       f"Only {st['n']} message(s) on {name}: not enough to measure a rate "
                       f"(expected ~{expected:g} Hz).", ev)
    rate = st["rate_hz"]
    err = abs(rate / float(expected) - 1.0)
    ev["rel_error"] = err
    if err <= p.rel_tol:
        return Finding(round(rate, 4), 1.0, "pass",
                       f"{name} is published at {rate:.3g} Hz (expected ~{expected:g} Hz).", ev)
    hint = (f"{name} is published at {rate:.3g} Hz but ~{expected:g} Hz was expected "
            f"(timer period {1.0 / float(expected):.3g} s).")
    if rate < float(expected):
        hint += " Check the timer period, and that no callback blocks the executor (e.g. sleep or input())."
    else:
        hint += " Check the timer period and that you publish once per timer callback only."
    if err <= p.partial_rel_tol:
        return Finding(round(rate, 4), p.partial_credit, "partial", hint, ev)
    return Finding(round(rate, 4), 0.0, "fail", hint, ev)
