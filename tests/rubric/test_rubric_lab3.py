"""rubrics/enee467_lab3.yaml mirrors the lab's points table and the ARCHITECTURE item ids."""

from __future__ import annotations

from pathlib import Path

import pytest

from grader.rubric import Section, load_rubric
from grader.scenario.model import ActionGoal, Goal, GoalReached, Publish, Replay, Start

REPO = Path(__file__).resolve().parents[2]
LAB3 = REPO / "rubrics" / "enee467_lab3.yaml"
DATA = Path(__file__).parent / "data"

# docs/ARCHITECTURE.md, "Rubric item ids for ENEE 467 Lab 3": id -> (points, kind, analyzer)
EXPECTED = {
    "ex1.pub_topic": (4, "auto", "topic_type"),
    "ex1.pub_values": (3, "auto", "random_numbers_values"),
    "ex1.pub_rate": (3, "auto", "publish_rate"),
    "ex1.boxmuller": (6, "auto", "boxmuller"),
    "ex1.sub_logging": (2, "auto", "boxmuller_logging"),
    "ex1.normality": (2, "auto", "normality"),
    "ex2.goals_reached": (8, "auto", "goals_reached"),
    "ex2.turn_direction": (3, "auto", "turn_direction"),
    "ex2.control_law": (3, "auto", "control_law"),
    "ex2.control_rate": (2, "auto", "publish_rate"),
    "ex2.goal_publisher": (4, "auto", "goal_publisher"),
    "ex2.goal_publisher_robust": (0, "advisory", "goal_publisher_robust"),
    "ex3.action_advertised": (2, "auto", "action_advertised"),
    "ex3.goals_succeed": (4, "auto", "action_goals_succeed"),
    "ex3.control_law": (1, "auto", "control_law"),
    "ex3.loop_paced": (1, "auto", "action_loop_paced"),
    "ex3.rejects_out_of_bounds": (2, "auto", "action_rejects_out_of_bounds"),
    "ex3.timeout": (0, "advisory", "action_timeout"),
    "ex3.client_rejected": (0, "advisory", "action_client_rejected"),
    "integrity.pose_publisher": (0, "integrity", "integrity_pose_publisher"),
    "integrity.no_teleport": (0, "integrity", "integrity_no_teleport"),
    "report": (10, "manual", None),
    "q1": (8, "manual", None), "q2": (8, "manual", None), "q3": (8, "manual", None),
    "q4": (8, "manual", None), "q5": (8, "manual", None),
}
# the lab text's points table
TABLE = {Section("report"): 10, **{Section("question", n): 8 for n in range(1, 6)},
         Section("exercise", 1): 20, Section("exercise", 2): 20, Section("exercise", 3): 10}


@pytest.fixture(scope="module")
def lab3():
    return load_rubric(LAB3, check_files=False)


def test_items_match_architecture_contract(lab3):
    got = {i.id: (i.points, i.kind, i.analyzer) for i in lab3.items}
    assert got == EXPECTED


def test_points_table_of_the_lab(lab3):
    sums: dict[Section, float] = {}
    for item in lab3.items:
        sums[item.section] = sums.get(item.section, 0) + item.points
    assert {s: p for s, p in sums.items() if p} == TABLE
    assert (lab3.total_max, lab3.auto_max, lab3.manual_max) == (100, 50, 50)
    assert lab3.lab == "enee467-lab3"


def test_scenarios_and_their_inputs(lab3):
    assert set(lab3.scenarios_used()) == {"ex1_publisher", "ex1_subscriber", "ex2_controller",
                                          "ex2_goal_publisher", "ex3_action"} == set(lab3.scenarios)
    assert not lab3.scenarios["ex1_publisher"].sim
    pub = lab3.scenarios["ex1_publisher"].processes[0]
    assert (pub.package, pub.executable) == ("random_numbers", "simple_publisher")

    replay = next(s.do for s in lab3.scenarios["ex1_subscriber"].steps if isinstance(s.do, Replay))
    assert (replay.count, replay.rate_hz, replay.topics, replay.lead) == (1000, 100, ("/random_numbers",), 4)
    assert replay.bag == (REPO / "fixtures" / "bags" / "random_numbers").resolve()

    ex2 = lab3.scenarios["ex2_controller"]
    goals = [s.do.xy for s in ex2.steps if isinstance(s.do, Goal)]
    assert goals[0] == (2.0, 7.0) and len(goals) == 4
    assert (ex2.goal_topic, ex2.goal_type) == ("/turtle1/goal", "std_msgs/msg/Float32MultiArray")
    short = [s for s in ex2.steps if isinstance(s.do, Publish)]
    # one goal of one number, which the lab's process_goal ignores, before the last goal
    assert [(s.id, s.do.topic, s.do.msg) for s in short] == [("short_goal", "/turtle1/goal", {"data": [2.0]})]
    assert [s.id for s in ex2.steps].index("short_goal") == len(ex2.steps) - 2
    for step in ex2.steps[1:]:
        if step in short:
            continue
        assert isinstance(step.until, GoalReached) and step.until.tolerance == 0.1
        # long enough for the lab's slowest suggested gains (K_1 = 0.1, K_2 = 0.5: up to ~40 s),
        # short enough that a controller that never settles does not hold a slot for minutes
        assert step.until.settle > 0 and 50 <= step.timeout <= 60 and step.target == step.goal

    gp = lab3.scenarios["ex2_goal_publisher"].processes[0]
    assert gp.module == "turtle_control.goal_publisher:main"
    assert [line.line for line in gp.stdin] == ["2.0,7.0", "oops", "8.0,3.0"]

    ex3 = lab3.scenarios["ex3_action"]
    server = ex3.process("server")
    # started as the lab starts it: its own declared defaults, none set by the grader
    assert not server.parameters
    actions = {s.id: s.action for s in ex3.steps if isinstance(s.do, ActionGoal)}
    assert {a.name for a in actions.values()} == {"/turtle_goal"}
    assert {a.type for a in actions.values()} == {"turtle_control_interfaces/action/SendGoal"}
    assert actions["out_of_bounds"].goal["goal"] == {"x": 15.0, "y": 15.0}
    assert actions["timeout"].goal["timeout"] == 0.5
    # the goal that must succeed carries a timeout far above the reference's ~8 s (the interface's
    # 10 s default failed on a loaded CI machine), and its step outlasts that timeout
    # ... and above the ~41 s the smallest gain the lab suggests (K_1 = 0.1) takes for any of them.
    # Three reachable goals: the last metres along y, then x, then y (a d_e or theta_e wrong
    # away from the first goal's geometry is seen)
    reach = ["reachable", "reachable_east", "reachable_north"]
    assert [actions[r].goal["goal"] for r in reach] == [{"x": 2.0, "y": 7.0}, {"x": 8.0, "y": 7.0},
                                                        {"x": 8.0, "y": 9.5}]
    for r in reach:
        step = next(s for s in ex3.steps if s.id == r)
        assert actions[r].goal["timeout"] >= 45.0 and step.timeout > actions[r].goal["timeout"]
    assert any(isinstance(s.do, Start) and s.start.root == ("client",) for s in ex3.steps)
    assert ex3.process("client").executable == "turtle_controller_client_node"


