"""A rubric's cross-references, checked once the whole model is at hand: scenarios, analyzers
and their parameters, sections and their sums, ``requires`` (unknown, unscored, cycles), files,
intake fields and recorded equivalent mutants. Each problem is ``(field path, message)``; the
loader (``grader.rubric.load``) turns the path into ``file:line: field``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Collection, Mapping

from grader.rubric.intake_fields import intake_problems
from grader.rubric.schema import POINTS_EPS, Rubric
from grader.contracts.text import suggest
from grader.contracts.mutants import OPERATORS


def rubric_problems(rubric: Rubric, analyzers: Mapping[str, Any] | Collection[str] | None,
                    check_files: bool) -> list[tuple[str, str]]:
    """Cross-references as ``(field path, message)``: scenarios, analyzers, sections, sums,
    ``requires``, files. ``analyzers``: name -> accepted parameter names (None: unchecked)."""
    out: list[tuple[str, str]] = []
    for sid, scenario in rubric.scenarios.items():
        out += [(f"scenarios.{sid}.{path}", msg) for path, msg in scenario.problems()]
        if check_files:
            for i, step in enumerate(scenario.steps):
                if step.replay is not None and not step.replay.bag.exists():
                    out.append((f"scenarios.{sid}.steps[{i}].replay.bag",
                                f"bag not found (looked for {step.replay.bag})"))
    seen_files: dict[Path, int] = {}
    for index, file in enumerate(rubric.analyzers):
        at = f"analyzers[{index}]"
        if file.suffix != ".py":
            out.append((at, f"an analyzer file is a Python module ending in .py, not {file.name!r}"))
        elif file in seen_files:
            out.append((at, f"{file.name} is listed twice (first at analyzers[{seen_files[file]}])"))
        elif check_files and not file.is_file():
            out.append((at, f"analyzer file not found (looked for {file})"))
        seen_files.setdefault(file, index)
    if check_files:
        for name, path in rubric.support.items():
            if not (path / "package.xml").is_file():
                out.append((f"support.{name}", f"support package {name!r}: no package.xml in {path}"))
    ids: dict[str, int] = {}
    scored = {i.id for i in rubric.items if i.kind == "auto"}
    all_ids = [i.id for i in rubric.items]
    for index, item in enumerate(rubric.items):
        at = f"items[{index}]"
        if item.id in ids:
            out.append((f"{at}.id", f"duplicate item id {item.id!r} (first at items[{ids[item.id]}])"))
        ids.setdefault(item.id, index)
        for sid in item.scenario:
            if sid not in rubric.scenarios:
                hint = suggest(sid, list(rubric.scenarios)) or (
                    f" (defined: {', '.join(sorted(rubric.scenarios))})" if rubric.scenarios
                    else " (no scenarios defined)")
                out.append((f"{at}.scenario", f"unknown scenario {sid!r}{hint}"))
        if item.analyzer and analyzers is not None:
            if item.analyzer not in analyzers:
                out.append((f"{at}.analyzer", f"unknown analyzer {item.analyzer!r}"
                            + suggest(item.analyzer, list(analyzers))))
            elif isinstance(analyzers, Mapping):
                accepted = set(analyzers[item.analyzer])
                for key in item.params:
                    if key not in accepted:
                        out.append((f"{at}.params.{key}", f"analyzer {item.analyzer!r} takes no parameter "
                                    f"{key!r}" + (suggest(key, sorted(accepted)) or
                                                  f" (accepted: {', '.join(sorted(accepted)) or 'none'})")))
                needed = accepted if not isinstance(analyzers[item.analyzer], Mapping) else \
                    {k for k, req in analyzers[item.analyzer].items() if req is True}
                for key in sorted(needed - set(item.params)) if isinstance(analyzers[item.analyzer], Mapping) else ():
                    out.append((f"{at}.params", f"analyzer {item.analyzer!r} needs the parameter {key!r}"))
                for key in item.hidden_params:
                    if key not in accepted:
                        out.append((f"{at}.hidden_params", f"analyzer {item.analyzer!r} has no "
                                    f"parameter {key!r} to hide"))
        for req in item.requires:
            if req not in all_ids:
                out.append((f"{at}.requires", f"unknown item {req!r}" + suggest(req, all_ids)))
            elif req not in scored:
                out.append((f"{at}.requires", f"{req!r} is not a scored (auto) item; only those can gate points"))
            elif req == item.id:
                out.append((f"{at}.requires", "an item cannot require itself"))
        if item.requires and item.kind != "auto":
            out.append((f"{at}.requires", "only auto items earn points that can be gated"))
    out += _cycles(rubric)
    out += _sums(rubric)
    out += intake_problems(rubric)
    out += _equivalents(rubric)
    return out

def _equivalents(rubric: Rubric) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    first: dict[str, int] = {}
    for index, entry in enumerate(rubric.equivalent_mutants):
        at = f"equivalent_mutants[{index}].mutant"
        operator = entry.mutant.rsplit("-", 1)[0]
        if operator not in OPERATORS:
            out.append((at, f"unknown mutation operator {operator!r} in {entry.mutant!r} "
                            f"(known: {', '.join(OPERATORS)}); copy the id from grader rubric audit's report"))
        if entry.mutant in first:
            out.append((at, f"mutant {entry.mutant!r} is listed twice (first at "
                            f"equivalent_mutants[{first[entry.mutant]}])"))
        first.setdefault(entry.mutant, index)
    return out

def _cycles(rubric: Rubric) -> list[tuple[str, str]]:
    graph = {i.id: set(i.requires) for i in rubric.items}
    for index, item in enumerate(rubric.items):
        seen, todo = set(), list(item.requires)
        while todo:
            nxt = todo.pop()
            if nxt == item.id:
                return [(f"items[{index}].requires", f"{item.id!r} requires itself through others")]
            if nxt not in seen:
                seen.add(nxt)
                todo += graph.get(nxt, ())
    return []

def _sums(rubric: Rubric) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    if rubric.sections:
        declared = {s.section for s in rubric.sections}
        sums = {s: 0.0 for s in declared}
        seen: set = set()
        for index, spec in enumerate(rubric.sections):
            if spec.section in seen:
                out.append((f"sections[{index}].section", f"section {spec.section.key!r} is listed twice"))
            seen.add(spec.section)
        for index, item in enumerate(rubric.items):
            if item.section not in declared:
                out.append((f"items[{index}].section", f"section {item.section.key!r} is not in the "
                            "sections table" + suggest(item.section.key, [s.section.key for s in rubric.sections])))
                continue
            sums[item.section] += item.max_points
        for index, spec in enumerate(rubric.sections):
            if spec.points is not None and abs(sums[spec.section] - spec.points) > POINTS_EPS:
                out.append((f"sections[{index}].points", f"section {spec.section.key!r} declares "
                            f"{spec.points:g} points but its items add up to {sums[spec.section]:g}"))
    if rubric.total is not None:
        got = sum(i.max_points for i in rubric.items)
        if abs(got - rubric.total) > POINTS_EPS:
            out.append(("total", f"total is {rubric.total:g} but the items add up to {got:g}"))
    return out
