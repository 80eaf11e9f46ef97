"""The class view ``OUT/index.html``: score distribution, what the class got wrong (per item,
most failed first, with links to the students who failed), items whose repeated runs disagreed
(``repeat:`` scenarios, graded by the median or the worst run), a sortable and filterable table of
submissions (build failures, crashes, flags, time taken) and, after ``grader regrade``, who
changed and by how much.

The page reads completely without JavaScript; the inline script only adds sorting and filters.
"""

from __future__ import annotations

import os
import statistics
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import Any, Mapping, Sequence

from grader.contracts.late import late_by_text
from grader.contracts.output_folder import OutputFolder
from grader.contracts.result_document import ResultDocument
from grader.report.result import atomic_write, check_submission_id
from grader.report.style import CSS, INDEX_JS
from grader.rubric.result import ItemResult, Result
from grader.similarity.page import class_section

NUMERIC = {"auto", "total", "time", "delta", "late"}      # right-aligned columns of the submissions table
CATEGORIES = (("pass", "passed"), ("partial", "partly"), ("fail", "failed"), ("error", "not checked"))


@dataclass(frozen=True)
class Submission:
    """One row of the class view: the Result plus what result.json says about the run."""

    id: str
    result: Result
    build_failed: tuple[str, ...] = ()
    crashes: tuple[str, ...] = ()
    time_s: float | None = None
    previous: Mapping[str, Any] | None = None

    @classmethod
    def from_doc(cls, sid: str, result: Result, doc: ResultDocument | None) -> "Submission":
        failed = tuple(doc.build.failed) if doc is not None and not doc.build_ok and doc.build else ()
        timings = doc.timings if doc is not None else {}
        spent = [float(v) for k, v in timings.items() if isinstance(v, (int, float))
                 and (k == "build_s" or k.endswith(":wall_s"))]
        prev = doc.previous.model_dump(mode="json") if doc is not None and doc.previous is not None else None
        return cls(sid, result, failed, crashes_of(result), round(sum(spent), 1) if spent else None, prev)

    @property
    def delta(self) -> float | None:
        """Change of the automatic score since the previous grading (None: not regraded)."""
        if self.previous is None or not isinstance(self.previous.get("auto_score"), (int, float)):
            return None
        return round(self.result.auto_score - float(self.previous["auto_score"]), 2)

    def changed_items(self) -> list[tuple[str, Any, Any]]:
        """(item id, previous points or status, points or status now) for items that changed."""
        before = (self.previous or {}).get("items") or {}
        out = []
        for item in self.result.items:
            old = before.get(item.id)
            if not isinstance(old, Mapping):
                continue
            if old.get("points") != item.points or old.get("status") != item.status:
                out.append((item.id, _cell(old.get("points"), old.get("status")), _cell(item.points, item.status)))
        return out


def crashes_of(result: Result) -> tuple[str, ...]:
    """Student nodes that crashed, as recorded in the items' evidence (by the pipeline)."""
    seen: dict[str, None] = {}
    for item in result.items:
        for text in (item.evidence or {}).get("crashed_nodes") or ():
            seen.setdefault(str(text), None)
    return tuple(seen)


def _cell(points: Any, status: Any) -> str:
    if isinstance(points, (int, float)):
        return f"{points:g}"
    return str(status or "—")


def _num(v: float | None) -> str:
    return "—" if v is None else f"{v:g}"


def _late_cell(result: Result) -> str:
    """−5 (2 days), 0 (on time), — (no late policy)."""
    if result.late is None:
        return "—"
    return f"−{result.late_penalty:g} ({escape(late_by_text(result.late))})"


def _failed_items(result: Result) -> list[ItemResult]:
    return [i for i in result.items if i.kind in ("auto", "advisory") and i.status in ("fail", "partial", "error")]


def _link(sid: str, item_id: str | None = None, text: str | None = None) -> str:
    anchor = f"#item-{escape(item_id)}" if item_id else ""
    return f'<a href="{escape(sid)}/report.html{anchor}">{escape(text or sid)}</a>'


