"""The class view's figure: the distribution of automatic scores."""

from __future__ import annotations

import statistics
from typing import Sequence

from grader.report.figures import _LOCK, Plot, RenderedFigure
from grader.report.figures._mpl import BLUE, STYLE, VERMILION, new_figure, rc_context, to_svg

TITLE = "Automatic scores of the class: where most of the class stands, and who is far below"


def score_histogram(scores: Sequence[float], max_score: float, uid: str = "dist") -> RenderedFigure | None:
    """Histogram of ``scores`` on [0, max_score] in about ten bins, with the median marked."""
    if not scores or max_score <= 0:
        return None
    step = max(1.0, round(max_score / 10))
    edges = [k * step for k in range(int(max_score // step) + 1)]
    if edges[-1] < max_score:
        edges.append(max_score)
    edges[-1] += 1e-9                       # a full score falls in the last bin
    median = statistics.median(scores)
    with _LOCK, rc_context(STYLE):
        fig, ax = new_figure(TITLE, (7.6, 3.2), legend_width=2.2)
        counts, _, _ = ax.hist(list(scores), bins=edges, color="#9ecae1", edgecolor=BLUE, lw=0.8,
                               label=f"submissions ({len(scores)})")
        ax.axvline(median, color=VERMILION, lw=2, ls="--", label=f"median {median:g}")
        ax.set(xlabel=f"automatic score (points out of {max_score:g})", ylabel="submissions (count)",
               xlim=(0, max_score))
        ax.yaxis.get_major_locator().set_params(integer=True)
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
        bins = [f"{int(c)} between {edges[k]:g} and {min(edges[k + 1], max_score):g}"
                for k, c in enumerate(counts) if c]
        alt = (f"Histogram of the automatic scores of {len(scores)} submissions out of {max_score:g} points: "
               f"median {median:g}, lowest {min(scores):g}, highest {max(scores):g}. " + "; ".join(bins) + ".")
        plot = Plot(fig, TITLE, alt)
        return RenderedFigure(to_svg(plot, uid), TITLE, alt)
