"""Fixtures of the sandbox tests: a fake build holding the hostile programs, a "world" of files
no student may touch (other results, a rubric, fixtures, a build cache), and a unique token in
the argv of the processes a test starts (helpers: sandboxhelpers.py)."""

from __future__ import annotations

import os
import shutil
import signal
import uuid
from pathlib import Path

import pytest
from sandboxhelpers import HERE, processes_with


@pytest.fixture
def token():
    """A unique word for the argv of every process a test starts (found in /proc afterwards);
    whatever still carries it when the test ends (a failed containment) is killed by its pid."""
    word = f"grader-test-{uuid.uuid4().hex[:12]}"
    yield word
    for pid in processes_with(word):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


@pytest.fixture
def world(tmp_path: Path) -> Path:
    """Files outside the scenario's output folder that no student process may change."""
    w = tmp_path / "world"
    (w / "batch" / "classmate").mkdir(parents=True)
    (w / "batch" / "classmate" / "result.json").write_text('{"score": 12}')
    (w / "batch" / "grades.csv").write_text("submission,total\nclassmate,12\n")
    (w / "rubric").mkdir()
    (w / "rubric" / "lab.yaml").write_text("hidden_params: {secret: 42}\n")
    (w / "fixtures" / "reference").mkdir(parents=True)
    (w / "fixtures" / "reference" / "expected.yaml").write_text("ex1: pass\n")
    (w / "cache" / "0123abcd").mkdir(parents=True)
    (w / "cache" / "0123abcd" / "result.json").write_text("{}")
    return w


@pytest.fixture
def fake_build(tmp_path: Path) -> Path:
    """``<build>/install/hostile`` (an install prefix holding the test programs) and ``<build>/src``."""
    prefix = tmp_path / "build" / "install" / "hostile"
    (prefix / "lib" / "hostile").mkdir(parents=True)
    for script in ("hostile.py", "talker.py"):
        shutil.copy(HERE / script, prefix / "lib" / "hostile" / script)
    (tmp_path / "build" / "src" / "hostile").mkdir(parents=True)
    (tmp_path / "build" / "src" / "hostile" / "package.xml").write_text("<package><name>hostile</name></package>")
    return prefix
