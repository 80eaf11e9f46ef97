"""Exercise 2 goal publisher: stdin lines "x,y" become Float32MultiArray [x, y] on /turtle1/goal.

The driver types (see ``stdin_line`` events) ``2.0,7.0``, a malformed line, then ``8.0,3.0``.
The expected goals are taken from the well-formed stdin lines actually sent (falling back to the
``expected`` parameter when the scenario recorded no stdin events), so the analyzer follows the
scenario rather than hard-coding it.
"""

from __future__ import annotations

import math
import re
from typing import Any, cast

import numpy as np
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, register
from grader.analyze.evidence import SHARE, TIME
from grader.analyze._common import (Frames, events, missing_topic_feedback, own_exits, stdout_lines, times,
                                    topic)
from grader.contracts.events import ProcessExit, StdinLine


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


def _stdin(frames: Frames, process: str | None) -> tuple[str | None, list[StdinLine]]:
    """stdin_line events of the goal publisher process (given, or the only/first one typed to)."""
    ev = events(frames, StdinLine)
    procs = []
    for e in ev:
        if e.process not in procs:
            procs.append(e.process)
    if process is None:
        pick = [q for q in procs if q and "goal" in str(q).lower()]
        process = pick[0] if pick else (procs[0] if procs else None)
    return process, [e for e in ev if e.process == process]


def _goal_msgs(frames: Frames, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    df = topic(frames, name)
    if df is None or "data[0]" not in df.columns:
        return None
    x = df["data[0]"].to_numpy(float)
    y = df["data[1]"].to_numpy(float) if "data[1]" in df.columns else np.full(len(df), np.nan)
    n = df["data.len"].to_numpy(float) if "data.len" in df.columns else np.where(np.isfinite(y), 2.0, 1.0)
    return times(df), x, y, n


#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "goal_topic": ('goal topic', ''),
    "tol": ('allowed difference', ''),
    "partial_credit": ('credit for partly right', SHARE),
    "expected": ("goals typed [x, y]", "m"),
    "published": ("goals published [x, y]", "m"),
    "n_published": ("messages published", ""),
    "found_in_order": ("typed goals published in order", ""),
    "latency_s": ("delay from typing to publishing", "s"),
    "lengths_seen": ("numbers of values per message seen", ""),
    "malformed_line": ("malformed line typed", ""),
    "t_malformed": ("typed at", TIME),
    "exit_events": ("process exits", ""),
    "after_malformed": ("typed after a malformed line that stopped the node", ""),
    "returncode": ("exit code", ""),
    "traceback_lines": ("error output", ""),
    "undelivered_lines": ("lines that could not be typed (process gone)", ""),
    "later_goal_published": ("a later goal was still published", ""),
}


class GoalTopicParams(AnalyzerParams):
    """What ``goal_publisher`` and ``goal_publisher_robust`` share: where the goals go, which process."""

    goal_topic: str = Field("/turtle1/goal", description="topic the goal publisher publishes on")
    process: str | None = Field(None, description="runner process name of the goal publisher; None = detect")


class GoalPublisherParams(GoalTopicParams):
    expected: tuple[tuple[float, float], ...] = Field(
        ((2.0, 7.0), (8.0, 3.0)), description="m: goals [x, y] expected, used only when no stdin_line events "
                                              "were recorded")
    tol: float = Field(1e-3, ge=0, description="m: allowed difference between a typed and a published coordinate")
    partial_credit: float = Field(0.5, ge=0, le=1, description="credit when only the first goal appeared (in order)")


@register("goal_publisher", evidence={**EVIDENCE, "value": ("typed goals published", "")},
          expect="each typed line x,y published as [x, y] on {goal_topic}", params=GoalPublisherParams)
