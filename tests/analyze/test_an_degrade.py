"""Every analyzer degrades gracefully: no internal errors on empty, partial or unrelated bags."""

from __future__ import annotations

import pytest

import grader.analyze as A
from analyze_synth import T0, check, events_frame, law, simulate, with_meta

PARAMS = {"publish_rate": {"topic": "/turtle1/cmd_vel", "expected_hz": 33.33}}


def _bags() -> dict[str, dict]:
    sim = simulate([(0.2, 2.0, 7.0)], law("correct"), 4.0)
    return {
        "empty": {},
        "meta_only": with_meta({}),
        "events_only": with_meta({"/grader/events": events_frame([(T0, "scenario_start", {}),
                                                                  (T0 + 1, "scenario_end", {})])}),
        "garbage_events": with_meta({"/grader/events": events_frame([(T0, "goal_sent", {"goal": "x"}),
                                                                     (T0 + 1, "action_result", {})])}),
        "controller_sim": sim,
    }


@pytest.mark.parametrize("bag", list(_bags()))
def test_no_internal_errors(bag: str) -> None:
    frames = _bags()[bag]
    for name in A.builtin_names():      # (a lab's own analyzers are tested with its lab)
        f = check(A.run(name, frames, PARAMS.get(name, {})))
        assert "Internal analyzer error" not in f.feedback, (name, f.feedback, f.evidence)
        if bag in ("empty", "meta_only"):
            assert f.status in ("fail", "error"), (name, f.status, f.feedback)
