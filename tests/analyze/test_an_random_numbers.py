"""Exercise 1 publisher: topic/type from meta, message shape and uniformity."""

from __future__ import annotations

import numpy as np
import pytest

from analyze_synth import T0, check, frame, with_meta
from grader.analyze import get


def _rn(u1, u2, lens=None, topic="/random_numbers", types=None) -> dict:
    n = len(u1)
    cols = {"data[0]": u1, "data[1]": u2, "data.len": lens if lens is not None else [2] * n}
    return with_meta({topic: frame(T0 + np.arange(n), **cols)}, types=types)


def _uniform(n=60, seed=0):
    u = np.random.default_rng(seed).random((n, 2)).astype(np.float32).astype(float)
    return u[:, 0], u[:, 1]


def test_topic_type_pass_and_wrong_type_and_missing() -> None:
    f = check(get("topic_type")(_rn(*_uniform()), {}))
    assert f.status == "pass" and f.evidence["count"] == 60
    f = check(get("topic_type")(_rn(*_uniform(), types={"/random_numbers": "std_msgs/msg/Float64MultiArray"}), {}))
    assert f.status == "fail" and "Float64MultiArray" in f.feedback and "Float32MultiArray" in f.feedback
    f = check(get("topic_type")(_rn(*_uniform(), topic="/random_number"), {}))
    assert f.status == "fail" and "/random_number" in f.feedback and "similar" in f.feedback


def test_topic_type_accepts_short_type_spelling() -> None:
    f = check(get("topic_type")(_rn(*_uniform(), types={"/random_numbers": "std_msgs/Float32MultiArray"}), {}))
    assert f.status == "pass"


def test_values_pass() -> None:
    f = check(get("random_numbers_values")(_rn(*_uniform()), {}))
    assert f.status == "pass" and f.evidence["ks"]["u1_p"] > 0.001


def test_values_identical_pair_is_caught() -> None:
    u1, _ = _uniform()
    f = check(get("random_numbers_values")(_rn(u1, u1), {}))
    assert f.status == "partial" and "same number" in f.feedback


def test_values_not_uniform() -> None:
    u1, u2 = _uniform(200)
    f = check(get("random_numbers_values")(_rn(u1 * 0.5, u2), {}))
    assert f.status == "partial" and "values of u1 do not look uniform" in f.feedback


def test_values_wrong_length_and_range() -> None:
    u1, u2 = _uniform(20)
    lens = [2] * 20
    lens[3] = 3
    u2 = u2.copy()
    u2[5] = 1.5
    f = check(get("random_numbers_values")(_rn(u1, u2, lens), {}))
    assert f.status == "partial" and f.fraction == pytest.approx(0.5 * 18 / 20)
    assert "exactly 2" in f.feedback and "outside (0, 1)" in f.feedback


def test_values_missing_topic() -> None:
    f = check(get("random_numbers_values")(with_meta({}), {}))
    assert f.status == "fail" and "/random_numbers" in f.feedback


def test_topic_type_without_meta_uses_frame_attrs() -> None:
    fr = _rn(*_uniform())
    del fr["__meta__"]
    assert check(get("topic_type")(fr, {})).status == "pass"
    fr["/random_numbers"].attrs["type"] = "std_msgs/msg/String"
    f = check(get("topic_type")(fr, {}))
    assert f.status == "fail" and "std_msgs/msg/String" in f.feedback