def goal_publisher(frames: Frames, p: GoalPublisherParams) -> Finding:
    """The typed goals appear on /turtle1/goal as [x, y], in the order they were typed."""
    proc, lines = _stdin(frames, p.process)
    expected: list[dict[str, Any]] = []
    for e in lines:
        xy = parse_xy_line(e.line)
        if xy is not None and e.delivered:
            expected.append({"x": xy[0], "y": xy[1], "t": e.t, "line": e.line})
    if not expected:
        expected = [{"x": float(a), "y": float(b), "t": -np.inf, "line": f"{a},{b}"} for a, b in p.expected]
    msgs = _goal_msgs(frames, p.goal_topic)
    ev: dict = {"process": proc}
    # goals typed after a malformed line the node did not survive are goal_publisher_robust's
    # business: whether the next line still reached the dying process is a matter of a few
    # milliseconds (bench_flake: 1 of 2 goals in one run of three, 1 of 1 in the others)
    bad = [e for e in lines if parse_xy_line(e.line) is None]
    if bad and _stopped_by(frames, proc, bad[0], p):
        after = [g for g in expected if g["t"] > bad[0].t]
        if after:
            expected = [g for g in expected if g["t"] <= bad[0].t]
            ev["after_malformed"] = {"line": bad[0].line, "not_counted": [g["line"] for g in after]}
    ev["expected"] = [[g["x"], g["y"]] for g in expected]
    if msgs is None:
        return Finding.fail(missing_topic_feedback(frames, p.goal_topic, "std_msgs/msg/Float32MultiArray [x, y]")
                            + " Publish each typed goal with your node's send_goal(x, y).", ev)
    t, x, y, n = msgs
    ev["published"] = [[float(a), float(b)] for a, b in zip(x[:10], y[:10])]
    ev["n_published"] = int(len(t))
    k = 0
    latencies = []
    for ti, xi, yi in zip(t, x, y):
        if k >= len(expected):
            break
        g = expected[k]
        if ti >= g["t"] - 0.05 and abs(xi - g["x"]) <= p.tol and abs(yi - g["y"]) <= p.tol:
            latencies.append(float(ti - g["t"]) if np.isfinite(g["t"]) else None)
            k += 1
    ev.update({"found_in_order": k, "latency_s": latencies,
               "lengths_seen": sorted({int(v) for v in n[np.isfinite(n)]})})
    value = f"{k}/{len(expected)} goals"
    extra = ""
    if len(ev["lengths_seen"]) and ev["lengths_seen"] != [2]:
        extra = f" Messages had {ev['lengths_seen']} values; publish exactly [x, y]."
    if "after_malformed" in ev:
        extra += (f" (The node stopped on the malformed line '{ev['after_malformed']['line']}': the goals typed "
                  "after it count in the robustness item, not here.)")
    if k == len(expected):
        return Finding(value, 1.0, "pass",
                       f"All {k} typed goals were published on {p.goal_topic} in order.{extra}", ev)
    missing = expected[k]
    swapped = any(abs(xi - missing["y"]) <= p.tol and abs(yi - missing["x"]) <= p.tol for xi, yi in zip(x, y))
    if swapped:
        hint = f" A message [{missing['y']:g}, {missing['x']:g}] was seen: x and y are swapped; publish data = [x, y]."
    else:
        hint = (f" Goal [{missing['x']:g}, {missing['y']:g}] (typed as '{missing['line']}') never appeared; "
                "after input() parse both floats, call send_goal(x, y), and spin_once so it is sent.")
    if k >= 1:
        return Finding(value, p.partial_credit, "partial",
                       f"Only {k} of {len(expected)} typed goals were published.{hint}{extra}", ev)
    return Finding(value, 0.0, "fail", f"None of the typed goals were published correctly.{hint}{extra}", ev)


_TRACEBACK = re.compile(r"^\s*(Traceback \(most recent call last\)|\w+(Error|Exception)\b.*)")


def _exits_and_traceback(frames: Frames, proc: str | None, bad: StdinLine) -> tuple[list[ProcessExit], list[str]]:
    """The process's own exits (not the grader's stopping it) from the malformed line ``bad`` on,
    and the traceback lines it printed from then."""
    exits = [e for e in own_exits(frames) if e.process == proc and e.t >= bad.t]
    out = stdout_lines(frames)
    tb: list[str] = []
    if len(out):
        mine = out[(out["process"] == str(proc)) & (out["time"] >= bad.t - 0.05)]
        tb = [s for s in mine["raw"].tolist() if _TRACEBACK.match(s)]
    return exits, tb


