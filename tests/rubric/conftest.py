"""Helpers for rubric tests: write a rubric to a temp file and collect its problems."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any, Callable

import pytest

from grader.rubric import RubricError, load_rubric


@pytest.fixture
def write_rubric(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[[str], Path]:
    """Write dedented YAML to ``rubrics/x.yaml`` under a temp cwd, so messages read
    ``rubrics/x.yaml:LINE: ...`` exactly as a user would see them."""
    monkeypatch.chdir(tmp_path)

    def write(text: str, name: str = "x.yaml") -> Path:
        path = Path("rubrics") / name
        path.parent.mkdir(exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
        return path

    return write


@pytest.fixture
def problems(write_rubric: Callable[[str], Path]) -> Callable[..., list[str]]:
    """Load YAML text that must fail; return its problems as printed lines."""

    def run(text: str, **kwargs: Any) -> list[str]:
        path = write_rubric(text)
        with pytest.raises(RubricError) as info:
            load_rubric(path, **kwargs)
        assert str(info.value).startswith(f"rubric {path} has {len(info.value.problems)} problem")
        return [str(p) for p in info.value.problems]

    return run


@pytest.fixture
def line_of() -> Callable[..., int]:
    """1-based line of the nth line containing ``needle`` in (dedented) rubric text."""

    def find(text: str, needle: str, nth: int = 0) -> int:
        lines = textwrap.dedent(text).lstrip("\n").splitlines()
        hits = [i + 1 for i, line in enumerate(lines) if needle in line]
        return hits[nth]

    return find
