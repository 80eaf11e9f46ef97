"""Who did what in a recording: the grader's driver or student code.

* **Service calls.** Every call to a simulator service is in the bag (its services run with
  introspection: ``<service>/_service_event``), and each event names the client that made the
  call (``info.client_gid``). The driver records the GID of every client it calls with
  (``client_gid`` of its ``service_call`` events). A call is the grader's when its client belongs
  to the driver's DDS participant (the GID's first 12 bytes, the RTPS GUID prefix:
  :mod:`grader.scenario.client_gid` says why the prefix and not the whole GID, measured), and
  student code's otherwise. Whose call it is comes from the call itself, never from when it
  happened: a student's teleport right after the grader's own placement is still the student's.
  A recording whose driver calls carry no GID (made before the driver recorded them, or where the
  rmw could not say) cannot tell: its calls are ``unknown``.
* **Moves.** Calls that put a turtle somewhere without driving it: its ``teleport_absolute`` and
  ``teleport_relative``, ``/reset`` (every turtle back to the start), and ``/kill`` or ``/spawn``
  of its name (killed and spawned again elsewhere). A move by student code means the poses after
  it were not driven: every analyzer that pays for where the turtle went (goals reached, turns,
  action goals, circles, walls, crossings) gives nothing for what it judges across one, and says so.
* **Poses** come from the simulator's own record (:func:`grader.analyze._common.sim_pose`,
  :mod:`grader.sim.record`), so a node publishing poses of its own cannot move the turtle a grade
  is judged on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from grader.analyze import Finding
from grader.analyze._common import Frames, events, service_calls, sim_pose, since_start, times, topic
from grader.analyze.evidence import SINCE_START
from grader.scenario.client_gid import GUID_PREFIX_BYTES
from grader.contracts.events import ServiceCall

GRADER, STUDENT, UNKNOWN = "grader", "student code", "unknown"
#: services of a turtle that put it somewhere without driving it
TURTLE_MOVES = ("teleport_absolute", "teleport_relative")
#: global services that do, when they name the turtle (``reset``: every turtle)
GLOBAL_MOVES = ("reset", "kill", "spawn")

#: labels of the evidence this module adds to an analyzer's (see grader.analyze.evidence)
EVIDENCE = {
    "student_moves": ("calls of student code that moved the turtle", ""),
    "moved_by": ("moved by", ""),
    "client_gid": ("calling client (GID)", ""),
    "attribution": ("whose calls they were, judged from", ""),
    "service": ("service", ""), "request": ("request", ""), "t": ("called at", SINCE_START),
    "teleported": ("calls of student code that moved the turtle meanwhile", ""),
}


@dataclass
class Call:
    """One service call from the simulator's introspection events."""

    service: str
    t: float
    request: dict = field(default_factory=dict)
    client_gid: tuple[int, ...] = ()
    by: str = UNKNOWN

    def plain(self, frames: Frames) -> dict[str, Any]:
        """For evidence: the service, seconds since the start, the request and who called."""
        return {"service": self.service, "t": float(since_start(frames, self.t)),
                "request": {k: (v.item() if hasattr(v, "item") else v) for k, v in self.request.items()},
                "moved_by": self.by}


def driver_participants(frames: Frames) -> set[tuple[int, ...]] | None:
    """GUID prefixes of the clients the driver called with; None when a driver call has no GID
    (the recording cannot tell the grader's calls from others)."""
    out: set[tuple[int, ...]] = set()
    for e in events(frames, ServiceCall):
        gid = e.client_gid
        if gid is None or len(gid) < GUID_PREFIX_BYTES:
            return None
        out.add(tuple(int(b) for b in gid[:GUID_PREFIX_BYTES]))
    return out


def attribution_basis(frames: Frames) -> str:
    """How calls are attributed in this recording (for evidence and messages)."""
    if driver_participants(frames) is None:
        return ("nothing: the grader's own calls carry no client id in this recording (recorded before "
                "they were recorded, or the rmw could not say)")
    return "the calling client's id in each call"


