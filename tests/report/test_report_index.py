"""The class view from real recorded bags: score distribution, what the class got wrong (most failed
first, with links to the students), the submissions table, and the diff after `grader regrade`
with a changed rubric."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from grader.cli import main as grader_main
from grader.report import render_index
from grader.rubric.load import load_rubric
from grader.testing.batch import LAB3_BAGS, recorded_batch

REPO = Path(__file__).resolve().parents[2]
RUBRIC = REPO / "rubrics" / "enee467_lab3.yaml"
SUBS = ["bm_log10", "no_wrap", "reference"]


@pytest.fixture(scope="module")
def batch(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("class-view")
    recorded_batch(LAB3_BAGS, out, load_rubric(RUBRIC), only=SUBS)
    return out


def _rows(html: str, table: str) -> list[str]:
    body = html[html.index(f'<table class="{table}"'):]
    body = body[:body.index("</table>")]
    return re.findall(r"<tr data-[a-z]+=\"([^\"]+)\"", body)


def test_distribution_and_items_most_failed_first(batch):
    html = (batch / "index.html").read_text()
    assert "Score distribution" in html and "Histogram of the automatic scores of 3 submissions" in html
    assert html.count('class="plot"') == 1 and 'role="img"' in html
    items = _rows(html, "items-share")
    table = html[html.index('<table class="items-share"'):]
    failed = [int(x) for x in re.findall(r'<td class="num">(\d+) %</td>', table[:table.index("</table>")])]
    assert len(failed) == len(items) and failed == sorted(failed, reverse=True) and failed[0] > failed[-1]
    row = html[html.index('<tr data-item="ex1.boxmuller"'):]
    row = row[:row.index("</tr>")]
    assert 'href="bm_log10/report.html#item-ex1.boxmuller">✗\u00a0bm_log10</a>' in row and "reference" not in row
    row = html[html.index('<tr data-item="ex2.control_law"'):]
    row = row[:row.index("</tr>")]
    assert "◐\u00a0no_wrap" in row and "partly 1" in row


def test_submissions_table_is_sortable_and_readable_without_script(batch):
    html = (batch / "index.html").read_text()
    assert _rows(html, "subs") == SUBS
    row = html[html.index('<tr data-submission="no_wrap"'):]
    row = row[:row.index("</tr>")]
    assert 'data-failed="' in row and "ex2.goals_reached" in row and 'data-build="ok"' in row
    assert 'id="controls" hidden' in html and "<script>" in html          # controls only with JS
    assert re.search(r'<th scope="col" data-key="auto" data-type="num"', html)


def test_regrade_with_a_changed_rubric_shows_who_changed(batch, tmp_path):
    before = {s: json.loads((batch / s / "result.json").read_text()) for s in SUBS}
    assert all("previous" not in d for d in before.values())
    text = RUBRIC.read_text().replace("../fixtures/", f"{REPO}/fixtures/")
    changed = text.replace("params: {tol_reached: 0.1, settle_s: 1.0, stop_weight: 0.5}",
                           "params: {tol_reached: 8.0, settle_s: 1.0, stop_weight: 0.5}")
    assert changed != text
    rubric = tmp_path / "lab3_loose.yaml"
    rubric.write_text(changed)
    assert grader_main(["regrade", str(batch), "--rubric", str(rubric)]) == 0
    after = {s: json.loads((batch / s / "result.json").read_text()) for s in SUBS}
    for s in SUBS:
        assert after[s]["previous"]["auto_score"] == before[s]["auto_score"]
        assert after[s]["previous"]["items"]["ex2.goals_reached"]["points"] == \
            {i["id"]: i for i in before[s]["items"]}["ex2.goals_reached"]["points"]
    html = (batch / "index.html").read_text()
    assert "Regrade: who changed" in html
    regrade = _rows(html, "regrade")
    assert "no_wrap" in regrade and "reference" not in regrade          # only those that changed
    row = html[html.index('<table class="regrade"'):]
    row = row[row.index('data-submission="no_wrap"'):row.index("</tr>", row.index('data-submission="no_wrap"'))]
    delta = after["no_wrap"]["auto_score"] - before["no_wrap"]["auto_score"]
    was = {i["id"]: i for i in before["no_wrap"]["items"]}["ex2.goals_reached"]["points"]
    assert delta > 0 and f"+{delta:g}" in row and f"ex2.goals_reached: {was:g} →" in row


def test_empty_batch():
    assert "No graded submissions yet." in render_index({})
