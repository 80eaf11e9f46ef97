"""A real graded Lab 3 batch, without ROS: the committed recorded bags of three fixture
submissions (fixtures/bags/lab3/<submission>/<scenario>/) laid out as `grader grade` leaves
them (OUT/<id>/scenarios/<scenario>/bag) and graded from them with `grader regrade`.

reference has every scenario (50/50 automatic points); bm_log10 and wrong_topic have one each.
The batch is built once per session; every test gets its own copy.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from scorehelpers import REPO, RUBRIC

from grader.cli import main as grader_main

BAGS = REPO / "fixtures" / "bags" / "lab3"
SUBMISSIONS = ("reference", "bm_log10", "wrong_topic")


@pytest.fixture(scope="session")
def graded_batch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("batch") / "OUT"
    for sid in SUBMISSIONS:
        for scenario in sorted(p for p in (BAGS / sid).iterdir() if p.is_dir()):
            shutil.copytree(scenario, out / sid / "scenarios" / scenario.name)
    assert grader_main(["regrade", str(out), "--rubric", str(RUBRIC)]) == 0
    return out


@pytest.fixture
def batch(graded_batch: Path, tmp_path: Path) -> Path:
    """A private copy of the graded batch (OUT)."""
    out = tmp_path / "OUT"
    shutil.copytree(graded_batch, out)
    return out
