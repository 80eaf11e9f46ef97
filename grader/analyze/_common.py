"""Shared, pure helpers for analyzers: topic lookup, grader events, student output lines, goals.

Everything here reads the ``frames`` dict described in docs/ARCHITECTURE.md ("Bag → DataFrames"):
topic name → DataFrame indexed by receive time ``t`` (float seconds), plus ``"__meta__"`` with one
row per topic (``topic``, ``type``, ``count``, ``publishers``).
"""

from __future__ import annotations

import collections
import json
import math
import re
import threading
from typing import Any, Mapping, TypeVar, overload

import numpy as np
import pandas as pd

from grader.bag.timebase import to_scenario_time
from grader.contracts.events import (EVENTS_TOPIC, STDOUT_TOPIC, EventRecord, Graph, ProcessExit, ScenarioEnd,
                                    ScenarioStart, TurtlesHeld, TurtlesReleased, parse_event)
from grader.sim import truth_pose_topic
from grader.sim.physics import DT
from grader.sim.record import record_topic
from grader.analyze._lines import split_ros_console as split_ros_console, traceback_mask as traceback_mask  # re-exported

META = "__meta__"
EVENTS = EVENTS_TOPIC
STDOUT = STDOUT_TOPIC
ROSOUT = "/rosout"


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
    row: dict = rows.iloc[0].to_dict()
    return row


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


def sim_pose(frames: Frames, pose_topic: str) -> pd.DataFrame | None:
    """The poses of ``pose_topic`` that the simulator published: its own record of them
    (``/grader/sim_record/turtle1/pose``, written into the bag from the simulator's file, never
    taken from DDS: :mod:`grader.sim.record` says why only that is proof of origin). In bags
    recorded before the record existed: the simulator's live copy ``/grader/sim/turtle1/pose``,
    else the public topic (which any node can publish on)."""
    record = frames.get(record_topic(pose_topic))
    if isinstance(record, pd.DataFrame):       # the bag holds the record: nothing else counts
        return record if len(record) else None
    for name in (truth_pose_topic(pose_topic), pose_topic):
        df = topic(frames, name)
        if df is not None:
            return df
    return None


def sim_tick_times(frames: Frames, pose_topic: str, df: pd.DataFrame) -> np.ndarray | None:
    """The times of ``df`` (consecutive poses of :func:`sim_pose`) on the simulator's own clock,
    one 16 ms tick per pose, from its first pose's time; None unless ``df`` is the simulator's
    record (lossless: every pose it published, one per tick; a topic recorded over DDS may miss
    one). A simulator starved of CPU for more than its catch-up drops ticks, and its world falls
    behind the wall clock: a rate judged on the wall clock then measures the machine."""
    if not isinstance(frames.get(record_topic(pose_topic)), pd.DataFrame) or not len(df):
        return None
    return float(df.index[0]) + np.arange(len(df)) * DT


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
    """Why ``name`` has no messages, in words that tell the causes apart: a node advertised it
    and never published, or nothing published there (and what was published instead)."""
    graph = [n for e in events(frames, Graph) for n in e.publishers.get(name) or []]
    advertisers = [p for p in dict.fromkeys([*publishers_of(frames, name), *graph]) if not str(p).startswith("grader_")]
    if advertisers:
        return (f"{', '.join(advertisers)} advertised {name} but published no message on it"
                f"{' (' + what + ')' if what else ''}: check that publish() is called, e.g. from a timer "
                "that keeps running.")
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
_PARSED: collections.OrderedDict[int, tuple[pd.DataFrame, list[EventRecord]]] = collections.OrderedDict()
_PARSED_LOCK = threading.Lock()
_PARSED_KEPT = 16          # the events topics of the last few bags: every analyzer of a scenario reads them


def _loads(s: Any) -> dict[str, Any]:
    if isinstance(s, dict):
        return s
    try:
        d = json.loads(s)
    except (TypeError, ValueError):
        return {}
    return d if isinstance(d, dict) else {}


def _parsed(df: pd.DataFrame) -> list[EventRecord]:
    """Every event of the bag's events topic as its model, parsed once per DataFrame (the
    analyzers of a scenario each ask; the models are frozen, so sharing them is safe)."""
    with _PARSED_LOCK:                    # analyses of several scenarios may run in threads
        hit = _PARSED.get(id(df))
        if hit is not None and hit[0] is df:
            _PARSED.move_to_end(id(df))
            return hit[1]
    out = [parse_event(d, float(t)) for t, s in zip(times(df), df["data"]) if (d := _loads(s))]
    with _PARSED_LOCK:
        _PARSED[id(df)] = (df, out)
        while len(_PARSED) > _PARSED_KEPT:
            _PARSED.popitem(last=False)
    return out


E = TypeVar("E", bound=EventRecord)
E2 = TypeVar("E2", bound=EventRecord)
E3 = TypeVar("E3", bound=EventRecord)


