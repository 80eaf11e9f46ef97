"""Driving to goals: did the turtle reach each goal and stop, and did it turn the short way.

Goals come from ``goal_sent`` events on /grader/events (the driver publishes them) or, when the
scenario has none, from the Float32MultiArray messages on /turtle1/goal. A goal is active from
its send time until the next goal (or the end of the recording).

* ``goals_reached``: the lab's controller has no stopping tolerance; the turtle approaches the goal
  asymptotically, so "reached" means the distance fell below ``tol_reached`` within the time
  limit. It should then hold there and stop (commanded speed ~0, position steady).
* ``turn_direction``: with the wrapped theta_e of eq. (3) the turtle always turns the short way;
  a missing wrap (atan2(dy, dx) - theta) makes it turn the long way when the difference crosses
  +-pi, and a wrong sign makes it turn away.

Both judge the simulator's own poses only (``sim_pose``), and a goal during which student code
moved the turtle without driving it (a teleport, a reset, a kill and spawn: the call's client id
says whose call it was, :mod:`grader.analyze.provenance`) earns nothing in either.
The gains and form of Lab 3's law are checked by ``control_law`` (its own module).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from grader.analyze import Finding, graded, provenance, register
from grader.analyze._common import (Frames, events, fmt, missing_topic_feedback, sim_pose, since_start, thin, times, topic)
from grader.spec.world import WORLD_SIZE_M
from grader.analyze.goals import SentGoal, goals, heading_error
from grader.analyze.evidence import SHARE, TIME
from grader.scenario.events import Event

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

_GOAL_DEFAULTS = {
    "steps": None,                  # step ids whose goals count (None: every goal)
    "pose_topic": "/turtle1/pose",
    "goal_source": "auto",          # "auto" (events, else topic) | "events" | "topic" | "action"
    "goal_topic": "/turtle1/goal",
}


def _pose(frames: Frames, p: dict) -> pd.DataFrame | None:
    df = sim_pose(frames, p["pose_topic"])
    if df is None or not {"x", "y", "theta"} <= set(df.columns):
        return None
    return df


def _goals_with_end(frames: Frames, p: dict, pose: pd.DataFrame) -> list[SentGoal]:
    gl = goals(frames, p["goal_source"], p["goal_topic"])
    if p["steps"]:
        gl = [g for g in gl if g.extra.get("step") in set(p["steps"])]
    t_last = float(pose.index.max())
    ends = {e.get("step"): e["t"] for e in events(frames, Event.STEP_END) if e.get("step") is not None}
    scen_end = [e["t"] for e in events(frames, Event.SCENARIO_END)]
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


def _no_goals(frames: Frames, p: dict) -> Finding:
    if topic(frames, "/grader/events") is None and topic(frames, p["goal_topic"]) is None:
        return Finding.error("The scenario recorded neither /grader/events nor "
                             f"{p['goal_topic']}: no goals to evaluate (scenario problem).")
    return Finding.error(f"No goals were sent in this scenario (no goal_sent events, nothing on "
                         f"{p['goal_topic']}).")


def _no_pose(frames: Frames, p: dict) -> Finding:
    return Finding.error(missing_topic_feedback(frames, p["pose_topic"], "published by the simulator")
                         + " Without poses the controller cannot be evaluated (scenario problem).")


@register("goals_reached", evidence={**EVIDENCE, "value": ("goals reached", "")},
          expect="every goal within {tol_reached:g} m, then held within {tol_final:g} m and stopped",
          defaults={
    **_GOAL_DEFAULTS,
    "tol_reached": 0.1,      # m: distance below which a goal counts as reached
    "tol_final": 0.15,       # m: distance at the end of the goal's time window (held, not left)
    "time_limit_s": None,    # s after the goal was sent; None = until the next goal / the end
    "settle_s": 1.0,         # s at the end of the window examined for "stopped"
    "v_stop": 0.1,           # m/s: commanded speed (pose.linear_velocity) counted as stopped
    "steady_tol": 0.05,      # m: max displacement during settle_s counted as steady
    "stop_weight": 0.25,     # share of each goal's credit for holding/stopping after reaching it
})
def goals_reached(frames: Frames, p: dict) -> Finding:
    """Per goal: reached within tolerance and time, time to reach, final error, stopped afterwards."""
    pose = _pose(frames, p)
    if pose is None:
        return _no_pose(frames, p)
    gl = _goals_with_end(frames, p, pose)
    if not gl:
        return _no_goals(frames, p)
    t = times(pose)
    x, y = pose["x"].to_numpy(float), pose["y"].to_numpy(float)
    v = pose["linear_velocity"].to_numpy(float) if "linear_velocity" in pose.columns else None
    moved = provenance.moves(frames, p["pose_topic"])
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
        tt, d = t[m], np.hypot(x[m] - g.x, y[m] - g.y)
        limit = g.t + p["time_limit_s"] if p["time_limit_s"] else g.t_end
        hit = np.nonzero((d < p["tol_reached"]) & (tt <= limit))[0]
        reached = len(hit) > 0
        row.update(start_distance=float(d[0]), min_distance=float(d.min()), final_error=float(d[-1]),
                   reached=reached, time_to_reach=float(tt[hit[0]] - g.t) if reached else None)
        if reached:
            row["reached_at"] = [round(float(x[m][hit[0]]), 3), round(float(y[m][hit[0]]), 3)]
        settle = tt >= tt[-1] - p["settle_s"]
        disp = float(np.max(np.hypot(x[m][settle] - x[m][-1], y[m][settle] - y[m][-1])))
        vmax = float(np.max(np.abs(v[m][settle]))) if v is not None else None
        stopped = disp <= p["steady_tol"] and (vmax is None or vmax <= p["v_stop"])
        held = d[-1] <= p["tol_final"]
        row.update(settle_displacement=disp, settle_max_speed=vmax, stopped=bool(stopped), held=bool(held))
        score += (1 - p["stop_weight"]) * reached + p["stop_weight"] * (reached and held and stopped)
        rows.append(row)
    frac = score / len(gl)
    n_reached = sum(1 for r in rows if r.get("reached"))
    ev = {"goals": rows, "tol_reached": p["tol_reached"], "goal_source": gl[0].source,
          "trajectory": _trajectory(t, x, y, gl, pose["theta"].to_numpy(float))}
    if counted:     # the rubric's advice for a wrong controller is not for these (rubric.score)
        ev["student_moves"] = [c.plain(frames) for c in counted[:10]]
    ev.update(_wall_contacts(frames, t, x, y))
    value = f"{n_reached}/{len(gl)} reached"
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
                                f"(needs < {p['tol_reached']:g} m), final error {r['final_error']:.2f} m")
            else:
                problems.append(f"{label}: {r.get('note')}")
        elif not (r["held"] and r["stopped"]):
            problems.append(f"{label}: reached after {r['time_to_reach']:.1f} s but did not stay stopped "
                            f"(final error {r['final_error']:.2f} m, speed {fmt(r['settle_max_speed'])} m/s)")
    if not problems:
        times_txt = ", ".join(f"{r['time_to_reach']:.1f} s" for r in rows)
        return Finding(value, 1.0, "pass", f"All {len(gl)} goals reached and held (time to reach: {times_txt}).", ev)
    hint = ""
    if n_reached == 0 and not any(r.get("teleported") for r in rows):
        hint = (" Check the signs of the distance and heading errors and of the gains, and that the "
                "velocity commands reach the turtle's cmd_vel topic.")
    hint += provenance.ignored_poses_note(frames, p["pose_topic"])
    return Finding(value, frac, graded(frac), "; ".join(problems) + "." + hint, ev)


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


@register("turn_direction", evidence={**EVIDENCE, "value": ("goals turned the short way", "")},
          expect="the short way (at most 180°) for every goal that needs a turn of {min_turn_deg:g}° or more",
          defaults={
    **_GOAL_DEFAULTS,
    "min_turn_deg": 90.0,     # goals whose required turn is at least this are evaluated
    "wrap_turn_deg": 10.0,    # ... and goals where wrapping changes the turn, if at least this
    "ambiguous_deg": 10.0,    # within this of 180 deg both directions are accepted
    "detect_deg": 5.0,        # heading change that marks the turtle's first turn (evidence, and the
                              # verdict for a controller that turns without cmd_vel)
    "react_s": 0.1,           # a goal handed over without a hold: commands and turns count from
                              # this long after it (the controller may still be steering for the
                              # previous goal until its new one arrives)
    "cmd_topic": "/turtle1/cmd_vel",
})
def turn_direction(frames: Frames, p: dict) -> Finding:
    """For goals needing a large turn (or where the naive angle difference crosses +-pi), did the
    controller turn the short way? Judged from the sign of angular.z of the command the controller
    computed for the goal from the pose it was handed over at, against the turn needed from there.

    Why a command and not the path: when the step places the turtle, the simulator holds it still
    until the goal has been handed over (``turtles_released``), so the last command sent before
    the release was computed from the placement and the new goal, the same in every run. The
    path that follows is chaotic for exactly the controllers this item is about: one whose
    heading error is in degrees turns up to 3 rad per 16 ms tick, overshoots at once and turns
    back, so which way its heading seems to go, and the sign of its later commands, depend on
    its timer's phase. Without a hold, the first turning command from ``react_s`` after the goal
    decides. A held hand-over of which the bag has no command (a recorder that matched the
    controller late) is judged from the turtle's first tick after the release, which the last
    command sent while held drives. The heading the turtle took is kept as evidence, and decides
    only for a controller that sends no turning command (e.g. one that uses rotate_absolute).
    """
    pose = _pose(frames, p)
    if pose is None:
        return _no_pose(frames, p)
    gl = _goals_with_end(frames, p, pose)
    if not gl:
        return _no_goals(frames, p)
    t = times(pose)
    x, y, th = (pose[c].to_numpy(float) for c in ("x", "y", "theta"))
    cmd = topic(frames, p["cmd_topic"])
    released = {e.get("step"): e["t"] for e in events(frames, Event.TURTLES_RELEASED) if e.get("ok")}
    moved = provenance.moves(frames, p["pose_topic"])
    counted: list[provenance.Call] = []
    rows, judged, good = [], 0, 0
    series: list[dict] = []
    for k, g in enumerate(gl, 1):
        i0 = int(np.searchsorted(t, g.t, side="right")) - 1
        if i0 < 0:
            i0 = 0
        m = (t >= t[i0]) & (t <= g.t_end)
        if m.sum() < 3:
            continue
        req = float(heading_error(x[i0], y[i0], th[i0], g.x, g.y))
        naive = float(math.atan2(g.y - y[i0], g.x - x[i0]) - th[i0])
        wrap_matters = abs(naive - req) > 1.0
        row = {"goal": k, "x": g.x, "y": g.y, "start": [float(x[i0]), float(y[i0]), float(th[i0])],
               "required_turn_deg": math.degrees(req), "naive_turn_deg": math.degrees(naive),
               "wrap_matters": bool(wrap_matters)}
        series.append(_heading_series(frames, k, t[m], x[m], y[m], th[m], g))
        if not (abs(req) >= math.radians(p["min_turn_deg"]) or
                (wrap_matters and abs(req) >= math.radians(p["wrap_turn_deg"]))):
            row["evaluated"] = False
            rows.append(row)
            continue
        row["evaluated"] = True
        during = provenance.within(moved, g.t, g.t_end)
        if during:      # a turn made by a teleport is no turn: this goal earns nothing
            counted += during
            row.update(short_way=False, teleported=len(during), note=provenance.moved_text(frames, during))
            judged += 1
            rows.append(row)
            continue
        # a held hand-over: the last command before the release (computed from the placement);
        # else the first turning command from react_s after the goal
        t_release = released.get(g.extra.get("step"))
        t_from = t_release if t_release is not None else g.t + p["react_s"]
        row["judged_from_s"] = float(t_from - g.t)
        pose_turn = _first_turn(t, th, t_from, g.t_end, p["detect_deg"])
        row["initial_turn"] = _TURN_WORDS[pose_turn]
        w_judged, first_move = None, 0
        if cmd is not None and "angular.z" in cmd.columns:
            ct = cmd["pub_t"].to_numpy(float) if "pub_t" in cmd.columns else times(cmd)
            ct = np.where(np.isfinite(ct), ct, times(cmd))
            w = cmd["angular.z"].to_numpy(float)
            turning = np.abs(w) > 1e-3
            during_hold: Any = np.nonzero(turning & (ct > g.t) & (ct <= t_from))[0] if t_release is not None else []
            after = np.nonzero(turning & (ct > t_from) & (ct <= g.t_end))[0]
            unrecorded = t_release is not None and not ((ct > g.t) & (ct <= t_from)).any()
            # the first tick that moved the heading at all (a held pose is exactly constant)
            first_move = _first_turn(t, th, t_from, g.t_end, FIRST_TICK_DEG) if unrecorded else 0
            if len(during_hold):
                w_judged, row["command_sent_s"] = float(w[during_hold[-1]]), float(ct[during_hold[-1]] - g.t)
            elif first_move:
                # held, but the bag has no command from the hold (a recorder that matched the
                # controller late): the turtle's first tick after the release is driven by the
                # last command the simulator got while it was held, so its sign is that command's
                row["basis_note"] = "no command of the hand-over is in the bag: judged from the first tick after the release"
            elif len(after):
                w_judged, row["command_sent_s"] = float(w[after[0]]), float(ct[after[0]] - g.t)
            row["first_cmd_angular_z"] = w_judged
        cmd_turn = int(np.sign(w_judged)) if w_judged is not None else first_move
        row["commanded_turn"] = _TURN_WORDS[cmd_turn]
        turn = cmd_turn if w_judged is not None or cmd_turn else pose_turn
        row["basis"] = "command" if w_judged is not None else ("first tick" if cmd_turn else "pose")
        ambiguous = abs(req) >= math.pi - math.radians(p["ambiguous_deg"])
        ok = turn != 0 and (ambiguous or turn == int(np.sign(req)))
        row.update(ambiguous=bool(ambiguous), short_way=bool(ok), turn=_TURN_WORDS[turn])
        judged += 1
        good += ok
        rows.append(row)
    ev = {"goals": rows, "heading_error": series}
    if counted:
        ev["student_moves"] = [c.plain(frames) for c in counted[:10]]
    if judged == 0:
        return Finding.error("No goal in this scenario required a large turn from where the turtle was, "
                             "so the turn direction could not be judged.", ev)
    frac = good / judged
    value = f"{good}/{judged} short way"
    if good == judged:
        return Finding(value, 1.0, "pass", f"The turtle turned the short way for all {judged} large-turn goal(s).", ev)
    bad = [r for r in rows if r.get("evaluated") and not r.get("short_way")]
    r = bad[0]
    if r.get("teleported"):
        msg = (f"For goal ({r['x']:g}, {r['y']:g}) the turtle was moved without driving ({r['note']}): "
               "a turn made that way earns nothing.")
    elif r["turn"] == "none":
        msg = (f"For goal ({r['x']:g}, {r['y']:g}) the turtle did not turn at all (needed "
               f"{r['required_turn_deg']:+.0f}°): the angular command should be proportional to "
               "the heading error.")
    else:
        how = ("the controller's first command for it turned" if r["basis"] in ("command", "first tick")
               else "the turtle started turning")
        msg = (f"For goal ({r['x']:g}, {r['y']:g}) the turtle needed to turn {r['required_turn_deg']:+.0f}° "
               f"but {how} {r['turn']}, the long way.")
        if r["wrap_matters"]:
            msg += (" The heading error must be wrapped to (-π, π]: atan2(dy, dx) - theta is not "
                    "(atan2(sin e, cos e) wraps it).")
        else:
            msg += " Check the sign of the heading error and of the angular gain."
    return Finding(value, frac, graded(frac), msg, ev)


_TURN_WORDS = {1: "left (CCW)", -1: "right (CW)", 0: "none"}
#: a heading change this large (1e-4 rad) is a tick's motion, not float32 noise of a held pose
FIRST_TICK_DEG = math.degrees(1e-4)


def _first_turn(t: np.ndarray, th: np.ndarray, t_from: float, t_end: float, detect_deg: float) -> int:
    """Which way the heading first moved by ``detect_deg`` after ``t_from`` (+1 left, -1 right, 0)."""
    i1 = min(int(np.searchsorted(t, t_from, side="left")), len(t) - 1)
    m1 = (t >= t[i1]) & (t <= t_end)
    dth = np.unwrap(th[m1]) - th[i1]
    over = np.nonzero(np.abs(dth) >= math.radians(detect_deg))[0]
    return int(np.sign(dth[over[0]])) if len(over) else 0


def _heading_series(frames: Frames, k: int, t: np.ndarray, x: np.ndarray, y: np.ndarray, th: np.ndarray,
                    g: SentGoal, max_points: int = 120) -> dict:
    """theta_e over time while goal ``k`` was active (the report's heading-error figure)."""
    keep = thin(len(t), max_points)
    err = np.degrees(heading_error(x[keep], y[keep], th[keep], g.x, g.y))
    return {"goal": k, "label": f"goal {k} ({g.x:g}, {g.y:g})", "t": since_start(frames, t[keep]).tolist(),
            "theta_e_deg": np.round(err, 2).tolist()}
