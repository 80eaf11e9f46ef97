"""grader.api: the functions behind grade/check/regrade, typed and usable from Python.

Offline (recorded Lab 3 bags, no ROS): the API's regrade is what `grader regrade` prints and
writes, read_frames/analyze give an item's finding as grading does, and every option of the
three commands is a keyword of its function (the CLI only parses and prints)."""

from __future__ import annotations

import argparse
import inspect
import json
import typing
from pathlib import Path

import pandas as pd
import pytest

from grader import api
from grader.cli import build_parser
from grader.errors import GraderError
from grader.grading.graded import GradedSubmission
from grader.grading.pipeline import regrade_submission
from grader.rubric.load import RubricError
from grader.rubric.schema import Rubric
from grader.testing.batch import LAB3_BAGS, layout

REPO = Path(__file__).resolve().parents[2]
LAB3 = REPO / "rubrics" / "enee467_lab3.yaml"
REFERENCE = LAB3_BAGS / "reference"


def test_load_rubric_gives_a_rubric_or_located_problems(tmp_path: Path) -> None:
    rubric = api.load_rubric(LAB3)
    assert isinstance(rubric, Rubric) and rubric.lab == "enee467-lab3"
    bad = tmp_path / "bad.yaml"
    bad.write_text(LAB3.read_text().replace("lab: enee467-lab3", "lab: Enee 467"))
    with pytest.raises(RubricError, match=r"bad.yaml:\d+: lab: "):
        api.load_rubric(bad, check_files=False)


def test_regrade_is_what_the_command_prints_and_writes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from grader.cli import main

    layout(LAB3_BAGS, tmp_path / "api", only=["reference", "pub_10hz"])
    layout(LAB3_BAGS, tmp_path / "cli", only=["reference", "pub_10hz"])
    seen: list[str] = []
    graded = api.regrade(tmp_path / "api", str(LAB3), on_done=lambda g: seen.append(g.id))
    assert [g.id for g in graded] == seen == ["pub_10hz", "reference"]
    assert all(isinstance(g, GradedSubmission) for g in graded)
    assert (tmp_path / "api" / "grades.csv").is_file() and (tmp_path / "api" / "index.html").is_file()
    assert main(["regrade", str(tmp_path / "cli"), "--rubric", str(LAB3)]) == 0
    # the committed bags were recorded by another grader version: each line says so, and a note follows
    printed = [line.split("  (rests on", 1)[0] for line in capsys.readouterr().out.splitlines()
               if not line.startswith("note: ")]
    assert printed == [f"{g.id}: {g.result.auto_score:g}/{g.result.auto_max:g}" for g in graded]
    for g in graded:
        api_items = json.loads((tmp_path / "api" / g.id / "result.json").read_text())["items"]
        cli_items = json.loads((tmp_path / "cli" / g.id / "result.json").read_text())["items"]
        assert [(i["id"], i["points"], i["status"]) for i in api_items] == \
               [(i["id"], i["points"], i["status"]) for i in cli_items]
    # one submission folder: just that one, from a loaded Rubric as well as a path
    one, = api.regrade(tmp_path / "api" / "reference", api.load_rubric(LAB3))
    assert one.result.auto_score == next(g for g in graded if g.id == "reference").result.auto_score
    with pytest.raises(GraderError, match="holds no graded submissions"):
        api.regrade(tmp_path, LAB3)


def test_read_frames_and_analyze_give_the_graded_finding(tmp_path: Path) -> None:
    scenario = REFERENCE / "ex1_publisher"
    frames = api.read_frames(scenario)
    assert "__meta__" in frames and isinstance(frames["/random_numbers"], pd.DataFrame)
    assert frames["/random_numbers"].index.name == "t"
    only = api.read_frames(scenario / "bag", topics=["/random_numbers"])
    assert list(only) == ["/random_numbers"]
    assert len(only["/random_numbers"]) == len(frames["/random_numbers"])
    finding = api.analyze(LAB3, "ex1.pub_rate", scenario)
    assert finding.status == "pass" and finding.params["expected_hz"] == 1.0
    assert api.analyze(LAB3, "ex1.pub_rate", frames).value == finding.value
    # the same as a regrade of the submission scores it
    layout(LAB3_BAGS, tmp_path, only=["reference"])
    graded = regrade_submission(tmp_path / "reference", api.load_rubric(LAB3))
    assert graded.result.item("ex1.pub_rate").value == finding.value
    with pytest.raises(GraderError, match="has no item 'ex9'"):
        api.analyze(LAB3, "ex9", frames)
    with pytest.raises(GraderError, match="graded by a person"):
        api.analyze(LAB3, "report", frames)
    with pytest.raises(GraderError, match="not found"):
        api.read_frames(tmp_path / "nope")


def test_user_errors_are_grader_errors(tmp_path: Path) -> None:
    with pytest.raises(GraderError, match="say which lab to check"):
        api.check(tmp_path)
    with pytest.raises(GraderError, match="--due replaces the due date .* has none"):
        api.grade(tmp_path, LAB3, tmp_path / "out", due="2025-02-14 23:59")
    with pytest.raises(GraderError, match="--timezone goes with --due"):
        api.grade(tmp_path, LAB3, tmp_path / "out", timezone="UTC")


# CLI option (argparse dest) -> the API keyword it becomes
RENAMED = {"no_reuse": "reuse", "map": "roster_map", "path": "path", "func": None, "command": None,
           "rubric": "rubric", "submissions": "submissions", "workspace": "workspace",
           # grader.similarity's options, gathered into one Settings
           **{o: "similarity" for o in ("known", "boilerplate", "threshold", "behaviour_threshold", "max_pages",
                                        "no_similarity")}}


def _subparser(name: str) -> argparse.ArgumentParser:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices[name]
    raise AssertionError("no subcommands")


@pytest.mark.parametrize("command,function", [("grade", api.grade), ("check", api.check), ("regrade", api.regrade)])
def test_every_option_of_the_command_is_a_keyword_of_its_function(command: str, function: typing.Any) -> None:
    dests = {a.dest for a in _subparser(command)._actions if a.dest != "help"}
    params = set(inspect.signature(function).parameters)
    missing = sorted(d for d in dests if RENAMED.get(d, d) is not None and RENAMED.get(d, d) not in params)
    assert not missing, f"grader {command} options without an api.{function.__name__} keyword: {missing}"


def test_the_api_is_typed_and_documented() -> None:
    from grader.analyze import Finding
    from grader.intake.batch import IntakeBatch

    from grader.api.similarity import Settings as SimilaritySettings

    names = {"pd": pd, "Finding": Finding, "GradedSubmission": GradedSubmission, "IntakeBatch": IntakeBatch,
             "Rubric": Rubric, "SimilaritySettings": SimilaritySettings}
    for name in api.__all__:
        obj = getattr(api, name)
        if inspect.isfunction(obj):
            assert obj.__doc__ and len(obj.__doc__) > 60, name
            hints = typing.get_type_hints(obj, localns=names)
            assert "return" in hints and set(inspect.signature(obj).parameters) <= set(hints), name