def _distribution(subs: Sequence[Submission]) -> str:
    from grader.report.figures.classview import score_histogram  # noqa: PLC0415 - report.figures.classview loads matplotlib (311 ms CPU), only on this path

    scores = [s.result.auto_score for s in subs]
    top = max((s.result.auto_max for s in subs), default=0.0)
    fig = score_histogram(scores, top)
    if fig is None:
        return ""
    return (f'<section aria-labelledby="dist-h"><h2 id="dist-h">Score distribution</h2>'
            f'<figure class="plot-fig">{fig.svg}<figcaption>{escape(fig.alt)}</figcaption></figure></section>')


def _item_table(subs: Sequence[Submission]) -> str:
    """Per item: share passed / partly / failed / not checked, most failed first."""
    first = subs[0].result
    rows = []
    for item in first.items:
        if item.kind not in ("auto", "advisory"):
            continue
        got: dict[str, list[str]] = {k: [] for k, _ in CATEGORIES}
        for s in subs:
            try:
                status = s.result.item(item.id).status
            except KeyError:
                continue
            if status in got:
                got[status].append(s.id)
        n = sum(len(v) for v in got.values())
        if not n:
            continue
        share = {k: len(v) / n for k, v in got.items()}
        # most not passed first; among equals, real failures before analyses that could not run
        rows.append(((-(share["fail"] + share["error"]), -share["fail"], -share["partial"]), item, got, share))
    rows.sort(key=lambda r: r[0])
    body = []
    for _, item, got, share in rows:
        bar = "".join(f'<span class="b-{k}" style="width:{100 * share[k]:.1f}%" title="{words}: '
                      f'{len(got[k])}"></span>' for k, words in CATEGORIES if got[k])
        counts = " · ".join(f"{words} {len(got[k])}" for k, words in CATEGORIES if got[k])
        mark = {"fail": "✗", "error": "!", "partial": "◐"}
        who = [_link(sid, item.id, f"{mark[k]}\u00a0{sid}") for k in ("fail", "error", "partial") for sid in got[k]]
        lost = got["fail"] + got["partial"]
        if lost:            # its report's player, at the moment that decided the item
            who.append(f'<a class="replay-link" href="{escape(lost[0])}/report.html#replay-item={escape(item.id)}">'
                       f'▶\u00a0replay of {escape(lost[0])}</a>')
        points = "no points" if item.kind == "advisory" else f"{item.max_points:g}"
        body.append(f'<tr data-item="{escape(item.id)}"><th scope="row">{escape(item.title)}<br>'
                    f'<span class="id">{escape(item.id)}</span></th><td class="num">{points}</td>'
                    f'<td class="num">{100 * (share["fail"] + share["error"]):.0f} %</td>'
                    f'<td><div class="bar" aria-hidden="true">{bar}</div><span class="sub">{counts}</span></td>'
                    f'<td class="who">{" ".join(who) or "—"}</td></tr>')
    return (f'<section aria-labelledby="items-h"><h2 id="items-h">What the class got wrong</h2>'
            f'<p class="sub">Each automatically checked item, most failed first (failed includes not checked); the '
            f'links open the reports of the students who did not pass it: ✗ failed, ! not checked, '
            f'◐ partly.</p><div class="scroll">'
            f'<table class="items-share"><thead><tr><th scope="col">Item</th><th scope="col" class="num">Points</th>'
            f'<th scope="col" class="num">Failed</th><th scope="col">Passed / partly / failed / not checked</th>'
            f'<th scope="col">Students who did not pass</th></tr></thead><tbody>{"".join(body)}</tbody>'
            f'</table></div></section>')


def _repeated(decided: Mapping[str, Any]) -> bool:
    """Whether an item's grade came from repeated runs: its own, or those of one of its scenarios."""
    return int(decided.get("runs") or 1) > 1 or any(sc.get("repeat_by") for sc in decided.get("scenarios") or ())


