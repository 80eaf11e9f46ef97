"""``OUT/<id>/result.json`` as a typed document: :class:`ResultDocument`.

It is the on-disk envelope of a grade, not a second ``Result``: ``grader.rubric.result.Result``
stays the one in-memory model the engine scores, reports and exports (its totals are computed
from its items), and ``grader.report.result`` converts between the two (``result_document``,
``result_from_document``). The document adds what only the file has: the totals as they were
written, the submission id, the run's records (build, errors, timings, scenarios, recordings,
the sandbox, the intake, the previous grade of a regrade) and the seal.

Schema 1 is the one form there has been; a file written before these models (grader 2026-12-03
and earlier) is read and written back byte for byte (``tests/report/test_result_document.py``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from grader.contracts.document import Document, Number
from grader.contracts.values import JsonValue

__all__ = ["BuildEntry", "HiddenEntry", "ItemEntry", "NoticeEntry", "PreviousEntry", "PreviousItem",
           "RESULT_SCHEMA", "ResultDocument", "SealEntry", "SectionEntry"]

#: result.json's ``schema``: the form of the document
RESULT_SCHEMA = 1


class _Entry(BaseModel):
    """A record inside the document: unknown keys kept, as the document's own are."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False)


#: ``{"exercise": 1}``, ``{"report": null}``: a section as result.json writes it
SectionKey = dict[str, int | str | None]


class ItemEntry(_Entry):
    """One scored item (``grader.rubric.result.ItemResult`` written out)."""

    id: str
    title: str
    section: SectionKey
    kind: Literal["auto", "manual", "advisory", "integrity"]
    public: bool
    points: Number | None
    max_points: Number
    status: str
    feedback: str
    hint: str | None = None
    value: JsonValue = None
    fraction: Number | None = None
    evidence: dict[str, JsonValue] = Field(default_factory=dict)
    params: dict[str, JsonValue] = Field(default_factory=dict)
    hidden_params: list[str] = Field(default_factory=list)
    requires: list[str] = Field(default_factory=list)
    analyzer: str | None = None
    decided: dict[str, JsonValue] = Field(default_factory=dict)


class SectionEntry(_Entry):
    section: SectionKey
    title: str
    name: str | None = None
    points: Number
    max_points: Number
    auto_points: Number
    auto_max: Number
    pending_max: Number
    items: list[str]


class NoticeEntry(_Entry):
    """An integrity flag or an advisory warning."""

    id: str
    title: str
    status: str
    feedback: str


class HiddenEntry(_Entry):
    """What the student view left out."""

    items: int = 0
    points: Number = 0


class BuildEntry(_Entry):
    ok: bool = True
    failed: list[str] = Field(default_factory=list)


class PreviousItem(_Entry):
    points: Number | None = None
    status: str | None = None


class PreviousEntry(_Entry):
    """What a regrade keeps of the result.json it replaced (``grader.report.result.previous_summary``)."""

    auto_score: Number | None = None
    score: Number | None = None
    total: Number | None = None
    versions: dict[str, str] = Field(default_factory=dict)
    items: dict[str, PreviousItem] = Field(default_factory=dict)


class SealEntry(_Entry):
    """``grader.report.seal``: the digests of the files graded and the MAC over the document."""

    inputs: dict[str, str] = Field(default_factory=dict)
    mac: str


class ResultDocument(Document):
    """result.json. The first block is the grade (``grader.report.result.result_document``);
    the optional block after ``versions`` is what the pipeline adds, in the order it writes them;
    ``seal`` comes last."""

    schema_version: Literal[1] = Field(alias="schema")      # RESULT_SCHEMA
    submission: str
    lab: str
    title: str
    view: Literal["student", "instructor"]
    score: Number
    auto_score: Number
    auto_max: Number
    max_score: Number
    manual_max: Number
    pending_max: Number
    total: Number | None
    complete: bool
    hidden: HiddenEntry = Field(default_factory=HiddenEntry)
    sections: list[SectionEntry] = Field(default_factory=list)
    items: list[ItemEntry]
    late_penalty: Number | None = None
    #: ``grader.contracts.late.LatePenalty.to_dict()``; kept as written (its floats may be ints)
    late: dict[str, JsonValue] | None = None
    #: ``grader.contracts.contract.Mismatch.to_dict()`` each
    contract: list[dict[str, JsonValue]] = Field(default_factory=list)
    integrity_flags: list[NoticeEntry] = Field(default_factory=list)
    warnings: list[NoticeEntry] = Field(default_factory=list)
    versions: dict[str, str] = Field(default_factory=dict)
    # -- the run (grader.grading.outputs.write_outputs) --
    build: BuildEntry | None = None
    errors: list[str] = Field(default_factory=list)
    timings: dict[str, JsonValue] = Field(default_factory=dict)
    scenarios: list[str] = Field(default_factory=list)
    scenarios_reused: dict[str, JsonValue] = Field(default_factory=dict)
    sandbox: dict[str, JsonValue] | None = None
    previous: PreviousEntry | None = None
    recordings: dict[str, JsonValue] = Field(default_factory=dict)
    recordings_by_other_grader: dict[str, JsonValue] = Field(default_factory=dict)
    intake: dict[str, JsonValue] | None = None
    analyzer_files: list[str] = Field(default_factory=list)
    time_scale: dict[str, JsonValue] = Field(default_factory=dict)
    ended_early: dict[str, JsonValue] = Field(default_factory=dict)
    seal: SealEntry | None = None

    @model_validator(mode="before")
    @classmethod
    def _known_schema(cls, data: JsonValue) -> JsonValue:
        """A newer grader's file is said to be one, before any field of it is judged."""
        if isinstance(data, dict) and data.get("schema") != RESULT_SCHEMA:
            raise ValueError(f"schema {data.get('schema')!r} is not {RESULT_SCHEMA} (a newer grader "
                             "wrote it, or it is not a result.json)")
        return data

    @classmethod
    def grade_keys(cls) -> tuple[str, ...]:
        """The JSON keys of the grade itself: every field up to ``versions`` (the rest is the
        run's records and the seal)."""
        keys = tuple(info.alias or name for name, info in cls.model_fields.items())
        return keys[: keys.index("versions") + 1]

    def run_records(self) -> dict[str, JsonValue]:
        """The keys that are neither the grade nor the seal (build, errors, timings, ..., and any
        a newer grader added), in their order: what a rewrite of the grade keeps."""
        grade = self.grade_keys()
        return {k: v for k, v in self.to_json().items() if k not in grade and k != "seal"}

    def without_seal(self) -> dict[str, JsonValue]:
        """The JSON object the seal's MAC covers (everything but the seal)."""
        body = self.to_json()
        body.pop("seal", None)
        return body

    def with_seal(self, seal: SealEntry) -> "ResultDocument":
        return self.model_copy(update={"seal": seal})

    @property
    def build_ok(self) -> bool:
        """False only when a build was recorded and failed."""
        return self.build is None or self.build.ok
