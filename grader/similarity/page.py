"""The side-by-side page of one pair (``OUT/similarity/pair-A--B.html``) and the class view's
section "Similar submissions". Words matter here: the pages say what is similar and how unusual it
is in this class, never that anyone cheated.
"""

from __future__ import annotations

from html import escape
from pathlib import Path
from typing import Any, Mapping

from grader.similarity.summary import KNOWN_PREFIX, OUT_DIR, PAIRS_CSV

NOTE = ("Similarity is not proof of misconduct: honest solutions of one lab share a lot. This page "
        "shows what the two have in common and how unusual that is in this class; read the code and the "
        "reports before drawing any conclusion.")
CLASS_NOTE = ("Similarity is not proof of misconduct: honest solutions of one lab share a lot. Each pair's "
              "page shows what the two have in common and how unusual that is in this class; read the code "
              "and the reports before drawing any conclusion.")
GROUP_WORDS = {"path": "trajectory", "commands": "commands sent", "values": "published values",
               "rate": "publish rate", "log": "log line", "names": "name", "failure": "item not passed",
               "measured": "measured value"}
PAGE_CSS = """
.pair-grid{display:grid;grid-template-columns:1fr 1fr;gap:.8rem}
.pair-grid pre{font-size:.78rem;line-height:1.3;max-height:32rem;overflow:auto;border:1px solid #ccc;
  padding:.4rem;margin:0;white-space:pre-wrap;word-break:break-word}
mark.m{background:#ffe08a;color:inherit}
.pair-grid h4{margin:.2rem 0;font-size:.9rem}
table.shared td,table.shared th{padding:.2rem .5rem;vertical-align:top}
@media print{.pair-grid pre{max-height:none}}
"""


def _name(sid: str) -> str:
    return f"known solution {sid[len(KNOWN_PREFIX):]}" if sid.startswith(KNOWN_PREFIX) else sid


def _report_link(sid: str, prefix: str = "../") -> str:
    if sid.startswith(KNOWN_PREFIX):
        return escape(_name(sid))
    return f'<a href="{prefix}{escape(sid)}/report.html">{escape(sid)}</a>'


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def _distance_words(f: Mapping[str, Any]) -> str:
    d = f.get("distance")
    if d is None:
        return "the same"
    group = f.get("group")
    if group == "path":
        return f"{100 * d:.1f} cm apart (RMS)"
    if group in ("rate", "measured"):
        return f"{100 * d:.1f} % apart"
    return f"{d:.2f} of the class's spread apart"


def feature_sentence(f: Mapping[str, Any], n_class: int) -> str:
    """'trajectory: path of /turtle1/pose in step goal_wrap, 0.4 cm apart; 4 of 8 submissions ...'"""
    what = GROUP_WORDS.get(str(f.get("group")), str(f.get("group")))
    holders = int(f.get("holders", 2))
    forced = float(f.get("forced") or 0.0)
    text = (f"{what}: {f.get('label')}, {_distance_words(f)}; {holders} of {f.get('among') or n_class} "
            f"submissions show this "
            f"({f.get('bits', 0):.1f} bits of rarity)")
    if forced > 0:
        text += f"; {100 * forced:.0f} % of it is what passing submissions do"
    return text


def _regions_html(text: str, slices: list) -> str:
    out, at = [], 0
    for start, end in sorted(slices):
        start, end = max(start, at), max(end, at)
        out.append(escape(text[at:start]))
        out.append(f'<mark class="m">{escape(text[start:end])}</mark>')
        at = end
    out.append(escape(text[at:]))
    return "".join(out)


