"""Exercise 3: the action server's control loop is paced (``self.rate.sleep()``), not a busy loop.

The lab's execute_callback "runs at a constant frequency determined by the parameter
controller_rate" (30 Hz in the template): one velocity command per iteration, then
``self.rate.sleep()``. Without the sleep the loop still steers the turtle to every goal, so the
goal items cannot see it (grader rubric audit: the mutant without ``self.rate.sleep()`` kept
50/50), but it publishes as fast as Python can (thousands of commands a second) and takes a
whole CPU core for as long as a goal runs.

Measured on the commands the server published while each accepted goal ran (from the goal to
its result): the count over the time. The bounds are wide on purpose: the rate is the student's
parameter (a default of 15 or 60 Hz is theirs to choose), so only a loop far above any rate a
parameter would set, or one that hardly publishes at all, loses the item.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from grader.analyze import AnalyzerParams, Finding, register
from grader.analyze._common import Frames, times, topic
from grader.analyze.action_goals import action_goals, under_other_action_name

EVIDENCE = {
    "cmd_topic": ("velocity command topic", ""),
    "max_hz": ("fastest paced loop accepted", "Hz"),
    "min_hz": ("slowest loop accepted", "Hz"),
    "min_duration_s": ("goals shorter than this are not measured", "s"),
    "goals": ("goals measured", ""),
    "goal": ("goal (x, y)", "m"),
    "duration_s": ("time from goal to result", "s"),
    "commands": ("commands published meanwhile", ""),
    "rate_hz": ("commands per second", "Hz"),
}


class ActionLoopPacedParams(AnalyzerParams):
    cmd_topic: str = Field("/turtle1/cmd_vel", description="topic of the server's velocity commands")
    max_hz: float = Field(200.0, gt=0, description="Hz: fastest paced loop accepted (the template's 30 Hz, a "
                                                   "parameter of 60 or 120 Hz: all well below)")
    min_hz: float = Field(5.0, ge=0, description="Hz: slowest loop accepted (a loop that steers at all publishes "
                                                 "more often than this)")
    min_duration_s: float = Field(1.0, gt=0, description="s: a goal answered faster has too few commands to count")


@register("action_loop_paced", timing="the control loop's pacing", evidence={**EVIDENCE, "value": ("commands per second while goals ran", "Hz")},
          expect="between {min_hz:g} and {max_hz:g} velocity commands a second while a goal runs",
          params=ActionLoopPacedParams)
def action_loop_paced(frames: Frames, p: ActionLoopPacedParams) -> Finding:
    """Commands per second while accepted goals ran, within [min_hz, max_hz]."""
    return under_other_action_name(frames, _action_loop_paced(frames, p))


def _action_loop_paced(frames: Frames, p: ActionLoopPacedParams) -> Finding:
    gs = [g for g in action_goals(frames) if g["accepted"] and g["t_result"] is not None
          and g["t_result"] - g["t_sent"] >= p.min_duration_s]
    if not gs:
        return Finding.fail("No accepted goal ran long enough to see the control loop "
                            f"(at least {p.min_duration_s:g} s from goal to result).", {})
    df = topic(frames, p.cmd_topic)
    t = np.sort(times(df)) if df is not None else np.array([])
    rows, n_all, d_all = [], 0, 0.0
    for g in gs:
        n = int(np.searchsorted(t, g["t_result"], side="right") - np.searchsorted(t, g["t_sent"], side="right"))
        d = float(g["t_result"] - g["t_sent"])
        rows.append({"goal": [g["x"], g["y"]], "duration_s": round(d, 3), "commands": n,
                     "rate_hz": round(n / d, 2)})
        n_all += n
        d_all += d
    rate = n_all / d_all
    ev = {"goals": rows, "rate_hz": round(rate, 2)}
    if rate > p.max_hz:
        return Finding(round(rate, 1), 0.0, "fail",
                       f"While its goals ran the server published {n_all} commands in {d_all:.1f} s "
                       f"({rate:.0f} a second): the loop is not paced. Call self.rate.sleep() once per "
                       "iteration, so that it runs at controller_rate.", ev)
    if rate < p.min_hz:
        return Finding(round(rate, 1), 0.0, "fail",
                       f"While its goals ran the server published {n_all} commands on {p.cmd_topic} "
                       f"in {d_all:.1f} s: publish one Twist per loop iteration.", ev)
    return Finding(round(rate, 1), 1.0, "pass",
                   f"The loop published {rate:.0f} commands a second while its goals ran.", ev)
