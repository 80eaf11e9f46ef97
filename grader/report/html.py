"""Self-contained HTML reports: one page per submission and an index for a batch.

No external assets (inline CSS, inline SVG, PNGs as data URIs) so a report can be mailed,
archived or opened offline; semantic tables with captions and text status labels (never colour
alone) so it works with screen readers and in black-and-white print.
"""

from __future__ import annotations

import base64
import os
from html import escape
from pathlib import Path
from typing import Any, Mapping, Sequence

from grader.report.result import plain_file_name, atomic_write, check_submission_id, jsonable
from grader.report.svg import PLOT_KEYS, plots_for
from grader.rubric.score import PENDING, ItemResult, Notice, Result, SectionResult

STATUS_LABEL = {"pass": "✓ pass", "partial": "◐ partial", "fail": "✗ fail", "error": "! error",
                PENDING: "… pending"}
MAX_ROWS = 12
MAX_LIST = 8
MAX_PROBLEM_CHARS = 3000

CSS = """
:root{--ink:#1b1b1b;--muted:#555;--line:#c8c8c8;--pass:#0b6e2e;--partial:#8a5300;--fail:#a4161a;
--error:#5b3c88;--pending:#1f4e8c}
*{box-sizing:border-box}
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:var(--ink);
margin:0 auto;max-width:1100px;padding:1.2rem}
h1{font-size:1.5rem;margin:.2rem 0}h2{font-size:1.2rem;margin:1.6rem 0 .4rem;display:flex;
justify-content:space-between;gap:1rem;border-bottom:2px solid var(--ink)}
.sub{color:var(--muted);margin:0}
.scores{display:flex;flex-wrap:wrap;gap:.8rem;margin:1rem 0}
.score{border:1px solid var(--line);border-radius:6px;padding:.5rem .9rem;min-width:11rem}
.score b{display:block;font-size:1.6rem}
.score span{color:var(--muted);font-size:.85rem}
table{border-collapse:collapse;width:100%;margin:.3rem 0}
table.items{table-layout:fixed}col.c-item{width:32%}col.c-status{width:7.5rem}col.c-points{width:6.5rem}
tr.group th{background:none;border-bottom:1px solid var(--ink);padding-top:.7rem}
table.items td{overflow-wrap:anywhere}tbody th{background:none}
th,td{border-bottom:1px solid var(--line);padding:.35rem .5rem;text-align:left;vertical-align:top}
th{background:#f2f2f2;font-weight:600}
caption{text-align:left;font-weight:600;padding:.3rem 0}
td.num,th.num{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}
code,.id{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.85em;color:var(--muted)}
.badge{display:inline-block;border:1.5px solid currentColor;border-radius:999px;padding:0 .55rem;
font-size:.8rem;font-weight:700;white-space:nowrap}
.s-pass{color:var(--pass)}.s-partial{color:var(--partial)}.s-fail{color:var(--fail)}
.s-error{color:var(--error)}.s-pending{color:var(--pending)}
.hint{color:var(--muted);font-size:.9em;margin:.25rem 0 0}
tr.detail td{border-bottom:1px solid var(--line);padding-top:0;background:#fafafa}
table.ev{width:auto;font-size:.82rem;margin:.2rem 0}
table.ev th,table.ev td{padding:.1rem .45rem;border-bottom:1px solid #e3e3e3}
table.ev th{background:#eee}
.plots{display:flex;flex-wrap:wrap;gap:1rem;margin:.4rem 0}
.plots svg{max-width:100%;height:auto;border:1px solid #e3e3e3;background:#fff}
.box{border:2px solid;border-radius:6px;padding:.5rem .9rem;margin:1rem 0}
.box.flags{border-color:var(--fail)}.box.warn{border-color:var(--partial)}
.box h2{border:0;margin:.2rem 0}
figure{margin:.5rem 0}figure img{max-width:360px;border:1px solid var(--line);image-rendering:pixelated}
.sr{position:absolute;width:1px;height:1px;overflow:hidden;clip-path:inset(50%);white-space:nowrap}
ul.problems pre{white-space:pre-wrap;margin:.2rem 0;font-size:.8rem;max-height:16rem;overflow:auto}
footer{color:var(--muted);font-size:.8rem;margin-top:2rem;border-top:1px solid var(--line)}
a{color:#0b4f9c}
@media (max-width:700px){table.items colgroup,table.items thead{display:none}
table.items,table.items>tbody,table.items>tbody>tr,table.items>tbody>tr>td{display:block;width:auto}
table.items>tbody>tr.item{border-top:1px solid var(--line);padding-top:.3rem}
table.items>tbody>tr.item>td{border:0;padding:.1rem .5rem}table.items td.num{text-align:left}
table.items>tbody>tr.group>th{display:block}.scores .score{flex:1 1 100%}}
@media print{body{font-size:10.5pt;max-width:none;padding:0}
th{background:none}tr,figure,.plots svg{break-inside:avoid}h2{break-after:avoid}
tr.detail td{background:none}a{color:inherit;text-decoration:none}}
"""