def _unsteady(decided: Mapping[str, Any]) -> bool:
    """Whether its runs disagreed: within a repeated run, or between its scenarios (chase's spawn
    items: the chase run and the start-up runs are the same start-up)."""
    each = decided.get("scenarios") or ()
    return (decided.get("stable") is False or any(sc.get("stable") is False for sc in each)
            or len({sc.get("status") for sc in each}) > 1)


def _unstable(subs: Sequence[Submission]) -> str:
    """Items graded from repeated runs (``repeat:`` in the rubric: the median run, or the worst
    with ``repeat_by: worst``) whose runs disagreed: the grades a student may question first,
    with how each run came out."""
    from grader.report.readable import spread_text  # noqa: PLC0415 - at the head it would close a circle: report.index -> report -> report.index

    repeated = [(s, i) for s in subs for i in s.result.items if _repeated(i.decided or {})]
    if not repeated:
        return ""
    unstable = [(s, i) for s, i in repeated if _unsteady(i.decided or {})]
    lead = (f"{len(repeated)} item result(s) were graded from repeated runs; "
            f"{len(unstable)} of them came out differently from run to run.")
    if not unstable:
        return (f'<section aria-labelledby="unstable-h"><h2 id="unstable-h">Unstable items</h2>'
                f'<p class="sub" id="unstable-none">{escape(lead)}</p></section>')
    rows = "".join(f'<tr data-submission="{escape(s.id)}" data-item="{escape(i.id)}"><th scope="row">{_link(s.id)}</th>'
                   f'<td>{_link(s.id, i.id, i.id)}</td><td class="num">{_num(i.points)} / {_num(i.max_points)}</td>'
                   f'<td>{escape(spread_text(i.decided))}</td></tr>' for s, i in sorted(unstable, key=lambda si: (si[1].id, si[0].id)))
    return (f'<section aria-labelledby="unstable-h"><h2 id="unstable-h">Unstable items</h2>'
            f'<p class="sub">{escape(lead)} Each is graded by its median run, or its worst where the rubric '
            f'says so (the Runs column); read the report before a student asks.</p><div class="scroll"><table class="unstable"><thead><tr>'
            f'<th scope="col">Submission</th><th scope="col">Item</th><th scope="col" class="num">Points</th>'
            f'<th scope="col">Runs</th></tr></thead><tbody>{rows}</tbody></table></div></section>')


def _starved(subs: Sequence[Submission]) -> str:
    """Submissions whose result still holds timing items the grading machine was too busy to
    measure (``Result.starved``: 0 points for now, status error): to be graded again."""
    starved = [(s, item_id, why) for s in subs for item_id, why in s.result.starved.items()]
    if not starved:
        return ""
    ids = sorted({s.id for s, _i, _w in starved})
    rows = "".join(f'<tr data-submission="{escape(s.id)}" data-item="{escape(i)}"><th scope="row">{_link(s.id)}</th>'
                   f'<td>{_link(s.id, i, i)}</td><td>{escape(why)}</td></tr>' for s, i, why in starved)
    return (f'<section aria-labelledby="starved-h"><h2 id="starved-h">Not measured: the machine was too busy</h2>'
            f'<p class="sub" id="starved-lead">{len(ids)} submission(s) have timing items that were recorded while the '
            f'grading machine starved them of CPU even when graded again; they score 0 until they are graded on a '
            f'quieter machine: <code>grader grade ... --resume</code> (or <code>--only {escape(" ".join(ids))}</code>).</p>'
            f'<div class="scroll"><table class="starved"><thead><tr><th scope="col">Submission</th>'
            f'<th scope="col">Item</th><th scope="col">Why</th></tr></thead><tbody>{rows}</tbody></table></div></section>')


