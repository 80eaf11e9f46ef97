"""The turtle-chase lab's own analyzers: ``rubrics/chase.yaml`` names this file under ``analyzers:``.

This file is the whole of the lab's grading code: it lives next to its rubric, registers its
analyzers exactly as the grader's own modules do (``@register`` from ``grader.analyze``, pure
functions from the recording's DataFrames to a ``Finding``) and reads the same helpers; nothing
of it is inside the ``grader`` package. An instructor who installed the grader as a tool writes
a lab this way.

* ``chase_spawned``: student code called ``/spawn`` and the simulator created a turtle named
  ``turtle2`` (the simulator's spawn service runs with introspection, so every call is in the
  bag with its request, its response and the calling client's id).
* ``chase_catches``: after each step that moves turtle1 (the grader teleports turtle1 and places
  turtle2, both held still until the student's node has answered with a command computed from
  the new poses), turtle2 comes within ``catch_m`` of turtle1 within ``time_limit_s`` of the
  release, while turtle1 stays where the grader put it (a node that drives turtle1 toward
  turtle2 does not chase).
* ``chase_short_way``: at the moves that need a large turn (or where an unwrapped heading error
  turns the long way), the command turtle2 got from the placement turns toward turtle1 the short way.
* ``chase_follows``: while the grader drives turtle1 (a circle, by publishing on
  ``/turtle1/cmd_vel``), turtle2 stays within ``follow_m`` of it after ``catch_up_s``.

All poses are the simulator's own record of what it published (``sim_pose``), never the public
topics a node could publish on. A window in which student code moved either turtle without
driving it (a teleport, a kill, a reset) earns nothing; the lab's own ``/spawn`` of turtle2 is
no such move: a spawn only puts a turtle somewhere when no turtle of that name exists, which
after the first spawn takes a kill or a reset, and those are counted.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, provenance, register
from grader.analyze.toolkit import Frames, events, since_start, sim_pose, thin, times, topic
from grader.analyze.evidence import SHARE
from grader.report.figures import FigureContext, Plot, figure
from grader.scenario.client_gid import GUID_PREFIX_BYTES
from grader.contracts.events import StepEnd, StepStart, TurtlesReleased

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE: dict[str, Any] = {
    **provenance.EVIDENCE,
    "calls": ("calls of /spawn by student code", ""), "name": ("turtle name asked for", ""), "by": ("called by", ""),
    "spawned": ("turtles the simulator spawned for student code", ""),
    "spawned_by_grader": ("the grader spawned the turtle itself (the node had not)", ""),
    "service": ("service", ""), "request_name": ("name requested", ""),
    "response_name": ("name the simulator gave", ""),
    "extra_calls": ("calls after the turtle existed", ""), "max_calls": ("calls allowed", ""),
    "extra_calls_credit": ("credit when the turtle was spawned with extra calls", SHARE),
    "moves": ("moves of turtle1", ""), "caught": ("moves caught in time", ""),
    "step": ("step", ""), "turtle1": ("turtle1 placed at (x, y)", "m"),
    "turtle2_start": ("turtle2 placed at (x m, y m, heading rad)", ""),
    "caught_s": ("time to catch", "s"), "closest_m": ("closest approach", "m"),
    "turtle1_moved_m": ("turtle1 moved meanwhile", "m"), "ok": ("in time", ""), "why": ("why not", ""),
    "catch_m": ("caught within", "m"), "time_limit_s": ("time allowed per move", "s"),
    "still_m": ("turtle1 may drift by", "m"), "steps": ("steps that move turtle1", ""),
    "chaser_pose": ("chaser's pose topic", ""), "target_pose": ("target's pose topic", ""),
    "follow_m": ("must stay within", "m"), "catch_up_s": ("time to catch up first", "s"),
    "min_share": ("share of the time needed", SHARE), "share": ("share of the time within", SHARE),
    "max_m": ("largest distance after catching up", "m"), "mean_m": ("mean distance after catching up", "m"),
    "driven_m": ("distance turtle1 was driven", "m"), "judged_s": ("time judged", "s"),
    "chased_m": ("distance turtle2 drove meanwhile", "m"),
    "required_turn_deg": ("turn toward turtle1 from the placement", "deg"),
    "naive_turn_deg": ("unwrapped heading error there", "deg"), "angular_z": ("angular.z of the command", "rad/s"),
    "cmd_topic": ("command topic", ""), "min_turn_deg": ("moves judged from a turn of", "deg"),
    "wrap_turn_deg": ("and where wrapping matters, from", "deg"),
    "ambiguous_deg": ("within this of 180° either way counts", "deg"), "min_drive_m": ("turtle1 driven at least", "m"),
    "teleported": ("calls of student code that moved a turtle meanwhile", ""),
    "x": ("x", "m"), "y": ("y", "m"), "theta": ("heading", "rad"),
    "distance": None,
}


# ------------------------------------------------------------------------------------ helpers
def _student_moves(frames: Frames, pose_topics: tuple[str, ...]) -> list[provenance.Call]:
    """Calls of student code that put one of the turtles somewhere without driving it, except
    ``/spawn`` (see the module docstring: a spawn that moves anything follows a kill or reset)."""
    found = [c for p in pose_topics for c in provenance.moves(frames, p) if c.service.rsplit("/", 1)[-1] != "spawn"]
    unique = {(c.service, c.t): c for c in found}
    return sorted(unique.values(), key=lambda c: c.t)


def _step_times(frames: Frames, step: str) -> tuple[float | None, float | None, float | None]:
    """(start, release, end) of a step: the release of its held hand-over, if it had one."""
    start = next((e.t for e in events(frames, StepStart) if e.step == step), None)
    end = next((e.t for e in events(frames, StepEnd) if e.step == step), None)
    released = next((e.t for e in events(frames, TurtlesReleased) if e.step == step and e.ok), None)
    return start, released, end


def _pairs(frames: Frames, chaser: str, target: str) -> pd.DataFrame | None:
    """One row per pose of the chaser with the target's pose of the same simulator tick:
    ``t, x2, y2, th2, x1, y1, d`` (both from the simulator's own record)."""
    p2, p1 = sim_pose(frames, chaser), sim_pose(frames, target)
    if p2 is None or p1 is None or not {"x", "y", "theta"} <= set(p2.columns) or not {"x", "y"} <= set(p1.columns):
        return None
    a = pd.DataFrame({"t": times(p2), "x2": p2["x"].to_numpy(float), "y2": p2["y"].to_numpy(float),
                      "th2": p2["theta"].to_numpy(float)})
    b = pd.DataFrame({"t": times(p1), "x1": p1["x"].to_numpy(float), "y1": p1["y"].to_numpy(float)})
    # the simulator publishes every turtle's pose in the same 16 ms tick: the nearest one is its own
    out = pd.merge_asof(a, b, on="t", direction="nearest", tolerance=0.012).dropna()
    out["d"] = np.hypot(out["x1"] - out["x2"], out["y1"] - out["y2"])
    return out.reset_index(drop=True)


def _no_chaser(frames: Frames, chaser: str) -> Finding:
    turtle = provenance.turtle_of(chaser)
    return Finding.fail(f"There was no {turtle} to chase with: the simulator published no {chaser} (call /spawn "
                        f"with name '{turtle}' when your node starts).", {"chaser_pose": chaser})


def _series(frames: Frames, rows: pd.DataFrame, t0: float) -> dict[str, list[float]]:
    keep = thin(len(rows))
    return {"t": np.round(rows["t"].to_numpy(float)[keep] - t0, 3).tolist(),
            "d": np.round(rows["d"].to_numpy(float)[keep], 3).tolist()}


# ---------------------------------------------------------------------------------- analyzers
class ChaseSpawnedParams(AnalyzerParams):
    service: str = Field("/spawn", description="the simulator's spawn service")
    name: str = Field("turtle2", description="the turtle the lab asks for")
    max_calls: int = Field(1, ge=1, description="calls of the service the lab allows")
    extra_calls_credit: float = Field(0.5, ge=0, le=1, description="share: credit when the turtle was spawned "
                                                                   "but with more calls")


@register("chase_spawned", evidence={**EVIDENCE, "value": ("spawned", "")},
          expect="one call of {service} by your node that creates {name}", params=ChaseSpawnedParams)
def chase_spawned(frames: Frames, p: ChaseSpawnedParams) -> Finding:
    """Student code called the spawn service and the simulator created the turtle ``name``."""
    calls = _spawn_calls(frames, p.service)
    mine = [c for c in calls if c["by"] != provenance.GRADER]
    ev: dict[str, Any] = {"calls": [{k: v for k, v in c.items() if k != "gid"} for c in mine[:10]],
                          "name": p.name}
    made = [c for c in mine if c["response_name"] == p.name
            or (c["response_name"] is None and c["request_name"] == p.name)]
    ev["spawned"] = sorted({c["response_name"] for c in mine if c["response_name"]})
    # a placement with ``spawn: true`` made the turtle when the node had not: say so, the steps
    # after it were graded with the grader's turtle
    graders = [c for c in calls if c["by"] == provenance.GRADER and c["response_name"] == p.name]
    ev["spawned_by_grader"] = bool(graders)
    instead = (f" The grader spawned {p.name} itself {float(since_start(frames, graders[0]['t'])):.1f} s after the "
               "start, so that the items after it could be graded." if graders else "")
    if not mine:
        # "never called" would not be true of a node that called before its client had found
        # the service: the request is lost (bench_flake: wait_for_service(timeout_sec=-10.0),
        # which checks once, got turtle2 in one run of three)
        return Finding.fail(f"The simulator's {p.service} got no request from your node: call it once when "
                            f"the node starts, with name '{p.name}' (turtlesim/srv/Spawn), after "
                            "wait_for_service(timeout_sec=...) with a positive timeout has returned True (a "
                            "request sent before the client has found the service is lost)." + instead, ev,
                            value="no call")
    if not made:
        other = ev["spawned"]
        said = (f"the simulator spawned {', '.join(other)}" if other
                else "the simulator spawned nothing (see its log: a name already taken or not a valid name)")
        asked = ", ".join(repr(c["request_name"]) for c in mine[:3])
        return Finding.fail(f"Your node called {p.service} {len(mine)} time(s) with name {asked}, and {said}; "
                            f"this lab asks for a turtle named '{p.name}'." + instead, ev,
                            value=", ".join(other) or "nothing")
    extra = len(mine) - p.max_calls
    ev["extra_calls"] = max(0, extra)
    first = made[0]
    when = float(since_start(frames, first["t"]))
    if extra > 0:
        return Finding(f"{p.name} ({len(mine)} calls)", p.extra_calls_credit, "partial",
                       f"{p.name} was spawned {when:.1f} s after the start, but your node called {p.service} "
                       f"{len(mine)} times: call it once, when the node starts (not in a timer or a callback).", ev)
    return Finding(p.name, 1.0, "pass", f"Your node spawned {p.name} ({when:.1f} s after the start).", ev)


def _spawn_calls(frames: Frames, service: str) -> list[dict[str, Any]]:
    """Each call of the spawn service: time, requested and given name, and whose call it was
    (by the calling client's id, as :mod:`grader.analyze.provenance` tells them)."""
    df = topic(frames, service.rstrip("/") + "/_service_event")
    if df is None:
        return []
    t = times(df)
    gid_cols = sorted((c for c in df.columns if str(c).startswith("info.client_gid[")),
                      key=lambda c: int(str(c)[len("info.client_gid["):-1]))
    seq = df["info.sequence_number"].to_numpy() if "info.sequence_number" in df.columns else np.arange(len(df))
    driver = provenance.driver_participants(frames)
    out: dict[tuple, dict[str, Any]] = {}
    for i in range(len(df)):
        gid = tuple(int(v) if v == v else -1 for v in (df[c].iloc[i] for c in gid_cols))
        call = out.setdefault((gid, seq[i]), {"t": float(t[i]), "request_name": None, "response_name": None,
                                              "gid": gid})
        for key, col in (("request_name", "request[0].name"), ("response_name", "response[0].name")):
            value = df[col].iloc[i] if col in df.columns else None
            if isinstance(value, str) and call[key] is None and _present(df, i, col.split("[", 1)[0]):
                call[key] = value
    for call in out.values():
        gid = call["gid"]
        call["by"] = (provenance.UNKNOWN if driver is None or len(gid) < GUID_PREFIX_BYTES else
                      provenance.GRADER if gid[:GUID_PREFIX_BYTES] in driver else provenance.STUDENT)
    return sorted(out.values(), key=lambda c: c["t"])


def _present(df: pd.DataFrame, i: int, part: str) -> bool:
    """The event at row ``i`` carries its ``request``/``response`` (each event has only one)."""
    col = f"{part}.len"
    return col not in df.columns or int(df[col].iloc[i] or 0) > 0


#: the turtles' pose topics, which chase_catches, chase_follows and chase_short_way all take
ChaserPose = Annotated[str, Field(description="the chaser's (turtle2's) pose topic")]
TargetPose = Annotated[str, Field(description="the target's (turtle1's) pose topic")]
#: what a chaser that catches and keeps up does (the lab text's law)
_STEER = ("Steer toward turtle1: angular.z = K_w * e with e = atan2(dy, dx) - theta wrapped into [-pi, pi] and "
          "K_w > 0, and a speed that grows with the distance, linear.x = K_v * d.")


class ChaseCatchesParams(AnalyzerParams):
    steps: tuple[str, ...] = Field(description="the steps that each move turtle1 (and place turtle2)")
    chaser_pose: ChaserPose = "/turtle2/pose"
    target_pose: TargetPose = "/turtle1/pose"
    catch_m: float = Field(1.0, gt=0, description="m: caught: the turtles' centres this close")
    time_limit_s: float = Field(10.0, gt=0, description="s: time allowed to catch, after the release")
    still_m: float = Field(0.2, ge=0, description="m: turtle1 may drift this far while nobody drives it")


@register("chase_catches", timing="catching the turtle within the scenario's time", evidence={**EVIDENCE, "value": ("moves caught", "")},
          expect="turtle2 within {catch_m:g} m of turtle1 at most {time_limit_s:g} s after every move of turtle1",
          params=ChaseCatchesParams)
def chase_catches(frames: Frames, p: ChaseCatchesParams) -> Finding:
    """After each move of turtle1, turtle2 comes within ``catch_m`` within ``time_limit_s``."""
    if not p.steps:
        return Finding.error("chase_catches needs the ids of the steps that move turtle1 (steps: [...]).")
    pairs = _pairs(frames, p.chaser_pose, p.target_pose)
    if pairs is None:
        return _no_chaser(frames, p.chaser_pose)
    moved = _student_moves(frames, (p.chaser_pose, p.target_pose))
    rows: list[dict[str, Any]] = []
    series = []
    for k, step in enumerate(p.steps, 1):
        start, t0, end = _step_times(frames, step)
        row: dict[str, Any] = {"step": step, "ok": False}
        rows.append(row)
        if start is None:
            row["why"] = "the step did not run"
            continue
        t0 = t0 if t0 is not None else start
        end = end if end is not None else float(pairs["t"].iloc[-1])
        w = pairs[(pairs["t"] >= t0) & (pairs["t"] <= end)]
        if len(w) < 2:
            row["why"] = "no poses of both turtles during the step"
            continue
        held = pairs[(pairs["t"] >= start) & (pairs["t"] <= t0)]
        placed = held.iloc[-1] if not held.empty else w.iloc[0]     # before the first tick of the chase
        x1, y1 = float(placed["x1"]), float(placed["y1"])
        row.update(turtle1=[round(x1, 3), round(y1, 3)],
                   turtle2_start=[round(float(placed[c]), 3) for c in ("x2", "y2", "th2")],
                   closest_m=round(float(w["d"].min()), 3))
        series.append({"move": k, **_series(frames, w, t0)})
        during = provenance.within(moved, start, end)
        if during:
            row.update(why=provenance.moved_text(frames, during), teleported=len(during))
            continue
        hit = np.nonzero(w["d"].to_numpy(float) <= p.catch_m)[0]
        upto = w if not len(hit) else w.iloc[: hit[0] + 1]
        drift = float(np.hypot(upto["x1"] - x1, upto["y1"] - y1).max())
        row["turtle1_moved_m"] = round(drift, 3)
        if drift > p.still_m:
            row["why"] = (f"turtle1 moved {drift:.2f} m though the grader did not drive it: your node must drive "
                          f"turtle2 only")
            continue
        if not len(hit):
            row["why"] = (f"turtle2 came no closer than {row['closest_m']:.2f} m in "
                          f"{float(w['t'].iloc[-1]) - t0:.1f} s")
            continue
        caught = float(w["t"].iloc[hit[0]]) - t0
        row["caught_s"] = round(caught, 3)
        row["ok"] = caught <= p.time_limit_s
        if not row["ok"]:
            row["why"] = f"caught after {caught:.1f} s, more than {p.time_limit_s:g} s"
    good = sum(bool(r["ok"]) for r in rows)
    ev = {"moves": rows, "caught": good, "distance": series}
    if moved:
        ev["student_moves"] = [c.plain(frames) for c in moved[:10]]
    value = f"{good}/{len(rows)} moves"
    if good == len(rows):
        slowest = max(r["caught_s"] for r in rows)
        return Finding(value, 1.0, "pass", f"turtle2 caught turtle1 after every move (within {p.catch_m:g} m, "
                       f"{slowest:.1f} s at the slowest; {p.time_limit_s:g} s allowed).", ev)
    bad = [r for r in rows if not r["ok"]]
    first = bad[0]
    where = f" at ({first['turtle1'][0]:g}, {first['turtle1'][1]:g})" if "turtle1" in first else ""
    if any("drive turtle2 only" in str(r.get("why")) for r in bad):
        advice = (f" Publish your commands on /{provenance.turtle_of(p.chaser_pose)}/cmd_vel; "
                  f"{provenance.turtle_of(p.target_pose)} belongs to the grader.")
    elif all(r.get("teleported") for r in bad):
        advice = " Only velocity commands may move a turtle."
    else:
        advice = " " + _STEER
    return Finding(value, good / len(rows), "partial" if good else "fail",
                   f"turtle2 caught turtle1 within {p.catch_m:g} m and {p.time_limit_s:g} s after {good} of "
                   f"{len(rows)} moves; after move {rows.index(first) + 1} (turtle1{where}) {first['why']}." + advice,
                   ev)


class ChaseFollowsParams(AnalyzerParams):
    step: str = Field(description="the step during which the grader drives turtle1")
    chaser_pose: ChaserPose = "/turtle2/pose"
    target_pose: TargetPose = "/turtle1/pose"
    follow_m: float = Field(2.0, gt=0, description="m: distance to stay within")
    catch_up_s: float = Field(5.0, ge=0, description="s: time after the step starts that is not judged")
    min_share: float = Field(0.85, ge=0, le=1, description="share: of the judged poses within follow_m "
                                                           "(chase.yaml: why)")
    min_drive_m: float = Field(1.0, ge=0, description="m: turtle1 must have been driven this far for the check "
                                                      "to mean anything")


@register("chase_follows", evidence={**EVIDENCE, "value": ("time within reach", "")},
          expect="turtle2 within {follow_m:g} m of turtle1 for {min_share:.0%} of the drive after {catch_up_s:g} s",
          params=ChaseFollowsParams)
def chase_follows(frames: Frames, p: ChaseFollowsParams) -> Finding:
    """While the grader drives turtle1, turtle2 keeps within ``follow_m`` of it."""
    pairs = _pairs(frames, p.chaser_pose, p.target_pose)
    if pairs is None:
        return _no_chaser(frames, p.chaser_pose)
    start, _, end = _step_times(frames, p.step)
    if start is None:
        return Finding.error(f"The step {p.step!r} that drives turtle1 did not run; nothing to judge.")
    end = end if end is not None else float(pairs["t"].iloc[-1])
    w = pairs[(pairs["t"] >= start) & (pairs["t"] <= end)]
    judged = w[w["t"] >= start + p.catch_up_s]
    ev: dict[str, Any] = {"distance": [_series(frames, w, start)]}
    if len(judged) < 10:
        return Finding.error(f"Too few poses of both turtles during {p.step!r} to judge the chase.", ev)
    driven = float(np.hypot(np.diff(w["x1"]), np.diff(w["y1"])).sum())
    ev["driven_m"] = round(driven, 3)
    if driven < p.min_drive_m:
        return Finding.error(f"turtle1 moved only {driven:.2f} m during {p.step!r}: the grader's drive did not "
                             "happen, so following could not be judged.", ev)
    moved = provenance.within(_student_moves(frames, (p.chaser_pose, p.target_pose)), start, end)
    if moved:
        ev["student_moves"] = [c.plain(frames) for c in moved[:10]]
        return provenance.moved_finding(frames, moved, "following turtle1")
    d = judged["d"].to_numpy(float)
    share = float(np.mean(d <= p.follow_m))
    chased = float(np.hypot(np.diff(w["x2"]), np.diff(w["y2"])).sum())
    ev.update(share=round(share, 4), max_m=round(float(d.max()), 3), mean_m=round(float(d.mean()), 3),
              chased_m=round(chased, 3),
              judged_s=round(float(judged["t"].iloc[-1] - judged["t"].iloc[0]), 2))
    value = f"{share:.0%} within {p.follow_m:g} m"
    if share >= p.min_share:
        return Finding(value, 1.0, "pass", f"While turtle1 drove {driven:.1f} m, turtle2 stayed within "
                       f"{p.follow_m:g} m of it {share:.0%} of the time after {p.catch_up_s:g} s "
                       f"(at most {d.max():.2f} m away).", ev)
    if chased < p.min_drive_m:
        return Finding(value, 0.0, "fail", f"turtle2 moved only {chased:.2f} m while turtle1 drove {driven:.1f} m: "
                       f"no command reached it: publish your commands on /{provenance.turtle_of(p.chaser_pose)}/cmd_vel.",
                       ev)
    return Finding(value, 0.0, "fail", f"While turtle1 drove {driven:.1f} m, turtle2 was within {p.follow_m:g} m "
                   f"of it only {share:.0%} of the time after {p.catch_up_s:g} s (needs {p.min_share:.0%}; up to "
                   f"{d.max():.2f} m away, {d.mean():.2f} m on average). " + _STEER, ev)


class ChaseShortWayParams(AnalyzerParams):
    steps: tuple[str, ...] = Field(description="the steps that each move turtle1 and place turtle2")
    chaser_pose: ChaserPose = "/turtle2/pose"
    target_pose: TargetPose = "/turtle1/pose"
    cmd_topic: str = Field("/turtle2/cmd_vel", description="the chaser's command topic")
    min_turn_deg: float = Field(90.0, ge=0, le=180, description="deg: moves needing at least this turn are judged")
    wrap_turn_deg: float = Field(10.0, ge=0, le=180, description="deg: ... and those where wrapping changes the "
                                                                 "turn, from this turn on")
    ambiguous_deg: float = Field(10.0, ge=0, le=180, description="deg: within this of 180° either way is the "
                                                                 "short way")


@register("chase_short_way", evidence={**EVIDENCE, "value": ("turned the short way", "")},
          expect="turtle2 turning toward turtle1 the short way (at most 180°) after every move that needs a turn of "
                 "{min_turn_deg:g}° or more, or where an unwrapped heading error would turn the long way",
          params=ChaseShortWayParams)
def chase_short_way(frames: Frames, p: ChaseShortWayParams) -> Finding:
    """Did turtle2 start turning toward turtle1 the short way? Judged, as ``turn_direction`` judges
    a goal, from the sign of angular.z of the last command the node sent before the release: the
    turtles are held still from the placement until the node has answered the new poses, so that
    command was computed from the placement, the same in every run."""
    pairs = _pairs(frames, p.chaser_pose, p.target_pose)
    if pairs is None:
        return _no_chaser(frames, p.chaser_pose)
    cmd = topic(frames, p.cmd_topic)
    if cmd is not None and "angular.z" in cmd.columns:
        ct = cmd["pub_t"].to_numpy(float) if "pub_t" in cmd.columns else times(cmd)
        ct = np.where(np.isfinite(ct), ct, times(cmd))
        w = cmd["angular.z"].to_numpy(float)
    else:
        ct, w = np.array([]), np.array([])
    moved = _student_moves(frames, (p.chaser_pose, p.target_pose))
    rows: list[dict[str, Any]] = []
    for step in p.steps:
        start, released, end = _step_times(frames, step)
        if start is None or released is None:
            continue
        # the placement: the last pose of the hold (the first one after the release has moved a tick)
        held = pairs[(pairs["t"] >= start) & (pairs["t"] <= released)]
        at = held if not held.empty else pairs[pairs["t"] > released]
        if at.empty:
            continue
        r = at.iloc[-1] if not held.empty else at.iloc[0]
        bearing = math.atan2(r["y1"] - r["y2"], r["x1"] - r["x2"])
        naive = bearing - float(r["th2"])
        req = math.atan2(math.sin(naive), math.cos(naive))
        wrap_matters = abs(naive - req) > 1.0
        row: dict[str, Any] = {"step": step, "turtle1": [round(float(r["x1"]), 3), round(float(r["y1"]), 3)],
                               "turtle2_start": [round(float(r[c]), 3) for c in ("x2", "y2", "th2")],
                               "required_turn_deg": round(math.degrees(req), 1),
                               "naive_turn_deg": round(math.degrees(naive), 1)}
        if not (abs(req) >= math.radians(p.min_turn_deg)
                or (wrap_matters and abs(req) >= math.radians(p.wrap_turn_deg))):
            continue
        rows.append(row)
        during = provenance.within(moved, start, end if end is not None else math.inf)
        if during:
            row.update(ok=False, why=provenance.moved_text(frames, during))
            continue
        turning = np.abs(w) > 1e-3
        before = np.nonzero(turning & (ct > start) & (ct <= released))[0]
        after = np.nonzero(turning & (ct > released) & (ct <= (end if end is not None else math.inf)))[0]
        pick = before[-1] if len(before) else after[0] if len(after) else None
        if pick is None:
            row.update(ok=False, why=f"turtle2 got no turning command on {p.cmd_topic}")
            continue
        row["angular_z"] = round(float(w[pick]), 4)
        ambiguous = abs(req) >= math.pi - math.radians(p.ambiguous_deg)
        row["ok"] = bool(ambiguous or np.sign(w[pick]) == np.sign(req))
        if not row["ok"]:
            side = "left" if req > 0 else "right"
            row["why"] = (f"turtle1 was {abs(math.degrees(req)):.0f}° to the {side}, and the node turned the other "
                          f"way (angular.z = {w[pick]:.2f})")
    if not rows:
        return Finding.error(f"No move in steps {list(p.steps)} needed a large turn or a wrapped heading error; "
                             "nothing to judge (rubric problem).")
    good = sum(bool(r["ok"]) for r in rows)
    ev = {"moves": rows}
    value = f"{good}/{len(rows)} moves"
    if good == len(rows):
        return Finding(value, 1.0, "pass", f"turtle2 turned toward turtle1 the short way at each of the {len(rows)} "
                       "moves that test it.", ev)
    first = next(r for r in rows if not r["ok"])
    advice = (f"Publish the commands on {p.cmd_topic}." if "no turning command" in first["why"] else
              "angular.z must have the sign of the heading error atan2(dy, dx) - theta wrapped into [-pi, pi] "
              "(atan2(sin e, cos e)): positive turns left.")
    return Finding(value, good / len(rows), "partial" if good else "fail",
                   f"turtle2 turned the short way at {good} of {len(rows)} moves; at {first['step']}, {first['why']}. "
                   + advice, ev)


# ------------------------------------------------------------------------------------- figure
def _curves(evidence: Any) -> list[tuple[str, list[float], list[float]]]:
    """The distance series of the evidence as (label, t, d); [] for anything malformed."""
    out = []
    for k, s in enumerate(evidence if isinstance(evidence, list) else [], 1):
        t, d = (s.get("t"), s.get("d")) if isinstance(s, dict) else (None, None)
        if (isinstance(t, list) and isinstance(d, list) and len(t) == len(d) > 1
                and all(isinstance(v, (int, float)) for v in t + d)):
            out.append((f"move {s.get('move', k)}" if "move" in s else "during the drive", t, d))
    return out


@figure("chase_catches", "chase_follows")
def chase_distance(ctx: FigureContext) -> Plot | None:
    """turtle2's distance to turtle1 over time, with the distance and time the lab asks for."""
    curves = _curves(ctx.evidence.get("distance"))
    if not curves:
        return None
    catches = ctx.item.analyzer == "chase_catches"
    limit = ctx.param("catch_m" if catches else "follow_m")
    when = ctx.param("time_limit_s" if catches else "catch_up_s")
    if not isinstance(limit, (int, float)) or not isinstance(when, (int, float)):
        return None
    title = (f"After each jump of turtle1 the distance should fall below {limit:g} m within {when:g} s" if catches
             else f"After {when:g} s the distance should stay below {limit:g} m")
    fig, ax = ctx.axes(title, size=(6.4, 3.6))
    for label, t, d in curves:
        ax.plot(t, d, label=label)
    ax.axhline(limit, color="0.3", linestyle="--", label=f"{limit:g} m")
    ax.axvline(when, color="0.6", linestyle=":", label=f"{when:g} s")
    ax.set(xlabel="time since the release (s)" if catches else "time since the drive began (s)",
           ylabel="distance turtle2 to turtle1 (m)")
    ax.legend(loc="upper right")
    closest = ", ".join(f"{label}: {min(d):.2f} m" for label, _t, d in curves)
    return Plot(fig, title, alt=f"Distance from turtle2 to turtle1 over time; closest approach {closest}; "
                f"limit {limit:g} m, time {when:g} s.")
