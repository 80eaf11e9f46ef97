"""A scenario's replay data, taken from its bag once: what the report's player draws.

The turtles' poses as the simulator published them (its own record, :func:`sim_pose`), the pen
as the student and the grader set it, every grader event (steps, goals, placements, calls and
their answers, lines typed, processes starting and ending), the velocity commands and the log
lines, all as seconds since the scenario started, rounded to the millisecond. Written beside the
bag as ``replay.js`` (a script that adds one entry to ``window.graderReplays``), so a report
opened from ``file://`` without network loads it: browsers refuse ``fetch`` of a local file,
not a ``<script src>``.

Size: poses at half turtlesim's 62.5 Hz (linear interpolation between two samples 32 ms apart
stays within 1 mm of the pose for any speed the lab's controllers reach: the turtle turns at most
~0.3 rad between them), commands thinned to :data:`MAX_COMMANDS`, log lines capped at
:data:`MAX_LINES`: the Lab 3 reference's five scenarios take ~150 KB in all.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Callable

import numpy as np

from grader.analyze._common import (Frames, events, rosout_lines, scenario_end_time, scenario_start,
                                    service_calls, sim_pose, stdout_lines, thin, times, topic)
from grader.analyze.goals import goal_xy
from grader.report.result import atomic_write
from grader.contracts import events as ev
from grader.contracts.world import WORLD_SIZE_M
from grader.contracts.output_folder import SCENARIOS_DIR

REPLAY_FILE = "replay.js"
POSE_STRIDE = 2              # every second pose of turtlesim's 62.5 Hz (see the module's docstring)
MAX_POSES = 6000             # per turtle: 190 s at 31 Hz, more than any lab's scenario
MAX_COMMANDS = 1500          # per turtle: velocity commands kept for the timeline
MAX_LINES = 400              # log lines and grader events, each
MAX_TEXT = 160               # characters of one line
PEN_DEFAULT = (179, 184, 255, 3, 0)      # turtlesim's pen (r, g, b, width, off)
PLACING = ("teleport_absolute", "spawn")     # the services the grader places a turtle with
_POSE = re.compile(r"^/([A-Za-z][A-Za-z0-9_]*)/pose$")
#: grader events the timeline lists, with what each says
_SAID: dict[type[ev.EventRecord], Callable[[Any], str]] = {
    ev.StepStart: lambda e: f"step {e.step} starts",
    ev.StepEnd: lambda e: f"step {e.step} ends ({e.ended_by})",
    ev.GoalSent: lambda e: f"goal {_xy(e.goal)} sent" + (f" on {e.topic}" if e.topic else ""),
    ev.MessageSent: lambda e: f"grader published on {e.topic}",
    ev.ServiceCall: lambda e: f"grader calls {e.service} {_short(e.request)}",
    ev.ServiceResponse: lambda e: f"{e.service} answers {_short(e.response)}",
    ev.ServiceMissing: lambda e: f"no service {e.service}",
    ev.ActionServerMissing: lambda e: f"no action server {e.action}",
    ev.ActionGoalSent: lambda e: f"goal {_xy(goal_xy(e.goal))} sent to {e.action}",
    ev.ActionGoalResponse: lambda e: f"{e.action} {'accepts' if e.accepted else 'rejects'} the goal",
    ev.ActionResult: lambda e: f"{e.action} result {_short(e.result)} (status {e.status})",
    ev.ActionCancelSent: lambda e: "grader cancels the goal",
    ev.StdinLine: lambda e: f"typed into {e.process}: {e.line}",
    ev.NodeStarted: lambda e: f"{e.process} started",
    ev.ProcessExit: lambda e: f"{e.process} exited ({e.returncode})",
    ev.TurtlesHeld: lambda e: "grader holds the turtle",
    ev.TurtlesReleased: lambda e: "grader releases the turtle",
    ev.ReplayStart: lambda e: f"grader replays {e.count} messages",
    ev.LimitHit: lambda e: f"limit reached: {e.limit}",
}


def _xy(xy: Any) -> str:
    try:
        return f"({float(xy[0]):.2f}, {float(xy[1]):.2f})"
    except (TypeError, ValueError, IndexError, KeyError):
        return "?"


def _short(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"), default=str)[:80]


def _rel(frames: Frames, t: Any) -> np.ndarray:
    t0 = scenario_start(frames)
    return np.round(np.asarray(t, float) - (t0 if t0 is not None else 0.0), 3)


def _turtles(frames: Frames) -> dict[str, dict[str, list[float]]]:
    out = {}
    for name in sorted(frames):
        match = _POSE.match(str(name))
        df = sim_pose(frames, name) if match else None
        if match is None or df is None or not {"x", "y", "theta"} <= set(df.columns):
            continue
        keep = np.arange(0, len(df), POSE_STRIDE)
        if len(df) - 1 not in keep:
            keep = np.append(keep, len(df) - 1)
        keep = keep[thin(len(keep), MAX_POSES)]
        rows = df.iloc[keep]
        out[match[1]] = {"t": _rel(frames, times(df)[keep]).tolist(),
                         "x": np.round(rows["x"].to_numpy(float), 3).tolist(),
                         "y": np.round(rows["y"].to_numpy(float), 3).tolist(),
                         "th": np.round(rows["theta"].to_numpy(float), 3).tolist()}
    return out


def _pens(frames: Frames, turtles: list[str]) -> dict[str, list[list[float]]]:
    """Each turtle's pen changes, ``[t, r, g, b, width, off]``: its ``set_pen`` calls as the
    simulator received them (service introspection), whoever made them."""
    out: dict[str, list[list[float]]] = {}
    for turtle in turtles:
        df = topic(frames, f"/{turtle}/set_pen/_service_event")
        if df is None:
            continue
        rows = []
        for call in service_calls(df):
            req = call["request"]
            pen = [int(req.get(k, d)) for k, d in zip(("r", "g", "b", "width", "off"), PEN_DEFAULT)]
            rows.append([float(_rel(frames, call["t"])), *pen])
        out[turtle] = rows
    return out


def _clears(frames: Frames) -> list[float]:
    """When the drawing was wiped (``/clear``, ``/reset``)."""
    found: list[float] = []
    for service in ("/clear", "/reset"):
        df = topic(frames, f"{service}/_service_event")
        if df is not None:
            found += [float(_rel(frames, c["t"])) for c in service_calls(df)]
    return sorted(found)


def _commands(frames: Frames, turtles: list[str]) -> dict[str, dict[str, list[float]]]:
    out = {}
    for turtle in turtles:
        df = topic(frames, f"/{turtle}/cmd_vel")
        if df is None or "linear.x" not in df.columns or "angular.z" not in df.columns:
            continue
        keep = thin(len(df), MAX_COMMANDS)
        out[turtle] = {"t": _rel(frames, times(df)[keep]).tolist(),
                       "v": np.round(df["linear.x"].to_numpy(float)[keep], 3).tolist(),
                       "w": np.round(df["angular.z"].to_numpy(float)[keep], 3).tolist()}
    return out


def _steps(frames: Frames) -> list[list[Any]]:
    """``[start, end, id, ended_by]`` of each step."""
    open_: dict[str, float] = {}
    rows = []
    for e in events(frames, (ev.StepStart, ev.StepEnd)):
        t = float(_rel(frames, e.t))
        if isinstance(e, ev.StepStart):
            open_[e.step] = t
        else:
            rows.append([open_.pop(e.step, t), t, e.step, e.ended_by])
    return rows


def _goals(frames: Frames) -> list[list[Any]]:
    """``[t, x, y, how]`` of every goal the grader handed over (a topic, a service, an action)."""
    rows = []
    for e in events(frames, (ev.GoalSent, ev.ActionGoalSent)):
        xy = goal_xy(e.goal)
        if xy is None:
            continue
        how = (e.topic if isinstance(e, ev.GoalSent) else e.action) or "service"
        rows.append([float(_rel(frames, e.t)), round(xy[0], 3), round(xy[1], 3), how])
    return rows


def _placements(frames: Frames) -> list[list[Any]]:
    """``[t, x, y, theta, service]`` of every turtle the grader placed (teleport or spawn)."""
    rows = []
    for e in events(frames, ev.ServiceCall):
        service, req = e.service, e.request
        if service.rsplit("/", 1)[-1] in PLACING and "x" in req and "y" in req:
            rows.append([float(_rel(frames, e.t)), round(float(req["x"]), 3), round(float(req["y"]), 3),
                         round(float(req.get("theta", 0.0)), 3), service])
    return rows


def _said(frames: Frames) -> list[list[Any]]:
    rows = []
    for e in events(frames, tuple(_SAID)):
        rows.append([float(_rel(frames, e.t)), e.event, _SAID[type(e)](e)[:MAX_TEXT]])
    return rows[:MAX_LINES]


def _lines(frames: Frames) -> list[list[Any]]:
    """Log lines: ``[t, who, text]`` from /rosout and the processes' stdout."""
    rows: list[list[Any]] = []
    ro = rosout_lines(frames)
    if len(ro):
        rows += [[float(t), str(w), str(x)[:MAX_TEXT]]
                 for t, w, x in zip(_rel(frames, ro["time"]), ro["logger"], ro["text"])]
    so = stdout_lines(frames)
    if len(so):
        rows += [[float(t), str(w), str(x)[:MAX_TEXT]]
                 for t, w, x in zip(_rel(frames, so["time"]), so["process"], so["text"])]
    rows.sort(key=lambda r: r[0])
    return rows[:MAX_LINES]