def _regrade(subs: Sequence[Submission]) -> str:
    regraded = [s for s in subs if s.previous is not None]
    if not regraded:
        return ""
    changed = [s for s in regraded if s.delta or s.changed_items()]
    changed.sort(key=lambda s: (-abs(s.delta or 0), s.id))
    if not changed:
        return (f'<section aria-labelledby="regrade-h"><h2 id="regrade-h">Regrade</h2><p id="regrade-none">'
                f'{len(regraded)} submission(s) regraded; no score or item result changed.</p></section>')
    rows = []
    for s in changed:
        d = s.delta or 0.0
        cls = "delta-up" if d > 0 else "delta-down" if d < 0 else ""
        items = "; ".join(f"{escape(i)}: {escape(a)} → {escape(b)}" for i, a, b in s.changed_items())
        rows.append(f'<tr data-submission="{escape(s.id)}"><th scope="row">{_link(s.id)}</th>'
                    f'<td class="num">{_num(s.previous.get("auto_score") if s.previous else None)}</td>'
                    f'<td class="num">{_num(s.result.auto_score)}</td>'
                    f'<td class="num {cls}">{"+" if d > 0 else ""}{d:g}</td><td>{items or "—"}</td></tr>')
    return (f'<section aria-labelledby="regrade-h"><h2 id="regrade-h">Regrade: who changed</h2>'
            f'<p class="sub">{len(changed)} of {len(regraded)} regraded submission(s) changed since their '
            f'previous grading (automatic points).</p><div class="scroll"><table class="regrade"><thead><tr>'
            f'<th scope="col">Submission</th><th scope="col" class="num">Before</th>'
            f'<th scope="col" class="num">After</th><th scope="col" class="num">Change</th>'
            f'<th scope="col">Items changed (before → after)</th></tr></thead><tbody>{"".join(rows)}</tbody>'
            f'</table></div></section>')


def _sub_table(subs: Sequence[Submission]) -> str:
    first = subs[0].result
    options = "".join(f'<option value="{escape(i.id)}">{escape(i.id)}</option>'
                      for i in first.items if i.kind in ("auto", "advisory"))
    regraded = any(s.previous is not None for s in subs)
    late = any(s.result.late is not None for s in subs)
    rows = []
    for s in sorted(subs, key=lambda s: s.id):
        r = s.result
        failed = _failed_items(r)
        flags = [n.item_id for n in r.integrity_flags]
        delta = s.delta
        cells = [
            f'<th scope="row">{_link(s.id)}</th>',
            f'<td class="num">{_num(r.auto_score)} / {_num(r.auto_max)}</td>',
            f'<td class="num">{_num(r.total)} / {_num(r.max_score)}</td>',
            f'<td>{" ".join(_link(s.id, i.id, i.id) for i in failed) or "—"}</td>',
            f'<td>{escape(", ".join(flags)) or "—"}</td>',
            f'<td>{"failed: " + escape(", ".join(s.build_failed)) if s.build_failed else "ok"}</td>',
            f'<td>{"<br>".join(escape(c) for c in s.crashes) or "—"}</td>',
            f'<td class="num">{_num(s.time_s)}</td>',
        ]
        if late:
            cells.insert(3, f'<td class="num" title="{escape(r.late.note if r.late else "")}">{_late_cell(r)}</td>')
        if regraded:
            cells.append(f'<td class="num">{"—" if delta is None else ("+" if delta > 0 else "") + f"{delta:g}"}</td>')
        data = {"submission": s.id, "auto": f"{r.auto_score:g}", "total": "" if r.total is None else f"{r.total:g}",
                "failed": " ".join(i.id for i in failed), "nfailed": str(len(failed)), "flags": " ".join(flags),
                "build": "failed" if s.build_failed else "ok", "crashes": str(len(s.crashes)),
                "time": "" if s.time_s is None else f"{s.time_s:g}", "delta": "" if delta is None else f"{delta:g}",
                "late": f"{r.late_penalty:g}" if r.late is not None else ""}
        attrs = " ".join(f'data-{k}="{escape(v)}"' for k, v in data.items())
        rows.append(f"<tr {attrs}>{''.join(cells)}</tr>")
    cols = [("submission", "Submission", "text"), ("auto", "Automatic", "num"), ("total", "Total", "num"),
            ("nfailed", "Items not passed", "num"), ("flags", "Integrity flags", "text"),
            ("build", "Build", "text"), ("crashes", "Crashes", "num"), ("time", "Time (s)", "num")]
    if late:
        cols.insert(3, ("late", "Late penalty", "num"))
    if regraded:
        cols.append(("delta", "Change at regrade", "num"))
    head = "".join(f'<th scope="col" data-key="{k}" data-type="{t}"{" class=num" if k in NUMERIC else ""}>'
                   f'<button type="button" class="sort">{escape(text)}</button></th>' for k, text, t in cols)
    problem_opts = ('<option value="">all</option><option value="build">build failed</option>'
                    '<option value="crash">a node crashed</option>'
                    + ('<option value="changed">changed at regrade</option>' if regraded else ""))
    controls = (f'<div class="controls" id="controls" hidden>'
                f'<label>Submission<input id="f-text" type="search" placeholder="id contains…"></label>'
                f'<label>Did not pass item<select id="f-item"><option value="">any</option>{options}</select></label>'
                f'<label>Integrity flag<select id="f-flag"><option value="">all</option>'
                f'<option value="any">flagged</option><option value="none">not flagged</option></select></label>'
                f'<label>Problem<select id="f-problem">{problem_opts}</select></label>'
                f'<span id="f-count" role="status"></span></div>')
    return (f'<section aria-labelledby="subs-h"><h2 id="subs-h">Submissions</h2>{controls}<div class="scroll">'
            f'<table class="subs" id="subs"><caption class="sr">Submissions, sortable by each column</caption>'
            f'<thead><tr>{head}</tr></thead><tbody>{"".join(rows)}</tbody></table></div></section>')


