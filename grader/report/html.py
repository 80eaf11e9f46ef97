"""The report page of one submission: what to fix first, then every item by section.

Self-contained (inline CSS, figures as inline SVG, canvas PNGs as data URIs) so a report can be
mailed, archived, printed or opened offline; its one script is the replay player's
(:mod:`grader.report.player`, data beside the page in ``scenarios/<id>/replay.js``), and the
page reads completely without it. Each failing item opens with one
sentence of what was measured against what was expected, then the feedback and hint, then its
figure; passing items are one line each that expands to their measurements and figure. Status is
text plus symbol, never colour alone. The class view lives in ``grader.report.index``.
"""

from __future__ import annotations

import base64
import os
from html import escape
from pathlib import Path
from typing import Any, Mapping, Sequence

from grader.report import readable
from grader.contracts.output_folder import REPORT_HTML
from grader.report.figures import FigureContext, figures_for
from grader.report.player import PLAYER_CSS, moment_link, player_html
from grader.report.result import atomic_write, check_submission_id, plain_file_name
from grader.report.style import CSS
from grader.rubric.result import PENDING, ItemResult, Notice, Result, SectionResult

STATUS_LABEL = {"pass": "✓ pass", "partial": "◐ partial", "fail": "✗ fail", "error": "! not checked",
                PENDING: "… pending"}
MAX_PROBLEM_CHARS = 3000


def _num(value: float | None) -> str:
    return "—" if value is None else f"{value:g}"


def _badge(status: str) -> str:
    return f'<span class="badge s-{escape(status)}">{escape(STATUS_LABEL.get(status, status))}</span>'


def _points(item: ItemResult) -> str:
    if item.kind in ("advisory", "integrity"):
        return "no points" if item.kind == "advisory" else "flag"
    return f"{_num(item.points)} / {_num(item.max_points)} pts"


