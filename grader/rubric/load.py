"""``load_rubric``: read a rubric file and fail with every problem listed, or return a Rubric."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Collection, Mapping

from grader.errors import GraderError
from grader.rubric._nodes import Problem, parse
from grader.rubric.schema import Rubric, validate


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


def registered_analyzers() -> dict[str, list[str]] | None:
    """``{analyzer: accepted parameter names}`` from grader.analyze, or None without it."""
    try:
        from grader import analyze
    except ImportError:
        return None
    names, defaults = getattr(analyze, "names", None), getattr(analyze, "defaults", None)
    if names is None or defaults is None:
        return None
    return {name: sorted(defaults(name)) for name in names()}


def load_rubric(path: str | os.PathLike[str], *, check_files: bool = True,
                analyzers: Collection[str] | Mapping[str, Collection[str]] | _Registry | None = REGISTRY,
                ) -> Rubric:
    """Load and validate a rubric YAML file.

    Relative paths in the rubric (``support`` packages, replayed bags) are resolved against the
    rubric's own directory, so a rubric and its fixtures can move together. ``check_files``
    makes missing support packages / bags errors. ``analyzers`` (default: the grader.analyze
    registry) makes unknown analyzer names and parameters errors now, not hours into a batch;
    pass None to skip that (e.g. for a rubric whose analyzers are not written yet). Raises
    :class:`RubricError` (a GraderError) listing every problem as ``file:line: field: message``.
    """
    if isinstance(analyzers, _Registry):
        analyzers = registered_analyzers()
    path = Path(path)
    shown = display_path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GraderError(f"rubric {shown} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GraderError(f"cannot read rubric {shown}: {exc}") from None
    root, problems = parse(text, shown)
    if problems:
        raise RubricError(shown, problems)
    rubric, problems = validate(root, shown, path.resolve().parent, check_files=check_files,
                                analyzers=analyzers)
    if problems or rubric is None:
        raise RubricError(shown, problems)
    return dataclasses.replace(rubric, source=path.resolve())