def _similar(summary: Mapping[str, Any] | None) -> str:
    return class_section(summary)


def render_index(results: Mapping[str, Result], *, title: str | None = None,
                 docs: Mapping[str, ResultDocument] | None = None,
                 similarity: Mapping[str, Any] | None = None) -> str:
    """The class view. ``docs``: each submission's result.json (build status, timings, previous
    grading), optional. ``similarity``: ``OUT/similarity/similarity.json`` (grader.similarity), for
    the section "Similar submissions"."""
    subs = []
    for sid in sorted(results):
        check_submission_id(sid)
        subs.append(Submission.from_doc(sid, results[sid], (docs or {}).get(sid)))
    first = subs[0].result if subs else None
    heading = title or (f"{first.title}: class view" if first else "Class view")
    if subs:
        scores = [s.result.auto_score for s in subs]
        assert first is not None                    # (there are submissions)
        lead = (f"{len(subs)} submission(s). Automatic score out of {first.auto_max:g}: median "
                f"{statistics.median(scores):g}, mean {statistics.mean(scores):.1f}, lowest {min(scores):g}, "
                f"highest {max(scores):g}. Totals stay empty (—) until manual items are graded.")
        body = (_distribution(subs) + _item_table(subs) + _starved(subs) + _unstable(subs) + _regrade(subs)
                + _sub_table(subs)
                + _similar(similarity))
        script = f"<script>{INDEX_JS}</script>"
    else:
        lead, body, script = "No graded submissions yet.", "", ""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(heading)}</title><style>{CSS}</style></head>
<body><main><h1>{escape(heading)}</h1>
<p class="sub" id="lead">{escape(lead)}</p>
{body}</main>{script}</body></html>
"""


def write_index(out_dir: str | os.PathLike[str], results: Mapping[str, Result], **kwargs: Any) -> Path:
    path = OutputFolder(Path(out_dir)).index_html
    atomic_write(path, render_index(results, **kwargs))
    return path


def read_docs(out_dir: str | os.PathLike[str], ids: Sequence[str]) -> dict[str, ResultDocument]:
    """Each submission's result.json (build, timings, previous, intake); one that cannot be read
    is left out (the class view shows its Result without them)."""
    docs = {}
    for sid in ids:
        try:
            docs[sid] = ResultDocument.read(OutputFolder(Path(out_dir)).submission(sid).result_json)
        except (OSError, ValueError):
            continue
    return docs


__all__ = ["Submission", "crashes_of", "read_docs", "render_index", "write_index"]
