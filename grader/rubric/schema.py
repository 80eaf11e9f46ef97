"""The rubric schema as code: dataclasses plus a validator that reports every problem at once.

A rubric is the single place where an instructor states *what* is graded (items, points,
sections), *how* (analyzer + params, partial-credit rule) and *on which recording* (scenario).
Keeping all of it declarative means a new lab is a new YAML file (and at most a new analyzer),
not new grading code. Every problem is reported as ``file:line: field.path: message`` so the
instructor can fix the whole file in one pass. Format reference: grader/rubric/README.md.
"""

from __future__ import annotations

import math
import re
import string
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Collection, Iterable, Mapping

from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from grader.rubric._nodes import Fields, Problem, Reader, describe, join_path, suggest
from grader.rubric.scenarios import PACKAGE, Scenario, read_scenario

SCHEMA_VERSION = 1
KINDS = ("auto", "manual", "advisory", "integrity")
STATUSES = ("pass", "partial", "fail", "error")
FEEDBACK_KEYS = STATUSES
LAB_ID = re.compile(r"^[a-z0-9][a-z0-9._-]*$")
ITEM_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
SCENARIO_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
ANALYZER = re.compile(r"^[a-z][a-z0-9_]*$")
SECTION_KIND = re.compile(r"^[a-z][a-z0-9_]*$")
_EPS = 1e-9


# ----------------------------------------------------------------------------------------------
# dataclasses

@dataclass(frozen=True)
class Section:
    """Where an item is counted: ``report``, ``{question: 3}``, ``{exercise: 1}``, ``integrity``.

    Any lower-case kind is allowed (``part``, ``task``...) so a future lab can name its own.
    """

    kind: str
    number: int | str | None = None

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


@dataclass(frozen=True)
class SectionSpec:
    """An entry of the optional ``sections:`` table: display order, title, declared total."""

    section: Section
    title: str | None = None
    points: float | None = None
    line: int = 0

    @property
    def display_title(self) -> str:
        return f"{self.section.label}: {self.title}" if self.title else self.section.label


@dataclass(frozen=True)
class Partial:
    """How an analyzer's ``fraction`` (0..1) becomes a share of the item's points.

    ``linear``: fraction as is. ``none``: all or nothing (full points only at fraction 1).
    ``steps``: the credit of the first ``(threshold, credit)`` pair whose threshold the
    fraction reaches, thresholds descending; below every threshold the credit is 0.
    """

    mode: str = "linear"
    steps: tuple[tuple[float, float], ...] = ()

    def credit(self, fraction: float) -> float:
        if not math.isfinite(fraction):
            return 0.0
        fraction = min(1.0, max(0.0, fraction))
        if self.mode == "none":
            return 1.0 if fraction >= 1.0 - _EPS else 0.0
        if self.mode == "steps":
            for threshold, credit in self.steps:
                if fraction >= threshold - _EPS:
                    return credit
            return 0.0
        return fraction


@dataclass(frozen=True)
class Item:
    """One graded line of the rubric. ``scenarios`` lists the recordings its analyzer reads;
    with several, the analyzer runs on each and the worst finding counts (integrity checks
    that must hold in every run)."""

    id: str
    title: str
    section: Section
    points: float
    kind: str = "auto"
    public: bool = True
    scenarios: tuple[str, ...] = ()
    analyzer: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    partial: Partial = field(default_factory=Partial)
    feedback: Mapping[str, str] = field(default_factory=dict)
    hint: str | None = None
    line: int = 0

    @property
    def scenario(self) -> str | None:
        """The (first) scenario id, for the common single-scenario case."""
        return self.scenarios[0] if self.scenarios else None

    @property
    def automatic(self) -> bool:
        """Graded by an analyzer (every kind except manual)."""
        return self.kind != "manual"