def replay_data(frames: Frames, scenario: str) -> dict[str, Any]:
    """What the player needs of one scenario run (pure: frames in, plain data out)."""
    turtles = _turtles(frames)
    end = float(_rel(frames, scenario_end_time(frames)))
    ends = [end] + [d["t"][-1] for d in turtles.values() if d["t"]]
    return {"scenario": scenario, "world": WORLD_SIZE_M, "end": round(max(ends), 3),
            "turtles": turtles, "pens": _pens(frames, list(turtles)), "clears": _clears(frames),
            "pen_default": list(PEN_DEFAULT), "commands": _commands(frames, list(turtles)),
            "steps": _steps(frames), "goals": _goals(frames), "placements": _placements(frames), "events": _said(frames), "lines": _lines(frames)}


def replay_script(data: dict[str, Any]) -> str:
    """``replay.js``: adds ``data`` to ``window.graderReplays`` under its scenario."""
    body = json.dumps(data, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    key = json.dumps(data["scenario"])
    return f"(window.graderReplays = window.graderReplays || {{}})[{key}] = {body};\n"


def write_replay(scenario_dir: Path, frames: Frames) -> None:
    """The scenario folder's ``replay.js`` from its frames (the folder's name is the scenario)."""
    path = Path(scenario_dir) / REPLAY_FILE
    atomic_write(path, replay_script(replay_data(frames, Path(scenario_dir).name)))


def replays(sub_out: Path, scenarios_dir: str = SCENARIOS_DIR) -> list[str]:
    """The scenario folders of a submission's output that have replay data, in order."""
    root = Path(sub_out) / scenarios_dir
    return sorted(p.parent.name for p in root.glob(f"*/{REPLAY_FILE}")) if root.is_dir() else []


def pose_at(data: dict[str, Any], turtle: str, t: float) -> tuple[float, float]:
    """The turtle's position at ``t`` as the player draws it (linear between samples): what a
    test compares with the bag."""
    track = data["turtles"][turtle]
    ts = np.asarray(track["t"], float)
    return float(np.interp(t, ts, track["x"])), float(np.interp(t, ts, track["y"]))


__all__ = ["REPLAY_FILE", "pose_at", "replay_data", "replay_script", "replays", "write_replay"]
