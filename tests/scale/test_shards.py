"""`grader grade --shard K/N` splits a class deterministically, and `grader merge` puts the shard
outputs back together into exactly what one unsharded run gives (shard outputs built offline
from the committed Lab 3 bags, as ``grader regrade`` would), refusing duplicates and rubric
mismatches with one clear error each."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.grading.shards import in_shard, write_shard_note
from grader.rubric.load import load_rubric
from grader.testing.batch import LAB3_BAGS, recorded_batch

REPO = Path(__file__).resolve().parents[2]
LAB3_RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"
IDS = sorted(p.name for p in LAB3_BAGS.iterdir() if p.is_dir())


def test_every_id_is_in_exactly_one_shard_whatever_else_is_in_the_class() -> None:
    ids = [f"student_{i:03d}" for i in range(400)] + IDS + ["a", "Z.zip", "x-y_z"]
    for n in range(1, 8):
        owners = {sid: [k for k in range(1, n + 1) if in_shard(sid, k, n)] for sid in ids}
        assert all(len(ks) == 1 for ks in owners.values()), n
        sizes = [sum(1 for ks in owners.values() if ks == [k]) for k in range(1, n + 1)]
        assert min(sizes) > 0.6 * len(ids) / n, (n, sizes)          # a fair split, not one shard
        # stable: a student's shard depends on the id alone, not on who else is in the folder
        assert {sid: ks[0] for sid, ks in owners.items() if sid in IDS} == \
               {sid: [k for k in range(1, n + 1) if in_shard(sid, k, n)][0] for sid in IDS}


@pytest.mark.parametrize("bad", ["0/2", "3/2", "2", "a/b", "1/0"])
def test_a_shard_outside_1_to_n_is_a_clear_error(bad: str, tmp_path: Path, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        grader_main(["grade", str(tmp_path), "--rubric", str(LAB3_RUBRIC), "-o", str(tmp_path / "o"),
                     "--shard", bad])
    assert exc.value.code == 2
    assert "expected K/N with 1 <= K <= N" in capsys.readouterr().err


@pytest.fixture(scope="module")
def rubric():
    return load_rubric(LAB3_RUBRIC)


@pytest.fixture(scope="module")
def shards(tmp_path_factory, rubric) -> dict[str, Path]:
    """Two shard outputs and one unsharded output of the same recorded submissions."""
    root = tmp_path_factory.mktemp("shards")
    out = {}
    for k in (1, 2):
        out[f"part{k}"] = root / f"part{k}"
        recorded_batch(LAB3_BAGS, out[f"part{k}"], rubric, only=[s for s in IDS if in_shard(s, k, 2)])
        write_shard_note(out[f"part{k}"], rubric, k, 2)
    out["whole"] = root / "whole"
    recorded_batch(LAB3_BAGS, out["whole"], rubric)
    return out


def _rows(out: Path) -> dict[str, dict]:
    with open(out / "grades.csv", newline="") as f:
        return {row["submission"]: row for row in csv.DictReader(f)}


@pytest.mark.slow
def test_merged_shards_equal_one_unsharded_batch(shards: dict[str, Path], tmp_path: Path, capsys) -> None:
    parts = [shards["part1"], shards["part2"]]
    assert all(any(p.iterdir()) for p in parts), "both shards hold submissions"
    merged = tmp_path / "merged"
    assert grader_main(["merge", *map(str, parts), "-o", str(merged), "--rubric", str(LAB3_RUBRIC)]) == 0
    assert f"merged {len(IDS)} submissions from 2 outputs" in capsys.readouterr().out
    assert _rows(merged) == _rows(shards["whole"])
    for sid in IDS:
        got = json.loads((merged / sid / "result.json").read_text())
        want = json.loads((shards["whole"] / sid / "result.json").read_text())
        assert got["items"] == want["items"], sid
        assert (merged / sid / "report.html").is_file() and (merged / sid / "scenarios").is_dir()
    index = (merged / "index.html").read_text()
    assert all(f"{sid}/report.html" in index for sid in IDS)
    # the merged class is compared as one (grader similarity runs after the merge)
    assert (merged / "similarity" / "similarity.json").is_file() and 'id="similar-h"' in index


@pytest.mark.slow
def test_a_submission_in_two_shards_is_refused_and_nothing_is_merged(shards, tmp_path: Path, capsys) -> None:
    again = tmp_path / "part1-again"
    shutil.copytree(shards["part1"], again, symlinks=True)
    sid = next(p.name for p in again.iterdir() if (p / "result.json").is_file())
    merged = tmp_path / "merged"
    assert grader_main(["merge", str(shards["part1"]), str(again), str(shards["part2"]), "-o", str(merged),
                        "--rubric", str(LAB3_RUBRIC)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("grader: error: cannot merge:")
    assert f"{sid} is in both {shards['part1']} and {again}" in err
    assert not merged.exists()


@pytest.mark.slow
def test_shards_graded_with_another_rubric_are_refused(shards, tmp_path: Path, capsys) -> None:
    # the same lab, one threshold changed: the shards were not graded with this rubric (its
    # relative paths still resolve: the fixtures beside it are the repository's)
    (tmp_path / "rubrics").mkdir()
    (tmp_path / "fixtures").symlink_to(REPO / "fixtures")
    edited = tmp_path / "rubrics" / "enee467_lab3.yaml"
    text = LAB3_RUBRIC.read_text()
    edited.write_text(text.replace("r2_min: 0.9", "r2_min: 0.8"))
    assert text != edited.read_text()
    merged = tmp_path / "merged"
    rc = grader_main(["merge", str(shards["part1"]), str(shards["part2"]), "-o", str(merged),
                      "--rubric", str(edited)])
    err = capsys.readouterr().err
    assert rc == 2 and "was graded with another rubric" in err, err
    assert not merged.exists()
    # another lab altogether
    rc = grader_main(["merge", str(shards["part1"]), "-o", str(merged),
                      "--rubric", str(REPO / "rubrics" / "first_nodes.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and "graded for lab 'enee467-lab3', not 'first-nodes'" in err, err
    assert not merged.exists()
