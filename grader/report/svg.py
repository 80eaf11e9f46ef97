"""Tiny inline-SVG plots for the HTML report (no plotting library: reports must stay
self-contained and the grader must not grow a matplotlib dependency).

Plots are built from analyzer ``evidence``:
* ``trajectory``: ``{x: [...], y: [...], goals?: [[x, y], ...], label?}`` or a list of those
  (one per goal/step) -> turtle path in the turtlesim world (0..11.09 m square);
* ``histogram``: ``{bins: [...], counts: [...], reference?: "normal" | {normal: {mean, std}}}``
  where bins are edges (len(counts)+1) or centres (len(counts)) -> bars, plus the expected
  counts of the reference normal distribution when one is named.
Malformed evidence yields no plot rather than an error: a report must always render.
"""

from __future__ import annotations

import math
from html import escape
from typing import Any, Iterable, Mapping, Sequence

WORLD_M = 11.088889122009277        # turtlesim world width = height (see specs)
# Okabe-Ito: distinguishable with common colour-vision deficiencies
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
MAX_POINTS = 1500


def _floats(values: Any) -> list[float] | None:
    if not isinstance(values, (list, tuple)):
        return None
    out = []
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        out.append(float(v))
    return out


def _fmt(v: float) -> str:
    return f"{v:.2f}".rstrip("0").rstrip(".") if abs(v) < 1e4 else f"{v:.3g}"


