"""The collateral-loss audit: does one mistake cost only the items about it?

The mutation audit asks "does some item lose points when the code is wrong?". This one asks the
other question (issue 37): when the reference is changed in one aspect the way students change
it (``grader.audit.aspects``: a node's name, a topic's name, a log line printed instead, a timer's
period), do *only* the items about that aspect lose points? An item is about an aspect when its
analyzer judges it (``register(judges=...)``, ``timing=``) and, for a name, when its parameters
name the contract entry that was renamed (a name the lab does not fix is about no item). Every
other lost item is a collateral loss: the student pays twice for one mistake. A rubric records
a collateral loss it accepts, with why, in ``accepted_collateral``; the report says
"collateral losses: N (M accepted)".

It grades with the mutation audit's machinery (``grader.audit.run``: the reference first, at full
marks, then every mutant as one batch with recording reuse), and writes ``collateral.json`` and
``collateral.md`` next to the audit's own files.
"""

from __future__ import annotations

import ast
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from grader.api import load_rubric
from grader.api.rubrics import item_roles, judges
from grader.audit.aspects import ASPECT_OPERATORS, ASPECTS
from grader.audit.outcome import AuditReport, Outcome
from grader.audit.run import run_audit

#: the contract kinds whose names each name aspect renames
_NAME_KINDS = {"node names": ("nodes",), "ros names": ("topics", "services", "actions")}


@dataclass
class MutantLoss:
    """What one one-aspect mutant cost."""

    mutant: str
    description: str
    aspect: str
    about: list[str]                       # items that judge what it changed
    lost: dict[str, float]                 # item -> points lost
    collateral: dict[str, float] = field(default_factory=dict)    # lost, not about it, not accepted
    accepted: dict[str, str] = field(default_factory=dict)        # item -> the rubric's reason
    status: str = "killed"                 # the mutation audit's status (killed, surviving, ...)


@dataclass
class CollateralReport:
    lab: str
    rubric: str
    mutants: list[MutantLoss]

    @property
    def collateral(self) -> int:
        return sum(len(m.collateral) for m in self.mutants)

    @property
    def accepted(self) -> int:
        return sum(len(m.accepted) for m in self.mutants)

    def headline(self) -> str:
        return (f"{len(self.mutants)} one-aspect mutants; collateral losses: {self.collateral + self.accepted} "
                f"({self.accepted} accepted)")

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "collateral_losses": self.collateral + self.accepted, "accepted_losses": self.accepted}


def _renamed(original: str) -> str:
    """The name a rename mutant changed (its original source is a string literal)."""
    try:
        value = ast.literal_eval(original)
    except (ValueError, SyntaxError):
        return original
    return str(value).strip("/").rsplit("/", 1)[-1]


def roles_named(rubric: Any, aspect: str, name: str) -> set[str]:
    """Contract roles of ``aspect``'s kinds whose name is ``name`` (namespace and / aside)."""
    kinds = _NAME_KINDS.get(aspect, ())
    return {role for kind, role, entry in rubric.contract.entries()
            if kind in kinds and str(entry.name).strip("/").rsplit("/", 1)[-1] == name}


def items_about(rubric: Any, aspect: str, original: str) -> list[str]:
    """The automatic items that judge what a mutant of ``aspect`` changed."""
    roles = roles_named(rubric, aspect, _renamed(original)) if aspect in _NAME_KINDS else set()
    out = []
    for item in rubric.items:
        if not item.automatic or aspect not in judges(item.analyzer):
            continue
        if aspect in _NAME_KINDS and not roles & item_roles(rubric.contract, item):
            continue
        out.append(item.id)
    return out


def classify(rubric: Any, outcome: Outcome) -> MutantLoss:
    m = outcome.mutant
    aspect = ASPECTS[str(m["operator"])]
    about = items_about(rubric, aspect, str(m["original"]))
    reasons = {item: a.reason for a in rubric.accepted_collateral if a.mutant == m["id"] for item in a.items}
    loss = MutantLoss(mutant=str(m["id"]), description=str(m["description"]), aspect=aspect, about=about,
                      lost=dict(outcome.lost), status=outcome.status)
    for item, points in outcome.lost.items():
        if item in about:
            continue
        if item in reasons:
            loss.accepted[item] = reasons[item]
        else:
            loss.collateral[item] = points
    return loss


def run_collateral(rubric_path: Path, out: Path, *, say: Callable[[str], None] = print,
                   **audit_options: Any) -> CollateralReport:
    """Grade the reference's one-aspect mutants (``audit_options`` as for ``run_audit``) and
    classify what each cost; writes ``collateral.json`` and ``collateral.md`` into ``out``."""
    audit: AuditReport = run_audit(rubric_path, out, operators=list(ASPECT_OPERATORS), say=say, **audit_options)
    rubric = load_rubric(rubric_path)
    report = CollateralReport(lab=audit.lab, rubric=audit.rubric,
                              mutants=[classify(rubric, o) for o in audit.outcomes if o.status != "error"])
    out = Path(out)
    (out / "collateral.json").write_text(json.dumps(report.to_json(), indent=1) + "\n")
    (out / "collateral.md").write_text(markdown(report, errors=[o for o in audit.outcomes if o.status == "error"]))
    return report


def _points(lost: dict[str, float]) -> str:
    return ", ".join(f"{k} -{v:g}" for k, v in lost.items()) or "—"


def text_summary(report: CollateralReport) -> str:
    lines = [f"{report.lab}: collateral-loss audit of {report.rubric}", f"  {report.headline()}"]
    for m in report.mutants:
        if m.collateral:
            lines.append(f"  COLLATERAL {m.mutant} ({m.aspect}: {m.description}): {_points(m.collateral)}"
                         f"  [about it: {', '.join(m.about) or 'no item'}]")
    return "\n".join(lines)


def _by_reason(accepted: dict[str, str]) -> dict[str, list[str]]:
    """The accepted items grouped by their reason (one rubric entry's items share one)."""
    out: dict[str, list[str]] = {}
    for item, reason in accepted.items():
        out.setdefault(reason, []).append(item)
    return out


def markdown(report: CollateralReport, errors: Sequence[Outcome] = ()) -> str:
    out = [f"# Collateral-loss audit: {report.lab}", "", f"Rubric `{report.rubric}`. {report.headline()}.", "",
           "| mutant | aspect | change | items about it | lost | collateral | accepted |",
           "|---|---|---|---|---|---|---|"]
    for m in report.mutants:
        desc = m.description.replace("|", "\\|")
        accepted = "; ".join(f"{', '.join(items)}: {reason}" for reason, items in _by_reason(m.accepted).items()
                             ).replace("|", "\\|") or "—"
        out.append(f"| `{m.mutant}` | {m.aspect} | {desc} | {', '.join(m.about) or '—'} | {_points(m.lost)} | "
                   f"{_points(m.collateral)} | {accepted} |")
    if errors:
        out += ["", f"Not graded: {', '.join(str(o.mutant['id']) for o in errors)}."]
    return "\n".join(out) + "\n"
