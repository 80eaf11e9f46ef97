"""The rubric model: items, points, sections, and the scenarios they are graded on.

A rubric is the single place where an instructor states *what* is graded (items, points,
sections), *how* (analyzer + params, partial-credit rule, which items gate others) and *on which
recording* (scenario, see ``grader.scenario.model``). A new lab is a new YAML file (and at most a
new analyzer), not new grading code. The classes mirror the YAML keys one to one; the loader
(``grader.rubric.load``) validates a file into them and reports every problem as
``file:line: field.path: message``. Format reference: rubrics/README.md.

The cross-references checked once the whole model is at hand (``Rubric.problems``) are in
``crossrefs.py``; the contract and intake fields are in modules of their own (``contract.py``,
``intake_fields.py``).
"""

from __future__ import annotations

import math
import string
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import BeforeValidator, Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from grader.rubric.intake_fields import LatePolicy, LooseFiles
from grader.contracts.contract import Contract
from grader.rubric.contract import item_roles, resolve_references, scenario_roles
from grader.contracts.fields import Model, PackageName, with_rules
from grader.scenario.model import Scenario
from grader.contracts.text import pattern_text

SCHEMA_VERSION: Literal[1] = 1
KINDS = ("auto", "manual", "advisory", "integrity")
#: tolerance of float comparisons of points and fractions (sums of fractional points)
POINTS_EPS = 1e-9