def _stopped_by(frames: Frames, proc: str | None, bad: StdinLine, p: GoalTopicParams) -> bool:
    """The process stopped on its own after the malformed line ``bad`` (an exit with an error,
    or a traceback in its output) and published none of the goals typed after it. Timing-free:
    when the exit came (before or after the next line was typed) does not matter."""
    exits, tb = _exits_and_traceback(frames, proc, bad)
    if not (tb or any(e.returncode not in (0, None) for e in exits)):
        return False
    msgs = _goal_msgs(frames, p.goal_topic)
    return msgs is None or not bool(np.any(msgs[0] > bad.t))


class GoalPublisherRobustParams(GoalTopicParams):
    tol: float = Field(1e-3, ge=0, description="m: allowed difference between a typed and a published coordinate")


@register("goal_publisher_robust", evidence={**EVIDENCE, "value": ("after a malformed line", "")},
          expect="the node prints an error and keeps reading goals", params=GoalPublisherRobustParams)
def goal_publisher_robust(frames: Frames, p: GoalPublisherRobustParams) -> Finding:
    """The goal publisher survives a malformed line ("Wrong data format!") and keeps working.

    Evidence, strongest first: a process_exit event after the malformed line and before the next
    typed line (crash), a Python traceback in its output after the malformed line (crash), a goal
    typed after the malformed line appearing on the topic (survived).
    """
    proc, lines = _stdin(frames, p.process)
    if not lines:
        return Finding.error("The scenario recorded no stdin_line events, so robustness to a malformed line "
                             "could not be tested.")
    bad = [e for e in lines if parse_xy_line(e.line) is None]
    if not bad:
        return Finding.error("The scenario typed no malformed line, so robustness could not be tested.",
                             {"process": proc})
    b = bad[0]
    later = [e for e in lines if e.t > b.t]
    next_t = later[0].t if later else np.inf
    ev: dict = {"process": proc, "malformed_line": b.line, "t_malformed": b.t}
    exits, tb = _exits_and_traceback(frames, proc, b)
    crash_exit = [e for e in exits if e.t < next_t + 0.5]
    undelivered = [e for e in later if not e.delivered]
    ev.update({"exit_events": [{"t": e.t, "returncode": e.returncode} for e in exits],
               "traceback_lines": tb[:6], "undelivered_lines": [e.line for e in undelivered]})
    good_later = [parse_xy_line(e.line) for e in later]
    good_later = [g for g in good_later if g is not None]
    survived = False
    msgs = _goal_msgs(frames, p.goal_topic)
    if msgs is not None and good_later:
        t, x, y, _ = msgs
        gx, gy = cast(tuple, good_later[0])          # (Nones filtered out above)
        survived = bool(np.any((t > b.t) & (np.abs(x - gx) <= p.tol) & (np.abs(y - gy) <= p.tol)))
    ev["later_goal_published"] = survived
    if crash_exit or undelivered or (tb and not survived):
        if tb:
            exc = tb[-1].strip()
        elif crash_exit:
            exc = f"exit code {crash_exit[0].returncode}"
        else:
            exc = "the process had exited when the next line was typed"
        return Finding("crashed", 0.0, "fail",
                       f"Your goal publisher crashed on the malformed line '{b.line}' ({exc}). "
                       "Do the split and float conversion inside try/except (e.g. catch ValueError) and "
                       "print \"Wrong data format!\".", ev)
    if survived or not good_later:
        return Finding("survived", 1.0, "pass",
                       f"Your goal publisher handled the malformed line '{b.line}' and kept working.", ev)
    return Finding("unclear", 0.0, "fail",
                   f"After the malformed line '{b.line}' the next typed goal was never published: make "
                   "sure a bad line is rejected and the loop keeps reading input.", ev)