class _Page:
    """Renders items once each; remembers figure errors (shown to instructors only)."""

    def __init__(self, result: Result, params: Mapping[str, Mapping[str, Any]], replays: Sequence[str] = (),
                 item_scenarios: Mapping[str, Sequence[str]] | None = None) -> None:
        self.result = result
        self.student = result.student_view
        self.params = params
        self.replays = replays                      # scenario folders with replay data
        self.item_scenarios = item_scenarios or {}
        self.figure_errors: list[str] = []

    def moment(self, item: ItemResult) -> str:
        return moment_link(item, self.item_scenarios.get(item.id, ()), self.replays)

    def _params(self, item: ItemResult) -> dict[str, Any]:
        return readable.item_params(item, self.params.get(item.id))

    def _visible_params(self, item: ItemResult) -> dict[str, Any]:
        p = self._params(item)
        if self.student:
            hidden = readable.hidden_names(item)
            p = {k: v for k, v in p.items() if k not in hidden}
        return p

    def _hidden(self, item: ItemResult) -> set[str]:
        return readable.hidden_names(item) if self.student else set()

    def figures(self, item: ItemResult) -> str:
        ev = readable.strip_hidden(dict(item.evidence or {}), self._hidden(item))
        ctx = FigureContext(item, ev, self._visible_params(item), self.student)
        figs, errors = figures_for(ctx, "f-" + "".join(c if c.isalnum() else "-" for c in item.id))
        self.figure_errors += errors
        note = ""
        if errors and not self.student:
            note = (f'<p class="sub">{len(errors)} figure(s) could not be drawn: '
                    f'{escape(errors[0].splitlines()[0])}</p>')
        if not figs:
            return note
        body = "".join(f'<figure class="plot-fig">{f.svg}<figcaption>{escape(f.alt)}</figcaption></figure>'
                       for f in figs)
        return f'<div class="figs">{body}</div>{note}'

    def details(self, item: ItemResult) -> str:
        """Measurements in words, thresholds, and the raw evidence (collapsed)."""
        thresholds = readable.threshold_rows(item, self._params(item), student_view=self.student)
        # a parameter the evidence echoes is shown once, with the thresholds
        ev = item.evidence or {}
        shown = ({k for k, v in self._params(item).items() if v is not None and ev.get(k) == v}
                 if thresholds else set())
        rows = readable.evidence_rows(item, hidden=self._hidden(item) | shown)
        parts = []
        tables = []
        if rows:
            tables.append('<table class="ev"><caption>Measurements</caption><tbody>'
                         + "".join(f'<tr><th scope="row">{escape(k)}</th><td>{v}</td></tr>' for k, v in rows)
                         + "</tbody></table>")
        if thresholds:
            tables.append('<table class="ev"><caption>Settings and thresholds</caption><tbody>'
                         + "".join(f'<tr><th scope="row">{escape(k)}</th><td>{v}</td></tr>'
                                   for k, v in thresholds) + "</tbody></table>")
        if tables:
            parts.append(f'<div class="tables">{"".join(tables)}</div>')
        if item.evidence:
            raw = readable.raw_json(item.evidence, self._hidden(item))
            parts.append(f'<details class="more"><summary>Raw evidence (as in result.json)</summary>'
                         f'<pre class="raw">{escape(raw)}</pre></details>')
        return "".join(parts)

    def sentence(self, item: ItemResult) -> str:
        if item.kind == "manual":
            return ""
        text = readable.measured_sentence(item, self._visible_params(item), student_view=self.student)
        runs = readable.spread_text(item.decided)       # a repeated scenario: how its runs came out
        return f'<p class="measured">{escape(text)}</p>' + (f'<p class="runs">{escape(runs)}</p>' if runs else "")

    def card(self, item: ItemResult) -> str:
        """A failing item in full: measured vs expected, feedback, hint, figure, details."""
        hint = f'<p class="hint"><b>Hint:</b> {escape(item.hint)}</p>' if item.hint else ""
        details = self.details(item)
        more = (f'<details class="more"><summary>All measurements and thresholds</summary>{details}</details>'
                if details else "")
        return (f'<article class="card s-{escape(item.status)}{" advisory" if item.kind == "advisory" else ""}" '
                f'id="item-{escape(item.id)}" aria-labelledby="h-{escape(item.id)}">'
                f'<h3 id="h-{escape(item.id)}">{_badge(item.status)} <span>{escape(item.title)}</span>'
                f'<span class="pts">{_points(item)}</span><span class="id">{escape(item.id)}</span></h3>'
                f'{self.sentence(item)}<p class="feedback">{escape(item.feedback)}</p>{hint}'
                f'{self.moment(item)}{self.figures(item)}{more}</article>')

    def line(self, item: ItemResult, in_card: bool) -> str:
        """One line per item in its section: a link to the card, or expandable details."""
        attrs = f'data-item="{escape(item.id)}" data-status="{escape(item.status)}"'
        head = (f'{_badge(item.status)} <span class="title">{escape(item.title)}</span> '
                f'<span class="pts">{_points(item)}</span> <span class="fb">{escape(item.feedback)}</span>')
        if in_card:
            return (f'<li {attrs} id="line-{escape(item.id)}"><div class="line">{_badge(item.status)} '
                    f'<span class="title">{escape(item.title)}</span> <span class="pts">{_points(item)}</span> '
                    f'<a class="fb" href="#item-{escape(item.id)}">explained under “What to fix first”</a>'
                    f'</div></li>')
        if item.kind == "manual":
            return f'<li {attrs} id="item-{escape(item.id)}"><div class="line">{head}</div></li>'
        body = self.sentence(item) + self.moment(item) + self.figures(item) + self.details(item)
        return (f'<li {attrs} id="item-{escape(item.id)}"><details><summary>{head}</summary>'
                f'<div class="body">{body}</div></details></li>')


def _to_fix(result: Result) -> list[ItemResult]:
    """Items that did not pass, in the order to work on them: failed or partly passed auto items
    by points lost, then those that could not be checked (their cause is usually a problem above
    them, e.g. a node that did not build), then advisory warnings (no points)."""
    auto = [i for i in result.items if i.kind == "auto" and i.status in ("fail", "partial", "error")]
    auto.sort(key=lambda i: (i.status == "error", -(i.max_points - (i.points or 0))))
    advisory = [i for i in result.items if i.kind == "advisory" and i.status != "pass"]
    return auto + advisory


