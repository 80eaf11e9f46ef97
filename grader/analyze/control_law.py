"""ENEE 467 Lab 3, Exercise 2: the P-controller's law, v = K_1 d_e and w = K_2 theta_e (the lab's
eq. 2-3), estimated from the bag: each cmd_vel is paired with the latest pose recorded before it
and the active goal; linear.x ~ K1 d_e and angular.z ~ K2 theta_e are fitted by least squares
without intercept, and the fit with an unwrapped theta_e is compared to tell a missing wrap.
Lab 3's own analyzer (its gains and equation numbers are that lab's). Goals during which student
code moved the turtle without driving it (:mod:`grader.analyze.provenance`) are left out: their
poses were not reached by the commands being fitted.

Which pose a command was computed from is a matter of scheduling: the latest one recorded, or
the tick before when the controller's pose callback ran late. While the turtle turns slowly
both give nearly the same theta_e; while it spins (theta_e in degrees: up to 3 rad per tick) they
differ by radians, and the fit depended on the machine's load (issue 22's flake benchmark:
R² 0.94 at --jobs 2 and 4, 0.38 at --jobs 8, pass vs partial). So a command whose two candidate
poses differ by more than ``max_tick_turn`` in theta_e is left out of the angular fit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from pydantic import Field

from grader.analyze import Finding, graded, provenance, register
from grader.analyze._common import (Frames, events, fmt, missing_topic_feedback, sentence, since_start, thin, times,
                                    topic)
from grader.analyze.goals import fit_gain, heading_error
from grader.analyze.action_goals import under_other_action_name
from grader.analyze.controller import EVIDENCE, GoalParams, _goals_with_end, _no_goals, _no_pose, _pose
from grader.contracts.events import TurtlesReleased


class ControlLawParams(GoalParams):
    cmd_topic: str = Field("/turtle1/cmd_vel", description="topic of the controller's velocity commands")
    r2_min: float = Field(0.9, ge=0, le=1, description="both fits need at least this R^2 for full credit")
    min_d: float = Field(0.05, ge=0, description="m: rows closer to the goal are left out of the angular fit "
                                                  "(theta_e ill-defined)")
    skip_after_goal_s: float = Field(0.15, ge=0, description="s after a goal change during which the controller "
                                                             "may not know it yet")
    wrap_margin: float = Field(0.05, ge=0, description='R^2 gain of the unwrapped fit that counts as "better"')
    min_wrap_rows: int = Field(5, ge=1, description="rows where wrapping changes theta_e, needed to judge the wrap")
    use_pub_time: bool = Field(True, description="pair cmd_vel by its send time (pub_t) when recorded")
    min_rows: int = Field(20, ge=1, description="commands paired with a pose and a goal needed for the fit")
    max_tick_turn: float = Field(0.2, gt=0, description="rad: theta_e may differ this much between the two poses a "
                                                        "command may have been computed from (else it is left out "
                                                        "of the angular fit)")


@register("control_law", evidence={**EVIDENCE, "value": ("fitted control law", "")},
          expect="linear.x = K1·d_e and angular.z = K2·theta_e (wrapped) with K1, K2 > 0 and R² ≥ {r2_min:g}",
          params=ControlLawParams)
def control_law(frames: Frames, p: ControlLawParams) -> Finding:
    """Estimated K1, K2 and R^2 of v = K1 d_e, w = K2 theta_e; flags wrong signs and a missing wrap.

    Credit: half for the linear law (K1 > 0, R^2 >= r2_min), half for the angular law (K2 > 0,
    R^2 >= r2_min, theta_e wrapped). A right sign with a poor fit earns a quarter.
    """
    finding = _control_law(frames, p)
    return under_other_action_name(frames, finding) if p.goal_source == "action" else finding


def _control_law(frames: Frames, p: ControlLawParams) -> Finding:
    pose = _pose(frames, p)
    if pose is None:
        return _no_pose(frames, p)
    cmd = topic(frames, p.cmd_topic)
    if cmd is None or "linear.x" not in cmd.columns or "angular.z" not in cmd.columns:
        return Finding.fail(missing_topic_feedback(frames, p.cmd_topic, "your controller's output"))
    gl = _goals_with_end(frames, p, pose)
    if not gl:
        return _no_goals(frames, p)
    moved = provenance.moves(frames, p.pose_topic)
    j, gd = _paired_commands(frames, p, cmd, pose, gl, moved)
    ev: dict = {"rows": int(len(j))}
    if moved and gd["moved"].all():
        return provenance.moved_finding(frames, moved, "the control law")
    if len(j) < p.min_rows:
        return Finding(len(j), 0.0, "fail",
                       f"Only {len(j)} cmd_vel message(s) while a goal was active: the controller must publish "
                       "from its timer callback (every 0.03 s) once it has a pose and a goal.", ev)
    dx, dy = j["gx"].to_numpy() - j["x"].to_numpy(), j["gy"].to_numpy() - j["y"].to_numpy()
    th = j["th"].to_numpy()
    d_e = np.hypot(dx, dy)
    th_e = heading_error(j["x"].to_numpy(), j["y"].to_numpy(), th, j["gx"].to_numpy(), j["gy"].to_numpy())
    th_naive = np.arctan2(dy, dx) - th
    v, w = j["v"].to_numpy(), j["w"].to_numpy()
    k1, r2v = fit_gain(d_e, v)
    far = d_e >= p.min_d
    th_e0 = heading_error(j["x0"].to_numpy(), j["y0"].to_numpy(), j["th0"].to_numpy(), j["gx"].to_numpy(),
                          j["gy"].to_numpy())
    ambiguous = np.abs(np.angle(np.exp(1j * (th_e - th_e0)))) > p.max_tick_turn     # NaN: kept
    far = (d_e >= p.min_d) & ~ambiguous
    k2, r2w = fit_gain(th_e[far], w[far])
    k2n, r2n = fit_gain(th_naive[far], w[far])
    wrap_rows = int((np.abs(th_naive - th_e)[far] > 1.0).sum())
    ev["rows_turning_fast"] = int(ambiguous.sum())
    ev.update({"K1": k1, "R2_linear": r2v, "K2": k2, "R2_angular": r2w,
               "K2_unwrapped": k2n, "R2_angular_unwrapped": r2n, "rows_where_wrap_matters": wrap_rows,
               "sample": [{"d_e": float(a), "theta_e": float(b), "linear_x": float(cv), "angular_z": float(cw)}
                          for a, b, cv, cw in list(zip(d_e, th_e, v, w))[:: max(1, len(v) // 8)][:8]]})
    missing_wrap = wrap_rows >= p.min_wrap_rows and np.isfinite(r2n) and r2n > r2w + p.wrap_margin
    ev["wrap"] = ("missing" if missing_wrap else "ok") if wrap_rows >= p.min_wrap_rows else "not testable"
    keep = thin(len(v), 300)
    ev["fit_rows"] = {"t": since_start(frames, j["t"].to_numpy()[keep]).tolist(),
                      "d_e": np.round(d_e[keep], 4).tolist(), "theta_e": np.round(th_e[keep], 4).tolist(),
                      "theta_e_unwrapped": np.round(th_naive[keep], 4).tolist(),
                      "linear_x": np.round(v[keep], 4).tolist(), "angular_z": np.round(w[keep], 4).tolist()}
    lin, ang, notes = _credit(p, k1, r2v, k2, r2w, k2n, r2n, missing_wrap)
    frac = lin + ang
    value = f"K1={fmt(k1, 3)} (R² {fmt(r2v)}), K2={fmt(k2, 3)} (R² {fmt(r2w)})"
    if not notes:
        return Finding(value, 1.0, "pass",
                       f"Your controller follows v = {k1:.3g}·d_e and ω = {k2:.3g}·theta_e "
                       f"(R² {r2v:.3f} / {r2w:.3f}).", ev)
    return Finding(value, frac, graded(frac), sentence("; ".join(notes)), ev)


def _paired_commands(frames: Frames, p: ControlLawParams, cmd: pd.DataFrame, pose: pd.DataFrame, gl: list,
                     moved: list) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Each command of an active goal beside the pose it was computed from (and the tick
    before), the goal and whether the turtle was moved without driving; from the release of a
    held hand-over, else ``skip_after_goal_s`` after the goal. Returns it and the goals."""
    ct = times(cmd)
    if p.use_pub_time and "pub_t" in cmd.columns:
        pt = cmd["pub_t"].to_numpy(float)
        ct = np.where(np.isfinite(pt), pt, ct)
    c = pd.DataFrame({"t": ct, "v": cmd["linear.x"].to_numpy(float), "w": cmd["angular.z"].to_numpy(float)})
    c = c.sort_values("t", kind="stable")
    ps = pd.DataFrame({"t": times(pose), "x": pose["x"].to_numpy(float), "y": pose["y"].to_numpy(float),
                       "th": pose["theta"].to_numpy(float)}).sort_values("t", kind="stable")
    for col in ("x", "y", "th"):          # the tick before: the other pose a command may come from
        ps[f"{col}0"] = ps[col].shift(1)
    gd = pd.DataFrame({"t": [g.t for g in gl], "gx": [g.x for g in gl], "gy": [g.y for g in gl],
                       "g_end": [g.t_end for g in gl],
                       "moved": [bool(provenance.within(moved, g.t, g.t_end)) for g in gl]})
    j = pd.merge_asof(c, ps, on="t", direction="backward")
    j = pd.merge_asof(j, gd, on="t", direction="backward")
    j = j.dropna(subset=["x", "gx"])
    j = j[(j["t"] <= j["g_end"]) & ~j["moved"].astype(bool)]
    goal_t = gd["t"].to_numpy()
    k = np.searchsorted(goal_t, j["t"].to_numpy(), side="right") - 1
    since = j["t"].to_numpy() - goal_t[k]
    # a goal handed over while the turtle was held: from its release (until then a command may
    # still be for the old goal); else skip_after_goal_s after it
    released = {e.step: e.t for e in events(frames, TurtlesReleased) if e.ok}
    start = np.array([released.get(g.extra.get("step"), g.t + p.skip_after_goal_s) for g in gl])
    j = j[(since >= p.skip_after_goal_s) & (j["t"].to_numpy() >= start[k])]
    return j, gd


