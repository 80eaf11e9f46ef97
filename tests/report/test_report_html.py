"""The report page: self-contained, escaped, failing items first and in full, passing items one
line each, evidence in words (no internal key names, times since the scenario start), student
view without hidden items or thresholds."""

from __future__ import annotations

import base64
import re
from dataclasses import dataclass, field
from html.parser import HTMLParser
from typing import Any, Mapping

import pytest

from grader.grading.outputs import effective_params
from grader.report import render_html, write_html
from grader.report.html import _to_fix
from grader.rubric import score
from grader.rubric.result import ItemResult

PNG_1x1 = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==")


class _Collector(HTMLParser):
    """Well-formedness + what the tests look at: item lines, cards, external references, and the
    text a reader sees without opening anything (outside collapsed details, svg and pre)."""

    VOID = {"meta", "br", "col", "img", "input", "link", "hr", "source"}

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[tuple[str, dict]] = []
        self.errors: list[str] = []
        self.items: dict[str, str] = {}
        self.cards: list[str] = []
        self.external: list[str] = []
        self.ids: list[str] = []
        self.visible: list[str] = []

    def _hidden(self) -> bool:
        """Inside an svg, a pre, or a details element other than in its summary (closed)."""
        for k, (tag, _attrs) in enumerate(self.stack):
            if tag in ("svg", "pre", "style", "script"):
                return True
            if tag == "details" and not (k + 1 < len(self.stack) and self.stack[k + 1][0] == "summary"):
                return True
        return False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.append(attrs["id"])
        if "data-item" in attrs and tag == "li":
            self.items[attrs["data-item"]] = attrs["data-status"]
        if tag == "article" and "card" in (attrs.get("class") or ""):
            self.cards.append(attrs["id"].removeprefix("item-"))
        for key in ("src", "href", "xlink:href"):
            value = attrs.get(key) or ""
            if re.match(r"^(https?:)?//", value):
                self.external.append(value)
        if tag not in self.VOID:
            self.stack.append((tag, attrs))

    def handle_startendtag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.append(attrs["id"])

    def handle_endtag(self, tag):
        if tag in self.VOID:
            return
        if not self.stack or self.stack[-1][0] != tag:
            self.errors.append(f"unexpected </{tag}> with open {[t for t, _ in self.stack[-3:]]}")
            return
        self.stack.pop()

    def handle_data(self, data):
        if data.strip() and not self._hidden():
            self.visible.append(data.strip())


@pytest.fixture(scope="module")
def page(lab3, lab3_result) -> str:
    """The instructor report of the conftest result (rendered once: figures cost ~0.1 s each)."""
    return render_html(lab3_result, "alice", versions={"grader": "0.1.0"}, params=effective_params(lab3))


def parse(html: str) -> _Collector:
    parser = _Collector()
    parser.feed(html)
    parser.close()
    return parser


def test_report_is_well_formed_and_self_contained(lab3, page):
    html = page
    doc = parse(html)
    assert doc.errors == [] and doc.stack == []
    assert doc.external == [] and "<link" not in html and "<script" not in html.replace("&lt;script", "")
    assert set(doc.items) == set(lab3.item_ids)                 # every item exactly once, in its section
    assert doc.items["ex1.pub_rate"] == "partial" and doc.items["report"] == "pending"
    assert ">47 / 50<" in html and "— / 100" in html and "grader 0.1.0" in html
    assert len(doc.ids) == len(set(doc.ids)), "ids must be unique in the page"


def test_untrusted_text_is_escaped(page):
    html = page
    assert "<script>alert(1)</script>" not in html
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html


def test_failing_items_come_first_in_full_biggest_loss_first(lab3_result, page):
    html = page
    doc = parse(html)
    # auto items by points lost (pub_rate 1.5, turn_direction 1.5), then advisory warnings
    assert doc.cards == ["ex1.pub_rate", "ex2.turn_direction", "ex2.goal_publisher_robust", "ex3.timeout"]
    assert [i.id for i in _to_fix(lab3_result)] == doc.cards
    card = html[html.index('id="item-ex1.pub_rate"'):]
    card = card[:card.index("</article>")]
    # one sentence measured vs expected, then the feedback, then the hint
    sentence = re.search(r'<p class="measured">([^<]*)</p>', card).group(1)
    assert sentence == "Publish rate: 0.8 Hz — expected 1 Hz ± 10%."
    assert card.index('class="measured"') < card.index('class="feedback"') < card.index('class="hint"')
    # in the section list the failing item is one line pointing at its card
    assert 'id="line-ex1.pub_rate"' in html and 'href="#item-ex1.pub_rate"' in html


def test_passing_items_are_one_expandable_line(page):
    html = page
    line = html[html.index('<li data-item="ex2.goals_reached"'):]
    line = line[:line.index("</li>")]
    assert line.count("<details>") == 1 and "<summary>" in line
    summary = line[line.index("<summary>"):line.index("</summary>")]
    assert "svg" not in summary and "✓ pass" in summary
    body = line[line.index("</summary>"):]
    assert '<svg xmlns="http://www.w3.org/2000/svg"' in body and "Measurements" in body