def _notices(title: str, css: str, notices: tuple[Notice, ...]) -> str:
    if not notices:
        return ""
    items = "".join(f'<li>{_badge(n.status)} <b>{escape(n.title)}</b> <span class="id">{escape(n.item_id)}</span>'
                    f': {escape(n.feedback)} <a href="#item-{escape(n.item_id)}">details</a></li>' for n in notices)
    return f'<section class="box {css}" aria-label="{escape(title)}"><h2>{escape(title)}</h2><ul>{items}</ul></section>'


def _contract_html(result: Result) -> str:
    """Names the lab fixes that the submission spells differently: one line each, before the
    items, with the items each one blocks (their own cards say the same in one sentence)."""
    if not result.contract:
        return ""
    titles = {i.id: i.title for i in result.items}
    rows = []
    for m in result.contract:
        blocked = ", ".join(f'<a href="#item-{escape(b)}">{escape(titles.get(b, b))}</a>' for b in m.blocks)
        rows.append(f'<li data-role="{escape(m.role)}"><b>{escape(m.feedback)}</b>'
                    + (f" It blocks: {blocked}." if blocked else "") + "</li>")
    return (f'<section class="box flags" id="contract" aria-label="Names this lab fixes"><h2>Names this lab '
            f'fixes</h2><p class="sub">Use these names exactly: the items that depend on a name are checked '
            f'once it is right.</p><ul>{"".join(rows)}</ul></section>')


def _canvas_html(canvas_png: Any) -> str:
    if canvas_png is None:
        return ""
    shots = canvas_png.items() if isinstance(canvas_png, Mapping) else [("canvas", canvas_png)]
    figures = []
    for label, path in shots:
        try:
            data = Path(path).read_bytes()
        except OSError:
            continue
        if not data.startswith(b"\x89PNG"):
            continue
        uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
        figures.append(f'<figure><img src="{uri}" alt="Turtlesim canvas at the end of {escape(str(label))}">'
                       f'<figcaption>Canvas: {escape(str(label))}</figcaption></figure>')
    if not figures:
        return ""
    return (f'<section aria-labelledby="canvas-h"><h2 id="canvas-h">Simulator canvas</h2>'
            f'<div class="figs">{"".join(figures)}</div></section>')


def _problems_html(problems: Sequence[str]) -> str:
    """Build failures and scenario errors: they explain items not checked, so they come first."""
    if not problems:
        return ""
    items = "".join(f"<li><pre>{escape(p[:MAX_PROBLEM_CHARS])}"
                    f"{'…' if len(p) > MAX_PROBLEM_CHARS else ''}</pre></li>" for p in problems)
    return (f'<section class="box flags" aria-label="Problems while grading"><h2>Problems while '
            f'grading</h2><ul class="problems">{items}</ul></section>')


def _notes_html(notes: Sequence[str]) -> str:
    """How the grading ran, when it matters for reading it (e.g. scenarios on simulated time)."""
    if not notes:
        return ""
    items = "".join(f"<li>{escape(n)}</li>" for n in notes)
    return f'<section class="box" aria-label="How the scenarios ran" id="run-notes"><ul>{items}</ul></section>'


def _section_points(sec: SectionResult) -> str:
    if sec.pending_max:
        return "graded by the instructor"
    return f"{_num(sec.points)} / {_num(sec.max_points)}" if sec.max_points else "checks without points"


