"""Driving to goals: did the turtle reach each goal and stop, and did it turn the short way.

Goals come from ``goal_sent`` events on /grader/events (the driver publishes them) or, when the
scenario has none, from the Float32MultiArray messages on /turtle1/goal. A goal is active from
its send time until the next goal (or the end of the recording).

* ``goals_reached``: the lab's controller has no stopping tolerance; the turtle approaches the goal
  asymptotically, so "reached" means the distance fell below ``tol_reached`` within the time
  limit. It should then hold there and stop (commanded speed ~0, position steady).
* ``turn_direction`` (:mod:`grader.analyze.turns`): did it turn the short way.

Both judge the simulator's own poses only (``sim_pose``), and a goal during which student code
moved the turtle without driving it (a teleport, a reset, a kill and spawn: the call's client id
says whose call it was, :mod:`grader.analyze.provenance`) earns nothing in either.
The gains and form of Lab 3's law are checked by ``control_law`` (its own module).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, graded, provenance, register
from grader.analyze._common import (Frames, events, fmt, missing_topic_feedback, sim_pose, since_start, times, topic)
from grader.contracts.world import WORLD_SIZE_M
from grader.analyze.goals import SentGoal, goals
from grader.analyze.evidence import SHARE, TIME
from grader.contracts.events import ScenarioEnd, StepEnd

#: labels and units of the evidence (see grader.analyze.evidence); shared by the three analyzers
EVIDENCE = {
    "steps": ('steps whose goals count (empty: all)', ''),
    "pose_topic": ('pose topic', ''),
    "goal_topic": ('goal topic', ''),
    "cmd_topic": ('command topic', ''),
    "skip_after_goal_s": ('time left out after each goal', 's'),
    "wrap_margin": ('margin from ±π for wrap-dependent samples', 'rad'),
    "min_wrap_rows": ('samples needed to judge the wrap', ''),
    "use_pub_time": ('use publisher send times', ''),
    "min_rows": ('samples needed for the fit', ''),
    "wrap_turn_deg": ('judge goals where wrapping changes the turn by', 'deg'),
    "ambiguous_deg": ('within this of 180° both ways are fine', 'deg'),
    "detect_deg": ('heading change that marks the first turn', 'deg'),
    "react_s": ('the turn is measured from this long after the goal', 's'),
    "goals": ("goals", ""),
    "goal": ("goal", ""),
    "x": ("goal x", "m"), "y": ("goal y", "m"),
    "t_sent": ("goal sent at", TIME),
    "window_s": ("time the goal was active", "s"),
    "start_distance": ("distance when the goal was sent", "m"),
    "min_distance": ("closest approach", "m"),
    "final_error": ("distance at the end", "m"),
    "reached": ("reached", ""),
    "time_to_reach": ("time to reach", "s"),
    "reached_at": None,
    "closest_t": ("closest at", TIME),
    "last_t": ("goal ended at", TIME),
    "settle_displacement": ("movement in the last second", "m"),
    "settle_max_speed": ("top speed in the last second", "m/s"),
    "stopped": ("stopped", ""), "held": ("stayed at the goal", ""),
    "tol_reached": ("goal tolerance", "m"),
    "tol_final": ("tolerance at the end", "m"),
    "time_limit_s": ("time limit per goal", "s"),
    "settle_s": ("time examined for stopping", "s"),
    "v_stop": ("speed counted as stopped", "m/s"),
    "steady_tol": ("movement counted as steady", "m"),
    "stop_weight": ("share of credit for stopping", SHARE),
    "goal_source": ("where goals are read (events, topic, auto, action)", ""),
    "trajectory": None,
    "wall_contacts": ("times the turtle hit a wall", ""),
    "teleported": ("calls of student code that moved the turtle while the goal was active", ""),
    "wall_points": None,
    # turn_direction
    "start": None,
    "required_turn_deg": ("turn needed (left +, right −)", "deg"),
    "naive_turn_deg": ("turn without wrapping the angle", "deg"),
    "wrap_matters": ("wrapping changes the turn", ""),
    "evaluated": ("judged", ""),
    "initial_turn": ("first turned", ""),
    "first_cmd_angular_z": ("angular.z of the controller's first command for the goal", "rad/s"),
    "commanded_turn": ("the controller's first command for the goal turned", ""),
    "command_sent_s": ("that command sent this long after the goal", "s"),
    "turn": ("turned (the verdict)", ""),
    "basis": ("judged from", ""),
    "judged_from_s": ("judged from this long after the goal was sent", "s"),
    "ambiguous": ("either way is fine (near 180°)", ""),
    "short_way": ("turned the short way", ""),
    "min_turn_deg": ("goals judged from a turn of", "deg"),
    "heading_error": None,
    **provenance.EVIDENCE,
    # control_law
    "rows": ("cmd_vel messages paired with a pose and a goal", ""),
    "K1": ("fitted K1 (linear.x = K1·d_e)", "1/s"),
    "R2_linear": ("R² of the linear fit", ""),
    "K2": ("fitted K2 (angular.z = K2·theta_e)", "1/s"),
    "R2_angular": ("R² of the angular fit", ""),
    "K2_unwrapped": ("K2 if theta_e is not wrapped", "1/s"),
    "R2_angular_unwrapped": ("R² if theta_e is not wrapped", ""),
    "rows_where_wrap_matters": ("messages where wrapping changes theta_e", ""),
    "rows_turning_fast": ("messages left out of the angular fit: theta_e changed too much in a tick", ""),
    "max_tick_turn": ("theta_e change per tick beyond which a message is left out", "rad"),
    "wrap": ("theta_e wrapped to [−π, π]", ""),
    "r2_min": ("R² needed", ""),
    "min_d": ("closest distance used in the angular fit", "m"),
    "sample": None,
    "fit_rows": None,
}

class GoalParams(AnalyzerParams):
    """The parameters every analyzer of driving to goals shares (``goals_reached``,
    ``turn_direction``, ``control_law``): which goals count and where poses and goals are read."""

    steps: tuple[str, ...] | None = Field(None, description="step ids whose goals count (None: every goal)")
    pose_topic: str = Field("/turtle1/pose", description="topic of the simulator's poses")
    goal_source: Literal["auto", "events", "topic", "action"] = Field(
        "auto", description='where goals are read: "auto" (events, else topic) | "events" | "topic" | "action"')
    goal_topic: str = Field("/turtle1/goal", description="topic of the goals (Float32MultiArray [x, y])")


def _pose(frames: Frames, p: GoalParams) -> pd.DataFrame | None:
    df = sim_pose(frames, p.pose_topic)
    if df is None or not {"x", "y", "theta"} <= set(df.columns):
        return None
    return df


def _goals_with_end(frames: Frames, p: GoalParams, pose: pd.DataFrame) -> list[SentGoal]:
    gl = goals(frames, p.goal_source, p.goal_topic)
    if p.steps:
        gl = [g for g in gl if g.extra.get("step") in set(p.steps)]
    t_last = float(pose.index.max())
    ends = {e.step: e.t for e in events(frames, StepEnd)}
    scen_end = [e.t for e in events(frames, ScenarioEnd)]
    for g in gl:
        cands = [t_last]
        if math.isfinite(g.t_end):
            cands.append(g.t_end)
        step = g.extra.get("step")
        if step is not None and step in ends and ends[step] > g.t:
            cands.append(ends[step])
        if scen_end:
            cands.append(scen_end[-1])
        g.t_end = min(cands)
    return gl


def _no_goals(frames: Frames, p: GoalParams) -> Finding:
    if topic(frames, "/grader/events") is None and topic(frames, p.goal_topic) is None:
        return Finding.error("The scenario recorded neither /grader/events nor "
                             f"{p.goal_topic}: no goals to evaluate (scenario problem).")
    return Finding.error(f"No goals were sent in this scenario (no goal_sent events, nothing on "
                         f"{p.goal_topic}).")


def _no_pose(frames: Frames, p: GoalParams) -> Finding:
    return Finding.error(missing_topic_feedback(frames, p.pose_topic, "published by the simulator")
                         + " Without poses the controller cannot be evaluated (scenario problem).")


def pose_and_goals(frames: Frames, p: GoalParams) -> tuple[pd.DataFrame, list[SentGoal]] | Finding:
    """The simulator's poses and the goals sent (each with its end), or the finding that says
    which is missing."""
    pose = _pose(frames, p)
    if pose is None:
        return _no_pose(frames, p)
    gl = _goals_with_end(frames, p, pose)
    if not gl:
        return _no_goals(frames, p)
    return pose, gl


class GoalsReachedParams(GoalParams):
    tol_reached: float = Field(0.1, gt=0, description="m: distance below which a goal counts as reached")
    tol_final: float = Field(0.15, ge=0, description="m: distance at the end of the goal's time window (held, not left)")
    time_limit_s: float | None = Field(None, gt=0, description="s after the goal was sent; None = until the next goal / the end")
    settle_s: float = Field(1.0, gt=0, description='s at the end of the window examined for "stopped"')
    v_stop: float = Field(0.1, ge=0, description="m/s: commanded speed (pose.linear_velocity) counted as stopped")
    steady_tol: float = Field(0.05, ge=0, description="m: max displacement during settle_s counted as steady")
    stop_weight: float = Field(0.25, ge=0, le=1,
                               description="share of each goal's credit for holding/stopping after reaching it")


@register("goals_reached", timing="reaching each goal within its time", evidence={**EVIDENCE, "value": ("goals reached", "")},
          expect="every goal within {tol_reached:g} m, then held within {tol_final:g} m and stopped",
          params=GoalsReachedParams)
def goals_reached(frames: Frames, p: GoalsReachedParams) -> Finding:
    """Per goal: reached within tolerance and time, time to reach, final error, stopped afterwards."""
    found = pose_and_goals(frames, p)
    if isinstance(found, Finding):
        return found
    pose, gl = found
    t = times(pose)
    x, y = pose["x"].to_numpy(float), pose["y"].to_numpy(float)
    v = pose["linear_velocity"].to_numpy(float) if "linear_velocity" in pose.columns else None
    moved = provenance.moves(frames, p.pose_topic)
    counted: list[provenance.Call] = []     # the moves that cost a goal
    rows = []
    score = 0.0
    for k, g in enumerate(gl, 1):
        m = (t >= g.t) & (t <= g.t_end)
        row: dict[str, Any] = {"goal": k, "x": g.x, "y": g.y, "t_sent": g.t, "window_s": g.t_end - g.t}
        during = provenance.within(moved, g.t, g.t_end)
        if during:
            # student code put the turtle somewhere while this goal was active: no arrival counts
            counted += during
            row.update(reached=False, teleported=len(during),
                       note=f"the turtle was moved without driving ({provenance.moved_text(frames, during)}) while "
                            "this goal was active: a goal reached that way earns nothing")
            rows.append(row)
            continue
        if m.sum() < 2:
            row.update(reached=False, note="no poses recorded while this goal was active")
            rows.append(row)
            continue
        reached, held, stopped = _arrival(p, g, t[m], x[m], y[m], v[m] if v is not None else None, row)
        score += (1 - p.stop_weight) * reached + p.stop_weight * (reached and held and stopped)
        rows.append(row)
    frac = score / len(gl)
    n_reached = sum(1 for r in rows if r.get("reached"))
    ev = {"goals": rows, "tol_reached": p.tol_reached, "goal_source": gl[0].source,
          "trajectory": _trajectory(t, x, y, gl, pose["theta"].to_numpy(float))}
    if counted:     # the rubric's advice for a wrong controller is not for these (rubric.score)
        ev["student_moves"] = [c.plain(frames) for c in counted[:10]]
    ev.update(_wall_contacts(frames, t, x, y))
    value = f"{n_reached}/{len(gl)} reached"
    problems = _goal_problems(frames, p, rows, counted)
    ev.update(_decisive_moment(frames, rows))
    if not problems:
        times_txt = ", ".join(f"{r['time_to_reach']:.1f} s" for r in rows)
        return Finding(value, 1.0, "pass", f"All {len(gl)} goals reached and held (time to reach: {times_txt}).", ev)
    hint = ""
    if n_reached == 0 and not any(r.get("teleported") for r in rows):
        hint = (" Check the signs of the distance and heading errors and of the gains, and that the "
                "velocity commands reach the turtle's cmd_vel topic.")
    hint += provenance.ignored_poses_note(frames, p.pose_topic)
    return Finding(value, frac, graded(frac), "; ".join(problems) + "." + hint, ev)


def _decisive_moment(frames: Frames, rows: list[dict]) -> dict[str, Any]:
    """``at_s``/``at`` of the first goal that cost points: its closest approach, or the end of
    its window for one reached but not held; nothing when every goal was reached and held."""
    for r in rows:
        label = f"goal {r['goal']} ({r['x']:g}, {r['y']:g})"
        if not r.get("reached") and "closest_t" in r:
            return {"at_s": float(since_start(frames, r["closest_t"])),
                    "at": f"{label}: closest approach, {r['min_distance']:.2f} m"}
        if r.get("reached") and not (r.get("held") and r.get("stopped")):
            return {"at_s": float(since_start(frames, r["last_t"])), "at": f"{label}: the end of its time, not stopped"}
        if not r.get("reached"):
            return {"at_s": float(since_start(frames, r["t_sent"])), "at": f"{label}: {r.get('note', 'not reached')}"}
    return {}


def _arrival(p: GoalsReachedParams, g: Any, tt: np.ndarray, xs: np.ndarray, ys: np.ndarray, vs: np.ndarray | None,
             row: dict) -> tuple[bool, bool, bool]:
    """One goal's poses while it was active: reached within ``tol_reached`` (and the time limit),
    held within ``tol_final`` and stopped over the last ``settle_s``; the numbers go in ``row``."""
    d = np.hypot(xs - g.x, ys - g.y)
    limit = g.t + p.time_limit_s if p.time_limit_s else g.t_end
    hit = np.nonzero((d < p.tol_reached) & (tt <= limit))[0]
    reached = len(hit) > 0
    row.update(start_distance=float(d[0]), min_distance=float(d.min()), final_error=float(d[-1]),
               reached=reached, time_to_reach=float(tt[hit[0]] - g.t) if reached else None,
               closest_t=float(tt[int(np.argmin(d))]), last_t=float(tt[-1]))
    if reached:
        row["reached_at"] = [round(float(xs[hit[0]]), 3), round(float(ys[hit[0]]), 3)]
    settle = tt >= tt[-1] - p.settle_s
    disp = float(np.max(np.hypot(xs[settle] - xs[-1], ys[settle] - ys[-1])))
    vmax = float(np.max(np.abs(vs[settle]))) if vs is not None else None
    stopped = disp <= p.steady_tol and (vmax is None or vmax <= p.v_stop)
    held = d[-1] <= p.tol_final
    row.update(settle_displacement=disp, settle_max_speed=vmax, stopped=bool(stopped), held=bool(held))
    return reached, bool(held), bool(stopped)


def _goal_problems(frames: Frames, p: GoalsReachedParams, rows: list[dict], counted: list) -> list[str]:
    """A sentence per goal not reached and held (one for all the goals a teleport cost)."""
    problems = []
    moved_goals = [r for r in rows if r.get("teleported")]
    if moved_goals:     # one sentence for all of them
        labels = ", ".join(f"{r['goal']} ({r['x']:g}, {r['y']:g})" for r in moved_goals)
        problems.append(f"goal{'s' if len(moved_goals) > 1 else ''} {labels}: the turtle was moved without "
                        f"driving ({provenance.moved_text(frames, counted)}) while "
                        f"{'they were' if len(moved_goals) > 1 else 'it was'} active: a goal reached that way "
                        "earns nothing")
    for r in rows:
        label = f"goal {r['goal']} ({r['x']:g}, {r['y']:g})"
        if not r.get("reached"):
            if r.get("teleported"):
                continue
            elif "min_distance" in r:
                problems.append(f"{label}: closest approach {r['min_distance']:.2f} m "
                                f"(needs < {p.tol_reached:g} m), final error {r['final_error']:.2f} m")
            else:
                problems.append(f"{label}: {r.get('note')}")
        elif not (r["held"] and r["stopped"]):
            problems.append(f"{label}: reached after {r['time_to_reach']:.1f} s but did not stay stopped "
                            f"(final error {r['final_error']:.2f} m, speed {fmt(r['settle_max_speed'])} m/s)")
    return problems


def _trajectory(t: np.ndarray, x: np.ndarray, y: np.ndarray, gl: list, theta: np.ndarray | None = None,
                max_points: int = 400) -> list[dict]:
    """The path driven towards each goal, thinned for the report's figure (``theta0``: heading
    when the goal was sent)."""
    paths = []
    for k, g in enumerate(gl, 1):
        m = (t >= g.t) & (t <= g.t_end)
        if m.sum() < 2:
            continue
        step = max(1, int(m.sum()) // max_points)
        path = {"x": np.round(x[m][::step], 3).tolist(), "y": np.round(y[m][::step], 3).tolist(),
                "goal": [g.x, g.y], "label": f"goal {k} ({g.x:g}, {g.y:g})"}
        if theta is not None:
            path["theta0"] = round(float(theta[m][0]), 4)
        paths.append(path)
    return paths


def _wall_contacts(frames: Frames, t: np.ndarray, x: np.ndarray, y: np.ndarray, eps: float = 1e-3) -> dict:
    """How often the turtle ran into a wall (turtlesim clamps the pose to [0, WORLD_SIZE_M]): the
    number of contact episodes and where the first ones were (s since the scenario start, x, y)."""
    at = (x <= eps) | (y <= eps) | (x >= WORLD_SIZE_M - eps) | (y >= WORLD_SIZE_M - eps)
    starts = np.nonzero(at & ~np.concatenate(([False], at[:-1])))[0]
    pts = [[float(s), round(float(x[i]), 3), round(float(y[i]), 3)]
           for s, i in zip(since_start(frames, t[starts[:20]]), starts[:20])]
    return {"wall_contacts": int(len(starts)), "wall_points": pts}