def nice_ticks(lo: float, hi: float, count: int = 5) -> list[float]:
    """Round tick values (1, 2, 5 x 10^k steps) covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / max(1, count)
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 5, 10)), key=lambda s: abs(math.log(s / raw)))
    start = math.ceil(lo / step - 1e-9) * step
    ticks, v = [], start
    while v <= hi + 1e-9 * step:
        ticks.append(round(v, 10))
        v += step
    return ticks


class _Frame:
    """Maps data coordinates into a plot area with margins for axes labels."""

    def __init__(self, x0: float, x1: float, y0: float, y1: float, width: int = 360,
                 height: int = 300, left: int = 44, right: int = 12, top: int = 12,
                 bottom: int = 36) -> None:
        self.x0, self.x1, self.y0, self.y1 = x0, x1, y0, y1
        self.w, self.h = width, height
        self.left, self.right, self.top, self.bottom = left, right, top, bottom

    def px(self, x: float) -> float:
        return self.left + (x - self.x0) / (self.x1 - self.x0) * (self.w - self.left - self.right)

    def py(self, y: float) -> float:
        return self.h - self.bottom - (y - self.y0) / (self.y1 - self.y0) * (self.h - self.top - self.bottom)

    def axes(self, xlabel: str, ylabel: str) -> list[str]:
        out = [f'<rect x="{self.left}" y="{self.top}" width="{self.w - self.left - self.right}" '
               f'height="{self.h - self.top - self.bottom}" fill="none" stroke="#555" stroke-width="1"/>']
        for t in nice_ticks(self.x0, self.x1):
            x = self.px(t)
            out.append(f'<line x1="{x:.1f}" y1="{self.h - self.bottom}" x2="{x:.1f}" '
                       f'y2="{self.h - self.bottom + 4}" stroke="#555"/>')
            out.append(f'<text x="{x:.1f}" y="{self.h - self.bottom + 15}" text-anchor="middle">{_fmt(t)}</text>')
        for t in nice_ticks(self.y0, self.y1):
            y = self.py(t)
            out.append(f'<line x1="{self.left - 4}" y1="{y:.1f}" x2="{self.left}" y2="{y:.1f}" stroke="#555"/>')
            out.append(f'<text x="{self.left - 6}" y="{y + 3.5:.1f}" text-anchor="end">{_fmt(t)}</text>')
        cx = (self.left + self.w - self.right) / 2
        out.append(f'<text x="{cx:.1f}" y="{self.h - 4}" text-anchor="middle">{escape(xlabel)}</text>')
        cy = (self.top + self.h - self.bottom) / 2
        out.append(f'<text x="11" y="{cy:.1f}" text-anchor="middle" '
                   f'transform="rotate(-90 11 {cy:.1f})">{escape(ylabel)}</text>')
        return out


def _svg(frame: _Frame, title: str, desc: str, body: Iterable[str]) -> str:
    return (f'<svg xmlns="http://www.w3.org/2000/svg" class="plot" role="img" '
            f'viewBox="0 0 {frame.w} {frame.h}" width="{frame.w}" height="{frame.h}" '
            f'font-family="sans-serif" font-size="10" fill="#222">'
            f'<title>{escape(title)}</title><desc>{escape(desc)}</desc>{"".join(body)}</svg>')


def _thin(xs: list[float], ys: list[float]) -> tuple[list[float], list[float]]:
    step = max(1, math.ceil(len(xs) / MAX_POINTS))
    if step == 1:
        return xs, ys
    keep = list(range(0, len(xs), step))
    if keep[-1] != len(xs) - 1:
        keep.append(len(xs) - 1)
    return [xs[i] for i in keep], [ys[i] for i in keep]


def _paths(evidence: Any) -> list[dict[str, Any]]:
    """Normalise ``trajectory`` evidence into a list of {x, y, label, goals}."""
    entries = evidence if isinstance(evidence, list) else [evidence]
    out = []
    for index, entry in enumerate(entries):
        if not isinstance(entry, Mapping):
            continue
        xs, ys = _floats(entry.get("x")), _floats(entry.get("y"))
        if xs is None or ys is None or len(xs) != len(ys) or not xs:
            continue
        pairs = [(x, y) for x, y in zip(xs, ys) if math.isfinite(x) and math.isfinite(y)]
        if not pairs:
            continue
        goals = []
        for g in (entry.get("goals") or ([entry["goal"]] if "goal" in entry else [])):
            g = _floats(g)
            if g is not None and len(g) == 2:
                goals.append(g)
        label = entry.get("label")
        out.append({"x": [p[0] for p in pairs], "y": [p[1] for p in pairs],
                    "label": str(label) if label is not None else f"path {index + 1}",
                    "goals": goals})
    return out


def trajectory_svg(evidence: Any, title: str = "Turtle trajectory") -> str | None:
    """Turtle path(s) in world coordinates with goals; None when the evidence is unusable."""
    paths = _paths(evidence)
    if not paths:
        return None
    lo = min(0.0, *(min(p["x"] + p["y"]) for p in paths))
    hi = max(WORLD_M, *(max(p["x"] + p["y"]) for p in paths))
    frame = _Frame(lo, hi, lo, hi, width=330, height=330, bottom=36)
    body = frame.axes("x (m)", "y (m)")
    legend_y = frame.top + 12
    descs = []
    for index, path in enumerate(paths):
        colour = PALETTE[index % len(PALETTE)]
        xs, ys = _thin(path["x"], path["y"])
        points = " ".join(f"{frame.px(x):.1f},{frame.py(y):.1f}" for x, y in zip(xs, ys))
        body.append(f'<polyline points="{points}" fill="none" stroke="{colour}" stroke-width="1.6" '
                    f'stroke-linejoin="round"/>')
        sx, sy = frame.px(xs[0]), frame.py(ys[0])
        body.append(f'<circle cx="{sx:.1f}" cy="{sy:.1f}" r="3" fill="{colour}"/>')
        for gx, gy in path["goals"]:
            cx, cy = frame.px(gx), frame.py(gy)
            body.append(f'<path d="M{cx - 5:.1f},{cy - 5:.1f}L{cx + 5:.1f},{cy + 5:.1f}'
                        f'M{cx - 5:.1f},{cy + 5:.1f}L{cx + 5:.1f},{cy - 5:.1f}" '
                        f'stroke="{colour}" stroke-width="2"/>')
        if len(paths) > 1 or path["goals"]:
            lx = frame.left + 8
            body.append(f'<line x1="{lx}" y1="{legend_y - 3}" x2="{lx + 14}" y2="{legend_y - 3}" '
                        f'stroke="{colour}" stroke-width="2"/>'
                        f'<text x="{lx + 18}" y="{legend_y}">{escape(path["label"])}</text>')
            legend_y += 13
        goals = ", ".join(f"({_fmt(g[0])}, {_fmt(g[1])})" for g in path["goals"])
        descs.append(f'{path["label"]}: from ({_fmt(path["x"][0])}, {_fmt(path["y"][0])}) to '
                     f'({_fmt(path["x"][-1])}, {_fmt(path["y"][-1])})'
                     + (f", goal {goals}" if goals else ""))
    return _svg(frame, title, "; ".join(descs) + ". Dots mark starts, crosses mark goals.", body)


def _normal_cdf(x: float, mean: float, std: float) -> float:
    return 0.5 * (1 + math.erf((x - mean) / (std * math.sqrt(2))))


def _reference(spec: Any) -> tuple[float, float] | None:
    if spec == "normal":
        return 0.0, 1.0
    if isinstance(spec, Mapping) and isinstance(spec.get("normal"), Mapping):
        mean = spec["normal"].get("mean", 0.0)
        std = spec["normal"].get("std", 1.0)
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (mean, std)) and std > 0:
            return float(mean), float(std)
    return None


def _edges(bins: list[float], n: int) -> list[float] | None:
    if len(bins) == n + 1:
        edges = bins
    elif len(bins) == n and n >= 2:
        half = [(b - a) / 2 for a, b in zip(bins, bins[1:])]
        edges = [bins[0] - half[0]] + [a + h for a, h in zip(bins, half)] + [bins[-1] + half[-1]]
    else:
        return None
    if any(b <= a for a, b in zip(edges, edges[1:])) or not all(map(math.isfinite, edges)):
        return None
    return edges


def histogram_svg(evidence: Any, title: str = "Histogram") -> str | None:
    """Bars of ``counts`` over ``bins`` with an optional normal reference curve."""
    if not isinstance(evidence, Mapping):
        return None
    counts = _floats(evidence.get("counts"))
    bins = _floats(evidence.get("bins"))
    if not counts or bins is None or any(c < 0 or not math.isfinite(c) for c in counts):
        return None
    edges = _edges(bins, len(counts))
    if edges is None:
        return None
    ref = _reference(evidence.get("reference"))
    total = sum(counts)
    expected: list[tuple[float, float]] = []
    if ref and total > 0:
        mean, std = ref
        width = (edges[-1] - edges[0]) / len(counts)
        steps = 120
        for k in range(steps + 1):
            x = edges[0] + (edges[-1] - edges[0]) * k / steps
            pdf = math.exp(-0.5 * ((x - mean) / std) ** 2) / (std * math.sqrt(2 * math.pi))
            expected.append((x, total * width * pdf))
    top = max([*counts, *(e for _, e in expected), 1.0]) * 1.08
    frame = _Frame(edges[0], edges[-1], 0.0, top, width=360, height=240)
    body = frame.axes(str(evidence.get("xlabel", "value")), "count")
    for (a, b), c in zip(zip(edges, edges[1:]), counts):
        x, w = frame.px(a), frame.px(b) - frame.px(a)
        y = frame.py(c)
        body.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{max(w - 0.6, 0.4):.1f}" '
                    f'height="{frame.py(0) - y:.1f}" fill="#56B4E9" stroke="#0072B2" stroke-width="0.5"/>')
    desc = f"{int(total)} values in {len(counts)} bins from {_fmt(edges[0])} to {_fmt(edges[-1])}"
    if expected:
        pts = " ".join(f"{frame.px(x):.1f},{frame.py(y):.1f}" for x, y in expected)
        body.append(f'<polyline points="{pts}" fill="none" stroke="#D55E00" stroke-width="2"/>')
        lx = frame.w - frame.right - 110
        body.append(f'<line x1="{lx}" y1="{frame.top + 10}" x2="{lx + 14}" y2="{frame.top + 10}" '
                    f'stroke="#D55E00" stroke-width="2"/><text x="{lx + 18}" y="{frame.top + 13}">'
                    f'normal({_fmt(ref[0])}, {_fmt(ref[1])}) expected</text>')
        desc += f"; the curve shows the counts expected from a normal({_fmt(ref[0])}, {_fmt(ref[1])}) distribution"
    return _svg(frame, title, desc + ".", body)


PLOT_KEYS = ("trajectory", "histogram")


def plots_for(evidence: Mapping[str, Any], item_title: str) -> list[str]:
    """Every plot the evidence supports, as SVG strings."""
    plots = []
    if "trajectory" in evidence:
        svg = trajectory_svg(evidence["trajectory"], f"Trajectory: {item_title}")
        if svg:
            plots.append(svg)
    if "histogram" in evidence:
        svg = histogram_svg(evidence["histogram"], f"Histogram: {item_title}")
        if svg:
            plots.append(svg)
    return plots


__all__: Sequence[str] = ("histogram_svg", "trajectory_svg", "plots_for", "nice_ticks", "PLOT_KEYS")
