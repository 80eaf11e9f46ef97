"""A recording is reused by the same grader and never by a changed one.

One submission, one short scenario (the simulator, the recorder, the driver and a student node:
every grader process of a recording runs), graded three times into one cache by copies of the
grader package: the same code twice (the second run copies the recording), then a copy with one
driver constant changed (it records again). The first run also shows, with
``PYTHONPROFILEIMPORTTIME``, that every grader module the scenario child and its grader processes
import is in the recording code set; a regrade by the changed grader names the recording another
grader made, in its output, result.json and the instructor's report.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from grader.cache.code import PACKAGE, RECORDING_ROOTS, closure

REPO = Path(__file__).resolve().parents[2]
SUBMISSION = REPO / "fixtures" / "submissions" / "first_nodes" / "reference"
RUBRIC = """\
schema: 1
lab: cache-reuse
title: "A greeting, recorded once"
total: 1
sections:
  - {section: {part: 1}, title: Greeting, points: 1}
scenarios:
  hello:
    description: my_first_node beside the simulator, so every grader process of a recording runs.
    processes:
      - {name: node, package: my_first_package, executable: my_first_node}
    steps:
      - id: greeting
        until: {condition: output, process: node, pattern: "(?i)hello"}
        timeout: 15
      - {id: idle, wait: 0.5}
    limits: {wall_s: 60}
items:
  - id: node.greeting
    title: my_first_node logs a greeting
    section: {part: 1}
    points: 1
    scenario: hello
    analyzer: logged
    params: {logger: my_first_node, pattern: "(?i)\\\\bhello\\\\b"}
"""
DRIVER_CONSTANT = ("poll: float = 0.02,", "poll: float = 0.025,")      # Driver.wait_until's poll period
IMPORT_LINE = re.compile(r"^import time:\s+\d+ \|\s+\d+ \|\s+(grader(?:\.\w+)*)\s*$", re.M)

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(3600)]


def _grader_copy(dest: Path, edit: tuple[str, str] | None = None) -> Path:
    shutil.copytree(PACKAGE, dest / "grader", ignore=shutil.ignore_patterns("__pycache__", "_data"))
    if edit:
        driver = dest / "grader" / "scenario" / "driver.py"
        text = driver.read_text()
        assert edit[0] in text, "the driver constant this test changes is gone: pick another"
        driver.write_text(text.replace(edit[0], edit[1]))
    return dest


def _grader(site: Path, *args: str, **env: str) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "grader.cli", *args], cwd=site, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(site), **env}, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("reuse")
    same, edited = _grader_copy(root / "same"), _grader_copy(root / "edited", DRIVER_CONSTANT)
    shutil.copytree(SUBMISSION, root / "subs" / "alice", ignore=shutil.ignore_patterns("expected.yaml"))
    (root / "hello.yaml").write_text(RUBRIC)
    out: dict = {"root": root, "same": same, "edited": edited}
    for name, site, env in (("first", same, {"PYTHONPROFILEIMPORTTIME": "1"}), ("again", same, {}),
                            ("changed", edited, {})):
        _grader(site, "grade", str(root / "subs"), "--rubric", str(root / "hello.yaml"), "-o", str(root / name),
                "--cache-dir", str(root / "cache"), "--jobs", "2", **env)
        out[name] = json.loads((root / name / "alice" / "result.json").read_text())
        out[f"{name}_batch"] = json.loads((root / "cache" / "last_batch.json").read_text())
    return out


def test_an_unchanged_grader_reuses_the_recording(runs: dict) -> None:
    first, again = runs["first"], runs["again"]
    key = first["recordings"]["hello"]["key"]
    assert key and first["scenarios_reused"] == {} and runs["first_batch"]["recordings_missed"] == 1
    assert again["scenarios_reused"]["hello"]["key"] == key
    assert again["scenarios_reused"]["hello"]["from"] == "alice"
    assert again["recordings"]["hello"]["reused_from"]["from"] == "alice"
    assert again["recordings"]["hello"]["made_by"] == first["recordings"]["hello"]["made_by"]
    assert runs["again_batch"]["recordings_hit"] == 1 and runs["again_batch"]["builds_hit"] == 1
    assert [i["status"] for i in again["items"]] == [i["status"] for i in first["items"]] == ["pass"]


def test_a_changed_driver_constant_records_again(runs: dict) -> None:
    first, changed = runs["first"], runs["changed"]
    assert changed["scenarios_reused"] == {}
    assert "reused_from" not in changed["recordings"]["hello"]
    assert changed["recordings"]["hello"]["key"] != first["recordings"]["hello"]["key"]
    assert changed["recordings"]["hello"]["made_by"]["code"] != first["recordings"]["hello"]["made_by"]["code"]
    assert runs["changed_batch"]["recordings_missed"] == 1 and runs["changed_batch"]["recordings_hit"] == 0
    assert runs["changed_batch"]["builds_hit"] == 1            # the driver makes no build: that stays
    assert [i["status"] for i in changed["items"]] == ["pass"]


def test_every_module_a_recording_imports_is_in_the_code_set(runs: dict) -> None:
    scenario = runs["root"] / "first" / "alice" / "scenarios" / "hello"
    logs = [scenario / "scenario.log", *sorted((scenario / "logs").glob("*"))]
    imported = {m for f in logs if f.is_file() for m in IMPORT_LINE.findall(f.read_text(errors="replace"))}
    assert {"grader.scenario.driver", "grader.bag.recorder_thread", "grader.sim.node"} <= imported, imported
    modules, _ = closure(RECORDING_ROOTS, package=runs["same"] / "grader")
    assert imported - modules == set()


def test_a_regrade_names_recordings_another_grader_made(runs: dict) -> None:
    root = runs["root"]
    out = _grader(runs["edited"], "regrade", str(root / "first"), "--rubric", str(root / "hello.yaml")).stdout
    assert "alice: 1/1  (rests on recordings another grader made: hello)" in out
    assert "note: 1 of 1 grades rest on recordings made by another grader" in out
    result = json.loads((root / "first" / "alice" / "result.json").read_text())
    assert "recorded by grader" in result["recordings_by_other_grader"]["hello"]
    assert result["recordings"]["hello"]["key"] == runs["first"]["recordings"]["hello"]["key"]
    assert "its grade rests on a recording recorded by grader" in (root / "first" / "alice" / "report.html").read_text()
    # the grader that made it sees nothing to say
    out = _grader(runs["same"], "regrade", str(root / "first"), "--rubric", str(root / "hello.yaml")).stdout
    assert "another grader" not in out
    assert "recordings_by_other_grader" not in json.loads((root / "first" / "alice" / "result.json").read_text())
