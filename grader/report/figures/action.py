"""Action-server figure: a timeline of the goals sent (accepted or rejected, feedback, result)
above the turtle's distance to each accepted goal."""

from __future__ import annotations

from typing import Any, Mapping

from grader.contracts.world import WORLD_SIZE_M
from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import OUTSIDE, BLUE, FAIL, GREEN, MUTED, PALETTE, PASS, floats, fmt, key, num

TITLES = {
    "action_goals_succeed": "Action goals over time: reachable goals should end in success, close to the goal",
    "action_rejects_out_of_bounds": "Action goals over time: goals outside the world should be rejected at once",
    "action_timeout": "Action goals over time: the short-timeout goal should end soon after its time_out",
}


def _goals(ctx: FigureContext) -> list[Mapping[str, Any]]:
    tl = ctx.evidence.get("timeline")
    rows = tl.get("goals") if isinstance(tl, Mapping) else None
    return [r for r in rows if isinstance(r, Mapping) and num(r.get("t_sent")) is not None] \
        if isinstance(rows, list) else []


def _relevant(analyzer: str, row: Mapping[str, Any], ctx: FigureContext) -> bool:
    x, y = num(row.get("x")), num(row.get("y"))
    if x is None or y is None:
        return False
    outer = num(ctx.param("outer_bound")) or WORLD_SIZE_M
    inside = 0 <= x <= outer and 0 <= y <= outer
    short = num(row.get("time_out")) is not None and 0 < (num(row.get("time_out")) or 0) <= \
        (num(ctx.param("short_timeout_s")) or 5.0)
    if analyzer == "action_rejects_out_of_bounds":
        return not inside
    if analyzer == "action_timeout":
        return inside and short
    return inside and not short


def _describe(row: Mapping[str, Any]) -> str:
    name = f"{row.get('label')} ({fmt(num(row.get('x')))}, {fmt(num(row.get('y')))})"
    text = f"{name}: sent at {fmt(num(row.get('t_sent')))} s"
    if row.get("accepted") is None:
        return text + ", never answered"
    if not row.get("accepted"):
        return text + f", rejected at {fmt(num(row.get('t_response')))} s"
    text += ", accepted"
    if num(row.get("t_result")) is None:
        return text + ", no result"
    dur = (num(row.get("t_result")) or 0) - (num(row.get("t_sent")) or 0)
    text += f", {'success' if row.get('success') else 'failure'} after {dur:.1f} s"
    dist = row.get("distance")
    d = floats(dist.get("d")) if isinstance(dist, Mapping) else None
    if d:
        text += f" at {d[-1]:.2f} m from the goal"
    return text


@figure("action_goals_succeed", "action_rejects_out_of_bounds", "action_timeout")
def timeline(ctx: FigureContext) -> Plot | None:
    goals = _goals(ctx)
    if not goals:
        return None
    analyzer = ctx.item.analyzer or ""
    title = TITLES.get(analyzer, "Action goals over time")
    fig, (top, bottom) = ctx.axes(title, size=(7.6, 4.8), nrows=2, legend_width=2.1, sharex=True,
                                  gridspec_kw={"height_ratios": [1, 1.3]})
    labels = []
    fig.subplots_adjust(left=1.15 / 7.6)

    for k, row in enumerate(goals):
        y = len(goals) - k
        alpha = 1.0 if _relevant(analyzer, row, ctx) else 0.35
        t0 = num(row.get("t_sent")) or 0.0
        t_resp, t_res = num(row.get("t_response")), num(row.get("t_result"))
        end = t_res if t_res is not None else t_resp if t_resp is not None else t0
        top.plot([t0, end], [y, y], color=MUTED, lw=3, alpha=alpha * 0.6, solid_capstyle="butt")
        top.plot(t0, y, ">", color=BLUE, ms=7, alpha=alpha)
        if t_resp is not None:
            acc = bool(row.get("accepted"))
            top.plot(t_resp, y, "o" if acc else "X", color=PASS if acc else FAIL, ms=7, alpha=alpha,
                     mec="black", mew=0.5)
        if t_res is not None:
            ok = bool(row.get("success"))
            top.plot(t_res, y, "*" if ok else "s", color=PASS if ok else FAIL, ms=9 if ok else 6, alpha=alpha,
                     mec="black", mew=0.5)
        labels.append((y, f"{row.get('label')}\n({fmt(num(row.get('x')))}, {fmt(num(row.get('y')))})"))
        dist = row.get("distance")
        if isinstance(dist, Mapping):
            t, d = floats(dist.get("t")), floats(dist.get("d"))
            if t and d and len(t) == len(d):
                bottom.plot(t, d, color=PALETTE[k % len(PALETTE)], alpha=max(alpha, 0.5),
                            label=f"{row.get('label')} ({fmt(num(row.get('x')))}, {fmt(num(row.get('y')))})")
    seen = {(r.get("accepted"), r.get("success") if num(r.get("t_result")) is not None else None) for r in goals}
    key(top, "goal sent", ">", color=BLUE, ms=7)
    if any(a for a, _ in seen):
        key(top, "accepted", "o", color=PASS, mec="black", mew=0.5, ms=7)
    if any(a is False for a, _ in seen):
        key(top, "rejected", "X", color=FAIL, mec="black", mew=0.5, ms=7)
    if any(s is True for _, s in seen):
        key(top, "result: success", "*", color=PASS, mec="black", mew=0.5, ms=9)
    if any(s is False for _, s in seen):
        key(top, "result: failure", "s", color=FAIL, mec="black", mew=0.5, ms=6)
    if any(not _relevant(analyzer, r, ctx) for r in goals):
        key(top, "faded: not judged here", "s", color=MUTED, alpha=0.35)
    tl = ctx.evidence.get("timeline")
    fb = floats(tl.get("feedback_t")) if isinstance(tl, Mapping) else None
    if fb:
        top.plot(fb, [0.35] * len(fb), "|", color=GREEN, ms=8, label=f"feedback messages ({len(fb)})")
    top.set_yticks([y for y, _ in labels], [text for _, text in labels], fontsize=7)
    top.set(ylim=(0, len(goals) + 0.7))
    top.grid(axis="y", visible=False)
    top.legend(**OUTSIDE)
    tol = next((num(r.get("goal_tol")) for r in ctx.evidence.get("goals", []) if isinstance(r, Mapping)
                and num(r.get("goal_tol"))), None)
    if tol:
        bottom.axhline(tol, color="black", ls="--", lw=1, label=f"goal tolerance {tol:g} m")
    bottom.set(xlabel="time since the scenario started (s)", ylabel="distance to the goal (m)", ylim=(0, None))
    if bottom.get_legend_handles_labels()[0]:
        bottom.legend(**OUTSIDE)
    alt = f"Timeline of {len(goals)} action goal(s). " + "; ".join(_describe(r) for r in goals) + "."
    if fb:
        alt += f" {len(fb)} feedback message(s)."
    return Plot(fig, title=title, alt=alt)