def _num(value: float | None) -> str:
    if value is None:
        return "—"
    return f"{value:g}"


def _badge(status: str) -> str:
    label = STATUS_LABEL.get(status, status)
    return f'<span class="badge s-{escape(status)}">{escape(label)}</span>'


# -- evidence -------------------------------------------------------------------------------

def _scalar(value: Any) -> str:
    if isinstance(value, float):
        return escape(f"{value:.4g}")
    if isinstance(value, str) and len(value) > 300:
        return escape(value[:300]) + "…"
    return escape("null" if value is None else str(value))


def _value_html(value: Any, depth: int = 0) -> str:
    """A compact rendering: scalars, short lists, tables for lists of records, nested maps."""
    if isinstance(value, Mapping):
        return _mapping_table(value, depth + 1) if depth < 2 else escape(str(value)[:200])
    if isinstance(value, list):
        if value and all(isinstance(v, Mapping) for v in value):
            return _records_table(value)
        if all(not isinstance(v, Mapping) for v in value) and depth < 3:
            shown = ", ".join(_value_html(v, depth + 1) for v in value[:MAX_LIST])
            more = f", … ({len(value)} values)" if len(value) > MAX_LIST else ""
            return f"[{shown}{more}]"
        return escape(f"list of {len(value)}")
    return _scalar(value)


def _mapping_table(mapping: Mapping[str, Any], depth: int = 0) -> str:
    rows = [f'<tr><th scope="row">{escape(str(k))}</th><td>{_value_html(v, depth)}</td></tr>'
            for k, v in mapping.items()]
    return f'<table class="ev">{"".join(rows)}</table>'


def _records_table(records: list[Mapping[str, Any]]) -> str:
    columns: list[str] = []
    for rec in records[:MAX_ROWS]:
        for key in rec:
            if key not in columns:
                columns.append(str(key))
    head = "".join(f'<th scope="col">{escape(c)}</th>' for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{_value_html(rec.get(c), 2)}</td>" for c in columns)
                   + "</tr>" for rec in records[:MAX_ROWS])
    more = (f'<tr><td colspan="{len(columns)}">… {len(records) - MAX_ROWS} more rows</td></tr>'
            if len(records) > MAX_ROWS else "")
    return f'<table class="ev"><thead><tr>{head}</tr></thead><tbody>{body}{more}</tbody></table>'


def _evidence_html(item: ItemResult) -> str:
    evidence = jsonable(item.evidence) or {}
    parts = []
    plain = {k: v for k, v in evidence.items() if k not in PLOT_KEYS}
    if plain:
        parts.append(_mapping_table(plain))
    plots = plots_for(evidence, item.title)
    if plots:
        parts.append(f'<div class="plots">{"".join(plots)}</div>')
    return "".join(parts)


# -- page -------------------------------------------------------------------------------------

def _item_rows(item: ItemResult) -> str:
    hint = (f'<p class="hint">Hint: {escape(item.hint)}</p>'
            if item.hint and item.status not in ("pass", PENDING) else "")
    if item.value is not None:
        hint = f'<p class="hint">Measured: {_value_html(jsonable(item.value))}</p>' + hint
    points = ("—" if item.points is None else _num(item.points))
    if item.kind in ("advisory", "integrity"):
        points_cell = f'<td class="num">{escape(item.kind)}</td>'
    else:
        points_cell = f'<td class="num">{points} / {_num(item.max_points)}</td>'
    row = (f'<tr class="item" id="item-{escape(item.id)}" data-item="{escape(item.id)}" '
           f'data-status="{escape(item.status)}">'
           f'<td>{escape(item.title)}<br><span class="id">{escape(item.id)}</span></td>'
           f'<td>{_badge(item.status)}</td>{points_cell}'
           f'<td>{escape(item.feedback)}{hint}</td></tr>')
    detail = _evidence_html(item)
    if detail:
        row += f'<tr class="detail"><td colspan="4">{detail}</td></tr>'
    return row