def test_evidence_in_words_with_units_and_times_since_start(page):
    html = page
    line = html[html.index('<li data-item="ex2.goals_reached"'):]
    line = line[:line.index("</li>")]
    tables = line[:line.index("Raw evidence")]
    # labels and units from the analyzer, not key names; t_sent as seconds after the start
    assert "goal sent at" in tables and "s after the start" in tables and "distance at the end" in tables
    assert "t_sent" not in tables and "final_error" not in tables and "goal_source" not in tables
    assert re.search(r"<td>1\.50</td>", tables) and "1795262901" not in tables
    # the raw evidence is kept, collapsed
    raw = line[line.index("Raw evidence"):]
    assert "t_sent" in raw and "1795262901.75" in raw


def test_no_internal_key_is_visible_by_default(page):
    doc = parse(page)
    visible = " ".join(doc.visible)
    for key in ("t_sent", "goal_source", "tol_reached", "scenario_start", "periods_s", "final_error"):
        assert key not in visible


@dataclass(frozen=True)
class ItemWithParams(ItemResult):
    """What the grader's result will carry per item (params as run, names the rubric hides)."""

    params: Mapping[str, Any] = field(default_factory=dict)
    hidden_params: tuple[str, ...] = ()


def _with_params(result, item_id: str, params: dict, hidden: tuple[str, ...]):
    from dataclasses import asdict, replace

    items = tuple(ItemWithParams(**{**{f: getattr(i, f) for f in asdict(i)}, "params": params,
                                    "hidden_params": hidden}) if i.id == item_id else i for i in result.items)
    return replace(result, items=items)


def test_thresholds_from_params_and_hidden_ones_never_reach_students(lab3_result):
    params = {"tol_reached": 0.1, "tol_final": 0.15, "settle_s": 1.0}
    result = _with_params(lab3_result, "ex2.goals_reached", params, ("tol_reached",))
    staff = render_html(result, "alice")
    assert "goal tolerance" in staff and "(hidden from students)" in staff
    student_result = result.for_student()
    item = student_result.item("ex2.goals_reached")
    assert "tol_reached" not in item.params and "tol_reached" not in item.evidence
    student = render_html(student_result, "alice")
    line = student[student.index('data-item="ex2.goals_reached"'):]
    line = line[:line.index("</li>")]
    assert "goal tolerance" not in line and "tol_reached" not in line and "hidden from students" not in line
    assert "tolerance at the end" in line                      # visible thresholds stay
    assert "goal tolerance (0.1 m)" not in line                 # nor in the figure's legend


def test_expected_part_needs_visible_thresholds(lab3_result, make_finding, lab3):
    result = score(lab3, {"ex1.pub_rate": make_finding(0.8, 0.5, "partial", "slow", {"rate_hz": 0.8})})
    hidden = _with_params(result, "ex1.pub_rate", {"expected_hz": 1.0, "rel_tol": 0.1}, ("rel_tol",))
    staff = render_html(hidden, "a")
    assert "Publish rate: 0.8 Hz — expected 1 Hz ± 10%." in staff
    student = render_html(hidden.for_student(), "a")
    assert "Publish rate: 0.8 Hz." in student and "± 10%" not in student


def test_student_view_page(lab3_result):
    html = render_html(lab3_result.for_student(), "alice")
    doc = parse(html)
    assert "integrity.no_teleport" not in doc.items and "Integrity flags" not in html
    assert "integrity." not in html
    assert "2 further check(s) without points" in html and "Self-check" in html


def test_instructor_view_shows_integrity_flags(page):
    html = page
    assert "Integrity flags (for review)" in html and 'href="#item-integrity.no_teleport"' in html


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
    {"goals": "x", "trajectory": [{"x": [1, 2], "y": [1, 2], "goal": "here"}], "wall_points": [[1]]},
    {"goals": [{"goal": 1, "t_sent": "soon", "reached_at": [1]}], "scenario_start": "x"},
])
def test_malformed_evidence_never_breaks_the_page(lab3, make_finding, evidence):
    result = score(lab3, {"ex2.goals_reached": make_finding(evidence=evidence),
                          "ex1.normality": make_finding(evidence=evidence)})
    html = render_html(result, "bob")
    assert parse(html).errors == [] and "could not be drawn" not in html


def test_files(tmp_path, lab3_result):
    page = write_html(tmp_path, "alice", lab3_result)
    assert page == tmp_path / "alice" / "report.html" and page.read_text().startswith("<!DOCTYPE html>")
    student = write_html(tmp_path, "alice", lab3_result.for_student(), filename="student.html")
    assert student == page.with_name("student.html") and "Self-check" in student.read_text()
    with pytest.raises(ValueError):
        write_html(tmp_path, "alice", lab3_result, filename="../x.html")
