"""A class graded for real (`grader grade`: builds, simulator, bags), then compared: copies rank at
the top by source and by behaviour, a rewritten copy is found by its behaviour, honest correct
solutions that converge on one trajectory stay below the copies, a known public solution is named,
and the side-by-side page renders in headless Chromium.

ONE grading batch (grader.testing.similarity_class: nine Lab 3 controllers, the controller scenario
only) serves every assertion of this file.
"""

from __future__ import annotations

import csv
import json
import shutil
from itertools import combinations
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.similarity.summary import KNOWN_PREFIX, OUT_DIR, SUMMARY
from grader.testing.browser import Browser, find_chromium
from grader.testing.similarity_class import (COPIES, HONEST, KNOWN, TEST_STEP_TIMEOUT, build_class,
                                             controller_rubric)

pytestmark = [pytest.mark.slow, pytest.mark.heavy, pytest.mark.ros, pytest.mark.timeout(3600)]

KNOWN_ID = KNOWN_PREFIX + "public_turtle_lab3"


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> tuple[Path, Path, dict]:
    """`grader grade CLASS --known KNOWN` (what `make demo` runs, similarity included): OUT,
    the rubric and OUT/similarity/similarity.json."""
    root = tmp_path_factory.mktemp("sim-class")
    build_class(root / "class")
    rubric = controller_rubric(root / "rubric.yaml", step_timeout=TEST_STEP_TIMEOUT)
    out = root / "out"
    code = grader_main(["grade", str(root / "class"), "--rubric", str(rubric), "-o", str(out), "--jobs", "2",
                        "--known", str(KNOWN), "--cache-dir", str(root / "cache")])
    assert code == 0
    return out, rubric, json.loads((out / OUT_DIR / SUMMARY).read_text())


def _pairs(summary: dict) -> dict[frozenset, dict]:
    return {frozenset((p["a"], p["b"])): p for p in summary["pairs"]}


def _get(pairs: dict, a: str, b: str, key: str) -> float:
    p = pairs.get(frozenset((a, b)))
    return p[key] if p else 0.0


def test_the_class_graded_as_its_fixtures_say(graded) -> None:
    out, _, summary = graded
    assert summary["class_size"] == 9 and summary["pairs_compared"] == 36
    for sid in HONEST:
        doc = json.loads((out / sid / "result.json").read_text())
        assert doc["auto_score"] == doc["auto_max"], sid
    for sid in COPIES:     # no_wrap's bug, in every copy
        doc = json.loads((out / sid / "result.json").read_text())
        assert {i["id"]: i["status"] for i in doc["items"]}["ex2.turn_direction"] != "pass", sid
        assert (out / sid / "source").is_dir() and (out / sid / "scenarios" / "ex2_controller" / "fingerprint.json").exists()


def test_copies_rank_at_the_top_by_source(graded) -> None:
    _, _, summary = graded
    pairs = _pairs(summary)
    by_source = sorted(summary["pairs"], key=lambda p: -p["source"])
    top = {frozenset((p["a"], p["b"])) for p in by_source[:4]}
    source_copies = {frozenset(c) for c in combinations(("orig", "copy_a", "copy_b"), 2)}
    assert top == source_copies | {frozenset(("known_copy", KNOWN_ID))}, by_source[:6]
    for pair in top:
        assert pairs[pair]["source"] > 0.9 and pairs[pair]["listed"], pairs[pair]
    assert pairs[frozenset(("known_copy", KNOWN_ID))]["known"]
    # the rewrite keeps no source in common that counts: behaviour has to find it
    assert _get(pairs, "orig", "rewritten", "source") < 0.3
    # honest solutions share what the lab gives and what every solution writes, not fingerprints
    for a, b in combinations(sorted(HONEST), 2):
        assert _get(pairs, a, b, "source") < 0.5, (a, b)


def test_copies_rank_at_the_top_by_behaviour(graded) -> None:
    _, _, summary = graded
    pairs = _pairs(summary)
    copy_pairs = [frozenset(c) for c in combinations(sorted(COPIES), 2)]
    others = [k for k in pairs if k not in copy_pairs and not any(s.startswith(KNOWN_PREFIX) for s in k)]
    lowest_copy = min(_get(pairs, *sorted(c), "behaviour") for c in copy_pairs)
    highest_other = max((pairs[k]["behaviour"] for k in others), default=0.0)
    assert lowest_copy > highest_other, (lowest_copy, highest_other)
    # the rewritten copy (other structure, same constants and behaviour) is found by behaviour ...
    rewritten = pairs[frozenset(("orig", "rewritten"))]
    assert rewritten["listed"] and rewritten["behaviour"] >= summary["settings"]["behaviour_threshold"], rewritten
    # ... with the features that made it: a shared unusual trajectory, the same failing item
    groups = {f["group"] for f in rewritten["features"]}
    assert {"path", "failure"} <= groups, groups
    # the four are shown once, as one group
    assert sorted(summary["clusters"]) == [sorted(COPIES)]