def _items_table(caption: str, rows: str) -> str:
    return (f'<table class="items"><caption class="sr">{escape(caption)}</caption>'
            f'<colgroup><col class="c-item"><col class="c-status"><col class="c-points"><col></colgroup>'
            f'<thead><tr><th scope="col">Item</th><th scope="col">Status</th>'
            f'<th scope="col" class="num">Points</th><th scope="col">Feedback</th></tr></thead>'
            f'<tbody>{rows}</tbody></table>')


def _notices(title: str, css: str, notices: tuple[Notice, ...]) -> str:
    if not notices:
        return ""
    items = "".join(f'<li>{_badge(n.status)} <b>{escape(n.title)}</b> '
                    f'<span class="id">{escape(n.item_id)}</span>: {escape(n.feedback)}</li>'
                    for n in notices)
    return f'<section class="box {css}" aria-label="{escape(title)}"><h2>{escape(title)}</h2><ul>{items}</ul></section>'


def _canvas_html(canvas_png: str | os.PathLike[str] | Mapping[str, str | os.PathLike[str]] | None) -> str:
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
    return f'<section aria-label="Simulator canvas"><h2>Simulator canvas</h2><div class="plots">{"".join(figures)}</div></section>'


def _section_note(section: SectionResult) -> str:
    if section.pending_max:
        return "graded by the instructor"
    if not section.max_points:
        return "checks without points"
    return ""


def _problems_html(problems: Sequence[str]) -> str:
    """Build failures and scenario errors: they explain 'error' rows, so they come first."""
    if not problems:
        return ""
    items = "".join(f"<li><pre>{escape(p[:MAX_PROBLEM_CHARS])}"
                    f"{'…' if len(p) > MAX_PROBLEM_CHARS else ''}</pre></li>" for p in problems)
    return (f'<section class="box flags" aria-label="Problems while grading"><h2>Problems while '
            f'grading</h2><ul class="problems">{items}</ul></section>')


