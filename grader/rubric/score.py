"""Scoring: apply a rubric to analyzer findings. Pure, no I/O, so a grade is recomputable.

``score(rubric, findings)`` turns each item's Finding (duck-typed: ``value``, ``fraction``,
``status``, ``feedback``, ``evidence``; see grader.analyze) into points with the item's
partial-credit rule, fills the rubric's feedback templates, and collects what needs a human:
ungraded manual items (kept as empty points), advisory warnings (0 points) and integrity flags.

The model it fills (``Result``, ``ItemResult``, the sections and the student view) is
``grader.rubric.result``.
"""

from __future__ import annotations

import math
import string
from dataclasses import replace
from typing import Any, Iterable, Mapping, Protocol

from grader.errors import GraderError
from grader.contracts.contract import Mismatch
from grader.rubric.result import PENDING, ItemResult, Result
from grader.rubric.schema import Item, Rubric
from grader.contracts.status import STATUSES

_RANK = {"fail": 0, "partial": 1, "error": 2, "pass": 3}


class FindingLike(Protocol):
    value: Any
    fraction: float
    status: str
    feedback: str
    evidence: dict


def score(rubric: Rubric, findings: Mapping[str, FindingLike | None], *,
          manual: Mapping[str, float] | None = None, contract: Iterable[Mismatch] | None = None) -> Result:
    """Score every rubric item.

    ``findings``: item id -> Finding, or None when the analysis could not run (scenario crashed,
    bag missing); absent ids count as None. ``manual``: points a person gave to manual items.
    ``contract``: the contract names the recordings show under another name (default: the
    ``contract`` of ``findings``, as ``grader.grading.analysis.analyze_bags`` returns them);
    each blocks the items that depend on it and did not pass. Unknown ids in ``findings`` are a
    programming error (ValueError); bad manual points are a user error (GraderError).
    """
    ids = set(rubric.item_ids)
    stray = sorted(set(findings) - ids)
    if stray:
        raise ValueError(f"findings for items not in rubric {rubric.lab}: {', '.join(stray)}")
    manual = dict(manual or {})
    _check_manual(rubric, manual)
    items = []
    for item in rubric.items:
        if item.kind == "manual":
            items.append(_score_manual(item, manual.get(item.id)))
        else:
            items.append(_score_auto(item, findings.get(item.id)))
    mismatches = tuple(contract if contract is not None else getattr(findings, "contract", ()) or ())
    items, mismatches = _block(rubric, items, mismatches)
    items = _gate(items)
    return Result(lab=rubric.lab, title=rubric.title, items=tuple(items),
                  section_specs=tuple(rubric.sections), contract=mismatches)


def _block(rubric: Rubric, items: list[ItemResult], mismatches: tuple[Mismatch, ...]
           ) -> tuple[list[ItemResult], tuple[Mismatch, ...]]:
    """A contract name spelt differently is one finding; the items that depend on it (their
    parameters name it, or their scenario runs or drives it) and failed are blocked by it: 0
    points, its sentence as their feedback, their own verdict kept in the evidence. An item that
    passed or partly passed anyway keeps its result; integrity flags keep theirs."""
    if not mismatches:
        return items, mismatches
    blocks: dict[int, list[str]] = {i: [] for i in range(len(mismatches))}
    out = []
    for result in items:
        item = rubric.item(result.id)
        if item.kind not in ("auto", "advisory") or result.status not in ("fail", "error"):
            out.append(result)
            continue
        by = [k for k, m in enumerate(mismatches)
              if any(sc in m.scenarios and m.role in rubric.item_roles(item, sc) for sc in item.scenario)]
        if not by:
            out.append(result)
            continue
        for k in by:
            blocks[k].append(result.id)
        text = " ".join(dict.fromkeys(mismatches[k].feedback for k in by))
        out.append(replace(result, points=0.0 if item.kind == "auto" else result.points, status="fail",
                           feedback=text, evidence={**result.evidence, "blocked_by": [mismatches[k].role for k in by],
                                                    "own_status": result.status, "own_feedback": result.feedback}))
    return out, tuple(replace(m, blocks=tuple(blocks[k])) for k, m in enumerate(mismatches))