def _scores(result: Result) -> str:
    manual = "pending" if result.manual_score is None else _num(result.manual_score)
    scores = [("Automatic", f"{_num(result.auto_score)} / {_num(result.auto_max)}", "graded from the recordings")]
    if result.manual_max:
        scores.append(("Manual", f"{manual} / {_num(result.manual_max)}", "report and questions, by the instructor"))
    if result.late is not None:
        scores.append(("Late", f"−{_num(result.late_penalty)}",
                       "set by the instructor" if result.late.override_points is not None else "late policy"))
    scores.append(("Total", f"{_num(result.total)} / {_num(result.max_score)}",
                   "final" if result.complete else f"{_num(result.pending_max)} points still to grade"))
    return "".join(f'<div class="score" data-score="{escape(k.lower())}">{escape(k)}'
                   f'<b>{escape(v)}</b><span>{escape(note)}</span></div>' for k, v, note in scores)


def _late_html(result: Result) -> str:
    """The late policy's verdict in words: when it came in, who says so, what it cost."""
    late = result.late
    if late is None:
        return ""
    text = late.note
    if late.override_points is not None:
        text += (f" The instructor set the late penalty to {_num(late.override_points)} point(s)"
                 + (f" ({late.override_source})." if late.override_source else "."))
    return f'<p class="sub" id="late">{escape(text)}</p>'


def _who_html(intake: Mapping[str, Any] | None) -> str:
    """Whose submission, as the roster and the LMS say (result.json ``intake``)."""
    if not intake or intake.get("source") not in ("canvas", "gradescope", "classroom") and not intake.get("student"):
        return ""
    student = intake.get("student") or {}
    lms = {"canvas": "Canvas user id", "gradescope": "Gradescope submission", "classroom": "repository"}
    parts = [str(student.get("name") or student.get("email") or "not on the roster")]
    if intake.get("source") in lms and intake.get("lms_id"):
        parts.append(f"{lms[intake['source']]} {intake['lms_id']}")
    parts.append(", ".join(str(n) for n in intake.get("original") or [])[:300])
    return f'<p class="sub" id="who">{escape(" · ".join(p for p in parts if p))}</p>'


