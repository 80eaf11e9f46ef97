"""`grader check`: the student's self-check runs the public items only and exits 0 only when they pass."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from grader.cli import main as grader_main

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(900)     # 158 s on a quiet machine; over 300 s at load 20
def test_check_on_a_buggy_workspace(tmp_path: Path, capsys, monkeypatch) -> None:
    ws = tmp_path / "ros2_ws"
    shutil.copytree(REPO / "fixtures" / "submissions" / "enee467_lab3" / "bm_log10", ws)
    monkeypatch.chdir(ws)                       # default workspace: the current folder
    rc = grader_main(["check", "--lab", "enee467-lab3", "--cache-dir", str(tmp_path / "cache")])
    out = capsys.readouterr().out
    assert rc == 1
    # the names the lab fixes come first, before anything runs
    assert out.index("Names this lab fixes") < out.index("self-check (")
    assert "topic       /random_numbers" in out and "ros2 run random_numbers simple_publisher" in out
    assert "NAME " not in out                   # bm_log10 spells every fixed name right
    assert "FAIL  ex1.boxmuller" in out and "log10" in out
    assert "PASS  ex2.goals_reached" in out
    assert "integrity." not in out              # hidden items are not shown to students
    report = ws / ".grader-check" / "check"
    assert (report / "report.html").exists()
    # the self-check's report replays each scenario it ran, from data beside it (issue 39)
    html = (report / "report.html").read_text()
    ran = sorted(p.parent.parent.name for p in report.glob("scenarios/*/bag/metadata.yaml"))
    assert len(ran) >= 5 and all((report / "scenarios" / sc / "replay.js").is_file() and
                                 f'data-scenario="{sc}"' in html for sc in ran), ran
    doc = json.loads((report / "result.json").read_text())
    assert doc["view"] == "student"
    assert not any(i["id"].startswith("integrity.") for i in doc["items"])


def test_check_needs_a_lab(capsys) -> None:
    assert grader_main(["check", "."]) == 2
    assert "--lab enee467-lab3" in capsys.readouterr().err
    assert grader_main(["check", ".", "--lab", "nope"]) == 2
    assert "known labs: enee467-lab3" in capsys.readouterr().err