def _gate(items: list[ItemResult]) -> list[ItemResult]:
    """Items with ``requires`` earn their points only once every required item earned some
    (passed, or partly: Lab 3's server that reaches two of three goals has written the control
    loop, so its advertised action and its rejection of an out-of-bounds goal are its own work).
    The gate keeps given code from earning points; "passes fully" made one chaotic goal of a
    buggy server cost five more points in one run of three (bench_flake, issue 22)."""
    earned = {i.id: (i.points or 0) > 0 and i.status in ("pass", "partial") for i in items}
    status = {i.id: i.status for i in items}
    out = []
    for item in items:
        unmet = [r for r in item.requires if not earned.get(r)]
        if not unmet or not item.points:
            out.append(item)
            continue
        names = ", ".join(f"{r} ({status.get(r, 'missing')})" for r in unmet)
        text = (f"No points yet: this item counts once {' and '.join(unmet)} "
                f"{'earns' if len(unmet) == 1 else 'earn'} points (now: {names}). " + item.feedback).strip()
        out.append(replace(item, points=0.0, status="fail", feedback=text,
                           evidence={**item.evidence, "gated_by": unmet, "own_status": item.status,
                                     "own_points": item.points}))
    return out


def worst_finding(findings: Iterable[FindingLike | None]) -> FindingLike | None:
    """For an item run on several scenarios: the worst finding counts (fail < partial < error
    < pass, then lowest fraction). Missing findings are ignored; all missing gives None."""
    present = [f for f in findings if f is not None]
    if not present:
        return None
    return min(present, key=lambda f: (_RANK.get(str(f.status), 2), _fraction(f.fraction)))


def _check_manual(rubric: Rubric, manual: Mapping[str, float]) -> None:
    problems = []
    for item_id, points in manual.items():
        try:
            item = rubric.item(item_id)
        except KeyError:
            problems.append(f"{item_id}: not an item of rubric {rubric.lab}")
            continue
        if item.kind != "manual":
            problems.append(f"{item_id}: is graded automatically ({item.kind}), not by hand")
        elif (isinstance(points, bool) or not isinstance(points, (int, float))
              or not math.isfinite(points) or not 0 <= points <= item.points):
            problems.append(f"{item_id}: expected points between 0 and {item.points:g}, got {points!r}")
    if problems:
        raise GraderError("manual grades: " + "; ".join(problems))


def _score_manual(item: Item, points: float | None) -> ItemResult:
    if points is None:
        return _result(item, None, PENDING, "Graded by the instructor.", None)
    status = "pass" if points >= item.points else ("fail" if points == 0 else "partial")
    return _result(item, round(float(points), 2), status, "", points / item.points)


def _score_auto(item: Item, finding: FindingLike | None) -> ItemResult:
    if finding is None:
        text = item.feedback.get("error") or (
            "Not checked: the automatic analysis did not run (see the run log).")
        return _result(item, 0.0, "error", text, None)
    fraction = _fraction(getattr(finding, "fraction", 0.0))
    status = str(getattr(finding, "status", "error"))
    if status not in STATUSES:
        status = "error"
    if item.kind == "auto":
        points = 0.0 if status == "error" else round(item.partial.credit(fraction) * item.points, 2)
        if status != "error":
            status = ("pass" if points >= item.points - 1e-9
                      else "fail" if points <= 1e-9 else "partial")
    else:                        # advisory / integrity: 0 points, the analyzer's verdict stands
        points = 0.0
    evidence = getattr(finding, "evidence", None) or {}
    text = _feedback(item, status, finding, fraction, points, evidence)
    decided = dict(getattr(finding, "decided", None) or {"by": "one run", "runs": 1})
    if decided.get("outcomes"):           # each run's points and status under this item's rule
        decided["outcomes"] = [{**o, **_scored(item, o.get("status"), o.get("fraction"))}
                               for o in decided["outcomes"]]
    return replace(_result(item, points, status, text, fraction, value=getattr(finding, "value", None),
                           evidence=evidence, params=getattr(finding, "params", None) or None),
                   decided=decided)


