"""Source similarity (grader.similarity.code) on the fixtures: disguised copies rank first, given
code never counts, known solutions are found both ways. No ROS."""

from __future__ import annotations

import ast
import shutil
from pathlib import Path

import pytest

from grader.similarity import code
from grader.similarity.files import snapshot, source_files
from grader.testing.copies import disguise_python, disguise_tree
from grader.testing.similarity_class import KNOWN, LAB3, SIM

REPO = Path(__file__).resolve().parents[2]
SUPPORT = REPO / "fixtures" / "support" / "enee467_lab3"


@pytest.fixture(scope="module")
def boiler():
    return code.boilerplate_hashes([LAB3 / "handout", SUPPORT])


def _class(tmp: Path) -> dict[str, Path]:
    subs = {"orig": LAB3 / "no_wrap" / "src" / "turtle_control",
            "rewritten": SIM / "rewritten_no_wrap",
            "honest_b": SIM / "honest_b", "honest_c": SIM / "honest_c"}
    for i, name in enumerate(("copy_a", "copy_b"), 1):
        subs[name] = disguise_tree(subs["orig"], tmp / name, seed=i)
    subs["known_copy"] = disguise_tree(KNOWN / "public_turtle_lab3", tmp / "known_copy", seed=7)
    return subs


def test_disguise_keeps_python_and_changes_every_own_name():
    text = (LAB3 / "no_wrap/src/turtle_control/turtle_control/turtle_control.py").read_text()
    out = disguise_python(text, seed=3)
    assert out != text
    tree = ast.parse(out)
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    defs = {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    attrs = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
    assert not {"theta_e", "x_e", "compute_control", "TurtleControl", "pose_callback", "K_1"} & (names | defs | attrs)
    assert {"rclpy", "np", "Twist"} <= names and "main" in defs and "create_publisher" in attrs
    assert "#" not in "".join(line.split('"')[0] for line in out.splitlines())   # comments dropped
    assert len(out.splitlines()) < len(text.splitlines())                         # another layout


def test_copies_rank_first_by_source(tmp_path, boiler):
    subs = _class(tmp_path)
    sets = [code.read_set(sid, path, boiler) for sid, path in sorted(subs.items())]
    matches = code.compare_all(sets, min_shared=8)
    ranked = sorted(matches.values(), key=lambda m: -m.score)
    top = {frozenset((m.a, m.b)) for m in ranked[:3]}
    assert top == {frozenset(p) for p in (("orig", "copy_a"), ("orig", "copy_b"), ("copy_a", "copy_b"))}
    for m in ranked[:3]:
        assert m.score > 0.95, m           # renamed and reformatted: the same fingerprints
    # a rewrite (other structure, same constants) is not a source copy; behaviour finds it (test_sim_class)
    rewritten = max((m.score for m in matches.values() if "rewritten" in (m.a, m.b)), default=0.0)
    assert rewritten < 0.3
    honest = max((m.score for m in matches.values() if {m.a, m.b} <= {"honest_b", "honest_c", "known_copy"}),
                 default=0.0)
    assert honest < 0.5


def test_given_code_never_counts(tmp_path, boiler):
    """Two submissions that only hand back the handout (and the support package) share nothing."""
    a = shutil.copytree(LAB3 / "handout" / "src", tmp_path / "a")
    b = shutil.copytree(LAB3 / "handout" / "src", tmp_path / "b")
    sa, sb = code.read_set("a", a, boiler), code.read_set("b", b, boiler)
    assert sa.size == 0 and sb.size == 0
    assert code.compare_all([sa, sb], min_shared=1) == {}
    # without the boilerplate they are identical: the removal is what makes them 0
    assert code.compare_one(code.read_set("a", a), code.read_set("b", b)).score == 1.0


def test_known_solution_both_ways(tmp_path, boiler):
    subs = _class(tmp_path)
    known = code.read_set("known:public_turtle_lab3", KNOWN / "public_turtle_lab3", boiler)
    scores = {sid: code.compare_one(code.read_set(sid, path, boiler), known) for sid, path in subs.items()}
    best = max(scores, key=lambda s: scores[s].score)
    assert best == "known_copy"
    assert scores["known_copy"].a_in_b > 0.8 and scores["known_copy"].b_in_a > 0.8
    assert all(m.score < 0.5 for sid, m in scores.items() if sid != "known_copy")


def test_counted_files_and_interfaces(tmp_path, boiler):
    """Launch files, CMakeLists.txt and interface definitions count; a reformatted .srv matches."""
    pkg = tmp_path / "ws" / "src" / "goal_if"
    (pkg / "srv").mkdir(parents=True)
    (pkg / "launch").mkdir()
    (pkg / "srv" / "SetGoal.srv").write_text("# goal\nfloat64 x\nfloat64 y\nstring frame_name_for_goal\n---\n"
                                             "bool success\nstring message_from_the_server\n")
    (pkg / "CMakeLists.txt").write_text("cmake_minimum_required(VERSION 3.8)\nproject(goal_if)\n")
    (pkg / "launch" / "both.launch.py").write_text("from launch import LaunchDescription\n")
    (pkg / "launch" / "both.launch.xml").write_text("<launch/>\n")
    (pkg / "package.xml").write_text("<package/>")
    rels = {p.as_posix() for p in source_files(tmp_path / "ws")}
    assert rels == {"src/goal_if/srv/SetGoal.srv", "src/goal_if/CMakeLists.txt",
                    "src/goal_if/launch/both.launch.py", "src/goal_if/launch/both.launch.xml"}
    other = tmp_path / "other"
    (other / "srv").mkdir(parents=True)
    (other / "srv" / "SetGoal.srv").write_text("float64   x   # x of the goal\n\nfloat64 y\nstring frame_name_for_goal"
                                               "\n---\nbool success\nstring message_from_the_server\n")
    m = code.compare_one(code.read_set("a", tmp_path / "ws" / "src" / "goal_if" / "srv", boiler),
                         code.read_set("b", other, boiler))
    assert m.score == 1.0
    assert snapshot(tmp_path / "ws", tmp_path / "out") == 4
    assert (tmp_path / "out" / "source" / "src" / "goal_if" / "srv" / "SetGoal.srv").exists()


def test_source_fingerprints_are_the_same_in_every_process(tmp_path) -> None:
    """copydetect's own k-gram hash is Python's hash(), reseeded per process: two runs of one
    class scored otherwise. Two processes with other PYTHONHASHSEEDs must keep the same
    fingerprints (this fails with copydetect's hash)."""
    import os
    import subprocess
    import sys

    script = ("import sys; from pathlib import Path; from grader.similarity import code; "
              "s = code.read_set('x', Path(sys.argv[1])); print(sorted(s.hashes)[:50], s.size)")
    target = str(LAB3 / "no_wrap" / "src" / "turtle_control")
    runs = [subprocess.run([sys.executable, "-c", script, target], capture_output=True, text=True, check=True,
                           cwd=REPO, env={**os.environ, "PYTHONHASHSEED": seed}).stdout for seed in ("1", "2")]
    assert runs[0] == runs[1] and runs[0].strip()
