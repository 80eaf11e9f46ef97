"""Analyzers: pure functions ``(frames, params) -> Finding`` that turn a recorded bag into evidence.

Why pure: every grade must be recomputable from its bag alone, offline, in milliseconds, and
testable on synthetic DataFrames. So analyzers only read the ``frames`` dict produced by
``grader.bag.frames.load_frames`` (plus its ``"__meta__"`` frame) and never import rclpy.

Registry
--------
``@register("name", defaults={...})`` records an analyzer and the parameters it accepts. The
registered callable merges the caller's ``params`` over those defaults and rejects unknown keys
(a misspelt rubric parameter must not silently fall back to a default). ``get(name)`` returns the
registered callable, ``names()`` lists them, ``defaults(name)`` shows the accepted parameters (the
rubric loader can validate YAML against it), and ``run(name, frames, params)`` never raises: an
analyzer crash becomes a ``Finding`` with status ``"error"``.

``register`` also records what the evidence means (``evidence=`` labels and units, ``expect=``
the expected result in words; see ``grader.analyze.evidence``); ``evidence_labels(name)`` and
``expected_text(name)`` give them to the report. Every finding's evidence gets
``scenario_start`` (epoch seconds of the scenario's ``scenario_start`` event, when recorded), so
the times in it can be shown as seconds since the scenario started.
"""

from __future__ import annotations

import copy
import functools
import importlib
import math
import traceback
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
import pandas as pd

from grader.errors import GraderError

__all__ = ["Finding", "register", "get", "names", "defaults", "required", "run", "jsonable", "STATUSES",
           "evidence_labels", "expected_text", "REQUIRED"]


class _Required:
    """Default of a parameter the rubric must give (the loader rejects an item without it)."""

    def __repr__(self) -> str:
        return "REQUIRED"

    def __deepcopy__(self, memo: dict) -> "_Required":
        return self


REQUIRED = _Required()

STATUSES = ("pass", "partial", "fail", "error")

# Modules whose import registers analyzers. Imported lazily by get()/names() so that importing
# grader.analyze itself stays cheap and free of import cycles.
_MODULES = (
    "rate",
    "random_numbers",
    "boxmuller",
    "controller",
    "control_law",
    "goal_publisher",
    "action_server",
    "integrity",
    "graph",
    "services",
    "motion",
    "logs",
    "pen",
)

Frames = Mapping[str, pd.DataFrame]
AnalyzerFn = Callable[[Frames, dict], "Finding"]

_REGISTRY: dict[str, AnalyzerFn] = {}
_DEFAULTS: dict[str, dict[str, Any]] = {}
_LABELS: dict[str, dict[str, Any]] = {}
_EXPECT: dict[str, str] = {}
_loaded = False


