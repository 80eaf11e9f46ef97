"""matplotlib set-up shared by the figures: Agg backend, one style, figures → inline SVG.

Why SVG text (``svg.fonttype: none``) instead of glyph paths: the figure stays a few tens of kB,
its text is selectable and searchable, and the page's own font is used. Why ids are rewritten:
several SVGs inlined in one HTML page share one id space, and matplotlib numbers its ids per
figure (``axes_1``, clip paths), so each figure's ids get a unique prefix.
"""

from __future__ import annotations

import io
import math
import re
import textwrap
from html import escape
from typing import Any

import matplotlib

matplotlib.use("Agg", force=False)   # no display; must precede any pyplot import anywhere

from cycler import cycler  # noqa: E402  (a matplotlib dependency)
from matplotlib import rc_context  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

#: Okabe-Ito: distinguishable with the common colour-vision deficiencies and in greyscale print
BLUE, ORANGE, GREEN, PINK, YELLOW, SKY, VERMILION, BLACK = (
    "#0072B2", "#E69F00", "#009E73", "#CC79A7", "#F0E442", "#56B4E9", "#D55E00", "#000000")
PALETTE = (BLUE, VERMILION, GREEN, PINK, ORANGE, SKY, BLACK)
LINESTYLES = ("-", "--", "-.", ":")
PASS, FAIL, MUTED = GREEN, VERMILION, "#777777"

STYLE: Any = {            # (typed Any: matplotlib types rc keys as a Literal)
    "font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8,
    "xtick.labelsize": 8, "ytick.labelsize": 8, "axes.titlelocation": "left",
    "axes.grid": True, "grid.color": "#dddddd", "grid.linewidth": 0.6,
    "axes.spines.top": False, "axes.spines.right": False, "axes.edgecolor": "#555555",
    "axes.prop_cycle": cycler(color=PALETTE),
    "legend.framealpha": 0.92, "legend.edgecolor": "#cccccc",
    "lines.linewidth": 1.5, "lines.markersize": 5,
    "svg.fonttype": "none", "svg.hashsalt": "grader-report",   # text as text; reproducible ids
    "figure.facecolor": "white", "font.family": "sans-serif",
}


def new_figure(title: str, size: tuple[float, float], nrows: int = 1, ncols: int = 1,
               legend_width: float = 0.0, **kwargs: Any) -> tuple[Figure, Any]:
    """A Figure with ``title`` (wrapped) at its top left and fixed margins in inches (matplotlib's
    constrained layout doubled the cost of a figure), ``legend_width`` inches kept free on the
    right for a legend outside the axes (``ax.legend(**OUTSIDE)``)."""
    width, height = size
    fig = Figure(figsize=size)
    lines = textwrap.wrap(title, max(30, int(width * 72 / 5.6)))
    fig.suptitle("\n".join(lines), x=0.1 / width, y=1 - 0.06 / height, ha="left", va="top",
                 fontsize=STYLE["axes.titlesize"], fontweight="bold")
    top = 0.2 + 0.18 * len(lines)
    fig.subplots_adjust(left=0.75 / width, right=1 - (0.15 + legend_width) / width,
                        bottom=0.55 / height, top=1 - top / height,
                        wspace=0.35 if ncols > 1 else None, hspace=0.35 if nrows > 1 else None)
    axes = fig.subplots(nrows, ncols, squeeze=True, **kwargs)
    for ax in fig.axes:          # ~6 ticks per axis: enough to read values, and each tick costs
        ax.xaxis.set_major_locator(MaxNLocator(6))
        ax.yaxis.set_major_locator(MaxNLocator(6))
    return fig, axes


#: ``ax.legend(**OUTSIDE)``: legend to the right of the axes (with ``legend_width`` kept free)
OUTSIDE: dict[str, Any] = {"loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "borderaxespad": 0.0}


def report_style() -> Any:
    """The report's matplotlib style, as a context: figures are drawn and written to SVG inside
    it (``svg.fonttype`` among its settings: written outside, text became glyph paths)."""
    return rc_context(STYLE)


_ID = re.compile(r'\bid="([^"]+)"')
_REF = re.compile(r'(url\(#|xlink:href="#|href="#)([^")]+)')


def to_svg(plot: Any, uid: str) -> str:
    """The figure of ``plot`` (a ``Plot``) as an inline ``<svg>`` element: accessible name and
    description from the plot's title and alt text, scalable (viewBox only), ids unique under ``uid``."""
    buf = io.StringIO()
    plot.fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None, "Format": None,
                                                  "Type": None})
    svg = buf.getvalue()
    svg = svg[svg.index("<svg"):]
    svg = re.sub(r"<metadata>.*?</metadata>\s*", "", svg, flags=re.S)
    svg = re.sub(r"<defs>\s*<style[^>]*>.*?</style>\s*</defs>\s*", "", svg, count=1, flags=re.S)
    svg = _ID.sub(lambda m: f'id="{uid}-{m.group(1)}"', svg)
    svg = _REF.sub(lambda m: f"{m.group(1)}{uid}-{m.group(2)}", svg)
    head = re.match(r"<svg[^>]*>", svg)
    assert head is not None
    box = re.search(r'viewBox="([^"]+)"', head.group(0))
    view = box.group(1) if box else "0 0 432 288"
    w_pt, h_pt = (float(v) for v in view.split()[2:4])
    root = (f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
            f'class="plot" role="img" viewBox="{view}" width="{w_pt * 4 / 3:.0f}" height="{h_pt * 4 / 3:.0f}" '
            f'aria-labelledby="{uid}-title {uid}-desc">'
            f'<title id="{uid}-title">{escape(plot.title)}</title>'
            f'<desc id="{uid}-desc">{escape(plot.alt)}</desc>')
    return root + svg[head.end():].strip()


# -- helpers for figure modules ---------------------------------------------------------------

def key(ax: Any, label: str, marker: str = "none", color: str = "black", ls: str = "none", **kw: Any) -> None:
    """A legend entry only (nothing drawn): explains a marker used in several colours."""
    ax.plot([], [], marker=marker, color=color, ls=ls, label=label, **kw)


def floats(values: Any) -> list[float] | None:
    """A list of finite-or-NaN floats, or None when ``values`` is not a list of numbers (null
    becomes NaN: evidence stores NaN as null)."""
    if not isinstance(values, (list, tuple)):
        return None
    out = []
    for v in values:
        if v is None:
            out.append(math.nan)
        elif isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        else:
            out.append(float(v))
    return out


def num(value: Any) -> float | None:
    """A finite float, or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    v = float(value)
    return v if math.isfinite(v) else None


def fmt(value: float | None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "n/a"
    return f"{value:.{digits}g}"
