"""A recording is reused by the same grader and never by a changed one; the cache that grading
fills is listed, pruned and kept under its cap.

One submission, one short scenario (the simulator, the recorder, the driver and a student node:
every grader process of a recording runs), graded three times into one cache by copies of the
grader package: the same code twice (the second run copies the recording), then a copy with one
driver constant changed (it records again). The first run also shows, with
``PYTHONPROFILEIMPORTTIME``, that every grader module the scenario child and its grader processes
import is in the recording code set; a regrade by the changed grader names the recording another
grader made, in its output, result.json and the instructor's report.

The cache those runs filled (one build area, two recordings) is then listed (``grader cache
info``), pruned to a size (the least recently used recording goes, the rest stay), and a batch of
two submissions with a tiny cap (``--cache-max-size 1k``) grades both correctly and leaves the
cache under the cap.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from grader.cache.code import PACKAGE, RECORDING_ROOTS, closure
from grader.cache.store import entries

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
    cache = root / "cache"
    out: dict = {"root": root, "same": same, "edited": edited, "cache": cache}
    for name, site, env in (("first", same, {"PYTHONPROFILEIMPORTTIME": "1"}), ("again", same, {}),
                            ("changed", edited, {})):
        t0 = time.monotonic()
        _grader(site, "grade", str(root / "subs"), "--rubric", str(root / "hello.yaml"), "-o", str(root / name),
                "--cache-dir", str(cache), "--jobs", "2", **env)
        out[f"{name}_s"] = round(time.monotonic() - t0, 1)
        out[name] = json.loads((root / name / "alice" / "result.json").read_text())
        out[f"{name}_batch"] = json.loads((cache / "last_batch.json").read_text())
    # the cache those runs filled: listed, then pruned to a size (least recently used first)
    cache_args = ("--cache-dir", str(cache))
    out["info"] = json.loads(_grader(same, "cache", "info", "--json", *cache_args).stdout)
    out["info_text"] = _grader(same, "cache", "info", *cache_args).stdout
    out["entries"] = {e.path.name: (e.kind, e.size, e.last_used) for e in entries(cache)}
    oldest = min((v for v in out["entries"].items() if v[1][0] == "recording"), key=lambda kv: kv[1][2])[0]
    out["lru_recording"] = oldest
    fits = sum(size for _kind, size, _used in out["entries"].values()) - out["entries"][oldest][1]
    out["dry_run"] = _grader(same, "cache", "prune", "--max-size", str(fits), "--dry-run", *cache_args).stdout
    out["entries_after_dry_run"] = sorted(e.path.name for e in entries(cache))
    out["pruned"] = _grader(same, "cache", "prune", "--max-size", str(fits), *cache_args).stdout
    out["entries_after_prune"] = {e.path.name: e.kind for e in entries(cache)}
    # a batch of two (alice, and bob, whose package differs by a comment) with a tiny cap
    shutil.copytree(SUBMISSION, root / "subs2" / "alice", ignore=shutil.ignore_patterns("expected.yaml"))
    shutil.copytree(SUBMISSION, root / "subs2" / "bob", ignore=shutil.ignore_patterns("expected.yaml"))
    node = root / "subs2" / "bob" / "src" / "my_first_package" / "my_first_package" / "my_first_node.py"
    node.write_text(node.read_text() + "\n# bob's copy\n")
    t0 = time.monotonic()
    capped = _grader(same, "grade", str(root / "subs2"), "--rubric", str(root / "hello.yaml"), "-o",
                     str(root / "capped"), *cache_args, "--jobs", "2", "--cache-max-size", "1k")
    out["capped_s"] = round(time.monotonic() - t0, 1)
    out["capped_stderr"] = capped.stderr
    out["capped"] = {s: json.loads((root / "capped" / s / "result.json").read_text()) for s in ("alice", "bob")}
    out["capped_batch"] = json.loads((cache / "last_batch.json").read_text())
    out["capped_info"] = json.loads(_grader(same, "cache", "info", "--json", *cache_args).stdout)
    print({k: v for k, v in out.items() if k.endswith("_s")})       # durations, for the commit message
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


def test_cache_info_lists_what_grading_filled(runs: dict) -> None:
    info = runs["info"]
    kinds = {k: v["entries"] for k, v in info["kinds"].items()}
    # one build area for all three runs (the driver makes no build), two recordings (two graders)
    assert kinds == {"build": 1, "support build": 0, "recording": 2, "temporary": 0}, kinds
    assert info["kinds"]["build"]["bytes"] > 0 and info["kinds"]["recording"]["bytes"] > 0
    assert info["total_bytes"] == sum(v["bytes"] for v in info["kinds"].values())
    last = info["last_batch"]                 # the changed grader's batch
    assert last["submissions"] == 1 and last["builds_hit"] == 1 and last["recordings_missed"] == 1
    text = runs["info_text"]
    assert "recording            2" in text and "recordings 0/1 (0%) reused" in text, text
    assert "builds 1/1 (100%) from the cache" in text


def test_cache_prune_removes_the_least_recently_used_first(runs: dict) -> None:
    lru = runs["lru_recording"]
    # the unchanged grader's recording, last used by its second run, before the changed grader's
    assert lru == runs["again"]["recordings"]["hello"]["key"]
    assert "would remove 1 recording" in runs["dry_run"], runs["dry_run"]
    assert lru in runs["entries_after_dry_run"]
    assert "removed 1 recording" in runs["pruned"], runs["pruned"]
    after = runs["entries_after_prune"]
    assert lru not in after and runs["changed"]["recordings"]["hello"]["key"] in after
    assert sorted(after.values()) == ["build", "recording"]


def test_a_batch_with_a_tiny_cap_grades_correctly_and_ends_under_it(runs: dict) -> None:
    for sid, result in runs["capped"].items():
        assert [i["status"] for i in result["items"]] == ["pass"], (sid, result["items"])
        assert result["auto_score"] == result["auto_max"] == 1, result
    batch = runs["capped_batch"]
    assert batch["submissions"] == 2 and batch["recordings_missed"] == 2      # alice's was pruned above
    assert batch["builds_hit"] == 1 and batch["builds_missed"] == 1            # bob's comment: a build of its own
    assert batch["pruned_entries"] >= 4 and batch["size_after"] <= 1000, batch
    assert runs["capped_info"]["total_bytes"] <= 1000 and runs["capped_info"]["entries"] == 0
    assert "over its 1.0 kB cap: removed" in runs["capped_stderr"], runs["capped_stderr"][-2000:]
