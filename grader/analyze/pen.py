"""The pen: ``set_pen`` calls where the turtle crosses a line, and the colours on the canvas.

* ``pen_on_crossings``: the simulator runs its services with introspection, so every
  ``/turtle1/set_pen`` request is in the bag (``_service_event``). Crossings of ``x = split_x``
  are read off the simulator's poses; each crossing must be followed, within ``max_delay_s`` (a
  few 16 ms pose periods), by exactly one call with that direction's colour, and there must be
  no other calls, but one: before the first crossing, a node may set the pen to the colour of
  the side the turtle is on (``start_calls``). The lab text's own node does this (its
  ``previous_x_`` starts at 0, so the first pose, at x = 5.54, reads as a rightward crossing and
  sets blue), and so does a node that sets its initial state on purpose; either way the trail is
  the right colour from the start, which is what the lab asks for. Only the side the turtle is on
  when the call reaches the simulator counts (the latest simulator pose before the call, or the
  first pose when the call comes earlier), so a wrong start colour is still a call not at a
  crossing.
  A run in which student code moved the turtle without driving it (:mod:`grader.analyze.provenance`)
  earns nothing: its crossings were not driven.
* ``canvas_colours``: the canvas the simulator saved at the end (``canvas.png`` beside the bag,
  loaded as the ``__canvas__`` frame: one row per drawn pixel) shows each colour on its side.
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, graded, provenance, register
from grader.analyze.evidence import SHARE, SINCE_START
from grader.analyze._common import (sim_pose, Frames, missing_topic_feedback, scenario_end_time, service_calls,
                                    thin, times, topic)

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    **provenance.EVIDENCE,
    "crossings": ("crossings of the line", ""), "direction": ("direction", ""), "wanted": ("colour wanted (r, g, b)", ""),
    "ok": ("as expected", ""), "why": ("problem", ""), "delay_s": ("call after the crossing", "s"),
    "color": ("colour set (r, g, b)", ""), "width": ("pen width", ""), "extra_calls": ("calls not at a crossing", ""),
    "calls": ("set_pen calls", ""), "split_x": ("line x", "m"), "sides": ("colours by side", ""),
    "pixels": ("pixels", ""), "on_its_side": ("pixels on its side", ""), "share": ("share on its side", SHARE),
    "drawn_pixels": ("pixels drawn", ""), "right_color": ("colour right of the line", ""),
    "left_color": ("colour left of the line", ""), "max_delay_s": ("time allowed after a crossing", "s"),
    "min_pixels": ("pixels needed per colour", ""), "min_share": ("share needed on its side", SHARE),
    "t": ("time", SINCE_START), "service": ("service", ""), "pose_topic": ("pose topic", ""),
    "y": ("at y", "m"), "path": None, "share_by_direction": ("share right per direction", SHARE),
    "min_credit": ("credit below which nothing is earned", SHARE),
    "start_calls": ("calls before the first crossing that may set the colour of the side the turtle is on", ""),
    "start_call": ("call before the first crossing, with the colour of the side the turtle was on", ""),
    "side": ("side of the line", ""),
}

CANVAS = "__canvas__"

#: one channel of a pen colour (turtlesim's SetPen r, g, b are uint8)
Channel = Annotated[int, Field(ge=0, le=255)]
Colour = tuple[Channel, Channel, Channel]


class PenParams(AnalyzerParams):
    """The line the pen colour changes at, and the colour of each side."""

    pose_topic: str = Field("/turtle1/pose", description="the simulator's pose topic")
    split_x: float = Field(5.5, description="m: the line the pen colour changes at")
    right_color: Colour = Field((0, 0, 255), description="r, g, b set when crossing to the right (x grows)")
    left_color: Colour = Field((0, 255, 0), description="r, g, b set when crossing to the left")


def crossings(t: np.ndarray, x: np.ndarray, split: float, y: np.ndarray | None = None) -> list[dict[str, Any]]:
    """Times, directions (and heights) at which ``x`` crosses ``split``."""
    out = []
    for i in np.nonzero((x[:-1] <= split) != (x[1:] <= split))[0]:
        row = {"t": float(t[i + 1]), "direction": "right" if x[i + 1] > split else "left"}
        if y is not None:
            row["y"] = float(y[i + 1])
        out.append(row)
    return out


def _color(request: dict) -> list[int] | None:
    try:
        return [int(request["r"]), int(request["g"]), int(request["b"])]
    except (KeyError, TypeError, ValueError):
        return None


def _start_calls(calls: list[dict], used: list[bool], t_pose: np.ndarray, x_pose: np.ndarray,
                 cross: list[dict], want: dict[str, list[int]], p: PenOnCrossingsParams) -> list[dict]:
    """The first ``start_calls`` calls before the first crossing's window that set the pen as
    wanted for the side the turtle was on when the call arrived (marked used, so they are not
    extra). Setting the right colour for where the turtle is, is what the lab asks for at every
    moment, including before the turtle has crossed anything."""
    if not cross or not len(t_pose):
        return []
    before = cross[0]["t"] - 0.05            # the first crossing's window opens here (see the matcher)
    out: list[dict] = []
    for i, call in enumerate(calls):
        if len(out) >= p.start_calls or call["t"] >= before:
            break
        k = max(int(np.searchsorted(t_pose, call["t"], side="right")) - 1, 0)
        side = "right" if x_pose[k] > p.split_x else "left"
        if call["color"] != want[side] or (p.width is not None and call["width"] != p.width) or call["off"]:
            break                            # a wrong first call: it stays a call not at a crossing
        used[i] = True
        out.append({"t": call["t"], "color": call["color"], "side": side})
    return out


class PenOnCrossingsParams(PenParams):
    service: str = Field("/turtle1/set_pen", description="the simulator's set_pen service")
    width: int | None = Field(3, ge=0, description="pen width the calls must set (None: any)")
    max_delay_s: float = Field(0.1, ge=0, description="s: from the crossing pose to the call reaching the simulator")
    start_calls: int = Field(1, ge=0, description="calls before the first crossing accepted when they set the "
                                                  "colour of the side the turtle is on (the initial state)")
    # a node calling set_pen on (nearly) every pose, 1100-1270 calls for 2-18 crossings, got 0.01 or
    # 0.02 of 7 points by its call count (bench_flake, issue 22)
    min_credit: float = Field(0.05, ge=0, le=1, description="less credit than this earns nothing")


@register("pen_on_crossings", evidence={**EVIDENCE, "value": ('crossings with the right call', '')},
          expect="one set_pen call per crossing of x = {split_x:g}, with that side's colour, and no other "
                 "(up to {start_calls} before the first crossing may set the colour of the side the turtle is on)",
          params=PenOnCrossingsParams)
def pen_on_crossings(frames: Frames, p: PenOnCrossingsParams) -> Finding:
    moved = provenance.moves(frames, p.pose_topic)
    if moved:
        return provenance.moved_finding(frames, moved, "each crossing")
    pose = sim_pose(frames, p.pose_topic)
    if pose is None or "x" not in pose.columns:
        return Finding.error(missing_topic_feedback(frames, p.pose_topic, "published by the simulator"))
    t0 = float(times(pose)[0])
    x_all = pose["x"].to_numpy(float)
    y_all = pose["y"].to_numpy(float) if "y" in pose.columns else None
    cross = crossings(times(pose), x_all, p.split_x, y_all)
    # after the scenario's end the student's node is being stopped while the turtle coasts on:
    # crossings then cannot be answered and do not count
    end = scenario_end_time(frames)
    cross = [c for c in cross if not (end == end and c["t"] > end - p.max_delay_s)]
    df = topic(frames, f"{p.service}/_service_event")
    calls = [{"t": c["t"], "color": _color(c["request"]), "width": c["request"].get("width"),
              "off": c["request"].get("off")} for c in (service_calls(df) if df is not None else [])]
    want = {"right": list(p.right_color), "left": list(p.left_color)}
    used = [False] * len(calls)
    starts = _start_calls(calls, used, times(pose), x_all, cross, want, p)
    rows = []
    for c in cross:
        k = next((i for i, call in enumerate(calls) if not used[i]
                  and c["t"] - 0.05 <= call["t"] <= c["t"] + p.max_delay_s), None)
        row = {"t": c["t"] - t0, "direction": c["direction"], "wanted": want[c["direction"]], "y": c.get("y")}
        if k is None:
            late = next((call for i, call in enumerate(calls) if not used[i] and call["t"] > c["t"]), None)
            row.update(ok=False, why="no set_pen call within "
                       f"{p.max_delay_s:g} s" + (f" (next call {late['t'] - c['t']:.2f} s later)" if late else ""))
        else:
            used[k] = True
            call = calls[k]
            good = call["color"] == want[c["direction"]] and (p.width is None or call["width"] == p.width) \
                and not call["off"]
            row.update(ok=good, delay_s=call["t"] - c["t"], color=call["color"], width=call["width"],
                       why=None if good else f"set {call['color']} width {call['width']}")
        rows.append(row)
    extra = [{"t": call["t"] - t0, "color": call["color"]} for i, call in enumerate(calls) if not used[i]]
    # nor can the calls that answer those crossings be judged (grader rubric audit: a crossing
    # 0.03 s before the end, left out above, and its call 5 ms later counted as a stray call)
    if end == end:
        extra = [e for e in extra if e["t"] + t0 < end - p.max_delay_s - 0.05]
    matched = sum(1 for r in rows if r["ok"])
    ev = {"crossings": rows[:40], "extra_calls": extra[:20], "calls": len(calls), "split_x": p.split_x}
    if starts:
        ev["start_call"] = [{**c, "t": c["t"] - t0} for c in starts]
    if y_all is not None:
        keep = thin(len(x_all), 600)
        ev["path"] = {"x": np.round(x_all[keep], 3).tolist(), "y": np.round(y_all[keep], 3).tolist()}
    if not cross:
        return Finding.fail(f"The turtle never crossed x = {p.split_x:g}, so the pen colour change could not "
                            "be checked.", ev, value="no crossings")
    shares = _direction_shares(rows)
    frac = _credit(shares, len(rows), len(extra))
    ev["share_by_direction"] = {d: round(v, 4) for d, v in shares.items()}
    value = f"{matched}/{len(rows)} crossings" + (f", {len(extra)} extra call(s)" if extra else "")
    if frac >= 1.0:
        times_ = "once" if len(starts) == 1 else f"{len(starts)} times"
        start = f" (and {times_} before the first crossing, with the colour of the side the turtle was on)" \
            if starts else ""
        return Finding(value, 1.0, "pass", f"set_pen was called with the right colour at each of the "
                       f"{len(rows)} crossings of x = {p.split_x:g}, and only then{start}.", ev)
    if frac < p.min_credit:
        frac = 0.0
    problems = []
    bad = [r for r in rows if not r["ok"]]
    if bad:
        r = bad[0]
        problems.append(f"{len(bad)} of {len(rows)} crossings went wrong (first at t = {r['t']:.1f} s going "
                        f"{r['direction']}: {r['why']}, wanted {r['wanted']})")
    if extra:
        problems.append(f"{len(extra)} set_pen call(s) not at a crossing (first at t = {extra[0]['t']:.1f} s, "
                        f"colour {extra[0]['color']})")
    return Finding(value, frac, graded(frac), "; ".join(problems) + ".", ev)


def _direction_shares(rows: list[dict]) -> dict[str, float]:
    """Per direction the turtle crossed in, the share of its crossings answered right."""
    return {d: sum(r["ok"] for r in rs) / len(rs)
            for d in ("right", "left") if (rs := [r for r in rows if r["direction"] == d])}


def _credit(shares: dict[str, float], crossings: int, extra: int) -> float:
    """The share of crossings answered right, each direction weighing half (one direction only:
    all of it), times the share of calls that answered a crossing. A node that sets the wrong
    colour one way gets 0.5 however many crossings its path had: judged per crossing it got
    6/13, 7/14 or 5/11 in three runs of the same code (bench_flake, issue 22)."""
    if not shares:
        return 0.0
    return float(np.mean(list(shares.values()))) * crossings / (crossings + extra)


class CanvasColoursParams(PenParams):
    min_pixels: int = Field(50, ge=0, description="each colour must cover at least this many pixels")
    min_share: float = Field(0.95, ge=0, le=1, description="share of each colour's pixels on its own side")


@register("canvas_colours", evidence={**EVIDENCE, "value": ('colours on the canvas', '')},
          expect='{right_color} right and {left_color} left of x = {split_x:g}', params=CanvasColoursParams)
def canvas_colours(frames: Frames, p: CanvasColoursParams) -> Finding:
    canvas = frames.get(CANVAS)
    if not isinstance(canvas, pd.DataFrame) or not {"x_m", "r", "g", "b"} <= set(canvas.columns):
        return Finding.error("The simulator's canvas was not saved with this scenario (scenario problem).")
    rgb = canvas[["r", "g", "b"]].to_numpy(int)
    x = canvas["x_m"].to_numpy(float)
    rows: dict[str, dict[str, Any]] = {}
    ok = True
    for side, colour in (("right", p.right_color), ("left", p.left_color)):
        mask = np.all(rgb == np.asarray(colour, int), axis=1)
        n = int(mask.sum())
        on_side = int(((x > p.split_x) if side == "right" else (x <= p.split_x))[mask].sum())
        share = on_side / n if n else 0.0
        rows[side] = {"color": list(colour), "pixels": n, "on_its_side": on_side, "share": share}
        ok = ok and n >= p.min_pixels and share >= p.min_share
    ev = {"sides": rows, "split_x": p.split_x, "drawn_pixels": int(len(canvas))}
    value = ", ".join(f"{s}: {r['pixels']} px ({r['share']:.0%} on its side)" for s, r in rows.items())
    if ok:
        return Finding(value, 1.0, "pass", f"The canvas shows {list(p.right_color)} right of x = {p.split_x:g} "
                       f"and {list(p.left_color)} left of it.", ev)
    problems = []
    for side, r in rows.items():
        if r["pixels"] < p.min_pixels:
            problems.append(f"almost no {r['color']} on the canvas ({r['pixels']} px)")
        elif r["share"] < p.min_share:
            problems.append(f"only {r['share']:.0%} of the {r['color']} trail is on the {side} of x = {p.split_x:g}")
    frac = sum(1 for r in rows.values() if r["pixels"] >= p.min_pixels and r["share"] >= p.min_share) / 2
    return Finding(value, frac, graded(frac), "The canvas: " + "; ".join(problems) + ".", ev)