def _credit(p: ControlLawParams, k1: float, r2v: float, k2: float, r2w: float, k2n: float, r2n: float,
            missing_wrap: bool) -> tuple[float, float, list[str]]:
    """Half the credit for each law (a quarter for the right sign with a poor fit) and what the
    student reads about each shortfall."""
    notes = []
    lin = 0.0
    if not np.isfinite(k1) or k1 <= 0:
        notes.append(f"linear.x does not grow with the distance to the goal (K1 ≈ {fmt(k1, 3)}): "
                     "use linear.x = K1·d_e with K1 > 0")
    elif r2v >= p.r2_min:
        lin = 0.5
    else:
        lin = 0.25
        notes.append(f"linear.x is only loosely proportional to d_e (R² = {r2v:.2f}): use linear.x = K1·d_e")
    ang = 0.0
    if missing_wrap:
        ang = 0.25 if k2n > 0 else 0.0
        notes.append(f"angular.z follows atan2(dy, dx) − theta without wrapping (R² {r2n:.2f} vs {r2w:.2f} "
                     "wrapped), so the turtle turns the long way: compute theta_e with eq. (3)")
    elif not np.isfinite(k2) or k2 <= 0:
        notes.append(f"angular.z has the wrong sign (K2 ≈ {fmt(k2, 3)}): a positive theta_e (goal to the left) "
                     "needs a positive (counter-clockwise) angular.z; check the atan2 argument order and K2 > 0")
    elif r2w >= p.r2_min:
        ang = 0.5
    else:
        ang = 0.25
        notes.append(f"angular.z is only loosely proportional to theta_e (R² = {r2w:.2f}): use angular.z = K2·theta_e")
    return lin, ang, notes
