"""What a mutation audit found: one :class:`Outcome` per mutant, the :class:`AuditReport` of them.

Records of their own, beside the audit's run (``grader.audit.run``) and its report
(``grader.audit.report``), which both take them: the report module read them from the run's and
the run wrote them with the report's, a circle of two files.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass
class Outcome:
    """What grading one mutant gave."""

    mutant: dict[str, Any]               # Mutant.summary()
    diff: str
    status: str                          # killed | equivalent | surviving | error
    auto_score: float | None = None
    auto_max: float | None = None
    lost: dict[str, float] = field(default_factory=dict)   # item id -> points lost
    reason: str | None = None            # the rubric's reason, for an equivalent mutant
    error: str | None = None
    wall_s: float | None = None          # build + scenarios of this mutant


@dataclass
class AuditReport:
    rubric: str
    lab: str
    reference: str
    operators: list[str]
    made: int                            # mutants of the reference (after leaving out given files)
    given_files: list[str]               # files left out: handed out unchanged
    sample: int | None
    seed: int
    time_scale: float
    jobs: int
    outcomes: list[Outcome]
    wall_s: float = 0.0
    reference_wall_s: float = 0.0
    stale_equivalents: list[str] = field(default_factory=list)   # recorded ids no mutant has
    regraded: bool = False               # --regrade: recordings of an earlier run, analyzed again

    def count(self, status: str) -> int:
        return sum(1 for o in self.outcomes if o.status == status)

    @property
    def graded(self) -> int:
        return len(self.outcomes)

    @property
    def score(self) -> float | None:
        """Mutation score: killed / (graded - equivalent - errors)."""
        judged = self.graded - self.count("equivalent") - self.count("error")
        return self.count("killed") / judged if judged else None

    def to_json(self) -> dict[str, Any]:
        doc = asdict(self)
        doc["counts"] = {s: self.count(s) for s in ("killed", "equivalent", "surviving", "error")}
        doc["graded"] = self.graded
        doc["score"] = self.score
        return doc