@dataclass(frozen=True)
class Rubric:
    lab: str
    title: str
    source: Path
    items: tuple[Item, ...]
    scenarios: Mapping[str, Scenario] = field(default_factory=dict)
    sections: tuple[SectionSpec, ...] = ()
    support: Mapping[str, Path] = field(default_factory=dict)
    total: float | None = None
    description: str = ""

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
        return float(sum(i.points for i in self.items))

    @property
    def auto_max(self) -> float:
        return float(sum(i.points for i in self.items if i.kind == "auto"))

    @property
    def manual_max(self) -> float:
        return float(sum(i.points for i in self.items if i.kind == "manual"))

    def section_specs(self) -> list[SectionSpec]:
        """Sections in display order: the ``sections:`` table, then undeclared ones as met."""
        specs = list(self.sections)
        known = {s.section for s in specs}
        for item in self.items:
            if item.section not in known:
                known.add(item.section)
                specs.append(SectionSpec(item.section))
        return specs

    def support_paths(self) -> dict[str, Path]:
        """``{package: absolute path}`` for ``grader.workspace`` (supplied when missing)."""
        return dict(self.support)

    def scenarios_used(self) -> list[str]:
        """Scenario ids some item needs, in first-use order (what the runner must record)."""
        seen: dict[str, None] = {}
        for item in self.items:
            for sid in item.scenarios:
                seen.setdefault(sid, None)
        return list(seen)


# ----------------------------------------------------------------------------------------------
# validation

_TOP_KEYS = ("schema", "lab", "title", "description", "total", "support", "sections",
             "scenarios", "items")
_ITEM_KEYS = ("id", "title", "section", "points", "kind", "public", "scenario", "analyzer",
              "params", "partial", "feedback", "hint")


def validate(root: Node | None, file: str, base_dir: Path, *, check_files: bool = True,
             analyzers: Collection[str] | Mapping[str, Collection[str]] | None = None,
             ) -> tuple[Rubric | None, list[Problem]]:
    """Turn a composed YAML document into a Rubric, or list every problem found.

    ``analyzers``: names known to ``grader.analyze`` (or name -> accepted parameter names);
    when given, unknown analyzer names (and parameters) are problems too. Passed in, so the
    schema itself does not import the analysis layer.
    ``check_files``: support packages and replayed bags must exist.
    """
    reader = Reader(file)
    if root is None:
        reader.error(1, "", "the rubric is empty")
        return None, reader.problems
    f = reader.fields(root, "", _TOP_KEYS, required=("lab", "title", "items"))
    if f is None:
        return None, reader.problems
    if "schema" in f:
        version = f.number("schema", integer=True, minimum=1)
        if version is not None and version != SCHEMA_VERSION:
            f.error("schema", f"this grader reads rubric schema {SCHEMA_VERSION}, got {version}")
    lab = f.string("lab", pattern=LAB_ID, what="a lab id like 'enee467-lab3' (lower case, digits, . _ -)")
    title = f.string("title")
    description = f.string("description", "") or ""
    total = f.number("total", minimum=0)
    support = _read_support(reader, f, base_dir, check_files)
    sections = _read_sections(reader, f)
    scenarios: dict[str, Scenario] = {}
    scenario_lines: dict[str, int] = {}
    if "scenarios" in f:
        for sid, key_node, snode, spath in reader.mapping_entries(f.value_node("scenarios"),
                                                                  f.sub("scenarios")):
            scenario_lines[sid] = key_node.start_mark.line + 1
            if not SCENARIO_ID.match(sid):
                reader.error(key_node, spath, f"expected a scenario id (letters, digits, _ or -), got {sid!r}")
                continue
            scenario = read_scenario(reader, snode, spath, sid, base_dir, check_files)
            if scenario is not None:
                scenarios[sid] = scenario
    before_items = len(reader.problems)
    items = _read_items(reader, f, set(scenario_lines), analyzers)
    if items is not None and len(reader.problems) == before_items:
        # sums are only meaningful when every item was read; other problems don't stop them
        _check_sections(reader, f, sections, items)
        _check_total(reader, f, total, items)
    if reader.problems:
        return None, sorted(reader.problems)
    rubric = Rubric(lab=lab, title=title, source=Path(file), items=tuple(items or ()),
                    scenarios=scenarios, sections=tuple(sections), support=support,
                    total=total, description=description)
    return rubric, []


