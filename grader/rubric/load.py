"""``load_rubric``: read a rubric file and fail with every problem listed, or return a Rubric."""

from __future__ import annotations

import re
import json
import os
from pathlib import Path
from typing import Collection, Mapping

from pydantic import ValidationError

from grader.errors import GraderError
from grader.rubric.contract import resolve_references
from grader.rubric.crossrefs import rubric_problems
from grader.rubric.located import Problem, dotted, load_located, problems_from
from grader.rubric.schema import Rubric
from grader.contracts.params import problems


class RubricError(GraderError):
    """A rubric that cannot be used; ``problems`` keeps the located problems for tools/tests."""

    def __init__(self, path: str, problems: list[Problem]) -> None:
        self.path = path
        self.problems = problems
        count = f"{len(problems)} problem{'s' if len(problems) != 1 else ''}"
        lines = "\n".join(f"  {p}" for p in problems)
        super().__init__(f"rubric {path} has {count}:\n{lines}")


def display_path(path: Path) -> str:
    """The path as the user would type it: relative to the working directory when inside it."""
    try:
        return os.path.relpath(path) if path.is_absolute() and Path.cwd() in path.parents else str(path)
    except ValueError:  # pragma: no cover - other drive on Windows
        return str(path)


class _Registry:
    """Sentinel: use the analyzers registered in grader.analyze (if that layer is importable)."""

    def __repr__(self) -> str:
        return "REGISTRY"


REGISTRY = _Registry()


def registered_analyzers() -> dict[str, dict[str, bool]] | None:
    """``{analyzer: {parameter: required?}}`` from grader.analyze, or None without it."""
    try:
        from grader import analyze  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path
    except ImportError:
        return None
    return {name: {k: k in analyze.required(name) for k in sorted(analyze.defaults(name))}
            for name in analyze.names()}


def parameter_value_problems(rubric: Rubric) -> list[tuple[str, str]]:
    """Each item parameter whose value its analyzer's model refuses (``tol_reached: -1``), as
    ``(items[i].params.key, why and what is allowed)``; unknown analyzers and names are
    :func:`grader.rubric.crossrefs.rubric_problems`' to say."""
    try:
        from grader import analyze  # noqa: PLC0415 - analyze loads pandas, numpy (424 ms CPU), only on this path
    except ImportError:
        return []
    known = set(analyze.names())
    out: list[tuple[str, str]] = []
    for index, item in enumerate(rubric.items):
        model = analyze.params_model(item.analyzer) if item.analyzer in known else None
        if model is not None:
            out += [(f"items[{index}].params.{key}", f"analyzer {item.analyzer!r}: {why}")
                    for key, why in problems(model, item.params)]
    return out


def load_analyzer_files(rubric: Rubric) -> list[tuple[str, str]]:
    """Import the rubric's own analyzer files (``analyzers:``, grader.analyze.plugins); the
    problems as ``(field path, message)``. Nothing when grader.analyze is not importable (a
    wheel build reads rubrics with PyYAML and pydantic only)."""
    try:
        from grader.analyze.plugins import load_file  # noqa: PLC0415 - analyze.plugins loads pandas, numpy (424 ms CPU), only on this path
    except ImportError:
        return []
    out: list[tuple[str, str]] = []
    for index, file in enumerate(rubric.analyzers):
        if file.suffix != ".py" or not file.is_file():
            if file.suffix == ".py":
                out.append((f"analyzers[{index}]", f"analyzer file not found (looked for {file})"))
            continue                              # (a wrong suffix is the model's problem)
        try:
            load_file(file)
        except GraderError as exc:
            out.append((f"analyzers[{index}]", str(exc)))
    return out


def load_rubric(path: str | os.PathLike[str], *, check_files: bool = True,
                analyzers: Collection[str] | Mapping[str, Collection[str]] | _Registry | None = REGISTRY,
                ) -> Rubric:
    """Load and validate a rubric YAML file.

    Relative paths in the rubric (``support`` packages, ``handout``, replayed bags) are resolved
    against the rubric's own directory, so a rubric and its fixtures can move together.
    ``check_files`` makes missing ones errors. ``analyzers`` (default: the grader.analyze
    registry, after importing the rubric's own ``analyzers:`` files) makes unknown analyzer names
    and parameters errors now, not hours into a batch; pass None to skip that (and the import). Raises :class:`RubricError` (a GraderError) listing every problem as
    ``file:line: field: message``.
    """
    path = Path(path)
    shown = display_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GraderError(f"rubric {shown} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GraderError(f"cannot read rubric {shown}: {exc}") from None
    data, located = load_located(text, shown, empty="the rubric is empty")
    if located.problems or data is None:
        raise RubricError(shown, sorted(located.problems))
    if not isinstance(data, dict):
        raise RubricError(shown, [Problem(shown, 1, "", "expected a mapping, got a list" if isinstance(data, list)
                                             else f"expected a mapping, got {data!r}")])
    data, unresolved = resolve_references(data)      # $role -> the contract's name
    refs = sorted({Problem(shown, located.line(p), dotted(p), m) for p, m in unresolved})
    try:
        rubric = Rubric.model_validate_json(json.dumps(data, default=str),
                                            context={"base_dir": path.resolve().parent})
    except ValidationError as exc:
        at_refs = {p.path for p in refs}
        found = [p for p in problems_from(exc.errors(), data, located, Rubric) if p.path not in at_refs]
        raise RubricError(shown, sorted(set(refs + found))) from None
    if refs:
        raise RubricError(shown, refs)
    plugin_problems: list[tuple[str, str]] = []
    if isinstance(analyzers, _Registry):
        plugin_problems = load_analyzer_files(rubric)
        analyzers = registered_analyzers()
        plugin_problems += parameter_value_problems(rubric)
    cross = rubric_problems(rubric, analyzers, check_files)   # cross-references (grader.rubric.crossrefs)
    cross += [p for p in plugin_problems if p not in cross]
    if cross:
        raise RubricError(shown, sorted({Problem(shown, located.line(_split(p)), p, m) for p, m in cross}))
    rubric._source = path.resolve()
    return rubric


def _split(dotted: str) -> tuple:
    """``items[3].params.k`` -> ``("items", 3, "params", "k")`` (to look up a line)."""
    out: list = []
    for part in re.findall(r"\[(\d+)\]|\[('[^']*')\]|([^.\[\]]+)", dotted):
        index, quoted, name = part
        out.append(int(index) if index else quoted.strip("'") if quoted else name)
    return tuple(out)
