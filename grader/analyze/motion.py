"""How the turtle moved: circles (radius, period, centre), staying clear of the walls, keeping
moving. Judged on the simulator's own poses (``/turtle1/pose`` at 62.5 Hz).

* ``circle_radius`` / ``circle_period``: a constant Twist (v, w) drives turtlesim's unicycle on
  a circle of radius v / w, once round every 2 pi / w seconds. The radius and centre come from an
  algebraic least-squares circle fit (Kasa) to the positions, the period from the slope of the
  unwrapped heading (a line fit of theta over time), both over the poses after the turtle started
  moving (``skip_s`` more, to leave out the first command's latency). ``turn``/``drive`` (optional)
  also judge which way round: the sign of the heading's slope (left = counter-clockwise heading)
  and whether the turtle moves the way it faces (the step between two poses projected on the
  heading; the pose's ``linear_velocity`` is a speed, without a sign). (2, -1) and (-2, 1) make
  the same radius and period as (2, 1), round another centre.
* ``keeps_moving``: the commands arrive before turtlesim's 1 s command timeout stops the turtle,
  the turtle is moving (judged from its positions, not its commanded velocity) for (almost)
  the whole run, and no student process crashed while it ran.
* ``no_wall_contact``: turtlesim clamps the turtle at the walls and logs "Oh no! I hit the
  wall!"; neither may happen. The closest approach to a wall is reported; with ``approach_m``
  it must be at most that: a turtle that circles in the middle never meets a wall to avoid.

Each judges the whole run on the simulator's own poses; a run in which student code moved the
turtle without driving it (a teleport, a reset, a kill and spawn: :mod:`grader.analyze.provenance`)
earns nothing in any of them: its path was not driven.
"""

from __future__ import annotations

import math
from typing import Literal, cast

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, provenance, register
from grader.analyze.evidence import SHARE, SINCE_START, TIME
from grader.analyze._common import (own_exits, sim_pose, sim_tick_times, Frames, fmt, held_mask,
                                    missing_topic_feedback, rosout_lines, scenario_end_time, thin, times, topic)
from grader.contracts.world import WORLD_SIZE_M
from grader.analyze.rate import rate_stats

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    **provenance.EVIDENCE,

    "radius_m": ("fitted radius", "m"), "centre": ("circle centre (x, y)", "m"), "rms_m": ("RMS distance from the circle", "m"),
    "expected_m": ("expected radius", "m"), "rel_error": ("relative error", SHARE), "poses": ("poses used", ""),
    "path": None, "period_s": ("time for one circle", "s"), "angular_velocity_rad_s": ("turning rate", "rad/s"),
    "turns": ("circles recorded", ""), "expected_s": ("expected period", "s"), "direction": ("direction", ""),
    "timed_on": ("timed on", ""),
    "rel_tol": ("allowed relative error", SHARE), "skip_s": ("time left out after the start", "s"),
    "commands": ("velocity commands", ""), "rate_hz": ("command rate", "Hz"), "max_gap_s": ("longest gap between commands", "s"),
    "moving_share": ("share of the time moving", SHARE), "stalls": ("stops", ""), "start": ("stopped at", TIME),
    "duration_s": ("for", "s"), "limit_gap_s": ("simulator's command timeout", "s"),
    "min_moving_share": ("share of the time that must be moving", SHARE), "min_speed": ("speed counted as moving", "m/s"),
    "min_clearance_m": ("closest approach to a wall", "m"), "closest_at": ("closest point (x, y)", "m"),
    "closest_t": ("closest at", SINCE_START), "wall_warnings": ("'hit the wall' warnings", ""),
    "contacts": ("poses touching a wall", ""), "world_max": ("world size", "m"), "min_clearance": ("clearance required", "m"),
    "pose_topic": ("pose topic", ""), "cmd_topic": ("command topic", ""), "sim_logger": ("the simulator's logger", ""),
    "world_max_m": ("world size", "m"), "contact_points": None,
    "approach_m": ("must come this close to a wall", "m"), "crashed": ("crashed while it ran", ""),
    "turn": ("turning", ""), "drive": ("driving", ""), "forward_share": ("share of the path driven nose first", SHARE),
    "direction_credit": ("credit for the right radius the wrong way round", SHARE),
}

