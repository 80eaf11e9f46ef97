"""Evidence in words: labels and units from the analyzer (``grader.analyze.evidence``), times as
seconds since the scenario started, thresholds from the item's parameters, hidden ones left out.

Only keys the analyzer labelled are shown; the raw evidence (every key, as in result.json) goes
in a collapsed ``<details>`` of the page. In the student view, parameters the rubric marks
hidden (``item.hidden_params``) are removed everywhere: thresholds, evidence echoing them, the
"expected" part of the first sentence, and the raw evidence.
"""

from __future__ import annotations

import json
import math
import string
from collections import Counter
from html import escape
from typing import Any, Iterable, Mapping

from grader.analyze import evidence_labels, expected_text
from grader.analyze.evidence import SHARE, SINCE_START, TIME
from grader.report.result import compact_number_lists
from grader.rubric.score import render_template
from grader.rubric.result import ItemResult, strip_keys

MAX_ROWS = 12
MAX_LIST = 8
MAX_TEXT = 300
_MISSING = object()


def item_params(item: ItemResult, fallback: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The analyzer's effective parameters: the item's own (result.json ``params``) when the
    grader recorded them, else ``fallback`` (defaults merged with the rubric's)."""
    own = getattr(item, "params", None)
    return dict(own) if own is not None else dict(fallback or {})


def hidden_names(item: ItemResult) -> set[str]:
    return {str(n) for n in (getattr(item, "hidden_params", None) or ())}


def strip_hidden(value: Any, hidden: set[str]) -> Any:
    """``value`` without mapping keys named in ``hidden`` (at any depth)."""
    return strip_keys(value, hidden) if hidden else value


# -- values --------------------------------------------------------------------------------

def _number(v: float, digits: int = 4) -> str:
    if float(v).is_integer() and abs(v) < 1e9:
        return str(int(v))
    return f"{v:.{digits}g}"


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def format_value(value: Any, unit: str = "", t0: float | None = None, *, with_unit: bool = True) -> str:
    """Plain text of one evidence value in its unit ("0.1 m", "3.2 s after the start", "12 %")."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if _is_num(value):
        v = float(value)
        if not math.isfinite(v):
            return "—"
        if unit == TIME:
            if t0 is None:
                return f"{_number(v, 12)} (epoch s)" if with_unit else _number(v, 12)
            return f"{v - t0:.2f} s after the start" if with_unit else f"{v - t0:.2f}"
        if unit == SHARE:
            return f"{100 * v:.3g} %" if with_unit else f"{100 * v:.3g}"
        if unit == SINCE_START:
            return f"{v:.2f} s after the start" if with_unit else f"{v:.2f}"
        text = _number(v)
        if unit == "deg":
            return text + "°"
        return f"{text} {unit}" if unit and with_unit else text
    if isinstance(value, str):
        return value if len(value) <= MAX_TEXT else value[:MAX_TEXT] + "…"
    if isinstance(value, list):
        if value and all(_is_num(v) for v in value) and len(value) <= 3 and unit not in (TIME, SINCE_START):
            inner = ", ".join(_number(float(v)) for v in value)
            return f"({inner})" + (f" {unit}" if unit and with_unit else "")
        shown = [format_value(v, unit, t0, with_unit=False) for v in value[:MAX_LIST]]
        more = f", … ({len(value)} in all)" if len(value) > MAX_LIST else ""
        tail = (f" {_unit_words(unit)}" if unit and with_unit and unit not in (SHARE,) else "")
        return (", ".join(shown) + more + tail) if shown else "none"
    if isinstance(value, Mapping):
        return ", ".join(f"{k}: {format_value(v)}" for k, v in list(value.items())[:MAX_LIST])
    return str(value)


def _unit_words(unit: str) -> str:
    return {TIME: "s after the start", SINCE_START: "s after the start"}.get(unit, unit)


def _header_unit(unit: str) -> str:
    return {TIME: "s after the start", SINCE_START: "s after the start", SHARE: "%", "": ""}.get(unit, unit)


# -- tables -------------------------------------------------------------------------------

class _Labels:
    def __init__(self, analyzer: str | None) -> None:
        self.table = evidence_labels(analyzer)

    def get(self, path: str, key: str) -> Any:
        if path in self.table:
            return self.table[path]
        return self.table.get(key, _MISSING)


def evidence_rows(item: ItemResult, *, hidden: Iterable[str] = ()) -> list[tuple[str, str]]:
    """(label, value HTML) for every labelled evidence key, in the evidence's order."""
    hide = set(hidden)
    labels = _Labels(item.analyzer)
    ev = item.evidence or {}
    t0 = ev.get("scenario_start") if _is_num(ev.get("scenario_start")) else None
    return _rows(ev, labels, "", hide, t0)


def _rows(ev: Mapping[str, Any], labels: _Labels, prefix: str, hide: set[str],
          t0: float | None) -> list[tuple[str, str]]:
    rows = []
    for key, value in ev.items():
        key = str(key)
        if key in hide:
            continue
        lab = labels.get(prefix + key, key)
        if lab is None or lab is _MISSING:
            continue
        text, unit = lab
        if isinstance(value, Mapping):
            sub = _rows(value, labels, prefix + key + ".", hide, t0)
            if sub:
                rows.append((text, _kv_table(sub)))
            continue
        if isinstance(value, list) and value and all(isinstance(v, Mapping) for v in value):
            table = _records(value, labels, hide, t0)
            if table:
                rows.append((text, table))
            continue
        rows.append((text, escape(format_value(value, unit, t0))))
    return rows


def _kv_table(rows: list[tuple[str, str]]) -> str:
    body = "".join(f'<tr><th scope="row">{escape(k)}</th><td>{v}</td></tr>' for k, v in rows)
    return f'<table class="ev">{body}</table>'


def _records(records: list[Mapping[str, Any]], labels: _Labels, hide: set[str], t0: float | None) -> str:
    cols: list[tuple[str, str, str]] = []
    for rec in records[:MAX_ROWS]:
        for key in rec:
            key = str(key)
            lab = labels.get(key, key)
            if key in hide or lab is None or lab is _MISSING or any(c[0] == key for c in cols):
                continue
            cols.append((key, lab[0], lab[1]))
    if not cols:
        return ""
    head = "".join(f'<th scope="col">{escape(text)}'
                   + (f' <span class="unit">({escape(_header_unit(unit))})</span>' if _header_unit(unit) else "")
                   + "</th>" for _, text, unit in cols)
    body = "".join("<tr>" + "".join(
        f'<td>{escape(format_value(rec.get(k), unit, t0, with_unit=False))}</td>' for k, _, unit in cols)
        + "</tr>" for rec in records[:MAX_ROWS])
    more = (f'<tr><td colspan="{len(cols)}">… {len(records) - MAX_ROWS} more rows in result.json</td></tr>'
            if len(records) > MAX_ROWS else "")
    return f'<table class="ev"><thead><tr>{head}</tr></thead><tbody>{body}{more}</tbody></table>'


def threshold_rows(item: ItemResult, params: Mapping[str, Any], *, student_view: bool) -> list[tuple[str, str]]:
    """(label, value) of the labelled parameters; hidden ones left out for students and marked
    for instructors."""
    labels = _Labels(item.analyzer)
    hidden = hidden_names(item)
    rows = []
    for key, value in params.items():
        lab = labels.get(key, key)
        if lab is None or lab is _MISSING or value is None:
            continue
        if key in hidden and student_view:
            continue
        note = " (hidden from students)" if key in hidden else ""
        rows.append((lab[0], escape(format_value(value, lab[1])) + note))
    return rows


def measured_sentence(item: ItemResult, params: Mapping[str, Any], *, student_view: bool) -> str:
    """"<what>: <measured> — expected <expected>." (plain text); the expected part is left out
    when it needs a threshold hidden from students or a value nobody recorded."""
    labels = _Labels(item.analyzer)
    lab = labels.get("value", "value")
    what, unit = lab if isinstance(lab, tuple) else ("result", "")
    measured = "not measured" if item.value is None else format_value(item.value, unit)
    sentence = f"{what[:1].upper()}{what[1:]}: {measured}"
    template = expected_text(item.analyzer)
    if template:
        names = _fields(template)
        hidden = hidden_names(item)
        if not (student_view and names & hidden):
            context = {**(item.evidence or {}), **params}
            text = render_template(template, context)
            if "{" not in text and "n/a" not in text:
                sentence += f" — expected {text}"
    return sentence.rstrip(".") + "."


def _fields(template: str) -> set[str]:
    out = set()
    try:
        for _, name, _, _ in string.Formatter().parse(template):
            if name:
                out.add(name.split(".")[0].split("[")[0])
    except ValueError:
        pass
    return out


def raw_json(evidence: Mapping[str, Any], hidden: set[str] | None = None, max_list: int = 12) -> str:
    """The evidence as indented JSON with long lists cut (the full lists are in result.json)."""
    def cut(v: Any) -> Any:
        if isinstance(v, Mapping):
            return {str(k): cut(x) for k, x in v.items()}
        if isinstance(v, list):
            head = [cut(x) for x in v[:max_list]]
            return head + ([f"… {len(v) - max_list} more"] if len(v) > max_list else [])
        return v

    return compact_number_lists(json.dumps(cut(strip_hidden(dict(evidence), hidden or set())), indent=1,
                                           ensure_ascii=False, default=str))


def spread_text(decided: Mapping[str, Any] | None) -> str:
    """The report's sentence: "Graded by the median of 3 runs: 2 of 3 runs partial (1.5 points),
    1 of 3 pass (3 points)." (or "by the worst of 3 runs (it has to work in every run)"), and for
    an item on several scenarios of which one was repeated, how each came out. Empty for an item
    decided by one run."""
    if not decided:
        return ""
    text = _runs_text(decided)
    each = decided.get("scenarios") or ()
    if any(s.get("repeat_by") for s in each):
        said = "; ".join(f"{s.get('scenario')} ({_how(s)}: {s.get('status')})" for s in each)
        text = (text + " " if text else "") + f"The item takes the worst of its scenarios: {said}."
    return text


def _how(one: Mapping[str, Any]) -> str:
    """"one lockstep run", "the worst of 3 runs", "the median of 2 runs": a scenario's runs."""
    runs, by = int(one.get("runs") or 1), one.get("repeat_by")
    if not by:
        return str(one.get("by") or "one run")
    return f"the {by} of {runs} run{'s' if runs > 1 else ''}"


def _runs_text(decided: Mapping[str, Any]) -> str:
    if max(int(decided.get("runs") or 1), int(decided.get("planned") or 1)) <= 1:
        return ""
    runs = int(decided["runs"])
    counts: Counter = Counter((o.get("status"), o.get("points")) for o in decided.get("outcomes") or ())
    parts = []
    for (status, points), n in counts.most_common():
        amount = f" ({points:g} points)" if isinstance(points, (int, float)) else ""
        parts.append(f"{n} of {runs} run{'s' if runs > 1 else ''} {status}{amount}")
    planned = int(decided.get("planned") or runs)
    if decided.get("repeat_by") == "worst":
        extra = (f"; a further {planned - runs} run(s) could not have raised it" if planned > runs else "")
        return (f"Graded by the worst of {runs} run{'s' if runs > 1 else ''} (it has to work in every run): "
                + ", ".join(parts) + extra + ".")
    extra = (f"; a further {planned - runs} run(s) could not have changed the median"
             if planned > runs else "")
    return f"Graded by the median of {runs} runs: " + ", ".join(parts) + extra + "."
