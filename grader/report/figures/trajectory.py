"""Trajectory figure: the turtle's path to each goal in the turtlesim world, the goals with their
tolerance circles, the start pose, where each goal was sent and reached, and wall contacts."""

from __future__ import annotations

import math
from typing import Any, Mapping

from grader.contracts.world import WORLD_SIZE_M     # the world is [0, WORLD_SIZE_M]^2 (a wall on every side)
from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import OUTSIDE, LINESTYLES, MUTED, PALETTE, floats, fmt, key, num

TITLE = "Turtle path per goal: each path should end inside its goal's circle"


def _paths(evidence: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Usable entries of ``evidence["trajectory"]`` (one path per goal); malformed ones dropped."""
    raw = evidence.get("trajectory")
    entries = raw if isinstance(raw, list) else [raw]
    out: list[dict[str, Any]] = []
    for entry in entries:
        if not isinstance(entry, Mapping):
            continue
        xs, ys = floats(entry.get("x")), floats(entry.get("y"))
        if not xs or ys is None or len(xs) != len(ys):
            continue
        pts = [(x, y) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y)]
        goal = floats(entry.get("goal"))
        if not pts:
            continue
        out.append({"x": [p[0] for p in pts], "y": [p[1] for p in pts],
                    "goal": goal if goal and len(goal) == 2 else None,
                    "label": str(entry.get("label") or f"path {len(out) + 1}"),
                    "theta0": num(entry.get("theta0"))})
    return out


def _rows(evidence: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    rows = evidence.get("goals")
    return [r for r in rows if isinstance(r, Mapping)] if isinstance(rows, list) else []


def _row_text(row: Mapping[str, Any] | None) -> str:
    if row is None:
        return ""
    if row.get("reached"):
        text = f"reached after {fmt(num(row.get('time_to_reach')), 2)} s"
        if row.get("held") is False or row.get("stopped") is False:
            text += f", then left it (final distance {fmt(num(row.get('final_error')), 2)} m)"
        return text
    closest = num(row.get("min_distance"))
    return "not reached" + (f" (closest {closest:.2f} m)" if closest is not None else "")


@figure("goals_reached")
def trajectory(ctx: FigureContext) -> Plot | None:
    paths = _paths(ctx.evidence)
    if not paths:
        return None
    rows = _rows(ctx.evidence)
    tol = num(ctx.param("tol_reached"))
    fig, ax = ctx.axes(TITLE, size=(7.6, 4.8), legend_width=3.1)
    ax.add_patch(_rect(ax))
    descs = []
    for k, path in enumerate(paths):
        colour, style = PALETTE[k % len(PALETTE)], LINESTYLES[(k // len(PALETTE)) % len(LINESTYLES)]
        row = rows[k] if k < len(rows) else None
        ax.plot(path["x"], path["y"], color=colour, linestyle=style,
                label=f"{path['label']}: {_row_text(row)}".rstrip(": "))
        ax.plot(path["x"][0], path["y"][0], "o", mfc="white", mec=colour, mew=1.5, ms=6)
        if path["goal"]:
            gx, gy = path["goal"]
            ax.plot(gx, gy, "X", color=colour, ms=8, mec="black", mew=0.6)
            if tol:
                ax.add_patch(_circle(ax, (gx, gy), tol, colour))
        at = floats(row.get("reached_at")) if row else None
        if at and len(at) == 2:
            ax.plot(at[0], at[1], "D", color=colour, mec="black", mew=0.6, ms=5)
        descs.append(f"{path['label']}: {_row_text(row) or 'path shown'}")
    key(ax, "where the goal was sent", "o", mfc="white", mec="black", mew=1.5)
    key(ax, "goal", "X", color="#999999", mec="black", mew=0.6, ms=8)
    key(ax, "where it was reached", "D", color="#999999", mec="black", mew=0.6)
    first = paths[0]
    if first["theta0"] is not None:
        th = first["theta0"]
        ax.annotate("", xy=(first["x"][0] + 0.9 * math.cos(th), first["y"][0] + 0.9 * math.sin(th)),
                    xytext=(first["x"][0], first["y"][0]),
                    arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.3})
        ax.plot([], [], color="black", marker=r"$\rightarrow$", ls="none", ms=10, label="start pose (heading)")
    walls = ctx.evidence.get("wall_points")
    n_walls = int(num(ctx.evidence.get("wall_contacts")) or 0)
    if isinstance(walls, list) and walls:
        pts: list[Any] = [floats(w) for w in walls]
        pts = [p for p in pts if p and len(p) == 3]
        if pts:
            ax.plot([p[1] for p in pts], [p[2] for p in pts], "s", ms=8, mfc="none", mec="black", mew=1.8,
                    label=f"wall contact ({n_walls}×)")
    if tol:
        ax.plot([], [], color=MUTED, ls=":", label=f"goal tolerance ({tol:g} m)")
    ax.set(xlim=(-0.3, WORLD_SIZE_M + 0.3), ylim=(-0.3, WORLD_SIZE_M + 0.3), xlabel="x (m)", ylabel="y (m)",
           aspect="equal")
    ax.legend(**OUTSIDE)
    alt = (f"Turtle path in the {WORLD_SIZE_M:.1f} m square world for {len(paths)} goal(s). "
           + ". ".join(descs) + "."
           + (f" Goal tolerance {tol:g} m." if tol else "")
           + (f" The turtle hit a wall {n_walls} time(s)." if n_walls else " No wall contact."))
    return Plot(fig, title=TITLE, alt=alt)


def _rect(ax: Any) -> Any:
    from matplotlib.patches import Rectangle  # noqa: PLC0415 - matplotlib.patches: 311 ms CPU to import, paid only on this path

    return Rectangle((0, 0), WORLD_SIZE_M, WORLD_SIZE_M, fill=False, edgecolor="#444444", lw=1.2, zorder=0)


def _circle(ax: Any, centre: tuple[float, float], radius: float, colour: str) -> Any:
    from matplotlib.patches import Circle  # noqa: PLC0415 - matplotlib.patches: 311 ms CPU to import, paid only on this path

    return Circle(centre, radius, fill=False, edgecolor=colour, linestyle=":", lw=1.3)