def test_honest_alternatives_are_not_ranked_above_copies(graded) -> None:
    """honest_b and honest_c drive one trajectory (the lab's gains): what every passing
    submission does is forced by the lab, so it is no evidence."""
    _, _, summary = graded
    pairs = _pairs(summary)
    ranked = [frozenset((p["a"], p["b"])) for p in summary["pairs"]]         # the class view's order
    copy_ranks = [ranked.index(frozenset(c)) for c in combinations(sorted(COPIES), 2)]
    honest_ranks = [ranked.index(frozenset(c)) for c in combinations(sorted(HONEST), 2) if frozenset(c) in pairs]
    assert max(copy_ranks) < min(honest_ranks, default=len(ranked))
    for a, b in combinations(sorted(HONEST), 2):
        assert not (pairs.get(frozenset((a, b))) or {}).get("listed"), (a, b)
    same_path = pairs.get(frozenset(("honest_b", "honest_c")))
    if same_path:   # their paths are close, and marked as what passing submissions do
        assert all(f["forced"] > 0.5 for f in same_path["features"] if f["group"] == "path")


def test_outputs_and_offline_recompute(graded, tmp_path) -> None:
    """pairs.csv lists every pair; `grader similarity OUT` recomputes the same scores offline,
    from the bags when the stored fingerprints are gone."""
    out, rubric, summary = graded
    rows = list(csv.DictReader((out / OUT_DIR / "pairs.csv").open()))
    assert len(rows) == len(summary["pairs"]) and rows[0]["a"] and "behaviour" in rows[0]
    index = (out / "index.html").read_text()
    assert 'id="similar-h"' in index and "side by side" in index and "Group 1 (4 submissions)" in index
    copy = tmp_path / "out"
    shutil.copytree(out, copy, symlinks=True)
    for fp in copy.glob("*/scenarios/*/fingerprint.json"):
        fp.unlink()
    assert grader_main(["similarity", str(copy), "--rubric", str(rubric), "--known", str(KNOWN), "--jobs", "2"]) == 0
    again = json.loads((copy / OUT_DIR / SUMMARY).read_text())
    assert [(p["a"], p["b"], p["source"], p["behaviour"]) for p in again["pairs"]] == \
           [(p["a"], p["b"], p["source"], p["behaviour"]) for p in summary["pairs"]]


@pytest.mark.skipif(find_chromium() is None, reason="chromium is not installed (apt-get install chromium)")
def test_side_by_side_pages_render_in_chromium(graded) -> None:
    out, _, summary = graded
    pairs = _pairs(summary)
    pages = [pairs[frozenset(("orig", "copy_a"))]["page"], pairs[frozenset(("orig", "rewritten"))]["page"],
             pairs[frozenset(("known_copy", KNOWN_ID))]["page"]]
    with Browser() as browser:
        for name in pages:
            page = browser.open((out / OUT_DIR / name).as_uri(), width=1280)
            assert page.errors == [], (name, page.errors)
            got = page.eval("""(() => ({
              marks: document.querySelectorAll('mark.m').length,
              figs: [...document.querySelectorAll('figure svg')].map(s => s.getBoundingClientRect().width),
              text: document.querySelector('main').innerText,
              wide: document.documentElement.scrollWidth > document.documentElement.clientWidth + 1,
              links: [...document.querySelectorAll('a[href$="report.html"]')].length}))()""")
            assert not got["wide"], name
            assert "not proof of misconduct" in got["text"] and "cheat" not in got["text"].lower()
            if "rewritten" in name:
                assert got["figs"] and all(w > 200 for w in got["figs"]), got["figs"]   # both paths, one plot
                assert "trajectory" in got["text"]
            else:
                assert got["marks"] >= 2, name          # matched regions highlighted on both sides
            if "known" in name:
                assert "known solution public_turtle_lab3" in got["text"] and got["links"] == 1
            page.close()
        index = browser.open((out / "index.html").as_uri(), width=1280)
        assert index.errors == []
        assert index.eval("document.querySelectorAll('#similar tbody tr').length") >= 7
        index.close()
