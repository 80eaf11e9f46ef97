"""Goals and the geometry of driving to them: where goals come from in a recording (the driver's
``goal_sent`` events, else messages on a goal topic), the heading error, and least-squares gains.
Pure functions on the ``frames`` of a bag (see grader.analyze._common)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from grader.analyze._common import TELEPORT_SERVICES, Frames, events, times, topic
from grader.contracts.events import ActionGoalSent, GoalSent, ServiceCall


def goal_xy(obj: Any) -> tuple[float, float] | None:
    """Extract (x, y) from the shapes the driver may use: [x, y], {"x","y"}, {"goal": {...}}."""
    if obj is None:
        return None
    if isinstance(obj, (list, tuple)) and len(obj) >= 2:
        try:
            return float(obj[0]), float(obj[1])
        except (TypeError, ValueError):
            return None
    if isinstance(obj, Mapping):
        if "x" in obj and "y" in obj:
            try:
                return float(obj["x"]), float(obj["y"])
            except (TypeError, ValueError):
                return None
        for k in ("goal", "data", "position", "target"):
            if k in obj:
                r = goal_xy(obj[k])
                if r is not None:
                    return r
    return None


@dataclass
class SentGoal:
    """A goal as a recording shows it sent (``t``, where), until the next one (``t_end``); the
    rubric's goal (what a scenario sends) is ``grader.contracts.fields.Goal``."""

    t: float
    x: float
    y: float
    source: str
    t_end: float = float("nan")
    extra: dict = field(default_factory=dict)


def goals(frames: Frames, source: str = "auto", goal_topic: str = "/turtle1/goal") -> list[SentGoal]:
    """Goals in time order: ``goal_sent`` events (auto/events) or Float32MultiArray on goal_topic,
    or with ``source="action"`` the goals the driver sent to an action server.

    Consecutive identical goals are merged (re-sending the same goal does not restart it).
    ``t_end`` is the next goal's time, or the scenario's own teleport/reset that ends the attempt
    (a rubric may place the turtle before the next goal: a turtle placed on the goal it failed
    to reach has not reached it), or NaN for the last goal.
    """
    out: list[SentGoal] = []
    if source == "action":
        # goals sent to an action server (``action:`` steps): the same geometry, driven by the
        # server's execute loop instead of a topic-fed controller
        for sent in events(frames, ActionGoalSent):
            xy = goal_xy(sent.goal)
            if xy is not None:
                out.append(SentGoal(sent.t, xy[0], xy[1], "action", extra={"step": sent.step}))
    if source in ("auto", "events"):
        for e in events(frames, GoalSent):
            if e.topic not in (None, goal_topic):
                continue                      # a Float32MultiArray published elsewhere
            xy = goal_xy(e.goal)
            if xy is not None:
                out.append(SentGoal(e.t, xy[0], xy[1], "events", extra={"step": e.step}))
    if not out and source in ("auto", "topic"):
        df = topic(frames, goal_topic)
        if df is not None and "data[0]" in df.columns and "data[1]" in df.columns:
            for t, x, y in zip(times(df), df["data[0]"], df["data[1]"]):
                if np.isfinite(x) and np.isfinite(y):
                    out.append(SentGoal(float(t), float(x), float(y), "topic"))
    out.sort(key=lambda g: g.t)
    merged: list[SentGoal] = []
    for g in out:
        if merged and abs(merged[-1].x - g.x) < 1e-3 and abs(merged[-1].y - g.y) < 1e-3:
            continue
        merged.append(g)
    for a, b in zip(merged, merged[1:]):
        a.t_end = b.t
    placed = sorted(c.t for c in events(frames, ServiceCall) if c.service.rsplit("/", 1)[-1] in TELEPORT_SERVICES)
    for g in merged:
        after = [t for t in placed if t > g.t and not t >= g.t_end]     # t_end NaN: the last goal
        if after:
            g.t_end = after[0]
    return merged


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def heading_error(x: Any, y: Any, theta: Any, xd: Any, yd: Any) -> Any:
    """theta_e of the lab's eq. (3): signed angle from the heading to the goal, in (-pi, pi]."""
    dx, dy = np.asarray(xd) - np.asarray(x), np.asarray(yd) - np.asarray(y)
    c, s = np.cos(theta), np.sin(theta)
    return np.arctan2(dy * c - dx * s, dx * c + dy * s)


def r2(y: np.ndarray, yhat: np.ndarray) -> float:
    """Centred coefficient of determination (can be negative for a bad no-intercept fit)."""
    y = np.asarray(y, float)
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    ss_res = float(np.sum((y - yhat) ** 2))
    if ss_tot <= 1e-12:
        return 1.0 if ss_res <= 1e-12 else float("-inf")
    return 1.0 - ss_res / ss_tot


def fit_gain(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least squares y = K x without intercept; returns (K, R^2)."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    den = float(np.dot(x, x))
    if den <= 1e-12:
        return float("nan"), float("nan")
    k = float(np.dot(x, y) / den)
    return k, r2(y, k * x)