class PoseParams(AnalyzerParams):
    """The simulator's poses, and the speed above which the turtle counts as moving."""

    pose_topic: str = Field("/turtle1/pose", description="the simulator's pose topic")
    min_speed: float = Field(0.05, ge=0, description="m/s: a speed above this counts as moving")


class CircleRadiusParams(PoseParams):
    expected_m: float = Field(gt=0, description="m: v / w of the commanded Twist, e.g. 2.0")
    rel_tol: float = Field(0.05, ge=0, description="|radius / expected - 1| <= rel_tol passes")
    skip_s: float = Field(0.5, ge=0, description="s: after the turtle started moving left out")
    turn: Literal["left", "right"] | None = Field(
        None, description='"left" (angular.z > 0) or "right"; None: either')
    drive: Literal["forward", "backward"] | None = Field(
        None, description='"forward" (linear.x > 0) or "backward"; None: either')
    direction_credit: float = Field(0.5, ge=0, le=1,
                                    description="credit for the right radius driven the wrong way round")


# rel_tol and skip_s are declared in each circle model, after its expected value: the order
# of the rubric guide's table and of a finding's params stays the one they had
class CirclePeriodParams(PoseParams):
    expected_s: float = Field(gt=0, description="s: 2 pi / w of the commanded Twist, e.g. 6.2832")
    rel_tol: float = Field(0.05, ge=0, description="|period / expected - 1| <= rel_tol passes")
    skip_s: float = Field(0.5, ge=0, description="s: after the turtle started moving left out")


def _moving_pose(frames: Frames, p: CircleRadiusParams | CirclePeriodParams
                 ) -> tuple[pd.DataFrame | None, Finding | None]:
    """The poses from the moment the turtle first moved (plus ``skip_s``)."""
    moved = provenance.moves(frames, p.pose_topic)
    if moved:
        return None, provenance.moved_finding(frames, moved, "the circle")
    df = sim_pose(frames, p.pose_topic)
    if df is None or not {"x", "y", "theta", "linear_velocity"} <= set(df.columns):
        return None, Finding.error(missing_topic_feedback(frames, p.pose_topic, "published by the simulator"))
    moving = np.nonzero(np.abs(df["linear_velocity"].to_numpy(float)) > p.min_speed)[0]
    if len(moving) == 0:
        return None, Finding.fail("The turtle never moved: no velocity command reached it (publish "
                                  "geometry_msgs/msg/Twist on /turtle1/cmd_vel).", {"poses": len(df)})
    t = times(df)
    df = df[t >= t[moving[0]] + p.skip_s]
    if len(df) < 20:
        return None, Finding.fail("The turtle moved too briefly to measure its path.", {"poses": len(df)})
    return df, None


def fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """Kasa fit: centre (cx, cy), radius, and the RMS distance of the points from the circle."""
    a = np.column_stack([x, y, np.ones_like(x)])
    b = x * x + y * y
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    cx, cy = sol[0] / 2, sol[1] / 2
    r = math.sqrt(max(sol[2] + cx * cx + cy * cy, 0.0))
    rms = float(np.sqrt(np.mean((np.hypot(x - cx, y - cy) - r) ** 2)))
    return float(cx), float(cy), r, rms


def _within(value: float, expected: float, rel_tol: float) -> bool:
    return math.isfinite(value) and abs(value / expected - 1.0) <= rel_tol


@register("circle_radius", evidence={**EVIDENCE, "value": ('circle radius', '')},
          expect='{expected_m:g} m ± {rel_tol:.0%}', params=CircleRadiusParams)