def _read_support(reader: Reader, f: Fields, base_dir: Path, check_files: bool) -> dict[str, Path]:
    support: dict[str, Path] = {}
    if "support" not in f:
        return support
    for name, key_node, vnode, path in reader.mapping_entries(f.value_node("support"), f.sub("support")):
        if not PACKAGE.match(name):
            reader.error(key_node, path, f"expected a ROS package name, got {name!r}")
            continue
        text = reader.string(vnode, path, what="a path to the package (relative to the rubric)")
        if text is None:
            continue
        resolved = (base_dir / text).resolve()
        if check_files and not (resolved / "package.xml").is_file():
            reader.error(vnode, path, f"support package {name!r}: no package.xml in {text!r} "
                                      f"(looked in {resolved})")
            continue
        support[name] = resolved
    return support


def read_section(reader: Reader, node: Node, path: str) -> Section | None:
    """``report`` | ``{exercise: 1}`` | ``{question: 3}`` (one key: a lower-case kind)."""
    if isinstance(node, ScalarNode):
        kind = reader.string(node, path, pattern=SECTION_KIND,
                             what="a section like report, {exercise: 1} or {question: 3}")
        return Section(kind) if kind else None
    if not isinstance(node, MappingNode) or len(node.value) != 1:
        reader.error(node, path, f"expected a section like report, {{exercise: 1}} or {{question: 3}}, "
                                 f"got {describe(node, reader.scalar(node))}")
        return None
    key_node, value_node = node.value[0]
    kind = reader.string(key_node, path, pattern=SECTION_KIND, what="a lower-case section kind")
    number = reader.scalar(value_node)
    if isinstance(number, bool) or not (
            (isinstance(number, int) and number >= 0)
            or (isinstance(number, str) and re.match(r"^[A-Za-z0-9._-]+$", number))):
        reader.error(value_node, join_path(path, kind or "?"),
                     f"expected a section number like 1 or '2b', got {describe(value_node, number)}")
        return None
    return Section(kind, number) if kind else None


def _read_sections(reader: Reader, f: Fields) -> list[SectionSpec]:
    specs: list[SectionSpec] = []
    if "sections" not in f:
        return specs
    seen: dict[Section, int] = {}
    for _, node, path in reader.items(f.value_node("sections"), f.sub("sections")):
        g = reader.fields(node, path, ("section", "title", "points"), required=("section",))
        if g is None or "section" not in g:
            continue
        section = read_section(reader, g.value_node("section"), g.sub("section"))
        title = g.string("title")
        points = g.number("points", minimum=0)
        if section is None:
            continue
        if section in seen:
            g.error("section", f"section {section.key!r} is listed twice (first on line {seen[section]})")
            continue
        seen[section] = g.line
        specs.append(SectionSpec(section, title, points, g.line))
    return specs


def _read_items(reader: Reader, f: Fields, scenario_ids: set[str],
                analyzers: Collection[str] | Mapping[str, Collection[str]] | None) -> list[Item] | None:
    if "items" not in f:
        return None
    items: list[Item] = []
    first_line: dict[str, int] = {}
    nodes = list(reader.items(f.value_node("items"), f.sub("items")))
    if not nodes and not reader.problems:
        f.error("items", "a rubric needs at least one item")
    for _, node, path in nodes:
        item = _read_item(reader, node, path, scenario_ids, analyzers)
        if item is None:
            continue
        if item.id in first_line:
            reader.error(node, join_path(path, "id"),
                         f"duplicate item id {item.id!r} (first on line {first_line[item.id]})")
            continue
        first_line[item.id] = item.line
        items.append(item)
    return items


