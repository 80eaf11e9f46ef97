"""Figures for how the turtle moved: the fitted circle, the path against the walls, the pen
colour changes where the path crosses its line, and the service calls on a timeline."""

from __future__ import annotations

from typing import Any, Mapping, cast

from grader.contracts.world import WORLD_SIZE_M
from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import BLUE, GREEN, OUTSIDE, VERMILION, floats, fmt, key, num



def _path(evidence: Mapping[str, Any]) -> tuple[list[float], list[float]] | None:
    path = evidence.get("path")
    if not isinstance(path, Mapping):
        return None
    xs, ys = floats(path.get("x")), floats(path.get("y"))
    if not xs or not ys or len(xs) != len(ys):
        return None
    return xs, ys


def _world(ax: Any) -> None:
    from matplotlib.patches import Rectangle  # noqa: PLC0415 - matplotlib.patches: 311 ms CPU to import, paid only on this path

    ax.add_patch(Rectangle((0, 0), WORLD_SIZE_M, WORLD_SIZE_M, fill=False, ec="#555555", lw=1.2, label="walls"))
    ax.set(xlim=(-0.3, WORLD_SIZE_M + 0.3), ylim=(-0.3, WORLD_SIZE_M + 0.3), xlabel="x (m)", ylabel="y (m)", aspect="equal")


@figure("circle_radius")
def fitted_circle(ctx: FigureContext) -> Plot | None:
    pts = _path(ctx.evidence)
    centre = floats(ctx.evidence.get("centre"))
    radius = num(ctx.evidence.get("radius_m"))
    if pts is None or not centre or len(centre) != 2 or radius is None:
        return None
    from matplotlib.patches import Circle  # noqa: PLC0415 - matplotlib.patches: 311 ms CPU to import, paid only on this path

    expected = num(ctx.param("expected_m"))
    title = "The path should lie on the fitted circle, whose radius should be the expected one"
    fig, ax = ctx.axes(title, size=(7.4, 4.8), legend_width=2.9)
    _world(ax)
    ax.plot(*pts, color=BLUE, lw=1.4, label="turtle path")
    ax.add_patch(Circle(cast(Any, tuple(centre)), radius, fill=False, ec=VERMILION, lw=1.2, ls="--",
                        label=f"fitted circle, r = {fmt(radius, 3)} m"))
    if expected:
        ax.add_patch(Circle(cast(Any, tuple(centre)), expected, fill=False, ec=GREEN, lw=1.0, ls=":",
                            label=f"expected r = {expected:g} m"))
    ax.plot(*centre, "+", color=VERMILION, ms=10, mew=2, label=f"centre ({centre[0]:.2f}, {centre[1]:.2f})")
    ax.legend(**OUTSIDE)
    return Plot(fig, title, alt=f"Turtle path of {len(pts[0])} points; fitted circle radius {fmt(radius, 3)} m "
                f"around ({centre[0]:.2f}, {centre[1]:.2f}) m" + (f", expected {expected:g} m." if expected else "."))


@figure("no_wall_contact")
def walls(ctx: FigureContext) -> Plot | None:
    pts = _path(ctx.evidence)
    if pts is None:
        return None
    closest = floats(ctx.evidence.get("closest_at"))
    contacts = [c for c in ctx.evidence.get("contact_points") or [] if isinstance(c, list) and len(c) == 2]
    title = "The path should stay inside the walls without touching them"
    fig, ax = ctx.axes(title, size=(7.4, 4.8), legend_width=2.9)
    _world(ax)
    ax.plot(*pts, color=BLUE, lw=1.0, label="turtle path")
    if closest and len(closest) == 2:
        clearance = num(ctx.evidence.get("min_clearance_m"))
        ax.plot(*closest, "o", mfc="none", mec=VERMILION, ms=9, mew=1.6,
                label=f"closest to a wall ({fmt(clearance, 2)} m)")
    if contacts:
        ax.plot([c[0] for c in contacts], [c[1] for c in contacts], "x", color=VERMILION, ms=7,
                label=f"wall contact ({len(contacts)})")
    ax.legend(**OUTSIDE)
    return Plot(fig, title, alt=f"Turtle path inside the {WORLD_SIZE_M:.2f} m square; closest approach "
                f"{fmt(num(ctx.evidence.get('min_clearance_m')), 2)} m; {len(contacts)} wall contacts.")