def circle_radius(frames: Frames, p: CircleRadiusParams) -> Finding:
    df, problem = _moving_pose(frames, p)
    if problem or df is None:           # (no problem: there are poses)
        return cast(Finding, problem)
    x, y = df["x"].to_numpy(float), df["y"].to_numpy(float)
    cx, cy, r, rms = fit_circle(x, y)
    keep = thin(len(x))
    ev = {"radius_m": r, "centre": [cx, cy], "rms_m": rms, "expected_m": p.expected_m,
          "rel_error": r / p.expected_m - 1.0, "poses": len(df),
          "path": {"x": np.round(x[keep], 3).tolist(), "y": np.round(y[keep], 3).tolist()}}
    value = f"r = {r:.3f} m"
    if rms > 0.1 * max(r, 0.1):
        return Finding(value, 0.0, "fail", f"The path is not a circle (points deviate {rms:.2f} m on average "
                       f"from the best circle, r = {r:.2f} m): the velocity command must stay constant.", ev)
    wrong_way = _wrong_way(df, p, ev)
    if wrong_way:
        value += f", {ev['drive']} turning {ev['turn']}"
    if not _within(r, p.expected_m, p.rel_tol):
        return Finding(value, 0.0, "fail", f"The circle's radius is {r:.2f} m, expected {p.expected_m:g} m "
                       f"± {p.rel_tol:.0%} (radius = linear.x / angular.z)." + (f" {wrong_way}" if wrong_way else ""), ev)
    if wrong_way:
        return Finding(value, p.direction_credit, "partial", f"Circle of radius {r:.3f} m around "
                       f"({cx:.2f}, {cy:.2f}), but {wrong_way}", ev)
    return Finding(value, 1.0, "pass", f"Circle of radius {r:.3f} m around ({cx:.2f}, {cy:.2f}) "
                   f"(expected {p.expected_m:g} m ± {p.rel_tol:.0%}).", ev)


def _wrong_way(df: pd.DataFrame, p: CircleRadiusParams, ev: dict) -> str:
    """What is wrong with the way round (``turn``, ``drive``), in words; "" when nothing is (or
    nothing was asked). Fills ``ev`` with the turn, the drive and the forward share."""
    t = times(df)
    theta = np.unwrap(df["theta"].to_numpy(float))
    slope = float(np.polyfit(t - t[0], theta, 1)[0])
    heading = df["theta"].to_numpy(float)[:-1]
    ahead = np.diff(df["x"].to_numpy(float)) * np.cos(heading) + np.diff(df["y"].to_numpy(float)) * np.sin(heading)
    moved = np.abs(ahead) > 1e-6
    forward = float(np.mean(ahead[moved] > 0)) if moved.any() else 1.0
    ev.update(turn="left" if slope > 0 else "right", drive="forward" if forward >= 0.5 else "backward",
              forward_share=forward)
    wrong = []
    if p.drive and ev["drive"] != p.drive:
        wrong.append(f"the turtle drove {ev['drive']} (linear.x {'<' if ev['drive'] == 'backward' else '>'} 0)")
    if p.turn and ev["turn"] != p.turn:
        wrong.append(f"{'it' if wrong else 'the turtle'} turned {ev['turn']} (angular.z {'<' if ev['turn'] == 'right' else '>'} 0)")
    if not wrong:
        return ""
    asked, signs = [], []
    if p.drive:
        asked.append(f"driving {p.drive}")
        signs.append(f"linear.x {'>' if p.drive == 'forward' else '<'} 0")
    if p.turn:
        asked.append(f"turning {p.turn}")
        signs.append(f"angular.z {'>' if p.turn == 'left' else '<'} 0")
    return "; ".join(wrong) + f": the lab asks for {' while '.join(asked)} ({', '.join(signs)})."


@register("circle_period", timing="the circle's period", evidence={**EVIDENCE, "value": ('time for one circle', '')},
          expect='{expected_s:.3g} s ± {rel_tol:.0%}', params=CirclePeriodParams)
