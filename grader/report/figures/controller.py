"""Controller figures: the commands against the errors with the fitted gains (control_law), and
the heading error over time per goal (turn_direction)."""

from __future__ import annotations

import math
from typing import Any, Mapping, cast

from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import OUTSIDE, BLUE, LINESTYLES, MUTED, PALETTE, floats, fmt, num

BELOW = {"loc": "upper left", "bbox_to_anchor": (0.0, -0.2), "borderaxespad": 0.0, "fontsize": 7}
FIT_TITLE = "Controller commands against the errors: the points should lie on the fitted lines"
HEADING_TITLE = "Heading error per goal: it should shrink to 0° without crossing ±180°"


def _series(rows: Mapping[str, Any], *keys: str) -> list[list[float]] | None:
    cols = [floats(rows.get(k)) for k in keys]
    if any(c is None for c in cols) or len({len(cast(list, c)) for c in cols}) != 1 or not cols[0]:
        return None
    return cols  # type: ignore[return-value]


def _line(ax: Any, k: float | None, xs: list[float], colour: str, label: str, style: str = "-") -> None:
    finite = [x for x in xs if math.isfinite(x)]
    if k is None or not finite:
        return
    lo, hi = min(finite), max(finite)
    ax.plot([lo, hi], [k * lo, k * hi], color=colour, linestyle=style, lw=1.2, label=label, zorder=3)


@figure("control_law")
def control_fit(ctx: FigureContext) -> Plot | None:
    rows = ctx.evidence.get("fit_rows")
    if not isinstance(rows, Mapping):
        return None
    cols = _series(rows, "d_e", "theta_e", "theta_e_unwrapped", "linear_x", "angular_z")
    if cols is None:
        return None
    d_e, th_e, th_raw, v, w = cols
    ev = ctx.evidence
    k1, r2v, k2, r2w = (num(ev.get(k)) for k in ("K1", "R2_linear", "K2", "R2_angular"))
    k2n, r2n = num(ev.get("K2_unwrapped")), num(ev.get("R2_angular_unwrapped"))
    min_d = num(ctx.param("min_d")) or 0.0
    far = [d >= min_d for d in d_e]
    fig, (left, right) = ctx.axes(FIT_TITLE, size=(8.4, 4.6), ncols=2)
    left.plot(d_e, v, "o", color=BLUE, ms=3, alpha=0.5, mew=0, label="your linear.x", zorder=2)
    _line(left, k1, d_e, "black", f"fit linear.x = K1·d_e, K1 = {fmt(k1)} (R² {fmt(r2v, 2)})")
    left.set(xlabel="distance to the goal d_e (m)", ylabel="linear.x (m/s)")
    left.legend(**BELOW)
    te = [t for t, f in zip(th_e, far) if f]
    wf = [x for x, f in zip(w, far) if f]
    right.plot(te, wf, "o", color=BLUE, ms=3, alpha=0.5, mew=0, label="your angular.z vs wrapped theta_e",
               zorder=2)
    _line(right, k2, te, "black", f"fit angular.z = K2·theta_e, K2 = {fmt(k2)} (R² {fmt(r2w, 2)})")
    wrap_problem = ev.get("wrap") == "missing"
    if wrap_problem:
        tr = [t for t, f in zip(th_raw, far) if f]
        right.plot(tr, wf, "x", color=MUTED, ms=3, alpha=0.7, label="against theta_e NOT wrapped")
        _line(right, k2n, tr, "#000000", f"unwrapped fit K2 = {fmt(k2n)} (R² {fmt(r2n, 2)})", "--")
    right.set(xlabel="heading error theta_e (rad)", ylabel="angular.z (rad/s)")
    right.legend(**BELOW)
    fig.subplots_adjust(bottom=1.45 / 4.6)
    alt = (f"Two scatter plots of {len(d_e)} controller commands. linear.x against the distance to the goal: "
           f"fitted K1 = {fmt(k1)} with R² = {fmt(r2v, 2)}. angular.z against the heading error: fitted "
           f"K2 = {fmt(k2)} with R² = {fmt(r2w, 2)}.")
    if wrap_problem:
        alt += (f" Against the heading error without wrapping the fit is better (K2 = {fmt(k2n)}, "
                f"R² = {fmt(r2n, 2)}): theta_e is not wrapped to [−π, π].")
    return Plot(fig, title=FIT_TITLE, alt=alt)


def _break_at_wrap(t: list[float], err: list[float]) -> tuple[list[float], list[float]]:
    """A gap (NaN) where the wrapped angle jumps between +180° and −180°, instead of a vertical
    line across the plot."""
    ts, es = [], []
    for k, (a, e) in enumerate(zip(t, err)):
        if k and abs(e - err[k - 1]) > 180:
            ts.append(math.nan)
            es.append(math.nan)
        ts.append(a)
        es.append(e)
    return ts, es


@figure("turn_direction")
def heading_error(ctx: FigureContext) -> Plot | None:
    series = ctx.evidence.get("heading_error")
    if not isinstance(series, list):
        return None
    usable: list[Any] = []
    for s in series:
        if isinstance(s, Mapping):
            cols = _series(s, "t", "theta_e_deg")
            if cols:
                t, err = _break_at_wrap(*cols)
                usable.append((str(s.get("label") or f"goal {len(usable) + 1}"), t, err))
    if not usable:
        return None
    rows = {r.get("goal"): r for r in ctx.evidence.get("goals", []) if isinstance(r, Mapping)}
    fig, ax = ctx.axes(HEADING_TITLE, size=(7.6, 3.4), legend_width=2.9)
    descs = []
    for k, (label, t, err) in enumerate(usable):
        row = rows.get(k + 1, {})
        verdict = ("short way" if row.get("short_way") else "long way" if row.get("evaluated") else
                   "small turn, not judged")
        ax.plot(t, err, color=PALETTE[k % len(PALETTE)], linestyle=LINESTYLES[k % len(LINESTYLES)],
                label=f"{label}: {verdict}")
        first = next((e for e in err if math.isfinite(e)), math.nan)
        descs.append(f"{label} starts at {first:+.0f}° ({verdict})")
    for y in (-180, 180):
        ax.axhline(y, color=MUTED, lw=0.8, ls=":")
    ax.axhline(0, color="black", lw=0.8)
    ax.set(xlabel="time since the scenario started (s)", ylabel="heading error theta_e (°)",
           ylim=(-190, 190), yticks=[-180, -90, 0, 90, 180])
    ax.legend(**OUTSIDE)
    alt = ("Heading error over time for each goal, in degrees (positive: goal to the left). "
           + "; ".join(descs) + ".")
    return Plot(fig, title=HEADING_TITLE, alt=alt)
