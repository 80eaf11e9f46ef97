"""The wheel's copy of the labs: rubrics staged with what they reference, found by `grader labs`
and `grader check --lab` when no checkout is around."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from grader import labs
from grader.cli import main as grader_main
from grader.errors import GraderError
from grader.rubric.load import load_rubric
from grader.rubric.stage import referenced_paths, stage_rubrics

REPO = Path(__file__).resolve().parents[2]
LAB3 = REPO / "rubrics" / "enee467_lab3.yaml"


@pytest.fixture
def packaged(tmp_path: Path, monkeypatch) -> Path:
    """What setup.py puts in the wheel, and a grader that sees only that (no checkout)."""
    data = tmp_path / "site" / "grader" / "_data"
    labs.stage_package_data(REPO, data)
    monkeypatch.setattr(labs, "PACKAGED_DATA", data)
    monkeypatch.setattr(labs, "in_checkout", lambda: False)
    return data


def test_lab3_references_its_support_package_and_bag() -> None:
    refs = referenced_paths(load_rubric(LAB3, analyzers=None))
    assert REPO / "fixtures/support/enee467_lab3/turtle_control_interfaces" in refs
    assert REPO / "fixtures/bags/random_numbers" in refs


def test_staged_rubrics_are_byte_identical_and_self_contained(packaged: Path) -> None:
    all_refs: list[Path] = []
    for rubric in sorted((REPO / "rubrics").glob("*.yaml")):
        copy = packaged / "rubrics" / rubric.name
        assert copy.read_bytes() == rubric.read_bytes()        # nothing rewritten
        refs = referenced_paths(load_rubric(copy))
        assert all(p.is_relative_to(packaged) and p.exists() for p in refs)
        all_refs += refs
    assert packaged / "fixtures/bags/random_numbers/metadata.yaml" in \
        [p for p in (packaged / "fixtures").rglob("*") if p.is_file()]
    assert (packaged / "requirements" / "ros-wheels.txt").read_text() == \
        (REPO / "requirements" / "ros-wheels.txt").read_text()
    # only what a rubric references: no submissions, no unreferenced bags
    stray = [p for p in (packaged / "fixtures").rglob("*")
             if p.is_file() and not any(p == r or p.is_relative_to(r) for r in all_refs)]
    assert not stray


def test_restaging_drops_what_is_gone(tmp_path: Path) -> None:
    dest = tmp_path / "_data"
    (dest / "rubrics").mkdir(parents=True)
    (dest / "rubrics" / "removed_lab.yaml").write_text("lab: gone\n")
    labs.stage_package_data(REPO, dest)
    assert not (dest / "rubrics" / "removed_lab.yaml").exists()


def test_installed_grader_lists_and_finds_packaged_labs(packaged: Path, capsys) -> None:
    assert labs.rubrics_dir() == packaged / "rubrics"
    assert labs.requirements_dir() == packaged / "requirements"
    assert labs.rubric_for_lab("enee467-lab3") == packaged / "rubrics" / "enee467_lab3.yaml"
    assert grader_main(["labs"]) == 0
    out = capsys.readouterr().out
    assert "enee467-lab3" in out and "100 points (50 automatic)" in out and "Lab 3" in out
    assert grader_main(["labs", "--json"]) == 0
    listed = {lab["id"]: lab for lab in json.loads(capsys.readouterr().out)}
    assert listed["enee467-lab3"]["points"] == 100 and listed["enee467-lab3"]["auto_points"] == 50
    assert grader_main(["check", ".", "--lab", "nope"]) == 2
    err = capsys.readouterr().err
    assert "known labs: " in err and all(lab in err for lab in ("enee467-lab3", "turtle-chase", "wall-pen"))


def test_checkout_uses_its_own_rubrics() -> None:
    assert labs.in_checkout()
    assert labs.rubric_for_lab("enee467-lab3") == LAB3


def _rubric_with_bag(folder: Path, bag: str) -> Path:
    text = LAB3.read_text().replace("../fixtures/bags/random_numbers", bag).replace(
        "../fixtures/support/enee467_lab3/turtle_control_interfaces",
        str(REPO / "fixtures/support/enee467_lab3/turtle_control_interfaces"))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "lab.yaml").write_text(text)
    return folder / "lab.yaml"


def test_absolute_reference_cannot_be_packaged(tmp_path: Path) -> None:
    rubric = _rubric_with_bag(tmp_path / "mine", str(REPO / "fixtures/bags/random_numbers"))
    with pytest.raises(GraderError, match="absolute path"):
        stage_rubrics([rubric], tmp_path / "out")


def test_reference_outside_the_root_cannot_be_packaged(tmp_path: Path) -> None:
    bag = tmp_path / "elsewhere" / "random_numbers"
    import shutil

    shutil.copytree(REPO / "fixtures/bags/random_numbers", bag)
    rubric = _rubric_with_bag(tmp_path / "course" / "rubrics", "../../elsewhere/random_numbers")
    with pytest.raises(GraderError, match="outside"):
        stage_rubrics([rubric], tmp_path / "out", root=tmp_path / "course")


def test_setup_in_a_checkout_points_to_make_bootstrap(capsys) -> None:
    assert grader_main(["setup"]) == 2
    assert "make bootstrap" in capsys.readouterr().err


def test_setup_refuses_what_it_must_not_touch(tmp_path: Path, monkeypatch) -> None:
    from grader import bootstrap

    monkeypatch.setattr(bootstrap, "ensure_tools", lambda: pytest.fail("got past the checks"))
    monkeypatch.setattr(sys, "prefix", sys.base_prefix)                 # grader in the system Python
    with pytest.raises(bootstrap.BootstrapError, match="not a virtual environment"):
        bootstrap.setup_here()
    venv = tmp_path / "venv"
    venv.mkdir()
    (venv / "pyvenv.cfg").write_text("include-system-site-packages = false\n")
    monkeypatch.setattr(sys, "prefix", str(venv))
    monkeypatch.setattr(bootstrap, "system_ros_available", lambda exclude=None: True)
    with pytest.raises(bootstrap.BootstrapError, match="--system-site-packages"):
        bootstrap.setup_here()
