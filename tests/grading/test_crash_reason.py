"""A node that died mid-scenario: every item that lost points says so, and in which step.

Why: the Lab 3 audit's mutant `len(msg.data) >= -2` dies on the scenario's one-number goal
before the last goal; its goals_reached is partial (3 of 4), and until this test the student read
only "goal 4 not reached ... check the signs of d_e and theta_e", which is not the cause.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "analyze"))

from analyze_synth import T0, law, simulate, stdout_frame, string_frame, with_meta  # noqa: E402
from grader.grading.analysis import analyze_item  # noqa: E402
from grader.rubric import load_rubric  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
GOALS = [(0.5, 2.0, 7.0), (25.5, 5.0, 1.0)]


def _dies_before_goal_2() -> dict:
    correct = law("correct")

    def controller(x, y, th, gx, gy):      # dead after the first goal: no command moves it
        return (0.0, 0.0) if (gx, gy) == GOALS[1][1:] else correct(x, y, th, gx, gy)

    frames = simulate(GOALS, controller, 50.0)
    rows = [(t, json.loads(d)) for t, d in zip(frames["/grader/events"].index, frames["/grader/events"]["data"])]
    rows += [(T0 + 24.0, {"event": "step_start", "step": "short_goal"}),
             (T0 + 24.2, {"event": "process_exit", "process": "controller", "returncode": 1,
                          "stopped_by_grader": False}),
             (T0 + 25.4, {"event": "step_start", "step": "goal_right"})]
    frames["/grader/events"] = string_frame(sorted(rows, key=lambda r: r[0]))
    frames["/grader/stdout"] = stdout_frame([(T0 + 24.1, "controller", "stderr",
                                              "IndexError: array index out of range")])
    return with_meta({k: v for k, v in frames.items() if k != "__meta__"},
                     publishers={"/turtle1/pose": ["/turtlesim"]})


def test_a_partial_item_names_the_crash_and_its_step() -> None:
    item = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml").item("ex2.goals_reached")
    finding = analyze_item(item, _dies_before_goal_2())
    assert finding.status == "partial", finding.feedback
    assert ("Node stopped: controller crashed (exit code 1) during step 'short_goal' "
            "(IndexError: array index out of range).") in finding.feedback
    assert finding.evidence["crashed_nodes"]


def test_a_full_mark_item_is_left_alone() -> None:
    item = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml").item("ex2.goals_reached")
    frames = _dies_before_goal_2()
    ev = frames["/grader/events"]
    keep = [not ('"goal_sent"' in d and '"goal1"' in d) for d in ev["data"]]
    frames["/grader/events"] = pd.DataFrame(ev[keep])
    finding = analyze_item(item, frames)
    assert finding.status == "pass" and "Node stopped" not in finding.feedback
