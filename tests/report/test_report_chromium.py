"""The reports in a real headless Chromium (DevTools protocol over a pipe, grader.testing.browser).

Every report of a batch built offline from the committed real bags (regrade-style, no ROS) and the
class view load without console errors or broken images, show every figure with its accessible
name and description, fit a 1280 px window, and print on A4 and Letter without cut tables. A full-page
screenshot of each page and a PDF of two pages are kept as artefacts (the folder is printed; set
GRADER_ARTIFACTS to choose it).
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from grader.report import write_html
from grader.rubric.load import load_rubric
from grader.testing.batch import LAB3_BAGS, recorded_batch
from grader.testing.browser import A4, LETTER, Browser, find_chromium

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="chromium is not installed "
                                "(apt-get install chromium); the HTML report is only checked statically")

#: printable width in CSS px of A4 and Letter with the pages' 12 mm margins (96 px per inch)
PRINT_WIDTHS = {"A4": round((A4[0] - 2 * 12 / 25.4) * 96), "Letter": round((LETTER[0] - 2 * 12 / 25.4) * 96)}

PROBE = """(() => {
  const de = document.documentElement, vw = de.clientWidth;
  const wide = [...document.querySelectorAll('main *')].filter(e => e.getBoundingClientRect().right > vw + 1)
    .map(e => e.tagName + '.' + e.className);
  const imgs = [...document.images].filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt);
  const figs = [...document.querySelectorAll('svg.plot')].map(s => {
    const ids = (s.getAttribute('aria-labelledby') || '').split(' ');
    const t = ids.map(id => document.getElementById(id)).map(e => e ? e.textContent : '');
    const r = s.getBoundingClientRect();
    return {title: t[0] || '', desc: t[1] || '', w: r.width, h: r.height};
  });
  const tables = [...document.querySelectorAll('table')].filter(t => t.getBoundingClientRect().right > vw + 1).length;
  return {scrollWidth: de.scrollWidth, clientWidth: vw, wide: wide.slice(0, 5), broken: imgs,
          figures: figs, cutTables: tables};
})()"""
OPEN_ALL = "document.querySelectorAll('details').forEach(d => d.open = true); true"
#: evidence key names a reader must never see by default (issue 10), and epoch times
INTERNAL = ("n_len_not_2", "number_position", "lag_window_s", "gaps_excluded", "goal_source", "t_sent",
            "scenario_start", "tol_reached", "rel_error")


@pytest.fixture(scope="module")
def artifacts(tmp_path_factory) -> Path:
    folder = Path(os.environ.get("GRADER_ARTIFACTS") or tmp_path_factory.mktemp("report-artifacts"))
    folder.mkdir(parents=True, exist_ok=True)
    print(f"\nreport screenshots and PDFs: {folder}")
    return folder


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("chromium-batch")
    recorded_batch(LAB3_BAGS, out, load_rubric(REPO / "rubrics" / "enee467_lab3.yaml"))
    return out


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


def _pages(batch: Path) -> list[Path]:
    return [batch / "index.html", *sorted(batch.glob("*/report.html"))]


def _name(page: Path, batch: Path) -> str:
    return "index" if page.parent == batch else page.parent.name


@pytest.mark.slow         # ~10 s to regrade the batch, ~1 s per page in the browser
def test_every_page_of_a_batch_in_chromium_at_1280(batch, browser, artifacts):
    pages = _pages(batch)
    assert len(pages) == 1 + len([p for p in LAB3_BAGS.iterdir() if p.is_dir()])
    problems = {}
    for path in pages:
        name = _name(path, batch)
        source = path.read_text()
        page = browser.open(path.as_uri(), width=1280)
        try:
            closed_text = page.eval("document.body.innerText")
            page.eval(OPEN_ALL)
            probe = page.eval(PROBE)
            page.screenshot(artifacts / f"{name}.png")
            issues = []
            if page.errors:
                issues.append(f"console: {page.errors}")
            if probe["broken"]:
                issues.append(f"broken images: {probe['broken']}")
            if probe["scrollWidth"] > probe["clientWidth"]:
                issues.append(f"wider than 1280 px: {probe['wide']}")
            figures, drawn = probe["figures"], source.count('class="plot"')
            if len(figures) != drawn:
                issues.append(f"{len(figures)} figures rendered of {drawn}")
            for fig in figures:
                if len(fig["title"]) < 20 or len(fig["desc"]) < 40 or fig["w"] < 300 or fig["h"] < 150:
                    issues.append(f"figure without title/description or too small: {fig}")
            shown = [k for k in INTERNAL if k in closed_text]
            if shown or re.search(r"\b17\d{8}\b", closed_text):
                issues.append(f"raw keys or epoch times visible: {shown}")
            if issues:
                problems[name] = issues
        finally:
            page.close()
    assert not problems, json.dumps(problems, indent=1)
    shots = sorted(artifacts.glob("*.png"))
    assert len(shots) >= len(pages) and all(s.stat().st_size > 20_000 for s in shots)


@pytest.mark.slow
def test_pages_print_on_a4_and_letter_without_cut_tables(batch, browser, artifacts):
    problems = {}
    for path in _pages(batch):
        name = _name(path, batch)
        page = browser.open(path.as_uri(), width=1280)
        try:
            page.media("print")
            for paper, width in PRINT_WIDTHS.items():
                page.resize(width, 1000)
                probe = page.eval(PROBE)
                if probe["cutTables"] or probe["scrollWidth"] > probe["clientWidth"]:
                    problems[f"{name} on {paper}"] = probe["wide"]
            if name in ("index", "no_wrap"):
                pdf = page.pdf(artifacts / f"{name}-A4.pdf", A4)
                assert len(re.findall(rb"/Type\s*/Page[^s]", pdf.read_bytes())) >= 2
                page.pdf(artifacts / f"{name}-Letter.pdf", LETTER)
            assert page.errors == []
        finally:
            page.close()
    assert not problems, problems


@pytest.mark.slow
def test_class_view_sorts_and_filters(batch, browser):
    page = browser.open((batch / "index.html").as_uri(), width=1280)
    try:
        order = "[...document.querySelectorAll('#subs tbody tr')].filter(r => !r.hidden).map(r => r.dataset.submission)"
        autos = "[...document.querySelectorAll('#subs tbody tr')].map(r => +r.dataset.auto)"
        page.eval("document.querySelector('th[data-key=auto] button').click(); true")
        scores = page.eval(autos)
        assert scores == sorted(scores, reverse=True) and scores[0] == 50
        page.eval("document.querySelector('th[data-key=auto] button').click(); true")
        assert page.eval(autos) == sorted(scores)
        page.eval("const s = document.getElementById('f-item'); s.value = 'ex1.boxmuller';"
                  "s.dispatchEvent(new Event('input')); true")
        shown = page.eval(order)
        assert "bm_log10" in shown and "reference" not in shown
        assert page.eval("document.getElementById('f-count').textContent") == f"{len(shown)} of 10 shown"
        assert page.errors == []
    finally:
        page.close()


@pytest.mark.parametrize("width", [1280, 420])
def test_conftest_report_fits_the_window(tmp_path, lab3_result, width):
    """A quick check outside the slow batch: one page, no console error, no sideways scroll."""
    path = write_html(tmp_path, "alice", lab3_result)
    with Browser() as browser:
        page = browser.open(path.as_uri(), width=width)
        page.eval(OPEN_ALL)
        probe = page.eval(PROBE)
        assert page.errors == [] and not probe["broken"]
        assert probe["scrollWidth"] <= probe["clientWidth"], probe["wide"]
        assert len(probe["figures"]) == 2 and all(f["title"] and f["desc"] for f in probe["figures"])
        assert page.eval("document.querySelector('[data-score=automatic] b').textContent") == "47 / 50"