def circle_period(frames: Frames, p: CirclePeriodParams) -> Finding:
    """The time of one circle, from the heading's rate over the whole run, on the simulator's
    ticks (16 ms of its world each, so a simulator starved of CPU does not lengthen it); a
    turtle that stops between commands stands still for those ticks, and that lengthens it."""
    df, problem = _moving_pose(frames, p)
    if problem or df is None:           # (no problem: there are poses)
        return cast(Finding, problem)
    # on the simulator's ticks: bench_flake at load ~24 timed a correct circle at 6.53 s in one
    # run and 6.71 s (fail) in another on the wall clock, the simulator waiting 0.46 s per second
    # for a CPU; a student's pause still counts (the turtle stands still for those ticks)
    ticks = sim_tick_times(frames, p.pose_topic, df)
    t = times(df) if ticks is None else ticks
    theta = np.unwrap(df["theta"].to_numpy(float))
    slope, _ = np.polyfit(t - t[0], theta, 1)
    period = 2 * math.pi / abs(slope) if abs(slope) > 1e-6 else float("inf")
    turns = abs(theta[-1] - theta[0]) / (2 * math.pi)
    ev = {"period_s": period, "angular_velocity_rad_s": float(slope), "turns": turns,
          "expected_s": p.expected_s, "rel_error": period / p.expected_s - 1.0 if math.isfinite(period) else None,
          "direction": "counter-clockwise" if slope > 0 else "clockwise",
          "timed_on": "the recorded times" if ticks is None else "the simulator's ticks (16 ms each)"}
    value = f"T = {fmt(period, 3)} s"
    if turns < 1.0:
        return Finding(value, 0.0, "fail", f"The turtle went only {turns:.2f} times round; a period needs at "
                       "least one full circle.", ev)
    if _within(period, p.expected_s, p.rel_tol):
        return Finding(value, 1.0, "pass", f"One circle every {period:.3f} s (expected {p.expected_s:g} s "
                       f"± {p.rel_tol:.0%}), {turns:.1f} circles recorded.", ev)
    return Finding(value, 0.0, "fail", f"One circle takes {period:.2f} s, expected {p.expected_s:g} s ± "
                   f"{p.rel_tol:.0%} (period = 2π / angular.z; pauses between commands lengthen it).", ev)


class KeepsMovingParams(PoseParams):
    cmd_topic: str = Field("/turtle1/cmd_vel", description="the velocity command topic")
    max_gap_s: float = Field(1.0, gt=0, description="s: turtlesim stops the turtle 1 s after the last command")
    min_moving_share: float = Field(0.95, ge=0, le=1,
                                    description="share of the time after the first move with speed > min_speed")


@register("keeps_moving", timing="the gaps between velocity commands (turtlesim's 1 s command timeout)", evidence={**EVIDENCE, "value": ('time moving', '')},
          expect='commands less than {max_gap_s:g} s apart, moving {min_moving_share:.0%} of the time, no crash',
          params=KeepsMovingParams)