def _read_item(reader: Reader, node: Node, path: str, scenario_ids: set[str],
               analyzers: Collection[str] | Mapping[str, Collection[str]] | None) -> Item | None:
    mark = len(reader.problems)
    g = reader.fields(node, path, _ITEM_KEYS, required=("id", "title", "section"))
    if g is None:
        return None
    item_id = g.string("id", pattern=ITEM_ID, what="an item id like 'ex1.pub_rate'")
    title = g.string("title")
    section = g.get("section", lambda n, p: read_section(reader, n, p))
    kind = g.string("kind", "auto", choices=KINDS)
    points = g.number("points", minimum=0)
    public = g.boolean("public", True)
    hint = g.string("hint")
    params = g.mapping("params")
    scenarios = _read_item_scenarios(reader, g, scenario_ids)
    analyzer = g.string("analyzer", pattern=ANALYZER, what="an analyzer name (lower_case)")
    if analyzer and analyzers is not None:
        if analyzer not in analyzers:
            g.error("analyzer", f"unknown analyzer {analyzer!r}{suggest(analyzer, analyzers)}")
        elif isinstance(analyzers, Mapping) and "params" in g:
            _check_params(reader, g, analyzer, analyzers[analyzer])
    partial = _read_partial(reader, g) if "partial" in g else Partial()
    feedback = _read_feedback(reader, g)
    if kind == "manual":
        for key in ("scenario", "analyzer", "params", "partial"):
            if key in g:
                g.error(key, f"manual items are graded by a person; remove {key!r} or use kind: auto")
    elif kind is not None:
        for key in ("scenario", "analyzer"):
            if key not in g:
                g.error(key, f"required key is missing ({kind} items are checked by an "
                             f"analyzer on a scenario's recording)")
    if kind in ("advisory", "integrity"):
        if points not in (None, 0):
            g.error("points", f"{kind} items carry no points (they are "
                              f"{'warnings' if kind == 'advisory' else 'flags for review'}); "
                              f"set points: 0 or use kind: auto")
        if "partial" in g:
            g.error("partial", f"{kind} items carry no points, so partial credit does not apply")
        points = 0.0 if points is None else points
    elif "points" not in g:
        g.error("points", f"required key is missing ({kind or 'auto'} items need points)")
    elif points == 0:
        g.error("points", f"{kind} items need points > 0; use kind: advisory for a 0-point check")
    if len(reader.problems) > mark:
        return None
    return Item(id=item_id, title=title, section=section, points=float(points), kind=kind,
                public=bool(public), scenarios=scenarios, analyzer=analyzer, params=params,
                partial=partial, feedback=feedback, hint=hint, line=g.line)


def _check_params(reader: Reader, g: Fields, analyzer: str, accepted: Collection[str]) -> None:
    """Parameter names the analyzer does not accept (it would refuse them at grading time)."""
    node = g.value_node("params")
    if not isinstance(node, MappingNode):
        return
    for key_node, _, _ in reader.pairs(node, g.sub("params")):
        key = reader.scalar(key_node)
        if isinstance(key, str) and key not in accepted:
            known = ", ".join(sorted(accepted)) or "none"
            hint = suggest(key, accepted) or f" (accepted: {known})"
            reader.error(key_node, join_path(g.sub("params"), key),
                         f"analyzer {analyzer!r} takes no parameter {key!r}{hint}")


def _read_item_scenarios(reader: Reader, g: Fields, scenario_ids: set[str]) -> tuple[str, ...]:
    if "scenario" not in g:
        return ()
    node, path = g.value_node("scenario"), g.sub("scenario")
    names: list[tuple[str, Node, str]] = []
    if isinstance(node, ScalarNode):
        sid = reader.string(node, path, what="a scenario id")
        if sid:
            names.append((sid, node, path))
    else:
        for _, child, cpath in reader.items(node, path):
            sid = reader.string(child, cpath, what="a scenario id")
            if sid:
                names.append((sid, child, cpath))
        if isinstance(node, SequenceNode) and not node.value:
            reader.error(node, path, "expected at least one scenario id")
    for sid, snode, spath in names:
        if sid not in scenario_ids:
            hint = suggest(sid, scenario_ids) or (
                f" (defined: {', '.join(sorted(scenario_ids))})" if scenario_ids else " (no scenarios defined)")
            reader.error(snode, spath, f"unknown scenario {sid!r}{hint}")
    return tuple(s for s, _, _ in names)


