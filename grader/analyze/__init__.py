"""Analyzers: pure functions ``(frames, params) -> Finding`` that turn a recorded bag into evidence.

Why pure: every grade must be recomputable from its bag alone, offline, in milliseconds, and
testable on synthetic DataFrames. So analyzers only read the ``frames`` dict produced by
``grader.bag.frames.load_frames`` (plus its ``"__meta__"`` frame) and never import rclpy.

Registry
--------
Analyzers come from three places, all registered with the same ``@register`` and validated the
same way (``grader.analyze.plugins``): every public module of this package (discovered, no list
to edit), the modules an installed distribution names under the entry point group
``grader.analyzers``, and Python files next to a rubric that names them (``analyzers:
[my_lab_checks.py]``). A name defined twice is an error naming both places.

``@register("name", params=Params)`` records an analyzer and the parameters it accepts: a
``grader.contracts.params.AnalyzerParams`` model (types, bounds, defaults, one line of meaning
each, which the rubric guide prints). The registered callable validates the caller's ``params``
against it, rejects unknown keys (a misspelt rubric parameter must not silently fall back to a
default) and calls the analyzer with the model. (A plug-in may declare ``defaults={...}``
instead, a plain dict: names are checked, values are not, and the analyzer gets a dict.) ``get(name)`` returns the
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
import math
import traceback
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Mapping

import pandas as pd
from pydantic import ValidationError

from grader.analyze.plugins import load_builtin_and_installed
from grader.analyze.registry import (_DEFAULTS, _EXPECT, _JUDGES, _LABELS, _ORIGIN, _PARAMS, _REGISTRY,
                                     _TIMING, DuplicateAnalyzer, _defining, forget)
from grader.errors import GraderError
from grader.contracts.jsonable import jsonable
from grader.contracts.params import AnalyzerParams, default_values, explained
from grader.contracts.status import STATUSES

__all__ = ["Finding", "register", "get", "names", "forget", "defaults", "required", "run", "jsonable", "STATUSES",
           "evidence_labels", "expected_text", "REQUIRED", "DuplicateAnalyzer", "origin", "graded",
           "builtin_names", "params_model", "effective_params", "AnalyzerParams"]


class _Required:
    """Default of a parameter the rubric must give (the loader rejects an item without it)."""

    def __repr__(self) -> str:
        return "REQUIRED"

    def __deepcopy__(self, memo: dict) -> "_Required":
        return self


REQUIRED = _Required()


Frames = Mapping[str, pd.DataFrame]
AnalyzerFn = Callable[[Frames, Any], "Finding"]

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
             params: type[AnalyzerParams] | None = None,
             evidence: Mapping[str, Any] | None = None,
             expect: str | None = None, timing: str | None = None,
             judges: tuple[str, ...] = ()) -> Callable[[AnalyzerFn], AnalyzerFn]:
    """Register an analyzer under ``name`` with the parameters it accepts (``params``, a model;
    or ``defaults``, a plain dict of names and defaults), the labels and units of its evidence
    and what it expects, in words (both for the report). ``timing``: what wall or simulated
    timing its verdict depends on, in words ("the publish rate"), for an analyzer whose verdict
    a CPU-starved recording can change. ``judges``: the aspects of the code it is about ("node
    names", "ros names", "logging"); the collateral-loss audit expects a mistake in an aspect to
    cost only the items of analyzers that judge it."""
    if params is not None and defaults is not None:
        raise ValueError(f"analyzer {name!r}: declare params= or defaults=, not both")
    dflt = _declared_defaults(params) if params is not None else dict(defaults or {})

    def deco(fn: AnalyzerFn) -> AnalyzerFn:
        origin = _defining[-1] if _defining else fn.__module__
        if name in _REGISTRY:
            raise DuplicateAnalyzer(f"analyzer {name!r} is defined twice: by {_ORIGIN.get(name, '?')} and by "
                                    f"{origin}; rename one of them")

        @functools.wraps(fn)
        def wrapper(frames: Frames, given_params: Mapping[str, Any] | None = None) -> Finding:
            given = dict(given_params or {})
            merged = _checked(name, dflt, given)
            finding = fn(frames, _validated(name, params, given) if params is not None
                         else copy.deepcopy(merged))        # analyzers may not mutate shared defaults
            finding.params = jsonable(merged)            # every threshold that decided it
            if isinstance(finding, Finding) and "scenario_start" not in finding.evidence:
                from grader.analyze._common import scenario_start  # noqa: PLC0415 - at the head it would close a circle: analyze -> analyze._common -> analyze

                t0 = scenario_start(frames)
                if t0 is not None:
                    finding.evidence["scenario_start"] = t0
            return finding

        wrapper.analyzer_name = name  # type: ignore[attr-defined]
        wrapper.defaults = dict(dflt)  # type: ignore[attr-defined]
        _REGISTRY[name] = wrapper
        _ORIGIN[name] = origin
        _DEFAULTS[name] = dict(dflt)
        if params is not None:
            _PARAMS[name] = params
        _LABELS[name] = dict(evidence or {})
        if expect:
            _EXPECT[name] = expect
        if timing:
            _TIMING[name] = timing
        _JUDGES[name] = tuple(judges) + (("timing",) if timing else ())
        return wrapper

    return deco


def _declared_defaults(model: type[AnalyzerParams]) -> dict[str, Any]:
    """A model's fields as ``{name: default}``, REQUIRED for those without one."""
    declared = default_values(model)
    return {key: declared.get(key, REQUIRED) for key in model.model_fields}


def _checked(name: str, dflt: Mapping[str, Any], given: Mapping[str, Any]) -> dict[str, Any]:
    """``given`` over the defaults, as the rubric wrote them; GraderError for an unknown or
    missing parameter."""
    unknown = sorted(set(given) - set(dflt))
    if unknown:
        raise GraderError(f"analyzer {name!r}: unknown parameter(s) {', '.join(unknown)}; "
                          f"accepted: {', '.join(sorted(dflt)) or '(none)'}")
    missing = sorted(k for k, v in dflt.items() if v is REQUIRED and k not in given)
    if missing:
        raise GraderError(f"analyzer {name!r} needs the parameter(s) {', '.join(missing)}")
    return {**copy.deepcopy(dict(dflt)), **given}


def _validated(name: str, model: type[AnalyzerParams], given: Mapping[str, Any]) -> AnalyzerParams:
    """The model of ``given`` (validated once); GraderError naming each value it refuses."""
    try:
        return model.model_validate(dict(given))
    except ValidationError as exc:
        wrong = explained(model, exc)
        raise GraderError(f"analyzer {name!r}: " + "; ".join(f"{key}: {why}" for key, why in wrong)) from None


def _load_all() -> None:
    """Import the built-in analyzer modules and the installed plug-ins (once per process)."""
    load_builtin_and_installed()


def origin(name: str) -> str:
    """Where analyzer ``name`` was defined: its module, ``entry point ...`` or a rubric's file."""
    get(name)
    return _ORIGIN[name]


def get(name: str) -> AnalyzerFn:
    """The registered analyzer ``name``; GraderError naming the known ones if there is none."""
    _load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise GraderError(f"unknown analyzer {name!r}; known: {', '.join(sorted(_REGISTRY))}") from None


def names() -> list[str]:
    """Every registered analyzer: built in, installed plug-ins, rubric files loaded so far."""
    _load_all()
    return sorted(_REGISTRY)


def builtin_names() -> list[str]:
    """The analyzers of this package's own modules (what the rubric guide documents)."""
    _load_all()
    return sorted(n for n in _REGISTRY if _ORIGIN.get(n, "").startswith(f"{__name__}."))


def defaults(name: str) -> dict[str, Any]:
    """Accepted parameters of analyzer ``name`` with their default values."""
    get(name)
    return copy.deepcopy(_DEFAULTS[name])


def evidence_labels(name: str | None) -> dict[str, Any]:
    """``{key: (label, unit) | None}`` for analyzer ``name``'s evidence (common keys included);
    only the common table for an unknown or missing analyzer (e.g. a result of an older grader)."""
    from grader.analyze.evidence import merged  # noqa: PLC0415 - at the head it would close a circle: analyze -> analyze.evidence -> analyze

    if name:
        _load_all()
    return merged(_LABELS.get(name or "", {}))


def expected_text(name: str | None) -> str | None:
    """Analyzer ``name``'s expected result in words (a template over params and evidence)."""
    if name:
        _load_all()
    return _EXPECT.get(name or "")


def timing(name: str | None, declared: bool | None = None) -> str | None:
    """What timing analyzer ``name``'s verdict depends on, in words (None: none). ``declared``:
    a rubric item's own ``timing`` (True/False), which overrides the analyzer's declaration."""
    if name:
        _load_all()
    words = _TIMING.get(name or "")
    if declared is None:
        return words
    return (words or "its timing") if declared else None


def judges(name: str | None) -> tuple[str, ...]:
    """The aspects of the code analyzer ``name`` judges (``register(judges=...)``, and
    ``timing`` when it declares its timing)."""
    if name:
        _load_all()
    return _JUDGES.get(name or "", ())


def params_model(name: str) -> type[AnalyzerParams] | None:
    """Analyzer ``name``'s parameter model (None for a plug-in that declared a plain dict)."""
    get(name)
    return _PARAMS.get(name)


def effective_params(name: str, given: Mapping[str, Any]) -> dict[str, Any]:
    """The values analyzer ``name`` runs with for a rubric's ``given`` parameters: the given
    over the declared defaults, as written (what a finding's ``params`` records)."""
    get(name)
    return {**copy.deepcopy(_DEFAULTS[name]), **dict(given)}


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
