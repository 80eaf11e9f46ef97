"""The analyzers' registry: what ``@register`` records per name, shared by the package's face
(``grader.analyze``: ``register``, ``get``, ``run``) and the loader of built-in modules, plug-ins and
rubric files (``grader.analyze.plugins``), which both read and change it; here, neither imports
the other for it.
"""

from __future__ import annotations

from typing import Any, Callable, Collection

from grader.errors import GraderError

#: name -> the registered callable ``(frames, params) -> Finding``
_REGISTRY: dict[str, Callable[..., Any]] = {}
_DEFAULTS: dict[str, dict[str, Any]] = {}
#: name -> its parameter model (grader.contracts.params), for an analyzer that declares one
_PARAMS: dict[str, Any] = {}
_LABELS: dict[str, dict[str, Any]] = {}
_EXPECT: dict[str, str] = {}
#: name -> what timing its verdict depends on, in words (a rate, a period, a timeout): such an
#: item cannot lose points on a recording the grading machine starved (grader.grading.starvation)
_TIMING: dict[str, str] = {}
#: name -> the aspects of the code it judges ("node names", "ros names", "logging"): a mistake
#: in that aspect is this analyzer's to charge (grader.audit.collateral)
_JUDGES: dict[str, tuple[str, ...]] = {}
_ORIGIN: dict[str, str] = {}      # name -> where it was defined (a module, an entry point, a file)
#: set by grader.analyze.plugins while it imports a plug-in, so a name says where it came from
_defining: list[str] = []


class DuplicateAnalyzer(GraderError, ValueError):
    """An analyzer name defined twice (by two modules, plug-ins or rubric files)."""


def forget(names_: Collection[str]) -> None:
    """Unregister analyzers (a plug-in file reloaded after it changed, or unloaded by a test)."""
    for name in names_:
        for table in (_REGISTRY, _DEFAULTS, _PARAMS, _LABELS, _EXPECT, _ORIGIN, _TIMING, _JUDGES):
            table.pop(name, None)
