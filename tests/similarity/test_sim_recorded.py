"""`grader similarity OUT` on a batch regraded from committed real bags (no build, no ROS): the
behaviour fingerprints written by the analysis, the pair list in the class view, pairs.csv, and
the side-by-side page in headless Chromium. The slow, real class is tests/similarity/test_sim_class.py.

The class: the Lab 3 reference, no_wrap and never_stops (their recorded controller scenario and
their source), and ``no_wrap_copy``: no_wrap's recording under another id with no_wrap's source
renamed and reformatted.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.rubric.load import load_rubric
from grader.similarity.files import snapshot
from grader.similarity.summary import OUT_DIR, SUMMARY
from grader.testing.batch import LAB3_BAGS, recorded_batch
from grader.testing.browser import Browser, find_chromium
from grader.testing.copies import disguise_tree
from grader.testing.similarity_class import LAB3, controller_rubric

MEMBERS = ("reference", "no_wrap", "never_stops")


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("sim-recorded")
    bags = root / "bags"
    for sid in MEMBERS:
        (bags / sid).mkdir(parents=True)
        os.symlink(LAB3_BAGS / sid / "ex2_controller", bags / sid / "ex2_controller")
    (bags / "no_wrap_copy").mkdir()
    os.symlink(LAB3_BAGS / "no_wrap" / "ex2_controller", bags / "no_wrap_copy" / "ex2_controller")
    rubric = controller_rubric(root / "rubric.yaml")
    out = root / "out"
    recorded_batch(bags, out, load_rubric(rubric))
    for sid in MEMBERS:
        snapshot(LAB3 / sid / "src", out / sid)
    disguise_tree(LAB3 / "no_wrap" / "src", root / "disguised", seed=5)
    snapshot(root / "disguised", out / "no_wrap_copy")
    return out, rubric


def test_analysis_writes_the_fingerprints(batch) -> None:
    out, _ = batch
    for sid in (*MEMBERS, "no_wrap_copy"):
        doc = json.loads((out / sid / "scenarios" / "ex2_controller" / "fingerprint.json").read_text())
        groups = {f["group"] for f in doc["features"]}
        assert {"path", "commands", "values", "rate", "names"} <= groups, (sid, groups)


def test_grader_similarity_lists_the_copy(batch, capsys) -> None:
    out, rubric = batch
    assert grader_main(["similarity", str(out), "--rubric", str(rubric), "--threshold", "0.4"]) == 0
    printed = capsys.readouterr().out
    assert "no_wrap" in printed and "no_wrap_copy" in printed
    summary = json.loads((out / OUT_DIR / SUMMARY).read_text())
    top = summary["pairs"][0]
    assert (top["a"], top["b"]) == ("no_wrap", "no_wrap_copy"), top
    # one recording under two ids: all they did alike, but for the steps where no_wrap drives as
    # the passing reference does (the lab forces that part)
    assert top["source"] > 0.9 and top["behaviour"] > 0.75 and top["listed"]
    assert top["behaviour"] > 10 * max(p["behaviour"] for p in summary["pairs"][1:])
    assert summary["settings"]["threshold"] == 0.4 and summary["class_size"] == 4
    rows = list(csv.DictReader((out / OUT_DIR / "pairs.csv").open()))
    assert {(r["a"], r["b"]) for r in rows} == {(p["a"], p["b"]) for p in summary["pairs"]}
    index = (out / "index.html").read_text()
    assert 'data-pair="no_wrap--no_wrap_copy"' in index and f'{OUT_DIR}/{top["page"]}' in index


def test_bad_options_are_refused_clearly(batch, capsys) -> None:
    out, rubric = batch
    assert grader_main(["similarity", str(out), "--rubric", str(rubric), "--known", str(out / "nowhere")]) != 0
    assert "--known" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        grader_main(["similarity", str(out), "--rubric", str(rubric), "--threshold", "70"])
    assert "between 0 and 1" in capsys.readouterr().err


@pytest.mark.skipif(find_chromium() is None, reason="chromium is not installed (apt-get install chromium)")
def test_side_by_side_page_in_chromium(batch, tmp_path) -> None:
    out, rubric = batch
    if not (out / OUT_DIR / SUMMARY).exists():
        grader_main(["similarity", str(out), "--rubric", str(rubric), "--threshold", "0.4"])
    summary = json.loads((out / OUT_DIR / SUMMARY).read_text())
    page_name = next(p["page"] for p in summary["pairs"] if (p["a"], p["b"]) == ("no_wrap", "no_wrap_copy"))
    shutil.copy(out / OUT_DIR / page_name, tmp_path / "shown.html")      # the file as written, kept
    with Browser() as browser:
        page = browser.open((out / OUT_DIR / page_name).as_uri(), width=1280)
        got = page.eval("""(() => ({
          marks: [...document.querySelectorAll('.pair-grid pre')].map(p => p.querySelectorAll('mark.m').length),
          figs: [...document.querySelectorAll('figure svg')].map(s => {
             const ids = (s.getAttribute('aria-labelledby') || '').split(' ').filter(Boolean);
             return {w: s.getBoundingClientRect().width, named: ids.length > 0 && ids.every(i => document.getElementById(i))};
          }),
          rows: document.querySelectorAll('table.shared tbody tr').length,
          back: document.querySelector('a[href="../index.html#similar-h"]') !== null,
          reports: [...document.querySelectorAll('a[href$="report.html"]')].map(a => a.getAttribute('href')),
          wide: document.documentElement.scrollWidth > document.documentElement.clientWidth + 1}))()""")
        assert page.errors == [], page.errors
        assert got["marks"] and all(n > 0 for n in got["marks"]), got["marks"]   # both sides highlighted
        assert got["figs"] and all(f["w"] > 200 and f["named"] for f in got["figs"]), got["figs"]
        assert got["rows"] >= 3 and got["back"] and not got["wide"]
        assert got["reports"] == ["../no_wrap/report.html", "../no_wrap_copy/report.html"]
        page.close()
        page = browser.open((out / "index.html").as_uri(), width=1280)
        assert page.errors == [], page.errors
        href = page.eval("document.querySelector('#similar tbody tr a[href^=\"similarity/\"]').getAttribute('href')")
        assert href == f"{OUT_DIR}/{page_name}"
        page.close()


def test_pages_are_made_for_the_most_similar_pairs_only(batch, tmp_path) -> None:
    """--max-pages bounds the pages (and class-view rows) of a class where many pairs reach the
    threshold; pairs.csv keeps them all."""
    out, rubric = batch
    copy = tmp_path / "out"
    shutil.copytree(out, copy, symlinks=True)
    assert grader_main(["similarity", str(copy), "--rubric", str(rubric), "--threshold", "0", "--max-pages", "1"]) == 0
    summary = json.loads((copy / OUT_DIR / SUMMARY).read_text())
    assert all(p["listed"] for p in summary["pairs"]) and len(summary["pairs"]) == 6
    assert [p["page"] is not None for p in summary["pairs"]] == [True] + [False] * 5
    assert len(list((copy / OUT_DIR).glob("pair-*.html"))) == 1
    index = (copy / "index.html").read_text()
    assert index.count("side by side</a>") == 1 and "5 more pair(s) are listed" in index


def test_fingerprints_are_made_from_the_bags_when_missing(batch, tmp_path) -> None:
    """A batch graded before fingerprints were kept: `grader similarity` reads the bags (on two
    processes) and scores every pair as it does from the stored fingerprints."""
    out, rubric = batch
    grader_main(["similarity", str(out), "--rubric", str(rubric)])
    want = json.loads((out / OUT_DIR / SUMMARY).read_text())
    copy = tmp_path / "out"
    shutil.copytree(out, copy, symlinks=True)
    gone = list(copy.glob("*/scenarios/*/fingerprint.json"))
    assert len(gone) == 4
    for fp in gone:
        fp.unlink()
    assert grader_main(["similarity", str(copy), "--rubric", str(rubric), "--jobs", "2"]) == 0
    got = json.loads((copy / OUT_DIR / SUMMARY).read_text())
    assert all(fp.exists() for fp in gone)
    assert [(p["a"], p["b"], p["source"], p["behaviour"]) for p in got["pairs"]] == \
           [(p["a"], p["b"], p["source"], p["behaviour"]) for p in want["pairs"]]
