"""rubrics/chase.yaml and its own analyzer file, judged on recordings simulated with the
simulator's physics (grader.sim.physics: the very tick of the reference turtlesim).

Each recording follows the rubric's own scenario (its placements, turtle1's jumps and the drive
of turtle1), as the driver runs it: the turtles held still from the placement until the node has
answered, released, then the node's commands every 50 ms (or every pose). So the thresholds are
tested against what correct code with the gains the lab text leaves open does, and each grading
decision against the look-alikes: the usual bugs and a cheat.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd
import pytest

from grader import analyze
from grader.rubric import load_rubric
from grader.scenario.model import GoalReached, Publish, ServiceCall
from grader.sim.physics import DT, H, W, Turtle
from grader.sim.record import record_topic

REPO = Path(__file__).resolve().parents[2]
CHASE = REPO / "rubrics" / "chase.yaml"
T0 = 1_700_000_000.0
DRIVER_GID = [1, 15, 127, 1, 1, 0, 234, 157, 1, 0, 0, 0, 0, 0, 25, 4]
STUDENT_GID = [1, 15, 99, 7, 7, 0, 11, 22, 1, 0, 0, 0, 0, 0, 3, 4]
HOLD_S = 0.3           # the hand-over: the node answers the placement while both turtles are held

Law = Callable[[tuple[float, float, float], tuple[float, float]], tuple[float, float]]


def p_law(kv: float, kw: float, *, wrap: bool = True, sign: float = 1.0, stop: float = 0.0,
          vmax: float | None = None, speed: float | None = None) -> Law:
    """linear.x = kv d (or a fixed speed), angular.z = kw e, e wrapped into [-pi, pi] or not."""
    def law(me: tuple[float, float, float], target: tuple[float, float]) -> tuple[float, float]:
        dx, dy = target[0] - me[0], target[1] - me[1]
        d = math.hypot(dx, dy)
        e = math.atan2(dy, dx) - me[2]
        if wrap:
            e = math.atan2(math.sin(e), math.cos(e))
        if d < stop:
            return 0.0, 0.0
        v = speed if speed is not None else kv * d
        return (min(v, vmax) if vmax else v), sign * kw * e
    return law


@dataclass
class Recording:
    """What the recorder would have written: the simulator's poses, the commands, the events."""

    t: float = T0
    poses: dict[str, list[tuple]] = field(default_factory=lambda: {"turtle1": [], "turtle2": []})
    cmds: list[tuple[float, float, float]] = field(default_factory=list)
    events: list[tuple[float, dict]] = field(default_factory=list)
    services: dict[str, list[dict]] = field(default_factory=dict)
    seq: int = 0

    def event(self, name: str, **fields) -> None:
        self.events.append((self.t, {"event": name, "wall": self.t, **fields}))

    def call(self, service: str, gid: list[int], request: dict, response: dict | None = None) -> None:
        self.seq += 1
        rows = self.services.setdefault(service, [])
        base = {"info.sequence_number": self.seq, **{f"info.client_gid[{i}]": b for i, b in enumerate(gid)}}
        rows.append({"t": self.t, "info.event_type": 1, "request.len": 1, "response.len": 0, **base,
                     **{f"request[0].{k}": v for k, v in request.items()}})
        rows.append({"t": self.t + 0.001, "info.event_type": 2, "request.len": 0, "response.len": 1, **base,
                     **{f"response[0].{k}": v for k, v in (response or {}).items()}})
        if gid == DRIVER_GID:
            self.event("service_call", service=service, client_gid=gid, request=request)

    def frames(self) -> dict[str, pd.DataFrame]:
        out: dict[str, pd.DataFrame] = {}
        for name, rows in self.poses.items():
            if rows:
                a = np.array(rows, float)
                out[record_topic(f"/{name}/pose")] = pd.DataFrame(
                    {"x": a[:, 1], "y": a[:, 2], "theta": a[:, 3], "linear_velocity": a[:, 4],
                     "angular_velocity": a[:, 5]}, index=pd.Index(a[:, 0], name="t"))
        if self.cmds:
            c = np.array(self.cmds, float)
            out["/turtle2/cmd_vel"] = pd.DataFrame({"pub_t": c[:, 0], "linear.x": c[:, 1], "angular.z": c[:, 2]},
                                                   index=pd.Index(c[:, 0] + 0.001, name="t"))
        out["/grader/events"] = pd.DataFrame({"data": [json.dumps(e) for _, e in self.events]},
                                             index=pd.Index([t for t, _ in self.events], name="t"))
        for service, rows in self.services.items():
            df = pd.DataFrame(rows).set_index("t")
            out[f"{service}/_service_event"] = df
        return out