def render_html(result: Result, submission: str, *, versions: Mapping[str, str] | None = None,
                canvas_png: Any = None, problems: Sequence[str] = (),
                params: Mapping[str, Mapping[str, Any]] | None = None, notes: Sequence[str] = (),
                intake: Mapping[str, Any] | None = None, replays: Sequence[str] = (),
                item_scenarios: Mapping[str, Sequence[str]] | None = None) -> str:
    """The report page of one submission. Pass ``result.for_student()`` for the self-check
    view; ``canvas_png`` is a PNG path (or {label: path}) embedded as a data URI; ``problems``
    are build/scenario errors shown at the top; ``params`` (item id -> effective analyzer
    parameters) is used for items whose result does not carry its own ``params``; ``notes``:
    lines on how the scenarios ran (``--time-scale``); ``intake``: result.json's ``intake``
    (the student and the LMS's ids, under the title); ``replays``: the scenario folders with
    replay data (``scenarios/<id>/replay.js`` beside the page), ``item_scenarios`` the scenarios
    each item is judged on (the replay player, :mod:`grader.report.player`)."""
    page = _Page(result, params or {}, replays, item_scenarios)
    fix = _to_fix(result)
    carded = {i.id for i in fix}
    lost = sum(i.max_points - (i.points or 0) for i in fix if i.kind == "auto")
    if fix:
        first = fix[0]
        lead = (f'<p class="sub">{len(fix)} item(s) to look at, {_num(round(lost, 2))} point(s) to gain; '
                f'start with <a href="#item-{escape(first.id)}">{escape(first.title)}</a>.</p>')
        fix_html = (f'<section aria-labelledby="fix-h"><h2 id="fix-h"><span>What to fix first</span></h2>{lead}'
                    + "".join(page.card(i) for i in fix) + "</section>")
    else:
        fix_html = '<p class="sub" id="all-pass">Every automatically graded item passes.</p>'
    sections = _sections_html(result, page, carded)
    summary = _summary_html(result)
    hidden = ""
    if result.student_view and result.hidden_items:
        worth = f"worth {_num(result.hidden_points)} point(s) " if result.hidden_points else "without points "
        hidden = (f'<p class="sub" id="hidden-note">Self-check view: {result.hidden_items} further '
                  f'check(s) {worth}are graded later and not shown here.</p>')
    flags = "" if result.student_view else _notices("Integrity flags (for review)", "flags", result.integrity_flags)
    version_text = ", ".join(f"{k} {v}" for k, v in (versions or {}).items())
    title = f"{result.title} — {submission}"
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title><style>{CSS}{PLAYER_CSS if replays else ""}</style></head>
<body><main>
<header><p class="sub">{escape(result.title)}</p>
<h1>{"Self-check" if result.student_view else "Grade report"}: <span id="submission">{escape(submission)}</span></h1>
{_who_html(intake)}
<div class="scores" id="scores">{_scores(result)}</div>{_late_html(result)}{hidden}</header>
{_problems_html(problems)}
{_contract_html(result)}
{_notes_html(notes)}
{flags}
{summary}
{fix_html}
{sections}
{_canvas_html(canvas_png)}
{player_html(replays, result.items, item_scenarios or {})}
</main>
<footer><p>Generated by grader{(" — " + escape(version_text)) if version_text else ""}.
Lab <code>{escape(result.lab)}</code>. Times are seconds since the scenario started; every measurement is in
result.json.</p></footer>
</body></html>
"""


def _sections_html(result: Result, page: "_Page", carded: set[str]) -> str:
    """A section per part of the rubric with its items' lines (a card's item links to it), and
    the sections graded by the instructor as one compact list at the end."""
    by_id = {i.id: i for i in result.items}
    sections, manual = [], []
    for index, sec in enumerate(result.sections):
        lines = "".join(page.line(by_id[i], i in carded) for i in sec.item_ids)
        if all(by_id[i].kind == "manual" for i in sec.item_ids):
            # report and questions: one compact list at the end instead of a section each
            manual.append(f'<li id="sec-{index}" class="group"><b>{escape(sec.title)}</b>'
                          f'<ul class="items">{lines}</ul></li>')
            continue
        sections.append(f'<section id="sec-{index}" aria-labelledby="sec-{index}-h">'
                        f'<h2 id="sec-{index}-h"><span>{escape(sec.title)}</span>'
                        f'<span>{_section_points(sec)}</span></h2><ul class="items">{lines}</ul></section>')
    if manual:
        points = "pending" if result.manual_score is None else _num(result.manual_score)
        sections.append(f'<section aria-labelledby="manual-h"><h2 id="manual-h"><span>Graded by the instructor'
                        f'</span><span>{points} / {_num(result.manual_max)}</span></h2>'
                        f'<ul class="manual">{"".join(manual)}</ul></section>')
    return "".join(sections)


def _summary_html(result: Result) -> str:
    """The table of points by section."""
    summary_rows = "".join(
        f'<tr><th scope="row"><a href="#sec-{i}">{escape(s.title)}</a></th>'
        f'<td class="num">{_num(s.points) if s.max_points and not s.pending_max else "—"}</td>'
        f'<td class="num">{_num(s.max_points) if s.max_points else "—"}</td>'
        f'<td>{"graded by the instructor" if s.pending_max else "" if s.max_points else "checks without points"}'
        f'</td></tr>' for i, s in enumerate(result.sections))
    return (f'<table class="summary"><caption>Points by section</caption><thead><tr>'
               f'<th scope="col">Section</th><th scope="col" class="num">Points</th>'
               f'<th scope="col" class="num">Max</th><th scope="col">Note</th></tr></thead>'
               f'<tbody>{summary_rows}</tbody></table>')


def write_html(out_dir: str | os.PathLike[str], submission: str, result: Result, *,
               filename: str = REPORT_HTML, **kwargs: Any) -> Path:
    """Write ``out_dir/<submission>/report.html`` (kwargs as for render_html; ``filename``
    e.g. ``student.html`` for the self-check view next to the full report)."""
    check_submission_id(submission)
    path = Path(out_dir) / submission / plain_file_name(filename)
    atomic_write(path, render_html(result, submission, **kwargs))
    return path