LabId = Annotated[str, pattern_text(r"^[a-z0-9][a-z0-9._-]*$", "a lab id like 'enee467-lab3' (lower case, digits, . _ -)")]
ItemId = Annotated[str, pattern_text(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", "an item id like 'ex1.pub_rate'")]
ScenarioId = Annotated[str, pattern_text(r"^[A-Za-z][A-Za-z0-9_-]*$", "a scenario id (letters, digits, _ or -)")]
AnalyzerName = Annotated[str, pattern_text(r"^[a-z][a-z0-9_]*$", "an analyzer name (lower_case)")]
# (the same language as an analyzer name, written differently so each has its own error text)
SectionKind = Annotated[str, pattern_text(r"^[a-z][a-z_0-9]*$", "a lower-case section kind like exercise")]
SectionNumber = Union[Annotated[int, Field(ge=0)],
                      Annotated[str, pattern_text(r"^[A-Za-z0-9._-]+$", "a section number like 1 or '2b'")]]
Text = Annotated[str, Field(min_length=1, pattern=r"\S")]
MutantId = Annotated[str, pattern_text(r"^[a-z][a-z_]*-[0-9a-f]{8}$", "a mutant id like 'flip_sign-1a2b3c4d' (grader rubric audit)")]
Points = Annotated[float, Field(ge=0, allow_inf_nan=False)]


def _relative_path(value: Any, info: ValidationInfo) -> Any:
    """Paths in a rubric are relative to the rubric's own folder."""
    base = (info.context or {}).get("base_dir")
    if isinstance(value, str) and base is not None:
        return str((Path(base) / value).resolve())
    return value


RubricPath = Annotated[Path, BeforeValidator(_relative_path), Field(strict=False)]


class Section(Model):
    """Where an item is counted: ``report``, ``{question: 3}``, ``{exercise: 1}``, ``integrity``.

    Any lower-case kind is allowed (``part``, ``task``...) so a lab can name its own.
    """

    kind: SectionKind
    number: SectionNumber | None = None

    def __init__(self, kind: str | None = None, number: int | str | None = None, /, **data: Any) -> None:
        """``Section("exercise", 1)`` as well as keywords."""
        if kind is not None:
            data.setdefault("kind", kind)
            data.setdefault("number", number)
        super().__init__(**data)

    @model_validator(mode="before")
    @classmethod
    def _yaml_forms(cls, value: Any) -> Any:
        if isinstance(value, str):
            return {"kind": value}
        if isinstance(value, dict) and len(value) == 1 and "kind" not in value:
            (kind, number), = value.items()
            return {"kind": kind, "number": number}
        if isinstance(value, dict) and "kind" not in value:
            raise ValueError("expected a section like report, {exercise: 1} or {question: 3}")
        return value

    @property
    def key(self) -> str:
        """Stable text id: ``exercise 1``, ``report``."""
        return self.kind if self.number is None else f"{self.kind} {self.number}"

    @property
    def label(self) -> str:
        """Human label: ``Exercise 1``, ``Report``."""
        name = self.kind.replace("_", " ").capitalize()
        return name if self.number is None else f"{name} {self.number}"

    def as_dict(self) -> dict[str, int | str | None]:
        """JSON form used in result.json: ``{"exercise": 1}``, ``{"report": null}``."""
        return {self.kind: self.number}


class SectionSpec(Model):
    """An entry of the optional ``sections:`` table: display order, title, declared total."""

    section: Section
    title: str | None = None
    points: Points | None = None

    def __init__(self, section: Section | None = None, title: str | None = None,
                 points: float | None = None, /, **data: Any) -> None:
        if section is not None:
            data.update(section=section, title=title, points=points)
        super().__init__(**data)

    @property
    def display_title(self) -> str:
        return f"{self.section.label}: {self.title}" if self.title else self.section.label


class Partial(Model):
    """How an analyzer's ``fraction`` (0..1) becomes a share of the item's points.

    ``linear``: fraction as is. ``none``: all or nothing (full points only at fraction 1).
    ``{steps: [[threshold, credit], ...]}``: the credit of the first pair whose threshold the
    fraction reaches, thresholds descending; below every threshold the credit is 0.
    """

    mode: Literal["linear", "none", "steps"] = "linear"
    steps: Annotated[tuple[Annotated[tuple[Annotated[float, Field(ge=0, le=1)], Annotated[float, Field(ge=0, le=1)]],
                                     Field(strict=False)], ...], Field(strict=False)] = ()

    def __init__(self, mode: str | None = None, steps: tuple = (), /, **data: Any) -> None:
        if mode is not None:
            data.update(mode=mode, steps=steps)
        super().__init__(**data)

    @model_validator(mode="before")
    @classmethod
    def _yaml_forms(cls, value: Any) -> Any:
        if isinstance(value, str):
            return {"mode": value}
        if isinstance(value, dict) and "steps" in value and "mode" not in value:
            steps = value["steps"]
            if isinstance(steps, list):
                steps = tuple(tuple(p) if isinstance(p, list) else p for p in steps)
            return {**value, "mode": "steps", "steps": steps}
        return value

    @model_validator(mode="after")
    def _descending(self) -> "Partial":
        if self.mode == "steps" and not self.steps:
            raise ValueError("expected at least one [threshold, credit] pair")
        for (t0, c0), (t1, c1) in zip(self.steps, self.steps[1:]):
            if t1 >= t0:
                raise ValueError(f"thresholds must decrease: {t1:g} follows {t0:g}")
            if c1 > c0:
                raise ValueError(f"credit must not grow as the threshold falls: {c1:g} after {c0:g}")
        return self

    def credit(self, fraction: float) -> float:
        if not math.isfinite(fraction):
            return 0.0
        fraction = min(1.0, max(0.0, fraction))
        if self.mode == "none":
            return 1.0 if fraction >= 1.0 - POINTS_EPS else 0.0
        if self.mode == "steps":
            for threshold, credit in self.steps:
                if fraction >= threshold - POINTS_EPS:
                    return credit
            return 0.0
        return fraction


def template_problem(text: str) -> str | None:
    """Why ``text`` is not a usable ``str.format`` template, or None. Placeholders are names
    (``{value}``, ``{value:.2f}``, evidence keys); positional ``{}`` cannot be filled."""
    try:
        for _, name, spec, _ in string.Formatter().parse(text):
            if name is None:
                continue
            if name == "" or name.isdigit():
                return "placeholders need a name such as {value}; write {{ and }} for literal braces"
            if "{" in (spec or ""):
                return "nested placeholders in a format spec are not supported"
    except ValueError as exc:
        return f"invalid template ({exc}); write {{{{ and }}}} for literal braces"
    return None


class Feedback(Model):
    """Texts per status (``str.format`` templates: ``{value}``, ``{feedback}``, evidence and
    params keys). ``partial`` falls back to ``fail``; no text: the analyzer's own feedback."""

    pass_: str | None = Field(None, alias="pass")
    partial: str | None = None
    fail: str | None = None
    error: str | None = None

    model_config = {**Model.model_config, "populate_by_name": True}

    @field_validator("pass_", "partial", "fail", "error")
    @classmethod
    def _template(cls, text: str | None) -> str | None:
        problem = template_problem(text) if text is not None else None
        if problem:
            raise ValueError(problem)
        return text

    def get(self, status: str) -> str | None:
        return getattr(self, "pass_" if status == "pass" else status, None)


def _scenario_ids(value: Any) -> Any:
    if isinstance(value, str):
        return (value,)
    return tuple(value) if isinstance(value, list) else value


class Item(Model):
    """One graded line of the rubric.

    ``scenario``: the recordings its analyzer reads; with several, the analyzer runs on each and
    the worst finding counts (integrity checks that must hold in every run). ``requires``: items
    that must earn points (pass, or partly) before this one does (e.g. a server that advertises
    its action earns nothing until it also reaches a goal). ``hidden_params``: parameters
    (thresholds) not shown in the student view. ``handout_credit``: why the lab's handed-out code may earn this item
    (the handout test fails on any scored item the handout passes without it).
    """

    id: ItemId
    title: Text
    section: Section
    points: Points = 0.0
    kind: Literal["auto", "manual", "advisory", "integrity"] = "auto"
    public: bool = True
    scenario: Annotated[tuple[ScenarioId, ...], BeforeValidator(_scenario_ids), Field(strict=False)] = ()
    analyzer: AnalyzerName | None = None
    params: dict[str, Any] = {}
    partial: Partial = Partial()
    feedback: Feedback = Feedback()
    hint: Text | None = None
    requires: Annotated[tuple[ItemId, ...], BeforeValidator(_scenario_ids), Field(strict=False)] = ()
    hidden_params: Annotated[tuple[str, ...], Field(strict=False)] = ()
    handout_credit: Text | None = None
    #: whether the verdict depends on wall or simulated timing (a rate, a period, a timeout), so
    #: that a recording the grading machine starved cannot fail it; unset: as its analyzer declares
    timing: bool | None = None

    @model_validator(mode="wrap")
    @classmethod
    def _kind_rules(cls, value: Any, handler: Any) -> Any:
        """Rules that depend on which keys were written; reported together with field errors."""
        if not isinstance(value, dict):
            return handler(value)
        own: list[tuple[tuple, str]] = []
        kind = value.get("kind", "auto")
        if kind == "manual":
            for key in ("scenario", "analyzer", "params", "partial", "requires", "hidden_params"):
                if key in value:
                    own.append(((key,), f"manual items are graded by a person; remove {key!r} or use kind: auto"))
        elif kind in KINDS:
            for key in ("scenario", "analyzer"):
                if key not in value:
                    own.append(((key,), f"required key is missing ({kind} items are checked by an "
                                        "analyzer on a scenario's recording)"))
        if kind in ("advisory", "integrity"):
            if value.get("points") not in (None, 0):
                own.append((("points",), f"{kind} items carry no points (they are "
                            f"{'warnings' if kind == 'advisory' else 'flags for review'}); "
                            "set points: 0 or use kind: auto"))
            if "partial" in value:
                own.append((("partial",), f"{kind} items carry no points, so partial credit does not apply"))
            value = {**value, "points": 0.0}
        elif kind in ("auto", "manual"):
            if "points" not in value:
                own.append((("points",), f"required key is missing ({kind} items need points)"))
            elif value["points"] == 0 and not isinstance(value["points"], bool):
                own.append((("points",), f"{kind} items need points > 0; use kind: advisory for a 0-point check"))
        return with_rules(cls, handler, value, own)

    @property
    def automatic(self) -> bool:
        """Graded by an analyzer (every kind except manual)."""
        return self.kind != "manual"

    @property
    def max_points(self) -> float:
        return float(self.points)


class EquivalentMutant(Model):
    """A mutant of the reference solution (``grader rubric audit``) that keeps full marks
    because it is still a correct solution, not because the rubric cannot see the bug."""

    mutant: MutantId
    reason: Text = Field(description="why the mutated code is still correct (what it changes and why that is fine)")


class AcceptedCollateral(Model):
    """Items a one-aspect mutant of the reference (``grader rubric collateral``) may cost beyond
    those that judge its aspect, and why that second loss is right."""

    mutant: MutantId
    items: Annotated[tuple[ItemId, ...], BeforeValidator(_scenario_ids), Field(strict=False, min_length=1)]
    reason: Text = Field(description="why these items cannot be judged without the aspect the mutant changed")


class Rubric(Model):
    """A lab's whole grading scheme. ``source`` is the file it was loaded from."""

    schema_: Literal[1] = Field(SCHEMA_VERSION, alias="schema")
    lab: LabId
    title: Text
    description: str = ""
    total: Points | None = None
    handout: RubricPath | None = Field(None, description="the lab's handed-out starter code (a "
                                       "submission folder); it must earn no points")
    support: dict[PackageName, RubricPath] = Field(
        {}, description="packages supplied when a submission lacks them (e.g. given interfaces)")
    analyzers: Annotated[tuple[RubricPath, ...], Field(strict=False)] = Field(
        (), description="Python files (relative to the rubric) defining this lab's own analyzers and "
                        "figures; imported when the rubric is loaded (grader.analyze.plugins)")
    contract: Contract = Field(Contract(), description="the names students must use exactly (package, "
                               "executable, node, topic, service, action, launch file), each under a role; "
                               "the rest of the rubric refers to them as $role")
    sections: Annotated[tuple[SectionSpec, ...], Field(strict=False)] = ()
    scenarios: dict[ScenarioId, Scenario] = {}
    items: Annotated[tuple[Item, ...], Field(min_length=1, strict=False)]
    # how submissions arrive (grader.intake): the late policy and bare-file submissions
    late: LatePolicy | None = Field(None, description="due date and late policy (grader.intake)")
    loose_files: LooseFiles | None = Field(None, description="how bare .py files become a package")
    equivalent_mutants: Annotated[tuple[EquivalentMutant, ...], Field(strict=False)] = Field(
        (), description="mutants of the reference that keep full marks and are correct (grader rubric audit)")
    accepted_collateral: Annotated[tuple[AcceptedCollateral, ...], Field(strict=False)] = Field(
        (), description="one-aspect mutants whose loss of other items is right, with why (grader rubric collateral)")

    model_config = {**Model.model_config, "populate_by_name": True}
    _source: Path = PrivateAttr(default=Path("rubric.yaml"))

    @model_validator(mode="before")
    @classmethod
    def _references(cls, value: Any) -> Any:
        """``$role`` and ``${role}`` become the contract's names (the loader reports the ones it
        cannot resolve, with their lines; here they are left to fail their field's check)."""
        return resolve_references(value)[0]

    def item_roles(self, item: Item, scenario_id: str) -> set[str]:
        """Contract roles ``item`` depends on in ``scenario_id``: those its parameters name and
        those its scenario runs or drives."""
        scenario = self.scenarios.get(scenario_id)
        return item_roles(self.contract, item) | (scenario_roles(self.contract, scenario) if scenario else set())

    def scenario_roles(self, scenario_id: str) -> set[str]:
        """Contract roles to look for in ``scenario_id``'s recording: what it runs and drives, and
        what the parameters of the items graded on it name."""
        out = scenario_roles(self.contract, self.scenarios[scenario_id]) if scenario_id in self.scenarios else set()
        for item in self.items:
            if scenario_id in item.scenario:
                out |= item_roles(self.contract, item)
        return out

    @property
    def source(self) -> Path:
        return self._source

    def item(self, item_id: str) -> Item:
        for item in self.items:
            if item.id == item_id:
                return item
        raise KeyError(item_id)

    @property
    def item_ids(self) -> list[str]:
        return [i.id for i in self.items]

    @property
    def total_max(self) -> float:
        return float(sum(i.max_points for i in self.items))

    @property
    def auto_max(self) -> float:
        return float(sum(i.max_points for i in self.items if i.kind == "auto"))

    @property
    def manual_max(self) -> float:
        return float(sum(i.max_points for i in self.items if i.kind == "manual"))

    def section_specs(self) -> list[SectionSpec]:
        """Sections in display order: the ``sections:`` table, then undeclared ones as met."""
        specs = list(self.sections)
        known = {s.section for s in specs}
        for item in self.items:
            if item.section not in known:
                known.add(item.section)
                specs.append(SectionSpec(section=item.section))
        return specs

    def support_paths(self) -> dict[str, Path]:
        """``{package: absolute path}`` for ``grader.workspace`` (supplied when missing)."""
        return dict(self.support)

    def scenarios_used(self) -> list[str]:
        """Scenario ids some item needs, in first-use order (what the runner must record)."""
        seen: dict[str, None] = {}
        for item in self.items:
            for sid in item.scenario:
                seen.setdefault(sid, None)
        return list(seen)

