"""The goals the driver sent to an action server, each with its response and result, rebuilt
from the driver's ``/grader/events`` (what every Exercise 3 item reads), and where they went when
the server offers the action under another name (``ActionGoal.by_type``).

Events are paired by their step (``_ID_KEYS``) when the driver provides it, else in order
(responses answer goals in the order they were sent, results answer accepted goals in order),
which does not depend on the driver waiting between goals.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from grader.analyze import Finding
from grader.analyze._common import Frames, events
from grader.analyze.goals import goal_xy
from grader.contracts.events import ActionGoalResponse, ActionGoalSent, ActionResult, ActionServerFound

_STATUS = {0: "UNKNOWN", 1: "ACCEPTED", 2: "EXECUTING", 3: "CANCELING", 4: "SUCCEEDED", 5: "CANCELED", 6: "ABORTED"}


def _field(goal: dict[str, Any], *keys: str) -> Any:
    """The first of ``keys`` in the goal message (e.g. ``goal_tol``), None when it has none."""
    return next((goal[k] for k in keys if k in goal), None)


def _status_name(s: Any) -> str | None:
    if s is None:
        return None
    if isinstance(s, (int, float)) and not isinstance(s, bool):
        return _STATUS.get(int(s), str(s))
    return str(s).upper().replace("STATUS_", "")


def action_goals(frames: Frames) -> list[dict]:
    """Goals sent to the action server with their response and result, in send order."""
    ev = events(frames, (ActionGoalSent, ActionGoalResponse, ActionResult))
    goals_: list[dict] = []
    wait_resp: list[dict] = []
    wait_res: list[dict] = []
    g: dict | None
    for e in ev:
        gid = e.step or None               # the driver tags each goal's events with its step
        if isinstance(e, ActionGoalSent):
            xy = goal_xy(e.goal)
            tol = _field(e.goal, "goal_tol")
            to = _field(e.goal, "time_out", "timeout")
            g = {"t_sent": e.t, "x": xy[0] if xy else None, "y": xy[1] if xy else None,
                 "goal_tol": float(tol) if tol is not None else None,
                 "time_out": float(to) if to is not None else None,
                 "label": "",
                 "id": gid, "accepted": None, "t_response": None, "status": None, "success": None,
                 "t_result": None}
            goals_.append(g)
            wait_resp.append(g)
        elif isinstance(e, ActionGoalResponse):
            # the oldest goal still waiting with the same id (ids may repeat), else the oldest one
            g = next((c for c in wait_resp if gid is not None and c["id"] == gid), None) or \
                next(iter(wait_resp), None)
            if g is None:
                continue
            if g in wait_resp:
                wait_resp.remove(g)
            g["accepted"] = e.accepted
            g["t_response"] = e.t
            if g["accepted"]:
                wait_res.append(g)
        else:
            g = next((c for c in wait_res if gid is not None and c["id"] == gid), None) or \
                next(iter(wait_res), None)
            if g is None:
                continue
            if g in wait_res:
                wait_res.remove(g)
            succ = e.result.get("success")
            g["success"] = None if succ is None else bool(succ)
            g["status"] = _status_name(e.status)
            g["t_result"] = e.t
    return goals_


def sent_elsewhere(frames: Frames, name: str | None = None) -> str | None:
    """The name the goals went to when the server offers the rubric's action (``name``: any)
    under another name of its type (``ActionGoal.by_type``), else None."""
    for e in events(frames, (ActionServerFound, ActionGoalSent)):
        asked = e.asked_for
        if asked and (name is None or "/" + asked.lstrip("/") == name):
            return e.action
    return None


def under_other_action_name(frames: Frames, finding: Finding) -> Finding:
    """``finding`` with what it saw said to be under the student's name for the action."""
    other = sent_elsewhere(frames)
    if other is None or finding.status == "error":
        return finding
    asked = next(e.asked_for for e in events(frames, ActionGoalSent) if e.asked_for)
    note = (f" (Sent to {other}, the name your server offers the action under; the lab's name is {asked}: "
            "that is charged once, by the item about the action's name.)")
    return dataclasses.replace(finding, feedback=finding.feedback + note,
                               evidence={**finding.evidence, "served_as": other})