def _source_section(p: Mapping[str, Any], sets: Mapping[str, Any]) -> str:
    from grader.similarity.code import matched_regions  # noqa: PLC0415 - similarity.code loads numpy (147 ms CPU), only on this path

    a, b = sets.get(p["a"]), sets.get(p["b"])
    if a is None or b is None or not p.get("shared_fingerprints"):
        return ('<section aria-labelledby="src-h"><h2 id="src-h">Source</h2><p>No source in common beyond '
                'the code the students were given and code most of the class shares.</p></section>')
    blocks = []
    for r in matched_regions(a, b)[:8]:
        blocks.append(
            f'<div class="pair-grid"><div><h4>{escape(_name(p["a"]))}: {escape(r.a_file)} '
            f'({_pct(r.a_share)} matched)</h4><pre>{_regions_html(r.a_text, r.a_slices)}</pre></div>'
            f'<div><h4>{escape(_name(p["b"]))}: {escape(r.b_file)} ({_pct(r.b_share)} matched)</h4>'
            f'<pre>{_regions_html(r.b_text, r.b_slices)}</pre></div></div>')
    lead = (f"{_pct(p['a_in_b'])} of {escape(_name(p['a']))}'s counted code is found in "
            f"{escape(_name(p['b']))}, and {_pct(p['b_in_a'])} of {escape(_name(p['b']))}'s in "
            f"{escape(_name(p['a']))} ({p['shared_fingerprints']} fingerprints in common). Identifiers, "
            f"strings, comments and layout are ignored; code the students were given and code most of the "
            f"class shares are left out. Highlighted: the matched regions.")
    return (f'<section aria-labelledby="src-h"><h2 id="src-h">Source</h2><p>{lead}</p>'
            f'{"".join(blocks)}</section>')


def _behaviour_section(p: Mapping[str, Any], summary: Mapping[str, Any]) -> str:
    from grader.similarity.figures import overlay_figures  # noqa: PLC0415 - similarity.figures loads pandas, matplotlib, numpy (424 ms CPU), only on this path

    if p.get("known"):
        return ('<section aria-labelledby="beh-h"><h2 id="beh-h">Behaviour</h2><p>A known solution has no '
                'recording (it was not graded), so only its source is compared.</p></section>')
    feats = p.get("features") or []
    n = int(summary.get("class_size", 0))
    if not feats:
        return ('<section aria-labelledby="beh-h"><h2 id="beh-h">Behaviour</h2><p>Nothing unusual in common: '
                'where the two behave alike, most of the class does too.</p></section>')
    rows = "".join(
        f'<tr><td>{escape(GROUP_WORDS.get(f["group"], f["group"]))}</td><td>{escape(f["label"])}</td>'
        f'<td>{escape(f["scenario"] or "—")}</td><td>{escape(_distance_words(f))}</td>'
        f'<td class="num">{f["holders"]} of {f.get("among") or n}</td><td class="num">{f["bits"]:.1f}</td>'
        f'<td class="num">{_pct(float(f["forced"]))}</td><td class="num">{f["evidence"]:.2f}</td></tr>'
        for f in feats)
    figures = overlay_figures(p, summary)
    figs = "".join(f'<figure class="plot-fig">{fig.svg}<figcaption>{escape(fig.alt)}</figcaption></figure>'
                   for fig in figures)
    lead = (f"Behaviour similarity {_pct(p['behaviour'])} ({p['behaviour_bits']:.1f} bits): what the two "
            f"submissions' code did in the recorded scenarios, each shared feature weighed by how few of the "
            f"{n} submissions share it (bits: log2 of the number with a recording of that scenario over that "
            f"count) and discounted where it "
            f"is what submissions passing the scenario do (the lab asks for it).")
    return (f'<section aria-labelledby="beh-h"><h2 id="beh-h">Behaviour</h2><p>{lead}</p><div class="scroll">'
            f'<table class="shared"><thead><tr><th scope="col">What</th><th scope="col">Feature</th>'
            f'<th scope="col">Scenario</th><th scope="col">How close</th><th scope="col">Share of the class</th>'
            f'<th scope="col">Rarity (bits)</th><th scope="col">Forced by the lab</th>'
            f'<th scope="col">Evidence (bits)</th></tr></thead><tbody>{rows}</tbody></table></div>{figs}</section>')


def render_pair(p: Mapping[str, Any], summary: Mapping[str, Any], out: Path) -> str:
    """The self-contained side-by-side page of one listed pair."""
    from grader.report.style import CSS  # noqa: PLC0415 - report.style loads pandas, numpy (424 ms CPU), only on this path

    title = f"{_name(p['a'])} and {_name(p['b'])}: what is similar"
    group = ""
    if p.get("cluster") is not None:
        members = summary["clusters"][p["cluster"]]
        group = (f'<p>Both belong to a group of {len(members)} submissions joined by similar pairs: '
                 f'{", ".join(escape(m) for m in members)}.</p>')
    lead = (f'<p>{_report_link(p["a"])} and {_report_link(p["b"])}: source similarity {_pct(p["source"])}, '
            f'behaviour similarity {_pct(p["behaviour"])} (listed at {_limits(summary)}). {escape(NOTE)}</p>')
    body = _source_section(p, summary.get("_sets") or {}) + _behaviour_section(p, summary)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title><style>{CSS}{PAGE_CSS}</style></head>