def _scored(item: Item, status: Any, fraction: Any) -> dict[str, Any]:
    """One run's points and status as this item scores them (as in :func:`_score_auto`)."""
    if item.kind != "auto" or status == "error":
        return {"points": 0.0, "status": status}
    points = round(item.partial.credit(_fraction(fraction)) * item.points, 2)
    return {"points": points,
            "status": "pass" if points >= item.points - 1e-9 else "fail" if points <= 1e-9 else "partial"}


def _fraction(value: Any) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return 0.0
    return min(1.0, max(0.0, value)) if math.isfinite(value) else 0.0


def _result(item: Item, points: float | None, status: str, feedback: str, fraction: float | None,
            value: Any = None, evidence: Mapping[str, Any] | None = None,
            params: Mapping[str, Any] | None = None) -> ItemResult:
    return ItemResult(id=item.id, title=item.title, section=item.section, kind=item.kind,
                      public=item.public, points=points, max_points=item.points, status=status,
                      feedback=feedback, hint=item.hint, value=value, fraction=fraction,
                      evidence=dict(evidence or {}), params=dict(params if params is not None else item.params),
                      hidden_params=tuple(item.hidden_params), requires=tuple(item.requires),
                      analyzer=item.analyzer)


def _feedback(item: Item, status: str, finding: FindingLike, fraction: float,
              points: float, evidence: Mapping[str, Any]) -> str:
    """The rubric's text for this status (partial falls back to fail), else the analyzer's.

    A finding whose evidence lists ``student_moves`` (student code moved the turtle without
    driving it: grader.analyze.provenance) keeps the analyzer's words: a rubric's advice is
    written for a solution that is wrong, and would tell a cheat to check its signs."""
    own = str(getattr(finding, "feedback", "") or "")
    if evidence.get("student_moves"):
        return own
    template = item.feedback.get(status)
    if template is None and status == "partial":
        template = item.feedback.get("fail")
    if template is None:
        return own
    context: dict[str, Any] = dict(getattr(finding, "params", None) or item.params)
    context.update({k: v for k, v in evidence.items() if isinstance(k, str)})
    context.update(value=getattr(finding, "value", None), fraction=fraction,
                   points=points, max_points=item.points,
                   status=status, feedback=own, id=item.id, title=item.title)
    return render_template(template, context)


class _Missing:
    """Stands in for an unknown placeholder: the text stays as written, e.g. ``{rate}``."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __format__(self, spec: str) -> str:
        return "{" + self.text + (":" + spec if spec else "") + "}"


class _Formatter(string.Formatter):
    def get_field(self, field_name: str, args: Any, kwargs: Any) -> tuple[Any, str]:
        try:
            value, key = super().get_field(field_name, args, kwargs)
            return value, str(key)
        except (KeyError, AttributeError, IndexError, TypeError, ValueError):
            return _Missing(field_name), field_name

    def format_field(self, value: Any, format_spec: str) -> str:
        if value is None:
            return "n/a"
        try:
            return str(super().format_field(value, format_spec))
        except (ValueError, TypeError):
            return str(value)

    def convert_field(self, value: Any, conversion: str | None) -> Any:
        if isinstance(value, _Missing):
            return value
        return super().convert_field(value, conversion)


def render_template(template: str, context: Mapping[str, Any]) -> str:
    """``str.format`` that never fails: unknown names stay visible, bad specs fall back to str."""
    try:
        return _Formatter().vformat(template, (), dict(context))
    except (ValueError, IndexError):   # malformed template slipped past validation
        return template
