"""Exercise 3: the turtle_goal action server (turtle_control_interfaces/action/SendGoal).

The driver's own action client emits ``action_goal_sent`` (goal, goal_tol, time_out),
``action_goal_response`` (accepted) and ``action_result`` (status, result.success) events; the
turtle's poses show whether a reported success is real; the goals with their answers are rebuilt
from the events by :mod:`grader.analyze.action_goals`.

Bounds: the world is [0, WORLD_SIZE_M]^2 (11.09 m). The lab's template rejects goals outside [0, 11], so goals
inside [0, ``inner_bound``] must be accepted and reached, goals outside [0, ``outer_bound``] must be
rejected, and the thin band in between is not judged.

The six Exercise 3 items are kept together: they share the bounds, the timeline and the way a
goal nobody answered is reported.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

import numpy as np
from pydantic import Field

from grader.analyze.evidence import SHARE, TIME
from grader.analyze import AnalyzerParams, Finding, graded, provenance, register
from grader.analyze._common import (Frames, sim_pose, events, meta, rosout_lines, since_start, stdout_lines, thin, times, topic)
from grader.contracts.world import WORLD_SIZE_M
from grader.analyze.goal_publisher import parse_xy_line
from grader.analyze.action_goals import action_goals, sent_elsewhere, under_other_action_name
from grader.contracts.events import (ActionGoalResponse, ActionGoalSent, ActionServerFound, ActionServerMissing,
                                    ProcessExit, StdinLine)

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    **provenance.EVIDENCE,
    "action_name": ('action name', ''),
    "client_logger": ("the client's logger", ''),
    "reject_pattern": ("pattern of the client's rejection message", ''),
    "short_timeout_s": ('goals with a time_out up to this are timeout probes', 's'),
    "pose_topic": ('pose topic', ''),
    "default_goal_tol": ('goal tolerance when the goal gives none', 'm'),
    "pos_slack": ('extra distance allowed at a success', 'm'),
    "late_credit": ('credit for giving up late', SHARE),
    "action": ("action name", ""),
    "events": None, "action_topics": None, "action_server_missing": ("goals sent without a server", ""),
    "goals": ("goals", ""),
    "goal": ("goal (x, y)", "m"),
    "goal_tol": ("goal tolerance", "m"),
    "accepted": ("accepted", ""),
    "success": ("result success", ""),
    "status": ("final status", ""),
    "duration_s": ("time from goal to result", "s"),
    "distance_at_result": ("turtle's distance from the goal at the result", "m"),
    "ok": ("as expected", ""),
    "problem": ("problem", ""),
    "outer_bound": ("world edge: goals beyond must be rejected", "m"),
    "inner_bound": ("goals inside this bound must succeed", "m"),
    "time_out": ("goal's time_out", "s"),
    "grace_s": ("time allowed after the time_out", "s"),
    "oob_line": ("out-of-bounds line typed", ""),
    "reject_lines": ("client's rejection messages", ""),
    "exit_events": ("client exits", ""),
    "returncode": ("exit code", ""),
    "responsive_after": ("client reacted to the next goal", ""),
    "output_after_next_line": ("client output after the next goal", ""),
    "timeline": None,
    "t_end": ("goal ended at", TIME),
}

INNER = 11.0          # goals inside [0, inner_bound]^2 must be accepted and reached
OUTER = WORLD_SIZE_M     # goals outside [0, outer_bound]^2 must be rejected
SHORT_TIMEOUT = 5.0   # a goal with 0 < time_out <= short_timeout_s is the "timeout" probe

# the parameters several of the Exercise 3 analyzers take (each model keeps its own order)
OuterBound = Annotated[float, Field(gt=0, description="m: goals outside [0, outer_bound]^2 must be rejected")]
ShortTimeout = Annotated[float, Field(ge=0, description="s: a goal with 0 < time_out <= short_timeout_s is "
                                                        "the timeout probe")]
PoseTopic = Annotated[str, Field(description="the turtle's pose topic")]
DefaultGoalTol = Annotated[float, Field(gt=0, description="m: goal tolerance when the event does not say which "
                                                          "goal_tol was sent")]


def _in_box(g: dict, hi: float) -> bool:
    return g["x"] is not None and 0.0 <= g["x"] <= hi and 0.0 <= g["y"] <= hi


def _is_timeout_probe(g: dict, p: ActionGoalsSucceedParams | ActionTimeoutParams) -> bool:
    if "timeout" in g["label"].lower():
        return True
    return g["time_out"] is not None and 0 < g["time_out"] <= p.short_timeout_s


class _Unanswered(Finding):
    def with_evidence(self, ev: dict) -> Finding:
        return Finding(self.value, 0.0, "error", self.feedback, ev)


def _unanswered(rows: list[dict]) -> _Unanswered | None:
    """A goal the server neither accepted nor rejected, as far as the grader could tell (no goal
    response, and the server's status topic never named it): not graded as the student's
    failure but reported as something to check (status error), never a silent 0."""
    for r in rows:
        if r.get("accepted") is None:
            gx, gy = r["goal"]
            return _Unanswered("no answer", 0.0, "error",
                               f"The grader got no answer to goal ({gx:g}, {gy:g}): no goal response, and the "
                               "server's status never mentioned the goal. This is not counted against the "
                               "submission; check the server's log (logs/) or regrade it.")
    return None


def _pose_at(frames: Frames, pose_topic: str, t: float) -> tuple[float, float] | None:
    df = sim_pose(frames, pose_topic)
    if df is None:
        return None
    i = int(np.searchsorted(times(df), t, side="right")) - 1
    if i < 0:
        return None
    return float(df["x"].iloc[i]), float(df["y"].iloc[i])


def _timeline(frames: Frames, pose_topic: str, max_points: int = 150) -> dict:
    """Every action goal over time (s since the scenario start): sent, answered, result, and the
    turtle's distance to it while it ran, plus feedback messages (the report's timeline figure)."""
    gs = action_goals(frames)
    df = sim_pose(frames, pose_topic)
    rows = []
    for k, g in enumerate(gs, 1):
        row = {"goal": k, "label": g["label"] or g["id"] or f"goal {k}", "x": g["x"], "y": g["y"],
               "accepted": g["accepted"], "success": g["success"], "status": g["status"],
               "time_out": g["time_out"]}
        for key in ("t_sent", "t_response", "t_result"):
            row[key] = float(since_start(frames, g[key])) if g[key] is not None else None
        if df is not None and g["x"] is not None and g["accepted"]:
            t = times(df)
            end = g["t_result"] if g["t_result"] is not None else float(t[-1])
            m = (t >= g["t_sent"]) & (t <= end)
            keep = thin(int(m.sum()), max_points)
            d = np.hypot(df["x"].to_numpy(float)[m] - g["x"], df["y"].to_numpy(float)[m] - g["y"])
            row["distance"] = {"t": since_start(frames, t[m][keep]).tolist(), "d": np.round(d[keep], 3).tolist()}
        rows.append(row)
    feedback = [since_start(frames, times(f)) for name, f in frames.items()
                if name.endswith("/_action/feedback") and not name.startswith("/turtle1/") and len(f)]
    fb = np.sort(np.concatenate(feedback)) if feedback else np.array([])
    return {"goals": rows, "feedback_t": fb[thin(len(fb), 200)].tolist()}


def _no_action_events(frames: Frames) -> Finding:
    if topic(frames, "/grader/events") is None:
        return Finding.error("/grader/events was not recorded: the action scenario did not run (scenario problem).")
    missing = events(frames, ActionServerMissing)
    if missing and not events(frames, ActionGoalSent):
        name = missing[0].action or "turtle_goal"
        return Finding.fail(f"No goal could be sent because the action server {name} was never found: "
                            "start the ActionServer in your node and keep spinning it.",
                            {"action_server_missing": len(missing)})
    return Finding.error("The scenario sent no action goals of this kind, so this item could not be tested.")


class ActionAdvertisedParams(AnalyzerParams):
    action_name: str = Field("/turtle_goal", description="the action server's name")


@register("action_advertised", judges=("ros names",), evidence={**EVIDENCE, "value": ("action server", "")},
          expect="an action server named {action_name}",
          params=ActionAdvertisedParams)
def action_advertised(frames: Frames, p: ActionAdvertisedParams) -> Finding:
    """The action server is advertised under the expected name (``ros2 action list`` shows it)."""
    name = "/" + p.action_name.lstrip("/")
    found_ev = events(frames, (ActionServerFound, ActionServerMissing))
    ev: dict = {"action": name, "events": [e.model_dump(exclude_unset=True) for e in found_ev[:5]]}
    for e in found_ev:
        if isinstance(e, ActionServerFound) and (not e.action or "/" + e.action.lstrip("/") == name):
            return Finding(name, 1.0, "pass", f"The action server {name} was found on the ROS graph.", ev)
    m = meta(frames)
    action_topics = []
    if m is not None:
        action_topics = [str(t) for t in m["topic"] if "/_action/" in str(t)]
        # a server publishes <name>/_action/status; an action *client* only subscribes to it,
        # so the topic alone (recorded with 0 messages) does not prove a server exists
        pubs = {str(t): list(p_) for t, p_ in zip(m["topic"], m["publishers"])} if "publishers" in m else {}
        status = name + "/_action/status"
        ours = [t for t in action_topics if t == status
                and (pubs.get(t) or m.loc[m["topic"] == t, "count"].sum() > 0)]
        ev["action_topics"] = action_topics
        if ours:
            return Finding(name, 1.0, "pass", f"The action server {name} is advertised ({ours[0]} seen).", ev)
    if found_ev and not any(isinstance(e, ActionServerFound) for e in found_ev):
        return Finding.fail(f"The grader waited for the action server {name} but it never appeared: create "
                            f"ActionServer(..., action_name=\"{name.lstrip('/')}\", ...) and spin the node "
                            "(MultiThreadedExecutor as in the template).", ev)
    elsewhere = sent_elsewhere(frames, name)
    if elsewhere is not None:         # the item about the action's name: the one charge for it
        ev["served_as"] = elsewhere
        return Finding(f"served as {elsewhere}", 0.0, "fail",
                       f"There is no action {name}: your server offers it as {elsewhere} (the grader sent its goals "
                       "there, so the other items judge what your server does). The lab's client and ros2 action "
                       f"send_goal use {name}: create ActionServer(..., \"{name.lstrip('/')}\", ...).", ev)
    answered = events(frames, ActionGoalResponse)
    if any((not e.action or "/" + e.action.lstrip("/") == name) and not e.asked_for for e in answered):
        return Finding(name, 1.0, "pass", f"The action server {name} answered goal requests.", ev)
    if topic(frames, "/grader/events") is None and m is None:
        return Finding.error("Neither events nor topic metadata were recorded (scenario problem).", ev)
    other = sorted({t.split("/_action/")[0] for t in action_topics} - {name})
    hint = f" Other actions seen: {', '.join(other)}." if other else ""
    return Finding.fail(f"No action server {name} was found: create ActionServer(..., action_name="
                        f"\"{name.lstrip('/')}\", ...) and keep the node spinning.{hint}", ev)


class ActionGoalsSucceedParams(AnalyzerParams):
    inner_bound: float = Field(INNER, gt=0, description="m: goals inside [0, inner_bound]^2 must be accepted "
                                                        "and reached")
    short_timeout_s: ShortTimeout = SHORT_TIMEOUT
    pose_topic: PoseTopic = "/turtle1/pose"
    default_goal_tol: DefaultGoalTol = 0.1
    pos_slack: float = Field(0.05, ge=0, description="m: added to goal_tol when checking the pose at result time")


@register("action_goals_succeed", timing="reaching each goal within its time_out", evidence={**EVIDENCE, "value": ("reachable goals", "")},
          expect="every goal inside [0, {inner_bound:g}] m accepted and ending with success=True",
          params=ActionGoalsSucceedParams)
def action_goals_succeed(frames: Frames, p: ActionGoalsSucceedParams) -> Finding:
    """Reachable goals are accepted and end with success=True with the turtle really within goal_tol."""
    return under_other_action_name(frames, _action_goals_succeed(frames, p))


def _action_goals_succeed(frames: Frames, p: ActionGoalsSucceedParams) -> Finding:
    gs = [g for g in action_goals(frames) if _in_box(g, p.inner_bound) and not _is_timeout_probe(g, p)]
    if not gs:
        return _no_action_events(frames)
    rows, ok_n = [], 0
    moved = provenance.moves(frames, p.pose_topic)
    for g in gs:
        tol = g["goal_tol"] if g["goal_tol"] else p.default_goal_tol
        row = {"goal": [g["x"], g["y"]], "goal_tol": tol, "accepted": g["accepted"], "success": g["success"],
               "status": g["status"], "t_end": g["t_result"] or g["t_response"] or g["t_sent"],
               "duration_s": (g["t_result"] - g["t_sent"]) if g["t_result"] is not None else None}
        problem = None
        if g["accepted"] is None:
            problem = "no response from the server"
        elif not g["accepted"]:
            problem = "rejected although it is inside the world"
        elif g["t_result"] is None:
            problem = "accepted but no result ever came back"
        elif provenance.within(moved, g["t_sent"], g["t_result"]):
            during = provenance.within(moved, g["t_sent"], g["t_result"])
            row["teleported"] = len(during)
            problem = (f"the turtle was moved without driving ({provenance.moved_text(frames, during)}) while "
                       "the goal ran: a goal reached that way earns nothing")
        else:
            pos = _pose_at(frames, p.pose_topic, g["t_result"])
            dist = math.hypot(pos[0] - g["x"], pos[1] - g["y"]) if pos else None
            row["distance_at_result"] = dist
            if not g["success"]:
                where = f", turtle {dist:.2f} m away" if dist is not None else ""
                limit = f", goal timeout {g['time_out']:g} s" if g["time_out"] is not None else ""
                problem = f"result success=False after {row['duration_s']:.1f} s (status {g['status']}{where}{limit})"
            elif dist is not None and dist > tol + p.pos_slack:
                problem = f"reported success but the turtle was {dist:.2f} m away (goal_tol {tol:g})"
            elif g["status"] not in (None, "SUCCEEDED"):
                # rclpy aborts a goal whose execute callback returns without succeed(): a
                # client (ros2 action send_goal) reads "ABORTED" whatever the result says
                problem = (f"the result says success=True but the goal ended {g['status']}: call "
                           "goal_handle.succeed() before returning the result")
        row["ok"] = problem is None
        row["problem"] = problem
        ok_n += problem is None
        rows.append(row)
    frac = ok_n / len(gs)
    ev: dict[str, Any] = {"goals": rows, "timeline": _timeline(frames, p.pose_topic)}
    if any(r.get("teleported") for r in rows):
        ev["student_moves"] = [c.plain(frames) for c in moved[:10]]
    value = f"{ok_n}/{len(gs)} succeeded"
    unanswered = _unanswered(rows)
    if unanswered:
        return unanswered.with_evidence(ev)
    if ok_n == len(gs):
        return Finding(value, 1.0, "pass", f"All {len(gs)} reachable goals were accepted and reached.", ev)
    bad = next(r for r in rows if not r["ok"])
    ev["at_s"] = float(since_start(frames, bad["t_end"]))
    ev["at"] = f"goal ({bad['goal'][0]:g}, {bad['goal'][1]:g}): {bad['problem']}"
    hint = ""
    if "away" in (bad["problem"] or ""):
        hint = " Compute d_e as the distance to the goal and break only when d_e <= goal_tol."
    elif bad["success"] is False:
        hint = " Fill in theta_e (eq. 3) and d_e (eq. 2) in execute_callback so the loop reaches the goal."
    return Finding(value, frac, graded(frac),
                   f"Goal ({bad['goal'][0]:g}, {bad['goal'][1]:g}): {bad['problem']}.{hint}", ev)


class ActionRejectsOutOfBoundsParams(AnalyzerParams):
    outer_bound: OuterBound = OUTER


@register("action_rejects_out_of_bounds", evidence={**EVIDENCE, "value": ("out-of-bounds goals", "")},
          expect="every goal outside [0, {outer_bound:.2f}] m rejected",
          params=ActionRejectsOutOfBoundsParams)
def action_rejects_out_of_bounds(frames: Frames, p: ActionRejectsOutOfBoundsParams) -> Finding:
    """Goals outside the world are rejected in goal_callback (GoalResponse.REJECT)."""
    return under_other_action_name(frames, _action_rejects_out_of_bounds(frames, p))


def _action_rejects_out_of_bounds(frames: Frames, p: ActionRejectsOutOfBoundsParams) -> Finding:
    gs = [g for g in action_goals(frames) if g["x"] is not None and not _in_box(g, p.outer_bound)]
    if not gs:
        return _no_action_events(frames)
    rows = [{"goal": [g["x"], g["y"]], "accepted": g["accepted"], "success": g["success"]} for g in gs]
    ok_n = sum(1 for g in gs if g["accepted"] is False)
    ev = {"goals": rows, "outer_bound": p.outer_bound, "timeline": _timeline(frames, "/turtle1/pose")}
    frac = ok_n / len(gs)
    value = f"{ok_n}/{len(gs)} rejected"
    if ok_n == len(gs):
        return Finding(value, 1.0, "pass", f"All {len(gs)} out-of-bounds goals were rejected.", ev)
    unanswered = _unanswered(rows)
    if unanswered:
        return unanswered.with_evidence(ev)
    bad = next(g for g in gs if g["accepted"] is not False)
    ev["at_s"] = float(since_start(frames, bad["t_response"] or bad["t_sent"]))
    ev["at"] = f"goal ({bad['x']:g}, {bad['y']:g}): the answer"
    what = "got no response" if bad["accepted"] is None else "was accepted"
    return Finding(value, frac, graded(frac),
                   f"Goal ({bad['x']:g}, {bad['y']:g}) is outside the world [0, {p.outer_bound:.2f}] but {what}: "
                   "in goal_callback return GoalResponse.REJECT when x or y is outside the world.", ev)


class ActionTimeoutParams(AnalyzerParams):
    outer_bound: OuterBound = OUTER
    short_timeout_s: ShortTimeout = SHORT_TIMEOUT
    pose_topic: PoseTopic = "/turtle1/pose"
    grace_s: float = Field(3.0, ge=0, description="s: after time_out within which success=False must arrive")
    late_credit: float = Field(0.5, ge=0, le=1, description="share: credit for success=False later than "
                                                            "time_out + grace_s")
    default_goal_tol: DefaultGoalTol = 0.1


@register("action_timeout", timing="the goal's time_out", evidence={**EVIDENCE, "value": ("short-timeout goal", "")},
          expect="success=False within {grace_s:g} s after the goal's time_out",
          params=ActionTimeoutParams)
def action_timeout(frames: Frames, p: ActionTimeoutParams) -> Finding:
    """A goal with a short time_out ends with success=False soon after its time_out (advisory).

    Note the template's loop condition ``T1 - now <= timeout`` is always true (T1 - now is
    negative); a server that never times out is the typical finding here.
    """
    return under_other_action_name(frames, _action_timeout(frames, p))


def _action_timeout(frames: Frames, p: ActionTimeoutParams) -> Finding:
    gs = [g for g in action_goals(frames) if _in_box(g, p.outer_bound) and _is_timeout_probe(g, p)]
    if not gs:
        return _no_action_events(frames)
    g = gs[0]
    to = g["time_out"] or p.short_timeout_s
    ev = {"goal": [g["x"], g["y"]], "time_out": g["time_out"], "accepted": g["accepted"], "success": g["success"],
          "status": g["status"], "duration_s": (g["t_result"] - g["t_sent"]) if g["t_result"] else None,
          "timeline": _timeline(frames, p.pose_topic),
          "at_s": float(since_start(frames, g["t_result"] or g["t_response"] or g["t_sent"])),
          "at": f"goal ({g['x']:g}, {g['y']:g}) with time_out {to:g} s: its end"}
    if g["accepted"] is not True:
        return Finding("not accepted", 0.0, "fail",
                       f"The short-timeout goal ({g['x']:g}, {g['y']:g}) was {'rejected' if g['accepted'] is False else 'not answered'}; "
                       "it is inside the world and must be accepted.", ev)
    if g["t_result"] is None:
        return Finding("no result", 0.0, "fail",
                       f"The goal with time_out={to:g} s never returned a result: end the loop when the elapsed time "
                       "(now - T1) exceeds the timeout and return success=False.", ev)
    dur = g["t_result"] - g["t_sent"]
    late = dur > to + p.grace_s
    if g["success"]:
        pos = _pose_at(frames, p.pose_topic, g["t_result"])
        tol = g["goal_tol"] or p.default_goal_tol
        if not late and pos and math.hypot(pos[0] - g["x"], pos[1] - g["y"]) <= tol + 0.05:
            return Finding("reached in time", 1.0, "pass",
                           f"The goal was genuinely reached within its time_out ({dur:.1f} s of {to:g} s).", ev)
        return Finding(f"success after {dur:.1f} s", 0.0, "fail",
                       f"The goal with time_out={to:g} s ran {dur:.1f} s and reported success: the timeout is not "
                       "enforced. In the template, 'T1 - self.get_clock().now() <= timeout' is always true; "
                       "compare self.get_clock().now() - T1 with the timeout.", ev)
    if late:
        return Finding(f"success=False after {dur:.1f} s", p.late_credit, graded(p.late_credit),
                       f"The goal returned success=False but only after {dur:.1f} s (time_out {to:g} s).", ev)
    return Finding(f"success=False after {dur:.1f} s", 1.0, "pass",
                   f"The goal timed out after {dur:.1f} s (time_out {to:g} s) with success=False.", ev)


class ActionClientRejectedParams(AnalyzerParams):
    outer_bound: OuterBound = OUTER
    process: str | None = Field(None, description="runner process name of the given client (None: the first "
                                                  "typed into whose name has 'client', else the first)")
    client_logger: str = Field("turtle_controller_client_node", description="the client's logger name")
    reject_pattern: str = Field("reject", description="text (lower case) of the client's rejection message")


@register("action_client_rejected", evidence={**EVIDENCE, "value": ("client after a rejected goal", "")},
          expect="the client reports the rejection and keeps working",
          params=ActionClientRejectedParams)
def action_client_rejected(frames: Frames, p: ActionClientRejectedParams) -> Finding:
    """The given client reports a rejected goal and keeps accepting input afterwards (advisory).

    Why advisory: the client is given code; this item shows whether the student's server answers
    a rejection in a way the client can handle (a server that never responds makes it hang).
    """
    stdin = events(frames, StdinLine)
    procs = [e.process for e in stdin]
    proc = p.process or next((q for q in procs if q and "client" in str(q).lower()), procs[0] if procs else None)
    lines = [e for e in stdin if e.process == proc]
    if not lines:
        return Finding.error("No lines were typed into the action client, so its behaviour on a rejected goal "
                             "could not be tested.")
    oob = [e for e in lines if (xy := parse_xy_line(e.line)) is not None and
           not (0 <= xy[0] <= p.outer_bound and 0 <= xy[1] <= p.outer_bound)]
    if not oob:
        return Finding.error("No out-of-bounds goal was typed into the client.", {"process": proc})
    b = oob[0]
    later = [e for e in lines if e.t > b.t]
    ro = rosout_lines(frames)
    so = stdout_lines(frames)
    texts: list[tuple[float, str]] = []
    if len(ro):
        r = ro[ro["logger"].str.lstrip("/") == p.client_logger.lstrip("/")]
        texts += list(zip(r["time"].tolist(), r["text"].tolist()))
    if len(so):
        s = so[so["process"] == str(proc)]
        texts += list(zip(s["time"].tolist(), s["text"].tolist()))
    texts.sort()
    t_end_window = later[0].t if later else np.inf
    rej = [tx for t, tx in texts if b.t - 0.05 <= t <= t_end_window + 0.5 and p.reject_pattern in tx.lower()]
    exits = [x for x in events(frames, ProcessExit) if x.process == proc and x.t > b.t]
    ev: dict = {"process": proc, "oob_line": b.line, "reject_lines": rej[:3],
                "exit_events": [{"t": x.t, "returncode": x.returncode} for x in exits]}
    responsive = None
    if later:
        t2 = later[0].t
        after = [tx for t, tx in texts if t > t2 and tx.strip() and "goal position" not in tx.lower()]
        responsive = bool(after)
        ev["output_after_next_line"] = after[:3]
    ev["responsive_after"] = responsive
    if not rej:
        return Finding("no rejection message", 0.0, "fail",
                       f"After the out-of-bounds goal '{b.line}' the client never reported 'Goal Rejected': "
                       "your server must answer with GoalResponse.REJECT from goal_callback.", ev)
    if responsive is False:
        return Finding("hangs", 0.5, "partial",
                       "The client reported the rejection but did not react to the next goal afterwards.", ev)
    return Finding("rejected, responsive", 1.0, "pass",
                   f"The client reported the rejection of '{b.line}'"
                   + (" and kept working." if responsive else "."), ev)