def jsonable(obj: Any) -> Any:
    """Convert numpy/pandas values to plain JSON types; NaN and infinities become None.

    Evidence goes straight into result.json and the HTML report, so it must serialise with the
    standard ``json`` module and never contain NaN (which is not valid JSON).
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, set)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [jsonable(v) for v in obj.tolist()]
    if isinstance(obj, pd.DataFrame):
        return [jsonable(r) for r in obj.to_dict(orient="records")]
    if isinstance(obj, pd.Series):
        return jsonable(obj.to_dict())
    if obj is pd.NA or obj is pd.NaT:
        return None
    return str(obj)


@dataclass
class Finding:
    """What one analyzer concluded about one rubric item.

    value: headline measurement (e.g. 0.998 Hz, "58/60 matched").
    fraction: 0.0..1.0 of the item's points earned (partial credit).
    status: "pass" | "partial" | "fail" | "error" (error = analysis impossible, not the student's
        fault as far as we can tell, e.g. the scenario produced no events).
    feedback: one or two sentences for the student.
    evidence: numbers/tables that justify it (JSON-serialisable; normalised on construction).
    """

    value: Any
    fraction: float
    status: str
    feedback: str
    evidence: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)    # the parameters it ran with (defaults merged)
    #: how the grade was decided when a scenario ran more than once (grader.grading.repeat):
    #: runs, how many agreed, each run's outcome; empty for an analyzer's own finding
    decided: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"Finding.status must be one of {STATUSES}, got {self.status!r}")
        f = float(self.fraction)
        if not math.isfinite(f):
            f = 0.0
        self.fraction = min(1.0, max(0.0, f))
        self.value = jsonable(self.value)
        self.evidence = jsonable(dict(self.evidence or {}))
        self.params = jsonable(dict(self.params or {}))

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def error(cls, feedback: str, evidence: dict | None = None, value: Any = None) -> "Finding":
        """Analysis impossible (scenario failed, input missing for reasons outside the student's code)."""
        return cls(value=value, fraction=0.0, status="error", feedback=feedback, evidence=evidence or {})

    @classmethod
    def fail(cls, feedback: str, evidence: dict | None = None, value: Any = None) -> "Finding":
        return cls(value=value, fraction=0.0, status="fail", feedback=feedback, evidence=evidence or {})


def graded(fraction: float, *, pass_at: float = 1.0 - 1e-9) -> str:
    """Status that matches a fraction: pass (full), partial (some), fail (none)."""
    if fraction >= pass_at:
        return "pass"
    if fraction > 0.0:
        return "partial"
    return "fail"


def register(name: str, defaults: Mapping[str, Any] | None = None, *,
             evidence: Mapping[str, Any] | None = None,
             expect: str | None = None) -> Callable[[AnalyzerFn], AnalyzerFn]:
    """Register an analyzer under ``name`` with the parameters it accepts and their defaults,
    the labels and units of its evidence and what it expects, in words (both for the report)."""
    dflt = dict(defaults or {})

    def deco(fn: AnalyzerFn) -> AnalyzerFn:
        if name in _REGISTRY:
            raise ValueError(f"analyzer {name!r} registered twice")

        @functools.wraps(fn)
        def wrapper(frames: Frames, params: Mapping[str, Any] | None = None) -> Finding:
            given = dict(params or {})
            unknown = sorted(set(given) - set(dflt))
            if unknown:
                raise GraderError(
                    f"analyzer {name!r}: unknown parameter(s) {', '.join(unknown)}; "
                    f"accepted: {', '.join(sorted(dflt)) or '(none)'}"
                )
            missing = sorted(k for k, v in dflt.items() if v is REQUIRED and k not in given)
            if missing:
                raise GraderError(f"analyzer {name!r} needs the parameter(s) {', '.join(missing)}")
            merged = {**copy.deepcopy(dflt), **given}   # analyzers may not mutate shared defaults
            finding = fn(frames, copy.deepcopy(merged))
            finding.params = jsonable(merged)            # every threshold that decided it
            if isinstance(finding, Finding) and "scenario_start" not in finding.evidence:
                from grader.analyze._common import scenario_start

                t0 = scenario_start(frames)
                if t0 is not None:
                    finding.evidence["scenario_start"] = t0
            return finding

        wrapper.analyzer_name = name  # type: ignore[attr-defined]
        wrapper.defaults = dict(dflt)  # type: ignore[attr-defined]
        _REGISTRY[name] = wrapper
        _DEFAULTS[name] = dict(dflt)
        _LABELS[name] = dict(evidence or {})
        if expect:
            _EXPECT[name] = expect
        return wrapper

    return deco


def _load_all() -> None:
    global _loaded
    if _loaded:
        return
    for mod in _MODULES:
        importlib.import_module(f"{__name__}.{mod}")
    _loaded = True


def get(name: str) -> AnalyzerFn:
    """The registered analyzer ``name``; GraderError naming the known ones if there is none."""
    _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise GraderError(f"unknown analyzer {name!r}; known: {', '.join(sorted(_REGISTRY))}") from None


def names() -> list[str]:
    _load_all()
    return sorted(_REGISTRY)


def defaults(name: str) -> dict[str, Any]:
    """Accepted parameters of analyzer ``name`` with their default values."""
    get(name)
    return copy.deepcopy(_DEFAULTS[name])


def evidence_labels(name: str | None) -> dict[str, Any]:
    """``{key: (label, unit) | None}`` for analyzer ``name``'s evidence (common keys included);
    only the common table for an unknown or missing analyzer (e.g. a result of an older grader)."""
    from grader.analyze.evidence import merged

    if name:
        _load_all()
    return merged(_LABELS.get(name or "", {}))


def expected_text(name: str | None) -> str | None:
    """Analyzer ``name``'s expected result in words (a template over params and evidence)."""
    if name:
        _load_all()
    return _EXPECT.get(name or "")


def required(name: str) -> list[str]:
    """Parameters of analyzer ``name`` that have no default (a rubric must give them)."""
    get(name)
    return sorted(k for k, v in _DEFAULTS[name].items() if v is REQUIRED)


def run(name: str, frames: Frames, params: Mapping[str, Any] | None = None) -> Finding:
    """Run an analyzer; any exception becomes an "error" Finding (a grade never dies on one item)."""
    try:
        fn = get(name)
        return fn(frames, dict(params or {}))
    except GraderError as exc:
        return Finding.error(f"Analyzer configuration problem: {exc}", {"analyzer": name})
    except Exception as exc:  # noqa: BLE001 - deliberately total
        tb = traceback.format_exception(type(exc), exc, exc.__traceback__)
        return Finding.error(
            f"Internal analyzer error in {name!r}: {type(exc).__name__}: {exc}",
            {"analyzer": name, "traceback": "".join(tb[-6:])},
        )