def keeps_moving(frames: Frames, p: KeepsMovingParams) -> Finding:
    """Commands arrive before the simulator's command timeout, the turtle never stalls, and no
    student process crashed while it ran."""
    moved = provenance.moves(frames, p.pose_topic)
    if moved:
        return provenance.moved_finding(frames, moved, "its motion")
    pose = sim_pose(frames, p.pose_topic)
    cmd = topic(frames, p.cmd_topic)
    if pose is None or "linear_velocity" not in pose.columns:
        return Finding.error(missing_topic_feedback(frames, p.pose_topic, "published by the simulator"))
    if cmd is None:
        return Finding.fail(missing_topic_feedback(frames, p.cmd_topic, "velocity commands"))
    ct = times(cmd)
    gaps = np.diff(ct)
    stats = rate_stats(ct, gap_factor=None)
    pt = times(pose)
    # speed from the positions (a turtle pushing against a wall has a velocity but goes nowhere)
    x, y = pose["x"].to_numpy(float), pose["y"].to_numpy(float)
    dt = np.maximum(np.diff(pt), 1e-3)
    speed = np.concatenate([[0.0], np.hypot(np.diff(x), np.diff(y)) / dt])
    # while the grader holds the turtle for a placement it cannot move: that time is not judged
    held = held_mask(frames, pt)
    # judged from the turtle's first move, not from the first command the recorder heard: the
    # simulator may match the student's publisher later than the recorder does (CI: a correct
    # 20 Hz controller "stood still for 0.8 s" right after its first recorded command)
    going = np.flatnonzero((speed > p.min_speed) & (pt >= ct[0]))
    after = (pt >= pt[going[0]]) & ~held if len(going) else (pt >= ct[0] + 0.1) & ~held
    share = float(np.mean(speed[after] > p.min_speed)) if after.any() else 0.0
    stalls = _stalls(pt[after], speed[after] > p.min_speed)
    ev = {"commands": len(ct), "rate_hz": stats["rate_hz"], "max_gap_s": float(gaps.max()) if len(gaps) else None,
          "moving_share": share, "stalls": stalls[:10], "limit_gap_s": p.max_gap_s,
          "held_s": float(np.sum(np.diff(pt)[held[1:]])) if len(pt) > 1 else 0.0}
    value = f"{share:.0%} of the time moving"
    problems = []
    # a driving process that crashed while the scenario ran stops the turtle for the rest of it;
    # how much of that stop the recording holds depends only on how soon the run ended after the
    # crash (wall_pen's hits_wall.flip_sign: moving 90 % in one run, 100 % in two, the same
    # crash). It drove the turtle if the commands ended with it (a bystander's crash does not count)
    crashes = [e for e in own_exits(frames)
               if e.returncode not in (0, None) and ct[-1] <= e.t + p.max_gap_s]
    if crashes:
        first = min(crashes, key=lambda e: e.t)
        ev["crashed"] = f"{first.process} (exit code {first.returncode})"
        problems.append(f"a student process ({first.process}) crashed (exit code "
                        f"{first.returncode}) while the scenario ran, so nothing drove the turtle "
                        "for the rest of it")
    slow = bool(len(gaps)) and gaps.max() >= p.max_gap_s
    if slow:
        problems.append(f"commands were {gaps.max():.2f} s apart at the longest, so the simulator's "
                        f"{p.max_gap_s:g} s command timeout stopped the turtle")
    if share < p.min_moving_share:
        longest = max(stalls, key=lambda s: s["duration_s"]) if stalls else None
        problems.append(f"the turtle moved only {share:.0%} of the time (needs {p.min_moving_share:.0%})"
                        + (f"; it stood still for {longest['duration_s']:.1f} s from t = "
                           f"{longest['start'] - pt[0]:.1f} s" if longest else ""))
    if not problems:
        return Finding(value, 1.0, "pass", f"Commands every {fmt(1 / stats['rate_hz'] if stats['rate_hz'] else float('nan'))} s "
                       f"on average (at most {gaps.max() if len(gaps) else 0:.2f} s apart): the turtle never stopped.", ev)
    advice = (": publish faster than once a second (a timer period below 1 s)" if slow else
              "" if crashes and len(problems) == 1 else
              ": it stopped going anywhere (check for turning on the spot or pushing against a wall)")
    return Finding(value, 0.0, "fail", "; ".join(problems)[0].upper() + "; ".join(problems)[1:] + advice + ".", ev)


def _stalls(t: np.ndarray, moving: np.ndarray) -> list[dict]:
    """Intervals where the turtle stood still, as {start, duration_s}."""
    out, start = [], None
    for ti, m in zip(t, moving):
        if not m and start is None:
            start = ti
        elif m and start is not None:
            out.append({"start": float(start), "duration_s": float(ti - start)})
            start = None
    if start is not None and len(t):
        out.append({"start": float(start), "duration_s": float(t[-1] - start)})
    return out