def simulate(law: Law, *, period_ticks: int = 3, spawn_name: str = "turtle2", spawns: int = 1,
             drives_turtle1: bool = False, cheat_teleport: bool = False) -> dict[str, pd.DataFrame]:
    """The rubric's ``chase`` scenario against a node with control law ``law``."""
    rubric = load_rubric(CHASE, check_files=False)
    rec = Recording()
    ns = 0
    turtles = {"turtle1": Turtle("turtle1", W / 2, H / 2, 0.0, ns)}
    state = {"held": False, "tick": 0, "cmd1": None}

    def tick(n: int = 1, until: Callable[[], bool] | None = None) -> None:
        nonlocal ns
        for _ in range(n):
            ns += int(DT * 1e9)
            rec.t += DT
            state["tick"] += 1
            me, target = turtles.get("turtle2"), turtles["turtle1"]
            if me is not None and state["tick"] % period_ticks == 0:
                v, w = law((me.pose_x, me.pose_y, me.pose_theta), (target.pose_x, target.pose_y))
                (target if drives_turtle1 else me).command_velocity(v, 0.0, w, False)
                if not drives_turtle1:
                    rec.cmds.append((rec.t, v, w))
            if state["cmd1"] is not None and state["tick"] % 6 == 0:       # the driver's 10 Hz
                turtles["turtle1"].command_velocity(*state["cmd1"], False)
            for name in sorted(turtles):
                turtle = turtles[name]
                turtle.update(ns, None, state["held"])
                rec.poses.setdefault(name, []).append((rec.t, turtle.pose_x, turtle.pose_y, turtle.pose_theta,
                                        turtle.pose_linear, turtle.pose_angular))
            if until is not None and until():
                return

    rec.event("scenario_start", scenario="chase", sim_node="turtlesim")
    tick(20)
    for _ in range(spawns):
        rec.call("/spawn", STUDENT_GID, {"name": spawn_name, "x": 1.0, "y": 1.0, "theta": 0.0},
                 {"name": "" if spawn_name in turtles else spawn_name})
        if spawn_name not in turtles:
            turtles[spawn_name] = Turtle(spawn_name, 1.0, 1.0, 0.0, ns)
        tick(10)
    for step in rubric.scenarios["chase"].steps:
        rec.event("step_start", step=step.id)
        start_t = rec.t
        if step.place is not None:
            state["held"] = True
            rec.event("turtles_held", step=step.id, ok=True)
            p = step.place
            rec.call(f"/{p.turtle}/teleport_absolute", DRIVER_GID, {"x": p.x, "y": p.y, "theta": p.theta})
            if p.turtle in turtles:
                turtles[p.turtle].teleport_absolute(p.x, p.y, p.theta)
        if isinstance(step.do, ServiceCall):
            req = step.do.request
            rec.call(step.do.name, DRIVER_GID, dict(req))
            turtles["turtle1"].teleport_absolute(req["x"], req["y"], req["theta"])
        if step.target is not None:
            rec.event("goal_sent", step=step.id, goal=[step.target.x, step.target.y], topic=None)
        if step.place is not None:
            tick(round(HOLD_S / DT))
            state["held"] = False
            rec.t += DT / 2          # the release comes between two ticks: the next pose has moved
            rec.event("turtles_released", step=step.id, ok=True)
            rec.t -= DT / 2
            if cheat_teleport and step.id == "catch_a":
                t1 = turtles["turtle1"]
                rec.call("/turtle2/teleport_absolute", STUDENT_GID, {"x": t1.pose_x, "y": t1.pose_y, "theta": 0.0})
                turtles["turtle2"].teleport_absolute(t1.pose_x, t1.pose_y, 0.0)
        if isinstance(step.do, Publish):
            msg = step.do.msg
            state["cmd1"] = (msg["linear"]["x"], 0.0, msg["angular"]["z"])
            tick(round(step.do.count / step.do.rate_hz / DT))
            state["cmd1"] = None
        remaining = step.limit_s - (rec.t - start_t)
        if remaining > 0 and isinstance(step.until, GoalReached):
            goal, tol, settle = step.target, step.until.tolerance, step.until.settle
            since = [None]

            # the closure is called within this iteration only (tick), so late binding is intended
            def reached() -> bool:
                me = turtles.get("turtle2")
                if me is None or math.hypot(me.pose_x - goal.x, me.pose_y - goal.y) > tol:  # noqa: B023
                    since[0] = None  # noqa: B023
                    return False
                since[0] = since[0] or rec.t  # noqa: B023
                return rec.t - since[0] >= settle  # noqa: B023

            tick(round(remaining / DT), until=reached)
        elif step.until is not None:         # startup: turtle2's poses are there
            tick(50)
        rec.event("step_end", step=step.id)
    rec.event("scenario_end", scenario="chase")
    return rec.frames()