@figure("pen_on_crossings")
def pen_crossings(ctx: FigureContext) -> Plot | None:
    pts = _path(ctx.evidence)
    split = num(ctx.evidence.get("split_x")) or num(ctx.param("split_x"))
    rows = [r for r in ctx.evidence.get("crossings") or [] if isinstance(r, Mapping)]
    if pts is None or split is None:
        return None
    title = f"Each crossing of x = {split:g} should change the pen (✓ on time, ✗ missed or wrong)"
    fig, ax = ctx.axes(title, size=(7.4, 4.8), legend_width=3.0)
    _world(ax)
    ax.plot(*pts, color="#777777", lw=0.8, label="turtle path")
    ax.axvline(split, color="black", lw=1.0, ls="--", label=f"x = {split:g}")
    good = [r for r in rows if r.get("ok") and num(r.get("y")) is not None]
    bad = [r for r in rows if not r.get("ok") and num(r.get("y")) is not None]
    for group, marker, colour, label in ((good, "o", GREEN, "crossing answered"),
                                         (bad, "X", VERMILION, "crossing not answered right")):
        if group:
            ax.plot([split] * len(group), [num(r["y"]) for r in group], marker, color=colour, ms=7,
                    mec="black", mew=0.5, ls="none", label=f"{label} ({len(group)})")
    extra = ctx.evidence.get("extra_calls") or []
    if extra:
        key(ax, f"set_pen calls not at a crossing: {len(extra)}", "s", color=BLUE)
    ax.legend(**OUTSIDE)
    return Plot(fig, title, alt=f"{len(rows)} crossings of x = {split:g}: {len(good)} answered with the right "
                f"colour in time, {len(bad)} not; {len(extra)} other set_pen calls.")


@figure("request_echoed")
def service_timeline(ctx: FigureContext) -> Plot | None:
    rows = [r for r in ctx.evidence.get("calls") or [] if isinstance(r, Mapping) and num(r.get("t")) is not None]
    if not rows:
        return None
    topic = str(ctx.evidence.get("topic") or "the topic")
    title = f"Each service call (▲) should be followed at once by one message on {topic} (●)"
    fig, ax = ctx.axes(title, size=(7.4, 2.8), legend_width=2.6)
    calls = [num(r["t"]) for r in rows]
    ax.plot(calls, [1] * len(calls), "^", color=BLUE, ms=9, ls="none", label="service call")
    msgs = [m for r in rows for m in (floats(r.get("message_t")) or [])]
    if msgs:
        ax.plot(msgs, [0] * len(msgs), "o", color=GREEN, ms=7, ls="none", label=f"message on {topic}")
    for r in rows:
        req: Mapping = r["request"] if isinstance(r.get("request"), Mapping) else {}
        text = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in list(req.items())[:3])
        ax.annotate(text, (num(r["t"]), 1), textcoords="offset points", xytext=(0, 8), ha="center", fontsize=7)
    ax.set(yticks=[0, 1], yticklabels=[topic, "calls"], ylim=(-0.6, 1.8), xlabel="time since the scenario started (s)")
    ax.legend(**OUTSIDE)
    answered = sum(1 for r in rows if r.get("match") and r.get("messages") == 1)
    return Plot(fig, title, alt=f"{len(rows)} service calls at " + ", ".join(f"{c:.1f}" for c in calls[:8])
                + f" s; {len(msgs)} messages on {topic}; {answered} calls followed by exactly one matching message.")