@overload
def events(frames: Frames, kind: None = None) -> list[EventRecord]: ...
@overload
def events(frames: Frames, kind: type[E]) -> list[E]: ...
@overload
def events(frames: Frames, kind: tuple[type[E], type[E2]]) -> list[E | E2]: ...
@overload
def events(frames: Frames, kind: tuple[type[E], type[E2], type[E3]]) -> list[E | E2 | E3]: ...
@overload
def events(frames: Frames, kind: tuple[type[EventRecord], ...]) -> list[EventRecord]: ...


def events(frames: Frames, kind: type[EventRecord] | tuple[type[EventRecord], ...] | None = None) -> list[Any]:
    """The driver's events of the bag (grader.contracts.events), in order, each with ``t`` = its
    receive time; with ``kind`` (a model, or a tuple of them) only those of that kind."""
    df = topic(frames, EVENTS)
    if df is None or "data" not in df.columns:
        return []
    every = _parsed(df)
    if kind is None:
        return list(every)
    models = kind if isinstance(kind, tuple) else (kind,)
    if not all(isinstance(m, type) and issubclass(m, EventRecord) for m in models):
        raise TypeError(f"events(frames, {kind!r}): ask for a model of grader.contracts.events (e.g. StepStart), "
                        "not an event's name")
    return [e for e in every if type(e) in models]


def sim_node(frames: Frames) -> str:
    """The reference simulator's node name (from ``scenario_start``): never a student's node."""
    return next((e.sim_node for e in events(frames, ScenarioStart)), None) or "turtlesim"


def own_exits(frames: Frames) -> list[ProcessExit]:
    """``process_exit`` events of student processes that ended on their own (a crash, or a return
    while the scenario ran), not those the grader stopped at its end: what the run's summary, a
    node that never appeared and a turtle that stopped are each explained by."""
    return [e for e in events(frames, ProcessExit) if not e.stopped_by_grader]


def has_events(frames: Frames) -> bool:
    return topic(frames, EVENTS) is not None


def held_mask(frames: Frames, t: np.ndarray) -> np.ndarray:
    """True where ``t`` (bag times) falls while the grader held the turtles still (from each
    ``turtles_held`` event to the ``turtles_released`` after it, or to the end): a placement's
    hand-over, time no student code could move the turtle in."""
    mask = np.zeros(len(t), dtype=bool)
    start = None
    for e in events(frames, (TurtlesHeld, TurtlesReleased)):
        if isinstance(e, TurtlesHeld):
            start = e.t if start is None else start
        elif start is not None:
            mask |= (t >= start) & (t <= e.t)
            start = None
    if start is not None:
        mask |= t >= start
    return mask


def scenario_start(frames: Frames) -> float | None:
    """Receive time of the driver's ``scenario_start`` event: the origin of the times a report
    shows ("12.3 s after the scenario started"). None when the bag has no such event."""
    ev = events(frames, ScenarioStart)
    return ev[0].t if ev else None


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
    ev = events(frames, ScenarioEnd)
    return ev[-1].t if ev else end_time(frames)


# --------------------------------------------------------------------------- student output lines
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
def _request(df: pd.DataFrame, i: int) -> dict:
    out = {}
    for c in df.columns:
        if str(c).startswith("request[0]."):
            v = df[c].iloc[i]
            if v is not None and not (isinstance(v, float) and math.isnan(v)):
                out[str(c).split(".", 1)[1]] = v
    return out


def service_calls(df: pd.DataFrame) -> list[dict]:
    """Calls recorded on a ``<service>/_service_event`` topic (service introspection), one entry
    ``{t, request, client_gid}`` per request: the several events of one call (request received,
    response sent, ...) share the client gid and sequence number. ``client_gid`` is the tuple of
    the GID's bytes as the server saw it (empty when the bag has none): whose call it was, see
    :mod:`grader.analyze.provenance`."""
    t = times(df)
    seq = df["info.sequence_number"].to_numpy() if "info.sequence_number" in df.columns else np.arange(len(df))
    gid_cols = sorted((c for c in df.columns if re.fullmatch(r"info\.client_gid\[\d+\]", str(c))),
                      key=lambda c: int(str(c)[len("info.client_gid["):-1]))
    calls: dict = {}
    for i in range(len(df)):
        gid = tuple(int(v) if v == v else -1 for v in (df[c].iloc[i] for c in gid_cols))
        key = (gid, seq[i])
        if key not in calls:
            calls[key] = {"t": float(t[i]), "request": _request(df, i), "client_gid": gid}
        elif not calls[key]["request"]:
            calls[key]["request"] = _request(df, i)
    return sorted(calls.values(), key=lambda c: c["t"])


#: services the driver places a turtle with (a goal's window ends at the driver's next one);
#: whose call a service event is: grader.analyze.provenance
TELEPORT_SERVICES = ("teleport_absolute", "teleport_relative", "reset")
