"""Copy rubrics together with every file they reference, so they work from anywhere.

A rubric names its analyzer files, support packages and replayed bags by paths relative to the rubric file
(``../fixtures/support/...``). To ship a rubric in the wheel or a Gradescope bundle, the rubric and
those files are copied keeping their layout relative to a common root: the relative paths then
resolve inside the copy exactly as in the source tree, so the rubric is copied byte for byte and
``rubrics/`` stays the single source (nothing is rewritten).

Used at wheel build time (``setup.py``, only PyYAML and pydantic available: this module must not import
pandas, rclpy or the analyzers) and by ``grader gradescope``.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Iterable

from grader.errors import GraderError
from grader.rubric.load import load_rubric
from grader.rubric.schema import Rubric

#: never copied from a support package: build products, VCS data, caches
IGNORED = ("build", "install", "log", ".git", "__pycache__", "*.pyc", ".pytest_cache", ".grader-check")


def referenced_paths(rubric: Rubric) -> list[Path]:
    """Absolute paths of everything ``rubric`` needs besides itself: its analyzer files, support
    packages and the bags its scenarios replay, in rubric order without repeats."""
    found: dict[Path, None] = {}
    for path in rubric.analyzers:
        found.setdefault(Path(path), None)
    for path in rubric.support.values():
        found.setdefault(Path(path), None)
    for scenario in rubric.scenarios.values():
        for step in scenario.steps:
            if step.replay is not None:
                found.setdefault(Path(step.replay.bag), None)
    return list(found)


def _copy(src: Path, dest: Path) -> None:
    if src.is_dir():
        shutil.copytree(src, dest, ignore=shutil.ignore_patterns(*IGNORED), dirs_exist_ok=True)
    else:
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dest)


def stage_rubrics(rubrics: Iterable[Path], dest: Path, *, root: Path | None = None) -> list[Path]:
    """Copy each rubric and the files it references into ``dest``; returns the staged rubrics.

    ``root`` is the folder whose layout is kept (the repository for the wheel); by default the
    deepest folder holding every rubric and every referenced file. Each staged rubric is loaded
    again and must find all its files inside ``dest``: a rubric that names a file by an absolute
    path, or outside ``root``, is an error instead of a bundle that breaks on another machine.
    """
    rubrics = [Path(r).resolve() for r in rubrics]
    loaded = [load_rubric(r, analyzers=None) for r in rubrics]   # check_files: every file exists
    refs = {r: referenced_paths(rub) for r, rub in zip(rubrics, loaded)}
    if root is None:
        everything = [str(r.parent) for r in rubrics] + [str(p) for ps in refs.values() for p in ps]
        root = Path(os.path.commonpath(everything)) if everything else Path.cwd()
    root = Path(root).resolve()
    dest = Path(dest).resolve()
    staged = []
    for rubric_path in rubrics:
        for path in [rubric_path, *refs[rubric_path]]:
            if not path.is_relative_to(root):
                raise GraderError(f"rubric {rubric_path.name} needs {path}, which is outside {root}; "
                                  "keep a rubric's support packages and bags next to it.")
            _copy(path, dest / path.relative_to(root))
        staged.append(dest / rubric_path.relative_to(root))
    for original, copy in zip(rubrics, staged):
        outside = [p for p in referenced_paths(load_rubric(copy, analyzers=None))
                   if not p.resolve().is_relative_to(dest)]
        if outside:
            raise GraderError(f"rubric {original.name} names {outside[0]} by an absolute path; write it "
                              "relative to the rubric file so the rubric can be packaged.")
    return staged
