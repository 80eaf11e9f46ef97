"""Box-Muller figures: printed value against the correct z per published pair (boxmuller), and
the distribution of the printed values against N(0, 1) as a histogram and a QQ plot (normality)."""

from __future__ import annotations

import math
from typing import Mapping

from grader.report.figures import FigureContext, Plot, figure
from grader.report.figures._mpl import BLUE, GREEN, VERMILION, floats, fmt, num

SCATTER_TITLE = "Printed value against the correct z for each published pair: points should lie on the diagonal"
HIST_TITLE = "Distribution of your printed values: the bars should follow the N(0, 1) curve"
QQ_TITLE = "Quantiles of your values against N(0, 1): the points should lie on the line"

#: what a named mistake looks like in the scatter (see grader.analyze.boxmuller.FORMULAS)
_LOOK = {
    "log10": "a straight line flatter than the diagonal (slope ≈ 0.66: log10 instead of ln)",
    "log2": "a straight line steeper than the diagonal (slope ≈ 1.20: log2 instead of ln)",
    "missing_2": "a straight line with slope ≈ 0.71 (the 2 under the square root is missing)",
    "swapped": "a cloud: u1 and u2 are swapped",
    "negated": "the other diagonal: the sign is wrong",
}


def _normal_pdf(x: float) -> float:
    return math.exp(-0.5 * x * x) / math.sqrt(2 * math.pi)


@figure("boxmuller")
def printed_vs_expected(ctx: FigureContext) -> Plot | None:
    pairs = ctx.evidence.get("pairs")
    if not isinstance(pairs, Mapping):
        return None
    z, printed = floats(pairs.get("expected_z")), floats(pairs.get("printed"))
    matched: list = pairs["matched"] if isinstance(pairs.get("matched"), list) else []
    if not z or printed is None or len(z) != len(printed):
        return None
    formula = str(pairs.get("formula") or "correct")
    ok = [bool(m) and formula == "correct" for m in (matched + [False] * len(z))[:len(z)]]
    fig, ax = ctx.axes(SCATTER_TITLE, size=(5.6, 4.8))
    finite = [v for v in z + printed if math.isfinite(v)] or [-3.0, 3.0]
    lo, hi = max(min(finite), -6.0), min(max(finite), 6.0)
    ax.plot([lo, hi], [lo, hi], color=GREEN, lw=2, label="correct: printed = z")
    good = [(a, b) for a, b, m in zip(z, printed, ok) if m]
    bad = [(a, b) for a, b, m in zip(z, printed, ok) if not m]
    if good:
        ax.plot(*zip(*good), "o", color=BLUE, ms=3.5, alpha=0.7, label=f"matches z ({len(good)})")
    if bad:
        ax.plot(*zip(*bad), "x", color=VERMILION, ms=4, alpha=0.8, label=f"does not match ({len(bad)})")
    ax.set(xlabel="correct z = sqrt(−2 ln u1)·cos(2π u2) (unitless)", ylabel="value you printed (unitless)",
           xlim=(lo - 0.2, hi + 0.2), ylim=(lo - 0.2, hi + 0.2), aspect="equal")
    ax.legend(loc="upper left")
    text = str(ctx.evidence.get("best_formula_text") or "")
    alt = f"Scatter of {len(z)} printed values against the correct z of the pair each answers: "
    alt += f"{len(good)} on the diagonal, {len(bad)} off it."
    if formula != "correct":
        alt += f" The values follow {text}" + (f", which shows as {_LOOK[formula]}" if formula in _LOOK else "") + "."
    return Plot(fig, title=SCATTER_TITLE, alt=alt)


@figure("normality")
def histogram(ctx: FigureContext) -> Plot | None:
    h = ctx.evidence.get("histogram")
    if not isinstance(h, Mapping):
        return None
    edges, counts = floats(h.get("bins")), floats(h.get("counts"))
    if not edges or not counts or len(edges) != len(counts) + 1 or any(c < 0 for c in counts):
        return None
    if any(b <= a for a, b in zip(edges, edges[1:])):
        return None
    total = sum(counts)
    if total <= 0:
        return None
    widths = [b - a for a, b in zip(edges, edges[1:])]
    density = [c / (total * w) for c, w in zip(counts, widths)]
    fig, ax = ctx.axes(HIST_TITLE, size=(5.8, 3.6))
    ax.bar(edges[:-1], density, width=widths, align="edge", color="#9ecae1", edgecolor=BLUE, lw=0.5,
           label=f"your {int(total)} values")
    xs = [edges[0] + (edges[-1] - edges[0]) * k / 160 for k in range(161)]
    ax.plot(xs, [_normal_pdf(x) for x in xs], color=VERMILION, lw=2, label="N(0, 1) density")
    mean, std = num(ctx.evidence.get("mean")), num(ctx.evidence.get("std"))
    if mean is not None and std:
        ax.plot(xs, [_normal_pdf((x - mean) / std) / std for x in xs], color="black", lw=1.2, ls="--",
                label=f"normal with your mean {mean:.2f}, std {std:.2f}")
    ax.set(xlabel="printed value z (unitless)", ylabel="density (per unit of z)")
    ax.legend(loc="upper left", fontsize=7)
    alt = (f"Histogram of {int(total)} printed values from {edges[0]:g} to {edges[-1]:g} with the standard "
           f"normal density. Mean {fmt(mean)}, standard deviation {fmt(std)} (N(0, 1): 0 and 1); "
           f"Shapiro-Wilk p = {fmt(num(ctx.evidence.get('shapiro_p')), 2)}, "
           f"Anderson-Darling p = {fmt(num(ctx.evidence.get('anderson_p')), 2)}.")
    return Plot(fig, title=HIST_TITLE, alt=alt)


@figure("normality")
def qq(ctx: FigureContext) -> Plot | None:
    q = ctx.evidence.get("qq")
    if not isinstance(q, Mapping):
        return None
    th, sample = floats(q.get("theoretical")), floats(q.get("sample"))
    if not th or sample is None or len(th) != len(sample):
        return None
    fig, ax = ctx.axes(QQ_TITLE, size=(4.8, 4.4))
    lo, hi = min(th), max(th)
    ax.plot([lo, hi], [lo, hi], color=VERMILION, lw=2, label="N(0, 1): sample = theory")
    ax.plot(th, sample, "o", color=BLUE, ms=3, alpha=0.7, label="your values (sorted)")
    ax.set(xlabel="N(0, 1) quantile (unitless)", ylabel="quantile of your values (unitless)")
    ax.legend(loc="upper left")
    slope = _slope(th, sample)
    alt = (f"QQ plot of {len(th)} quantiles of the printed values against the standard normal. "
           f"The points follow a line of slope {fmt(slope, 2)} (1 for N(0, 1); the slope is the standard "
           f"deviation).")
    return Plot(fig, title=QQ_TITLE, alt=alt)


def _slope(x: list[float], y: list[float]) -> float | None:
    pts = [(a, b) for a, b in zip(x, y) if math.isfinite(a) and math.isfinite(b)]
    if len(pts) < 2:
        return None
    mx = sum(a for a, _ in pts) / len(pts)
    my = sum(b for _, b in pts) / len(pts)
    den = sum((a - mx) ** 2 for a, _ in pts)
    return sum((a - mx) * (b - my) for a, b in pts) / den if den else None

