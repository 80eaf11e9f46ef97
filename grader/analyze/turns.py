"""Turning the short way: ``turn_direction``, from the command the controller computed for each goal.

With the wrapped theta_e of eq. (3) the turtle always turns the short way; a missing wrap
(atan2(dy, dx) - theta) makes it turn the long way when the difference crosses +-pi, and a wrong
sign makes it turn away. It shares the goals, poses and evidence of :mod:`grader.analyze.controller`
and, like ``goals_reached``, judges the simulator's own poses only; a goal during which student
code moved the turtle without driving it earns nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import Finding, graded, provenance, register
from grader.analyze._common import Frames, events, since_start, thin, times, topic
from grader.analyze.controller import EVIDENCE, GoalParams, pose_and_goals
from grader.analyze.goals import SentGoal, heading_error
from grader.contracts.events import TurtlesReleased


class TurnDirectionParams(GoalParams):
    min_turn_deg: float = Field(90.0, ge=0, le=180, description="deg: goals whose required turn is at least this "
                                                                "are evaluated")
    wrap_turn_deg: float = Field(10.0, ge=0, le=180, description="deg: ... and goals where wrapping changes the "
                                                                 "turn, if at least this")
    ambiguous_deg: float = Field(10.0, ge=0, le=180, description="deg: within this of 180 deg both directions are "
                                                                 "accepted")
    detect_deg: float = Field(5.0, gt=0, description="deg: heading change that marks the turtle's first turn "
                                                     "(evidence, and the verdict for a controller that turns "
                                                     "without cmd_vel)")
    react_s: float = Field(0.1, ge=0, description="s: a goal handed over without a hold: commands and turns count "
                                                  "from this long after it (the controller may still be steering "
                                                  "for the previous goal until its new one arrives)")
    cmd_topic: str = Field("/turtle1/cmd_vel", description="topic of the controller's velocity commands")


@register("turn_direction", evidence={**EVIDENCE, "value": ("goals turned the short way", "")},
          expect="the short way (at most 180°) for every goal that needs a turn of {min_turn_deg:g}° or more",
          params=TurnDirectionParams)
def turn_direction(frames: Frames, p: TurnDirectionParams) -> Finding:
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
    found = pose_and_goals(frames, p)
    if isinstance(found, Finding):
        return found
    pose, gl = found
    t = times(pose)
    x, y, th = (pose[c].to_numpy(float) for c in ("x", "y", "theta"))
    cmd = topic(frames, p.cmd_topic)
    released = {e.step: e.t for e in events(frames, TurtlesReleased) if e.ok}
    moved = provenance.moves(frames, p.pose_topic)
    counted: list[provenance.Call] = []
    rows: list[dict[str, Any]] = []
    judged, good = 0, 0
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
        row = {"goal": k, "x": g.x, "y": g.y, "t_sent": g.t, "start": [float(x[i0]), float(y[i0]), float(th[i0])],
               "required_turn_deg": math.degrees(req), "naive_turn_deg": math.degrees(naive),
               "wrap_matters": bool(wrap_matters)}
        series.append(_heading_series(frames, k, t[m], x[m], y[m], th[m], g))
        if not (abs(req) >= math.radians(p.min_turn_deg) or
                (wrap_matters and abs(req) >= math.radians(p.wrap_turn_deg))):
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
        judged += 1
        good += _turned_short_way(p, g, req, t, th, cmd, released.get(str(g.extra.get("step"))), row)
        rows.append(row)
    ev: dict[str, Any] = {"goals": rows, "heading_error": series}
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
    # the moment that decided it: when the turn was judged (the goal sent, plus the reaction time)
    ev["at_s"] = float(since_start(frames, float(bad[0]["t_sent"]) + float(bad[0].get("judged_from_s", 0.0))))
    ev["at"] = f"goal {bad[0]['goal']} ({bad[0]['x']:g}, {bad[0]['y']:g}): the turn"
    return Finding(value, frac, graded(frac), _long_way_message(bad[0]), ev)


def _turned_short_way(p: TurnDirectionParams, g: Any, req: float, t: np.ndarray, th: np.ndarray, cmd: pd.DataFrame | None,
                      t_release: float | None, row: dict) -> bool:
    """Did the turn that decides goal ``g`` (needing ``req`` rad) go the short way? A held
    hand-over is judged from the last command before the release (computed from the placement),
    else from the first turning command ``react_s`` after the goal; the pose's first turn only
    for a controller that sends none. Notes the evidence in ``row``."""
    t_from = t_release if t_release is not None else g.t + p.react_s
    row["judged_from_s"] = float(t_from - g.t)
    pose_turn = _first_turn(t, th, t_from, g.t_end, p.detect_deg)
    row["initial_turn"] = _TURN_WORDS[pose_turn]
    w_judged, first_move = _judged_command(cmd, g, t_release, t_from, t, th, row)
    cmd_turn = int(np.sign(w_judged)) if w_judged is not None else first_move
    row["commanded_turn"] = _TURN_WORDS[cmd_turn]
    turn = cmd_turn if w_judged is not None or cmd_turn else pose_turn
    row["basis"] = "command" if w_judged is not None else ("first tick" if cmd_turn else "pose")
    ambiguous = abs(req) >= math.pi - math.radians(p.ambiguous_deg)
    ok = turn != 0 and (ambiguous or turn == int(np.sign(req)))
    row.update(ambiguous=bool(ambiguous), short_way=bool(ok), turn=_TURN_WORDS[turn])
    return bool(ok)


def _judged_command(cmd: pd.DataFrame | None, g: Any, t_release: float | None, t_from: float,
                    t: np.ndarray, th: np.ndarray, row: dict) -> tuple[float | None, int]:
    """The command that decides a goal's turn: the last turning command sent while the turtle
    was held for the hand-over, else the first from ``t_from`` on; or, held with no command of
    the hold in the bag, the sign of the heading's first tick after the release. Returns the
    command's ``angular.z`` (None without one) and that tick's sign (0 when not used); notes both
    in ``row``."""
    if cmd is None or "angular.z" not in cmd.columns:
        return None, 0
    w_judged = None
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
    return w_judged, first_move


def _long_way_message(r: dict) -> str:
    """What the student reads about the first goal not turned the short way (its ``row``)."""
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
    return msg


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
