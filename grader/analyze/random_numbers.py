"""Exercise 1, publisher side: the topic exists with the right type and carries two U(0,1) values.

The lab asks for a Float32MultiArray on ``random_numbers`` (resolves to ``/random_numbers``) with
``[random.random(), random.random()]`` once per second. Topic/type come from the bag meta (what
the recorder saw on the graph), the values from the recorded messages.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from pydantic import Field
from scipy import stats

from grader.analyze.evidence import SHARE
from grader.analyze import AnalyzerParams, Finding, register
from grader.analyze._common import (Frames, meta, meta_row, missing_topic_feedback, norm_type, sentence,
                                    topic_or_student_topic,
                                    publishers_of, topic)


#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "min_count": ("messages needed", ""),
    "ks_min_samples": ('samples needed for the uniformity test', ''),
    "shape_credit": ('credit for the right shape only', SHARE),
    "fallback_type": ("type of the student's own topic to measure instead", ''),
    "type": ("message type", ""),
    "expected_type": ("message type expected", ""),
    "count": ("messages recorded", ""),
    "publishers": ("publishing nodes", ""),
    "n_len_not_2": ("messages without exactly 2 values", ""),
    "n_out_of_range": ("messages with a value outside (0, 1)", ""),
    "lengths_seen": ("numbers of values per message seen", ""),
    "first": ("first messages [u1, u2]", ""),
    "n_u1_equals_u2": ("messages with u1 = u2", ""),
    "ks": ("uniformity test", ""),
    "ks.u1_stat": ("uniformity test (Kolmogorov-Smirnov) of u1: statistic", ""),
    "ks.u1_p": ("uniformity test of u1: p-value", ""),
    "ks.u2_stat": ("uniformity test (Kolmogorov-Smirnov) of u2: statistic", ""),
    "ks.u2_p": ("uniformity test of u2: p-value", ""),
    "ks_alpha": ("p-value below which values are not uniform", ""),
    "min_messages": ("messages needed", ""),
    "columns": None,
}


class TopicTypeParams(AnalyzerParams):
    topic: str = Field("/random_numbers", description="the topic")
    type: str = Field("std_msgs/msg/Float32MultiArray", description="message type expected")
    min_count: int = Field(1, ge=0, description="messages needed")


@register("topic_type", params=TopicTypeParams, judges=("ros names",),
          evidence={**EVIDENCE, "value": ("message type", "")}, expect="{type} messages on {topic}")
def topic_type(frames: Frames, p: TopicTypeParams) -> Finding:
    """The topic was published with the expected message type (from the ``__meta__`` frame)."""
    name, want = p.topic, norm_type(p.type)
    row = meta_row(frames, name)
    if row is None and meta(frames) is None:
        # No meta frame: fall back to the topic frame itself (load_frames puts the type in attrs).
        df = topic(frames, name)
        if df is None:
            return Finding.fail(missing_topic_feedback(frames, name, f"type {want}"), {"topic": name})
        row = {"type": df.attrs.get("type") or want, "count": len(df)}
    if row is None:
        return Finding.fail(missing_topic_feedback(frames, name, f"type {want}"), {"topic": name})
    got = norm_type(row.get("type"))
    try:
        count = int(row.get("count"))  # type: ignore[arg-type]  # None is caught below
    except (TypeError, ValueError):
        df = topic(frames, name)
        count = 0 if df is None else len(df)
    ev = {"topic": name, "type": got, "expected_type": want, "count": count,
          "publishers": publishers_of(frames, name)}
    if got != want:
        return Finding(got, 0.0, "fail",
                       f"{name} has type {got}, but the lab asks for {want}: create the publisher "
                       f"with create_publisher({want.rsplit('/', 1)[-1]}, ...).", ev)
    if count < p.min_count:
        return Finding(count, 0.0, "fail",
                       f"{name} ({want}) exists but no messages were published on it: check that "
                       "your timer callback calls publish().", ev)
    return Finding(got, 1.0, "pass", f"{name} is published with type {want} ({count} messages).", ev)


class RandomNumbersValuesParams(AnalyzerParams):
    topic: str = Field("/random_numbers", description="the topic")
    min_messages: int = Field(3, ge=0, description="messages needed")
    ks_min_samples: int = Field(20, ge=1, description="run the uniformity test only with at least this many messages")
    ks_alpha: float = Field(0.001, ge=0, le=1, description="KS p-value below this -> \"not uniform\"")
    shape_credit: float = Field(0.5, ge=0, le=1,
                                description="credit when every message is [u1, u2] in (0,1) but uniformity fails")
    fallback_type: str | None = Field(None, description="e.g. std_msgs/msg/Float32MultiArray: judge the student's "
                                                        "own topic if misnamed")


@register("random_numbers_values", params=RandomNumbersValuesParams,
          evidence={**EVIDENCE, "value": ("valid messages", "")},
          expect="every message [u1, u2] with both values in (0, 1), uniformly distributed")
def random_numbers_values(frames: Frames, p: RandomNumbersValuesParams) -> Finding:
    """Every message holds exactly two values in (0, 1); u1 and u2 look U(0,1) and differ.

    Why each check: Box-Muller needs exactly two numbers, needs u1 > 0 (log) and u1 < 1 to be
    useful, and is only Normal if both are uniform and independent (publishing the same number
    twice is a classic slip).
    """
    df, name, note = topic_or_student_topic(frames, p.topic, p.fallback_type)
    if df is None:
        return Finding.fail(missing_topic_feedback(frames, name), {"topic": name})
    finding = _values(df, name, p)
    if note:
        finding.feedback = note + finding.feedback
        finding.evidence = {**finding.evidence, "measured_topic": name}
    return finding


def _values(df: pd.DataFrame, name: str, p: RandomNumbersValuesParams) -> Finding:
    n = len(df)
    if "data[0]" not in df.columns:
        return Finding.fail(f"Messages on {name} carry no data array: fill msg.data = [u1, u2].",
                            {"topic": name, "n": n, "columns": list(map(str, df.columns))[:20]})
    if "data.len" in df.columns:
        lens = df["data.len"].to_numpy(float)
    else:
        cols = [c for c in df.columns if str(c).startswith("data[")]
        lens = np.isfinite(df[cols].to_numpy(float)).sum(axis=1).astype(float)
    u1 = df["data[0]"].to_numpy(float)
    u2 = df["data[1]"].to_numpy(float) if "data[1]" in df.columns else np.full(n, np.nan)
    len_ok = lens == 2
    range_ok = (u1 > 0) & (u1 < 1) & (u2 > 0) & (u2 < 1)
    good = len_ok & range_ok
    ev: dict = {"topic": name, "n": n, "n_len_not_2": int((~len_ok).sum()),
                "n_out_of_range": int((len_ok & ~range_ok).sum()),
                "lengths_seen": sorted({int(x) for x in lens[np.isfinite(lens)]})[:10],
                "first": [[float(a), float(b)] for a, b in zip(u1[:5], u2[:5])]}
    if n < p.min_messages:
        return Finding(n, 0.0, "fail", f"Only {n} message(s) on {name}; the publisher should send one per second.", ev)
    good_ratio = float(good.mean())
    if good_ratio < 1.0:
        problems = []
        if ev["n_len_not_2"]:
            problems.append(f"{ev['n_len_not_2']} message(s) do not have exactly 2 values "
                            f"(lengths seen: {ev['lengths_seen']})")
        if ev["n_out_of_range"]:
            problems.append(f"{ev['n_out_of_range']} message(s) have a value outside (0, 1)")
        frac = p.shape_credit * good_ratio
        return Finding(f"{int(good.sum())}/{n} valid", frac, "partial" if frac > 0 else "fail",
                       "; ".join(problems) + ". Publish msg.data = [random.random(), random.random()].", ev)
    # Shape is right. Uniformity and independence.
    issues = []
    identical = np.isclose(u1, u2, rtol=0, atol=1e-7)
    ev["n_u1_equals_u2"] = int(identical.sum())
    if identical.mean() > 0.5:
        issues.append("u1 and u2 are the same number in most messages: call random.random() twice")
    if n >= 2 and np.unique(u1).size == 1:
        issues.append("u1 never changes: draw new random numbers in every timer callback")
    if n >= p.ks_min_samples:
        ks1 = stats.kstest(u1, "uniform")
        ks2 = stats.kstest(u2, "uniform")
        ev["ks"] = {"u1_stat": float(ks1.statistic), "u1_p": float(ks1.pvalue),
                    "u2_stat": float(ks2.statistic), "u2_p": float(ks2.pvalue)}
        bad = [nm for nm, r in (("u1", ks1), ("u2", ks2)) if r.pvalue < p.ks_alpha]
        if bad:
            issues.append(f"the values of {' and '.join(bad)} do not look uniform on (0,1) (KS test p < {p.ks_alpha:g})")
    else:
        ev["ks"] = None
    if issues:
        frac = p.shape_credit
        return Finding(f"{n}/{n} valid, not uniform", frac, "partial" if frac > 0 else "fail",
                       sentence("; ".join(issues)), ev)
    note = "" if ev["ks"] else f" (too few messages for a uniformity test: {n})"
    return Finding(f"{n}/{n} valid", 1.0, "pass",
                   f"All {n} messages on {name} hold two values in (0, 1){note}.", ev)
