"""Synthetic frames in the exact format of docs/ARCHITECTURE.md ("Bag → DataFrames").

The unicycle simulator follows docs/turtlesim.md ("The 16 ms tick", "Walls"): a 16 ms tick with dt = 0.016,
rotate first then translate with the new heading, 1 s command timeout, walls clamped (velocity not
zeroed), a pose published every tick with linear_velocity = |vx| and angular_velocity = w.
"""

from __future__ import annotations

import json
import math
from typing import Callable, Iterable

import numpy as np
import pandas as pd

T0 = 1_700_000_000.0     # epoch-like receive times, like real bags
DT = 0.016
W = 11.088889
START = (5.544445, 5.544445, 0.0)


def frame(t: Iterable[float], **cols) -> pd.DataFrame:
    t = np.asarray(list(t), float)
    df = pd.DataFrame({k: (list(v) if not np.isscalar(v) else [v] * len(t)) for k, v in cols.items()},
                      index=pd.Index(t, name="t"))
    return df


def string_frame(rows: Iterable[tuple[float, dict | str]]) -> pd.DataFrame:
    rows = list(rows)
    return frame([r[0] for r in rows],
                 data=[r[1] if isinstance(r[1], str) else json.dumps(r[1]) for r in rows])


def events_frame(rows: Iterable[tuple[float, str, dict]]) -> pd.DataFrame:
    return string_frame((t, {"event": ev, **payload}) for t, ev, payload in rows)


def stdout_frame(rows: Iterable[tuple[float, str, str, str]]) -> pd.DataFrame:
    """rows: (t, process, stream, line)."""
    return string_frame((t, {"process": p, "stream": s, "line": line}) for t, p, s, line in rows)


def rosout_frame(rows: Iterable[tuple[float, str, str]], lag: float = 0.002) -> pd.DataFrame:
    """rows: (stamp time, logger name, msg). Received `lag` s after the stamp."""
    rows = list(rows)
    st = np.array([r[0] for r in rows], float)
    return frame(st + lag, **{
        "stamp.sec": np.floor(st).astype(np.int64), "stamp.nanosec": np.round((st % 1) * 1e9).astype(np.int64),
        "level": [20] * len(rows), "name": [r[1] for r in rows], "msg": [r[2] for r in rows],
        "file": ["x.py"] * len(rows), "function": ["f"] * len(rows), "line": [1] * len(rows)})


TYPES = {
    "/turtle1/pose": "turtlesim/msg/Pose",
    "/turtle1/cmd_vel": "geometry_msgs/msg/Twist",
    "/turtle1/goal": "std_msgs/msg/Float32MultiArray",
    "/random_numbers": "std_msgs/msg/Float32MultiArray",
    "/rosout": "rcl_interfaces/msg/Log",
    "/grader/events": "std_msgs/msg/String",
    "/grader/stdout": "std_msgs/msg/String",
}


def with_meta(frames: dict, types: dict | None = None, publishers: dict | None = None) -> dict:
    """Add the "__meta__" frame: one row per topic (topic, type, count, publishers)."""
    types = {**TYPES, **(types or {})}
    publishers = publishers or {}
    rows = []
    for k, df in frames.items():
        if k == "__meta__":
            continue
        rows.append({"topic": k, "type": types.get(k, "unknown/msg/Unknown"), "count": len(df),
                     "publishers": list(publishers.get(k, []))})
    out = dict(frames)
    out["__meta__"] = pd.DataFrame(rows, columns=["topic", "type", "count", "publishers"])
    return out


# --------------------------------------------------------------------------- unicycle + controller
def wrap(a: float) -> float:
    return a - 2 * math.pi * math.floor((a + math.pi) / (2 * math.pi))


def law(kind: str = "correct", k1: float = 0.5, k2: float = 1.0) -> Callable:
    """Controllers of the lab: correct (eq. 1-3), wrong_sign (w = -K2 theta_e), no_wrap,
    degrees (w = K2 * theta_e in degrees: the right sign, ~57 times too much)."""
    def f(x, y, th, gx, gy):
        dx, dy = gx - x, gy - y
        d = math.hypot(dx, dy)
        if kind == "no_wrap":
            te = math.atan2(dy, dx) - th
        else:
            te = math.atan2(dy * math.cos(th) - dx * math.sin(th), dx * math.cos(th) + dy * math.sin(th))
        w = k2 * (math.degrees(te) if kind == "degrees" else te)
        if kind == "wrong_sign":
            w = -w
        return k1 * d, w
    return f


