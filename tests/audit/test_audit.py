"""grader rubric audit: finding the reference, leaving given code out, classifying outcomes
(offline), and one real audit of a few first-nodes mutants (slow)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from grader.audit.mutate import mutants
from grader.audit.outcome import Outcome
from grader.audit.run import _outcome, choose, find_reference, given_files
from grader.errors import GraderError
from grader.report.result import write_result
from grader.rubric.load import load_rubric
from grader.rubric.result import ItemResult, Result
from grader.rubric.schema import Section

REPO = Path(__file__).resolve().parents[2]
SUBS = REPO / "fixtures" / "submissions"


def test_reference_is_found_beside_the_handout_or_by_rubric_name(tmp_path: Path) -> None:
    lab3 = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    assert find_reference(lab3, None) == SUBS / "enee467_lab3" / "reference"          # beside the handout
    wall = load_rubric(REPO / "rubrics" / "wall_pen.yaml")                            # no handout
    assert find_reference(wall, None) == SUBS / "wall_pen" / "reference"
    assert find_reference(wall, SUBS / "wall_pen" / "chapter") == SUBS / "wall_pen" / "chapter"
    with pytest.raises(GraderError, match="not a folder"):
        find_reference(wall, tmp_path / "nope")
    alone = tmp_path / "lab.yaml"
    alone.write_text((REPO / "rubrics" / "wall_pen.yaml").read_text())
    with pytest.raises(GraderError, match=r"no reference solution found for lab\.yaml .*--reference PATH"):
        find_reference(load_rubric(alone), None)


def test_code_the_handout_gives_unchanged_is_not_mutated() -> None:
    lab3 = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    ref = SUBS / "enee467_lab3" / "reference"
    client = "src/turtle_controller_server/turtle_controller_server/action_client.py"
    assert client in given_files(ref, lab3.handout)
    chosen, made, given = choose(lab3, ref, None, None, 0)
    assert given == [client]
    assert made == len(chosen) and not any(m.file == client for m in chosen)
    everything, _, none = choose(lab3, ref, None, None, 0, all_files=True)
    assert none == [] and any(m.file == client for m in everything)
    sampled, made_again, _ = choose(lab3, ref, ["drop_call"], 4, seed=7)
    assert len(sampled) == 4 and made_again < made and {m.operator for m in sampled} == {"drop_call"}


def _result(folder: Path, points: dict[str, tuple[float, float]]) -> None:
    def item(iid: str, kind: str, p: float, mx: float) -> ItemResult:
        return ItemResult(id=iid, title=iid, section=Section("exercise", 1), kind=kind, public=True, points=p,
                          max_points=mx, status="pass" if p == mx else "partial", feedback="")

    items = [item(k, "auto", p, mx) for k, (p, mx) in points.items()] + [item("flag", "integrity", 0, 0)]
    write_result(folder.parent, folder.name, Result(lab="first-nodes", title="t", items=tuple(items)),
                 extra={"timings": {"build_s": 1.5, "scenarios_wall_s": 10}})


def test_outcomes_killed_equivalent_surviving_error(tmp_path: Path) -> None:
    m1, m2, m3, m4 = mutants(SUBS / "first_nodes" / "reference")[:4]
    _result(tmp_path / "a", {"x": (3, 3), "y": (0.5, 2)})
    _result(tmp_path / "b", {"x": (3, 3), "y": (2, 2)})
    _result(tmp_path / "c", {"x": (3, 3), "y": (2, 2)})
    killed = _outcome(m1, tmp_path / "a", None, {})
    assert (killed.status, killed.lost, killed.wall_s) == ("killed", {"y": 1.5}, 11.5)
    equivalent = _outcome(m2, tmp_path / "b", None, {m2.id: "still correct"})
    assert (equivalent.status, equivalent.reason) == ("equivalent", "still correct")
    surviving = _outcome(m3, tmp_path / "c", None, {m2.id: "still correct"})
    assert surviving.status == "surviving" and surviving.diff == m3.diff
    error = _outcome(m4, tmp_path / "d", "build: boom", {})
    assert isinstance(error, Outcome) and (error.status, error.error) == ("error", "build: boom")


# a killable mutant (no cmd_vel publish: no circle), one the rubric cannot see (a start-up log
# line nobody grades) and a renamed topic (the subscriber hears nothing)
KILLABLE = "drop_call-5c6dec4f"
SURVIVOR = "drop_call-2062c1f2"
RENAMED = "rename_topic-ee7f7777"


@pytest.mark.slow
@pytest.mark.heavy
@pytest.mark.timeout(900)
def test_audit_kills_a_broken_mutant_and_lists_survivors_with_diffs(tmp_path: Path) -> None:
    ref = SUBS / "first_nodes" / "reference"
    ids = {m.id: m for m in mutants(ref)}
    assert {KILLABLE, SURVIVOR, RENAMED} <= set(ids), "the mutants this test names changed id"
    # the rubric without its recorded equivalents, so the survivor is reported as one
    rubric = tmp_path / "first_nodes.yaml"
    text = (REPO / "rubrics" / "first_nodes.yaml").read_text()
    rubric.write_text(re.split(r"\nequivalent_mutants:", text)[0] + "\n")
    out = tmp_path / "audit"
    proc = subprocess.run([sys.executable, "-m", "grader.cli", "rubric", "audit", str(rubric), "--reference", str(ref),
                           "-o", str(out), "--only", KILLABLE, SURVIVOR, RENAMED, "--jobs", "2",
                           "--time-scale", "4", "--cache-dir", str(tmp_path / "cache")],
                          capture_output=True, text=True, timeout=840, cwd=REPO)
    assert proc.returncode == 1, proc.stdout + proc.stderr          # a survivor: exit 1
    doc = json.loads((out / "audit.json").read_text())
    status = {o["mutant"]["id"]: o["status"] for o in doc["outcomes"]}
    assert status == {KILLABLE: "killed", SURVIVOR: "surviving", RENAMED: "killed"}, proc.stdout
    lost = {o["mutant"]["id"]: o["lost"] for o in doc["outcomes"]}
    assert set(lost[KILLABLE]) == {"circle.radius", "circle.period", "circle.keeps_moving"}
    assert set(lost[RENAMED]) == {"news.heard"}
    assert doc["counts"] == {"killed": 2, "equivalent": 0, "surviving": 1, "error": 0}
    # the survivor is printed with its diff, and written into audit.md
    assert "SURVIVING (1)" in proc.stdout
    assert "-        self.get_logger().info('Number publisher has been started.')" in proc.stdout
    assert "+        pass" in proc.stdout
    md = (out / "audit.md").read_text()
    assert f"### `{SURVIVOR}`" in md and "```diff" in md
    assert (out / "graded" / "reference" / "result.json").is_file()
    assert (out / "graded" / "index.html").is_file()
