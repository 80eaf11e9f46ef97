"""Rate figure: the interval between consecutive messages over time, against the expected period."""

from __future__ import annotations

from typing import Mapping, cast

from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import OUTSIDE, BLUE, GREEN, VERMILION, floats, fmt, num


@figure("publish_rate")
def intervals(ctx: FigureContext) -> Plot | None:
    series = ctx.evidence.get("intervals")
    if not isinstance(series, Mapping):
        return None
    t, dt = floats(series.get("t")), floats(series.get("dt"))
    if not t or dt is None or len(t) != len(dt):
        return None
    expected = num(ctx.param("expected_hz"))
    tol = num(ctx.param("rel_tol"))
    measured = num(ctx.evidence.get("rate_hz"))
    topic = str(ctx.evidence.get("measured_topic") or ctx.evidence.get("topic") or "the topic")
    period = 1.0 / expected if expected else None
    title = (f"Time between messages on {topic}: points should lie in the band around {period:.3g} s"
             if period else f"Time between messages on {topic}")
    fig, ax = ctx.axes(title, size=(7.6, 3.3), legend_width=2.6)
    top = max([x for x in dt if x == x] or [1.0])
    limit = max(2.5 * period, 1.15 * sorted(dt)[int(0.99 * (len(dt) - 1))]) if period else top * 1.1
    inside = [(a, b) for a, b in zip(t, dt) if b <= limit]
    above = [(a, limit) for a, b in zip(t, dt) if b > limit]
    ax.plot([a for a, _ in inside], [b for _, b in inside], ".", color=BLUE, ms=3.5,
            label=f"interval between messages ({len(dt)} shown)")
    if above:
        ax.plot([a for a, _ in above], [b for _, b in above], "^", color=VERMILION, ms=6,
                label=f"longer than {limit:.3g} s (pause; drawn at the top)")
    if period:
        if tol:
            rate = cast(float, expected)                 # (a period: there is a rate)
            ax.axhspan(1.0 / (rate * (1 + tol)), 1.0 / (rate * (1 - tol)) if tol < 1 else limit,
                       color=GREEN, alpha=0.15, lw=0, label=f"expected {period:.3g} s ± {tol:.0%} of the rate")
        ax.axhline(period, color=GREEN, lw=1.5, label=f"expected period {period:.3g} s ({expected:g} Hz)")
    if measured:
        ax.axhline(1.0 / measured, color="black", lw=1.2, ls="--",
                   label=f"your mean interval {1.0 / measured:.3g} s ({measured:.3g} Hz)")
    ax.set(xlabel="time since the scenario started (s)", ylabel="interval (s)", ylim=(0, limit * 1.05))
    ax.legend(**OUTSIDE)
    alt = (f"Intervals between consecutive messages on {topic} over time ({len(dt)} shown). "
           f"Mean rate {fmt(measured)} Hz" + (f", expected {expected:g} Hz (period {period:.3g} s)" if period else "")
           + f"; shortest interval {fmt(min(dt))} s, longest {fmt(top)} s.")
    return Plot(fig, title=title, alt=alt)