def grade(frames: dict[str, pd.DataFrame]) -> dict[str, analyze.Finding]:
    rubric = load_rubric(CHASE, check_files=False)
    return {i.id: analyze.run(i.analyzer, frames, i.params) for i in rubric.items
            if i.analyzer and i.analyzer.startswith("chase_")}


def statuses(frames: dict[str, pd.DataFrame]) -> dict[str, str]:
    return {k: f.status for k, f in grade(frames).items()}


ALL_PASS = {"spawn.turtle2": "pass", "chase.catches": "pass", "chase.short_way": "pass", "chase.follows": "pass"}


def test_the_rubric_uses_its_own_analyzer_file() -> None:
    rubric = load_rubric(CHASE, check_files=False)
    assert [p.name for p in rubric.analyzers] == ["chase_checks.py"]
    mine = {i.analyzer for i in rubric.items if i.analyzer.startswith("chase_")}
    assert mine == {"chase_spawned", "chase_catches", "chase_short_way", "chase_follows"}
    assert all(analyze.origin(name).endswith("chase_checks.py") for name in mine)
    assert rubric.auto_max == 20


@pytest.mark.parametrize("kv,kw,period_ticks,extra", [
    (1.0, 4.0, 3, {}),                      # the lab text's example gains, a 20 Hz timer
    (1.0, 4.0, 1, {}),                      # every pose
    (1.5, 6.0, 1, {"stop": 0.5}),           # alt_function_style
    (0.8, 3.0, 6, {"vmax": 3.0}),           # alt_multithreaded: 10 Hz, capped
    (0.6, 2.5, 3, {}),                      # alt_spin_once_loop
    (0.6, 2.0, 6, {}),                      # smaller still, at the lab's slowest rate
    (2.0, 8.0, 6, {}),                      # large gains at 10 Hz
    (1.0, 4.0, 3, {"speed": 2.0, "stop": 0.3}),   # a fixed speed faster than turtle1 is correct too
])
def test_correct_gains_earn_every_point(kv: float, kw: float, period_ticks: int, extra: dict) -> None:
    found = grade(simulate(p_law(kv, kw, **extra), period_ticks=period_ticks))
    assert {k: f.status for k, f in found.items()} == ALL_PASS, {k: f.feedback for k, f in found.items()}


def test_no_wrap_turns_the_long_way_and_loses_turtle1() -> None:
    found = grade(simulate(p_law(1.0, 4.0, wrap=False)))
    assert found["chase.catches"].status == "pass"
    assert found["chase.short_way"].status == "partial" and found["chase.short_way"].fraction == 0.5
    assert "catch_b" in found["chase.short_way"].feedback and "wrapped" in found["chase.short_way"].feedback
    # judged from the placement itself (the held pose), not from a pose a tick into the turn
    turns = {m["step"]: m["required_turn_deg"] for m in found["chase.short_way"].evidence["moves"]}
    assert turns == pytest.approx({"catch_b": 62.6, "catch_c": 137.5}, abs=0.2)
    starts = [m["turtle2_start"] for m in found["chase.catches"].evidence["moves"]]
    assert sum(starts, []) == pytest.approx([2.0, 2.0, 0.0, 8.0, 8.0, 3.0, 8.5, 2.5, 0.0], abs=1e-3)
    assert found["chase.follows"].status == "fail"


def test_wrong_sign_fails_the_chase() -> None:
    got = statuses(simulate(p_law(1.0, 4.0, sign=-1.0)))
    assert got == {**ALL_PASS, "chase.catches": "fail", "chase.short_way": "fail", "chase.follows": "fail"}


def test_a_slow_fixed_speed_catches_only_the_near_jump() -> None:
    found = grade(simulate(p_law(0.0, 4.0, speed=0.5, stop=0.3)))
    catches = found["chase.catches"]
    assert catches.status == "partial" and [r["ok"] for r in catches.evidence["moves"]] == [False, True, False]
    assert "more than 10 s" in catches.feedback
    assert found["chase.follows"].status == "fail" and found["chase.short_way"].status == "pass"


def test_driving_turtle1_is_no_chase() -> None:
    found = grade(simulate(p_law(1.0, 4.0), drives_turtle1=True))
    assert found["chase.catches"].status == "fail"
    assert "turtle1 moved" in found["chase.catches"].feedback and "/turtle2/cmd_vel" in found["chase.catches"].feedback
    assert found["chase.short_way"].status == "fail" and found["chase.follows"].status == "fail"
    assert "/turtle2/cmd_vel" in found["chase.short_way"].feedback and "/turtle2/cmd_vel" in found["chase.follows"].feedback