def render_html(result: Result, submission: str, *, versions: Mapping[str, str] | None = None,
                canvas_png: str | os.PathLike[str] | Mapping[str, str | os.PathLike[str]] | None = None,
                problems: Sequence[str] = ()) -> str:
    """The report page of one submission. Pass ``result.for_student()`` for the self-check
    view; ``canvas_png`` is a PNG path (or {label: path}) embedded as a data URI; ``problems``
    are build/scenario errors shown at the top (they explain items with status error)."""
    title = f"{result.title} — {submission}"
    manual = ("pending" if result.manual_score is None else _num(result.manual_score))
    total = _num(result.total)
    scores = [
        ("Automatic", f"{_num(result.auto_score)} / {_num(result.auto_max)}", "graded from the recordings"),
    ]
    if result.manual_max:
        scores.append(("Manual", f"{manual} / {_num(result.manual_max)}", "report and questions, by the instructor"))
    scores.append(("Total", f"{total} / {_num(result.max_score)}",
                   "final" if result.complete else f"{_num(result.pending_max)} points still to grade"))
    score_html = "".join(f'<div class="score" data-score="{escape(k.lower())}">{escape(k)}'
                         f'<b>{escape(v)}</b><span>{escape(note)}</span></div>' for k, v, note in scores)
    hidden = ""
    if result.student_view and result.hidden_items:
        worth = (f"worth {_num(result.hidden_points)} point(s) " if result.hidden_points
                 else "without points ")
        hidden = (f'<p class="sub" id="hidden-note">Self-check view: {result.hidden_items} further '
                  f'check(s) {worth}are graded later and not shown here.</p>')
    by_id = {i.id: i for i in result.items}

    def anchor(index: int, sec: SectionResult) -> str:
        manual_only = all(by_id[i].kind == "manual" for i in sec.item_ids)
        return f"item-{sec.item_ids[0]}" if manual_only else f"sec-{index}"

    summary_rows = "".join(
        f'<tr><th scope="row"><a href="#{escape(anchor(i, s))}">{escape(s.title)}</a></th>'
        f'<td class="num">{_num(s.points) if s.max_points and not s.pending_max else "—"}</td>'
        f'<td class="num">{_num(s.max_points) if s.max_points else "—"}</td>'
        f'<td>{_section_note(s)}</td></tr>'
        for i, s in enumerate(result.sections))
    summary = (f'<table class="summary"><caption>Points by section</caption><thead><tr>'
               f'<th scope="col">Section</th><th scope="col" class="num">Points</th>'
               f'<th scope="col" class="num">Max</th><th scope="col">Note</th></tr></thead>'
               f'<tbody>{summary_rows}</tbody></table>')
    sections, manual_rows = [], []
    for index, sec in enumerate(result.sections):
        items = [by_id[i] for i in sec.item_ids]
        if all(i.kind == "manual" for i in items):
            # questions and report: one compact table at the end instead of a section each
            if len(items) > 1:
                manual_rows.append(f'<tr class="group"><th colspan="4" scope="rowgroup">'
                                   f'{escape(sec.title)}</th></tr>')
            manual_rows.extend(_item_rows(i) for i in items)
            continue
        rows = "".join(_item_rows(i) for i in items)
        points = (f"{_num(sec.points)} / {_num(sec.max_points)}" if sec.max_points else "flags only")
        sections.append(
            f'<section id="sec-{index}" aria-labelledby="sec-{index}-h">'
            f'<h2 id="sec-{index}-h"><span>{escape(sec.title)}</span><span>{points}</span></h2>'
            f'{_items_table(f"Items of {sec.title}", rows)}</section>')
    if manual_rows:
        sections.append(
            f'<section aria-labelledby="manual-h"><h2 id="manual-h"><span>Graded by the instructor'
            f'</span><span>{manual} / {_num(result.manual_max)}</span></h2>'
            f'{_items_table("Manually graded items", "".join(manual_rows))}</section>')
    version_text = ", ".join(f"{k} {v}" for k, v in (versions or {}).items())
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title><style>{CSS}</style></head>
<body><main>
<header><p class="sub">{escape(result.title)}</p>
<h1>{"Self-check" if result.student_view else "Grade report"}: <span id="submission">{escape(submission)}</span></h1>
<div class="scores" id="scores">{score_html}</div>{hidden}</header>
{_problems_html(problems)}
{_notices("Integrity flags (for review)", "flags", result.integrity_flags)}
{_notices("Warnings (no points)", "warn", result.warnings)}
{summary}
{"".join(sections)}
{_canvas_html(canvas_png)}
</main>
<footer><p>Generated by grader{(" — " + escape(version_text)) if version_text else ""}.
Lab <code>{escape(result.lab)}</code>.</p></footer>
</body></html>
"""


def write_html(out_dir: str | os.PathLike[str], submission: str, result: Result, *,
               filename: str = "report.html", **kwargs: Any) -> Path:
    """Write ``out_dir/<submission>/report.html`` (kwargs as for render_html; ``filename``
    e.g. ``student.html`` for the self-check view next to the full report)."""
    check_submission_id(submission)
    path = Path(out_dir) / submission / plain_file_name(filename)
    atomic_write(path, render_html(result, submission, **kwargs))
    return path


def render_index(results: Mapping[str, Result], *, title: str | None = None) -> str:
    """Batch overview linking each ``<id>/report.html`` with its scores and flags."""
    first = next(iter(results.values()), None)
    heading = title or (f"{first.title}: batch report" if first else "Batch report")
    rows = []
    for submission in sorted(results):
        check_submission_id(submission)
        r = results[submission]
        flags = ", ".join(n.item_id for n in r.integrity_flags)
        errors = sum(1 for i in r.items if i.status == "error")
        rows.append(
            f'<tr data-submission="{escape(submission)}"><th scope="row">'
            f'<a href="{escape(submission)}/report.html">{escape(submission)}</a></th>'
            f'<td class="num">{_num(r.auto_score)} / {_num(r.auto_max)}</td>'
            f'<td class="num">{_num(r.total)} / {_num(r.max_score)}</td>'
            f'<td class="num">{errors}</td><td>{escape(flags) or "—"}</td></tr>')
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(heading)}</title><style>{CSS}</style></head>
<body><main><h1>{escape(heading)}</h1>
<p class="sub">{len(results)} submission(s). Totals stay empty (—) until manual items are graded.</p>
<table><caption>Submissions</caption><thead><tr><th scope="col">Submission</th>
<th scope="col" class="num">Automatic</th><th scope="col" class="num">Total</th>
<th scope="col" class="num">Errors</th><th scope="col">Integrity flags</th></tr></thead>
<tbody>{"".join(rows)}</tbody></table></main></body></html>
"""


def write_index(out_dir: str | os.PathLike[str], results: Mapping[str, Result], **kwargs: Any) -> Path:
    path = Path(out_dir) / "index.html"
    atomic_write(path, render_index(results, **kwargs))
    return path
