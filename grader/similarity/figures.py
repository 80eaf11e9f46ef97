"""Figures of a pair's side-by-side page: both submissions' trajectories (and command series) on
one matplotlib plot, over the rest of the class in grey, so the page shows at a glance whether
the two share a path that the class does not drive."""

from __future__ import annotations

from typing import Any, Mapping

from grader.report.figures import _LOCK, Plot, RenderedFigure
from grader.report.figures._mpl import BLUE, MUTED, OUTSIDE, STYLE, VERMILION, new_figure, rc_context, to_svg

MAX_FIGURES = 4


def _values(summary: Mapping[str, Any], key: str) -> dict[str, Any]:
    out = {}
    for sid, feats in (summary.get("_features") or {}).items():
        for f in feats:
            if f.key == key:
                out[sid] = f.value
                break
    return out


def _path_plot(key: str, label: str, a: str, b: str, values: Mapping[str, Any], shared: Mapping[str, Any]) -> Plot:
    title = f"Both trajectories, {label}: the two submissions in colour, the rest of the class in grey"
    fig, ax = new_figure(title, (6.4, 4.6), legend_width=2.0)
    others = [sid for sid in values if sid not in (a, b)]
    for i, sid in enumerate(others):
        xy = values[sid]
        ax.plot([p[0] for p in xy], [p[1] for p in xy], color=MUTED, lw=0.8, alpha=0.5,
                label="other submissions" if i == 0 else None)
    for sid, colour, style in ((a, BLUE, "-"), (b, VERMILION, "--")):
        xy = values.get(sid) or []
        if xy:
            ax.plot([p[0] for p in xy], [p[1] for p in xy], color=colour, ls=style, lw=1.8, label=sid)
            ax.plot([xy[0][0]], [xy[0][1]], marker="o", color=colour)
    ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal")
    ax.legend(**OUTSIDE)
    alt = (f"Trajectories of {a} and {b} ({label}), {100 * (shared.get('distance') or 0):.1f} cm apart (RMS), "
           f"drawn over {len(others)} other submissions; {shared.get('holders')} of the class drive a path this "
           f"close to one of them.")
    return Plot(fig, title, alt)


def _series_plot(key: str, label: str, a: str, b: str, values: Mapping[str, Any], shared: Mapping[str, Any]) -> Plot:
    from grader.similarity.behaviour import CMD_GRID_S

    title = f"Both series, {label}: the two submissions in colour, the rest of the class in grey"
    fig, ax = new_figure(title, (6.4, 3.4), legend_width=2.0)
    grouped = shared.get("group") == "commands"
    for i, sid in enumerate(s for s in values if s not in (a, b)):
        ys = values[sid]
        xs = [k * CMD_GRID_S for k in range(len(ys))] if grouped else list(range(len(ys)))
        ax.plot(xs, ys, color=MUTED, lw=0.8, alpha=0.5, label="other submissions" if i == 0 else None)
    for sid, colour, style in ((a, BLUE, "-"), (b, VERMILION, "--")):
        ys = values.get(sid) or []
        xs = [k * CMD_GRID_S for k in range(len(ys))] if grouped else list(range(len(ys)))
        ax.plot(xs, ys, color=colour, ls=style, lw=1.8, label=sid)
    ax.set(xlabel="time after the first change (s)" if grouped else "quantile (0, 10, 25, 50, 75, 90, 100 %)",
           ylabel="value (unitless)")
    ax.legend(**OUTSIDE)
    alt = f"{label} of {a} and {b} on one plot over the rest of the class; {shared.get('holders')} submissions this close."
    return Plot(fig, title, alt)


def overlay_figures(p: Mapping[str, Any], summary: Mapping[str, Any]) -> list[RenderedFigure]:
    """Up to MAX_FIGURES figures of the pair's most telling shared paths and series."""
    out: list[RenderedFigure] = []
    seen: set[str] = set()
    for f in p.get("features") or ():
        if len(out) >= MAX_FIGURES or f["key"] in seen or f["group"] not in ("path", "commands"):
            continue
        seen.add(f["key"])
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
