"""Registry, Finding normalisation and the never-raising run()."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

import grader.analyze as A
from grader.errors import GraderError

EXPECTED = {
    "topic_type", "random_numbers_values", "publish_rate", "boxmuller", "boxmuller_logging", "normality",
    "goals_reached", "turn_direction", "control_law", "goal_publisher", "goal_publisher_robust",
    "action_advertised", "action_goals_succeed", "action_loop_paced", "action_rejects_out_of_bounds", "action_timeout",
    "action_client_rejected", "integrity_pose_publisher", "integrity_no_teleport",
    "nodes_running", "launch_installed", "service_answers", "request_echoed",
    "circle_radius", "circle_period", "keeps_moving", "no_wall_contact",
    "logged", "text_messages", "heard_messages", "pen_on_crossings", "canvas_colours",
}


def test_all_analyzers_registered() -> None:
    assert set(A.builtin_names()) == EXPECTED
    assert set(A.builtin_names()) <= set(A.names())


def test_unknown_param_is_rejected_with_the_accepted_names() -> None:
    with pytest.raises(GraderError, match="unknown parameter.*expected_hzz.*accepted: .*expected_hz"):
        A.get("publish_rate")({}, {"topic": "/x", "expected_hzz": 1.0})


def test_unknown_analyzer() -> None:
    with pytest.raises(GraderError, match="unknown analyzer 'nope'"):
        A.get("nope")


def test_run_turns_problems_into_error_findings() -> None:
    f = A.run("publish_rate", {}, {"bogus": 1})
    assert f.status == "error" and "bogus" in f.feedback
    # a frame whose index is not time breaks the analyzer internally: error, with a traceback
    bad = pd.DataFrame({"v": [1, 2, 3]}, index=pd.Index(["a", "b", "c"], name="t"))
    f = A.run("publish_rate", {"/x": bad}, {"topic": "/x", "expected_hz": 1.0})
    assert f.status == "error" and "Internal analyzer error" in f.feedback and f.evidence["traceback"]
    json.dumps(f.to_dict(), allow_nan=False)


def test_finding_normalises_evidence_and_fraction() -> None:
    f = A.Finding(np.float64(1.5), 1.7, "pass", "ok",
                  {"a": np.int64(3), "b": np.array([1.0, np.nan]), "c": (np.bool_(True), math.inf)})
    assert f.fraction == 1.0
    assert f.evidence == {"a": 3, "b": [1.0, None], "c": [True, None]}
    json.dumps(f.to_dict(), allow_nan=False)
    with pytest.raises(ValueError):
        A.Finding(1, 0.5, "maybe", "x")


def test_defaults_are_documented_per_analyzer() -> None:
    d = A.defaults("boxmuller")
    assert d["pass_ratio"] == 0.9 and d["bug_credit"] == {"sin_for_cos": 0.5}