<body><main><p><a href="../index.html#similar-h">← class view</a></p><h1>{escape(title)}</h1>
{lead}{group}{body}</main></body></html>
"""


def _limits(summary: Mapping[str, Any]) -> str:
    st = summary.get("settings", {})
    return (f"source similarity {_pct(st.get('threshold', 0.5))} or behaviour similarity "
            f"{_pct(st.get('behaviour_threshold', 0.3))} or more")


def class_section(summary: Mapping[str, Any] | None) -> str:
    """The class view's "Similar submissions" section (empty when similarity was not computed)."""
    if not summary:
        return ""
    listed = [p for p in summary.get("pairs") or () if p.get("listed")]
    n = summary.get("class_size", 0)
    limits = _limits(summary)
    known = summary.get("known") or []
    head = (f'{n} submissions, {summary.get("pairs_compared", 0)} pairs compared by source and behaviour'
            + (f', each also with {len(known)} known solution(s) ({", ".join(known)})' if known else "")
            + f'. Listed: pairs at {limits} (<code>grader similarity OUT --threshold S '
              f'--behaviour-threshold B</code>), the furthest above them first. All pairs: '
              f'<a href="{OUT_DIR}/{PAIRS_CSV}">{PAIRS_CSV}</a>. {escape(CLASS_NOTE)}')
    groups = ""
    if summary.get("clusters"):
        items = "".join(f'<li data-group="{i + 1}">Group {i + 1} ({len(c)} submissions): '
                        f'{", ".join(_report_link(s, "") for s in c)}</li>'
                        for i, c in enumerate(summary["clusters"]))
        groups = (f'<h3>Groups of three or more</h3><p class="sub">Submissions joined by listed pairs, '
                  f'shown once as a group.</p><ul class="sim-groups">{items}</ul>')
    shown = [p for p in listed if p.get("page")]
    more = (f'<p class="sub">{len(listed) - len(shown)} more pair(s) are listed: see '
            f'<a href="{OUT_DIR}/{PAIRS_CSV}">{PAIRS_CSV}</a> (pages are made for the '
            f'{len(shown)} most similar).</p>') if len(shown) < len(listed) else ""
    if not listed:
        table = f'<p id="similar-none">No pair is at {limits}.</p>'
    else:
        rows = []
        for rank, p in enumerate(shown, 1):
            top = "; ".join(escape(GROUP_WORDS.get(f["group"], f["group"]) + ": " + f["label"])
                            for f in (p.get("features") or [])[:3]) or "—"
            grp = "" if p.get("cluster") is None else f'group {p["cluster"] + 1}'
            rows.append(
                f'<tr data-pair="{escape(p["a"])}--{escape(p["b"])}" data-known="{"yes" if p["known"] else "no"}">'
                f'<td class="num">{rank}</td><th scope="row">{_report_link(p["a"], "")}</th>'
                f'<td>{_report_link(p["b"], "")}</td><td class="num">{_pct(p["source"])}</td>'
                f'<td class="num">{_pct(p["behaviour"])}</td><td>{escape(grp) or "—"}</td><td>{top}</td>'
                f'<td><a href="{OUT_DIR}/{escape(p["page"])}">side by side</a></td></tr>')
        table = (f'<div class="scroll"><table class="similar" id="similar"><thead><tr><th scope="col" class="num">'
                 f'#</th><th scope="col">Submission</th><th scope="col">Similar to</th><th scope="col" class="num">'
                 f'Source</th><th scope="col" class="num">Behaviour</th><th scope="col">Group</th>'
                 f'<th scope="col">Most unusual in common</th><th scope="col">Page</th></tr></thead>'
                 f'<tbody>{"".join(rows)}</tbody></table></div>{more}')
    return (f'<section aria-labelledby="similar-h"><h2 id="similar-h">Similar submissions</h2>'
            f'<p class="sub">{head}</p>{groups}{table}</section>')


__all__ = ["class_section", "feature_sentence", "render_pair"]
