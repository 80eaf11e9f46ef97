"""Shared, pure helpers for analyzers: topic lookup, grader events, student output lines, goals.

Everything here reads the ``frames`` dict described in docs/ARCHITECTURE.md ("Bag → DataFrames"):
topic name → DataFrame indexed by receive time ``t`` (float seconds), plus ``"__meta__"`` with one
row per topic (``topic``, ``type``, ``count``, ``publishers``).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np
import pandas as pd

from grader.bag.timebase import to_scenario_time
from grader.scenario.events import EVENTS_TOPIC, STDOUT_TOPIC, Event

META = "__meta__"
EVENTS = EVENTS_TOPIC
STDOUT = STDOUT_TOPIC
ROSOUT = "/rosout"

#: turtlesim's world is [0, W] x [0, H] with W = H = 11.088889 (float32 of 499/45).
WORLD_MAX = 11.088889

Frames = Mapping[str, pd.DataFrame]


# --------------------------------------------------------------------------- topics and meta
def norm_type(t: Any) -> str:
    """'std_msgs/Float32MultiArray' and 'std_msgs/msg/Float32MultiArray' compare equal."""
    s = str(t or "").strip()
    parts = s.split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return s


def meta(frames: Frames) -> pd.DataFrame | None:
    m = frames.get(META)
    if isinstance(m, pd.DataFrame) and "topic" in m.columns:
        return m
    return None


def meta_row(frames: Frames, topic: str) -> dict | None:
    m = meta(frames)
    if m is None:
        return None
    rows = m[m["topic"] == topic]
    if rows.empty:
        return None
    return rows.iloc[0].to_dict()


def publishers_of(frames: Frames, topic: str) -> list[str]:
    row = meta_row(frames, topic)
    if not row:
        return []
    pubs = row.get("publishers")
    if pubs is None or (isinstance(pubs, float) and math.isnan(pubs)):
        return []
    if isinstance(pubs, str):
        return [pubs] if pubs else []
    try:
        return [str(p) for p in list(pubs)]
    except TypeError:
        return []


def topic(frames: Frames, name: str) -> pd.DataFrame | None:
    """The topic's frame if it holds at least one message, else None."""
    df = frames.get(name)
    if isinstance(df, pd.DataFrame) and len(df) > 0:
        return df
    return None


def topic_or_student_topic(frames: Frames, name: str, type_name: str | None
                           ) -> tuple[pd.DataFrame | None, str, str]:
    """``name``'s frame, or, when it is missing and ``type_name`` is given, the one other topic of
    that type a student node published. Returns (frame, topic used, note for the feedback).

    Why: a wrong topic name is one mistake and costs the item that checks the name; values and
    rate are still judged on what the student's publisher actually sent.
    """
    df = topic(frames, name)
    if df is not None or not type_name:
        return df, name, ""
    m = meta(frames)
    if m is None:
        return None, name, ""
    graders = ("grader", "turtlesim")
    candidates = []
    for _, row in m.iterrows():
        t = str(row["topic"])
        pubs = [str(x) for x in (row.get("publishers") or [])]
        if t == name or str(row.get("type")) != type_name or not int(row.get("count") or 0):
            continue
        if pubs and all(x.startswith(graders) for x in pubs):
            continue
        candidates.append(t)
    if len(candidates) != 1 or topic(frames, candidates[0]) is None:
        return None, name, ""
    used = candidates[0]
    return topic(frames, used), used, f"Measured on your topic {used} (the lab asks for {name}). "


def times(df: pd.DataFrame) -> np.ndarray:
    return np.asarray(df.index, dtype=float)


def topics_present(frames: Frames, limit: int = 20) -> list[str]:
    """Topic names seen in the bag (meta first, else frame keys), for feedback texts."""
    m = meta(frames)
    if m is not None:
        names = [str(t) for t, c in zip(m["topic"], m.get("count", pd.Series([1] * len(m)))) if _nz(c)]
    else:
        names = [k for k, v in frames.items() if k != META and isinstance(v, pd.DataFrame) and len(v)]
    names = sorted(n for n in names if not n.startswith("/grader/"))
    return names[:limit]


def _nz(c: Any) -> bool:
    try:
        return float(c) > 0
    except (TypeError, ValueError):
        return True


def missing_topic_feedback(frames: Frames, name: str, what: str = "") -> str:
    present = topics_present(frames)
    similar = [t for t in present if _similar(t, name)]
    msg = f"No messages were recorded on {name}{' (' + what + ')' if what else ''}."
    if similar:
        msg += f" Found similar topic(s) {', '.join(similar)}: check the exact topic name."
    else:
        msg += f" Topics present: {', '.join(present) if present else '(none)'}."
    return msg


