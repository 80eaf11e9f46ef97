"""HTML report: self-contained, escaped, plots from evidence, index linking submissions."""

from __future__ import annotations

import base64
import re
from html.parser import HTMLParser

import pytest

from grader.report import render_html, render_index, write_html, write_index
from grader.report.svg import histogram_svg, nice_ticks, trajectory_svg
from grader.rubric import score

PNG_1x1 = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==")


class _Collector(HTMLParser):
    """Well-formedness + what the tests look at: tags, item rows, external references."""

    VOID = {"meta", "br", "col", "img", "line", "circle", "rect", "polyline", "path", "input", "link"}

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.rows: dict[str, str] = {}
        self.external: list[str] = []
        self.tags: list[str] = []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append(tag)
        if tag == "tr" and "data-item" in attrs:
            self.rows[attrs["data-item"]] = attrs["data-status"]
        for key in ("src", "href"):
            value = attrs.get(key) or ""
            if re.match(r"^(https?:)?//", value):
                self.external.append(value)
        if tag not in self.VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        self.tags.append(tag)

    def handle_endtag(self, tag):
        if tag in self.VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"unexpected </{tag}> with open {self.stack[-3:]}")
            return
        self.stack.pop()


def parse(html: str) -> _Collector:
    parser = _Collector()
    parser.feed(html)
    parser.close()
    return parser


def test_report_is_well_formed_and_self_contained(lab3, lab3_result):
    html = render_html(lab3_result, "alice", versions={"grader": "0.1.0"})
    doc = parse(html)
    assert doc.errors == [] and doc.stack == []
    assert doc.external == []
    assert "<link" not in html and "<script" not in html.replace("&lt;script", "")
    assert set(doc.rows) == set(lab3.item_ids)
    assert doc.rows["ex1.pub_rate"] == "partial" and doc.rows["report"] == "pending"
    assert ">47 / 50<" in html and "— / 100" in html and "grader 0.1.0" in html
    assert '<html lang="en">' in html


def test_untrusted_text_is_escaped(lab3_result):
    html = render_html(lab3_result, "alice")
    assert "<script>alert(1)</script>" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html


def test_plots_come_from_evidence(lab3_result):
    html = render_html(lab3_result, "alice")
    assert html.count('<svg xmlns="http://www.w3.org/2000/svg" class="plot" role="img"') == 2
    assert "<title>Trajectory: turtle_control_node drives the turtle to each goal</title>" in html
    assert "normal(0, 1) expected" in html
    # plot data is not repeated as a table
    assert ">trajectory<" not in html and ">histogram<" not in html


def test_student_view_page(lab3_result):
    html = render_html(lab3_result.for_student(), "alice")
    doc = parse(html)
    assert "integrity.no_teleport" not in doc.rows and "Integrity flags" not in html
    assert "2 further check(s) without points" in html and "Self-check" in html


def test_canvas_png_is_embedded(tmp_path, lab3_result):
    png = tmp_path / "canvas.png"
    png.write_bytes(PNG_1x1)
    html = render_html(lab3_result, "alice", canvas_png={"ex2_controller": png, "missing": tmp_path / "nope.png"})
    assert html.count("data:image/png;base64,") == 1
    assert 'alt="Turtlesim canvas at the end of ex2_controller"' in html


@pytest.mark.parametrize("evidence", [
    {"trajectory": {"x": [1, 2], "y": [1]}}, {"trajectory": {"x": "abc", "y": None}},
    {"trajectory": [{"x": [], "y": []}, 3]}, {"histogram": {"bins": [0, 1], "counts": [1, 2, 3]}},
    {"histogram": {"bins": [2, 1, 0], "counts": [1, 1]}}, {"histogram": {"counts": [-1], "bins": [0, 1]}},
    {"histogram": "x"}, {"trajectory": {"x": [float("nan")], "y": [1.0]}},
])
def test_malformed_plot_evidence_never_breaks_the_page(lab3, make_finding, evidence):
    result = score(lab3, {"ex2.goals_reached": make_finding(evidence=evidence)})
    html = render_html(result, "bob")
    assert parse(html).errors == [] and "<svg" not in html


def test_histogram_accepts_centres_and_draws_reference():
    svg = histogram_svg({"bins": [-1, 0, 1], "counts": [2, 5, 2], "reference": {"normal": {"mean": 0, "std": 1}}})
    assert svg and svg.count("<rect") == 1 + 3 and "<polyline" in svg
    assert histogram_svg({"bins": [-1, 0, 1], "counts": [2, 5, 2]}).count("<polyline") == 0


def test_trajectory_legend_and_goals():
    svg = trajectory_svg([{"x": [5, 6], "y": [5, 6], "goal": [6, 6], "label": "a<b"},
                          {"x": [6, 2], "y": [6, 7], "goals": [[2, 7]]}])
    assert svg.count("<polyline") == 2 and svg.count("<path d=") == 2
    assert "a&lt;b" in svg and "a<b" not in svg


def test_nice_ticks():
    assert nice_ticks(0, 11.09) == [0, 2, 4, 6, 8, 10]
    assert nice_ticks(-4, 4) == [-4, -2, 0, 2, 4]
    assert nice_ticks(0, 213) == [0, 50, 100, 150, 200]


def test_files_and_index(tmp_path, lab3, lab3_result):
    page = write_html(tmp_path, "alice", lab3_result)
    assert page == tmp_path / "alice" / "report.html" and page.read_text().startswith("<!DOCTYPE html>")
    student = write_html(tmp_path, "alice", lab3_result.for_student(), filename="student.html")
    assert student == page.with_name("student.html") and "Self-check" in student.read_text()
    with pytest.raises(ValueError):
        write_html(tmp_path, "alice", lab3_result, filename="../x.html")
    index = write_index(tmp_path, {"bob": score(lab3, {}), "alice": lab3_result})
    html = index.read_text()
    doc = parse(html)
    assert doc.errors == []
    assert html.index('href="alice/report.html"') < html.index('href="bob/report.html"')
    assert "integrity.no_teleport" in html
    assert render_index({}).count("<tr") == 1