class NoWallContactParams(AnalyzerParams):
    pose_topic: str = Field("/turtle1/pose", description="the simulator's pose topic")
    sim_logger: str = Field("turtlesim", description='the simulator\'s logger (its "hit the wall" warning)')
    world_max: float = Field(WORLD_SIZE_M, gt=0, description="m: the world is [0, world_max] in x and y")
    min_clearance: float = Field(0.0, ge=0, description="m: closer than this to a wall also counts as contact")
    approach_m: float | None = Field(
        None, ge=0, description="m: the path must come at least this close to a wall (None: any)")


@register("no_wall_contact", evidence={**EVIDENCE, "value": ('closest approach to a wall', '')},
          expect='no wall contact', params=NoWallContactParams)
def no_wall_contact(frames: Frames, p: NoWallContactParams) -> Finding:
    moved = provenance.moves(frames, p.pose_topic)
    if moved:
        return provenance.moved_finding(frames, moved, "staying clear of the walls")
    pose = sim_pose(frames, p.pose_topic)
    if pose is None or not {"x", "y"} <= set(pose.columns):
        return Finding.error(missing_topic_feedback(frames, p.pose_topic, "published by the simulator"))
    # after the scenario's end the grader stops the student's node and the turtle coasts on its
    # last command for up to 1 s (turtlesim's command timeout): at 5 m/s the lab text's node then
    # ran into the bottom wall 0.7 s after the end, failing in 2 of 3 runs (bench_flake, issue 22)
    end = scenario_end_time(frames)
    if end == end and (times(pose) <= end).any():
        pose = pose[times(pose) <= end]
    x, y = pose["x"].to_numpy(float), pose["y"].to_numpy(float)
    clearance = np.minimum.reduce([x, y, p.world_max - x, p.world_max - y])
    i = int(np.argmin(clearance))
    logs = rosout_lines(frames)
    hits = logs[(logs["logger"] == p.sim_logger) & logs["text"].str.contains("hit the wall", case=False)
                & ~(logs["time"] > end)]
    t0 = float(times(pose)[0])
    touched = np.nonzero(clearance <= max(p.min_clearance, 1e-3))[0]
    keep = np.union1d(thin(len(x)), touched[:50])
    ev = {"min_clearance_m": float(clearance[i]), "closest_at": [float(x[i]), float(y[i])],
          "closest_t": float(times(pose)[i] - t0), "wall_warnings": int(len(hits)),
          "contacts": int(len(touched)), "world_max_m": p.world_max,
          "path": {"x": np.round(x[keep], 3).tolist(), "y": np.round(y[keep], 3).tolist()},
          "contact_points": [[float(x[k]), float(y[k])] for k in touched[:50]]}
    value = f"closest {clearance[i]:.2f} m"
    if len(hits) or len(touched):
        where = f"({x[touched[0]]:.2f}, {y[touched[0]]:.2f})" if len(touched) else f"({x[i]:.2f}, {y[i]:.2f})"
        return Finding(value, 0.0, "fail", f"The turtle hit the wall at {where} "
                       f"({len(hits)} 'hit the wall' warning(s) from the simulator): turn away earlier.", ev)
    if p.approach_m is not None and clearance[i] > p.approach_m:
        return Finding(value, 0.0, "fail", f"The turtle never came within {p.approach_m:g} m of a wall (closest "
                       f"{clearance[i]:.2f} m, at ({x[i]:.2f}, {y[i]:.2f})): it stayed in the middle, so there was "
                       "no wall to avoid. Drive out towards the walls and turn away before you reach them.", ev)
    return Finding(value, 1.0, "pass", f"No wall contact; the closest approach was {clearance[i]:.2f} m at "
                   f"({x[i]:.2f}, {y[i]:.2f}).", ev)