def _read_partial(reader: Reader, g: Fields) -> Partial:
    node, path = g.value_node("partial"), g.sub("partial")
    if isinstance(node, ScalarNode):
        mode = reader.string(node, path, choices=("linear", "none"),
                             what="linear, none or {steps: [[threshold, credit], ...]}")
        return Partial(mode or "linear")
    h = reader.fields(node, path, ("steps",), required=("steps",))
    if h is None or "steps" not in h:
        return Partial()
    steps: list[tuple[float, float]] = []
    for index, pair, ppath in reader.items(h.value_node("steps"), h.sub("steps")):
        values = getattr(pair, "value", None)
        if not isinstance(values, list) or len(values) != 2 or isinstance(pair, MappingNode):
            reader.error(pair, ppath, f"expected a pair [threshold, credit], got "
                                      f"{describe(pair, reader.scalar(pair))}")
            continue
        threshold = reader.number(values[0], join_path(ppath, 0), minimum=0, maximum=1)
        credit = reader.number(values[1], join_path(ppath, 1), minimum=0, maximum=1)
        if threshold is None or credit is None:
            continue
        if steps and threshold >= steps[-1][0]:
            reader.error(pair, ppath, f"thresholds must decrease: {threshold:g} follows {steps[-1][0]:g}")
        elif steps and credit > steps[-1][1]:
            reader.error(pair, ppath, f"credit must not grow as the threshold falls: "
                                      f"{credit:g} after {steps[-1][1]:g}")
        steps.append((float(threshold), float(credit)))
    if not steps:
        h.error("steps", "expected at least one [threshold, credit] pair")
    return Partial("steps", tuple(steps))


def _read_feedback(reader: Reader, g: Fields) -> dict[str, str]:
    if "feedback" not in g:
        return {}
    h = reader.fields(g.value_node("feedback"), g.sub("feedback"), FEEDBACK_KEYS)
    if h is None:
        return {}
    texts: dict[str, str] = {}
    for key in h.keys():
        text = h.string(key)
        if text is None:
            continue
        problem = template_problem(text)
        if problem:
            h.error(key, problem)
            continue
        texts[key] = text
    return texts


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


def _check_sections(reader: Reader, f: Fields, sections: list[SectionSpec], items: list[Item]) -> None:
    """Item sections must be declared (when a table exists) and add up to declared points."""
    if "sections" not in f:
        return
    declared = {s.section: s for s in sections}
    labels = {s.section.key: s for s in sections}
    sums: dict[Section, float] = {s: 0.0 for s in declared}
    for index, item in enumerate(items):
        if item.section not in declared:
            reader.error(item.line, f"items[{index}].section",
                         f"section {item.section.key!r} is not in the sections table"
                         f"{suggest(item.section.key, labels)}")
            continue
        sums[item.section] += item.points
    for index, spec in enumerate(sections):
        if spec.points is not None and abs(sums[spec.section] - spec.points) > _EPS:
            reader.error(spec.line, f"sections[{index}].points",
                         f"section {spec.section.key!r} declares {spec.points:g} points but its "
                         f"items add up to {sums[spec.section]:g}")


def _check_total(reader: Reader, f: Fields, total: float | None, items: Iterable[Item]) -> None:
    if total is None:
        return
    got = sum(i.points for i in items)
    if abs(got - total) > _EPS:
        f.error("total", f"total is {total:g} but the items add up to {got:g}")
