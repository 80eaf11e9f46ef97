"""A graded submission as data: ``Result`` (every ``ItemResult``, notices, sections, the late
penalty, the totals) and the student's view of it (hidden items and evidence keys removed).
``grader.rubric.score`` fills it from analyzer findings; reports, exports and the class view
read it; ``result.json`` is it, written out.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from grader.rubric.schema import Section, SectionSpec

if TYPE_CHECKING:
    from grader.contracts.late import LatePenalty
    from grader.contracts.contract import Mismatch

#: status of a manual item nobody graded yet
PENDING = "pending"


@dataclass(frozen=True)
class ItemResult:
    """One scored item. ``points`` is None for a manual item nobody graded yet."""

    id: str
    title: str
    section: Section
    kind: str
    public: bool
    points: float | None
    max_points: float
    status: str                  # pass | partial | fail | error | pending
    feedback: str
    hint: str | None = None
    value: Any = None
    fraction: float | None = None
    evidence: Mapping[str, Any] = field(default_factory=dict)
    params: Mapping[str, Any] = field(default_factory=dict)       # thresholds that decided it
    #: how it was decided (grader.grading.repeat): {"by": "one run", "runs": 1}, or the median of
    #: repeated runs with how many agreed and each run's outcome and points; {} for manual items
    decided: Mapping[str, Any] = field(default_factory=dict)
    hidden_params: tuple[str, ...] = ()                           # not shown to students
    requires: tuple[str, ...] = ()                                # items gating its points
    analyzer: str | None = None  # the report looks up evidence labels and figures by analyzer


@dataclass(frozen=True)
class Notice:
    """An advisory warning or an integrity flag: something a person should read."""

    item_id: str
    title: str
    status: str
    feedback: str
    evidence: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SectionResult:
    section: Section
    title: str                 # display title: "Exercise 1: Random numbers"
    name: str | None           # the sections table's own title ("Random numbers"), if any
    points: float              # earned so far (auto + graded manual)
    max_points: float
    auto_points: float
    auto_max: float
    pending_max: float         # points of manual items not graded yet
    item_ids: tuple[str, ...]


@dataclass(frozen=True)
class Result:
    """Everything the report layer needs; totals are derived from ``items`` so they can't drift."""

    lab: str
    title: str
    items: tuple[ItemResult, ...]
    section_specs: tuple[SectionSpec, ...] = ()
    student_view: bool = False
    hidden_items: int = 0          # removed by for_student()
    hidden_points: float = 0.0
    late: "LatePenalty | None" = None   # the late policy's verdict (grader.intake.late), if any
    contract: tuple[Mismatch, ...] = ()   # contract names the student spelt differently

    def item(self, item_id: str) -> ItemResult:
        for item in self.items:
            if item.id == item_id:
                return item
        raise KeyError(item_id)

    @property
    def starved(self) -> dict[str, str]:
        """Item id -> why it was not measured: timing items that lost points on a recording the
        grading machine starved (``grader.grading.analysis.starved_timing``), to be recorded again."""
        return {i.id: str(i.evidence["starved"]) for i in self.items
                if i.status == "error" and isinstance(i.evidence, Mapping) and i.evidence.get("starved")}

    @property
    def starved_faster(self) -> dict[str, str]:
        """Those of :attr:`starved` measured on a recording made faster than real time (their
        limits were a K-th at K x): a recording at 1x is the one to make again."""
        starved = self.starved
        return {i.id: starved[i.id] for i in self.items
                if i.id in starved and float(i.evidence.get("starved_at_scale") or 1.0) > 1.0}

    @property
    def auto_score(self) -> float:
        return _sum(i.points for i in self.items if i.kind == "auto")

    @property
    def auto_max(self) -> float:
        return _sum(i.max_points for i in self.items if i.kind == "auto")

    @property
    def manual_max(self) -> float:
        return _sum(i.max_points for i in self.items if i.kind == "manual")

    @property
    def pending_max(self) -> float:
        return _sum(i.max_points for i in self.items if i.status == PENDING)

    @property
    def manual_score(self) -> float | None:
        """Points of manual items, or None while any of them is ungraded."""
        manual = [i for i in self.items if i.kind == "manual"]
        if any(i.points is None for i in manual):
            return None
        return _sum(i.points for i in manual)

    @property
    def score(self) -> float:
        """Points earned so far (automatic + manual items already graded)."""
        return _sum(i.points for i in self.items if i.points is not None)

    @property
    def max_score(self) -> float:
        return _sum(i.max_points for i in self.items)

    @property
    def late_penalty(self) -> float:
        """Points the late policy deducts (0 without one); never more than ``score``."""
        return 0.0 if self.late is None else self.late.points(self.score, self.max_score)

    @property
    def final_score(self) -> float:
        """``score`` less the late penalty: what a gradebook gets."""
        return round(self.score - self.late_penalty, 2)

    @property
    def complete(self) -> bool:
        return not any(i.status == PENDING for i in self.items)

    @property
    def total(self) -> float | None:
        """The final grade (late penalty deducted), once every manual item is graded; None before."""
        return self.final_score if self.complete else None

    @property
    def integrity_flags(self) -> tuple[Notice, ...]:
        """Integrity checks that did not pass cleanly (fail or partial): review by a person.
        An integrity check that could not run (error) is visible in its item row instead."""
        return tuple(_notice(i) for i in self.items
                     if i.kind == "integrity" and i.status in ("fail", "partial"))

    @property
    def warnings(self) -> tuple[Notice, ...]:
        """Advisory items that did not pass: shown to the student, worth no points."""
        return tuple(_notice(i) for i in self.items if i.kind == "advisory" and i.status != "pass")

    @property
    def sections(self) -> tuple[SectionResult, ...]:
        specs = list(self.section_specs)
        known = {s.section for s in specs}
        for item in self.items:
            if item.section not in known:
                known.add(item.section)
                specs.append(SectionSpec(section=item.section))
        out = []
        for spec in specs:
            items = [i for i in self.items if i.section == spec.section]
            if not items:
                continue
            auto = [i for i in items if i.kind == "auto"]
            out.append(SectionResult(
                section=spec.section, title=spec.display_title, name=spec.title,
                points=_sum(i.points for i in items if i.points is not None),
                max_points=_sum(i.max_points for i in items),
                auto_points=_sum(i.points for i in auto), auto_max=_sum(i.max_points for i in auto),
                pending_max=_sum(i.max_points for i in items if i.status == PENDING),
                item_ids=tuple(i.id for i in items)))
        return tuple(out)

    def for_student(self) -> "Result":
        """The self-check view: hidden (``public: false``) items and their points removed, and
        thresholds the rubric marks hidden (``hidden_params``) removed from each item's params
        and evidence."""
        visible = tuple(_without_hidden(i) for i in self.items if i.public)
        hidden = [i for i in self.items if not i.public]
        shown = {i.id for i in visible}
        contract = tuple(replace(m, blocks=tuple(b for b in m.blocks if b in shown)) for m in self.contract)
        return replace(self, items=visible, student_view=True, contract=contract,
                       hidden_items=self.hidden_items + len(hidden),
                       hidden_points=_sum([self.hidden_points, *(i.max_points for i in hidden)]))


def _without_hidden(item: ItemResult) -> ItemResult:
    hidden = {str(n) for n in (getattr(item, "hidden_params", None) or ())}
    if not hidden:
        return item
    changes: dict[str, Any] = {"evidence": strip_keys(item.evidence, hidden)}
    if isinstance(getattr(item, "params", None), Mapping):
        changes["params"] = {k: v for k, v in item.params.items() if k not in hidden}  # type: ignore[attr-defined]
    return replace(item, **changes)


def strip_keys(value: Any, hidden: set[str]) -> Any:
    """``value`` without mapping keys named in ``hidden``, at any depth."""
    if isinstance(value, Mapping):
        return {k: strip_keys(v, hidden) for k, v in value.items() if str(k) not in hidden}
    if isinstance(value, list):
        return [strip_keys(v, hidden) for v in value]
    return value


def _sum(values: Iterable[float | None]) -> float:
    return round(sum(v for v in values if v is not None), 2)


def _notice(item: ItemResult) -> Notice:
    return Notice(item.id, item.title, item.status, item.feedback, item.evidence)


# ----------------------------------------------------------------------------------------------