def _similar(a: str, b: str) -> bool:
    ka = re.sub(r"[^a-z0-9]", "", a.lower().rsplit("/", 1)[-1])
    kb = re.sub(r"[^a-z0-9]", "", b.lower().rsplit("/", 1)[-1])
    if not ka or not kb or a == b:
        return False
    return ka == kb or ka.rstrip("s") == kb.rstrip("s") or (len(kb) > 4 and (kb in ka or ka in kb))


def end_time(frames: Frames) -> float:
    """Last receive time of anything in the bag (NaN if the bag is empty)."""
    ends = [float(df.index.max()) for k, df in frames.items()
            if k != META and isinstance(df, pd.DataFrame) and len(df)]
    return max(ends) if ends else float("nan")


# --------------------------------------------------------------------------- grader events
def _loads(s: Any) -> dict:
    if isinstance(s, dict):
        return s
    try:
        d = json.loads(s)
    except (TypeError, ValueError):
        return {}
    return d if isinstance(d, dict) else {}


def events(frames: Frames, kind: str | Iterable[str] | None = None) -> list[dict]:
    """Parsed /grader/events messages (each dict gets ``t`` = bag receive time), optionally filtered."""
    df = topic(frames, EVENTS)
    if df is None or "data" not in df.columns:
        return []
    kinds = {kind} if isinstance(kind, str) else (set(kind) if kind is not None else None)
    out = []
    for t, s in zip(times(df), df["data"]):
        d = _loads(s)
        if not d:
            continue
        if kinds is not None and d.get("event") not in kinds:
            continue
        d = dict(d)
        d["t"] = float(t)
        out.append(d)
    return out


def has_events(frames: Frames) -> bool:
    return topic(frames, EVENTS) is not None


def scenario_start(frames: Frames) -> float | None:
    """Receive time of the driver's ``scenario_start`` event: the origin of the times a report
    shows ("12.3 s after the scenario started"). None when the bag has no such event."""
    ev = events(frames, "scenario_start")
    return float(ev[0]["t"]) if ev else None


def since_start(frames: Frames, t: Any) -> np.ndarray:
    """Times ``t`` (epoch seconds) as seconds since the scenario started (since the first
    recorded message when there is no ``scenario_start`` event), rounded to milliseconds."""
    t0 = scenario_start(frames)
    if t0 is None:
        starts = [float(df.index.min()) for k, df in frames.items()
                  if k != META and isinstance(df, pd.DataFrame) and len(df)]
        t0 = min(starts) if starts else 0.0
    return np.round(np.asarray(t, float) - t0, 3)


def thin(n: int, max_points: int = 400) -> np.ndarray:
    """Indices of at most ``max_points`` evenly spread rows of ``n`` (first and last kept): plot
    series in evidence stay small (result.json is read by people and tools)."""
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_points).round().astype(int))


def scenario_end_time(frames: Frames) -> float:
    ev = events(frames, Event.SCENARIO_END)
    return ev[-1]["t"] if ev else end_time(frames)


# --------------------------------------------------------------------------- student output lines
_ROS_PREFIX = re.compile(
    r"^\s*\[(DEBUG|INFO|WARN|WARNING|ERROR|FATAL)\]\s*\[(\d+(?:\.\d+)?)\]\s*\[([^\]]*)\]:\s?(.*)$"
)


def split_ros_console(line: str) -> tuple[str | None, float | None, str]:
    """'[INFO] [1718.25] [simple_subscriber]: 0.5' -> ('simple_subscriber', 1718.25, '0.5')."""
    m = _ROS_PREFIX.match(line)
    if not m:
        return None, None, line
    try:
        ts = float(m.group(2))
    except ValueError:
        ts = None
    return m.group(3), ts, m.group(4)


def rosout_lines(frames: Frames) -> pd.DataFrame:
    """/rosout as (time, logger, level, text). Time = the log stamp when present (when the node
    called the logger), else the receive time."""
    df = topic(frames, ROSOUT)
    if df is None or "msg" not in df.columns:
        return pd.DataFrame(columns=["time", "logger", "level", "text"])
    t = times(df)
    if "stamp.sec" in df.columns and "stamp.nanosec" in df.columns:
        st = pd.to_numeric(df["stamp.sec"], errors="coerce").to_numpy(float) + \
            pd.to_numeric(df["stamp.nanosec"], errors="coerce").to_numpy(float) * 1e-9
        # log stamps are system-clock times: in the frames' time base on simulated time
        st = np.where(np.isfinite(st) & (st > 0), to_scenario_time(frames, st), t)
    else:
        st = t
    return pd.DataFrame({
        "time": st,
        "logger": df["name"].astype(str).to_numpy() if "name" in df.columns else "",
        "level": df["level"].to_numpy() if "level" in df.columns else np.nan,
        "text": df["msg"].astype(str).to_numpy(),
    })


