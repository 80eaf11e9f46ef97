"""Figures of a pair's side-by-side page: both submissions' trajectories (and command series) on
one matplotlib plot, over the rest of the class in grey, so the page shows at a glance whether
the two share a path that the class does not drive."""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from matplotlib.collections import LineCollection

from grader.report.figures import _LOCK, Plot, RenderedFigure
from grader.report.figures._mpl import BLUE, MUTED, OUTSIDE, STYLE, VERMILION, new_figure, rc_context, to_svg
from grader.similarity.behaviour import CMD_GRID_S

MAX_FIGURES = 2         # a page's figures cost ~0.1 s each (matplotlib), and a class may list 50 pairs


def _values(summary: Mapping[str, Any], key: str) -> dict[str, Any]:
    out = {}
    for sid, feats in (summary.get("_features") or {}).items():
        for f in feats:
            if f.key == key:
                out[sid] = f.value
                break
    return out


def _path_plot(key: str, label: str, a: str, b: str, values: Mapping[str, Any], shared: Mapping[str, Any]) -> Plot:
    title = f"Both trajectories: {label}"            # the legend says which is which; the class in grey
    fig, ax = new_figure(title, (6.4, 4.6), legend_width=2.0)
    others = [sid for sid in values if sid not in (a, b)]
    if others:      # one artist for the whole class: a page of a 200-student class draws in 0.1 s
        ax.add_collection(LineCollection([np.asarray(values[sid], float).reshape(-1, 2) for sid in others],
                                         colors=MUTED, linewidths=0.8, alpha=0.5, label="other submissions"))
    for sid, colour, style in ((a, BLUE, "-"), (b, VERMILION, "--")):
        xy = values.get(sid) or []
        if xy:
            ax.plot([p[0] for p in xy], [p[1] for p in xy], color=colour, ls=style, lw=1.8, label=sid)
            ax.plot([xy[0][0]], [xy[0][1]], marker="o", color=colour)
    ax.autoscale_view()
    ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal")
    ax.legend(**OUTSIDE)
    alt = (f"Trajectories of {a} and {b} ({label}), {100 * (shared.get('distance') or 0):.1f} cm apart (RMS), "
           f"drawn over {len(others)} other submissions; {shared.get('holders')} of the class drive a path this "
           f"close to one of them.")
    return Plot(fig, title, alt)


def _series_plot(key: str, label: str, a: str, b: str, values: Mapping[str, Any], shared: Mapping[str, Any]) -> Plot:
    title = f"Both series: {label}"
    fig, ax = new_figure(title, (6.4, 3.4), legend_width=2.0)
    grouped = shared.get("group") == "commands"
    lines = []
    for sid in (s for s in values if s not in (a, b)):
        ys = np.asarray(values[sid], float)
        xs = np.arange(len(ys)) * (CMD_GRID_S if grouped else 1.0)
        lines.append(np.column_stack([xs, ys]))
    if lines:
        ax.add_collection(LineCollection(lines, colors=MUTED, linewidths=0.8, alpha=0.5, label="other submissions"))
    for sid, colour, style in ((a, BLUE, "-"), (b, VERMILION, "--")):
        own = values.get(sid) or []
        steps = [k * CMD_GRID_S for k in range(len(own))] if grouped else list(range(len(own)))
        ax.plot(steps, own, color=colour, ls=style, lw=1.8, label=sid)
    ax.autoscale_view()
    ax.set(xlabel="time after the first change (s)" if grouped else "quantile (0, 10, 25, 50, 75, 90, 100 %)",
           ylabel="value as published")
    ax.legend(**OUTSIDE)
    alt = f"{label} of {a} and {b} on one plot over the rest of the class; {shared.get('holders')} submissions this close."
    return Plot(fig, title, alt)


def overlay_figures(p: Mapping[str, Any], summary: Mapping[str, Any]) -> list[RenderedFigure]:
    """Up to MAX_FIGURES figures of the pair's most telling shared path and command series (one
    of each first, when it has both)."""
    out: list[RenderedFigure] = []
    feats = [f for f in p.get("features") or () if f["group"] in ("path", "commands")]
    firsts = [next((f for f in feats if f["group"] == g), None) for g in ("path", "commands")]
    ordered = [f for f in firsts if f] + [f for f in feats if f not in firsts]
    for f in ordered:
        if len(out) >= MAX_FIGURES:
            break
        values = _values(summary, f["key"])
        if p["a"] not in values or p["b"] not in values:
            continue
        maker = _path_plot if f["group"] == "path" else _series_plot
        try:
            with _LOCK, rc_context(STYLE):
                plot = maker(f["key"], f["label"], p["a"], p["b"], values, f)
                out.append(RenderedFigure(to_svg(plot, f"sim{len(out)}"), plot.title, plot.alt))
        except Exception:  # noqa: BLE001 - a figure that cannot be drawn is left out, never the page
            continue
    return out


__all__ = ["overlay_figures"]
