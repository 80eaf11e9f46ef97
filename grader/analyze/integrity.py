"""Integrity flags: the pose the grade is based on really comes from the simulator's physics.

* ``integrity_pose_publisher``: only the simulator publishes /turtle1/pose (and the grader's
  copy of it). From the publisher lists of the driver's graph snapshots; from the poses on the
  public topic that are not in the simulator's own record of what it published
  (:mod:`grader.sim.record`); and from the pose stream: jumps the unicycle cannot make in one
  16 ms tick without a teleport call, and a rate above the simulator's 62.5 Hz.
  The rate and jump heuristics read receive times, which a loaded machine bunches (at --jobs 8
  on 2 cores the "rate" reached 11,000 Hz and correct code was flagged), so they judge only
  recordings without the simulator's record or copy.
* ``integrity_no_teleport``: the simulator's services run with introspection, so any teleport
  (or reset) request appears on ``<service>/_service_event`` with the id of the client that made
  it; calls whose client is the grader's driver are not held against the student
  (:mod:`grader.analyze.provenance`: decided by the call itself, not its timing). set_pen calls
  are listed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, register
from grader.analyze import provenance
from grader.analyze._common import (Frames, end_time, events, meta, publishers_of, rosout_lines,
                                    service_calls, sim_pose, times, topic)
from grader.analyze.rate import rate_stats
from grader.sim import truth_pose_topic
from grader.sim.record import record_topic
from grader.contracts.events import Graph

DT = 0.016


#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "truth_poses": ("poses the simulator published", ""), "public_poses": ("poses on the public topic", ""),
    "foreign_poses": ("poses on the public topic the simulator never published", ""),
    "flag_services": ('services a student must not call', ''),
    "list_services": ('services whose calls are listed', ''),
    "pose_topic": ('pose topic', ''),
    "jump_tol": ("jump beyond the unicycle's reach flagged", 'm'),
    "max_rate_hz": ('pose rate above this means a second publisher', 'Hz'),
    "publishers": ("nodes publishing the pose", ""),
    "rosout_loggers": ("ROS loggers seen", ""),
    "rate_hz": ("pose rate", "Hz"),
    "jumps": ("jumps of the pose", ""),
    "from": ("from (x, y)", "m"), "to": ("to (x, y)", "m"), "distance": ("distance", "m"),
    "n_jumps": ("jumps of the pose", ""),
    "basis": ("judged from", ""),
    "flagged_calls": ("teleport or reset calls by student code", ""),
    "driver_calls": ("calls made by the grader", ""),
    "set_pen_calls": ("set_pen calls", ""),
    "service": ("service", ""),
    "request": ("request", ""),
    "x": ("x", "m"), "y": ("y", "m"), "theta": ("heading", "rad"),
    "service_event_topics_recorded": ("service calls were recorded", ""),
    "allowed": ("nodes allowed to publish the pose", ""),
    "unattributed_calls": ("teleport or reset calls whose caller the recording cannot tell", ""),
    "pose_basis": ("poses compared with", ""),
    **provenance.EVIDENCE,
}


class IntegrityPosePublisherParams(AnalyzerParams):
    pose_topic: str = Field("/turtle1/pose", description="pose topic")
    allowed: tuple[str, ...] = Field(("turtlesim",), description="node names allowed to publish the pose")
    jump_tol: float = Field(0.05, ge=0, description="m: beyond v*dt*ticks counted as a jump")
    max_rate_hz: float = Field(62.5 * 1.3, gt=0,
                               description="Hz: pose rate above this means a second publisher")


@register("integrity_pose_publisher", params=IntegrityPosePublisherParams,
          evidence={**EVIDENCE, "value": ("pose publishers", "")},
          expect="only the simulator publishing {pose_topic}")
def integrity_pose_publisher(frames: Frames, p: IntegrityPosePublisherParams) -> Finding:
    """Flag (fraction 0 / status fail) when something other than the simulator publishes the pose."""
    name = p.pose_topic
    allowed = {str(a).strip("/").rsplit("/", 1)[-1] for a in p.allowed}
    pubs = publishers_of(frames, name) + publishers_of(frames, truth_pose_topic(name))
    for e in events(frames, Graph):        # the driver's snapshots of the ROS graph
        for topic_name in (name, truth_pose_topic(name)):
            for node in e.publishers.get(topic_name) or []:
                if node not in pubs:
                    pubs.append(str(node))
    pubs = list(dict.fromkeys(pubs))
    ev: dict = {"topic": name, "publishers": pubs,
                "rosout_loggers": sorted(set(rosout_lines(frames)["logger"].tolist()))[:20]}
    problems = []
    foreign = [q for q in pubs if str(q).strip("/").rsplit("/", 1)[-1] not in allowed]
    if foreign:
        problems.append(f"{name} was also published by {', '.join(foreign)}")
    truth = sim_pose(frames, name)
    recorded = topic(frames, record_topic(name)) is not None
    ev["pose_basis"] = ("the simulator's own record of its poses" if recorded
                        else "the simulator's copy of its poses (recorded before the record existed)")
    for shown, stream in ((name, topic(frames, name)),
                          (f"the grader's copy {truth_pose_topic(name)}", topic(frames, truth_pose_topic(name)))):
        if truth is None or stream is None or stream is truth or not {"x", "y", "theta"} <= set(stream.columns):
            continue
        # the simulator publishes every pose on each topic, the very same numbers: a pose there
        # that is not among the simulator's own is someone else's
        foreign_poses = provenance.foreign_poses(truth, stream)
        if shown == name:
            ev.update(truth_poses=len(truth), public_poses=len(stream), foreign_poses=foreign_poses)
        if foreign_poses:
            problems.append(f"{foreign_poses} pose(s) on {shown} that the simulator never published")
    df = topic(frames, name)
    # with the simulator's record (or its copy) every foreign pose is named above; the stream's
    # rate and jumps only guess at them (a simulator starved on a loaded machine publishes its
    # late ticks in bursts: measured 9 kHz "rates" at load 60), so they judge only recordings without it
    exact = recorded or "foreign_poses" in ev
    if df is not None and not exact and len(df) >= 3 and {"x", "y"} <= set(df.columns):
        t = times(df)
        st = rate_stats(t, gap_factor=None)
        st["rate_hz"] = (len(t) - 1) / (t[-1] - t[0]) if t[-1] > t[0] else float("nan")   # bursts average out
        ev["rate_hz"] = st["rate_hz"]
        if np.isfinite(st["rate_hz"]) and st["rate_hz"] > p.max_rate_hz:
            problems.append(f"{name} arrives at {st['rate_hz']:.1f} Hz, above the simulator's 62.5 Hz")
        x, y = df["x"].to_numpy(float), df["y"].to_numpy(float)
        v = np.abs(df["linear_velocity"].to_numpy(float)) if "linear_velocity" in df.columns else np.zeros(len(df))
        moved = np.hypot(np.diff(x), np.diff(y))
        ticks = np.maximum(1, np.round(np.diff(t) / DT))
        allowed_step = np.maximum(v[1:], v[:-1]) * DT * ticks + p.jump_tol
        jumps = np.nonzero(moved > allowed_step)[0]
        all_jumps: list[dict[str, Any]] = [{"t": float(t[i + 1]), "from": [float(x[i]), float(y[i])],
                      "to": [float(x[i + 1]), float(y[i + 1])], "distance": float(moved[i])} for i in jumps]
        ev["jumps"] = all_jumps[:10]
        ev["n_jumps"] = len(all_jumps)
        # jumps right after a teleport/reset request are that request (flagged by integrity_no_teleport)
        teleports = _service_rows(frames, ("teleport_absolute", "teleport_relative", "reset", "spawn"))
        unexplained = [j for j in all_jumps if not any(abs(j["t"] - tt) < 0.5 for tt in teleports)]
        if unexplained:
            problems.append(f"the pose jumped {len(unexplained)} time(s) without a teleport call "
                            f"(first at t={unexplained[0]['t']:.2f}, {unexplained[0]['distance']:.2f} m)")
    elif df is None:
        return Finding.error(f"No {name} messages were recorded; the check could not run.", ev)
    parts = (["publisher list"] if pubs else []) + (
        ["the simulator's own record"] if recorded else ["the simulator's own copy of every pose"] if exact else [])
    ev["basis"] = " and ".join(parts) or "pose stream consistency (publisher list not recorded)"
    if problems:
        return Finding("flagged", 0.0, "fail",
                       "Integrity: " + "; ".join(problems) + ". Only the simulator may publish the turtle's pose.", ev)
    return Finding("ok", 1.0, "pass", f"{name} comes from the simulator only ({ev['basis']}).", ev)


def _service_rows(frames: Frames, names: tuple[str, ...]) -> list[float]:
    out: list[float] = []
    for key, df in frames.items():
        if not key.endswith("/_service_event") or df is None or len(df) == 0:
            continue
        svc = key[: -len("/_service_event")].rsplit("/", 1)[-1]
        if svc in names:
            out += times(df).tolist()
    return out


class IntegrityNoTeleportParams(AnalyzerParams):
    flag_services: tuple[str, ...] = Field(("/turtle1/teleport_absolute", "/turtle1/teleport_relative", "/reset"),
                                           description="services a student must not call")
    list_services: tuple[str, ...] = Field(("/turtle1/set_pen",), description="services whose calls are listed")


@register("integrity_no_teleport", params=IntegrityNoTeleportParams,
          evidence={**EVIDENCE, "value": ("teleport calls", "")},
          expect="no teleport or reset call by student code")
def integrity_no_teleport(frames: Frames, p: IntegrityNoTeleportParams) -> Finding:
    """Flag teleport/reset calls made by student code, told from the grader's own by the calling client's id; list set_pen calls.

    (:mod:`grader.analyze.provenance`: not by when a call was made.)"""
    if not math.isfinite(end_time(frames)):
        return Finding.error("The bag holds no messages; teleport calls could not be checked.")
    flagged: list = []
    listed: list = []
    explained: list = []
    unknown: list = []
    for svc in p.flag_services:
        for c in provenance.calls(frames, svc):
            {provenance.GRADER: explained, provenance.STUDENT: flagged}.get(c.by, unknown).append(c.plain(frames))
    for svc in p.list_services:
        df = topic(frames, f"{svc}/_service_event")
        if df is not None:
            listed += [{"service": svc, "t": c["t"], "request": c["request"]} for c in service_calls(df)]
    m = meta(frames)
    ev = {"flagged_calls": flagged[:20], "driver_calls": explained[:20], "set_pen_calls": listed[:20],
          "unattributed_calls": unknown[:20], "attribution": provenance.attribution_basis(frames),
          "service_event_topics_recorded": bool(m is not None and any("_service_event" in str(t) for t in m["topic"]))}
    if flagged:
        first = flagged[0]
        return Finding(f"{len(flagged)} call(s)", 0.0, "fail",
                       f"Integrity: {first['service']} was called by student code {len(flagged)} time(s) during "
                       f"grading (first {first['t']:.2f} s after the start); the turtle must reach goals by "
                       "driving, not teleporting.", ev)
    if unknown:
        return Finding.error(f"{len(unknown)} teleport or reset call(s) in this recording, and its grader calls "
                             "carry no client id, so whose they were cannot be told: grade the submission again "
                             "to record them.", ev)
    return Finding("none", 1.0, "pass",
                   "No teleport or reset calls by student code"
                   + (f"; {len(listed)} set_pen call(s) listed." if listed else "."), ev)