def calls(frames: Frames, service: str) -> list[Call]:
    """The calls of ``service`` (full name, e.g. ``/turtle1/teleport_absolute``), attributed."""
    df = topic(frames, service.rstrip("/") + "/_service_event")
    if df is None:
        return []
    driver = driver_participants(frames)
    out = []
    for c in service_calls(df):
        gid = tuple(c["client_gid"])
        if driver is None or len(gid) < GUID_PREFIX_BYTES:
            by = UNKNOWN
        else:
            by = GRADER if gid[:GUID_PREFIX_BYTES] in driver else STUDENT
        out.append(Call(service, c["t"], c["request"], gid, by))
    return out


def service_event_services(frames: Frames) -> list[str]:
    """Every service whose introspection events were recorded."""
    suffix = "/_service_event"
    return sorted(k[: -len(suffix)] for k in frames if isinstance(k, str) and k.endswith(suffix))


def turtle_of(pose_topic: str) -> str:
    """``/turtle1/pose`` -> ``turtle1``."""
    parts = pose_topic.strip("/").split("/")
    return parts[-2] if len(parts) >= 2 else parts[0]


def moves(frames: Frames, pose_topic: str = "/turtle1/pose", by: tuple[str, ...] = (STUDENT,)) -> list[Call]:
    """Calls (by ``by``: student code by default) that moved the turtle of ``pose_topic`` without
    driving it, in time order."""
    turtle = turtle_of(pose_topic)
    out: list[Call] = []
    for service in service_event_services(frames):
        parent, _, base = service.rpartition("/")
        if base in TURTLE_MOVES and parent.rsplit("/", 1)[-1] == turtle:
            named = None
        elif base in GLOBAL_MOVES:
            named = None if base == "reset" else turtle
        else:
            continue
        for c in calls(frames, service):
            if c.by in by and (named is None or str(c.request.get("name", "")) == named):
                out.append(c)
    return sorted(out, key=lambda c: c.t)


def within(found: list[Call], t0: float, t1: float) -> list[Call]:
    """The calls in [t0, t1] (t1 NaN: to the end)."""
    return [c for c in found if c.t >= t0 and (not np.isfinite(t1) or c.t <= t1)]


def moved_text(frames: Frames, found: list[Call]) -> str:
    """'/turtle1/teleport_absolute called by student code 3 time(s), first 2.1 s after the start'."""
    first = found[0]
    names = sorted({c.service for c in found})
    return (f"{' and '.join(names)} called by student code {len(found)} time(s), first "
            f"{float(since_start(frames, first.t)):.1f} s after the start")


def moved_finding(frames: Frames, found: list[Call], what: str, value: Any = "moved by student code") -> Finding:
    """0 points for an item judged across a move by student code, saying which and when."""
    return Finding(value, 0.0, "fail",
                   f"The turtle was moved without driving ({moved_text(frames, found)}): {what} is judged "
                   "on a turtle moved only by velocity commands, so this earns nothing.",
                   {"student_moves": [c.plain(frames) for c in found[:10]]})


def foreign_poses(truth: Any, stream: Any) -> int:
    """Poses of ``stream`` (while the simulator published) that are not among ``truth``'s: the
    simulator publishes the very same numbers on every pose topic, so any other pose is someone
    else's."""
    own = set(zip(truth["x"].round(6), truth["y"].round(6), truth["theta"].round(6)))
    t = times(stream)
    # only while the record ran: a pose received after its last entry may be the copy of a pose
    # whose entry a killed simulator never flushed
    sub = stream[(t >= float(times(truth)[0])) & (t <= float(times(truth)[-1]))]
    return sum(1 for key in zip(sub["x"].round(6), sub["y"].round(6), sub["theta"].round(6)) if key not in own)


def ignored_poses_note(frames: Frames, pose_topic: str) -> str:
    """A sentence for a failing finding when another node published poses on ``pose_topic``
    (they were not used: grades rest on the simulator's own poses); empty otherwise."""
    truth, public = sim_pose(frames, pose_topic), topic(frames, pose_topic)
    if truth is None or public is None or public is truth or not {"x", "y", "theta"} <= set(public.columns):
        return ""
    n = foreign_poses(truth, public)
    return (f" Judged on the simulator's own poses: {n} pose(s) on {pose_topic} that the simulator never "
            "published were ignored." if n else "")
