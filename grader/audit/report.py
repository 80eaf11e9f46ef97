"""The audit's report: a terminal summary, ``audit.md`` (diffs in Markdown) and ``audit.json``."""

from __future__ import annotations

import json
from pathlib import Path

from grader.audit.mutate import OPERATORS
from grader.audit.outcome import AuditReport, Outcome

MUTANT_STATUSES = ("killed", "equivalent", "surviving", "error")


def headline(report: AuditReport) -> list[str]:
    """The numbers: made, graded, killed, equivalent, surviving, errors, score, time."""
    sampled = f" (a sample of {report.graded}, seed {report.seed})" if report.sample is not None else ""
    score = report.score
    judged = report.graded - report.count("equivalent") - report.count("error")
    return [
        f"mutants made {report.made}, graded {report.graded}{sampled}: killed {report.count('killed')}, "
        f"equivalent {report.count('equivalent')}, surviving {report.count('surviving')}, "
        f"errors {report.count('error')}",
        "mutation score " + (f"{report.count('killed')}/{judged} = {100 * score:.1f} %" if score is not None
                             else "n/a (nothing judged)")
        + (f"; regraded offline from the recordings of an earlier run in {report.wall_s:.0f} s" if report.regraded else
           f"; wall time {report.wall_s:.0f} s (reference {report.reference_wall_s:.0f} s) at --jobs "
           f"{report.jobs}, --time-scale {report.time_scale:g}"),
    ]


def by_operator(report: AuditReport) -> list[tuple[str, dict[str, int]]]:
    rows = []
    for op in OPERATORS:
        mine = [o for o in report.outcomes if o.mutant["operator"] == op]
        if mine:
            rows.append((op, {s: sum(1 for o in mine if o.status == s) for s in MUTANT_STATUSES} | {"graded": len(mine)}))
    return rows


def _where(o: Outcome) -> str:
    return f"{o.mutant['file']}:{o.mutant['line']}"


def text_summary(report: AuditReport, diffs: bool = True) -> str:
    """What ``grader rubric audit`` prints."""
    lines = [f"{report.lab}: mutation audit of {report.rubric} (reference {report.reference})"]
    lines += ["  " + h for h in headline(report)]
    if report.given_files:
        lines.append(f"  not mutated (given unchanged by the handout): {', '.join(report.given_files)}")
    lines.append("  by operator:")
    for op, c in by_operator(report):
        lines.append(f"    {op:20} {c['graded']:3} graded: " + ", ".join(f"{c[s]} {s}" for s in MUTANT_STATUSES if c[s]))
    surviving = [o for o in report.outcomes if o.status == "surviving"]
    if surviving:
        lines.append(f"  SURVIVING ({len(surviving)}): full marks, not recorded as equivalent: a blind spot of the "
                     "rubric, or a correct mutant whose reason belongs in the rubric's equivalent_mutants")
        for o in surviving:
            lines.append(f"    {o.mutant['id']}  {_where(o)}  {o.mutant['description']}")
            if diffs:
                lines += ["      " + d.rstrip("\n") for d in o.diff.splitlines()]
    for status, title in (("equivalent", "equivalent (recorded in the rubric)"), ("error", "could not be graded")):
        mine = [o for o in report.outcomes if o.status == status]
        if mine:
            lines.append(f"  {title} ({len(mine)}):")
            for o in mine:
                why = o.reason if status == "equivalent" else (o.error or "").splitlines()[0][:200]
                lines.append(f"    {o.mutant['id']}  {_where(o)}  {o.mutant['description']}: {why}")
    if report.stale_equivalents:
        lines.append("  recorded equivalent_mutants that no mutant of the reference has any more (remove them): "
                     + ", ".join(report.stale_equivalents))
    return "\n".join(lines)


def markdown(report: AuditReport) -> str:
    """``audit.md``: the summary, the operator table, every survivor with its diff, every
    equivalent with its reason, and which items killed each mutant."""
    out = [f"# Mutation audit: {report.lab}", "", f"Rubric `{report.rubric}`, reference `{report.reference}`.", ""]
    out += [f"* {h}" for h in headline(report)]
    if report.given_files:
        out.append(f"* not mutated (handed out unchanged): {', '.join(f'`{f}`' for f in report.given_files)}")
    out += ["", "| operator | graded | killed | equivalent | surviving | error |", "|---|---|---|---|---|---|"]
    for op, c in by_operator(report):
        out.append(f"| {op} | {c['graded']} | {c['killed']} | {c['equivalent']} | {c['surviving']} | {c['error']} |")
    for status, title in (("surviving", "Surviving (blind spots)"), ("equivalent", "Equivalent (recorded)"),
                          ("error", "Not graded")):
        mine = [o for o in report.outcomes if o.status == status]
        if not mine:
            continue
        out += ["", f"## {title}: {len(mine)}", ""]
        for o in mine:
            out.append(f"### `{o.mutant['id']}` {_where(o)}: {o.mutant['description']}")
            if o.reason:
                out += ["", f"Reason: {o.reason}"]
            if o.error:
                out += ["", f"Error: {o.error.splitlines()[0] if o.error else ''}"]
            out += ["", "```diff", o.diff.rstrip("\n"), "```", ""]
    killed = [o for o in report.outcomes if o.status == "killed"]
    if killed:
        out += ["", f"## Killed: {len(killed)}", "", "| mutant | where | change | points lost |", "|---|---|---|---|"]
        for o in killed:
            lost = ", ".join(f"{k} -{v:g}" for k, v in o.lost.items())
            desc = o.mutant["description"].replace("|", "\\|")
            out.append(f"| `{o.mutant['id']}` | {_where(o)} | {desc} | {lost} |")
    return "\n".join(out) + "\n"


def write_report(report: AuditReport, out: Path) -> None:
    (out / "audit.json").write_text(json.dumps(report.to_json(), indent=1) + "\n")
    (out / "audit.md").write_text(markdown(report))