def test_no_turtle2_fails_every_chase_item_with_the_reason() -> None:
    found = grade(simulate(p_law(1.0, 4.0), spawns=0))
    assert {k: f.status for k, f in found.items()} == dict.fromkeys(ALL_PASS, "fail")
    assert "/spawn got no request from your node" in found["spawn.turtle2"].feedback
    assert all("no turtle2" in found[k].feedback for k in ("chase.catches", "chase.short_way", "chase.follows"))


def test_spawn_name_and_repeated_calls() -> None:
    wrong = grade(simulate(p_law(1.0, 4.0), spawn_name="chaser"))["spawn.turtle2"]
    assert wrong.status == "fail" and "chaser" in wrong.feedback and "turtle2" in wrong.feedback
    twice = grade(simulate(p_law(1.0, 4.0), spawns=3))
    assert twice["spawn.turtle2"].status == "partial" and "3 times" in twice["spawn.turtle2"].feedback
    assert twice["chase.catches"].status == "pass"      # the refused calls moved nothing


def test_a_student_teleport_onto_turtle1_earns_nothing_for_that_move() -> None:
    catches = grade(simulate(p_law(1.0, 4.0), cheat_teleport=True))["chase.catches"]
    assert catches.status == "partial" and [r["ok"] for r in catches.evidence["moves"]] == [False, True, True]
    assert "/turtle2/teleport_absolute called by student code" in catches.feedback


UNITS = {"", "m", "s", "Hz", "m/s", "rad", "rad/s", "deg", "1/s", "time", "share", "s since start"}


def _unlabelled(labels: dict, ev: dict, prefix: str = "") -> set[str]:
    """Evidence keys without a label (as tests/analyze/test_an_evidence_labels.py judges them)."""
    missing = set()
    for key, value in ev.items():
        if prefix + key not in labels and key not in labels:
            missing.add(prefix + key)
        elif labels.get(prefix + key, labels.get(key)) is None:
            continue
        elif isinstance(value, dict):
            missing |= _unlabelled(labels, value, prefix + key + ".")
        elif isinstance(value, list):
            for row in value:
                if isinstance(row, dict):
                    missing |= {f"{prefix}{key}[].{k}" for k in _unlabelled(labels, row)}
    return missing


def test_the_lab_analyzers_say_what_their_evidence_means() -> None:
    """The report shows only labelled evidence: every key the lab's analyzers produce on the
    recordings above has a label in words and a unit, as the built-in analyzers' must."""
    runs = [simulate(p_law(1.0, 4.0)), simulate(p_law(1.0, 4.0, wrap=False)), simulate(p_law(1.0, 4.0), spawns=0),
            simulate(p_law(1.0, 4.0), drives_turtle1=True, spawns=2), simulate(p_law(1.0, 4.0), cheat_teleport=True)]
    missing: dict[str, set[str]] = {}
    for frames in runs:
        for item_id, finding in grade(frames).items():
            gaps = _unlabelled(analyze.evidence_labels(finding_analyzer(item_id)), finding.evidence)
            if gaps:
                missing.setdefault(item_id, set()).update(gaps)
    assert not missing, missing
    for name in ("chase_spawned", "chase_catches", "chase_short_way", "chase_follows"):
        labels = analyze.evidence_labels(name)
        assert labels["value"] and analyze.expected_text(name), name
        for key, label in labels.items():
            assert label is None or (label[0] and label[1] in UNITS), (name, key, label)


def finding_analyzer(item_id: str) -> str:
    return next(i.analyzer for i in load_rubric(CHASE, check_files=False).items if i.id == item_id)


def test_the_lab_file_draws_the_distance_figure() -> None:
    """The lab's file registers a report figure too; it draws the real evidence and ignores junk."""
    from grader.report.figures import FigureContext, figures_for
    from grader.rubric.result import ItemResult
    from grader.rubric.schema import Section

    found = grade(simulate(p_law(0.0, 4.0, speed=0.5, stop=0.3)))

    def item(item_id: str, analyzer: str, evidence: object) -> FigureContext:
        res = ItemResult(id=item_id, title="", section=Section("part", 2), kind="auto", public=True, points=0,
                         max_points=7, status="fail", feedback="", evidence={"distance": evidence},
                         analyzer=analyzer)
        return FigureContext(item=res, evidence=res.evidence, params=found[item_id].params)

    for item_id, analyzer in (("chase.catches", "chase_catches"), ("chase.follows", "chase_follows")):
        drawn, errors = figures_for(item(item_id, analyzer, found[item_id].evidence["distance"]), "x")
        assert len(drawn) == 1 and not errors, errors
        assert "closest approach" in drawn[0].alt and "<svg" in drawn[0].svg
        for junk in (None, [], [{"t": [0, 1], "d": [1]}], [{"t": "a", "d": "b"}], ["x"], {"t": [1, 2]}):
            assert figures_for(item(item_id, analyzer, junk), "x") == ([], []), junk