def simulate(goal_list: list[tuple[float, float, float]], controller: Callable, duration: float,
             start=START, ctrl_period: float = 0.03, events: bool = True, ctrl_phase: float = 0.005,
             hold_s: float = 0.0) -> dict:
    """Run sim (62.5 Hz) + controller (timer) from T0; goals are (t_rel, x, y) sent by the driver.

    ``ctrl_phase``: when the controller's timer first fires after T0 (its phase against the
    simulator's ticks, which differs from run to run in a real graph). ``hold_s``: the turtle is
    held still from each goal until this long after it (as the driver does for a placed step),
    with the ``turtles_released`` event the analyzers read.
    Returns frames with /turtle1/pose, /turtle1/cmd_vel (with pub_t), /grader/events (goal_sent)
    or /turtle1/goal, and __meta__.
    """
    x, y, th = start
    vx = w = 0.0
    last_cmd_t = -1e9
    pose_rows, cmd_rows = [], []
    n_ticks = int(duration / DT)
    tick_times = [T0 + (k + 1) * DT for k in range(n_ticks)]
    ctrl_times = list(np.arange(T0 + ctrl_phase, T0 + duration, ctrl_period))
    goals_abs = [(T0 + g[0], g[1], g[2]) for g in goal_list]
    pending = []   # commands not yet consumed by a tick
    latest_pose = None
    it, ic = 0, 0
    while it < len(tick_times) or ic < len(ctrl_times):
        if ic < len(ctrl_times) and (it >= len(tick_times) or ctrl_times[ic] < tick_times[it]):
            tc = ctrl_times[ic]
            ic += 1
            active = [g for g in goals_abs if g[0] <= tc]
            if latest_pose is None or not active:
                continue
            gx, gy = active[-1][1], active[-1][2]
            v_cmd, w_cmd = controller(*latest_pose, gx, gy)
            cmd_rows.append((tc + 0.0008, tc, v_cmd, w_cmd))
            pending.append((tc + 0.0008, v_cmd, w_cmd))
        else:
            tk = tick_times[it]
            it += 1
            while pending and pending[0][0] <= tk:
                _, vx, w = pending.pop(0)
                last_cmd_t = tk
            if tk - last_cmd_t > 1.0:
                vx = w = 0.0
            if any(g[0] <= tk < g[0] + hold_s for g in goals_abs):
                xf, yf, tf = (float(np.float32(v)) for v in (x, y, th))
                pose_rows.append((tk + 0.0005, xf, yf, tf, 0.0, 0.0))
                latest_pose = (xf, yf, tf)
                continue
            th = wrap(th + w * DT)
            x += vx * math.cos(th) * DT
            y += vx * math.sin(th) * DT
            x, y = min(max(x, 0.0), W), min(max(y, 0.0), W)
            xf, yf, tf = (float(np.float32(v)) for v in (x, y, th))
            pose_rows.append((tk + 0.0005, xf, yf, tf, abs(vx), w))
            latest_pose = (xf, yf, tf)
    frames = {
        "/turtle1/pose": frame([r[0] for r in pose_rows], x=[r[1] for r in pose_rows], y=[r[2] for r in pose_rows],
                               theta=[r[3] for r in pose_rows], linear_velocity=[r[4] for r in pose_rows],
                               angular_velocity=[r[5] for r in pose_rows]),
        "/turtle1/cmd_vel": frame([r[0] for r in cmd_rows], **{
            "pub_t": [r[1] for r in cmd_rows], "linear.x": [r[2] for r in cmd_rows], "linear.y": 0.0,
            "linear.z": 0.0, "angular.x": 0.0, "angular.y": 0.0, "angular.z": [r[3] for r in cmd_rows]}),
    }
    if events:
        frames["/grader/events"] = events_frame(sorted(
            [(T0, "scenario_start", {})]
            + [(g[0], "goal_sent", {"goal": [g[1], g[2]], "step": f"goal{k}"}) for k, g in enumerate(goals_abs)]
            + ([(g[0] + hold_s, "turtles_released", {"step": f"goal{k}", "ok": True})
                for k, g in enumerate(goals_abs)] if hold_s else [])
            + [(T0 + duration, "scenario_end", {})], key=lambda r: r[0]))
    else:
        frames["/turtle1/goal"] = frame([g[0] + 0.001 for g in goals_abs], **{
            "data[0]": [g[1] for g in goals_abs], "data[1]": [g[2] for g in goals_abs], "data.len": 2})
    return with_meta(frames, publishers={"/turtle1/pose": ["/turtlesim"]})


def check(finding):
    """Every finding must be JSON-serialisable without NaN and well-formed; returns it."""
    d = finding.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["status"] in ("pass", "partial", "fail", "error")
    assert 0.0 <= d["fraction"] <= 1.0
    assert isinstance(d["feedback"], str) and d["feedback"]
    if d["status"] == "pass":
        assert d["fraction"] == 1.0
    return finding