def stdout_lines(frames: Frames) -> pd.DataFrame:
    """/grader/stdout as (time, process, stream, logger, text).

    Lines in ROS console format ("[INFO] [stamp] [logger]: text") are split so the logger and the
    (more precise) log stamp are kept; other lines keep the bag receive time.
    """
    df = topic(frames, STDOUT)
    cols = ["time", "process", "stream", "logger", "text", "raw"]
    if df is None or "data" not in df.columns:
        return pd.DataFrame(columns=cols)
    rows = []
    for t, s in zip(times(df), df["data"]):
        d = _loads(s)
        line = str(d.get("line", "")) if d else str(s)
        logger, ts, text = split_ros_console(line)
        rows.append((ts if ts is not None else np.nan, float(t), str(d.get("process", "")),
                     str(d.get("stream", "")), logger, text, line))
    out = pd.DataFrame(rows, columns=["stamp", *cols])
    # console stamps are system-clock times (mapped on simulated time); else the receive time
    stamp = out["stamp"].to_numpy(float)
    out["time"] = np.where(np.isfinite(stamp), to_scenario_time(frames, stamp), out["time"].to_numpy(float))
    return out[cols]


# --------------------------------------------------------------------------- goals
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


def parse_xy_line(line: str) -> tuple[float, float] | None:
    """The lab's stdin format "x,y" (two floats separated by a comma); None when malformed."""
    parts = str(line).strip().split(",")
    if len(parts) != 2:
        return None
    try:
        x, y = float(parts[0]), float(parts[1])
    except ValueError:
        return None
    if not (math.isfinite(x) and math.isfinite(y)):
        return None
    return x, y


@dataclass
class Goal:
    t: float
    x: float
    y: float
    source: str
    t_end: float = float("nan")
    extra: dict = field(default_factory=dict)


def goals(frames: Frames, source: str = "auto", goal_topic: str = "/turtle1/goal") -> list[Goal]:
    """Goals in time order: ``goal_sent`` events (auto/events) or Float32MultiArray on goal_topic.

    Consecutive identical goals are merged (re-sending the same goal does not restart it).
    ``t_end`` is the next goal's time (or NaN for the last goal).
    """
    out: list[Goal] = []
    if source in ("auto", "events"):
        for e in events(frames, Event.GOAL_SENT):
            if e.get("topic") not in (None, goal_topic):
                continue                      # a Float32MultiArray published elsewhere
            xy = goal_xy(e.get("goal"))
            if xy is None:
                xy = goal_xy(e)
            if xy is not None:
                out.append(Goal(e["t"], xy[0], xy[1], "events", extra={"step": e.get("step")}))
    if not out and source in ("auto", "topic"):
        df = topic(frames, goal_topic)
        if df is not None and "data[0]" in df.columns and "data[1]" in df.columns:
            for t, x, y in zip(times(df), df["data[0]"], df["data[1]"]):
                if np.isfinite(x) and np.isfinite(y):
                    out.append(Goal(float(t), float(x), float(y), "topic"))
    out.sort(key=lambda g: g.t)
    merged: list[Goal] = []
    for g in out:
        if merged and abs(merged[-1].x - g.x) < 1e-3 and abs(merged[-1].y - g.y) < 1e-3:
            continue
        merged.append(g)
    for a, b in zip(merged, merged[1:]):
        a.t_end = b.t
    return merged


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def heading_error(x, y, theta, xd, yd):
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


def fmt(v: float, nd: int = 2) -> str:
    return "n/a" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"


def sentence(s: str) -> str:
    """Upper-case the first letter (only) and end with a period: 'theta_e is ...' -> 'Theta_e is ...'."""
    s = s.strip()
    if not s:
        return s
    s = s[0].upper() + s[1:]
    return s if s.endswith((".", "!", "?")) else s + "."


# --------------------------------------------------------------------------- service calls
def _request(df, i: int) -> dict:
    out = {}
    for c in df.columns:
        if str(c).startswith("request[0]."):
            v = df[c].iloc[i]
            if v is not None and not (isinstance(v, float) and math.isnan(v)):
                out[str(c).split(".", 1)[1]] = v
    return out


def service_calls(df: pd.DataFrame) -> list[dict]:
    """Calls recorded on a ``<service>/_service_event`` topic (service introspection), one entry
    ``{t, request}`` per request: the several events of one call (request received, response
    sent, ...) share the client gid and sequence number."""
    t = times(df)
    seq = df["info.sequence_number"].to_numpy() if "info.sequence_number" in df.columns else np.arange(len(df))
    gid_cols = [c for c in df.columns if str(c).startswith("info.client_gid")]
    calls: dict = {}
    for i in range(len(df)):
        key = (tuple(df[c].iloc[i] for c in gid_cols), seq[i])
        if key not in calls:
            calls[key] = {"t": float(t[i]), "request": _request(df, i)}
        elif not calls[key]["request"]:
            calls[key]["request"] = _request(df, i)
    return sorted(calls.values(), key=lambda c: c["t"])