def test_geometry_of_ex2_goals():
    """turn_direction must have something to test: from the heading of arrival at each goal,
    the next one needs (b) a turn that only a *wrapped* theta_e takes the short way, for any
    plausible arrival heading at (2, 7), (c) about 180 degrees, (d) a RIGHT turn > 90 degrees."""
    import math
    _start = (5.544444561004639, 5.544444561004639)     # where the turtle starts (for the reader)
    scenario = load_rubric(LAB3, check_files=False).scenarios["ex2_controller"]
    a, b, c, d = [s.goal.xy for s in scenario.steps if s.goal is not None]
    assert a == (2.0, 7.0)  # the lab's own goal

    def bearing(p, q):
        return math.degrees(math.atan2(q[1] - p[1], q[0] - p[0]))

    def wrap(angle):
        return (angle + 180) % 360 - 180

    for arrival_heading in range(100, 181, 10):        # arriving at (2, 7) from the centre
        naive = bearing(a, b) - arrival_heading
        assert abs(naive) > 180 and abs(wrap(naive)) < 150, arrival_heading
    assert abs(wrap(bearing(b, c) - bearing(a, b))) > 165
    assert -150 < wrap(bearing(c, d) - bearing(b, c)) < -90
    assert all(0.5 < v < 10.5 for p in (a, b, c, d) for v in p)


def test_ex2_goals_leave_time_for_the_labs_slowest_suggested_gains():
    """The lab says to start with 0.1 <= K_1 <= 0.5 and 0.5 <= K_2 <= 1: a controller at the slow
    corner (K_1 = 0.1, K_2 = 0.5) is correct, and each goal step must leave it time to settle,
    with room for a loaded grading machine (a quarter of the step). Simulated on the unicycle of
    tests/analyze/analyze_synth.py (turtlesim's 16 ms tick), from the rubric's own placements."""
    import sys

    import numpy as np

    sys.path.insert(0, str(REPO / "tests" / "analyze"))
    from analyze_synth import START, law, simulate

    scenario = load_rubric(LAB3, check_files=False).scenarios["ex2_controller"]
    start = START
    for step in [s for s in scenario.steps if s.goal is not None]:
        if step.place is not None:
            start = (step.place.x, step.place.y, step.place.theta)
        gx, gy = step.goal.xy
        frames = simulate([(0.0, gx, gy)], law("correct", k1=0.1, k2=0.5), step.timeout, start=start)
        pose = frames["/turtle1/pose"]
        t = pose.index.to_numpy() - pose.index[0]
        far = np.hypot(pose["x"].to_numpy() - gx, pose["y"].to_numpy() - gy) >= step.until.tolerance
        assert not far[-1], f"{step.id}: not reached within {step.timeout:g} s"
        settled = t[np.nonzero(far)[0][-1] + 1] + step.until.settle
        assert settled <= 0.75 * step.timeout, f"{step.id}: settles after {settled:.1f} s of {step.timeout:g} s"
        start = (gx, gy, float(pose["theta"].iloc[-1]))


def test_params_fit_the_registered_analyzers():
    """The default load checks names and parameters against grader.analyze's registry."""
    from grader.rubric.load import registered_analyzers
    registry = registered_analyzers()
    rubric = load_rubric(LAB3, check_files=False)
    for item in rubric.items:
        if item.analyzer:
            assert set(item.params) <= set(registry[item.analyzer]), item.id


def test_fixtures_it_names_exist():
    """The default load checks files: the supplied interface package and the replayed bag."""
    rubric = load_rubric(LAB3)
    assert (rubric.support_paths()["turtle_control_interfaces"] / "package.xml").is_file()
    replay = next(s.replay for s in rubric.scenarios["ex1_subscriber"].steps if s.replay is not None)
    assert replay.bag.exists()


@pytest.mark.parametrize("name", ["future_goal_setter.yaml", "future_pen_colours.yaml",
                                  "future_circle.yaml"])
def test_format_describes_future_labs(name):
    rubric = load_rubric(DATA / name, check_files=False, analyzers=None)   # analyzers to be written
    assert rubric.items and rubric.scenarios_used() == list(rubric.scenarios)
