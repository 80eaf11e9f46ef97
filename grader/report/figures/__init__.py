"""Figures of the report: matplotlib (Agg) drawings of an item's evidence, inlined as SVG.

A figure is chosen by the item's analyzer. Adding one is one function in a module of this package
(every module here is imported on first use; no list to edit), in an installed plug-in's module
or in a rubric's analyzer file (``grader.analyze.plugins``: they are imported before figures are
drawn)::

    from grader.report.figures import FigureContext, Plot, figure

    @figure("circle_fit")                       # analyzer name(s) whose items get this figure
    def fitted_circle(ctx: FigureContext) -> Plot | None:
        pts = ctx.evidence.get("points")        # plot series the analyzer put in its evidence
        if not pts:
            return None                         # nothing to draw: no figure, never an error
        title = "The path should follow the fitted circle"
        fig, ax = ctx.axes(title, size=(5.0, 4.2))
        ax.plot(pts["x"], pts["y"], label="turtle path")
        ax.set(xlabel="x (m)", ylabel="y (m)")
        ax.legend()
        return Plot(fig, title=title, alt="Turtle path and the fitted circle of radius 2.0 m ...")

Rules every figure follows (the Chromium test checks the last two): axes labelled with units, a
legend, a title that says what to look at, and alt text that states the data in words. Figures
read only ``ctx.evidence`` and ``ctx.params`` (both already stripped of hidden thresholds in the
student view), so a report can be redrawn from result.json without the bag. Times in plot
series are seconds since the scenario started (``grader.analyze._common.since_start``).

Cost: matplotlib is imported on the first figure (~0.6 s CPU, once per process); a figure costs
~30-60 ms CPU (see benchmarks/bench_report.py).
"""

from __future__ import annotations

import importlib
import pkgutil
import threading
import traceback
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from grader.rubric.result import ItemResult
from grader.analyze.plugins import load_builtin_and_installed

__all__ = ["FigureContext", "Plot", "RenderedFigure", "figure", "figures_for", "registered"]


@dataclass
class Plot:
    """What a figure function returns: the matplotlib Figure, its title (what to look at) and
    its alt text (the data in words, for screen readers and when images are off)."""

    fig: Any
    title: str
    alt: str


@dataclass(frozen=True)
class RenderedFigure:
    svg: str          # inline <svg> with <title>/<desc>, ids unique in the page
    title: str
    alt: str


@dataclass(frozen=True)
class FigureContext:
    """Everything a figure may use. ``params``: the item's effective analyzer parameters."""

    item: ItemResult
    evidence: Mapping[str, Any]
    params: Mapping[str, Any] = field(default_factory=dict)
    student_view: bool = False

    def param(self, name: str, default: Any = None) -> Any:
        """A threshold from the params, else the same key echoed in the evidence."""
        value = self.params.get(name)
        if value is None:
            value = self.evidence.get(name)
        return default if value is None else value

    def axes(self, title: str, size: tuple[float, float] = (6.0, 3.6), nrows: int = 1, ncols: int = 1,
             legend_width: float = 0.0, **kwargs: Any) -> tuple[Any, Any]:
        """A new matplotlib Figure (no pyplot, so no global state) titled ``title`` (what to look
        at), and its axes; ``legend_width`` inches on the right are kept for a legend placed with
        ``ax.legend(**OUTSIDE)`` (from ``grader.report.figures._mpl``)."""
        from grader.report.figures._mpl import new_figure  # noqa: PLC0415 - report.figures._mpl loads matplotlib (311 ms CPU), only on this path

        return new_figure(title, size, nrows, ncols, legend_width, **kwargs)


FigureFn = Callable[[FigureContext], "Plot | Sequence[Plot] | None"]
_FIGURES: dict[str, list[FigureFn]] = {}
_LOCK = threading.Lock()          # matplotlib's rc settings are process-global
_loaded = False


def figure(*analyzers: str) -> Callable[[FigureFn], FigureFn]:
    """Register a figure function for the items of these analyzers (in registration order)."""
    if not analyzers:
        raise ValueError("@figure needs at least one analyzer name")

    def deco(fn: FigureFn) -> FigureFn:
        for name in analyzers:
            _FIGURES.setdefault(name, []).append(fn)
        return fn

    return deco


def _load_all() -> None:
    """Import this package's figure modules, then the installed plug-ins (which may draw some);
    a rubric's analyzer files were imported when the rubric was loaded."""
    global _loaded
    if _loaded:
        return
    for mod in pkgutil.iter_modules(__path__):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{__name__}.{mod.name}")
    _loaded = True

    load_builtin_and_installed()


def defined_by(module: str) -> bool:
    """Whether a figure of module ``module`` is registered (a plug-in file that only draws)."""
    return any(fn.__module__ == module for fns in _FIGURES.values() for fn in fns)


def forget_module(module: str) -> None:
    """Unregister the figures a module defined (its plug-in file was unloaded or reloaded)."""
    for name in list(_FIGURES):
        _FIGURES[name] = [fn for fn in _FIGURES[name] if fn.__module__ != module]
        if not _FIGURES[name]:
            del _FIGURES[name]


def registered() -> dict[str, list[str]]:
    """analyzer -> names of its figure functions (for docs and tests)."""
    _load_all()
    return {k: [f.__name__ for f in v] for k, v in sorted(_FIGURES.items())}


def figures_for(ctx: FigureContext, uid: str) -> tuple[list[RenderedFigure], list[str]]:
    """Every figure of ``ctx.item``'s analyzer as inline SVG, and the errors of figures that
    failed (a report always renders: a failing figure is left out, the error is returned).
    ``uid`` makes the SVG ids unique in the page."""
    _load_all()
    fns = _FIGURES.get(ctx.item.analyzer or "", [])
    if not fns or not ctx.evidence:
        return [], []
    from grader.report.figures._mpl import report_style, to_svg  # noqa: PLC0415 - report.figures._mpl loads matplotlib (311 ms CPU), only on this path

    out: list[RenderedFigure] = []
    errors: list[str] = []
    with _LOCK:
        for k, fn in enumerate(fns):
            try:
                with report_style():
                    made = fn(ctx)
                    plots: Sequence[Plot] = [] if made is None else ([made] if isinstance(made, Plot) else list(made))
                    out += [RenderedFigure(to_svg(p, f"{uid}-{k}-{n}"), p.title, p.alt) for n, p in enumerate(plots)]
            except Exception as exc:  # noqa: BLE001 - a figure never breaks a report
                tb = traceback.format_exception(type(exc), exc, exc.__traceback__)
                errors.append(f"{fn.__name__} ({ctx.item.id}): {type(exc).__name__}: {exc}\n"
                              + "".join(tb[-3:]))
    return out, errors
