"""A realistic scored Lab 3 result (fake findings with plot evidence) for the report tests."""

from __future__ import annotations

import math
import random
from pathlib import Path
from typing import Any

import pytest

from grader.rubric import Result, Rubric, load_rubric, score

REPO = Path(__file__).resolve().parents[2]
T0 = 1795262900.25          # a scenario_start (epoch s) like the recorder's


class FakeFinding:
    """Duck-typed grader.analyze.Finding: the report layer only reads these attributes."""

    def __init__(self, value: Any = None, fraction: float = 1.0, status: str = "pass",
                 feedback: str = "", evidence: dict | None = None) -> None:
        self.value, self.fraction, self.status = value, fraction, status
        self.feedback, self.evidence = feedback, evidence or {}


def _boxmuller_histogram(n: int = 1000) -> dict[str, Any]:
    rng = random.Random(467)
    zs = [math.sqrt(-2 * math.log(1 - rng.random())) * math.cos(2 * math.pi * rng.random())
          for _ in range(n)]
    edges = [-4 + 0.5 * k for k in range(17)]
    counts = [sum(1 for z in zs if a <= z < b) for a, b in zip(edges, edges[1:])]
    return {"bins": edges, "counts": counts, "reference": "normal", "xlabel": "z"}


def _path(start: tuple[float, float], goal: tuple[float, float], heading: float) -> dict[str, Any]:
    """A unicycle under the lab's P controller: enough to look like a real trajectory."""
    x, y, th = *start, heading
    xs, ys = [x], [y]
    for _ in range(600):
        dx, dy = goal[0] - x, goal[1] - y
        d = math.hypot(dx, dy)
        if d < 0.05:
            break
        e = math.atan2(dy * math.cos(th) - dx * math.sin(th), dx * math.cos(th) + dy * math.sin(th))
        v, w = 0.5 * d, 2.0 * e
        th += w * 0.03
        x += v * math.cos(th) * 0.03
        y += v * math.sin(th) * 0.03
        xs.append(x)
        ys.append(y)
    return {"x": xs, "y": ys, "goal": list(goal), "label": f"goal ({goal[0]:g}, {goal[1]:g})", "end_heading": th}


def _trajectories() -> list[dict[str, Any]]:
    out, pos, heading = [], (5.544, 5.544), 0.0
    for goal in ((2.0, 7.0), (6.0, 4.0), (2.5, 2.5)):
        path = _path(pos, goal, heading)
        heading = path.pop("end_heading")
        pos = (path["x"][-1], path["y"][-1])
        out.append(path)
    return out


def findings_for_lab3() -> dict[str, FakeFinding]:
    F = FakeFinding
    return {
        "ex1.pub_topic": F("std_msgs/msg/Float32MultiArray", evidence={"topic": "/random_numbers"}),
        "ex1.pub_values": F("6/6 valid", evidence={"messages": 6, "min": 0.031, "max": 0.97}),
        "ex1.pub_rate": F(0.8, 0.5, "partial", "Measured 0.80 Hz.", {"periods_s": [1.25, 1.24, 1.26, 1.25, 1.25]}),
        "ex1.boxmuller": F("1000/1000 matched", 1.0, "pass", "All values match.",
                           {"matched": 1000, "max_abs_error": 3.2e-7}),
        "ex1.sub_logging": F(True, evidence={"level": "INFO", "lines": 1000}),
        "ex1.normality": F(0.41, evidence={"shapiro_p": 0.41, "mean": 0.012, "std": 1.003,
                                           "histogram": _boxmuller_histogram()}),
        "ex2.goals_reached": F("3/3", 1.0, "pass", "", {
            "goals": [{"goal": 1, "x": 2.0, "y": 7.0, "t_sent": T0 + 1.5, "final_error": 0.046,
                       "reached": True, "time_to_reach": 9.8},
                      {"goal": 2, "x": 6.0, "y": 4.0, "t_sent": T0 + 11.5, "final_error": 0.048,
                       "reached": True, "time_to_reach": 11.2},
                      {"goal": 3, "x": 2.5, "y": 2.5, "t_sent": T0 + 23.0, "final_error": 0.049,
                       "reached": True, "time_to_reach": 10.1}],
            "tol_reached": 0.1, "goal_source": "events", "scenario_start": T0,
            "trajectory": _trajectories()}),
        "ex2.turn_direction": F("1/2 correct", 0.5, "partial",
                                "Turned right for the goal behind <script>alert(1)</script>.",
                                {"goal_behind": "right (expected left)", "goal_right": "right"}),
        "ex2.control_law": F(0.97, evidence={"K_1": 0.5, "K_2": 1.0, "r2_v": 0.99, "r2_w": 0.95}),
        "ex2.control_rate": F(33.2, evidence={"rate_hz": 33.2}),
        "ex2.goal_publisher": F([[2.0, 7.0]], evidence={"published": [[2.0, 7.0]]}),
        "ex2.goal_publisher_robust": F(None, 0.0, "fail", "The process exited after 'oops' (ValueError).",
                                       {"returncode": 1, "stderr_tail": "ValueError: not enough values to unpack"}),
        "ex3.action_advertised": F("/turtle_goal"),
        "ex3.goals_succeed": F("1/1", evidence={"results": [{"step": "reachable", "success": True, "error_m": 0.07}]}),
        "ex3.control_law": F(0.95, evidence={"K_1": 0.49, "K_2": 1.99, "r2_v": 0.95, "r2_w": 0.93}),
        "ex3.loop_paced": F(30.1, evidence={"rate_hz": 30.1}),
        "ex3.rejects_out_of_bounds": F("rejected"),
        "ex3.timeout": F(None, 0.0, "error", "No result for the timeout goal within 15 s.", {}),
        "ex3.client_rejected": F("Goal Rejected"),
        "integrity.pose_publisher": F("turtlesim only"),
        "integrity.no_teleport": F(1, 0.0, "fail", "1 teleport_absolute call during ex2_controller.",
                                   {"calls": [{"service": "/turtle1/teleport_absolute", "t": 12.5}]}),
    }


@pytest.fixture(scope="session")
def lab3() -> Rubric:
    return load_rubric(REPO / "rubrics" / "enee467_lab3.yaml", check_files=False)


@pytest.fixture(scope="session")
def lab3_result(lab3: Rubric) -> Result:
    return score(lab3, findings_for_lab3())


@pytest.fixture
def make_finding():
    return FakeFinding
