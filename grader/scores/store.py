"""Manual scores kept next to a grade: ``OUT/<id>/manual_scores.json``.

result.json is rewritten by every ``grader grade`` / ``grader regrade`` from the bags, so the
points a TA gave (``grader scores merge``) live in their own file that the pipeline re-applies
after scoring. A re-grade thus never loses them, and the file travels with the submission's
folder. Shape::

    {"schema": 1, "lab": "enee467-lab3", "submission": "alice",
     "items": {"q1": {"points": 7.0, "comment": "Rate is right, units missing.",
                      "source": "manual.csv line 3", "merged_at": "2025-01-31T17:02:11Z"}}}

Only graded items are listed; an item set back to ``pending`` is removed. A TA's override of the
late policy's penalty (the ``late_penalty`` column of a merged sheet) is kept beside them as
``"late_penalty": {"points": 0.0, "source": ..., "merged_at": ...}``.
"""

from __future__ import annotations

import json
import os
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Iterator, Mapping

from grader.errors import GraderError
from grader.rubric.result import PENDING, ItemResult, Result
from grader.report.result import atomic_write

MANUAL_SCORES = "manual_scores.json"
STORE_SCHEMA = 1
#: what an ungraded manual item says (as grader.rubric.score writes it)
PENDING_FEEDBACK = "Graded by the instructor."


@dataclass(frozen=True)
class ManualScore:
    """Points a person gave to one manual item, with the comment shown in the report."""

    points: float
    comment: str = ""
    source: str = ""               # where it came from: "manual.csv line 3"
    merged_at: str = ""            # UTC time of the merge that set it


def graded_item(item: ItemResult, score: ManualScore) -> ItemResult:
    """The manual item with these points: status as for any item (all points pass, none fail,
    partial between) and the comment as its feedback."""
    points = round(float(score.points), 2)
    status = "pass" if points >= item.max_points else ("fail" if points == 0 else "partial")
    fraction = points / item.max_points if item.max_points else None
    return replace(item, points=points, status=status, fraction=fraction, feedback=score.comment)


def pending_item(item: ItemResult) -> ItemResult:
    return replace(item, points=None, status=PENDING, fraction=None, feedback=PENDING_FEEDBACK)


def apply_manual_scores(result: Result, scores: Mapping[str, ManualScore]) -> Result:
    """``result`` with every manual item set from ``scores`` (pending when absent)."""
    items = tuple(
        (graded_item(i, scores[i.id]) if i.id in scores else pending_item(i)) if i.kind == "manual" else i
        for i in result.items)
    return replace(result, items=items)


def check_score(item: ItemResult | None, item_id: str, points: float) -> str | None:
    """Why ``points`` cannot be ``item_id``'s manual score in this result, or None."""
    if item is None:
        return f"{item_id} is not an item of this lab"
    if item.kind != "manual":
        return f"{item_id} is graded automatically ({item.kind})"
    if not 0 <= points <= item.max_points:
        return f"{points:g} is outside 0..{item.max_points:g} points"
    return None


# -- the file ---------------------------------------------------------------------------------

def _score(v: Mapping[str, Any]) -> ManualScore:
    return ManualScore(points=float(v["points"]), comment=str(v.get("comment", "")),
                       source=str(v.get("source", "")), merged_at=str(v.get("merged_at", "")))


def _read(sub_out: str | os.PathLike[str]) -> dict[str, Any] | None:
    path = Path(sub_out) / MANUAL_SCORES
    if not path.exists():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        if doc.get("schema") != STORE_SCHEMA:
            raise ValueError(f"schema {doc.get('schema')!r} is not {STORE_SCHEMA}")
        doc["items"] = {str(k): _score(v) for k, v in doc["items"].items()}
        late = doc.get("late_penalty")
        doc["late_penalty"] = _score(late) if late is not None else None
        doc["lab"] = str(doc["lab"])
        return doc
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise GraderError(f"{path} is not a readable manual-scores file ({exc}); fix or delete it "
                          f"and merge the TA's CSV again") from None


def _load(sub_out: str | os.PathLike[str]) -> tuple[str | None, dict[str, ManualScore]]:
    doc = _read(sub_out)
    return (None, {}) if doc is None else (str(doc["lab"]), doc["items"])


def load_manual_scores(sub_out: str | os.PathLike[str]) -> dict[str, ManualScore]:
    """The manual scores stored for one submission ({} when none were merged)."""
    return _load(sub_out)[1]


def load_late_override(sub_out: str | os.PathLike[str]) -> ManualScore | None:
    """The late penalty (points) a TA set for one submission, replacing the policy's; or None."""
    doc = _read(sub_out)
    return None if doc is None else doc["late_penalty"]


def manual_scores_text(lab: str, submission: str, scores: Mapping[str, ManualScore],
                       late: ManualScore | None = None) -> str:
    def entry(s: ManualScore) -> dict[str, Any]:
        return {"points": s.points, "comment": s.comment, "source": s.source, "merged_at": s.merged_at}

    doc: dict[str, Any] = {"schema": STORE_SCHEMA, "lab": lab, "submission": submission,
                           "items": {k: entry(s) for k, s in scores.items()}}
    if late is not None:
        doc["late_penalty"] = entry(late)
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


# -- the pipeline's hooks ---------------------------------------------------------------------

@contextmanager
def manual_scores_kept(sub_out: str | os.PathLike[str]) -> Iterator[None]:
    """Keep ``manual_scores.json`` while the block recreates the submission's folder
    (``grader grade`` starts each submission from an empty folder)."""
    path = Path(sub_out) / MANUAL_SCORES
    text = path.read_text(encoding="utf-8") if path.exists() else None
    try:
        yield
    finally:
        if text is not None and not path.exists():
            atomic_write(path, text)


def apply_saved_manual_scores(sub_out: str | os.PathLike[str], result: Result) -> tuple[Result, list[str]]:
    """Re-apply the merged manual scores of ``sub_out`` to a freshly scored ``result``
    (``grader grade`` / ``grader regrade``). A score the (changed) rubric no longer accepts is
    left out of the result, kept in the file and reported as a problem, never dropped silently."""
    lab, saved = _load(sub_out)
    if not saved:
        return result, []
    if lab != result.lab:
        return result, [f"{MANUAL_SCORES} holds scores for lab {lab!r}, not {result.lab!r}: not applied"]
    by_id = {i.id: i for i in result.items}
    usable: dict[str, ManualScore] = {}
    problems = []
    for item_id, score in saved.items():
        why = check_score(by_id.get(item_id), item_id, score.points)
        if why:
            problems.append(f"manual score {score.points:g} for {item_id} (in {MANUAL_SCORES}) not "
                            f"applied: {why}")
        else:
            usable[item_id] = score
    return apply_manual_scores(result, usable), problems
